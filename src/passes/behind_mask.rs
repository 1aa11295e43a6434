//! The behind layer's mask (graphics, inside the layer's own rendering instance): keeps
//! the layer's raster to the pixels whose first-layer trace missed. Before the layer's
//! objects, one full-screen triangle at depth 1 (reverse-Z nearest) writes every other
//! pixel (`glsl/behind_mask.frag` discards the missed ones), so the objects' `GREATER`
//! depth test rejects their fragments there before any fragment shading; after the
//! objects, the same triangle at depth 0 writes those pixels back to the clear values
//! (depth 0, zero ray and frame). The layer's G-buffer is then the one the unmasked
//! raster writes, bit for bit; its raster costs two full-screen passes of two texel
//! reads each plus the objects' fragments at the missed pixels, instead of every
//! object's fragments over the whole frame.
//!
//! Bindings (set 0, push descriptors): `u_first_depth` (the first layer's G-buffer depth,
//! sampled, `SHADER_READ_ONLY_OPTIMAL`), `u_first_hit_height` (its hit height, a storage
//! image read, `GENERAL`). Push constant: the triangle's depth. The pipeline's attachments are
//! the G-buffer's ([`RAY_FORMAT`], [`FRAME_FORMAT`], with the curve image [`CURVE_FORMAT`]
//! for a curved frame, written as zero; [`DEPTH_FORMAT`]), depth test `ALWAYS` with
//! writes.

use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{RasterDesc, RasterSet, raster_pipeline};
use crate::passes::gbuffer::{CURVE_FORMAT, DEPTH_FORMAT, FRAME_FORMAT, FirstLayer, RAY_FORMAT};
use crate::shaders;
use ash::vk;

/// The GLSL names of the bindings (`glsl/behind_mask.frag`).
const FIRST_DEPTH: &str = "u_first_depth";
const FIRST_HIT: &str = "u_first_hit_height";

/// The depth the mask blocks the layer's objects with (reverse-Z nearest: no fragment
/// passes `GREATER` against it).
pub const BLOCK_DEPTH: f32 = 1.0;
/// The depth the mask restores after the objects (the G-buffer's clear value).
pub const CLEAR_DEPTH: f32 = 0.0;

/// Set 0 as the shaders declare it (the curve variant's fragment stage binds nothing
/// more).
pub(crate) fn raster_set(curve: bool) -> Result<RasterSet> {
    RasterSet::new(
        &[
            (&shaders::BEHIND_MASK_VERT, vk::ShaderStageFlags::VERTEX),
            (fragment(curve), vk::ShaderStageFlags::FRAGMENT),
        ],
        &[
            (FIRST_DEPTH, vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
            (FIRST_HIT, vk::DescriptorType::STORAGE_IMAGE),
        ],
    )
}

fn fragment(curve: bool) -> &'static shaders::Shader {
    if curve {
        &shaders::BEHIND_MASK_FRAG_CURVE
    } else {
        &shaders::BEHIND_MASK_FRAG
    }
}

/// The mask's pipeline.
pub struct BehindMaskPass {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    set: RasterSet,
    sampler: vk::Sampler,
    curve: bool,
}

impl BehindMaskPass {
    /// Builds the pipeline (dynamic rendering with the G-buffer's attachments, the curve
    /// image among them when `curve`).
    pub fn new(ctx: &Context, curve: bool) -> Result<Self> {
        let set = raster_set(curve)?;
        let sampler = crate::gpu::pipeline::sampler(
            ctx,
            "behind_mask.sampler",
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        )?;
        let mut pass = BehindMaskPass {
            pipeline: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            set,
            sampler,
            curve,
        };
        // On failure `pass` is destroyed with what exists.
        match pass.build(ctx) {
            Ok(()) => Ok(pass),
            Err(e) => {
                // SAFETY: never recorded.
                unsafe { pass.destroy(ctx) };
                Err(e)
            }
        }
    }

    /// Whether it draws into a G-buffer with the curve image.
    pub fn has_curve(&self) -> bool {
        self.curve
    }

    fn build(&mut self, ctx: &Context) -> Result<()> {
        let dev = ctx.device();
        self.set_layout = self.set.set_layout(ctx, "behind_mask.set_layout")?;
        let set_layouts = [self.set_layout];
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX)
            .size(std::mem::size_of::<f32>() as u32)];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&ranges);
        // SAFETY: valid device and set layout.
        self.layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")?;
        ctx.set_name(self.layout, "behind_mask.layout");
        self.pipeline = raster_pipeline(
            ctx,
            &RasterDesc {
                vert: &shaders::BEHIND_MASK_VERT,
                frag: fragment(self.curve),
                layout: self.layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::ALWAYS,
                color_formats: &[RAY_FORMAT, FRAME_FORMAT, CURVE_FORMAT]
                    [..2 + usize::from(self.curve)],
                depth_format: DEPTH_FORMAT,
                name: "behind_mask.pipeline",
            },
        )?;
        Ok(())
    }

    /// Records one full-screen triangle at `depth` ([`BLOCK_DEPTH`] or [`CLEAR_DEPTH`])
    /// over every pixel but the missed ones of `first`.
    ///
    /// # Safety
    /// * `cmd` is recording inside a dynamic rendering instance whose attachments have the
    ///   G-buffer's formats, the viewport and scissor set.
    /// * When it executes, `first.depth` is in `SHADER_READ_ONLY_OPTIMAL` and `first.hit_height`
    ///   in `GENERAL`, their writes visible to fragment-shader reads; both and this pass
    ///   stay alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        first: FirstLayer,
        depth: f32,
    ) -> Result<()> {
        let depth_info = [vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: first.depth,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }];
        let hit_info = crate::gpu::pipeline::storage_view(first.hit_height);
        let writes = [
            self.set.image(FIRST_DEPTH, &depth_info)?,
            self.set.image(FIRST_HIT, &hit_info)?,
        ];
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording inside a rendering
        // instance with matching attachments; the writes match the set layout (both from
        // the shaders' reflection); the push constant range is the layout's.
        unsafe {
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
                vk::ShaderStageFlags::VERTEX,
                0,
                &depth.to_ne_bytes(),
            );
            dev.cmd_draw(cmd, 3, 1, 0, 0);
        }
        Ok(())
    }
}

impl Destroy for BehindMaskPass {
    /// Destroys the pipeline, layouts and sampler and nulls their handles (a second call
    /// does nothing).
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
