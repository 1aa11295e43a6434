//! The `pyramid` pass: the max-height pyramid (Oh, Ki & Lee's minimum-displacement
//! pyramid; Tevs et al.'s maximum mipmap), built on the GPU by a chain of compute
//! dispatches, each writing up to three levels (a level and the two above it, from
//! shared reads of the level below), reducing with `max` (`glsl/pyramid.comp`).
//!
//! # Levels and sizes
//!
//! Level 0 has one value per texel (or per bilinear cell, see [`PyramidKind`]): the
//! map's `W x H`. Level `L` has `ceil(W / 2^L) x ceil(H / 2^L)` nodes, down to `1 x 1`;
//! node `n` of level `L` covers the level-0 entries `[n 2^L, min((n + 1) 2^L, W))` of
//! its axis, so odd and non-square sizes stay conservative (the last node of a row
//! covers the one child that exists). These *logical* sizes are what the shaders use.
//!
//! Storage: one `R32_SFLOAT` image with a Vulkan mip chain whose level 0 is padded to
//! the next power of two per axis, so that each mip level (`max(1, W0 >> L)`) holds at
//! least the logical `ceil(W / 2^L)` nodes; padding texels are never read. A 1025-wide
//! map thus costs a 2048-wide level 0; the simplicity of `texelFetch(pyramid, node,
//! level)` is worth it.
//!
//! # The traversal's copy
//!
//! The chain is built in `R32_SFLOAT` (storage writes). A cell pyramid of an 8- or
//! 16-bit map is then blitted, level by level, into a copy in the map's own format
//! (`R8_UNORM` / `R16_UNORM`): its values are maxima of texels, so the copy holds
//! them exactly, and sampling it converts them exactly as sampling the height texture
//! converts the texels (the traversal compares the two). The traversals read the copy: a
//! quarter (or half) of the bytes, which is what a large map's traversal pays for (on
//! lavapipe `exact` on a 2048² map 1.18-1.25x faster, on 1024² 1.09-1.25x, the same hits;
//! the blit adds about 20 ms to a 2048² build). Without blit and sampling support for
//! that format, for footprint pyramids (means, not texels) and for the relaxed cone
//! build's falls pyramids (scratch, read once), the chain itself is read.
//!
//! # Contract (engine embedding)
//!
//! [`PyramidPass::record`] expects the height texture in `SHADER_READ_ONLY_OPTIMAL`,
//! visible to compute reads; it discards the pyramid's contents, records every level with
//! the barriers between them and leaves the pyramid in `SHADER_READ_ONLY_OPTIMAL`, its
//! writes made visible to compute-shader sampled reads. Build it only when the height
//! map changes.

use crate::abi::{ADDRESSING_CLAMP, ADDRESSING_REPEAT, PyramidParams};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::commands::read_image_level;
use crate::gpu::owned::Destroy;
use crate::gpu::sync::Access;
use crate::gpu::track::{Target, Tracker, binding_access};
use crate::gpu::{ComputePipeline, HeightTexture, Image, OneShot};
use crate::heightfield::{Addressing, HeightField};
pub use crate::method::PyramidKind;
use crate::shaders;
use ash::vk;

/// Format of the pyramid.
pub const PYRAMID_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// What the pass binds, by GLSL name (`glsl/pyramid.comp` numbers them): the height map,
/// then the storage levels `src` (read), `dst`, `next`, `next2` (written).
const BINDINGS: [(&str, vk::DescriptorType); 5] = [
    ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_src", vk::DescriptorType::STORAGE_IMAGE),
    ("u_dst", vk::DescriptorType::STORAGE_IMAGE),
    ("u_next", vk::DescriptorType::STORAGE_IMAGE),
    ("u_next2", vk::DescriptorType::STORAGE_IMAGE),
];

/// `PYRAMID_KIND_*` in `glsl/pyramid.comp`.
fn kind_code(kind: PyramidKind) -> u32 {
    match kind {
        PyramidKind::Footprint => 0,
        PyramidKind::Cell => 1,
        PyramidKind::Falls { neg_x, neg_y } => 2 + u32::from(neg_x) + 2 * u32::from(neg_y),
    }
}

/// Number of levels of a pyramid over `size` (level 0 to the `1 x 1` root).
pub fn level_count(size: [u32; 2]) -> u32 {
    let side = size[0].max(size[1]).max(1);
    side.next_power_of_two().trailing_zeros() + 1
}

/// Logical size of `level` (nodes per axis: `ceil(size / 2^level)`).
pub fn level_size(size: [u32; 2], level: u32) -> [u32; 2] {
    let shrink = |s: u32| {
        if level >= 32 {
            1
        } else {
            s.div_ceil(1u32 << level).max(1)
        }
    };
    [shrink(size[0]), shrink(size[1])]
}

/// The pyramid of one height map.
pub struct Pyramid {
    /// The mip-chained image the build writes (see the module docs for its padded sizes).
    pub image: Image,
    /// The traversal's copy in the map's format (see the module docs), when there is one.
    compact: Option<Image>,
    level_views: Vec<vk::ImageView>,
    sampler: vk::Sampler,
    /// What level 0 bounds.
    pub kind: PyramidKind,
    /// The map's size in texels (the logical size of level 0).
    pub size: [u32; 2],
    /// The addressing the pyramid was built for.
    pub addressing: Addressing,
}

impl Pyramid {
    /// Allocates the pyramid of a `size` map whose height texture has `height_format`
    /// (contents undefined until built).
    pub fn new(
        ctx: &Context,
        size: [u32; 2],
        kind: PyramidKind,
        addressing: Addressing,
        height_format: vk::Format,
    ) -> Result<Self> {
        let levels = level_count(size);
        let extent = vk::Extent2D {
            width: size[0].max(1).next_power_of_two(),
            height: size[1].max(1).next_power_of_two(),
        };
        let name = match kind {
            PyramidKind::Footprint => "pyramid[footprint]",
            PyramidKind::Cell => "pyramid[cell]",
            PyramidKind::Falls { neg_x, neg_y } => match (neg_x, neg_y) {
                (false, false) => "pyramid[falls+x+y]",
                (true, false) => "pyramid[falls-x+y]",
                (false, true) => "pyramid[falls+x-y]",
                (true, true) => "pyramid[falls-x-y]",
            },
        };
        let image = Image::new(
            ctx,
            name,
            PYRAMID_FORMAT,
            extent,
            levels,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        let mut pyramid = Pyramid {
            compact: None,
            level_views: Vec::new(),
            sampler: vk::Sampler::null(),
            kind,
            size,
            addressing,
            image,
        };
        if let Err(e) = pyramid.create_views(ctx, name) {
            // SAFETY: built above and never used by a command.
            unsafe { pyramid.destroy(ctx) };
            return Err(e);
        }
        if let Some(format) = compact_format(ctx, kind, height_format) {
            match Image::new(
                ctx,
                &format!("{name}.compact"),
                format,
                extent,
                levels,
                vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_DST
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            ) {
                Ok(image) => pyramid.compact = Some(image),
                Err(e) => {
                    // SAFETY: built above and never used by a command.
                    unsafe { pyramid.destroy(ctx) };
                    return Err(e);
                }
            }
        }
        Ok(pyramid)
    }

    /// The image the traversals read: the compact copy, or the chain.
    fn read_image(&self) -> &Image {
        self.compact.as_ref().unwrap_or(&self.image)
    }

    fn create_views(&mut self, ctx: &Context, name: &str) -> Result<()> {
        for level in 0..self.image.mip_levels {
            let view = self
                .image
                .level_view(ctx, level, &format!("{name}.level{level}"))?;
            self.level_views.push(view);
        }
        self.sampler = crate::gpu::pipeline::sampler(
            ctx,
            &format!("{name}.sampler"),
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        )?;
        Ok(())
    }

    /// Number of levels.
    pub fn levels(&self) -> u32 {
        self.image.mip_levels
    }

    fn level_range(&self, level: u32) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange {
            base_mip_level: level,
            level_count: 1,
            ..self.image.range()
        }
    }

    /// Descriptor for the trace pass (`texelFetch(pyramid, node, level)`).
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.read_image().view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Reads every level back (logical sizes, row by row). The pyramid must be built
    /// and idle in `SHADER_READ_ONLY_OPTIMAL`.
    pub fn read_levels(&self, ctx: &Context, shot: &OneShot) -> Result<Vec<Vec<f32>>> {
        let image = self.read_image();
        (0..self.levels())
            .map(|level| {
                let bytes = read_image_level(ctx, shot, image, level, Access::COMPUTE_SAMPLED)?;
                // The compact formats as the shaders see them (`c / (2^bits - 1)`).
                let stored: Vec<f32> = match image.format {
                    vk::Format::R8_UNORM => bytes.iter().map(|&c| f32::from(c) / 255.0).collect(),
                    vk::Format::R16_UNORM => bytemuck::cast_slice::<u8, u16>(&bytes)
                        .iter()
                        .map(|&c| f32::from(c) / 65535.0)
                        .collect(),
                    _ => bytemuck::cast_slice::<u8, f32>(&bytes).to_vec(),
                };
                let stride = (self.image.extent.width >> level).max(1) as usize;
                let [w, h] = level_size(self.size, level);
                Ok((0..h as usize)
                    .flat_map(|j| stored[j * stride..j * stride + w as usize].iter().copied())
                    .collect())
            })
            .collect()
    }
}

impl Destroy for Pyramid {
    /// Destroys views, sampler and image. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            for view in self.level_views.drain(..) {
                ctx.device().destroy_image_view(view, None);
            }
            if self.sampler != vk::Sampler::null() {
                ctx.device().destroy_sampler(self.sampler, None);
                self.sampler = vk::Sampler::null();
            }
            if let Some(mut compact) = self.compact.take() {
                compact.destroy(ctx);
            }
            self.image.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.image.bytes() + self.compact.bytes()
    }
}

/// The compact format of a `kind` pyramid of a `height_format` map (module docs), if
/// the device can blit `R32_SFLOAT` into it and sample it.
fn compact_format(
    ctx: &Context,
    kind: PyramidKind,
    height_format: vk::Format,
) -> Option<vk::Format> {
    // Footprint bounds are means, not texels; falls pyramids are the relaxed cone
    // build's scratch, read once.
    if kind != PyramidKind::Cell {
        return None;
    }
    let format = match height_format {
        vk::Format::R8_UNORM | vk::Format::R16_UNORM => height_format,
        _ => return None,
    };
    let dst = vk::FormatFeatureFlags::BLIT_DST | vk::FormatFeatureFlags::SAMPLED_IMAGE;
    (ctx.format_features(format).contains(dst)
        && ctx
            .format_features(PYRAMID_FORMAT)
            .contains(vk::FormatFeatureFlags::BLIT_SRC))
    .then_some(format)
}

/// The reduction pipeline.
pub struct PyramidPass {
    pipeline: ComputePipeline,
}

impl PyramidPass {
    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(PyramidPass {
            pipeline: ComputePipeline::new(
                ctx,
                "pyramid",
                &shaders::PYRAMID_COMP,
                &BINDINGS,
                std::mem::size_of::<PyramidParams>() as u32,
            )?,
        })
    }

    /// Records the whole chain (see the module docs for the layouts on entry and exit).
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * When the command buffer executes, `height` is in `SHADER_READ_ONLY_OPTIMAL`, its
    ///   writes visible to compute-shader sampled reads (as its fills leave it), and
    ///   no access of `pyramid`'s images (the chain and its compact copy) is pending (its contents are discarded: frames
    ///   that read an earlier build have completed).
    /// * `height`, `pyramid` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        height: &HeightTexture,
        pyramid: &Pyramid,
    ) -> Result<()> {
        // Each level (and the compact copy) is a resource of the build's tracker, which
        // places every barrier from the dispatches' declared accesses; all enter
        // discarded (no access pending: this function's contract).
        let mut t = Tracker::new();
        let levels = pyramid.levels();
        for level in 0..levels {
            t.enter(Some(level), Access::UNDEFINED);
        }
        t.enter(None, Access::UNDEFINED);
        let target = |key: Option<u32>| match (key, &pyramid.compact) {
            (Some(level), _) => Target::Image(pyramid.image.raw, pyramid.level_range(level)),
            (None, Some(compact)) => Target::Image(compact.raw, compact.range()),
            (None, None) => Target::Memory,
        };
        let heights = [height.descriptor()];
        let storage = |level: u32| {
            [vk::DescriptorImageInfo {
                sampler: vk::Sampler::null(),
                image_view: pyramid.level_views[level as usize],
                image_layout: vk::ImageLayout::GENERAL,
            }]
        };
        let addressing = match pyramid.addressing {
            Addressing::Repeat => ADDRESSING_REPEAT,
            Addressing::Clamp => ADDRESSING_CLAMP,
        };
        let mut level = 0;
        while level < levels {
            // Up to three levels per dispatch, as many as there are from this one.
            let count = (levels - level).min(3);
            // Level 0 reads the height map only; its `src` binding (statically used by
            // the shader, not read on that path) names level 0 itself, so no later
            // dispatch's write follows an unsynchronised read. A dispatch of fewer
            // levels binds its own level as `next` / `next2` (not written on that path).
            let bound = [
                level.saturating_sub(1),
                level,
                if count >= 2 { level + 1 } else { level },
                if count == 3 { level + 2 } else { level },
            ];
            // Each storage binding's level accessed as the shader's reflection says.
            for ((name, _), l) in BINDINGS[1..].iter().zip(bound) {
                let b = self.pipeline.bindings.iter().find(|b| b.name == *name);
                let b = b.ok_or_else(|| Error::Internal(format!("pyramid.comp has no {name}")))?;
                t.declare(Some(l), binding_access(b))?;
            }
            // SAFETY: this function's # Safety contract (`cmd` recording outside a render
            // pass, the pyramid alive and discarded on entry).
            unsafe { t.flush(ctx, cmd, target)? };
            let [src, dst, next, next2] = bound.map(storage);
            let p = &self.pipeline;
            let writes = [
                p.image("u_height", &heights)?,
                p.image("u_src", &src)?,
                p.image("u_dst", &dst)?,
                p.image("u_next", &next)?,
                p.image("u_next2", &next2)?,
            ];
            let src_size = if level == 0 {
                pyramid.size
            } else {
                level_size(pyramid.size, level - 1)
            };
            let dst_size = level_size(pyramid.size, level);
            let size_if = |written: bool, l: u32| {
                if written {
                    level_size(pyramid.size, l)
                } else {
                    [0, 0]
                }
            };
            let next_size = size_if(count >= 2, level + 1);
            let next2_size = size_if(count == 3, level + 2);
            let push = PyramidParams {
                src_size,
                dst_size,
                next_size,
                level,
                kind: kind_code(pyramid.kind),
                addressing,
                pad: 0,
                next2_size,
            };
            let grid = [next2_size, next_size, dst_size][3 - count as usize];
            // SAFETY: this function's # Safety contract: `cmd` is recording outside a
            // render pass; the writes match `BINDINGS` (the pipeline's set 0) and name
            // the live height texture (sampled-readable) and pyramid levels in `GENERAL`
            // (the barriers above); the push constants are the `PyramidParams` the
            // layout was built with; the pipeline lives as long as this pass.
            unsafe {
                self.pipeline.dispatch(
                    ctx,
                    cmd,
                    &writes,
                    bytemuck::bytes_of(&push),
                    grid[0],
                    grid[1],
                )
            };
            level += count;
        }
        let Some(compact) = &pyramid.compact else {
            // Left for the frames' sampled reads, as every build leaves its maps.
            for level in 0..levels {
                t.declare(Some(level), Access::COMPUTE_SAMPLED)?;
            }
            // SAFETY: as above.
            return unsafe { t.flush(ctx, cmd, target) };
        };
        // The traversal's copy: every level blitted (nearest, same size: the exact
        // float -> unorm conversion of values that are texels), padding included.
        for level in 0..levels {
            t.declare(Some(level), Access::TRANSFER_READ)?;
        }
        t.declare(None, Access::TRANSFER_WRITE)?;
        // SAFETY: as above; the copy is alive with no access pending.
        unsafe { t.flush(ctx, cmd, target)? };
        let layers = |level: u32| vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: level,
            base_array_layer: 0,
            layer_count: 1,
        };
        let regions: Vec<vk::ImageBlit> = (0..levels)
            .map(|level| {
                let corner = vk::Offset3D {
                    x: (pyramid.image.extent.width >> level).max(1) as i32,
                    y: (pyramid.image.extent.height >> level).max(1) as i32,
                    z: 1,
                };
                vk::ImageBlit {
                    src_subresource: layers(level),
                    src_offsets: [vk::Offset3D::default(), corner],
                    dst_subresource: layers(level),
                    dst_offsets: [vk::Offset3D::default(), corner],
                }
            })
            .collect();
        // SAFETY: as above; the chain is in `TRANSFER_SRC_OPTIMAL` and the copy in
        // `TRANSFER_DST_OPTIMAL` (the transitions above), the regions within both images'
        // levels (the same extents), and the device blits `R32_SFLOAT` into the copy's
        // format (`compact_format`).
        unsafe {
            ctx.device().cmd_blit_image(
                cmd,
                pyramid.image.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                compact.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &regions,
                vk::Filter::NEAREST,
            );
        }
        // Left for the frames' sampled reads.
        t.declare(None, Access::COMPUTE_SAMPLED)?;
        // SAFETY: as above.
        unsafe { t.flush(ctx, cmd, target) }
    }
}

impl Destroy for PyramidPass {
    /// Destroys the pipeline.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}

/// The same pyramid built on the CPU in `f32` with the shader's operation order (the
/// reference the GPU build is compared with bit for bit). Levels in logical sizes.
pub fn cpu_build(field: &HeightField, addressing: Addressing, kind: PyramidKind) -> Vec<Vec<f32>> {
    let size = [field.width(), field.height()];
    let (w, h) = (size[0] as usize, size[1] as usize);
    // Every texel converted once, and per column and row the indices of the neighbours
    // at -1, 0 and +1 with the addressing applied: the inner loop only reads and compares.
    let heights: Vec<f32> = (0..size[1])
        .flat_map(|j| (0..size[0]).map(move |i| field.texel(i, j)))
        .collect();
    let neighbours = |n: usize| -> [Vec<usize>; 3] {
        [-1i64, 0, 1].map(|d| {
            (0..n as i64)
                .map(|i| match addressing {
                    Addressing::Repeat => (i + d).rem_euclid(n as i64) as usize,
                    Addressing::Clamp => (i + d).clamp(0, n as i64 - 1) as usize,
                })
                .collect()
        })
    };
    let [c_prev, c_same, c_next] = neighbours(w);
    let [r_prev, r_same, r_next] = neighbours(h);
    let mut level0 = Vec::with_capacity(w * h);
    for j in 0..h {
        let rows = [r_prev[j] * w, r_same[j] * w, r_next[j] * w];
        for i in 0..w {
            let cols = [c_prev[i], c_same[i], c_next[i]];
            let t = |di: usize, dj: usize| heights[rows[dj] + cols[di]];
            level0.push(match kind {
                PyramidKind::Cell => t(1, 1).max(t(2, 1)).max(t(1, 2).max(t(2, 2))),
                PyramidKind::Falls { neg_x, neg_y } => {
                    let (a00, a10, a01, a11) = (t(1, 1), t(2, 1), t(1, 2), t(2, 2));
                    let falls_x = if neg_x {
                        a10 > a00 || a11 > a01
                    } else {
                        a00 > a10 || a01 > a11
                    };
                    let falls_y = if neg_y {
                        a01 > a00 || a11 > a10
                    } else {
                        a00 > a01 || a10 > a11
                    };
                    if falls_x || falls_y {
                        a00.max(a10).max(a01.max(a11))
                    } else {
                        0.0
                    }
                }
                PyramidKind::Footprint => {
                    let edges = [
                        (t(0, 1) + t(1, 1)) * 0.5,
                        (t(1, 1) + t(2, 1)) * 0.5,
                        (t(1, 0) + t(1, 1)) * 0.5,
                        (t(1, 1) + t(1, 2)) * 0.5,
                    ];
                    let corners = [
                        ((t(0, 0) + t(1, 0)) + (t(0, 1) + t(1, 1))) * 0.25,
                        ((t(1, 0) + t(2, 0)) + (t(1, 1) + t(2, 1))) * 0.25,
                        ((t(0, 1) + t(1, 1)) + (t(0, 2) + t(1, 2))) * 0.25,
                        ((t(1, 1) + t(2, 1)) + (t(1, 2) + t(2, 2))) * 0.25,
                    ];
                    edges.iter().chain(&corners).fold(t(1, 1), |m, &v| m.max(v))
                }
            });
        }
    }
    let mut levels = vec![level0];
    for level in 1..level_count(size) {
        let [sw, sh] = level_size(size, level - 1);
        let [dw, dh] = level_size(size, level);
        let src = &levels[level as usize - 1];
        let at = |i: u32, j: u32| src[(j.min(sh - 1) * sw + i.min(sw - 1)) as usize];
        let mut dst = Vec::with_capacity((dw * dh) as usize);
        for j in 0..dh {
            for i in 0..dw {
                let (ci, cj) = (2 * i, 2 * j);
                dst.push(
                    at(ci, cj)
                        .max(at(ci + 1, cj))
                        .max(at(ci, cj + 1).max(at(ci + 1, cj + 1))),
                );
            }
        }
        levels.push(dst);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_reach_a_single_root() {
        assert_eq!(level_count([1, 1]), 1);
        assert_eq!(level_count([1024, 1024]), 11);
        assert_eq!(level_count([1025, 3]), 12);
        assert_eq!(level_size([1025, 3], 1), [513, 2]);
        assert_eq!(level_size([1025, 3], 11), [1, 1]);
        assert_eq!(level_size([348, 1000], 9), [1, 2]);
        assert_eq!(level_size([348, 1000], 10), [1, 1]);
    }

    #[test]
    fn cpu_levels_bound_their_children() {
        let field = HeightField::from_fn(5, 3, "odd", |u, v| {
            (0.5 + 0.4 * (u * 7.0).sin()) * (0.5 + 0.5 * v)
        })
        .expect("valid field");
        for kind in [PyramidKind::Footprint, PyramidKind::Cell] {
            let levels = cpu_build(&field, Addressing::Repeat, kind);
            assert_eq!(levels.len(), 4);
            assert_eq!(levels.last().map(Vec::len), Some(1));
            let max = levels[0].iter().copied().fold(f32::MIN, f32::max);
            assert_eq!(levels[3][0], max);
        }
        // Cell (4, 2) wraps to texels (0, 0), (4, 0), (0, 2), (4, 2).
        let cells = cpu_build(&field, Addressing::Repeat, PyramidKind::Cell);
        let expect = [(4, 2), (0, 2), (4, 0), (0, 0)]
            .iter()
            .map(|&(i, j)| field.texel(i, j))
            .fold(f32::MIN, f32::max);
        assert_eq!(cells[0][2 * 5 + 4], expect);
    }
}
