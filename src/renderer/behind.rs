//! The behind layer of a frame of several objects: what a pixel whose displaced ray missed
//! shows (the next surface along its view ray instead of the sky). After the frame's
//! first record, the renderer marks the 8x8 tiles holding a missed pixel and culls the
//! layer's draws to them ([`crate::passes::behind_tiles`], on the GPU: each mesh drawn
//! as its clusters, [`super::behind_draws`], a cluster only where its screen rectangle
//! meets a missed tile in front of it, for a one-sided convex displaced mesh only a tile
//! where another material's pixels missed; one multi-draw command per mesh where the device
//! has `multiDrawIndirect`), rasterises the kept clusters into a second G-buffer (on
//! the listed route only its listed tiles cleared, [`crate::passes::behind_open`]; the
//! rest of its depth blocks them), keeping a fragment only at a pixel whose first-layer
//! trace missed and only behind the first layer's surface
//! (`glsl/include/dispmap_behind.glsl`; the plane's
//! shader tests the pixel first; with [`Renderer::set_behind_mask`], a depth mask of the
//! missed pixels, [`crate::passes::behind_mask`], rejects the meshes' fragments elsewhere
//! before they are shaded), lights that layer's flat geometry in the missed tiles, and
//! records the displacement pass a second time on it: frame slot 1, its own hit images
//! (cleared to no hit, then classified over the missed tiles only), the same colour image
//! (and motion image). The second trace and shade run only over the tiles that layer
//! covers. docs/embedding.md, "What a miss shows", is the same route for a host.

use super::behind_draws::{Cluster, coarsen, mesh_sources, whole_frame};
use super::*;
use crate::gpu::track::{Target, Tracker};
use crate::passes::behind_tiles::{BehindTiles, DRAW_STRIDE, DrawSource, MAX_DRAWS};
use crate::passes::gbuffer::{FirstLayer, IndirectDraws};

/// The behind layer's buffer accesses ([`BehindTiles`], the first layer's tile lists).
const BUFFER_WRITE: Access = Access {
    layout: vk::ImageLayout::UNDEFINED,
    ..Access::BUFFER_TRANSFER_WRITE
};
const COMPUTE_BUFFER_READ_WRITE: Access = Access {
    layout: vk::ImageLayout::UNDEFINED,
    ..Access::COMPUTE_STORAGE_READ_WRITE
};
const COMPUTE_BUFFER_WRITTEN: Access = Access {
    layout: vk::ImageLayout::UNDEFINED,
    ..Access::COMPUTE_STORAGE_WRITE
};

/// [`Access::INDIRECT_READ`] and reads by the vertex stage (the listed tiles' draw,
/// [`crate::passes::behind_open`]).
const INDIRECT_AND_VERTEX_READ: Access = Access {
    stage: vk::PipelineStageFlags2::from_raw(
        Access::INDIRECT_READ.stage.as_raw() | vk::PipelineStageFlags2::VERTEX_SHADER.as_raw(),
    ),
    ..Access::INDIRECT_READ
};

/// The frame slot of the pass the behind layer is recorded with (the first layer's is 0).
pub(super) const BEHIND_SLOT: u32 = 1;

/// Timestamp queries of the behind layer's one scope, after the pass's.
pub(super) const BEHIND_QUERIES: u32 = 2;

/// The behind layer's images and pipelines.
pub(super) struct Behind {
    /// Its G-buffer (the first layer's formats).
    gbuffer: GBuffer,
    /// Its hit images.
    hit: Hits,
    /// The behind variants of the pipelines the objects are drawn with: the tiled
    /// plane's, the meshes', the two-sided meshes' (each only when an object needs it).
    plane: Option<GBufferPass>,
    mesh: Option<GBufferPass>,
    two_sided: Option<GBufferPass>,
    /// The host's light of the layer's flat geometry (the sky is left as it is).
    background: BackgroundPass,
    /// The mask keeping the layer's raster to the missed pixels, when asked for
    /// ([`Renderer::set_behind_mask`]).
    mask: Option<crate::passes::behind_mask::BehindMaskPass>,
    /// Per draw of the layer (the objects' order) its clusters (`None`: the tiled plane,
    /// one piece), at most [`MAX_DRAWS`] pieces in all.
    clusters: Vec<Option<Vec<Cluster>>>,
    /// The missed tiles and the pieces' commands (built by the first record, and again
    /// for a new frame size).
    tiles: Option<BehindTiles>,
    /// Whether the layer's second record is classified over the missed tiles only (its
    /// hit images cleared first) or over the whole frame ([`Renderer::set_behind_listed`]).
    listed: bool,
    /// On the listed route, the pipeline that opens the listed tiles of the layer's
    /// raster ([`crate::passes::behind_open`]; built by the first listed record, again
    /// when the curve image comes or goes).
    open: Option<crate::passes::behind_open::BehindOpenPass>,
}

impl Destroy for Behind {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.gbuffer.destroy(ctx);
            self.hit.destroy(ctx);
            self.plane.destroy(ctx);
            self.mesh.destroy(ctx);
            self.two_sided.destroy(ctx);
            self.background.destroy(ctx);
            self.mask.destroy(ctx);
            self.tiles.destroy(ctx);
            self.open.destroy(ctx);
        }
    }
}

/// The resources whose barriers the behind layer's tracker derives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layer {
    FirstHitHeight,
    FirstDepth,
    FirstFrame,
    Ray,
    Frame,
    Depth,
    /// The layer's curve image (a frame with meshes).
    Curve,
    HitUv,
    HitHeight,
    Color,
    Motion,
    /// The missed tiles' buffer.
    Tiles,
    /// The first layer's tile lists and their arguments.
    FirstTiles,
}

impl Behind {
    /// The layer's images for `extent` and the pipelines of `objects`' kinds: the tiled
    /// plane (`plane`), one-sided and two-sided meshes, with the curve image (`curve`) and
    /// the mesh pipelines' twins that leave it uncomputed (`zero_curve`,
    /// [`GBufferPass::new_layer_with`]).
    /// `clusters`: per object its mesh's clusters (`None`: the tiled plane).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        c: &Context,
        extent: vk::Extent2D,
        plane: bool,
        mesh: bool,
        two_sided: bool,
        curve: bool,
        zero_curve: bool,
        clusters: Vec<Option<Vec<Cluster>>>,
    ) -> Result<Self> {
        let (gbuffer, hit) = layer_images(c, extent, curve)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let background = unsafe { Guard::new(c, BackgroundPass::new_behind(c)?) };
        let pipeline = |on: bool, mesh: bool, two_sided: bool| -> Result<Option<GBufferPass>> {
            on.then(|| GBufferPass::new_layer_with(c, mesh, two_sided, true, curve, zero_curve))
                .transpose()
        };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let plane = unsafe { Guard::new(c, pipeline(plane, false, false)?) };
        // SAFETY: as above.
        let mesh = unsafe { Guard::new(c, pipeline(mesh, true, false)?) };
        // SAFETY: as above.
        let two_sided = unsafe { Guard::new(c, pipeline(two_sided, true, true)?) };
        Ok(Behind {
            gbuffer: gbuffer.keep(),
            hit: hit.keep(),
            plane: plane.keep(),
            mesh: mesh.keep(),
            two_sided: two_sided.keep(),
            background: background.keep(),
            mask: None,
            listed: c.info().device_type == format!("{:?}", vk::PhysicalDeviceType::CPU),
            clusters: within_draws(clusters),
            tiles: None,
            open: None,
        })
    }

    /// Rebuilds the layer's G-buffer of `extent` and its pipelines (the mask's too, when it
    /// has one) with or without the curve image (`curve`: the first layer's,
    /// [`Renderer::set_curved`]; `zero_curve`: the mesh pipelines' twins that leave it
    /// uncomputed, [`GBufferPass::new_layer_with`]); the hit images and the background
    /// stay. On error the layer is unchanged.
    ///
    /// # Safety
    /// No pending GPU work uses the layer (the renderer waits for every frame).
    pub(super) unsafe fn set_curve(
        &mut self,
        c: &Context,
        extent: vk::Extent2D,
        curve: bool,
        zero_curve: bool,
    ) -> Result<()> {
        let gbuffer = if curve {
            GBuffer::new_curved(c, extent)?
        } else {
            GBuffer::new(c, extent)?
        };
        // SAFETY: no command has used the guarded values yet; they are kept below.
        let gbuffer = unsafe { Guard::new(c, gbuffer) };
        let pipeline = |old: &Option<GBufferPass>| -> Result<Option<GBufferPass>> {
            old.as_ref()
                .map(|p| {
                    GBufferPass::new_layer_with(
                        c,
                        p.is_mesh(),
                        p.is_two_sided(),
                        true,
                        curve,
                        zero_curve,
                    )
                })
                .transpose()
        };
        // SAFETY: as above.
        let plane = unsafe { Guard::new(c, pipeline(&self.plane)?) };
        // SAFETY: as above.
        let mesh = unsafe { Guard::new(c, pipeline(&self.mesh)?) };
        // SAFETY: as above.
        let two_sided = unsafe { Guard::new(c, pipeline(&self.two_sided)?) };
        let mask = self
            .mask
            .as_ref()
            .map(|_| crate::passes::behind_mask::BehindMaskPass::new(c, curve))
            .transpose()?;
        // SAFETY: as above.
        let mask = unsafe { Guard::new(c, mask) };
        let mut old = (
            std::mem::replace(&mut self.gbuffer, gbuffer.keep()),
            std::mem::replace(&mut self.plane, plane.keep()),
            std::mem::replace(&mut self.mesh, mesh.keep()),
            std::mem::replace(&mut self.two_sided, two_sided.keep()),
            std::mem::replace(&mut self.mask, mask.keep()),
        );
        // SAFETY: this function's contract: nothing pending uses the old objects.
        unsafe {
            old.0.destroy(c);
            old.1.destroy(c);
            old.2.destroy(c);
            old.3.destroy(c);
            old.4.destroy(c);
        }
        Ok(())
    }

    /// New images of `extent` (the caller swaps them in with [`Behind::swap_images`]).
    pub(super) fn images<'c>(
        c: &'c Context,
        extent: vk::Extent2D,
        curve: bool,
    ) -> Result<(Guard<'c, GBuffer>, Guard<'c, Hits>)> {
        layer_images(c, extent, curve)
    }

    /// Swaps in `images`, returning the old ones (to destroy once no frame uses them).
    pub(super) fn swap_images(&mut self, images: (GBuffer, Hits)) -> (GBuffer, Hits) {
        (
            std::mem::replace(&mut self.gbuffer, images.0),
            std::mem::replace(&mut self.hit, images.1),
        )
    }

    /// The behind pipeline of a first-layer draw's pipeline.
    fn pass_of(&self, mesh: bool, two_sided: bool) -> Result<&GBufferPass> {
        let p = match (mesh, two_sided) {
            (false, _) => &self.plane,
            (true, false) => &self.mesh,
            (true, true) => &self.two_sided,
        };
        p.as_ref()
            .ok_or_else(|| Error::Internal("no behind pipeline for an object's kind".into()))
    }
}

/// `clusters` merged (consecutive ones of a mesh) until all the draws' pieces number at
/// most [`MAX_DRAWS`].
fn within_draws(clusters: Vec<Option<Vec<Cluster>>>) -> Vec<Option<Vec<Cluster>>> {
    let pieces = |c: &[Option<Vec<Cluster>>]| -> usize {
        c.iter()
            .map(|c| c.as_ref().map_or(1, |c| c.len().max(1)))
            .sum()
    };
    let mut factor = 1;
    let mut out = clusters.clone();
    while pieces(&out) > MAX_DRAWS as usize {
        factor *= 2;
        out = clusters
            .iter()
            .map(|c| c.as_ref().map(|c| coarsen(c, factor)))
            .collect();
    }
    out
}

/// The layer's G-buffer and hit images, guarded until the caller keeps them.
fn layer_images(
    c: &Context,
    extent: vk::Extent2D,
    curve: bool,
) -> Result<(Guard<'_, GBuffer>, Guard<'_, Hits>)> {
    let gbuffer = if curve {
        GBuffer::new_curved(c, extent)?
    } else {
        GBuffer::new(c, extent)?
    };
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let gbuffer = unsafe { Guard::new(c, gbuffer) };
    // SAFETY: as above.
    let hit = unsafe {
        Guard::new(
            c,
            Hits::new(c, "behind.hits", extent, vk::ImageUsageFlags::TRANSFER_DST)?,
        )
    };
    Ok((gbuffer, hit))
}

impl Renderer {
    /// Whether frames draw the behind layer (see [`Renderer::set_behind`]).
    pub fn behind(&self) -> bool {
        self.behind.is_some() || self.behind_empty
    }

    /// Whether the behind layer is on but drawn empty: the frame's one object is a
    /// one-sided convex mesh (the generated cube or sphere), behind whose misses nothing
    /// can show, so frames neither allocate nor record the layer
    /// ([`Renderer::set_behind_convex_skip`]).
    pub fn behind_empty(&self) -> bool {
        self.behind_empty
    }

    /// Turns the behind layer on or off: with it, a pixel whose displaced ray misses (a
    /// clamp-addressed ray that leaves its decal, a curved ray that leaves its shell)
    /// shows the next surface along its view ray (the floor under a cube's carved bottom
    /// edge, a torus's far side behind the carved top of its near tube) instead of the
    /// sky. A renderer of several objects ([`Renderer::with_objects`]) draws it from the
    /// start when an object can miss (a displaced mesh or a clamp-addressed object); a
    /// mesh drawn alone ([`Renderer::with_assets`]) can have it (a non-convex mesh shows
    /// itself behind a curved miss) but starts without it; for a one-sided convex mesh
    /// alone the layer is on but empty ([`Renderer::behind_empty`]: nothing of a convex
    /// mesh lies behind its own surface); the tiled plane and the quad alone have nothing
    /// behind them. Turning it on is refused for a renderer not built with it (its pass
    /// has one frame slot).
    pub fn set_behind(&mut self, on: bool) -> Result<()> {
        let c = &*self.ctx;
        if on && !self.behind() && self.pass.settings().frames_in_flight <= BEHIND_SLOT {
            return Err(Error::invalid(
                "behind",
                "this renderer was built without a behind layer (the tiled plane or the \
                 quad alone, or objects that cannot miss)",
            ));
        }
        let empty = on && self.objects.is_none() && self.convex_alone && self.convex_skip;
        self.behind_empty = empty;
        match (on && !empty, &self.behind) {
            (true, None) => {
                let (plane, mesh, two_sided) = match (&self.objects, &self.mesh) {
                    (Some(o), _) => (
                        o.meshes.iter().any(Option::is_none),
                        o.mesh_pass.is_some(),
                        o.two_sided_pass.is_some(),
                    ),
                    (None, Some(m)) => (false, !m.two_sided, m.two_sided),
                    (None, None) => (false, false, false),
                };
                let clusters = match &self.objects {
                    Some(o) => o
                        .meshes
                        .iter()
                        .zip(&o.clusters)
                        .map(|(m, c)| m.as_ref().map(|_| c.clone()))
                        .collect(),
                    None => vec![Some(self.mesh_clusters.clone())],
                };
                self.behind = Some(Behind::new(
                    c,
                    self.settings.extent(),
                    plane,
                    mesh,
                    two_sided,
                    self.gbuffer.curve.is_some(),
                    self.gbuffer.curve.is_some() && self.draws_skip_curve()?,
                    clusters,
                )?);
            }
            (false, Some(_)) => {
                // SAFETY: every frame of this renderer was waited for (`render` submits and waits).
                unsafe { self.behind.destroy(c) };
            }
            _ => {}
        }
        Ok(())
    }

    /// Whether a one-sided convex mesh drawn alone has its behind layer drawn empty (`on`,
    /// the default: [`Renderer::behind_empty`]) or drawn as any mesh's, every object
    /// rasterised again and traced where it lies behind a miss (`off`: the same images
    /// bit for bit, at the layer's cost; for measuring and testing the skip). In a frame
    /// of several objects, `on` also spares each one-sided convex displaced mesh whose
    /// material no other object has the tiles where only its own pixels missed (its
    /// pieces are culled there; `off`: drawn and rejected fragment by fragment, the same
    /// images). Takes effect at once when the layer is on.
    pub fn set_behind_convex_skip(&mut self, on: bool) -> Result<()> {
        self.convex_skip = on;
        if self.behind() {
            self.set_behind(true)?;
        }
        Ok(())
    }

    /// Whether the behind layer's second record is classified over its missed tiles only
    /// ([`Renderer::set_behind_listed`]; `false` without a drawn layer).
    pub fn behind_listed(&self) -> bool {
        self.behind.as_ref().is_some_and(|b| b.listed)
    }

    /// Classifies the behind layer's second record over the missed tiles only, its hit
    /// images cleared to no hit first (`on`), or over the whole frame as the first
    /// layer's is (`off`). The images are the same bit for bit either way; the cost is
    /// not. The default follows the device: on for a CPU driver, where a full-frame
    /// `classify` is milliseconds (lavapipe at 640x360, the materials scene: the listed
    /// layer 2.0-2.7 ms, BENCHMARKS.md run V), off for a GPU, where it is tens of
    /// microseconds and the two transfer clears of the hit images are not (an NVIDIA H100
    /// at 1920x1080: 0.47 ms; BENCHMARKS.md, run N). Listed, the layer's raster also
    /// clears only its depth (to 1, blocking every pixel) and then opens the listed tiles
    /// (`glsl/behind_open.vert`): its objects' fragments elsewhere fail the early
    /// depth test, and its colour attachments are never cleared whole.
    /// Refused without a drawn behind layer ([`Renderer::set_behind`]).
    pub fn set_behind_listed(&mut self, on: bool) -> Result<()> {
        let Some(b) = &mut self.behind else {
            return Err(Error::invalid(
                "behind listed",
                "this renderer draws no behind layer (turn it on with set_behind first; a \
                 convex mesh alone draws it empty)",
            ));
        };
        b.listed = on;
        Ok(())
    }

    /// Whether the behind layer's raster is masked ([`Renderer::set_behind_mask`]).
    pub fn behind_mask(&self) -> bool {
        self.behind.as_ref().is_some_and(|b| b.mask.is_some())
    }

    /// Keeps the behind layer's raster to the missed pixels with a depth mask
    /// ([`crate::passes::behind_mask`]: one full-screen triangle before the objects blocks
    /// every other pixel, one after them clears those pixels again) or draws it unmasked
    /// (the default), each fragment then discarded by the behind shader after two texel
    /// reads. The images are the same bit for bit either way (the draws culled to the
    /// missed tiles either way). The mask trades two full-screen fragment passes for the
    /// objects' fragments at the pixels that did not miss: measured with every draw whole
    /// (before the culling), it saved nothing on lavapipe (whose raster was bound by
    /// geometry) and made the layer 2.3x as slow on an NVIDIA H200 (1.41 -> 3.25 ms at
    /// 1920x1080, a part with little graphics hardware); BENCHMARKS.md has the figures. Refused without a
    /// drawn behind layer ([`Renderer::set_behind`]; an empty one has no raster to mask).
    pub fn set_behind_mask(&mut self, on: bool) -> Result<()> {
        let c = &*self.ctx;
        let Some(b) = &mut self.behind else {
            return Err(Error::invalid(
                "behind mask",
                "this renderer draws no behind layer (turn it on with set_behind first; a \
                 convex mesh alone draws it empty)",
            ));
        };
        match (on, &b.mask) {
            (true, None) => {
                b.mask = Some(crate::passes::behind_mask::BehindMaskPass::new(
                    c,
                    b.gbuffer.curve.is_some(),
                )?)
            }
            // SAFETY: every frame of this renderer was waited for (`render` submits and waits).
            (false, Some(_)) => unsafe { b.mask.destroy(c) },
            _ => {}
        }
        Ok(())
    }

    /// The last frame's behind-layer hits (`None` without the layer): `NO_HIT_HEIGHT`
    /// where the layer has no geometry (every pixel whose first-layer trace hit, every
    /// pixel of an empty layer); the iteration counts are the pass's of its frame slot 1
    /// (0 in an empty layer).
    pub fn read_behind_hits(&self) -> Result<Option<Vec<HitTexel>>> {
        if self.behind_empty {
            let e = self.settings.extent();
            let none = [0.0, 0.0, crate::abi::NO_HIT_HEIGHT, 0.0];
            return Ok(Some(vec![none; (e.width * e.height) as usize]));
        }
        let Some(b) = &self.behind else {
            return Ok(None);
        };
        let iterations = self
            .pass
            .iterations(BEHIND_SLOT)
            .map(|i| (i, Access::COMPUTE_STORAGE_WRITE));
        self.read_layer_hits(&b.hit, iterations, Access::COMPUTE_STORAGE_READ)
            .map(Some)
    }

    /// Each pixel's material index in the last frame's behind layer (`None` without the
    /// layer; inside, `None` where it has no geometry or flat geometry), as
    /// [`Renderer::read_materials`] reads the first layer's.
    pub fn read_behind_materials(&self) -> Result<Option<Vec<Option<u32>>>> {
        if self.behind_empty {
            let e = self.settings.extent();
            return Ok(Some(vec![None; (e.width * e.height) as usize]));
        }
        let Some(b) = &self.behind else {
            return Ok(None);
        };
        let frame = read_image(
            &self.ctx,
            &self.shot,
            &b.gbuffer.frame,
            Access::COMPUTE_SAMPLED,
        )?;
        let depth = read_image(
            &self.ctx,
            &self.shot,
            &b.gbuffer.depth,
            Access::COMPUTE_SAMPLED,
        )?;
        let depth: &[f32] = bytemuck::cast_slice(&depth);
        Ok(Some(
            frame
                .chunks_exact(8)
                .zip(depth)
                .map(|(c, &d)| {
                    let word = |i: usize| u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
                    let f = crate::passes::gbuffer::frame::unpack([word(0), word(4)]);
                    // Depth 0: no geometry; the listed route's blocked depth: outside
                    // its listed tiles (the colours there undefined).
                    let geometry = d > 0.0 && d < crate::passes::behind_mask::BLOCK_DEPTH;
                    (geometry && f.material_plus_one >= 1).then(|| f.material_plus_one - 1)
                })
                .collect(),
        ))
    }

    /// Per draw of the behind layer (`draws` of them), the materials whose misses it
    /// cannot show ([`DrawSource::own`]): a one-sided convex displaced mesh's own material
    /// where no other object has it (nothing of a convex mesh lies behind its own
    /// surface, and its back faces are culled), unless
    /// [`Renderer::set_behind_convex_skip`] turned the skip off; else none.
    fn own_misses(&self, draws: usize) -> Vec<u32> {
        let Some(objects) = self.objects.as_ref().filter(|_| self.convex_skip) else {
            return vec![0; draws];
        };
        let materials: Vec<Option<u32>> = objects
            .materials
            .iter()
            .map(|m| m.map(MaterialId::index))
            .collect();
        let mut own = super::behind_draws::own_bits(&materials, &objects.convex);
        own.resize(draws, 0);
        own
    }

    /// Records the behind layer after the frame's first record, in one timestamp scope
    /// ([`PassName::Behind`]) of the renderer's pool: the layer's raster, its flat
    /// geometry's light, and the pass's second record (slot [`BEHIND_SLOT`], its own hit
    /// images, the same colour and motion images); `None` without the layer.
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue and is submitted
    /// (and waited for) while the renderer lives, after the frame's first record in the
    /// same command buffer (which left the hit images, colour and motion images in the
    /// pass's exit states and the G-buffer depth sampled-readable by compute); the
    /// layer's images' previous frame was waited for.
    pub(super) unsafe fn record_behind(
        &mut self,
        cmd: vk::CommandBuffer,
        camera: &crate::scene::FrameCamera,
        target: &ShadeTarget,
        motion: Option<crate::passes::motion::FrameMotion>,
    ) -> Result<Option<ScopeWriter>> {
        let Some(behind) = &self.behind else {
            return Ok(None);
        };
        let ctx = self.ctx.clone();
        let extent = self.settings.extent();
        // Each draw's pieces this frame: a mesh's clusters, each with its screen rectangle;
        // the tiled plane whole.
        let params: Vec<crate::abi::GBufferParams> = match (&self.objects, &self.mesh) {
            (Some(_), _) => self
                .object_draws(camera)?
                .unwrap_or_default()
                .iter()
                .map(|d| d.params)
                .collect(),
            (None, Some(_)) => vec![self.settings.scene.gbuffer_params(camera)],
            (None, None) => return Ok(None),
        };
        if params.len() != behind.clusters.len() {
            return Err(Error::Internal(
                "the behind layer's clusters do not match its draws".into(),
            ));
        }
        let own = self.own_misses(params.len());
        let mut sources = Vec::new();
        let mut ranges = Vec::new();
        for ((p, clusters), &own) in params.iter().zip(&behind.clusters).zip(&own) {
            let start = sources.len() as u32;
            match clusters {
                Some(c) => sources.extend(mesh_sources(
                    c,
                    p.view_proj,
                    p.camera_pos.truncate(),
                    extent,
                    own,
                )),
                None => sources.push(DrawSource {
                    rect: whole_frame(extent),
                    count: p.vertex_count(),
                    first: 0,
                    depth: 0.0,
                    own,
                }),
            }
            ranges.push((start, sources.len() as u32 - start));
        }
        let pieces = sources.len() as u32;
        if !behind
            .tiles
            .as_ref()
            .is_some_and(|t| t.fits(extent, pieces))
        {
            let tiles = BehindTiles::new(&ctx, extent, pieces)?;
            if let Some(b) = &mut self.behind
                && let Some(mut old) = b.tiles.replace(tiles)
            {
                // SAFETY: this function's contract: the layer's previous frame was waited
                // for, the last user of the old buffer.
                unsafe { old.destroy(&ctx) };
            }
        }
        // The listed route opens the listed tiles with a pipeline of the layer's attachments.
        if let Some(b) = &mut self.behind
            && b.listed
            && b.open
                .as_ref()
                .is_none_or(|o| o.has_curve() != b.gbuffer.curve.is_some())
        {
            let open =
                crate::passes::behind_open::BehindOpenPass::new(&ctx, b.gbuffer.curve.is_some())?;
            if let Some(mut old) = b.open.replace(open) {
                // SAFETY: this function's contract: the layer's previous frame was waited
                // for, the last user of the old pipeline.
                unsafe { old.destroy(&ctx) };
            }
        }
        let Some(behind) = &self.behind else {
            return Ok(None);
        };
        let Some(tiles) = &behind.tiles else {
            return Err(Error::Internal("no behind tiles".into()));
        };
        // The first layer's live materials' tiles (slot 0's lists, just written).
        let first_tiles = self.pass.live_tiles(0);
        // The first layer's draws (their push constants), each drawn again with the behind
        // variant of its pipeline.
        // A mesh drawn alone: its one draw.
        let draws = match (&self.objects, &self.mesh) {
            (Some(objects), _) => {
                let kinds: Vec<_> = self
                    .object_draws(camera)?
                    .unwrap_or_default()
                    .iter()
                    .map(|d| (d.params, d.pass.is_mesh(), d.pass.is_two_sided(), d.curve))
                    .collect();
                kinds
                    .into_iter()
                    .zip(&objects.meshes)
                    .map(|((params, mesh, two_sided, curve), buffers)| {
                        Ok(GBufferDraw {
                            pass: behind.pass_of(mesh, two_sided)?,
                            params,
                            mesh: buffers.as_ref(),
                            curve,
                        })
                    })
                    .collect::<Result<Vec<_>>>()?
            }
            (None, Some(mesh)) => vec![GBufferDraw {
                pass: behind.pass_of(true, mesh.two_sided)?,
                params: self.settings.scene.gbuffer_params(camera),
                mesh: Some(mesh),
                curve: true,
            }],
            (None, None) => return Ok(None),
        };
        let images = |key: Layer| -> Target {
            let image = match key {
                Layer::FirstHitHeight => &self.hit.height,
                Layer::FirstDepth => &self.gbuffer.depth,
                Layer::FirstFrame => &self.gbuffer.frame,
                Layer::Ray => &behind.gbuffer.ray,
                Layer::Frame => &behind.gbuffer.frame,
                Layer::Depth => &behind.gbuffer.depth,
                Layer::Curve => match &behind.gbuffer.curve {
                    Some(c) => c,
                    None => return Target::Memory,
                },
                Layer::HitUv => &behind.hit.uv,
                Layer::HitHeight => &behind.hit.height,
                Layer::Color => &self.color,
                Layer::Motion | Layer::Tiles | Layer::FirstTiles => return Target::Memory,
            };
            Target::Image(image.raw, image.range())
        };
        let mut t = Tracker::new();
        // The first record's exit states (the pass's module docs): the hit height, colour
        // and motion last written by compute-shader storage writes; the G-buffer depth and
        // frame sampled by compute (the renderer's entry barrier made their writes visible
        // there).
        for (key, written) in [
            (Layer::FirstHitHeight, true),
            (Layer::Color, true),
            (Layer::Motion, motion.is_some()),
        ] {
            if written {
                t.enter(key, Access::COMPUTE_STORAGE_WRITE);
                t.declare(key, Access::COMPUTE_STORAGE_WRITE)?;
            }
        }
        if !t.resolve()?.is_empty() {
            return Err(Error::Internal(
                "a written entry state needed a barrier".into(),
            ));
        }
        t.enter(Layer::FirstDepth, Access::COMPUTE_SAMPLED);
        t.enter(Layer::FirstFrame, Access::COMPUTE_SAMPLED);
        // The lists, last written by the first record's classify; the missed tiles' buffer
        // last read by the layer's previous frame (waited for).
        t.enter(Layer::FirstTiles, COMPUTE_BUFFER_WRITTEN);
        t.enter(Layer::Tiles, DISCARD);
        let curve = behind.gbuffer.curve.is_some();
        for key in [
            Layer::Ray,
            Layer::Frame,
            Layer::Depth,
            Layer::HitUv,
            Layer::HitHeight,
        ] {
            t.enter(key, DISCARD);
        }
        if curve {
            t.enter(Layer::Curve, DISCARD);
        }
        let fragment = vk::PipelineStageFlags2::FRAGMENT_SHADER;
        let mut w = ScopeWriter::new(
            Some(self.timestamps.0),
            GBUFFER_QUERIES + MAX_QUERIES,
            BEHIND_QUERIES,
        );
        // SAFETY: `cmd` is recording outside a render pass (this function's contract);
        // the pool holds the range (`HostParts::new`).
        unsafe { w.reset(&ctx, cmd) };
        let params = self.background_params(target);
        let inputs = FrameInputs {
            frame_slot: BEHIND_SLOT,
            gbuffer: behind.gbuffer.views(),
            hit: behind.hit.host(),
            shade: Some(*target),
            motion,
        };
        let first = FirstLayer {
            depth: self.gbuffer.depth.view,
            hit_height: self.hit.height.view,
        };
        let rays = camera.pixel_ray_params();
        let pass = &mut self.pass;
        // SAFETY: `cmd` is recording outside a render pass and `w.reset` was recorded
        // above (the scope's contract). In the body: each barrier is the tracker's, from
        // the states above (this function's contract) through the declared accesses, in
        // recording order; the layer's images, the first layer's, the colour and motion
        // images and the pipelines are the renderer's and live until the frame has
        // completed (it is waited for); the pass records slot 1, whose previous frame
        // completed (every frame is waited for).
        unsafe {
            w.scope(&ctx, cmd, PassName::Behind, |cmd| -> Result<()> {
                // The missed tiles, then each piece's command and the tiles' list; listed,
                // the layer's hits cleared to no hit (the pass writes the missed tiles' only).
                let listed = behind.listed;
                t.declare(Layer::Tiles, BUFFER_WRITE)?;
                if listed {
                    t.declare(Layer::HitUv, Access::TRANSFER_WRITE)?;
                    t.declare(Layer::HitHeight, Access::TRANSFER_WRITE)?;
                }
                t.flush(&ctx, cmd, images)?;
                tiles.record_reset(&ctx, cmd, &sources)?;
                for (image, value) in [
                    (&behind.hit.uv, 0.0),
                    (&behind.hit.height, crate::abi::NO_HIT_HEIGHT),
                ]
                .into_iter()
                .filter(|_| listed)
                {
                    ctx.device().cmd_clear_color_image(
                        cmd,
                        image.raw,
                        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                        &vk::ClearColorValue {
                            float32: [value, 0.0, 0.0, 0.0],
                        },
                        &[image.range()],
                    );
                }
                t.declare(Layer::Tiles, COMPUTE_BUFFER_READ_WRITE)?;
                t.declare(Layer::FirstTiles, Access::INDIRECT_READ)?;
                t.declare(Layer::FirstHitHeight, Access::COMPUTE_STORAGE_READ)?;
                t.declare(Layer::FirstDepth, Access::COMPUTE_SAMPLED)?;
                t.declare(Layer::FirstFrame, Access::COMPUTE_SAMPLED)?;
                t.flush(&ctx, cmd, images)?;
                tiles.record_misses(&ctx, cmd, first, self.gbuffer.frame.view, &first_tiles)?;
                for step in [0, 1] {
                    t.declare(Layer::Tiles, COMPUTE_BUFFER_READ_WRITE)?;
                    t.flush(&ctx, cmd, images)?;
                    tiles.record_cull(&ctx, cmd, step)?;
                }
                // The commands read by the draws and the list by the background (on the
                // listed route also by the vertex stage of the listed tiles' draw).
                t.declare(
                    Layer::Tiles,
                    if listed {
                        INDIRECT_AND_VERTEX_READ
                    } else {
                        Access::INDIRECT_READ
                    },
                )?;
                for (key, access) in [
                    (Layer::Ray, Access::COLOR_ATTACHMENT_WRITE),
                    (Layer::Frame, Access::COLOR_ATTACHMENT_WRITE),
                    (Layer::Depth, Access::DEPTH_ATTACHMENT_WRITE),
                    (
                        Layer::FirstHitHeight,
                        Access {
                            stage: fragment,
                            access: vk::AccessFlags2::SHADER_STORAGE_READ,
                            layout: vk::ImageLayout::GENERAL,
                        },
                    ),
                    (
                        Layer::FirstDepth,
                        Access {
                            stage: fragment,
                            access: vk::AccessFlags2::SHADER_SAMPLED_READ,
                            layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                        },
                    ),
                ] {
                    t.declare(key, access)?;
                }
                if curve {
                    t.declare(Layer::Curve, Access::COLOR_ATTACHMENT_WRITE)?;
                }
                t.flush(&ctx, cmd, images)?;
                // Each draw as its pieces, those off the missed tiles with no vertices;
                // on the listed route only the listed tiles cleared (the rest of the depth
                // blocks the objects' fragments before they are shaded); with the mask,
                // the objects' raster off the missed pixels rejected by the depth test
                // before fragment shading.
                let (buffer, offset) = tiles.draw(0);
                let open = match (listed, &behind.open) {
                    (true, Some(pass)) => Some((pass, tiles.open_tiles())),
                    (true, None) => {
                        return Err(Error::Internal(
                            "no pipeline for the behind layer's listed tiles".into(),
                        ));
                    }
                    (false, _) => None,
                };
                crate::passes::gbuffer::record_draws_behind_culled(
                    &ctx,
                    cmd,
                    &behind.gbuffer,
                    &draws,
                    &rays,
                    first,
                    behind.mask.as_ref(),
                    IndirectDraws {
                        buffer,
                        offset,
                        stride: DRAW_STRIDE,
                        ranges: &ranges,
                        open,
                    },
                )?;
                // The layer's flat geometry, lit by the host (the background's variant).
                for key in [Layer::Ray, Layer::Frame, Layer::Depth] {
                    t.declare(key, Access::COMPUTE_SAMPLED)?;
                }
                if curve {
                    t.declare(Layer::Curve, Access::COMPUTE_SAMPLED)?;
                }
                t.declare(Layer::Color, Access::COMPUTE_STORAGE_WRITE)?;
                t.flush(&ctx, cmd, images)?;
                behind.background.record_tiles(
                    &ctx,
                    cmd,
                    behind.gbuffer.views(),
                    self.color.view_ref(),
                    &params,
                    tiles,
                )?;
                // The pass's entry contract on the layer.
                t.declare(Layer::Color, Access::COMPUTE_STORAGE_WRITE)?;
                t.declare(Layer::HitUv, Access::COMPUTE_STORAGE_WRITE)?;
                t.declare(Layer::HitHeight, Access::COMPUTE_STORAGE_WRITE)?;
                if inputs.motion.is_some() {
                    t.declare(Layer::Motion, Access::COMPUTE_STORAGE_READ_WRITE)?;
                }
                t.flush(&ctx, cmd, images)?;
                if listed {
                    // Classified over the missed tiles only (the layer has no geometry
                    // elsewhere, its hits cleared above).
                    let list = tiles.list();
                    let (dispatch, offset) = tiles.list_dispatch();
                    pass.record_listed(
                        cmd,
                        &inputs,
                        crate::passes::classify::ListedTiles {
                            list: list[0],
                            dispatch,
                            offset,
                        },
                        Timestamps::Off,
                    )?;
                } else {
                    // Classified over the whole frame (every pixel's hit written).
                    pass.record(cmd, &inputs, Timestamps::Off)?;
                }
                Ok(())
            })?
        };
        Ok(Some(w))
    }
}
