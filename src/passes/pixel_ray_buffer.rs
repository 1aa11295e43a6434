//! The uniform buffer of the frame's pixel rays ([`PixelRayParams`]) that the plane's
//! fragment stages read (`glsl/gbuffer.frag`, `glsl/forward/forward.glsl`): device-local,
//! written in the command buffer (`vkCmdUpdateBuffer`) before the draw that reads it, so
//! that frames in flight each read their own camera without a host write racing the GPU.

use crate::abi::PixelRayParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::Buffer;
use crate::gpu::owned::Destroy;
use crate::gpu::sync::Access;
use crate::gpu::track::{Handle, Tracker};
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
    ) -> Result<()> {
        // The buffer enters after the previous frame's fragment reads, is written by the
        // update and then read by this frame's fragments; the tracker places the
        // barriers (write-after-read, then read-after-write).
        let buffer = Handle::buffer(&self.buffer);
        let mut t = Tracker::new();
        t.enter(buffer, Access::FRAGMENT_UNIFORM_READ);
        t.declare(buffer, Access::BUFFER_TRANSFER_WRITE)?;
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the update is 128 bytes (a multiple of 4, under 65536) of a live buffer
        // with TRANSFER_DST usage.
        unsafe {
            t.record(ctx, cmd)?;
            ctx.device()
                .cmd_update_buffer(cmd, self.buffer.raw, 0, bytemuck::bytes_of(rays));
        }
        t.declare(buffer, Access::FRAGMENT_UNIFORM_READ)?;
        // SAFETY: as above.
        unsafe { t.record(ctx, cmd) }
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
