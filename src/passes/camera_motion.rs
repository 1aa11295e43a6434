//! The `camera_motion` pass of the standalone renderer (a host's own work, not part of the
//! displacement pass): the motion vectors of its static world from the G-buffer depth and
//! the previous camera (`glsl/camera_motion.comp`), written into an `R32G32_SFLOAT` image
//! before [`crate::embed::DisplacementPass::record`], whose `motion` stage
//! ([`crate::passes::motion`], source `Surface`) then adds the displacement's parallax at
//! displaced pixels, as an engine's velocity buffer is corrected.
//!
//! Bindings: 0 G-buffer `depth` (sampled, `SHADER_READ_ONLY_OPTIMAL`), 1 motion
//! (`R32G32_SFLOAT` storage, written, `GENERAL`); push constants: [`MotionParams`]
//! (`depth_scale` and `material` unused): pixels, previous minus current.

use crate::abi::MotionParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::Destroy;
use crate::gpu::owned::Guard;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::gpu::sync::Access;
use crate::gpu::track::{Handle, Tracker};
use crate::gpu::{Image, ViewRef};
use crate::passes::motion::{DepthCamera, FrameMotion, MotionSettings};
use crate::shaders;
use ash::vk;

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;

/// The format of the renderer's motion image.
pub const CAMERA_MOTION_FORMAT: vk::Format = vk::Format::R32G32_SFLOAT;

/// The camera-motion pipeline.
pub struct CameraMotionPass {
    pipeline: FetchPipeline,
}

impl CameraMotionPass {
    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(CameraMotionPass {
            pipeline: FetchPipeline::new(
                ctx,
                "camera_motion",
                &shaders::CAMERA_MOTION_COMP,
                &[("u_depth", SAMPLED), ("u_motion", STORAGE)],
                std::mem::size_of::<MotionParams>() as u32,
            )?,
        })
    }

    /// Records the dispatch over the whole frame.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * The views belong to that device, of `motion`'s size; when the command buffer
    ///   executes `depth` is in `SHADER_READ_ONLY_OPTIMAL`, its writes visible to
    ///   compute-shader sampled reads, and `motion` in `GENERAL`, earlier accesses ordered
    ///   before compute-shader storage writes (the caller's barriers).
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        depth: vk::ImageView,
        motion: ViewRef,
        params: &MotionParams,
    ) -> Result<()> {
        let depth = self.pipeline.fetch_view(depth);
        let out = storage_view(motion.view);
        let p = &self.pipeline.pipeline;
        let writes = [p.image("u_depth", &depth)?, p.image("u_motion", &out)?];
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 and name live views in the layouts
        // above; the push constants are the `MotionParams` the layout was built with.
        unsafe {
            self.pipeline.pipeline.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(params),
                motion.extent.width,
                motion.extent.height,
            )
        };
        Ok(())
    }
}

impl Destroy for CameraMotionPass {
    /// Destroys the pipeline and sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}

/// The standalone renderer's motion output: the pass, its image and the camera of the
/// last frame rendered (the next frame's previous camera).
pub struct CameraMotion {
    pass: CameraMotionPass,
    /// The motion image (the frame's size; [`CAMERA_MOTION_FORMAT`], `STORAGE |
    /// TRANSFER_SRC`).
    pub image: Image,
    /// The camera of the last frame rendered with the output on (`None` before the first:
    /// that frame's previous camera is its own).
    pub previous: Option<DepthCamera>,
}

impl CameraMotion {
    /// The pass and an image of `extent`.
    pub fn new(ctx: &Context, extent: vk::Extent2D) -> Result<Self> {
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let pass = unsafe { Guard::new(ctx, CameraMotionPass::new(ctx)?) };
        let image = motion_image(ctx, extent)?;
        Ok(CameraMotion {
            pass: pass.keep(),
            image,
            previous: None,
        })
    }

    /// A new image of `extent`; the old one is destroyed.
    ///
    /// # Safety
    /// No command buffer that may still be pending uses the old image.
    pub unsafe fn resize(&mut self, ctx: &Context, extent: vk::Extent2D) -> Result<()> {
        let mut old = std::mem::replace(&mut self.image, motion_image(ctx, extent)?);
        // SAFETY: this function's contract: the GPU is done with the old image.
        unsafe { old.destroy(ctx) };
        Ok(())
    }

    /// Records the camera motion of a frame drawn with `current` into the image, ending
    /// with the image in `GENERAL`, visible to the displacement pass's `motion` stage
    /// (compute-shader storage reads and writes). Returns the frame's [`FrameMotion`].
    ///
    /// # Safety
    /// * `cmd` is recording outside a render pass on `ctx`'s queue family.
    /// * When it executes, `depth` is in `SHADER_READ_ONLY_OPTIMAL`, its writes visible to
    ///   compute-shader sampled reads, and the image's previous frame has completed.
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        depth: vk::ImageView,
        current: DepthCamera,
    ) -> Result<FrameMotion> {
        let previous = self.previous.unwrap_or(current);
        let e = self.image.extent;
        let params = MotionParams::new(
            current.view_proj,
            current.eye,
            previous.view_proj,
            [e.width, e.height],
            0.0,
            &MotionSettings::default(),
        );
        // The image enters discarded after its previous frame's reads (compute, or a
        // read-back copy), is written by the dispatch, and leaves for the pass's `motion`
        // stage (read and written in place); the tracker places the barriers.
        let discard = Access {
            stage: vk::PipelineStageFlags2::COMPUTE_SHADER | vk::PipelineStageFlags2::COPY,
            ..Access::UNDEFINED
        };
        let image = Handle::image(&self.image);
        let mut t = Tracker::new();
        t.enter(image, discard);
        t.declare(image, Access::COMPUTE_STORAGE_WRITE)?;
        // SAFETY: this function's contract; the image is this pass's, its previous frame
        // completed (so it may be discarded), in `GENERAL` for the dispatch between the
        // barriers.
        unsafe {
            t.record(ctx, cmd)?;
            self.pass
                .record(ctx, cmd, depth, self.image.view_ref(), &params)?;
            t.declare(image, Access::COMPUTE_STORAGE_READ_WRITE)?;
            t.record(ctx, cmd)?;
        }
        Ok(FrameMotion {
            image: self.image.host_view(),
            previous,
        })
    }
}

impl Destroy for CameraMotion {
    /// Destroys the pass and the image. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pass.destroy(ctx);
            self.image.destroy(ctx);
        }
    }
}

fn motion_image(ctx: &Context, extent: vk::Extent2D) -> Result<Image> {
    Image::new(
        ctx,
        "motion",
        CAMERA_MOTION_FORMAT,
        extent,
        1,
        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
    )
}
