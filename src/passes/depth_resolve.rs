//! The `depth_resolve` pass (graphics): writes the corrected depth of the displaced
//! surface ([`crate::passes::hit_depth`], `R32_SFLOAT`) into a `D32_SFLOAT` depth
//! attachment with one full-screen triangle whose fragment shader sets `gl_FragDepth`
//! (`glsl/depth_resolve.vert` / `.frag`), so that geometry drawn afterwards, fog or SSAO
//! meet the displaced surface instead of the macro polygon. Depth test `ALWAYS`, depth
//! writes on, no colour attachment. The depth is *merged*: only pixels whose G-buffer
//! frame names a material (displaced pixels; `glsl/include/dispmap_gbuffer.glsl`)
//! get the source's value (0, the reverse-Z clear value, where a displaced ray found no
//! surface); every other pixel (flat geometry, no geometry) keeps the target's depth.
//!
//! `record` expects the source and the G-buffer frame in `SHADER_READ_ONLY_OPTIMAL`,
//! visible to fragment-shader sampled reads, and the target in
//! `DEPTH_ATTACHMENT_OPTIMAL` with its contents (the attachment is loaded), earlier
//! accesses ordered before the depth reads and writes of the fragment tests; it leaves
//! the target written in that layout. The three images have the same size. It begins and ends its own dynamic rendering instance
//! (the device needs `dynamicRendering`).

use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{RasterDesc, RasterSet, raster_pipeline};
use crate::shaders;
use ash::vk;

/// The depth format the pass writes.
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// The depth-resolve pipeline.
pub struct DepthResolvePass {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    /// Set 0 as the shaders declare it.
    set: RasterSet,
    sampler: vk::Sampler,
}

/// The GLSL names of the bindings (`glsl/depth_resolve.frag`): the corrected depth and the
/// G-buffer frame.
const SOURCE: &str = "u_hit_depth";
const FRAME: &str = "u_frame";

/// Set 0 as the shaders declare it: the corrected depth and the G-buffer frame, bound by
/// their GLSL names.
pub(crate) fn raster_set() -> Result<RasterSet> {
    RasterSet::new(
        &[
            (&shaders::DEPTH_RESOLVE_VERT, vk::ShaderStageFlags::VERTEX),
            (&shaders::DEPTH_RESOLVE_FRAG, vk::ShaderStageFlags::FRAGMENT),
        ],
        &[
            (SOURCE, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
            (FRAME, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
        ],
    )
}

impl DepthResolvePass {
    /// Builds the pipeline (dynamic rendering, `D32_SFLOAT` depth attachment only).
    pub fn new(ctx: &Context) -> Result<Self> {
        let dev = ctx.device();
        let set = raster_set()?;
        let sampler = crate::gpu::pipeline::sampler(
            ctx,
            "depth_resolve.sampler",
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        )?;
        let mut pass = DepthResolvePass {
            pipeline: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            set,
            sampler,
        };
        // On failure `pass` is destroyed with what exists.
        match pass.build(ctx, dev) {
            Ok(()) => Ok(pass),
            Err(e) => {
                // SAFETY: never recorded.
                unsafe { pass.destroy(ctx) };
                Err(e)
            }
        }
    }

    fn build(&mut self, ctx: &Context, dev: &ash::Device) -> Result<()> {
        self.set_layout = self.set.set_layout(ctx, "depth_resolve.set_layout")?;
        let set_layouts = [self.set_layout];
        let layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        // SAFETY: valid device and set layout.
        self.layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")?;
        ctx.set_name(self.layout, "depth_resolve.layout");
        self.pipeline = raster_pipeline(
            ctx,
            &RasterDesc {
                vert: &shaders::DEPTH_RESOLVE_VERT,
                frag: &shaders::DEPTH_RESOLVE_FRAG,
                layout: self.layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::ALWAYS,
                color_formats: &[],
                depth_format: DEPTH_FORMAT,
                name: "depth_resolve.pipeline",
            },
        )?;
        Ok(())
    }

    /// Records the pass: every displaced pixel of `target` (a `D32_SFLOAT` view of
    /// `extent`; displaced: the host's G-buffer frame names a material) gets the
    /// value of `source` (an `R32_SFLOAT` view of the same size); the others keep their
    /// depth. Layouts: module docs.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance (the pass begins and ends its own dynamic rendering), for a
    ///   queue of the context's queue family.
    /// * `source` and `frame` (sampled usage) and `target` (`DEPTH_STENCIL_ATTACHMENT`
    ///   usage, a `D32_SFLOAT` view) belong to that device and are views of images of
    ///   `extent`; `target` is not a view of `source`'s or `frame`'s image.
    /// * When the command buffer executes, `source` and `frame` are in
    ///   `SHADER_READ_ONLY_OPTIMAL`, their writes visible to fragment-shader sampled
    ///   reads, and `target` in `DEPTH_ATTACHMENT_OPTIMAL`, its writes visible to and
    ///   earlier accesses ordered before the fragment tests' depth reads and writes (the
    ///   caller's barriers).
    /// * Both images and this pass stay alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        source: vk::ImageView,
        frame: vk::ImageView,
        target: vk::ImageView,
        extent: vk::Extent2D,
    ) -> Result<()> {
        let depth_attachment = vk::RenderingAttachmentInfo::default()
            .image_view(target)
            .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE);
        let area = crate::gpu::pipeline::frame_area(extent);
        let rendering = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1)
            .depth_attachment(&depth_attachment);
        let info = |view: vk::ImageView| {
            [vk::DescriptorImageInfo {
                sampler: self.sampler,
                image_view: view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            }]
        };
        let (source_info, frame_info) = (info(source), info(frame));
        let writes = [
            self.set.image(SOURCE, &source_info)?,
            self.set.image(FRAME, &frame_info)?,
        ];
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording; `extent` is the
        // size of the target attachment, so it is non-zero and within the viewport limits.
        unsafe { crate::gpu::pipeline::set_frame_viewport(ctx, cmd, extent) };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; source and target are alive and in the layouts documented above; the
        // writes match the set layout (both from the shaders' reflection).
        unsafe {
            dev.cmd_begin_rendering(cmd, &rendering);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            ctx.push_descriptor().cmd_push_descriptor_set(
                cmd,
                vk::PipelineBindPoint::GRAPHICS,
                self.layout,
                0,
                &writes,
            );
            dev.cmd_draw(cmd, 3, 1, 0, 0);
            dev.cmd_end_rendering(cmd);
        }
        Ok(())
    }
}

impl Destroy for DepthResolvePass {
    /// Destroys the pipeline, layouts and sampler and nulls their handles (a second call
    /// does nothing).
    ///
    /// # Safety
    /// No command buffer that recorded this pass is pending (the host waited on the
    /// fences of every frame that used it, or for the device to idle).
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            let dev = ctx.device();
            dev.destroy_pipeline(self.pipeline, None);
            dev.destroy_pipeline_layout(self.layout, None);
            dev.destroy_descriptor_set_layout(self.set_layout, None);
            dev.destroy_sampler(self.sampler, None);
            self.pipeline = vk::Pipeline::null();
            self.layout = vk::PipelineLayout::null();
            self.set_layout = vk::DescriptorSetLayout::null();
            self.sampler = vk::Sampler::null();
        }
    }
}
