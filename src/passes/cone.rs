//! The `cone` pass: the conservative cone map of the bilinear surface, built on the GPU
//! from the height map and the cell max pyramid (`glsl/cone.comp`) for the cone-stepping
//! methods (`cone`, `cone-exact`).
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
//! shader's header has the argument. Repeat addressing wraps the neighbourhood (the tiles
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
use crate::error::Result;
use crate::gpu::commands::read_image_level;
use crate::gpu::pipeline::{image_write, storage_view};
use crate::gpu::sync::{self, Access};
use crate::gpu::{ComputePipeline, HeightTexture, Image, OneShot};
use crate::heightfield::Addressing;
use crate::method::PyramidKind;
use crate::passes::pyramid::Pyramid;
use crate::shaders;
use ash::vk;

/// Format of the cone map: `(M, w)` per cell.
pub const CONE_FORMAT: vk::Format = vk::Format::R32G32_SFLOAT;

/// Half width, in cells, of the neighbourhood `glsl/cone.comp` bounds cell by cell
/// (`WINDOW` there); beyond it the pyramid bounds the surface.
pub const CONE_WINDOW: u32 = 4;

/// The widest cone ratio stored (`CONE_RATIO_MAX` in `glsl/cone.comp`).
pub const CONE_RATIO_MAX: f32 = 65536.0;

const BINDINGS: [(u32, vk::DescriptorType); 3] = [
    (0, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    (1, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    (2, vk::DescriptorType::STORAGE_IMAGE),
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
}

impl ConeMap {
    /// Allocates the cone map of a `size` height map (contents undefined until built).
    pub fn new(ctx: &Context, size: [u32; 2], addressing: Addressing) -> Result<Self> {
        let extent = vk::Extent2D {
            width: size[0].max(1),
            height: size[1].max(1),
        };
        let mut image = Image::new(
            ctx,
            "cone_map",
            CONE_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        let sampler = match crate::passes::sampler(
            ctx,
            "cone_map.sampler",
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        ) {
            Ok(s) => s,
            Err(e) => {
                image.destroy(ctx);
                return Err(e);
            }
        };
        Ok(ConeMap {
            image,
            sampler,
            size,
            addressing,
        })
    }

    /// Descriptor for the trace pass (`texelFetch(u_cone, cell, 0)`).
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.image.view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Reads the map back, row by row: `(M, w)` per cell. It must be built and idle in
    /// `SHADER_READ_ONLY_OPTIMAL`.
    pub fn read(&self, ctx: &Context, shot: &OneShot) -> Result<Vec<[f32; 2]>> {
        let bytes = read_image_level(ctx, shot, &self.image, 0, Access::COMPUTE_SAMPLED)?;
        let texels: &[[f32; 2]] = bytemuck::cast_slice(&bytes);
        Ok(texels.to_vec())
    }

    /// Destroys the sampler and image. The GPU must be done with them.
    pub fn destroy(&mut self, ctx: &Context) {
        if self.sampler != vk::Sampler::null() {
            // SAFETY: caller guarantees no pending use.
            unsafe { ctx.device().destroy_sampler(self.sampler, None) };
            self.sampler = vk::Sampler::null();
        }
        self.image.destroy(ctx);
    }
}

/// The cone generation pipeline.
pub struct ConePass {
    pipeline: ComputePipeline,
}

impl ConePass {
    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(ConePass {
            pipeline: ComputePipeline::new(
                ctx,
                "cone",
                &shaders::CONE_COMP,
                &BINDINGS,
                std::mem::size_of::<ConeParams>() as u32,
            )?,
        })
    }

    /// Records the generation (see the module docs for the layouts on entry and exit).
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * When the command buffer executes, `height` and `pyramid` (a
    ///   [`PyramidKind::Cell`] pyramid of the same map, built) are in
    ///   `SHADER_READ_ONLY_OPTIMAL`, their writes visible to compute-shader sampled
    ///   reads, and no access of `cone`'s image is pending (its contents are discarded).
    /// * `height`, `pyramid`, `cone` and this pass stay alive until the command buffer
    ///   has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        height: &HeightTexture,
        pyramid: &Pyramid,
        cone: &ConeMap,
    ) {
        debug_assert_eq!(pyramid.kind, PyramidKind::Cell);
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the cone map is alive and its contents may be discarded.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                &cone.image,
                Access::UNDEFINED,
                Access::COMPUTE_STORAGE_WRITE,
            )
        };
        let heights = [height.descriptor()];
        let pyramids = [pyramid.descriptor()];
        let out = storage_view(cone.image.view);
        let writes = [
            image_write(BINDINGS[0].0, BINDINGS[0].1, &heights),
            image_write(BINDINGS[1].0, BINDINGS[1].1, &pyramids),
            image_write(BINDINGS[2].0, BINDINGS[2].1, &out),
        ];
        let push = ConeParams {
            map_size: cone.size,
            levels: pyramid.levels(),
            addressing: match cone.addressing {
                Addressing::Repeat => ADDRESSING_REPEAT,
                Addressing::Clamp => ADDRESSING_CLAMP,
            },
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match `BINDINGS` (the pipeline's set 0) and name the live
        // height texture and pyramid (sampled-readable) and the cone map in `GENERAL`
        // (the transition above); the push constants are the `ConeParams` the layout was
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
        // SAFETY: as above; the cone map is in `GENERAL`, written by the dispatch.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                &cone.image,
                Access::COMPUTE_STORAGE_WRITE,
                Access::COMPUTE_SAMPLED,
            )
        };
    }

    /// Destroys the pipeline.
    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
