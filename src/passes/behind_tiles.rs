//! The behind layer's missed tiles: what keeps the standalone renderer's behind layer
//! (`src/renderer/behind.rs`) to the pixels whose first-layer trace missed, decided on the
//! GPU after the first record (no readback, no stall).
//!
//! * `behind_misses` (`glsl/behind_misses.comp`): one indirect dispatch per live material
//!   over the first layer's tile list of that material (only displaced pixels are traced,
//!   so only they can miss): each 8x8 tile holding a missed pixel
//!   (`dispmap_behind_missed`, `glsl/include/dispmap_behind.glsl`) sets its bit in its
//!   row's mask, keeps the nearest first-layer depth of its missed pixels and marks
//!   their material in its mask of materials.
//! * `behind_cull` (`glsl/behind_cull.comp`), step 0: the missed tiles into a list, and
//!   each of the layer's draws (a mesh's cluster of triangles, a plane) its indirect draw
//!   command: its own where its screen rectangle in tiles (projected on the CPU,
//!   conservatively, from the geometry's bounds: [`DrawSource`]) meets a missed tile
//!   whose nearest missed first-layer depth lies in front of the draw's farthest point
//!   and which holds a missed pixel of a material other than the draw's
//!   [`DrawSource::own`] (a one-sided convex mesh cannot show its own misses), else none;
//!   step 1: the list's indirect dispatch (one workgroup per listed tile, in
//!   rows of 65,535), which the layer's background pass runs over, and the listed tiles'
//!   indirect draw ([`crate::passes::behind_open`]: an instance per listed tile).
//!
//! One buffer holds it all, in sections: the list (a `VkDispatchIndirectCommand`, the
//! count, the tiles packed `x | y << 16`), the masks, the tiles' depths and materials, the draws' sources (written by
//! [`BehindTiles::record_reset`] each frame) and their commands (`VkDrawIndexedIndirectCommand`,
//! or a `VkDrawIndirectCommand` in its first four words), then the listed tiles'
//! `VkDrawIndirectCommand`.

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::Buffer;
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::pipeline::{ComputePipeline, FetchPipeline, storage_view};
use crate::passes::classify::{MaterialTiles, TILES, tile_count};
use crate::passes::gbuffer::FirstLayer;
use crate::shaders;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// Alignment of each section (at least every device's `minStorageBufferOffsetAlignment`).
const ALIGN: u64 = 256;
/// Bytes of a draw's source (two `uvec4`).
const SOURCE_BYTES: u64 = 32;
/// Bytes of a draw's command (a `VkDrawIndexedIndirectCommand`).
pub const DRAW_STRIDE: u64 = 20;
/// Bytes of the listed tiles' command after the draws' (a `VkDrawIndirectCommand`).
const OPEN_BYTES: u64 = crate::passes::behind_open::DRAW_BYTES;
/// The most draws a layer has: their sources are written with `vkCmdUpdateBuffer`
/// (at most 65,536 bytes).
pub const MAX_DRAWS: u32 = (65536 / SOURCE_BYTES) as u32;

/// One draw of the behind layer as the cull step reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawSource {
    /// Its screen rectangle in 8x8 tiles, `[x0, y0, x1, y1]` inclusive, conservative (it
    /// holds every pixel the draw can cover); `x0 > x1`: off the frame.
    pub rect: [u32; 4],
    /// Its index count (indexed) or vertex count.
    pub count: u32,
    /// Its first index (indexed) or first vertex.
    pub first: u32,
    /// A reverse-Z depth at or below (behind) every point it can draw (0: anywhere): it is
    /// drawn only where a missed tile's nearest missed first-layer depth lies in front.
    pub depth: f32,
    /// Materials (bit `m` for material `m` below 31) whose missed pixels it cannot show:
    /// it is drawn only where a tile holds a missed pixel of another material. A one-sided
    /// convex mesh's own material where no other object has it (nothing of the mesh lies
    /// behind its own surface); 0: every missed pixel counts.
    pub own: u32,
}

/// The bit of material `material` in [`DrawSource::own`]: `1 << material` below 31, else
/// 0 (in the tiles' masks of the materials whose pixels missed, `behind_misses`, the
/// materials from 31 on share bit 31, so no draw may claim it as its own).
pub fn material_bit(material: u32) -> u32 {
    if material < 31 { 1 << material } else { 0 }
}

/// The rectangle of no tile.
pub const NO_RECT: [u32; 4] = [1, 0, 0, 0];

/// The push constants of `behind_misses`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct MissParams {
    frame_size: [u32; 2],
    material: u32,
    mask_words: u32,
    rows: u32,
    pad: [u32; 3],
}

/// The push constants of `behind_cull`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CullParams {
    step: u32,
    rows: u32,
    mask_words: u32,
    draw_count: u32,
    tiles_x: u32,
    pad: [u32; 3],
}

/// The missed tiles' buffer and pipelines of one frame size and number of draws.
pub struct BehindTiles {
    buffer: Buffer,
    extent: vk::Extent2D,
    tiles: [u32; 2],
    mask_words: u32,
    draws: u32,
    masks_offset: u64,
    sources_offset: u64,
    draws_offset: u64,
    misses: FetchPipeline,
    cull: ComputePipeline,
}

fn align(n: u64) -> u64 {
    n.div_ceil(ALIGN) * ALIGN
}

impl BehindTiles {
    /// The buffer and pipelines for frames of `extent` and `draws` draws (at most
    /// [`MAX_DRAWS`]).
    pub fn new(ctx: &Context, extent: vk::Extent2D, draws: u32) -> Result<Self> {
        if draws > MAX_DRAWS {
            return Err(Error::invalid(
                "behind layer",
                format!("{draws} draws, more than {MAX_DRAWS}"),
            ));
        }
        let tiles = tile_count(extent);
        let mask_words = tiles[0].div_ceil(32);
        let list_bytes = 16 + 4 * u64::from(tiles[0]) * u64::from(tiles[1]);
        let masks_offset = align(list_bytes);
        let sources_offset = masks_offset + align(Self::masks_bytes(tiles, mask_words));
        let draws_offset = sources_offset + align(SOURCE_BYTES * u64::from(draws.max(1)));
        // The draws' commands, then the listed tiles' (`glsl/behind_open.vert`).
        let size = draws_offset + DRAW_STRIDE * u64::from(draws.max(1)) + OPEN_BYTES;
        let buffer = Buffer::new(
            ctx,
            "behind.tiles",
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        // SAFETY: no command has used the guarded values yet; they are kept below.
        let buffer = unsafe { Guard::new(ctx, buffer) };
        let storage = vk::DescriptorType::STORAGE_BUFFER;
        let misses = FetchPipeline::new(
            ctx,
            "behind_misses",
            &shaders::BEHIND_MISSES_COMP,
            &[
                ("u_first_depth", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
                ("u_first_hit_height", vk::DescriptorType::STORAGE_IMAGE),
                ("u_tiles", storage),
                ("u_masks", storage),
                ("u_first_frame", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
            ],
            std::mem::size_of::<MissParams>() as u32,
        )?;
        // SAFETY: as above.
        let misses = unsafe { Guard::new(ctx, misses) };
        let cull = ComputePipeline::new(
            ctx,
            "behind_cull",
            &shaders::BEHIND_CULL_COMP,
            &[
                ("u_masks", storage),
                ("u_list", storage),
                ("u_sources", storage),
                ("u_draws", storage),
            ],
            std::mem::size_of::<CullParams>() as u32,
        )?;
        Ok(BehindTiles {
            buffer: buffer.keep(),
            extent,
            tiles,
            mask_words,
            draws,
            masks_offset,
            sources_offset,
            draws_offset,
            misses: misses.keep(),
            cull,
        })
    }

    /// Bytes of the masks, the tiles' depths and the tiles' materials.
    fn masks_bytes(tiles: [u32; 2], mask_words: u32) -> u64 {
        4 * (u64::from(mask_words * tiles[1]) + 2 * u64::from(tiles[0]) * u64::from(tiles[1]))
    }

    /// The frame size and number of draws it was made for.
    pub fn fits(&self, extent: vk::Extent2D, draws: u32) -> bool {
        self.extent == extent && self.draws == draws
    }

    fn section(&self, offset: u64, range: u64) -> [vk::DescriptorBufferInfo; 1] {
        [vk::DescriptorBufferInfo {
            buffer: self.buffer.raw,
            offset,
            range,
        }]
    }

    /// The list section (`u_behind_tiles` of `glsl/background.comp`'s `BEHIND`): the
    /// dispatch, the count, the tiles.
    pub fn list(&self) -> [vk::DescriptorBufferInfo; 1] {
        self.section(0, self.masks_offset)
    }

    /// The list's `VkDispatchIndirectCommand`: the buffer and offset.
    pub fn list_dispatch(&self) -> (vk::Buffer, u64) {
        (self.buffer.raw, 0)
    }

    /// The listed tiles' draw ([`crate::passes::behind_open`]): the list and the command
    /// `behind_cull`'s step 1 writes.
    pub fn open_tiles(&self) -> crate::passes::behind_open::OpenTiles {
        crate::passes::behind_open::OpenTiles {
            list: self.list()[0],
            command: (
                self.buffer.raw,
                self.draws_offset + DRAW_STRIDE * u64::from(self.draws),
            ),
        }
    }

    /// Piece `i`'s command: the buffer and offset.
    pub fn draw(&self, i: u32) -> (vk::Buffer, u64) {
        (
            self.buffer.raw,
            self.draws_offset + DRAW_STRIDE * u64::from(i),
        )
    }

    /// Records the frame's start: the masks zeroed, the list emptied, the draws'
    /// `sources` written (transfer writes of the buffer).
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue; earlier accesses
    /// of the buffer are ordered before these transfer writes (the caller's barrier); it
    /// stays alive until the command buffer has executed.
    pub unsafe fn record_reset(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        sources: &[DrawSource],
    ) -> Result<()> {
        if sources.len() != self.draws as usize {
            return Err(Error::Internal(format!(
                "{} behind draws for a buffer of {}",
                sources.len(),
                self.draws
            )));
        }
        let words: Vec<u32> = sources
            .iter()
            .flat_map(|s| {
                let [x0, y0, x1, y1] = s.rect;
                [
                    x0,
                    y0,
                    x1,
                    y1,
                    s.count,
                    s.first,
                    s.depth.max(0.0).to_bits(),
                    s.own,
                ]
            })
            .collect();
        let dev = ctx.device();
        let masks = Self::masks_bytes(self.tiles, self.mask_words);
        // SAFETY: this function's contract; every write is inside the buffer (its
        // sections), 4-byte aligned, and the updates are at most 65,536 bytes (MAX_DRAWS).
        unsafe {
            dev.cmd_update_buffer(
                cmd,
                self.buffer.raw,
                0,
                bytemuck::cast_slice(&[0u32, 1, 1, 0]),
            );
            dev.cmd_fill_buffer(cmd, self.buffer.raw, self.masks_offset, masks.max(4), 0);
            if !words.is_empty() {
                dev.cmd_update_buffer(
                    cmd,
                    self.buffer.raw,
                    self.sources_offset,
                    bytemuck::cast_slice(&words),
                );
            }
        }
        Ok(())
    }

    /// Records `behind_misses` over each of `tiles` (the first layer's live materials'
    /// lists, [`crate::embed::DisplacementPass`]'s slot 0); `first_frame` is the first
    /// layer's G-buffer frame (`R32G32_UINT`, each pixel's material).
    ///
    /// # Safety
    /// As [`BehindTiles::record_reset`]; when the command buffer executes `first.depth` and
    /// `first_frame` are in `SHADER_READ_ONLY_OPTIMAL` and `first.hit_height` in `GENERAL`, their writes,
    /// the lists' and the reset's visible to compute-shader reads (the caller's
    /// barriers); everything stays alive until it has executed.
    pub unsafe fn record_misses(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        first: FirstLayer,
        first_frame: vk::ImageView,
        tiles: &[MaterialTiles],
    ) -> Result<()> {
        let depth = self.misses.fetch_view(first.depth);
        let frame = self.misses.fetch_view(first_frame);
        let hit = storage_view(first.hit_height);
        let masks = self.section(self.masks_offset, self.sources_offset - self.masks_offset);
        let p = &self.misses.pipeline;
        let writes = [
            p.image("u_first_depth", &depth)?,
            p.image("u_first_hit_height", &hit)?,
            p.buffer("u_masks", &masks)?,
            p.image("u_first_frame", &frame)?,
        ];
        for t in tiles {
            let push = MissParams {
                frame_size: [self.extent.width, self.extent.height],
                material: t.material,
                mask_words: self.mask_words,
                rows: self.tiles[1],
                pad: [0; 3],
            };
            debug_assert_eq!(TILES.0, "u_tiles");
            // SAFETY: this function's contract; the pipeline declares u_tiles.
            unsafe { t.dispatch(ctx, cmd, p, &writes, bytemuck::bytes_of(&push))? };
        }
        Ok(())
    }

    /// Records `behind_cull`'s `step` (0, then 1).
    ///
    /// # Safety
    /// As [`BehindTiles::record_reset`]; the earlier steps' writes (the reset, the
    /// masks, step 0) are visible to this dispatch (the caller's barriers).
    pub unsafe fn record_cull(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        step: u32,
    ) -> Result<()> {
        let p = &self.cull;
        let masks = self.section(self.masks_offset, self.sources_offset - self.masks_offset);
        let list = self.list();
        let sources = self.section(self.sources_offset, self.draws_offset - self.sources_offset);
        let draws = self.section(self.draws_offset, vk::WHOLE_SIZE);
        let writes = [
            p.buffer("u_masks", &masks)?,
            p.buffer("u_list", &list)?,
            p.buffer("u_sources", &sources)?,
            p.buffer("u_draws", &draws)?,
        ];
        let push = CullParams {
            step,
            rows: self.tiles[1],
            mask_words: self.mask_words,
            draw_count: self.draws,
            tiles_x: self.tiles[0],
            pad: [0; 3],
        };
        let group = p.local_size[0] * p.local_size[1];
        let groups = if step == 0 {
            self.tiles[1].max(self.draws).div_ceil(group)
        } else {
            1
        };
        // SAFETY: this function's contract; the writes match the pipeline's set 0.
        unsafe {
            p.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(&push),
                groups * p.local_size[0],
                1,
            )
        };
        Ok(())
    }
}

impl Destroy for BehindTiles {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.buffer.destroy(ctx);
            self.misses.destroy(ctx);
            self.cull.destroy(ctx);
        }
    }
}
