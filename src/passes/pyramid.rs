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
//! Storage: one image with a Vulkan mip chain whose level 0 is padded to the next power
//! of two per axis, so that each mip level (`max(1, W0 >> L)`) holds at least the
//! logical `ceil(W / 2^L)` nodes; padding texels are never read. A 1025-wide map thus
//! costs a 2048-wide level 0; the simplicity of `texelFetch(pyramid, node, level)` is
//! worth it.
//!
//! # What is kept
//!
//! A cell pyramid (the one the traversals read, kept as long as its map) is built
//! directly in the map's own format where its texels are 8- or 16-bit unorm
//! ([`storage_format`]: `R8_UNORM` / `R16_UNORM`; a host map's channel of such a format
//! too): every node is a maximum of texels, and the shader stores that texel's code, so
//! the pyramid samples exactly as the height texture samples the texels (bit for bit the
//! maxima an `f32` chain would hold), every level included. Other maps (`f32` texels, a
//! host's BC4 or float image, whose sampled values are not codes of a narrower format)
//! get an `R32_SFLOAT` chain of the exact maxima that stores levels 1 and up only: a
//! traversal that reaches a level-0 cell runs the exact leaf test on its texels, read
//! from the map itself, where a bound would have let it skip the cell (a miss leaves the
//! cell as the skip does: the same hits and step counts; the cone build reads a cell's
//! maximum from its 4 texels, `pyramid_node_max` in `glsl/common/pyramid.glsl` too);
//! its image's mip `m` holds level `m + 1` ([`Pyramid::first_stored_level`],
//! told to the shaders by [`Pyramid::shader_levels`]); [`Pyramid::levels`] counts level
//! 0 all the same. Level 0 is three quarters of the nodes. A 4096² map's cell pyramid is
//! thus 42.7 MiB (`R16_UNORM`), 21.3 MiB (`R8_UNORM`) or 21.3 MiB (`R32_SFLOAT`, levels
//! 1 and up). (Reading level 0 from the map for the 8- and 16-bit maps too would save
//! three quarters of theirs, but on lavapipe it made `exact` 1.4-2x slower: a level-0
//! step's gather and its wrapping arithmetic against one fetch, and a texel read in the
//! traversal's loop costs even where it is not taken.)
//!
//! The footprint pyramid (means of texels, `pyramid`'s bounds) and the relaxed cone
//! build's falls pyramids (scratch, read once) are full `R32_SFLOAT` chains. A device
//! without storage writes of the unorm format without a format qualifier (Vulkan 1.3's
//! `STORAGE_WRITE_WITHOUT_FORMAT` format feature; the level below is read through a
//! sampler) gets `R32_SFLOAT` cell pyramids.
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

/// Format of the `R32_SFLOAT` chains (footprint and falls pyramids, and a cell pyramid
/// where the device cannot store a unorm one: [`storage_format`]).
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

/// The `UNORM` variant's bindings: `src` is sampled (a device need not read a unorm
/// storage image without a format qualifier; lavapipe does not).
const UNORM_BINDINGS: [(&str, vk::DescriptorType); 5] = [
    BINDINGS[0],
    ("u_src", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    BINDINGS[2],
    BINDINGS[3],
    BINDINGS[4],
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

/// The first level a `kind` pyramid stored in `format` ([`storage_format`]) keeps: 1 for
/// an `R32_SFLOAT` cell pyramid (module docs), 0 for the others.
pub fn first_stored_level(kind: PyramidKind, format: vk::Format) -> u32 {
    u32::from(kind == PyramidKind::Cell && format == PYRAMID_FORMAT)
}

/// Texels of the image of a pyramid over `size` whose first stored level is `first`
/// ([`first_stored_level`]: its stored levels, padded; module docs): times the format's
/// bytes, what it holds.
pub fn stored_texels(first: u32, size: [u32; 2]) -> u64 {
    let (pw, ph) = (
        size[0].max(1).next_power_of_two(),
        size[1].max(1).next_power_of_two(),
    );
    let mips = level_count(size).saturating_sub(first).max(1);
    (first..first + mips)
        .map(|l| u64::from((pw >> l).max(1)) * u64::from((ph >> l).max(1)))
        .sum()
}

/// The pyramid of one height map.
pub struct Pyramid {
    /// The mip-chained image (see the module docs for its format, its padded sizes and
    /// the levels it stores: mip `m` holds level `m + first_stored_level(kind)`).
    pub image: Image,
    /// A view of each mip.
    level_views: Vec<vk::ImageView>,
    sampler: vk::Sampler,
    /// Levels, level 0 to the root, stored or not.
    levels: u32,
    /// The first level stored (mip 0).
    first: u32,
    /// What level 0 bounds.
    pub kind: PyramidKind,
    /// The map's size in texels (the logical size of level 0).
    pub size: [u32; 2],
    /// The addressing the pyramid was built for.
    pub addressing: Addressing,
}

impl Pyramid {
    /// Allocates the pyramid of a `size` map whose texels are of `height_format` (a
    /// [`HeightTexture::texel_format`]; contents undefined until built).
    pub fn new(
        ctx: &Context,
        size: [u32; 2],
        kind: PyramidKind,
        addressing: Addressing,
        height_format: vk::Format,
    ) -> Result<Self> {
        let levels = level_count(size);
        let format = storage_format(ctx, kind, height_format);
        let first = first_stored_level(kind, format);
        // A 1 x 1 map's `R32_SFLOAT` cell pyramid has no stored level; its image (one
        // texel, never written or read) keeps the descriptors valid.
        let mips = levels.saturating_sub(first).max(1);
        let extent = vk::Extent2D {
            width: (size[0].max(1).next_power_of_two() >> first).max(1),
            height: (size[1].max(1).next_power_of_two() >> first).max(1),
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
            format,
            extent,
            mips,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        let mut pyramid = Pyramid {
            level_views: Vec::new(),
            sampler: vk::Sampler::null(),
            levels,
            first,
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
        Ok(pyramid)
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

    /// Number of levels, level 0 to the root (what the shaders' `pyramid_levels` say),
    /// whether stored or not.
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// The first level its image stores (mip 0): 1 for an `R32_SFLOAT` cell pyramid, 0
    /// otherwise.
    pub fn first_stored_level(&self) -> u32 {
        self.first
    }

    /// What the shaders' `pyramid_levels` (the cone build's `levels`) say: bits 0-15 the
    /// levels, bit 16 set where level 0 is not stored (`glsl/common/pyramid.glsl`).
    pub fn shader_levels(&self) -> u32 {
        self.levels | (self.first << 16)
    }

    fn mip_range(&self, mip: u32) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange {
            base_mip_level: mip,
            level_count: 1,
            ..self.image.range()
        }
    }

    /// Descriptor for the trace pass (`texelFetch(pyramid, node, level)`).
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.image.view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Reads every stored level back (levels [`Pyramid::first_stored_level`] to the root,
    /// logical sizes, row by row), unorm codes `c` as `c / (2^bits - 1)` in `f32`. The
    /// pyramid must be built and idle in `SHADER_READ_ONLY_OPTIMAL`.
    pub fn read_levels(&self, ctx: &Context, shot: &OneShot) -> Result<Vec<Vec<f32>>> {
        let image = &self.image;
        (self.first..self.levels)
            .map(|level| {
                let mip = level - self.first;
                let bytes = read_image_level(ctx, shot, image, mip, Access::COMPUTE_SAMPLED)?;
                let stored: Vec<f32> = match image.format {
                    vk::Format::R8_UNORM => bytes.iter().map(|&c| f32::from(c) / 255.0).collect(),
                    vk::Format::R16_UNORM => bytemuck::cast_slice::<u8, u16>(&bytes)
                        .iter()
                        .map(|&c| f32::from(c) / 65535.0)
                        .collect(),
                    _ => bytemuck::cast_slice::<u8, f32>(&bytes).to_vec(),
                };
                let stride = (self.image.extent.width >> mip).max(1) as usize;
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
            self.image.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.image.bytes()
    }
}

/// The format a `kind` pyramid of a map whose texels are of `height_format` (a
/// [`HeightTexture::texel_format`]) is stored in (module docs): for a cell pyramid of
/// 8- or 16-bit unorm texels their own format, where the device samples it and writes it
/// through formatless storage images; `R32_SFLOAT` otherwise.
pub fn storage_format(ctx: &Context, kind: PyramidKind, height_format: vk::Format) -> vk::Format {
    let format = match (kind, height_format) {
        (PyramidKind::Cell, vk::Format::R8_UNORM | vk::Format::R16_UNORM) => height_format,
        _ => return PYRAMID_FORMAT,
    };
    let mut three = vk::FormatProperties3::default();
    let mut two = vk::FormatProperties2::default().push_next(&mut three);
    // SAFETY: the physical device belongs to the context's instance (Vulkan 1.3, which
    // has vkGetPhysicalDeviceFormatProperties2 and VkFormatProperties3), alive as long as
    // the context; the chain outlives the call.
    unsafe {
        ctx.instance().get_physical_device_format_properties2(
            ctx.physical_device(),
            format,
            &mut two,
        )
    };
    let needed = vk::FormatFeatureFlags2::STORAGE_IMAGE
        | vk::FormatFeatureFlags2::SAMPLED_IMAGE
        | vk::FormatFeatureFlags2::STORAGE_WRITE_WITHOUT_FORMAT
        | vk::FormatFeatureFlags2::TRANSFER_SRC;
    if three.optimal_tiling_features.contains(needed) {
        format
    } else {
        PYRAMID_FORMAT
    }
}

/// The reduction pipelines: `R32_SFLOAT` chains and unorm ones (`glsl/pyramid.comp`'s
/// `UNORM` variant).
pub struct PyramidPass {
    float: ComputePipeline,
    unorm: ComputePipeline,
}

impl PyramidPass {
    /// Builds the pipelines.
    pub fn new(ctx: &Context) -> Result<Self> {
        let push = std::mem::size_of::<PyramidParams>() as u32;
        let mut float =
            ComputePipeline::new(ctx, "pyramid", &shaders::PYRAMID_COMP, &BINDINGS, push)?;
        let unorm = match ComputePipeline::new(
            ctx,
            "pyramid[unorm]",
            &shaders::PYRAMID_COMP_UNORM,
            &UNORM_BINDINGS,
            push,
        ) {
            Ok(p) => p,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { float.destroy(ctx) };
                return Err(e);
            }
        };
        Ok(PyramidPass { float, unorm })
    }

    /// Records the whole chain (see the module docs for the layouts on entry and exit).
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * When the command buffer executes, `height` is in `SHADER_READ_ONLY_OPTIMAL`, its
    ///   writes visible to compute-shader sampled reads (as its fills leave it), and
    ///   no access of `pyramid`'s image is pending (its contents are discarded: frames
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
        // Each stored level (by mip) is a resource of the build's tracker, which places
        // every barrier from the dispatches' declared accesses; all enter discarded (no
        // access pending: this function's contract).
        let mut t = Tracker::new();
        let levels = pyramid.levels();
        let first = pyramid.first;
        let mips = pyramid.image.mip_levels;
        for mip in 0..mips {
            t.enter(mip, Access::UNDEFINED);
        }
        let target = |mip: u32| Target::Image(pyramid.image.raw, pyramid.mip_range(mip));
        // The mip a level's binding names: a level that is not stored (the cell
        // pyramid's level 0, bound where the shader does not read or write it) names
        // mip 0.
        let mip_of = |level: u32| level.saturating_sub(first).min(mips - 1);
        let code_max = match pyramid.image.format {
            vk::Format::R8_UNORM => 255,
            vk::Format::R16_UNORM => 65535,
            _ => 0,
        };
        let (pipeline, bindings) = if code_max == 0 {
            (&self.float, &BINDINGS)
        } else {
            (&self.unorm, &UNORM_BINDINGS)
        };
        let heights = [height.descriptor()];
        let storage = |mip: u32| {
            [vk::DescriptorImageInfo {
                sampler: vk::Sampler::null(),
                image_view: pyramid.level_views[mip as usize],
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
            // the shader, not read on that path) names level 0 itself (the float chain:
            // so no later dispatch's write follows an unsynchronised read) or the height
            // map (the unorm variant's sampled `src`). A dispatch of fewer levels binds
            // its own level as `next` / `next2` (not written on that path).
            let bound = [
                level.saturating_sub(1),
                level,
                if count >= 2 { level + 1 } else { level },
                if count == 3 { level + 2 } else { level },
            ]
            .map(mip_of);
            // Each storage binding's level accessed as the shader's reflection says.
            for (i, ((name, _), l)) in bindings[1..].iter().zip(bound).enumerate() {
                if i == 0 && level == 0 && code_max != 0 {
                    // The height map: sampled-readable on entry (this function's contract).
                    continue;
                }
                let b = pipeline.bindings.iter().find(|b| b.name == *name);
                let b = b.ok_or_else(|| Error::Internal(format!("pyramid.comp has no {name}")))?;
                t.declare(l, binding_access(b))?;
            }
            // SAFETY: this function's # Safety contract (`cmd` recording outside a render
            // pass, the pyramid alive and discarded on entry).
            unsafe { t.flush(ctx, cmd, target)? };
            let [mut src, dst, next, next2] = bound.map(storage);
            if code_max != 0 {
                src = if level == 0 {
                    heights
                } else {
                    [vk::DescriptorImageInfo {
                        sampler: pyramid.sampler,
                        image_view: pyramid.level_views[bound[0] as usize],
                        image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                    }]
                };
            }
            let p = pipeline;
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
                code_max,
                next2_size,
                store_dst: u32::from(level >= first),
                pad: [0; 3],
            };
            let grid = [next2_size, next_size, dst_size][3 - count as usize];
            // SAFETY: this function's # Safety contract: `cmd` is recording outside a
            // render pass; the writes match `bindings` (the pipeline's set 0) and name
            // the live height texture (sampled-readable) and pyramid levels in `GENERAL`
            // (written) or `SHADER_READ_ONLY_OPTIMAL` (the unorm variant's `src`: the
            // barriers above), of the format the pipeline stores (R32_SFLOAT for
            // `float`, a unorm format with the formatless storage features for `unorm`:
            // `storage_format`); the push constants are the `PyramidParams` the layout
            // was built with; the pipeline lives as long as this pass.
            unsafe {
                pipeline.dispatch(
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
        // Left for the frames' sampled reads, as every build leaves its maps.
        for mip in 0..mips {
            t.declare(mip, Access::COMPUTE_SAMPLED)?;
        }
        // SAFETY: as above.
        unsafe { t.flush(ctx, cmd, target) }
    }
}

impl Destroy for PyramidPass {
    /// Destroys the pipeline.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.float.destroy(ctx);
            self.unorm.destroy(ctx);
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
    fn only_the_f32_cell_pyramid_leaves_level_0_to_the_map() {
        let f32_cell = first_stored_level(PyramidKind::Cell, PYRAMID_FORMAT);
        assert_eq!(f32_cell, 1);
        assert_eq!(
            first_stored_level(PyramidKind::Cell, vk::Format::R16_UNORM),
            0
        );
        assert_eq!(
            first_stored_level(PyramidKind::Footprint, PYRAMID_FORMAT),
            0
        );
        // 4096²: levels 1 to 12 (4^12 - 1) / 3 nodes, a third of the full chain's level 0.
        let cell = stored_texels(1, [4096, 4096]);
        assert_eq!(cell, ((1u64 << 24) - 1) / 3);
        assert_eq!(stored_texels(0, [4096, 4096]), (1 << 24) + cell);
        // Padded: a 1025 x 3 map's level 1 is stored 1024 x 2 wide.
        assert_eq!(stored_texels(1, [1025, 3]), 2048 + 512 + 256 + 255);
        // A 1 x 1 map stores no level from 1 on but keeps one texel.
        assert_eq!(stored_texels(1, [1, 1]), 1);
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
