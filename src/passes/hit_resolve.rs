//! The pipeline shape `hit_depth` and `motion` share: one indirect dispatch per material
//! over its tiles ([`crate::passes::classify`]) that reads the hit buffer and the G-buffer
//! and writes one storage image of the frame's size.
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/hit_depth.comp` and
//! `glsl/motion.comp`:
//!
//! | binding | resource | layout on entry |
//! |---|---|---|
//! | 0 | hit buffer (storage, read) | `GENERAL` |
//! | 1 | G-buffer `ray` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 2 | G-buffer `depth` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 3 | G-buffer `normal` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 4 | G-buffer `tangent` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 5 | the output (storage; written, or read and written) | `GENERAL` |
//! | 15 | the material's tile list ([`crate::passes::classify`]) | |

use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, image_write, storage_view};
use crate::passes::classify::{MaterialTiles, TILES_BINDING};
use crate::passes::gbuffer::GBufferViews;
use crate::shaders::Shader;
use ash::vk;

const BINDINGS: [vk::DescriptorType; 6] = [
    vk::DescriptorType::STORAGE_IMAGE,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::STORAGE_IMAGE,
];

/// The views one dispatch binds (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct ResolveViews {
    /// The hit buffer (read).
    pub hit: vk::ImageView,
    /// The G-buffer (ray, depth, normal and tangent are read).
    pub gbuffer: GBufferViews,
    /// The output (binding 5).
    pub out: vk::ImageView,
}

/// A compute pipeline of the shared shape (module docs).
pub struct HitResolvePipeline {
    pipeline: FetchPipeline,
}

impl HitResolvePipeline {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// Builds the pipeline of `shader` named `name`, with `push_constant_size` bytes of
    /// push constants.
    pub fn new(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        push_constant_size: u32,
    ) -> Result<Self> {
        let mut bindings = crate::gpu::pipeline::numbered(&BINDINGS);
        bindings.push((TILES_BINDING, vk::DescriptorType::STORAGE_BUFFER));
        Ok(HitResolvePipeline {
            pipeline: FetchPipeline::new(ctx, name, shader, &bindings, push_constant_size)?,
        })
    }

    /// Records the dispatch over `tiles`' material.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * The views belong to that device, have the frame's size and the layouts of the
    ///   module docs when the command buffer executes, with their earlier writes visible
    ///   to the shader's accesses and earlier accesses of `out` ordered before its writes
    ///   (the caller's barriers); the tile list was written by a `classify` recorded
    ///   before in the same command buffer.
    /// * `push` is exactly the pipeline's push-constant size, in the shader's layout.
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        views: ResolveViews,
        tiles: MaterialTiles,
        push: &[u8],
    ) {
        let ResolveViews { hit, gbuffer, out } = views;
        let hits = storage_view(hit);
        let fetch = |view| self.pipeline.fetch_view(view);
        let ray = fetch(gbuffer.ray.view);
        let depth = fetch(gbuffer.depth.view);
        let normal = fetch(gbuffer.normal.view);
        let tangent = fetch(gbuffer.tangent.view);
        let out = storage_view(out);
        let writes = [
            image_write(0, BINDINGS[0], &hits),
            image_write(1, BINDINGS[1], &ray),
            image_write(2, BINDINGS[2], &depth),
            image_write(3, BINDINGS[3], &normal),
            image_write(4, BINDINGS[4], &tangent),
            image_write(5, BINDINGS[5], &out),
        ];
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 (bindings 0-5 here, the list added
        // by `dispatch`) and name live views in the layouts of the module docs; `push` is
        // the pipeline's push constants; the list is the classification's.
        unsafe { tiles.dispatch(ctx, cmd, &self.pipeline.pipeline, &writes, push) };
    }
}

impl Destroy for HitResolvePipeline {
    /// Destroys the pipeline and sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
