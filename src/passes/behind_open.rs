//! The behind layer's listed tiles opened (graphics, first in the layer's own rendering
//! instance, on the route that classifies the missed tiles only: a CPU driver's). The
//! layer's depth is cleared to [`BLOCK_DEPTH`] (reverse-Z nearest) and its colour
//! attachments are not cleared at all; this pass then writes the G-buffer's clear values
//! (zero ray, frame and curve, depth 0) over the 8x8 tiles `behind_cull` listed (two
//! triangles per tile, one instance per listed tile, its count read by an indirect
//! draw). The layer's objects drawn after it pass their `GREATER` depth test only in
//! those tiles: elsewhere no fragment is shaded, and no full-frame clear of the colour
//! attachments is paid for. Inside the listed tiles the G-buffer is the one the whole
//! cleared raster writes, bit for bit; outside them its depth is [`BLOCK_DEPTH`] and its
//! colours are undefined, which nothing reads (the layer's light and its second record
//! run over the listed tiles only).
//!
//! Bindings (set 0, push descriptors): `u_list` (`glsl/behind_cull.comp`'s list, a storage
//! buffer read by the vertex stage). Push constant: the frame's size. The pipeline's
//! attachments are the G-buffer's ([`RAY_FORMAT`], [`FRAME_FORMAT`], with the curve image
//! [`CURVE_FORMAT`], [`DEPTH_FORMAT`]), depth test `ALWAYS` with writes.

use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{RasterDesc, RasterSet, raster_pipeline};
#[cfg(doc)]
use crate::passes::behind_mask::BLOCK_DEPTH;
use crate::passes::gbuffer::{CURVE_FORMAT, DEPTH_FORMAT, FRAME_FORMAT, RAY_FORMAT};
use crate::shaders;
use ash::vk;

/// The GLSL name of the list's binding (`glsl/behind_open.vert`).
const LIST: &str = "u_list";

/// Bytes of the draw command this pass reads (a `VkDrawIndirectCommand`).
pub const DRAW_BYTES: u64 = 16;

/// Set 0 as the shaders declare it (the curve variant's fragment stage binds nothing
/// more).
pub(crate) fn raster_set(curve: bool) -> Result<RasterSet> {
    RasterSet::new(
        &[
            (&shaders::BEHIND_OPEN_VERT, vk::ShaderStageFlags::VERTEX),
            (fragment(curve), vk::ShaderStageFlags::FRAGMENT),
        ],
        &[(LIST, vk::DescriptorType::STORAGE_BUFFER)],
    )
}

fn fragment(curve: bool) -> &'static shaders::Shader {
    if curve {
        &shaders::BEHIND_OPEN_FRAG_CURVE
    } else {
        &shaders::BEHIND_OPEN_FRAG
    }
}

/// The listed tiles' draw: its command (four words, written on the GPU) and the list.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OpenTiles {
    /// The list (`u_list`).
    pub list: vk::DescriptorBufferInfo,
    /// The buffer and offset of its `VkDrawIndirectCommand`: 6 vertices, one instance per
    /// listed tile.
    pub command: (vk::Buffer, u64),
}

/// The pass's pipeline, for a G-buffer with or without the curve image.
#[derive(Debug)]
pub struct BehindOpenPass {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    set: RasterSet,
    curve: bool,
}

impl BehindOpenPass {
    /// Builds the pipeline (dynamic rendering with the G-buffer's attachments, the curve
    /// image among them when `curve`).
    pub fn new(ctx: &Context, curve: bool) -> Result<Self> {
        let mut pass = BehindOpenPass {
            pipeline: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            set: raster_set(curve)?,
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
        self.set_layout = self.set.set_layout(ctx, "behind_open.set_layout")?;
        let set_layouts = [self.set_layout];
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX)
            .size(std::mem::size_of::<[f32; 2]>() as u32)];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&ranges);
        // SAFETY: valid device and set layout.
        self.layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")?;
        ctx.set_name(self.layout, "behind_open.layout");
        self.pipeline = raster_pipeline(
            ctx,
            &RasterDesc {
                vert: &shaders::BEHIND_OPEN_VERT,
                frag: fragment(self.curve),
                layout: self.layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::ALWAYS,
                color_formats: &[RAY_FORMAT, FRAME_FORMAT, CURVE_FORMAT]
                    [..2 + usize::from(self.curve)],
                depth_format: DEPTH_FORMAT,
                name: "behind_open.pipeline",
            },
        )?;
        Ok(())
    }

    /// Records the listed tiles' draw (`tiles`) into a frame of `extent`.
    ///
    /// # Safety
    /// * `cmd` is recording inside a dynamic rendering instance whose attachments have the
    ///   G-buffer's formats (the curve image's as [`BehindOpenPass::has_curve`] says), the
    ///   viewport and scissor set.
    /// * When it executes, the list and the command were written and made visible to
    ///   vertex-shader storage reads and indirect reads; the command's instance count is
    ///   at most the list's length; the buffer and this pass stay alive until the command
    ///   buffer has executed.
    pub(crate) unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        tiles: OpenTiles,
        extent: vk::Extent2D,
    ) -> Result<()> {
        let list = [tiles.list];
        let writes = [self.set.buffer(LIST, &list)?];
        let size = [extent.width as f32, extent.height as f32];
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording inside a rendering
        // instance with matching attachments; the write matches the set layout (both from
        // the shaders' reflection); the push constant range is the layout's; the command
        // lies inside the buffer (4-byte aligned).
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
                bytemuck::bytes_of(&size),
            );
            dev.cmd_draw_indirect(cmd, tiles.command.0, tiles.command.1, 1, DRAW_BYTES as u32);
        }
        Ok(())
    }
}

impl Destroy for BehindOpenPass {
    /// Destroys the pipeline and layouts and nulls their handles (a second call does
    /// nothing).
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
        }
    }
}
