//! Standalone submissions: a command pool, one command buffer and a fence, plus the
//! upload and read-back copies built on them. Hosts never use this (they own their
//! command buffers); the CLI, tests and benchmarks do.

use super::sync::Access;
use super::track::{Handle, Tracker};
use super::{Buffer, Image};
use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use crate::gpu::owned::Destroy;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// A reusable command buffer submitted on the context's queue and waited for.
pub struct OneShot {
    pool: vk::CommandPool,
    /// The command buffer.
    pub cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

impl OneShot {
    /// Creates the pool, the command buffer and the fence, named after `name`.
    pub fn new(ctx: &Context, name: &str) -> Result<Self> {
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family_index())
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and create info.
        let pool =
            unsafe { ctx.device().create_command_pool(&info, None) }.vk("vkCreateCommandPool")?;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: `pool` is valid; one primary buffer.
        let cmd = unsafe { ctx.device().allocate_command_buffers(&alloc) }
            .vk("vkAllocateCommandBuffers")?[0];
        // SAFETY: valid device.
        let fence = unsafe {
            ctx.device()
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .vk("vkCreateFence")?;
        ctx.set_name(pool, &format!("{name}.pool"));
        ctx.set_name(cmd, &format!("{name}.cmd"));
        ctx.set_name(fence, &format!("{name}.fence"));
        Ok(OneShot { pool, cmd, fence })
    }

    /// Resets the command buffer and begins recording.
    pub fn begin(&self, ctx: &Context) -> Result<vk::CommandBuffer> {
        // SAFETY: the previous submission (if any) was waited for in `submit_and_wait`.
        unsafe {
            ctx.device()
                .reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())
                .vk("vkResetCommandBuffer")?;
            ctx.device()
                .begin_command_buffer(
                    self.cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .vk("vkBeginCommandBuffer")?;
        }
        Ok(self.cmd)
    }

    /// Ends recording, submits, and waits for the GPU to finish.
    pub fn submit_and_wait(&self, ctx: &Context) -> Result<()> {
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(self.cmd)];
        let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
        // SAFETY: the buffer was begun by `begin`; the fence is unsignalled (reset below
        // after each wait); the queue is only used from this thread in standalone mode.
        unsafe {
            ctx.device()
                .end_command_buffer(self.cmd)
                .vk("vkEndCommandBuffer")?;
            ctx.device()
                .queue_submit2(ctx.queue(), &submit, self.fence)
                .vk("vkQueueSubmit2")?;
            ctx.device()
                .wait_for_fences(&[self.fence], true, u64::MAX)
                .vk("vkWaitForFences")?;
            ctx.device()
                .reset_fences(&[self.fence])
                .vk("vkResetFences")?;
        }
        Ok(())
    }
}

impl Destroy for OneShot {
    /// Destroys the pool (and its buffer) and the fence. Nothing may be pending.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            ctx.device().destroy_fence(self.fence, None);
            ctx.device().destroy_command_pool(self.pool, None);
            self.fence = vk::Fence::null();
            self.pool = vk::CommandPool::null();
        }
    }
}

fn level_extent(image: &Image, level: u32) -> vk::Extent3D {
    vk::Extent3D {
        width: (image.extent.width >> level).max(1),
        height: (image.extent.height >> level).max(1),
        depth: 1,
    }
}

fn texel_bytes(image: &Image) -> Result<u64> {
    super::image::texel_size(image.format)
        .map(u64::from)
        .ok_or_else(|| {
            Error::invalid(
                image.name(),
                format!("no texel size for {:?}", image.format),
            )
        })
}

/// A host-visible `TRANSFER_SRC` buffer named `name` holding `bytes`.
pub fn staging_buffer(ctx: &Context, name: &str, bytes: &[u8]) -> Result<Buffer> {
    let mut staging = Buffer::new(
        ctx,
        name,
        bytes.len() as u64,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::CpuToGpu,
    )?;
    match staging.mapped_mut() {
        Some(mapped) => {
            mapped.copy_from_slice(bytes);
            Ok(staging)
        }
        None => {
            // SAFETY: built above and never used by a command.
            unsafe { staging.destroy(ctx) };
            Err(Error::invalid(name, "staging buffer is not mapped"))
        }
    }
}

/// Checks that `bytes` is exactly mip level 0 of `image`, tightly packed.
fn check_level0_bytes(image: &Image, bytes: &[u8]) -> Result<()> {
    let extent = level_extent(image, 0);
    let expected = texel_bytes(image)? * extent.width as u64 * extent.height as u64;
    if bytes.len() as u64 != expected {
        return Err(Error::invalid(
            image.name(),
            format!("upload of {} bytes, expected {expected}", bytes.len()),
        ));
    }
    Ok(())
}

/// A staging buffer for mip level 0 of `image` (checked to be exactly that size).
pub fn staging_for(ctx: &Context, image: &Image, bytes: &[u8]) -> Result<Buffer> {
    check_level0_bytes(image, bytes)?;
    staging_buffer(ctx, &format!("{}.staging", image.name()), bytes)
}

/// Uploads tightly packed `bytes` into mip level 0 of `image` and leaves it in `after`.
pub fn upload_image(
    ctx: &Context,
    shot: &OneShot,
    image: &Image,
    bytes: &[u8],
    after: Access,
) -> Result<()> {
    let mut staging = staging_for(ctx, image, bytes)?;
    let result = (|| {
        let cmd = shot.begin(ctx)?;
        // SAFETY: `cmd` was just begun; the staging buffer holds level 0.
        unsafe { record_upload_level0(ctx, cmd, &staging, image, after)? };
        shot.submit_and_wait(ctx)
    })();
    // SAFETY: the one-shot submission that used it was waited for (or never made).
    unsafe { staging.destroy(ctx) };
    result
}

/// Records the upload of `staging` into mip level 0 of `image`: its contents discarded
/// -> `TRANSFER_DST_OPTIMAL`, the copy, then -> `after`.
///
/// # Safety
/// As [`record_copy_to_level0`], except that level 0 may be in any layout on entry (its
/// contents are discarded, its earlier accesses must have completed): `cmd` is a command
/// buffer of `ctx`'s device in the recording state, outside a render pass instance, for
/// a queue of the context's queue family; `staging` holds level 0 tightly packed; both
/// stay alive until the command buffer has executed; `after.layout` is one the image's
/// usage allows.
pub unsafe fn record_upload_level0(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    staging: &Buffer,
    image: &Image,
    after: Access,
) -> Result<()> {
    // Level 0 is discarded (no earlier access pending: this function's contract), written
    // by the copy, then left as `after`; the tracker places the barriers.
    let level0 = Handle::level(image, 0);
    let mut t = Tracker::new();
    t.enter(level0, Access::UNDEFINED);
    let step = |t: &mut Tracker<Handle>, access| -> Result<()> {
        t.declare(level0, access)?;
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass and `image` is alive; level 0 entered discarded.
        unsafe { t.record(ctx, cmd) }
    };
    step(&mut t, Access::TRANSFER_WRITE)?;
    // SAFETY: as above; level 0 is in `TRANSFER_DST_OPTIMAL` (the barrier above) and
    // `staging` holds it tightly packed (this function's contract).
    unsafe { record_copy_to_level0(ctx, cmd, staging, image) };
    step(&mut t, after)
}

/// Records the copy of `staging` (tightly packed texels) into mip level 0 of `image`,
/// which must be in `TRANSFER_DST_OPTIMAL` ([`Access::TRANSFER_WRITE`]).
///
/// # Safety
/// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
///   render pass instance, for a queue of the context's queue family.
/// * `image` was created with `TRANSFER_DST` usage in a format [`texel_size`] knows,
///   and when the copy executes its level 0 is in `TRANSFER_DST_OPTIMAL`, earlier
///   accesses ordered before the transfer (the caller's barrier).
/// * `staging` was created with `TRANSFER_SRC` usage and holds at least level 0's
///   texels, tightly packed (as [`staging_for`] makes it).
/// * Both stay alive until the command buffer has executed.
///
/// [`texel_size`]: super::image::texel_size
pub unsafe fn record_copy_to_level0(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    staging: &Buffer,
    image: &Image,
) {
    let region = vk::BufferImageCopy::default()
        .image_subresource(vk::ImageSubresourceLayers {
            aspect_mask: image.range().aspect_mask,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        })
        .image_extent(level_extent(image, 0));
    // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
    // pass; level 0 is in `TRANSFER_DST_OPTIMAL`; the buffer holds the image's tightly
    // packed level 0 and both are alive.
    unsafe {
        ctx.device().cmd_copy_buffer_to_image(
            cmd,
            staging.raw,
            image.raw,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &[region],
        )
    };
}

/// Reads mip level 0 of `image`, currently in `current`, back to tightly packed bytes;
/// the image is returned to `current` afterwards.
pub fn read_image(
    ctx: &Context,
    shot: &OneShot,
    image: &Image,
    current: Access,
) -> Result<Vec<u8>> {
    read_image_level(ctx, shot, image, 0, current)
}

/// Reads mip level `level` of `image` (every level in `current`) back to tightly packed
/// bytes; the level is returned to `current` afterwards.
pub fn read_image_level(
    ctx: &Context,
    shot: &OneShot,
    image: &Image,
    level: u32,
    current: Access,
) -> Result<Vec<u8>> {
    if level >= image.mip_levels {
        return Err(Error::invalid(
            image.name(),
            format!("no mip level {level} (it has {})", image.mip_levels),
        ));
    }
    let extent = level_extent(image, level);
    let size = texel_bytes(image)? * extent.width as u64 * extent.height as u64;
    let mut staging = Buffer::new(
        ctx,
        &format!("{}.readback", image.name()),
        size,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuToCpu,
    )?;
    let result = (|| {
        let cmd = shot.begin(ctx)?;
        // The level enters in `current` (this function's documented input), is read by
        // the copy and returned to `current`; the copy's writes are made visible to the
        // host. The tracker places the barriers.
        let (source, target) = (Handle::level(image, level), Handle::buffer(&staging));
        let mut t = Tracker::new();
        t.enter(source, current);
        t.enter(target, Access::UNDEFINED);
        t.declare(source, Access::TRANSFER_READ)?;
        t.declare(target, Access::BUFFER_TRANSFER_WRITE)?;
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below, while `image`
        // and `staging` are alive; the level is in `current`, the buffer new.
        unsafe { t.record(ctx, cmd)? };
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: image.range().aspect_mask,
                mip_level: level,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(extent);
        // SAFETY: `cmd` is recording; buffer and image are alive and sized for the copy.
        unsafe {
            ctx.device().cmd_copy_image_to_buffer(
                cmd,
                image.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                staging.raw,
                &[region],
            )
        };
        t.declare(source, current)?;
        t.declare(target, Access::HOST_READ)?;
        // SAFETY: as above; the level is in `TRANSFER_SRC_OPTIMAL` after the copy.
        unsafe { t.record(ctx, cmd)? };
        shot.submit_and_wait(ctx)?;
        staging
            .mapped()
            .map(<[u8]>::to_vec)
            .ok_or_else(|| Error::invalid(image.name(), "read-back buffer is not mapped"))
    })();
    // SAFETY: the one-shot submission that used it was waited for (or never made).
    unsafe { staging.destroy(ctx) };
    result
}
