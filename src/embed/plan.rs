//! The pass's resources as one declarative plan: [`Plan`] is what the settings (the
//! material table, shadows, the corrected depth, the frame) need, a key per resource;
//! [`DisplacementPass::sync`] compares it with what exists, builds what differs under a
//! guard (a failure destroys what it built and leaves the pass as it was), then commits:
//! swaps in what was built and retires what the plan no longer names (destroyed once
//! every frame slot has been recorded again). Every setter is "change the settings,
//! then sync" (restoring the settings when the sync fails).
//!
//! | resource | key | built when |
//! |---|---|---|
//! | `trace` pipeline | method | a live material uses the method |
//! | pyramid / DIG corner / cone pipelines | (cone kind) | a live material needs them |
//! | height texture | map content, size, format, addressing | `add_material` / `set_material_height_map` (the upload is staged there); its mip chain follows level of detail |
//! | host height texture (views of the host's image) | image, channel, levels, size, format, addressing, contents version | `add_host_material` / `set_material_host_height_map` / `host_height_map_changed` (nothing to upload; the mip chain is the host's) |
//! | pyramid | (map, kind) | a material on the map needs it (its method, hard shadows' cell pyramid, a cone map's input) |
//! | cone map | (map, kind) | a material on the map uses a cone method |
//! | DIG corner grids | (material, block, extent) | the material is a DIG method |
//! | `shadow` pipelines, visibility images | (query), extent | self-shadowing on |
//! | corrected-depth pipeline and images | extent | the corrected depth on |
//! | motion pipeline | image format | the motion output on |
//! | tile lists | extent | always (their size follows the frame alone: adding or removing materials changes nothing) |
//! | map preparations ([`crate::passes::MAP_PREPARATIONS`]) and their pipelines | (map, kind) | the host asked for the kind ([`DisplacementPass::set_map_preparation`]) and a live material uses the map |
//!
//! What each frame in flight owns (tile lists, visibility, corrected depth, the
//! timestamp scopes it recorded last) is one [`Slot`] per frame slot.
//!
//! A new preparation pass of a map is an entry of the keyed table of map preparations:
//! its type implements [`crate::passes::prepare::MapPreparation`] (a constructor, its
//! pipeline and its record) and is listed in [`crate::passes::MAP_PREPARATIONS`]; the table
//! keys, builds, records, retires and hands out its entries (`map_preparations.rs`).

pub(super) use super::entries::{
    Built, Fill, MapEntry, MapKey, MapSource, MaterialEntry, PreparePass, Prepared, Slot,
};
use super::{DisplacementPass, HIT_DEPTH_FORMAT, ITERATIONS_FORMAT, VISIBILITY_FORMAT};
use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::{HeightTexture, Image};
use crate::method::{ConeKind, Method, PyramidKind};
use crate::passes::classify::TileLists;
use crate::passes::cone::{ConeMap, ConePass};
use crate::passes::dig::{CornerGrid, DigCornerPass};
use crate::passes::hit_depth::HitDepthPass;
use crate::passes::motion::MotionPass;
use crate::passes::prepare;
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::passes::shade::ShadePass;
use crate::passes::shadow::{ShadowPass, ShadowTrace};
use crate::passes::trace::TracePass;
use ash::vk;

/// The corrected-depth output: the `hit_depth` pipeline and one `R32_SFLOAT` image per
/// frame slot.
pub(super) struct DepthParts {
    pub pass: HitDepthPass,
    pub images: Vec<Image>,
}

impl Destroy for DepthParts {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pass.destroy(ctx);
            self.images.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.images.bytes()
    }
}

/// Swaps `new[i]` into `field(slot i)`, returning what it replaced (to retire).
fn swap_per_slot<T>(
    slots: &mut [Slot],
    new: Vec<T>,
    field: impl Fn(&mut Slot) -> &mut Option<T>,
) -> Vec<T> {
    slots
        .iter_mut()
        .zip(new)
        .filter_map(|(s, image)| field(s).replace(image))
        .collect()
}

/// What one map needs.
#[derive(Clone, Debug, Default, PartialEq)]
struct MapPlan {
    chain: bool,
    pyramids: Vec<PyramidKind>,
    cones: Vec<ConeKind>,
    /// Its map preparations (kinds).
    prepared: Vec<usize>,
}

/// What the settings need: a key per resource (module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Plan {
    /// Each trace pipeline: the method, curved, with iterations.
    methods: Vec<(Method, bool, bool)>,
    pyramid_pass: bool,
    corner_pass: bool,
    cone_kinds: Vec<ConeKind>,
    /// The kinds of map preparation with a live map to prepare.
    prepare_kinds: Vec<usize>,
    /// Per entry of the map table (`None`: no live material uses it).
    maps: Vec<Option<MapPlan>>,
    /// Per entry of the material table: the DIG block of its grids.
    corners: Vec<Option<[u32; 2]>>,
    shadow_traces: Vec<ShadowTrace>,
    shadowed_shade: bool,
    depth: bool,
    iterations: bool,
    motion: Option<vk::Format>,
    /// A live material walks the pass's meshes (the slots' walk lists).
    walk_list: bool,
}

fn push_unique<T: PartialEq>(v: &mut Vec<T>, x: T) {
    if !v.contains(&x) {
        v.push(x);
    }
}

/// What [`DisplacementPass::sync`] built, not yet committed.
#[derive(Default)]
struct Additions {
    traces: Vec<TracePass>,
    pyramid_pass: Option<PyramidPass>,
    corner_pass: Option<DigCornerPass>,
    cone_passes: Vec<ConePass>,
    prepare_passes: Vec<PreparePass>,
    shadow_passes: Vec<ShadowPass>,
    shade: Option<ShadePass>,
    textures: Vec<(usize, HeightTexture)>,
    pyramids: Vec<(usize, Pyramid)>,
    cones: Vec<(usize, ConeMap)>,
    prepared: Vec<(usize, Prepared)>,
    corners: Vec<(usize, Vec<CornerGrid>)>,
    visibility: Option<Vec<Image>>,
    iterations: Option<Vec<Image>>,
    depth: Option<DepthParts>,
    motion: Option<MotionPass>,
    tiles: Option<Vec<TileLists>>,
    walk_list: Option<Vec<crate::gpu::Buffer>>,
}

impl Destroy for Additions {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.traces.destroy(ctx);
            self.pyramid_pass.destroy(ctx);
            self.corner_pass.destroy(ctx);
            self.cone_passes.destroy(ctx);
            self.prepare_passes.destroy(ctx);
            self.shadow_passes.destroy(ctx);
            self.shade.destroy(ctx);
            for (_, t) in &mut self.textures {
                t.destroy(ctx);
            }
            for (_, p) in &mut self.pyramids {
                p.destroy(ctx);
            }
            for (_, c) in &mut self.cones {
                c.destroy(ctx);
            }
            for (_, p) in &mut self.prepared {
                p.destroy(ctx);
            }
            for (_, g) in &mut self.corners {
                g.destroy(ctx);
            }
            self.visibility.destroy(ctx);
            self.iterations.destroy(ctx);
            self.depth.destroy(ctx);
            self.motion.destroy(ctx);
            self.tiles.destroy(ctx);
            self.walk_list.destroy(ctx);
        }
    }
}

/// One value per frame slot from `make`; on a failure the ones made are destroyed.
pub(super) fn per_slot<T: Destroy>(
    ctx: &Context,
    frames: u32,
    mut make: impl FnMut(u32) -> Result<T>,
) -> Result<Vec<T>> {
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let mut made = unsafe { Guard::new(ctx, Vec::new()) };
    for s in 0..frames {
        made.push(make(s)?);
    }
    Ok(made.keep())
}

impl DisplacementPass {
    /// What the current settings need.
    pub(super) fn plan(&self) -> Plan {
        let mut plan = Plan {
            maps: vec![None; self.maps.len()],
            corners: vec![None; self.materials.len()],
            shadowed_shade: self.shadows.is_on(),
            depth: self.depth_on,
            iterations: self.iterations_on,
            motion: self.motion_on.map(|m| m.format),
            ..Plan::default()
        };
        for (i, m) in self.materials.iter().enumerate() {
            let Some(m) = m else { continue };
            let s = &m.settings;
            let needs = s.method.needs();
            push_unique(
                &mut plan.methods,
                (
                    s.method,
                    m.curved && s.method.traces_curved(),
                    self.iterations_on,
                ),
            );
            let map = plan.maps[m.map].get_or_insert_with(MapPlan::default);
            map.chain |= s.params.lod_threshold.is_some();
            if let Some(kind) = needs.pyramid {
                push_unique(&mut map.pyramids, kind);
            }
            if let Some(kind) = needs.cone {
                push_unique(&mut map.cones, kind);
                push_unique(&mut plan.cone_kinds, kind);
            }
            for &kind in &self.prepare_requested {
                push_unique(&mut map.prepared, kind);
                push_unique(&mut plan.prepare_kinds, kind);
            }
            if needs.dig_corners {
                plan.corners[i] = Some(s.params.block);
            }
            plan.walk_list |= m.curved && s.method.walks_meshes() && self.walk.triangles > 0;
            if self.shadows.is_on() {
                let trace = ShadowTrace::for_method(self.shadows.mode, s.method);
                push_unique(&mut plan.shadow_traces, trace);
                if trace == ShadowTrace::Pyramid {
                    push_unique(&mut map.pyramids, PyramidKind::Cell);
                }
            }
        }
        plan.pyramid_pass = plan.maps.iter().flatten().any(|m| !m.pyramids.is_empty());
        plan.corner_pass = plan.corners.iter().any(Option::is_some);
        plan
    }

    /// Builds what the plan needs and the pass lacks, then commits (module docs). On
    /// error nothing changed.
    pub(super) fn sync(&mut self) -> Result<()> {
        let plan = self.plan();
        let ctx = self.context()?.clone();
        let c = &*ctx;
        let extent = self.frame.extent;
        let frames = self.frame.frames_in_flight;
        let resized = self.built_extent != extent;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut add = unsafe { Guard::new(c, Additions::default()) };
        for &(m, curved, iterations) in &plan.methods {
            if !self
                .traces
                .iter()
                .any(|t| t.key() == (m, curved, iterations))
            {
                add.traces.push(TracePass::new(c, m, curved, iterations)?);
            }
        }
        if plan.pyramid_pass && self.pyramid_pass.is_none() {
            add.pyramid_pass = Some(PyramidPass::new(c)?);
        }
        if plan.corner_pass && self.corner_pass.is_none() {
            add.corner_pass = Some(DigCornerPass::new(c)?);
        }
        for &k in &plan.cone_kinds {
            if !self.cone_passes.iter().any(|p| p.kind == k) {
                add.cone_passes.push(ConePass::new(c, k)?);
            }
        }
        for &k in &plan.prepare_kinds {
            if !self.prepare_passes.iter().any(|p| p.kind == k) {
                let pass = prepare::KINDS[k].new_pass(c)?;
                add.prepare_passes.push(PreparePass { kind: k, pass });
            }
        }
        for &t in &plan.shadow_traces {
            if !self.shadow_passes.iter().any(|p| p.trace() == t) {
                add.shadow_passes.push(ShadowPass::new(c, t)?);
            }
        }
        if plan.shadowed_shade != self.shade.is_shadowed() {
            add.shade = Some(if plan.shadowed_shade {
                ShadePass::shadowed(c)?
            } else {
                ShadePass::new(c)?
            });
        }
        for (i, want) in plan.maps.iter().enumerate() {
            let (Some(want), Some(map)) = (want, &self.maps[i]) else {
                continue;
            };
            if map.texture.differs_for(c, want.chain) {
                add.textures
                    .push((i, map.texture.create_like(c, want.chain)?));
            }
            let size = map.texture.size();
            let format = map.texture.texel_format();
            for &kind in &want.pyramids {
                if !map.pyramids.iter().any(|p| p.value.kind == kind) {
                    let p = Pyramid::new(c, size, kind, map.key.addressing, format)?;
                    add.pyramids.push((i, p));
                }
            }
            for &kind in &want.cones {
                if !map.cones.iter().any(|m| m.value.kind == kind) {
                    let m = ConeMap::new(c, size, map.key.addressing, kind, format)?;
                    add.cones.push((i, m));
                }
            }
            for &kind in &want.prepared {
                if !map.prepared.iter().any(|p| p.kind == kind) {
                    let value = prepare::KINDS[kind].new_prepared(c, &map.texture)?;
                    let entry = Prepared {
                        kind,
                        value,
                        built: false,
                    };
                    add.prepared.push((i, entry));
                }
            }
        }
        for (i, want) in plan.corners.iter().enumerate() {
            let (Some(block), Some(_)) = (want, &self.materials[i]) else {
                continue;
            };
            let current = self.slots.first().and_then(|s| s.corner_grid(i));
            if resized || current.is_none_or(|g| g.block != *block) {
                let grids = per_slot(c, frames, |_| {
                    CornerGrid::new(c, [extent.width, extent.height], *block)
                })?;
                add.corners.push((i, grids));
            }
        }
        if plan.shadowed_shade && (resized || self.slots.iter().all(|s| s.visibility.is_none())) {
            add.visibility = Some(per_slot(c, frames, |s| {
                Image::new(
                    c,
                    &format!("embed.visibility{s}"),
                    VISIBILITY_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
                )
            })?);
        }
        if plan.iterations && (resized || self.slots.iter().all(|s| s.iterations.is_none())) {
            add.iterations = Some(per_slot(c, frames, |s| {
                Image::new(
                    c,
                    &format!("embed.iterations{s}"),
                    ITERATIONS_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE
                        | vk::ImageUsageFlags::TRANSFER_SRC
                        | vk::ImageUsageFlags::TRANSFER_DST,
                )
            })?);
        }
        if plan.depth && (resized || self.depth.is_none()) {
            // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
            let pass = unsafe { Guard::new(c, HitDepthPass::new(c)?) };
            let images = per_slot(c, frames, |s| {
                Image::new(
                    c,
                    &format!("embed.hit_depth{s}"),
                    HIT_DEPTH_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE
                        | vk::ImageUsageFlags::SAMPLED
                        | vk::ImageUsageFlags::TRANSFER_SRC
                        | vk::ImageUsageFlags::TRANSFER_DST,
                )
            })?;
            add.depth = Some(DepthParts {
                pass: pass.keep(),
                images,
            });
        }
        if let Some(format) = plan.motion
            && self.motion.as_ref().is_none_or(|m| m.format != format)
        {
            add.motion = Some(MotionPass::new(c, format)?);
        }
        if resized || self.slots.is_empty() {
            add.tiles = Some(per_slot(c, frames, |s| {
                TileLists::new(c, &format!("embed.tiles{s}"), extent)
            })?);
        }
        if plan.walk_list && (resized || self.slots.iter().all(|s| s.walk_list.is_none())) {
            add.walk_list = Some(per_slot(c, frames, |s| {
                crate::gpu::Buffer::new(
                    c,
                    &format!("embed.walk_list{s}"),
                    crate::passes::trace::walk_list_bytes(extent),
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::INDIRECT_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_DST,
                    gpu_allocator::MemoryLocation::GpuOnly,
                )
            })?);
        }
        let add = add.keep();
        self.commit(&plan, add);
        Ok(())
    }

    /// Swaps in what was built and retires what the plan no longer names.
    fn commit(&mut self, plan: &Plan, add: Additions) {
        let retired = &mut self.retired;
        self.traces.extend(add.traces);
        let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut self.traces)
            .into_iter()
            .partition(|t| plan.methods.contains(&t.key()));
        self.traces = keep;
        retired.retire(drop);
        if let Some(p) = add.pyramid_pass {
            self.pyramid_pass = Some(p);
        }
        if !plan.pyramid_pass {
            retired.retire(self.pyramid_pass.take());
        }
        if let Some(p) = add.corner_pass {
            self.corner_pass = Some(p);
        }
        if !plan.corner_pass {
            retired.retire(self.corner_pass.take());
        }
        self.cone_passes.extend(add.cone_passes);
        let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut self.cone_passes)
            .into_iter()
            .partition(|p| plan.cone_kinds.contains(&p.kind));
        self.cone_passes = keep;
        retired.retire(drop);
        self.prepare_passes.extend(add.prepare_passes);
        let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut self.prepare_passes)
            .into_iter()
            .partition(|p| plan.prepare_kinds.contains(&p.kind));
        self.prepare_passes = keep;
        retired.retire(drop);
        self.shadow_passes.extend(add.shadow_passes);
        let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut self.shadow_passes)
            .into_iter()
            .partition(|p| plan.shadow_traces.contains(&p.trace()));
        self.shadow_passes = keep;
        retired.retire(drop);
        if let Some(shade) = add.shade {
            retired.retire(std::mem::replace(&mut self.shade, shade));
        }
        for (i, texture) in add.textures {
            let Some(map) = &mut self.maps[i] else {
                continue;
            };
            // The mip chain follows level of detail; level 0 (the map) is unchanged.
            let old = std::mem::replace(&mut map.texture, texture);
            if map.pending_fill.is_some() {
                // `old` was never filled (its fill is still pending and now fills the
                // new texture): no frame reads it.
                retired.retire(old);
            } else {
                map.pending_fill = Some(Fill::Copy(old));
            }
        }
        for (i, p) in add.pyramids {
            if let Some(map) = &mut self.maps[i] {
                map.pyramids.push(Built {
                    value: p,
                    built: false,
                });
            }
        }
        for (i, m) in add.cones {
            if let Some(map) = &mut self.maps[i] {
                map.cones.push(Built {
                    value: m,
                    built: false,
                });
            }
        }
        for (i, p) in add.prepared {
            if let Some(map) = &mut self.maps[i] {
                map.prepared.push(p);
            }
        }
        for (i, want) in plan.maps.iter().enumerate() {
            match want {
                None => retired.retire(self.maps[i].take()),
                Some(want) => {
                    let Some(map) = &mut self.maps[i] else {
                        continue;
                    };
                    let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut map.pyramids)
                        .into_iter()
                        .partition(|p| want.pyramids.contains(&p.value.kind));
                    map.pyramids = keep;
                    retired.retire(drop);
                    let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut map.cones)
                        .into_iter()
                        .partition(|c| want.cones.contains(&c.value.kind));
                    map.cones = keep;
                    retired.retire(drop);
                    let (keep, drop): (Vec<_>, Vec<_>) = std::mem::take(&mut map.prepared)
                        .into_iter()
                        .partition(|p| want.prepared.contains(&p.kind));
                    map.prepared = keep;
                    retired.retire(drop);
                }
            }
        }
        // The tile lists first: the first sync makes the slots with them.
        if let Some(tiles) = add.tiles {
            if self.slots.is_empty() {
                self.slots = tiles
                    .into_iter()
                    .map(|tiles| Slot {
                        tiles,
                        visibility: None,
                        hit_depth: None,
                        corners: Vec::new(),
                        iterations: None,
                        walk_list: None,
                        scopes: Vec::new(),
                    })
                    .collect();
            } else {
                let old: Vec<TileLists> = self
                    .slots
                    .iter_mut()
                    .zip(tiles)
                    .map(|(s, t)| std::mem::replace(&mut s.tiles, t))
                    .collect();
                retired.retire(old);
            }
        }
        // The corner grids after the slots: each slot's of material `i` at its index.
        for (i, grids) in add.corners {
            for (s, grid) in self.slots.iter_mut().zip(grids) {
                if s.corners.len() <= i {
                    s.corners.resize_with(i + 1, || None);
                }
                retired.retire(s.corners[i].replace(grid));
            }
        }
        for s in &mut self.slots {
            for (i, grid) in s.corners.iter_mut().enumerate() {
                if plan.corners.get(i).is_none_or(Option::is_none) {
                    retired.retire(grid.take());
                }
            }
        }
        if let Some(v) = add.visibility {
            retired.retire(swap_per_slot(&mut self.slots, v, |s| &mut s.visibility));
        }
        if !plan.shadowed_shade {
            let old: Vec<Image> = self
                .slots
                .iter_mut()
                .filter_map(|s| s.visibility.take())
                .collect();
            retired.retire(old);
        }
        if let Some(l) = add.walk_list {
            retired.retire(swap_per_slot(&mut self.slots, l, |s| &mut s.walk_list));
        }
        if !plan.walk_list {
            let old: Vec<crate::gpu::Buffer> = self
                .slots
                .iter_mut()
                .filter_map(|s| s.walk_list.take())
                .collect();
            retired.retire(old);
        }
        if let Some(i) = add.iterations {
            retired.retire(swap_per_slot(&mut self.slots, i, |s| &mut s.iterations));
        }
        if !plan.iterations {
            let old: Vec<Image> = self
                .slots
                .iter_mut()
                .filter_map(|s| s.iterations.take())
                .collect();
            retired.retire(old);
        }
        if let Some(d) = add.depth {
            retired.retire(self.depth.replace(d.pass));
            retired.retire(swap_per_slot(&mut self.slots, d.images, |s| {
                &mut s.hit_depth
            }));
        }
        if !plan.depth {
            retired.retire(self.depth.take());
            let old: Vec<Image> = self
                .slots
                .iter_mut()
                .filter_map(|s| s.hit_depth.take())
                .collect();
            retired.retire(old);
        }
        if let Some(m) = add.motion {
            retired.retire(self.motion.replace(m));
        }
        if plan.motion.is_none() {
            retired.retire(self.motion.take());
        }
        self.built_extent = self.frame.extent;
    }
}
