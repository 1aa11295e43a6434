//! The `background` pass of the standalone renderer (a host's own shading, not part of
//! the displacement pass): before [`crate::embed::DisplacementPass::record`], it writes
//! the sky into pixels without geometry and lights pixels of flat geometry (G-buffer
//! frame's material 0) with their G-buffer normal (`glsl/background.comp`); the pass's
//! `shade` then writes the displaced pixels. An engine draws its own sky and flat
//! geometry instead.
//!
//! Bindings: 0 G-buffer `depth`, 1 `frame` (sampled,
//! `SHADER_READ_ONLY_OPTIMAL`), 3 colour (`R8G8B8A8_UNORM` storage, written, `GENERAL`);
//! push constants: [`ShadeParams`] (the frame's camera and light).

use crate::abi::ShadeParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::ViewRef;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::passes::gbuffer::GBufferViews;
use crate::shaders;
use ash::vk;

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;

/// The background pipeline.
pub struct BackgroundPass {
    pipeline: FetchPipeline,
}

impl BackgroundPass {
    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Self::build(ctx, false)
    }

    /// Builds the behind layer's variant (`glsl/background.comp`'s `BEHIND`): it lights
    /// the flat geometry of the behind layer's G-buffer and leaves pixels without
    /// geometry as they are (the first layer's colour), instead of drawing the sky there,
    /// over the missed tiles only (`BackgroundPass::record_tiles`, crate-internal).
    pub fn new_behind(ctx: &Context) -> Result<Self> {
        Self::build(ctx, true)
    }

    fn build(ctx: &Context, behind: bool) -> Result<Self> {
        let (name, shader) = if behind {
            ("background[behind]", &shaders::BACKGROUND_COMP_BEHIND)
        } else {
            ("background", &shaders::BACKGROUND_COMP)
        };
        let mut bindings = vec![
            ("u_depth", SAMPLED),
            ("u_frame", SAMPLED),
            ("u_color", STORAGE),
        ];
        if behind {
            bindings.push(("u_behind_tiles", vk::DescriptorType::STORAGE_BUFFER));
        }
        Ok(BackgroundPass {
            pipeline: FetchPipeline::new(
                ctx,
                name,
                shader,
                &bindings,
                std::mem::size_of::<ShadeParams>() as u32,
            )?,
        })
    }

    /// Records the dispatch over the whole frame.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * The views belong to that device, of `color`'s size; when the command buffer
    ///   executes the G-buffer is in `SHADER_READ_ONLY_OPTIMAL`, its writes visible to
    ///   compute-shader sampled reads, and `color` in `GENERAL`, earlier accesses ordered
    ///   before compute-shader storage writes (the caller's barriers).
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        gbuffer: GBufferViews,
        color: ViewRef,
        params: &ShadeParams,
    ) -> Result<()> {
        let fetch = |view| self.pipeline.fetch_view(view);
        let (depth, frame) = (fetch(gbuffer.depth.view), fetch(gbuffer.frame.view));
        let out = storage_view(color.view);
        let p = &self.pipeline.pipeline;
        let writes = [
            p.image("u_depth", &depth)?,
            p.image("u_frame", &frame)?,
            p.image("u_color", &out)?,
        ];
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 and name live views in the layouts
        // above; the push constants are the `ShadeParams` the layout was built with.
        unsafe {
            self.pipeline.pipeline.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(params),
                color.extent.width,
                color.extent.height,
            )
        };
        Ok(())
    }
}

impl BackgroundPass {
    /// Records the behind variant ([`BackgroundPass::new_behind`]) over the missed tiles
    /// of `tiles` ([`crate::passes::behind_tiles`]): one workgroup per listed tile, an
    /// indirect dispatch.
    ///
    /// # Safety
    /// As [`BackgroundPass::record`]; in addition the list and its dispatch were written
    /// before and made visible to compute-shader storage reads and indirect reads (the
    /// caller's barrier), and the buffer stays alive until the command buffer has executed.
    pub(crate) unsafe fn record_tiles(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        gbuffer: GBufferViews,
        color: ViewRef,
        params: &ShadeParams,
        tiles: &crate::passes::behind_tiles::BehindTiles,
    ) -> Result<()> {
        let fetch = |view| self.pipeline.fetch_view(view);
        let (depth, frame) = (fetch(gbuffer.depth.view), fetch(gbuffer.frame.view));
        let out = storage_view(color.view);
        let list = tiles.list();
        let p = &self.pipeline.pipeline;
        let writes = [
            p.image("u_depth", &depth)?,
            p.image("u_frame", &frame)?,
            p.image("u_color", &out)?,
            p.buffer("u_behind_tiles", &list)?,
        ];
        let (args, offset) = tiles.list_dispatch();
        // SAFETY: this function's # Safety contract, as in `record`; the buffer holds the
        // list's dispatch at `offset` and has INDIRECT_BUFFER usage.
        unsafe { p.dispatch_indirect(ctx, cmd, &writes, bytemuck::bytes_of(params), args, offset) };
        Ok(())
    }
}

impl Destroy for BackgroundPass {
    /// Destroys the pipeline and sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
