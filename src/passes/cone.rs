//! The `cone` pass: the conservative or relaxed cone map of the bilinear surface, built on
//! the GPU from the height map and the cell max pyramid (`glsl/cone.comp`) for the
//! cone-stepping methods (`cone`, `cone-exact`: conservative; `relaxed-cone`: relaxed).
//!
//! # The map
//!
//! One `R32G32_SFLOAT` texel `(M, w)` per bilinear cell `(i, j)` (the square between texel
//! centres `(i, j)` and `(i + 1, j + 1)`, as in [`crate::method::PyramidKind::Cell`]): `M`
//! the cell's maximum (its 4 corner texels' max: the cell pyramid's level 0) and `w` the
//! cone ratio, in texels of horizontal distance per unit of height (the full depth being
//! 1), such that every point `q` of the surface satisfies
//! `H(q) <= M + dist(q, C) / w`, `dist` the Euclidean distance in texels from `q` to the
//! cell's square `C`. The apex of the "cone" is the whole cell at height `M`, which makes
//! it correct for the bilinear surface anywhere over the cell (the correction of Bán,
//! Valasek, Bálint & Vad, "Robust Cone Step Mapping", EGSR 2024: a cone with its apex at
//! one texel centre does not bound the interpolated surface). A ray over `C` at a height
//! `h > M` can advance by `w (h - M) / (w + |d|)` (`|d|` its horizontal texels per unit of
//! height) without meeting the surface.
//!
//! # Generation
//!
//! One invocation per cell, `O(W H (R^2 + log))`: the cells within `R = 4` cells of it by
//! brute force on their corner texels (bounds that use the bilinear patch's linearity
//! along each axis: exact for a constant slope), everything beyond from the max pyramid's
//! neighbour rings (the quick generation of Valasek & Bán, EG 2022), each bounded by
//! its node maximum at a distance of at least `R`. Every bound is conservative; the
//! shader's header has the argument.
//!
//! # The relaxed map
//!
//! [`ConeKind::Relaxed`] (relaxed cone stepping, Policarpo & Oliveira 2007, with the
//! falling-edge correction of Bán et al. 2024 adapted to the cell apex): a window cell
//! `D` that is *monotone outward* gives no bound: per axis, `D`'s bilinear patch does not
//! fall going away from `C` (both edges non-decreasing in that direction), or is constant
//! along the axis where `D` is in `C`'s column or row (rays cross those cells either way).
//! Every other cell bounds the cone as in the conservative map (the window cells by their
//! corners, the rest by the pyramid), so a relaxed cone is never narrower than the
//! conservative one of the same cell.
//!
//! What the trace relies on: a ray that starts over `C` above `M` and steps to the cone's
//! boundary (as the conservative step does) crosses the surface **at most once**. The
//! segment stays inside the cone (the ray's height is linear along it, the cone's height
//! `M + dist / w` convex, and both ends are on or inside the cone), so it can only be
//! under the surface in cells whose surface may rise into the cone: the monotone-outward
//! cells (the conservative bounds keep every other cell below the cone, `C`'s own patch is
//! at most `M`). A ray leaving `C` moves away from it along both axes, so across a
//! monotone-outward patch the surface height along the ray never decreases while the ray
//! descends: once under the surface, the ray stays under it to the next cell, whose shared
//! edge then rises above the cone, so that cell is monotone outward too (any other cell's
//! surface is below the cone). Hence one height test at the step's end decides whether the
//! step crossed the surface, and a binary search over the step converges to that one
//! crossing. Clamp addressing's half cells `-1` and `W - 1` are constant along the clamped
//! axis, so the rule holds for them whichever way a ray crosses them. Repeat addressing wraps the neighbourhood (the tiles
//! beyond the root's neighbours are bounded by the global maximum); clamp addressing
//! includes the half cells at the decal's border and nothing beyond it.
//!
//! # Contract (engine embedding)
//!
//! [`ConePass::record`] expects the height texture and the cell pyramid built and in
//! `SHADER_READ_ONLY_OPTIMAL`, visible to compute sampled reads; it discards the cone
//! map's contents and leaves it in `SHADER_READ_ONLY_OPTIMAL`, visible to compute sampled
//! reads. Build it when the height map changes (after the pyramid).

use crate::abi::{ADDRESSING_CLAMP, ADDRESSING_REPEAT, ConeParams};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::commands::read_image_level;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::storage_view;
use crate::gpu::sync::Access;
use crate::gpu::track::{Target, Tracker, binding_access};
use crate::gpu::{ComputePipeline, HeightTexture, Image, OneShot};
use crate::heightfield::Addressing;
use crate::method::{ConeKind, PyramidKind};
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::shaders;
use ash::vk;

/// Format of the cone map: `(M, w)` per cell (storage support is checked when a map is
/// created: it is not mandatory in Vulkan). The relaxed map stores `-w` where its cone
/// is wider than the conservative one (where a step may end inside the surface, so the
/// trace tests the surface there only).
pub const CONE_FORMAT: vk::Format = vk::Format::R32G32_SFLOAT;

/// Half width, in cells, of the neighbourhood `glsl/cone.comp` bounds cell by cell
/// (`WINDOW` there); beyond it the pyramid bounds the surface.
pub const CONE_WINDOW: u32 = 4;

/// The widest cone ratio stored (`CONE_RATIO_MAX` in `glsl/cone.comp`).
pub const CONE_RATIO_MAX: f32 = 65536.0;

/// What the pass binds, by GLSL name (`glsl/cone.comp` numbers them).
const BINDINGS: [(&str, vk::DescriptorType); 3] = [
    ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_pyramid", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_cone", vk::DescriptorType::STORAGE_IMAGE),
];

/// The relaxed generation's bindings: the above, then the four falls pyramids
/// ([`PyramidKind::FALLS`] order).
const RELAXED_BINDINGS: [(&str, vk::DescriptorType); 7] = [
    BINDINGS[0],
    BINDINGS[1],
    BINDINGS[2],
    ("u_falls_pp", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_falls_np", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_falls_pn", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_falls_nn", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
];

/// The cone map of one height map.
pub struct ConeMap {
    /// The `W x H` image (`CONE_FORMAT`).
    pub image: Image,
    sampler: vk::Sampler,
    /// The map's size in texels (= cells).
    pub size: [u32; 2],
    /// The addressing the map was built for.
    pub addressing: Addressing,
    /// Conservative or relaxed.
    pub kind: ConeKind,
    /// The relaxed map's generation input: the four [`PyramidKind::FALLS`] pyramids of
    /// the map (empty for a conservative map, and once [`ConeMap::take_scratch`] took
    /// them after the build).
    falls: Vec<Pyramid>,
}

impl ConeMap {
    /// Allocates the `kind` cone map of a `size` height map whose texture has
    /// `height_format` (contents undefined until built).
    pub fn new(
        ctx: &Context,
        size: [u32; 2],
        addressing: Addressing,
        kind: ConeKind,
        height_format: vk::Format,
    ) -> Result<Self> {
        let extent = vk::Extent2D {
            width: size[0].max(1),
            height: size[1].max(1),
        };
        // `R32G32_SFLOAT` storage is not mandatory in Vulkan (the "extended" storage
        // formats): the cone methods need it, the other methods do not, so it is checked
        // here rather than in the device requirements.
        let needed = vk::FormatFeatureFlags::STORAGE_IMAGE | vk::FormatFeatureFlags::SAMPLED_IMAGE;
        if !ctx.format_features(CONE_FORMAT).contains(needed) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                what: format!("{CONE_FORMAT:?} with {needed:?} (the cone map of the cone methods)"),
            });
        }
        let name = match kind {
            ConeKind::Conservative => "cone_map",
            ConeKind::Relaxed => "relaxed_cone_map",
        };
        let mut image = Image::new(
            ctx,
            name,
            CONE_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        let sampler = match crate::gpu::pipeline::sampler(
            ctx,
            &format!("{name}.sampler"),
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        ) {
            Ok(s) => s,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { image.destroy(ctx) };
                return Err(e);
            }
        };
        let mut map = ConeMap {
            image,
            sampler,
            size,
            addressing,
            kind,
            falls: Vec::new(),
        };
        if kind == ConeKind::Relaxed {
            for falls in PyramidKind::FALLS {
                match Pyramid::new(ctx, size, falls, addressing, height_format) {
                    Ok(p) => map.falls.push(p),
                    Err(e) => {
                        // SAFETY: built above and never used by a command.
                        unsafe { map.destroy(ctx) };
                        return Err(e);
                    }
                }
            }
        }
        Ok(map)
    }

    /// Takes what only the build reads (the relaxed map's four falls pyramids, about 21
    /// bytes per texel), for the caller to destroy once the build has executed.
    pub fn take_scratch(&mut self) -> Vec<Pyramid> {
        std::mem::take(&mut self.falls)
    }

    /// Descriptor for the trace pass (`texelFetch(u_cone, cell, 0)`).
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.image.view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Reads the map back, row by row: `(M, w)` per cell as stored (the relaxed map's
    /// `w` negative where it is wider than the conservative ratio). It must be built and
    /// idle in `SHADER_READ_ONLY_OPTIMAL`.
    pub fn read(&self, ctx: &Context, shot: &OneShot) -> Result<Vec<[f32; 2]>> {
        let bytes = read_image_level(ctx, shot, &self.image, 0, Access::COMPUTE_SAMPLED)?;
        let texels: &[[f32; 2]] = bytemuck::cast_slice(&bytes);
        Ok(texels.to_vec())
    }
}

impl Destroy for ConeMap {
    /// Destroys the sampler, image and scratch. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            for mut falls in self.falls.drain(..) {
                falls.destroy(ctx);
            }
            if self.sampler != vk::Sampler::null() {
                ctx.device().destroy_sampler(self.sampler, None);
                self.sampler = vk::Sampler::null();
            }
            self.image.destroy(ctx);
        }
    }

    /// The cone map and, until the build is over, the relaxed map's falls pyramids.
    fn bytes(&self) -> u64 {
        self.image.bytes() + self.falls.bytes()
    }
}

/// The cone generation pipeline of one [`ConeKind`].
pub struct ConePass {
    pipeline: ComputePipeline,
    /// The relaxed generation's falls pyramids' build.
    falls_pass: Option<PyramidPass>,
    /// The kind of map it builds.
    pub kind: ConeKind,
}

impl ConePass {
    /// Builds the pipeline for `kind` maps.
    pub fn new(ctx: &Context, kind: ConeKind) -> Result<Self> {
        let (name, shader, bindings): (_, _, &[_]) = match kind {
            ConeKind::Conservative => ("cone", &shaders::CONE_COMP, &BINDINGS),
            ConeKind::Relaxed => (
                "relaxed_cone",
                &shaders::CONE_COMP_RELAXED,
                &RELAXED_BINDINGS,
            ),
        };
        let mut pipeline = ComputePipeline::new(
            ctx,
            name,
            shader,
            bindings,
            std::mem::size_of::<ConeParams>() as u32,
        )?;
        let falls_pass = match kind {
            ConeKind::Conservative => None,
            ConeKind::Relaxed => match PyramidPass::new(ctx) {
                Ok(p) => Some(p),
                Err(e) => {
                    // SAFETY: built above and never used by a command.
                    unsafe { pipeline.destroy(ctx) };
                    return Err(e);
                }
            },
        };
        Ok(ConePass {
            pipeline,
            falls_pass,
            kind,
        })
    }

    /// Records the generation (see the module docs for the layouts on entry and exit); a
    /// relaxed map's falls pyramids are built first (their contents discarded).
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * When the command buffer executes, `height` and `pyramid` (a
    ///   [`PyramidKind::Cell`] pyramid of the same map, built) are in
    ///   `SHADER_READ_ONLY_OPTIMAL`, their writes visible to compute-shader sampled
    ///   reads, and no access of `cone`'s image (nor of its scratch pyramids) is pending
    ///   (their contents are discarded). A relaxed map still holds its scratch (see
    ///   [`ConeMap::take_scratch`]).
    /// * `height`, `pyramid`, `cone` and this pass stay alive until the command buffer
    ///   has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        height: &HeightTexture,
        pyramid: &Pyramid,
        cone: &ConeMap,
    ) -> Result<()> {
        debug_assert_eq!(pyramid.kind, PyramidKind::Cell);
        debug_assert_eq!(cone.kind, self.kind);
        if let Some(falls_pass) = &self.falls_pass {
            debug_assert_eq!(cone.falls.len(), 4, "the relaxed map's scratch was taken");
            for falls in &cone.falls {
                // SAFETY: this function's # Safety contract: `cmd` is recording outside a
                // render pass; the height texture is sampled-readable; the falls
                // pyramids are the cone map's own, alive, and no access of them is
                // pending.
                unsafe { falls_pass.record(ctx, cmd, height, falls)? };
            }
        }
        // The cone map enters discarded (no access pending: this function's contract);
        // the tracker places its barriers from the dispatch's declared access.
        let mut t = Tracker::new();
        t.enter((), Access::UNDEFINED);
        let target = |()| Target::Image(cone.image.raw, cone.image.range());
        let out = self.pipeline.bindings.iter().find(|b| b.name == "u_cone");
        let out = out.ok_or_else(|| Error::Internal("the cone shader has no u_cone".into()))?;
        t.declare((), binding_access(out))?;
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the cone map is alive and its contents may be discarded.
        unsafe { t.flush(ctx, cmd, target)? };
        let heights = [height.descriptor()];
        let pyramids = [pyramid.descriptor()];
        let out = storage_view(cone.image.view);
        let falls: Vec<[vk::DescriptorImageInfo; 1]> =
            cone.falls.iter().map(|p| [p.descriptor()]).collect();
        let p = &self.pipeline;
        let mut writes = vec![
            p.image("u_height", &heights)?,
            p.image("u_pyramid", &pyramids)?,
            p.image("u_cone", &out)?,
        ];
        if self.falls_pass.is_some() {
            for ((name, _), info) in RELAXED_BINDINGS[3..].iter().zip(&falls) {
                writes.push(p.image(name, info)?);
            }
        }
        let push = ConeParams {
            map_size: cone.size,
            levels: pyramid.shader_levels(),
            addressing: match cone.addressing {
                Addressing::Repeat => ADDRESSING_REPEAT,
                Addressing::Clamp => ADDRESSING_CLAMP,
            },
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 (`BINDINGS`, or `RELAXED_BINDINGS`
        // for the relaxed pass) and name the live height texture, pyramid and (relaxed)
        // falls pyramids (sampled-readable: their builds above leave them so) and the
        // cone map in `GENERAL` (the transition above); the push constants are the `ConeParams` the layout was
        // built with; the pipeline lives as long as this pass.
        unsafe {
            self.pipeline.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(&push),
                cone.size[0],
                cone.size[1],
            )
        };
        // Left for the frames' sampled reads, as every build leaves its maps.
        t.declare((), Access::COMPUTE_SAMPLED)?;
        // SAFETY: as above.
        unsafe { t.flush(ctx, cmd, target) }
    }
}

impl Destroy for ConePass {
    /// Destroys the pipelines.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
            if let Some(mut p) = self.falls_pass.take() {
                p.destroy(ctx);
            }
        }
    }
}
