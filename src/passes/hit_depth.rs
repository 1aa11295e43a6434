//! The `hit_depth` pass: the corrected depth of the displaced surface, an
//! `R32_SFLOAT` image holding, per pixel, the reverse-Z clip depth of the hit point
//! (`glsl/hit_depth.comp` documents the reconstruction). Pixels without a hit (no
//! geometry, or a clamp-addressed ray that left the decal) hold 0, the cleared reverse-Z
//! depth at infinity, so geometry behind them shows; [`crate::passes::depth_resolve`]
//! copies the image into a `D32_SFLOAT` depth attachment.
//!
//! Bindings: [`crate::passes::hit_resolve`] (`u_hit_depth`: the corrected depth,
//! `R32_SFLOAT` storage, written).
//!
//! One dispatch resolves one material's pixels (a workgroup per tile of its list, the
//! material's `depth_scale`); `classify` writes the others' (the G-buffer's own depth:
//! flat geometry, or 0 without geometry).

use crate::abi::HitDepthParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::ViewRef;
use crate::gpu::owned::Destroy;
use crate::passes::classify::MaterialTiles;
use crate::passes::gbuffer::GBufferViews;
use crate::passes::hit_resolve::{HitResolvePipeline, ResolveViews};
use crate::shaders;
use ash::vk;
use glam::{DMat4, Mat4, Vec3};

/// Format of the corrected-depth image.
pub const HIT_DEPTH_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// The images the pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct HitDepthInputs {
    /// The hit images (read).
    pub hit: crate::passes::trace::HitViews,
    /// The G-buffer (ray, depth and frame are read).
    pub gbuffer: GBufferViews,
    /// The corrected depth (written; the frame's size).
    pub hit_depth: ViewRef,
    /// The material and its tiles.
    pub tiles: MaterialTiles,
}

impl HitDepthParams {
    /// The push constants for a frame drawn with `view_proj` (world to clip, the
    /// G-buffer's) from `eye`, with a displacement depth of `depth_scale` tile units.
    ///
    /// The shader works with offsets from the eye: `view_proj * translation(eye)` has no
    /// translation, so unprojecting a far pixel's small reverse-Z depth and projecting
    /// the hit never cancels large world coordinates (with the plain inverse
    /// view-projection in f32, a pixel 600 tiles away was off by 0.4% in depth). The
    /// matrices are composed and inverted in f64.
    pub fn new(view_proj: Mat4, eye: Vec3, frame_size: [u32; 2], depth_scale: f32) -> Self {
        let eye_clip = view_proj.as_dmat4() * DMat4::from_translation(eye.as_dvec3());
        let inv = eye_clip.inverse();
        HitDepthParams {
            inv_eye_clip: inv.as_mat4(),
            clip_z_row: eye_clip.row(2).as_vec4(),
            clip_w_row: eye_clip.row(3).as_vec4(),
            frame_size,
            depth_scale,
            material: 0,
        }
    }
}

/// The corrected-depth pass.
pub struct HitDepthPass {
    pipeline: HitResolvePipeline,
}

impl HitDepthPass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.bindings()
    }

    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(HitDepthPass {
            pipeline: HitResolvePipeline::new(
                ctx,
                "hit_depth",
                &shaders::HIT_DEPTH_COMP,
                "u_hit_depth",
                std::mem::size_of::<HitDepthParams>() as u32,
            )?,
        })
    }

    /// Records the dispatch over the material's tiles.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `inputs`' views belong to that device and have the formats and usages of the
    ///   module's table; the hit images and the G-buffer are of `inputs.hit_depth`'s size.
    /// * When the command buffer executes, the images are in the layouts of the module's
    ///   table: the hit images in `GENERAL`, their writes visible to compute-shader storage
    ///   reads; the G-buffer in `SHADER_READ_ONLY_OPTIMAL`, its writes visible to
    ///   compute-shader sampled reads; the corrected depth in `GENERAL`, earlier accesses
    ///   ordered before compute-shader storage writes (the caller's barriers); the tile
    ///   list written by a `classify` recorded before in the same command buffer.
    /// * The images behind `inputs` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: HitDepthInputs,
        params: &HitDepthParams,
    ) -> Result<()> {
        let HitDepthInputs {
            hit,
            gbuffer,
            hit_depth,
            tiles,
        } = inputs;
        let push = HitDepthParams {
            material: tiles.material,
            ..*params
        };
        // SAFETY: this function's # Safety contract is `HitResolvePipeline::record`'s (the
        // corrected depth as its output), with the `HitDepthParams` the pipeline was built
        // with (its material set here).
        unsafe {
            self.pipeline.record(
                ctx,
                cmd,
                ResolveViews {
                    hit,
                    gbuffer,
                    out: hit_depth.view,
                },
                tiles,
                bytemuck::bytes_of(&push),
            )
        }
    }
}

impl Destroy for HitDepthPass {
    /// Destroys the pipeline and sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
