//! The pipeline shape `hit_depth` and `motion` share: one indirect dispatch per material
//! over its tiles ([`crate::passes::classify`]) that reads the hit images and the G-buffer
//! and writes one storage image of the frame's size.
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/hit_depth.comp` and
//! `glsl/motion.comp`:
//!
//! | binding (GLSL name; the shader numbers it) | resource | layout on entry |
//! |---|---|---|
//! | `u_hit_uv`, `u_hit_height` | hit images (storage, read) | `GENERAL` |
//! | `u_ray` | G-buffer `ray` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_depth` | G-buffer `depth` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_frame` | G-buffer `frame` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_hit_depth` / `u_motion` | the output (storage; written, or read and written) | `GENERAL` |
//! | `u_tiles` | the material's tile list ([`crate::passes::classify`]) | |

use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::passes::classify::{MaterialTiles, TILES};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::trace::HitViews;
use crate::shaders::Shader;
use ash::vk;

/// What both shapes bind besides their output, by GLSL name (the shaders number them).
const BINDINGS: [(&str, vk::DescriptorType); 6] = [
    ("u_hit_uv", vk::DescriptorType::STORAGE_IMAGE),
    ("u_hit_height", vk::DescriptorType::STORAGE_IMAGE),
    ("u_ray", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_depth", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_frame", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    TILES,
];

/// The views one dispatch binds (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct ResolveViews {
    /// The hit images (read).
    pub hit: HitViews,
    /// The G-buffer (ray, depth and frame are read).
    pub gbuffer: GBufferViews,
    /// The output (the shader's `u_hit_depth` or `u_motion`).
    pub out: vk::ImageView,
}

/// A compute pipeline of the shared shape (module docs).
pub struct HitResolvePipeline {
    pipeline: FetchPipeline,
    /// The GLSL name of the storage image it writes.
    out: &'static str,
}

impl HitResolvePipeline {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// Builds the pipeline of `shader` named `name`, writing the storage image named
    /// `out` in the GLSL, with `push_constant_size` bytes of push constants.
    pub fn new(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        out: &'static str,
        push_constant_size: u32,
    ) -> Result<Self> {
        let mut bindings = BINDINGS.to_vec();
        bindings.push((out, vk::DescriptorType::STORAGE_IMAGE));
        Ok(HitResolvePipeline {
            pipeline: FetchPipeline::new(ctx, name, shader, &bindings, push_constant_size)?,
            out,
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
    ) -> Result<()> {
        let ResolveViews { hit, gbuffer, out } = views;
        let (hit_uv, hit_height) = (storage_view(hit.uv), storage_view(hit.height));
        let fetch = |view| self.pipeline.fetch_view(view);
        let ray = fetch(gbuffer.ray.view);
        let depth = fetch(gbuffer.depth.view);
        let frame = fetch(gbuffer.frame.view);
        let out = storage_view(out);
        let p = &self.pipeline.pipeline;
        let writes = [
            p.image("u_hit_uv", &hit_uv)?,
            p.image("u_hit_height", &hit_height)?,
            p.image("u_ray", &ray)?,
            p.image("u_depth", &depth)?,
            p.image("u_frame", &frame)?,
            p.image(self.out, &out)?,
        ];
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 (all but the list, which `dispatch`
        // adds) and name live views in the layouts of the module docs; `push` is the
        // pipeline's push constants; the list is the classification's.
        unsafe { tiles.dispatch(ctx, cmd, &self.pipeline.pipeline, &writes, push) }
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
