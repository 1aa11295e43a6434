//! The `forward` pass: what engines do with relief mapping and POM. Bevy, Godot, Unity
//! and Unreal evaluate the marcher in the fragment shader that writes their G-buffer; this
//! pass is that, for the benchmark's yardstick of dispmap's deferred frame (G-buffer,
//! classify, trace, shade): one raster pass whose fragment shader
//! (`glsl/forward/relief.frag`, `glsl/forward/pom.frag`) encodes the fragment as the
//! G-buffer pass does and marches its ray at once, writing the hit where the deferred
//! G-buffer writes the ray.
//!
//! | attachment | format | contents |
//! |---|---|---|
//! | location | attachment | format | contents |
//! |---|---|---|---|
//! | 0 | hit uv | `R32G32_SFLOAT` ([`crate::passes::trace::HIT_UV_FORMAT`]) | the hit's `u`, `v` (cleared to 0) |
//! | 1 | frame | `R32G32_UINT` | the G-buffer's (see [`crate::passes::gbuffer`]) |
//! | 2 | hit height | `R32_SFLOAT` ([`crate::passes::trace::HIT_HEIGHT_FORMAT`]) | the hit's height (cleared to a miss, `NO_HIT_HEIGHT`) |
//! | 3 | iterations | `R32_UINT` ([`crate::passes::trace::ITERATIONS_FORMAT`]) | the march's iteration count (cleared to 0) |
//! | | depth | `D32_SFLOAT` | the G-buffer's reverse-Z depth |
//!
//! The hit attachments are the hit images themselves, in `GENERAL` (a colour attachment
//! may be in `GENERAL`), so the frame's shading reads them as it reads the trace's hits
//! ([`crate::embed::DisplacementPass::record_shading`]). The G-buffer's `ray` attachment
//! is not written: nothing after the forward pass reads it.
//!
//! Bindings (set 0, push descriptors): 0 the height field (the map's own texture, its
//! sampler: bilinear, the map's addressing), 1 the step counts
//! ([`crate::abi::ForwardParams`], a uniform buffer the pass owns: the G-buffer's push
//! constants, [`GBufferParams`], already take the 128 bytes every device guarantees), 2
//! the frame's pixel rays ([`PixelRayParams`], as the G-buffer pass's: the entry is the
//! pixel's own centre ray, written in each recording).
//! The vertex stage is the G-buffer's (`glsl/gbuffer.vert`): the plane or the quad.
//!
//! The marchers are the compute trace's code with the same inputs, so the forward hits
//! are the deferred hits: bit for bit on lavapipe (`tests/forward.rs`). A compiler is free
//! to contract or reorder the two pipelines' floating-point operations differently (no
//! `precise` anywhere), so on another driver a ray may differ in its last bits and a march
//! sample flip, moving that pixel's hit by up to a step.

use crate::abi::{ForwardParams, GBufferParams, NO_HIT_HEIGHT, PixelRayParams};
use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::gpu::owned::Guard;
use crate::gpu::pipeline::{RasterDesc, RasterSet, raster_pipeline};
use crate::gpu::{Buffer, HeightTexture, Image};
use crate::method::{Method, MethodParams};
use crate::passes::gbuffer::{DEPTH_FORMAT, FRAME_FORMAT, GBuffer, PIXEL_RAYS};
use crate::passes::pixel_ray_buffer::PixelRayBuffer;
use crate::passes::trace::{HIT_HEIGHT_FORMAT, HIT_UV_FORMAT, ITERATIONS_FORMAT};
use crate::shaders;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The images the forward pass writes beside the G-buffer (the module table).
#[derive(Clone, Copy)]
pub struct ForwardTargets<'a> {
    /// The hit uv image.
    pub uv: &'a Image,
    /// The hit height image.
    pub height: &'a Image,
    /// The iteration counts.
    pub iterations: &'a Image,
}

/// The graphics pipeline of one method's forward pass and its parameter buffer.
pub struct ForwardPass {
    method: Method,
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    /// Set 0 as the shaders declare it.
    set: RasterSet,
    params: Buffer,
    rays: PixelRayBuffer,
}

/// What the forward pass binds, `(GLSL name, type)`: the height texture, the march's step
/// counts and the pixel rays (`glsl/forward/forward.glsl`).
const DECLARED: [(&str, vk::DescriptorType); 3] = [
    (HEIGHT, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    (MARCH, vk::DescriptorType::UNIFORM_BUFFER),
    (PIXEL_RAYS, vk::DescriptorType::UNIFORM_BUFFER),
];
const HEIGHT: &str = "u_height";
const MARCH: &str = "u_march";

/// Set 0 of a forward pipeline whose fragment stage is `frag` (a method's
/// [`Method::forward_shader`]) as the shaders declare it: the height texture, the march's
/// step counts and the pixel rays, each bound by its GLSL name ([`DECLARED`]).
pub(crate) fn raster_set(frag: &shaders::Shader) -> Result<RasterSet> {
    RasterSet::new(
        &[
            (&shaders::GBUFFER_VERT, vk::ShaderStageFlags::VERTEX),
            (frag, vk::ShaderStageFlags::FRAGMENT),
        ],
        &DECLARED,
    )
}

/// Writes the step counts of `params` into `buffer` (host-visible, host-coherent: the
/// submission that follows makes the write visible to the device).
fn write_params(buffer: &mut Buffer, params: &MethodParams) -> Result<()> {
    let value = ForwardParams {
        steps: params.steps,
        refine_steps: params.refine_steps,
        min_steps: params.min_steps,
        pad: 0,
    };
    let mapped = buffer
        .mapped_mut()
        .ok_or_else(|| Error::invalid("forward parameters", "the buffer is not mapped"))?;
    mapped.copy_from_slice(bytemuck::bytes_of(&value));
    Ok(())
}

impl ForwardPass {
    /// Builds the pipeline of `method` (one with a forward shader,
    /// [`Method::forward_shader`]); the step counts are `params`'.
    pub fn new(ctx: &Context, method: Method, params: &MethodParams) -> Result<Self> {
        let frag = method.forward_shader().ok_or_else(|| {
            Error::invalid(
                "method",
                format!(
                    "{method} has no forward path (the G-buffer pass runs {})",
                    Method::ALL
                        .iter()
                        .filter(|m| m.forward_shader().is_some())
                        .map(|m| m.name())
                        .collect::<Vec<_>>()
                        .join(" or ")
                ),
            )
        })?;
        let dev = ctx.device();
        let name = format!("forward[{method}]");
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut params_buffer = unsafe {
            Guard::new(
                ctx,
                Buffer::new(
                    ctx,
                    &format!("{name}.params"),
                    std::mem::size_of::<ForwardParams>() as u64,
                    vk::BufferUsageFlags::UNIFORM_BUFFER,
                    MemoryLocation::CpuToGpu,
                )?,
            )
        };
        write_params(&mut params_buffer, params)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let rays = unsafe {
            Guard::new(
                ctx,
                PixelRayBuffer::new(ctx, &format!("{name}.pixel_rays"))?,
            )
        };
        let set = raster_set(&frag)?;
        let set_layout = set.set_layout(ctx, &format!("{name}.set_layout"))?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)
            .size(std::mem::size_of::<GBufferParams>() as u32)];
        let set_layouts = [set_layout];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&ranges);
        // SAFETY: valid device and set layout.
        let layout = match unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")
        {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: created above, unused.
                unsafe { dev.destroy_descriptor_set_layout(set_layout, None) };
                return Err(e);
            }
        };
        let pipeline = raster_pipeline(
            ctx,
            &RasterDesc {
                vert: &shaders::GBUFFER_VERT,
                frag: &frag,
                layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::GREATER,
                color_formats: &[
                    HIT_UV_FORMAT,
                    FRAME_FORMAT,
                    HIT_HEIGHT_FORMAT,
                    ITERATIONS_FORMAT,
                ],
                depth_format: DEPTH_FORMAT,
                name: &format!("{name}.pipeline"),
            },
        );
        let pipeline = match pipeline {
            Ok(p) => p,
            Err(e) => {
                // SAFETY: created above, unused.
                unsafe {
                    dev.destroy_pipeline_layout(layout, None);
                    dev.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(e);
            }
        };
        ctx.set_name(layout, &format!("{name}.layout"));
        Ok(ForwardPass {
            method,
            pipeline,
            layout,
            set_layout,
            set,
            params: params_buffer.keep(),
            rays: rays.keep(),
        })
    }

    /// The method this pass runs.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Writes the step counts of `params` (`steps`, `refine_steps`, `min_steps`) into the
    /// parameter buffer, which every recorded frame reads when it executes: the GPU must
    /// be done with the frames recorded before (the caller waits for them).
    pub fn set_params(&mut self, params: &MethodParams) -> Result<()> {
        write_params(&mut self.params, params)
    }

    /// Records the pass: clears the hit, frame and depth attachments and draws
    /// the plane or the quad of `params` (the G-buffer pass's draw,
    /// [`crate::passes::gbuffer::GBufferPass::record`]) with the marcher in the fragment
    /// shader; `rays` are the frame's pixel rays
    /// ([`crate::scene::FrameCamera::pixel_ray_params`]), written into the pass's buffer in
    /// the command buffer.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * When the command buffer executes: `hit`'s images (of the module table's formats,
    ///   the G-buffer's size, with `COLOR_ATTACHMENT` usage) are in `GENERAL`, `target`'s
    ///   frame in `COLOR_ATTACHMENT_OPTIMAL` and its depth in
    ///   `DEPTH_ATTACHMENT_OPTIMAL`, earlier accesses ordered before the attachment writes
    ///   (the contents are cleared); `height` is in `SHADER_READ_ONLY_OPTIMAL` with its
    ///   writes visible to fragment-shader sampled reads; the GPU is done with the frames
    ///   recorded before the last [`ForwardPass::set_params`].
    /// * `target`, `hit`, `height` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        target: &GBuffer,
        hit: ForwardTargets,
        height: &HeightTexture,
        (params, rays): (&GBufferParams, &PixelRayParams),
    ) -> Result<()> {
        let extent = target.ray.extent;
        let attachment = crate::gpu::pipeline::cleared_color_attachment;
        let colors = [
            attachment(hit.uv.view, vk::ImageLayout::GENERAL, [0.0; 4]),
            attachment(
                target.frame.view,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                [0.0; 4],
            ),
            attachment(
                hit.height.view,
                vk::ImageLayout::GENERAL,
                [NO_HIT_HEIGHT, 0.0, 0.0, 0.0],
            ),
            // 0.0's bits are the unsigned 0.
            attachment(hit.iterations.view, vk::ImageLayout::GENERAL, [0.0; 4]),
        ];
        let depth = crate::gpu::pipeline::cleared_depth_attachment(target.depth.view);
        let rendering = vk::RenderingInfo::default()
            .render_area(crate::gpu::pipeline::frame_area(extent))
            .layer_count(1)
            .color_attachments(&colors)
            .depth_attachment(&depth);
        let heights = [height.descriptor()];
        let buffers = [vk::DescriptorBufferInfo {
            buffer: self.params.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }];
        let ray_info = self.rays.info();
        let writes = [
            self.set.image(HEIGHT, &heights)?,
            self.set.buffer(MARCH, &buffers)?,
            self.set.buffer(PIXEL_RAYS, &ray_info)?,
        ];
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the pass (and its buffer) outlives the command buffer.
        unsafe { self.rays.record_update(ctx, cmd, rays)? };
        // SAFETY: this function's # Safety contract: `cmd` is recording; `extent` is the
        // size of attachments `Image::new` created (non-zero, within
        // `maxImageDimension2D`), which the viewport limits cover.
        unsafe { crate::gpu::pipeline::set_frame_viewport(ctx, cmd, extent) };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the attachments and the height texture are alive and in the layouts
        // named above (the caller's barriers); the writes match set 0's layout (both from
        // the shaders' reflection: the height texture, two uniform buffers the pass owns); the push
        // constants are the layout's range; the plane pipeline draws without vertex
        // buffers.
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
            dev.cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                0,
                bytemuck::bytes_of(params),
            );
            dev.cmd_draw(cmd, params.vertex_count(), 1, 0, 0);
            dev.cmd_end_rendering(cmd);
        }
        Ok(())
    }
}

impl Destroy for ForwardPass {
    /// Destroys the pipeline, its layouts and the parameter buffer. The GPU must be done
    /// with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            let dev = ctx.device();
            dev.destroy_pipeline(self.pipeline, None);
            dev.destroy_pipeline_layout(self.layout, None);
            dev.destroy_descriptor_set_layout(self.set_layout, None);
            self.pipeline = vk::Pipeline::null();
            self.layout = vk::PipelineLayout::null();
            self.set_layout = vk::DescriptorSetLayout::null();
            self.params.destroy(ctx);
            self.rays.destroy(ctx);
        }
    }
}
