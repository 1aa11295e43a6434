//! A mesh's vertex and index buffers on the GPU, filled once through a staging buffer.

use super::Mesh;
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::owned::Destroy;
use crate::gpu::sync::Access;
use crate::gpu::track::{Target, Tracker};
use crate::gpu::{Buffer, OneShot};
use ash::vk;
use gpu_allocator::MemoryLocation;

const VERTICES: u8 = 0;
const INDICES: u8 = 1;

/// A buffer nothing has accessed.
const NEW: Access = Access::UNDEFINED;
/// Written by a copy.
const COPY_WRITE: Access = Access {
    layout: vk::ImageLayout::UNDEFINED,
    ..Access::TRANSFER_WRITE
};
/// Read as vertex attributes.
const VERTEX_READ: Access = Access {
    stage: vk::PipelineStageFlags2::VERTEX_ATTRIBUTE_INPUT,
    access: vk::AccessFlags2::VERTEX_ATTRIBUTE_READ,
    layout: vk::ImageLayout::UNDEFINED,
};
/// Read as indices.
const INDEX_READ: Access = Access {
    stage: vk::PipelineStageFlags2::INDEX_INPUT,
    access: vk::AccessFlags2::INDEX_READ,
    layout: vk::ImageLayout::UNDEFINED,
};

/// A mesh's vertex and index buffers in device-local memory (filled once through a
/// staging buffer).
pub struct MeshBuffers {
    /// Vertices ([`Vertex`](super::Vertex)).
    pub vertices: Buffer,
    /// `u32` indices.
    pub indices: Buffer,
    /// Number of indices.
    pub index_count: u32,
    /// [`Mesh::two_sided`]: drawn with the two-sided G-buffer pipeline.
    pub two_sided: bool,
}

impl MeshBuffers {
    /// Creates the buffers (named after the mesh), copies the mesh into them on `shot`
    /// and waits; the copy is made visible to vertex input (a barrier from the transfer
    /// to `VERTEX_ATTRIBUTE_INPUT` / `INDEX_INPUT` reads in the same submission).
    pub fn upload(ctx: &Context, shot: &OneShot, mesh: &Mesh) -> Result<Self> {
        let vertex_bytes: &[u8] = bytemuck::cast_slice(&mesh.vertices);
        let index_bytes: &[u8] = bytemuck::cast_slice(&mesh.indices);
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        let mut vertices = Buffer::new(
            ctx,
            &format!("mesh[{}].vertices", mesh.label),
            vertex_bytes.len() as u64,
            vk::BufferUsageFlags::VERTEX_BUFFER | dst,
            MemoryLocation::GpuOnly,
        )?;
        let mut indices = match Buffer::new(
            ctx,
            &format!("mesh[{}].indices", mesh.label),
            index_bytes.len() as u64,
            vk::BufferUsageFlags::INDEX_BUFFER | dst,
            MemoryLocation::GpuOnly,
        ) {
            Ok(b) => b,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { vertices.destroy(ctx) };
                return Err(e);
            }
        };
        let mut staging = match Buffer::new(
            ctx,
            &format!("mesh[{}].staging", mesh.label),
            (vertex_bytes.len() + index_bytes.len()) as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        ) {
            Ok(b) => b,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { vertices.destroy(ctx) };
                // SAFETY: built above and never used by a command.
                unsafe { indices.destroy(ctx) };
                return Err(e);
            }
        };
        let copied = (|| {
            let bytes = staging.mapped_mut().ok_or_else(|| {
                Error::invalid(mesh.label.clone(), "staging buffer is not mapped")
            })?;
            bytes[..vertex_bytes.len()].copy_from_slice(vertex_bytes);
            bytes[vertex_bytes.len()..].copy_from_slice(index_bytes);
            let cmd = shot.begin(ctx)?;
            // The new buffers: written by the copies, then read as vertex input; the
            // tracker derives the barrier between.
            let mut t = Tracker::new();
            for key in [VERTICES, INDICES] {
                t.enter(key, NEW);
            }
            t.declare(VERTICES, COPY_WRITE)?;
            t.declare(INDICES, COPY_WRITE)?;
            // SAFETY: `cmd` is recording outside a render pass; nothing has accessed the
            // new buffers (no barrier is needed, none is recorded).
            unsafe { t.flush(ctx, cmd, |_| Target::Memory)? };
            // SAFETY: `cmd` is recording; the three buffers are alive and large enough
            // for the regions (sizes computed from the same slices).
            unsafe {
                ctx.device().cmd_copy_buffer(
                    cmd,
                    staging.raw,
                    vertices.raw,
                    &[vk::BufferCopy {
                        src_offset: 0,
                        dst_offset: 0,
                        size: vertex_bytes.len() as u64,
                    }],
                );
                ctx.device().cmd_copy_buffer(
                    cmd,
                    staging.raw,
                    indices.raw,
                    &[vk::BufferCopy {
                        src_offset: vertex_bytes.len() as u64,
                        dst_offset: 0,
                        size: index_bytes.len() as u64,
                    }],
                );
            }
            t.declare(VERTICES, VERTEX_READ)?;
            t.declare(INDICES, INDEX_READ)?;
            // SAFETY: `cmd` is recording outside a render pass; the buffers are alive.
            unsafe { t.flush(ctx, cmd, |_| Target::Memory)? };
            shot.submit_and_wait(ctx)
        })();
        // SAFETY: the one-shot submission that used it was waited for (or never made).
        unsafe { staging.destroy(ctx) };
        if let Err(e) = copied {
            // SAFETY: the one-shot submission that used it was waited for (or never made).
            unsafe { vertices.destroy(ctx) };
            // SAFETY: the one-shot submission that used it was waited for (or never made).
            unsafe { indices.destroy(ctx) };
            return Err(e);
        }
        Ok(MeshBuffers {
            vertices,
            indices,
            index_count: mesh.indices.len() as u32,
            two_sided: mesh.two_sided,
        })
    }
}

impl Destroy for MeshBuffers {
    /// Destroys the buffers. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.vertices.destroy(ctx);
            self.indices.destroy(ctx);
        }
    }
}
