//! `height_range`: the lowest and highest height of a map's level 0, reduced on the GPU
//! (`glsl/height_range.comp`), as a map preparation ([`crate::passes::prepare`]): a host
//! asks for it with `pass.set_map_preparation::<HeightRange>(true)` and reads a material's
//! with `pass.map_preparation::<HeightRange>(id)` and [`HeightRange::read`].
//!
//! What it is for: with heights in `[lo, hi]` (1 = the macro surface) the displaced
//! surface lies between `(1 - hi) * depth_scale` and `(1 - lo) * depth_scale` below the
//! base surface ([`HeightRange::depths`]), not anywhere in `[0, depth_scale]`: a host
//! tightens the bounding volumes it culls and casts shadows with, and the shell it draws
//! the displaced geometry in, to that span. For a map the host owns
//! ([`crate::embed::HostHeightMap`]: a BC4 image, a normal map's alpha) dispmap has no
//! texels on the CPU, so the range comes from the texture as the GPU decodes it, the
//! texels every pass reads.
//!
//! The result is exact (every texel is compared; the workgroups merge with atomics on
//! order-preserving keys of the float bits, so it is the same in any order) and lives in
//! a host-readable buffer of 8 bytes per map.

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::owned::Destroy;
use crate::gpu::sync::Access;
use crate::gpu::track::{Target, Tracker, binding_access};
use crate::gpu::{Buffer, ComputePipeline, HeightTexture};
use crate::passes::PassName;
use crate::passes::prepare::MapPreparation;
use crate::shaders;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The texels one invocation reduces along each axis (`BLOCK` in the shader).
const BLOCK: u32 = 4;

/// The shader's bindings, by GLSL name.
const BINDINGS: [(&str, vk::DescriptorType); 2] = [
    ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_range", vk::DescriptorType::STORAGE_BUFFER),
];

#[cfg(test)]
/// The key the shader merges with (`key` in the shader): `a < b` iff `key(a) < key(b)`
/// for non-NaN floats.
fn key(h: f32) -> u32 {
    let bits = h.to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The float of a key.
fn unkey(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 {
        k & 0x7fff_ffff
    } else {
        !k
    })
}

/// One map's height range: a host-readable buffer the build writes `(key(lo), key(hi))`
/// into.
pub struct HeightRange {
    buffer: Buffer,
}

impl HeightRange {
    /// `[lowest, highest]` height of the map's level 0.
    ///
    /// # Safety
    /// The command buffer that recorded its build (the record or preparation after
    /// which [`crate::embed::DisplacementPass::map_preparation`] returned it) has executed:
    /// its fence has signalled.
    pub unsafe fn read(&self) -> Result<[f32; 2]> {
        let bytes = self
            .buffer
            .mapped()
            .ok_or_else(|| Error::Internal("the height range's buffer is not mapped".into()))?;
        let keys: [u32; 2] = bytemuck::pod_read_unaligned(&bytes[..8]);
        Ok([unkey(keys[0]), unkey(keys[1])])
    }

    /// The depths below the base surface the displaced surface spans with `range` and
    /// `depth_scale`: `[(1 - hi) * depth_scale, (1 - lo) * depth_scale]`.
    pub fn depths(range: [f32; 2], depth_scale: f32) -> [f32; 2] {
        [
            (1.0 - range[1]) * depth_scale,
            (1.0 - range[0]) * depth_scale,
        ]
    }
}

impl Destroy for HeightRange {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses the buffer), passed on.
        unsafe { self.buffer.destroy(ctx) }
    }

    fn bytes(&self) -> u64 {
        self.buffer.bytes()
    }
}

/// The reduction's pipeline.
pub struct HeightRangePass {
    pipeline: ComputePipeline,
}

impl Destroy for HeightRangePass {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses the pipeline), passed on.
        unsafe { self.pipeline.destroy(ctx) }
    }
}

impl MapPreparation for HeightRange {
    const NAME: PassName = PassName::HeightRange;
    type Pass = HeightRangePass;

    fn new_pass(ctx: &Context) -> Result<HeightRangePass> {
        let pipeline = ComputePipeline::new(
            ctx,
            "height_range",
            &shaders::HEIGHT_RANGE_COMP,
            &BINDINGS,
            0,
        )?;
        Ok(HeightRangePass { pipeline })
    }

    fn new(ctx: &Context, _texture: &HeightTexture) -> Result<Self> {
        let buffer = Buffer::new(
            ctx,
            "height_range",
            8,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        Ok(HeightRange { buffer })
    }

    /// Resets the buffer to `(u32::MAX, 0)`, dispatches one invocation per `BLOCK²`
    /// texels and leaves the buffer visible to the host.
    unsafe fn record(
        pass: &HeightRangePass,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        texture: &HeightTexture,
        prepared: &HeightRange,
    ) -> Result<()> {
        let p = &pass.pipeline;
        let out = (p.bindings.iter().find(|b| b.name == "u_range"))
            .ok_or_else(|| Error::Internal("height_range.comp has no u_range".into()))?;
        let mut t = Tracker::new();
        t.enter((), Access::UNDEFINED);
        let memory = |()| Target::Memory;
        t.declare((), Access::BUFFER_TRANSFER_WRITE)?;
        // SAFETY: this function's contract: `cmd` is recording outside a render pass and
        // the buffer, new, lives until it has executed; the tracker places the barriers
        // between the reset, the dispatch and the host's read.
        unsafe {
            t.flush(ctx, cmd, memory)?;
            let reset: [u32; 2] = [u32::MAX, 0];
            ctx.device().cmd_update_buffer(
                cmd,
                prepared.buffer.raw,
                0,
                bytemuck::cast_slice(&reset),
            );
            t.declare((), binding_access(out))?;
            t.flush(ctx, cmd, memory)?;
            let heights = [texture.descriptor()];
            let range = [vk::DescriptorBufferInfo {
                buffer: prepared.buffer.raw,
                offset: 0,
                range: 8,
            }];
            let writes = [p.image("u_height", &heights)?, p.buffer("u_range", &range)?];
            let [w, h] = texture.size();
            p.dispatch(ctx, cmd, &writes, &[], w.div_ceil(BLOCK), h.div_ceil(BLOCK));
            t.declare((), Access::HOST_READ)?;
            t.flush(ctx, cmd, memory)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The keys order floats as floats do, and decode to them.
    #[test]
    fn keys_keep_the_order_of_the_floats() {
        let xs = [
            f32::NEG_INFINITY,
            -2.5,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            0.25,
            1.0,
            3.0e9,
            f32::INFINITY,
        ];
        for w in xs.windows(2) {
            assert!(key(w[0]) < key(w[1]), "{} < {}", w[0], w[1]);
        }
        for x in xs {
            assert_eq!(unkey(key(x)).to_bits(), x.to_bits());
        }
    }
}
