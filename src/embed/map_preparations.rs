//! The table's map preparations ([`crate::passes::prepare`]): a host asks for a kind
//! ([`DisplacementPass::set_map_preparation`]), the plan keys an entry per (live map,
//! kind), the first record or preparation after builds it in the kind's scope
//! ([`DisplacementPass::record_map_preparations`]) and the host reads the built value
//! ([`DisplacementPass::map_preparation`]).

use super::DisplacementPass;
use super::inputs::MaterialId;
use crate::error::Result;
use crate::passes::prepare::{self, KINDS, MapPreparation};
use crate::timing::ScopeWriter;
use ash::vk;

impl DisplacementPass {
    /// Asks for the map preparation `P` (one of [`crate::passes::prepare::KINDS`]) of
    /// every live material's height map (`on`), or no longer (`off`: what was built is
    /// retired). The next record (or [`DisplacementPass::record_preparation`]) builds it
    /// for each map without it, in `P::NAME`'s scope; a map added later gets it in the
    /// record after. Needs no GPU idle. On error the pass is unchanged.
    pub fn set_map_preparation<P: MapPreparation>(&mut self, on: bool) -> Result<()> {
        self.check_alive()?;
        let kind = prepare::kind_of::<P>()?;
        let old = self.prepare_requested.clone();
        self.prepare_requested.retain(|&k| k != kind);
        if on {
            self.prepare_requested.push(kind);
        }
        if let Err(e) = self.sync() {
            self.prepare_requested = old;
            return Err(e);
        }
        Ok(())
    }

    /// Material `id`'s map's preparation `P` once a record or preparation has recorded
    /// its build (`None` before, or when it was not asked for). What it wrote is the GPU's
    /// once that command buffer has executed.
    pub fn map_preparation<P: MapPreparation>(&self, id: MaterialId) -> Option<&P> {
        let kind = prepare::kind_of::<P>().ok()?;
        let m = self.entry(id).ok()?;
        let map = self.maps[m.map].as_ref()?;
        let p = map.prepared.iter().find(|p| p.kind == kind && p.built)?;
        p.value.as_any().downcast_ref::<P>()
    }

    /// The scopes of the map preparations, in the order of [`KINDS`]: each unbuilt entry
    /// recorded from its map's texture.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`], after the uploads (every height texture's level 0
    /// sampled-readable).
    pub(super) unsafe fn record_map_preparations(
        &mut self,
        w: &mut ScopeWriter,
        cmd: vk::CommandBuffer,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        for (kind, k) in KINDS.iter().enumerate() {
            let unbuilt =
                |m: &super::plan::MapEntry| m.prepared.iter().any(|p| p.kind == kind && !p.built);
            let Some(pass) = self.prepare_passes.iter().find(|p| p.kind == kind) else {
                continue;
            };
            if !self.maps.iter().flatten().any(unbuilt) {
                continue;
            }
            // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the
            // writer's queries reset by `begin`). In the body: each height texture's
            // level 0 is sampled-readable (its fill recorded before this in the same
            // command buffer, or by an earlier frame); an entry is recorded only while
            // unbuilt, so no command has used it; the pass and the entries live until
            // they are retired after the frames that use them.
            unsafe {
                w.scope(ctx, cmd, k.name(), |cmd| {
                    for map in self.maps.iter().flatten() {
                        for p in map.prepared.iter().filter(|p| p.kind == kind && !p.built) {
                            k.record(&*pass.pass, ctx, cmd, &map.texture, &*p.value)?;
                        }
                    }
                    Ok(())
                })?
            };
            for map in self.maps.iter_mut().flatten() {
                for p in map.prepared.iter_mut().filter(|p| p.kind == kind) {
                    p.built = true;
                }
            }
        }
        Ok(())
    }
}
