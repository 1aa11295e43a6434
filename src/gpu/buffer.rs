//! Buffers with gpu-allocator memory.

use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use crate::gpu::owned::Destroy;
use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};

/// A buffer and its memory.
pub struct Buffer {
    /// The Vulkan handle.
    pub raw: vk::Buffer,
    /// Size in bytes.
    pub size: u64,
    allocation: Option<Allocation>,
    name: String,
}

impl Buffer {
    /// Creates a buffer named `name` in `location` memory.
    pub fn new(
        ctx: &Context,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self> {
        let info = vk::BufferCreateInfo::default()
            .size(size.max(1))
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid device and create info.
        let raw = unsafe { ctx.device().create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { ctx.device().get_buffer_memory_requirements(raw) };
        let allocation = ctx
            .allocator()
            .lock()
            .map_err(|_| {
                Error::Internal(
                    "the allocator's mutex is poisoned (a thread panicked holding it)".into(),
                )
            })?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            });
        let allocation = match allocation {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: not bound or used yet.
                unsafe { ctx.device().destroy_buffer(raw, None) };
                return Err(Error::Allocation {
                    name: name.into(),
                    source,
                });
            }
        };
        // SAFETY: memory and offset come from the allocator for these requirements.
        unsafe {
            ctx.device()
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        }
        .vk("vkBindBufferMemory")?;
        ctx.set_name(raw, name);
        Ok(Buffer {
            raw,
            size,
            allocation: Some(allocation),
            name: name.into(),
        })
    }

    /// The mapped bytes of a host-visible buffer.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..self.size as usize])
    }

    /// The mapped bytes of a host-visible buffer, writable.
    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        let size = self.size as usize;
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .map(|s| &mut s[..size])
    }
}

impl Destroy for Buffer {
    /// Destroys the buffer and frees its memory. The GPU must be done with it.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            if let Some(allocation) = self.allocation.take() {
                if let Ok(mut a) = ctx.allocator().lock() {
                    let _ = a.free(allocation);
                }
                ctx.device().destroy_buffer(self.raw, None);
                self.raw = vk::Buffer::null();
            }
        }
    }

    fn bytes(&self) -> u64 {
        self.allocation.as_ref().map_or(0, |a| a.size())
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.allocation.is_some() {
            log::warn!("buffer '{}' dropped without destroy(): leaked", self.name);
        }
    }
}
