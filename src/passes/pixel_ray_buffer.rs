//! The uniform buffer of the frame's pixel rays ([`PixelRayParams`]) that the plane's
//! fragment stages read (`glsl/gbuffer.frag`, `glsl/forward/forward.glsl`): device-local,
//! written in the command buffer (`vkCmdUpdateBuffer`) before the draw that reads it, so
//! that frames in flight each read their own camera without a host write racing the GPU.

use crate::abi::PixelRayParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::Buffer;
use crate::gpu::owned::Destroy;
use crate::gpu::sync::{self, Access};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The buffer (see the module docs).
pub struct PixelRayBuffer {
    buffer: Buffer,
}

impl PixelRayBuffer {
    /// Creates the buffer, named `name`.
    pub fn new(ctx: &Context, name: &str) -> Result<Self> {
        Ok(PixelRayBuffer {
            buffer: Buffer::new(
                ctx,
                name,
                std::mem::size_of::<PixelRayParams>() as u64,
                vk::BufferUsageFlags::UNIFORM_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuOnly,
            )?,
        })
    }

    /// Records the write of `rays`, ordered after every earlier fragment-shader read of
    /// the buffer (earlier frames on the queue) and before every later one.
    ///
    /// # Safety
    /// `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    /// render pass instance, for a queue of the context's queue family; this buffer stays
    /// alive until the command buffer has executed.
    pub unsafe fn record_update(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        rays: &PixelRayParams,
    ) {
        // The previous frame's fragment reads before the write (write-after-read), the
        // write before this frame's reads.
        let before = [sync::memory_barrier(
            Access::FRAGMENT_UNIFORM_READ,
            Access::TRANSFER_WRITE,
        )];
        let after = [sync::memory_barrier(
            Access::TRANSFER_WRITE,
            Access::FRAGMENT_UNIFORM_READ,
        )];
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the update is 128 bytes (a multiple of 4, under 65536) of a live buffer
        // with TRANSFER_DST usage.
        unsafe {
            dev.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().memory_barriers(&before));
            dev.cmd_update_buffer(cmd, self.buffer.raw, 0, bytemuck::bytes_of(rays));
            dev.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().memory_barriers(&after));
        }
    }

    /// The descriptor of the whole buffer.
    pub fn info(&self) -> [vk::DescriptorBufferInfo; 1] {
        [vk::DescriptorBufferInfo {
            buffer: self.buffer.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }]
    }
}

impl Destroy for PixelRayBuffer {
    /// Destroys the buffer. The GPU must be done with it.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.buffer.destroy(ctx);
        }
    }
}
