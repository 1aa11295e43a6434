//! Image and memory barriers (synchronization2).

use super::Image;
use crate::context::Context;
use ash::vk;

/// One side of a barrier: the pipeline stage, access and layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Access {
    /// Pipeline stage(s).
    pub stage: vk::PipelineStageFlags2,
    /// Memory access(es).
    pub access: vk::AccessFlags2,
    /// Image layout.
    pub layout: vk::ImageLayout,
}

impl Access {
    /// Nothing before: the contents are discarded.
    pub const UNDEFINED: Access = Access {
        stage: vk::PipelineStageFlags2::NONE,
        access: vk::AccessFlags2::NONE,
        layout: vk::ImageLayout::UNDEFINED,
    };
    /// Written as a colour attachment.
    pub const COLOR_ATTACHMENT_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
        access: vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
        layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
    };
    /// Tested and written as a depth attachment.
    pub const DEPTH_ATTACHMENT_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::from_raw(
            vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS.as_raw()
                | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS.as_raw(),
        ),
        access: vk::AccessFlags2::from_raw(
            vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ.as_raw()
                | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE.as_raw(),
        ),
        layout: vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
    };
    /// Sampled (texelFetch / texture) by compute shaders.
    pub const COMPUTE_SAMPLED: Access = Access {
        stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
        access: vk::AccessFlags2::SHADER_SAMPLED_READ,
        layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
    };
    /// Written as a storage image by compute shaders.
    pub const COMPUTE_STORAGE_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
        access: vk::AccessFlags2::SHADER_STORAGE_WRITE,
        layout: vk::ImageLayout::GENERAL,
    };
    /// A buffer read by compute shaders and as indirect commands (dispatches and draws):
    /// a list of tiles and the commands written from it.
    pub const INDIRECT_READ: Access = Access {
        stage: vk::PipelineStageFlags2::from_raw(
            vk::PipelineStageFlags2::DRAW_INDIRECT.as_raw()
                | vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw(),
        ),
        access: vk::AccessFlags2::from_raw(
            vk::AccessFlags2::INDIRECT_COMMAND_READ.as_raw()
                | vk::AccessFlags2::SHADER_STORAGE_READ.as_raw(),
        ),
        layout: vk::ImageLayout::UNDEFINED,
    };
    /// Read as a storage image by compute shaders.
    pub const COMPUTE_STORAGE_READ: Access = Access {
        stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
        access: vk::AccessFlags2::SHADER_STORAGE_READ,
        layout: vk::ImageLayout::GENERAL,
    };
    /// Read and written in place as a storage image by compute shaders (a host's motion
    /// image for the `motion` stage).
    pub const COMPUTE_STORAGE_READ_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
        access: vk::AccessFlags2::from_raw(
            vk::AccessFlags2::SHADER_STORAGE_READ.as_raw()
                | vk::AccessFlags2::SHADER_STORAGE_WRITE.as_raw(),
        ),
        layout: vk::ImageLayout::GENERAL,
    };
    /// Read as a uniform buffer by fragment shaders (the G-buffer's pixel-ray
    /// parameters; the layout is meaningless for a buffer).
    pub const FRAGMENT_UNIFORM_READ: Access = Access {
        stage: vk::PipelineStageFlags2::FRAGMENT_SHADER,
        access: vk::AccessFlags2::UNIFORM_READ,
        layout: vk::ImageLayout::UNDEFINED,
    };
    /// Source of a copy or blit.
    pub const TRANSFER_READ: Access = Access {
        stage: vk::PipelineStageFlags2::ALL_TRANSFER,
        access: vk::AccessFlags2::TRANSFER_READ,
        layout: vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
    };
    /// Destination of a copy or blit.
    pub const TRANSFER_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::ALL_TRANSFER,
        access: vk::AccessFlags2::TRANSFER_WRITE,
        layout: vk::ImageLayout::TRANSFER_DST_OPTIMAL,
    };
    /// A buffer written by a copy or an update (`vkCmdUpdateBuffer`).
    pub const BUFFER_TRANSFER_WRITE: Access = Access {
        stage: vk::PipelineStageFlags2::ALL_TRANSFER,
        access: vk::AccessFlags2::TRANSFER_WRITE,
        layout: vk::ImageLayout::UNDEFINED,
    };
    /// A buffer read by the host after the submission completed.
    pub const HOST_READ: Access = Access {
        stage: vk::PipelineStageFlags2::HOST,
        access: vk::AccessFlags2::HOST_READ,
        layout: vk::ImageLayout::UNDEFINED,
    };
}

/// An image barrier from `before` to `after` over `range`.
pub fn image_barrier(
    image: vk::Image,
    range: vk::ImageSubresourceRange,
    before: Access,
    after: Access,
) -> vk::ImageMemoryBarrier2<'static> {
    vk::ImageMemoryBarrier2::default()
        .image(image)
        .subresource_range(range)
        .src_stage_mask(before.stage)
        .src_access_mask(before.access)
        .old_layout(before.layout)
        .dst_stage_mask(after.stage)
        .dst_access_mask(after.access)
        .new_layout(after.layout)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
}

/// A global memory barrier from `before` to `after` (their layouts are ignored): for
/// buffers, whose every access it orders.
pub fn memory_barrier(before: Access, after: Access) -> vk::MemoryBarrier2<'static> {
    vk::MemoryBarrier2::default()
        .src_stage_mask(before.stage)
        .src_access_mask(before.access)
        .dst_stage_mask(after.stage)
        .dst_access_mask(after.access)
}

/// Records `barriers` in one `vkCmdPipelineBarrier2` (nothing when `barriers` is
/// empty). Several barriers recorded together are one command: batch those that belong
/// to the same point of the frame.
///
/// # Safety
/// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
///   render pass instance, for a queue of the context's queue family.
/// * Every barrier's image belongs to that device and stays alive until the command
///   buffer has executed; its subresource range lies within the image.
/// * When the command buffer executes, every subresource of a barrier's range is in the
///   barrier's `old_layout` (or that layout is `UNDEFINED`: the contents are
///   discarded), and its `new_layout` is one the image's usage allows (e.g.
///   `COLOR_ATTACHMENT_OPTIMAL` needs `COLOR_ATTACHMENT`).
pub unsafe fn record(ctx: &Context, cmd: vk::CommandBuffer, barriers: &[vk::ImageMemoryBarrier2]) {
    if barriers.is_empty() {
        return;
    }
    let dep = vk::DependencyInfo::default().image_memory_barriers(barriers);
    // SAFETY: this function's # Safety contract: `cmd` is recording outside a render pass
    // and the barriers' images are alive, in their old layouts.
    unsafe { ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
}

/// Records one barrier of `image`'s whole range ([`Image::range`]: every level, the
/// format's aspect) from `before` to `after`: the same command as [`record`] with the
/// one [`image_barrier`].
///
/// # Safety
/// As [`record`] for that barrier: `cmd` is a command buffer of `ctx`'s device in the
/// recording state, outside a render pass instance, for a queue of the context's queue
/// family; `image` stays alive until the command buffer has executed; when it executes,
/// every level of `image` is in `before.layout` (or that is `UNDEFINED`: the contents are
/// discarded), its earlier accesses are covered by `before`'s stages and accesses, and
/// `after.layout` is one the image's usage allows.
pub unsafe fn transition(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    image: &Image,
    before: Access,
    after: Access,
) {
    // SAFETY: this function's # Safety contract is `record`'s for this one barrier over
    // `image`'s own full range.
    unsafe {
        record(
            ctx,
            cmd,
            &[image_barrier(image.raw, image.range(), before, after)],
        )
    };
}
