//! The `classify` pass: sorts the frame's 8x8 tiles by material, so that every later
//! per-material pass (`dig_corners` aside, `trace`, `shadow`, `shade`, `hit_depth`) is
//! one indirect dispatch over the tiles that hold the material's pixels
//! (`glsl/classify.comp`, `glsl/common/tiles.glsl`). A frame's cost then follows its
//! displaced pixels, not its size times its materials: this is the tile classification
//! of deferred engines' material and lighting passes.
//!
//! A pixel's material is its G-buffer frame's material field (index + 1, 0 = not
//! displaced; read through `glsl/common/gbuffer.glsl`, packed by `glsl/include/dispmap_gbuffer.glsl`). Pixels of no
//! live material (no geometry, flat geometry, an index past the table or of a removed
//! material) are not traced: `classify` writes their hit texel (`NO_HIT_HEIGHT` without
//! geometry, [`NOT_DISPLACED_HEIGHT`] for flat geometry) and, with the corrected depth
//! on, their corrected depth (the G-buffer's own depth).
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/classify.comp`:
//!
//! | binding (GLSL name; the shader numbers it) | resource | layout on entry |
//! |---|---|---|
//! | `u_depth` | G-buffer `depth` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_frame` | G-buffer `frame` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_hit` | hit buffer (storage, written for pixels without displacement) | `GENERAL` |
//! | `u_tiles` | the tile lists (storage buffer, written) | |
//! | `u_args` | the dispatch arguments and counts (storage buffer, read and written) | |
//! | `u_hit_depth` | corrected depth (`DEPTH` variant; storage, written) | `GENERAL` |
//!
//! A per-material pass binds its material's list at binding [`TILES`] (`u_tiles`).

use crate::abi::ClassifyParams;
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, LOCAL_SIZE, storage_view};
use crate::gpu::{Buffer, ViewRef};
use crate::shaders;
use ash::vk;
use gpu_allocator::MemoryLocation;

pub use crate::abi::{MAX_MATERIALS, NOT_DISPLACED_HEIGHT};

/// The binding of a per-material pass's tile list (`u_tiles` in
/// `glsl/common/tiles.glsl`), as the passes declare it.
pub const TILES: (&str, vk::DescriptorType) = ("u_tiles", vk::DescriptorType::STORAGE_BUFFER);

/// `CLASSIFY_FLAG_WRITE_HITS` in `glsl/classify.comp`.
const FLAG_WRITE_HITS: u32 = 1;

/// Entries of a material's list are a multiple of this (256 bytes: the largest
/// `minStorageBufferOffsetAlignment` Vulkan allows, so every list starts aligned).
const LIST_ALIGN: u32 = 64;

/// Bytes of one material's arguments: a `VkDispatchIndirectCommand` and its live flag.
const ARGS_STRIDE: u64 = 16;

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;
const BUFFER: vk::DescriptorType = vk::DescriptorType::STORAGE_BUFFER;

/// The tile lists of one frame slot: one list per material of the table and its
/// indirect dispatch arguments.
pub struct TileLists {
    /// Every material's list (`capacity` entries each).
    pub tiles: Buffer,
    /// Per material a `VkDispatchIndirectCommand` and a live flag (16 bytes), then a
    /// count per material.
    pub args: Buffer,
    capacity: u32,
    materials: u32,
    extent: vk::Extent2D,
}

impl TileLists {
    /// Lists for `materials` table entries of a frame of `extent`.
    pub fn new(ctx: &Context, name: &str, extent: vk::Extent2D, materials: u32) -> Result<Self> {
        if materials == 0 || materials > MAX_MATERIALS {
            return Err(Error::invalid(
                "materials",
                format!("{materials} is outside 1..={MAX_MATERIALS}"),
            ));
        }
        let [tx, ty] = tile_count(extent);
        let capacity = (tx * ty).next_multiple_of(LIST_ALIGN);
        let tiles = Buffer::new(
            ctx,
            &format!("{name}.tiles"),
            u64::from(capacity) * u64::from(materials) * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let args = Buffer::new(
            ctx,
            &format!("{name}.args"),
            args_bytes(materials),
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        );
        let args = match args {
            Ok(a) => a,
            Err(e) => {
                let mut tiles = tiles;
                // SAFETY: built above and never used by a command.
                unsafe { tiles.destroy(ctx) };
                return Err(e);
            }
        };
        Ok(TileLists {
            tiles,
            args,
            capacity,
            materials,
            extent,
        })
    }

    /// The table entries the lists are for.
    pub fn materials(&self) -> u32 {
        self.materials
    }

    /// The frame size the lists are for.
    pub fn extent(&self) -> vk::Extent2D {
        self.extent
    }

    /// Material `m`'s list, for the binding [`TILES`].
    pub fn list(&self, m: u32) -> [vk::DescriptorBufferInfo; 1] {
        let bytes = u64::from(self.capacity) * 4;
        [vk::DescriptorBufferInfo {
            buffer: self.tiles.raw,
            offset: u64::from(m) * bytes,
            range: bytes,
        }]
    }

    /// The offset of material `m`'s `VkDispatchIndirectCommand` in [`TileLists::args`].
    pub fn args_offset(&self, m: u32) -> u64 {
        u64::from(m) * ARGS_STRIDE
    }

    /// Material `m`'s list and dispatch arguments.
    pub fn of(&self, m: u32) -> MaterialTiles {
        MaterialTiles {
            material: m,
            list: self.list(m)[0],
            args: self.args.raw,
            args_offset: self.args_offset(m),
        }
    }
}

impl Destroy for TileLists {
    /// Destroys both buffers. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.tiles.destroy(ctx);
            self.args.destroy(ctx);
        }
    }
}

/// One material's tiles: what a per-material pass dispatches over.
#[derive(Clone, Copy, Debug)]
pub struct MaterialTiles {
    /// The material (its index in the pass's table).
    pub material: u32,
    /// Its list, bound at [`TILES`].
    pub list: vk::DescriptorBufferInfo,
    /// The buffer holding its `VkDispatchIndirectCommand`.
    pub args: vk::Buffer,
    /// That command's offset.
    pub args_offset: u64,
}

impl MaterialTiles {
    /// Binds `pipeline` with `writes` plus the list (binding [`TILES`]) and `push`, and
    /// dispatches one workgroup per tile of the list.
    ///
    /// # Safety
    /// As [`crate::gpu::ComputePipeline::dispatch_indirect`]; the pipeline's set 0
    /// declares [`TILES`]; the lists were written by a `classify` recorded before in the
    /// same command buffer and made visible to the dispatch (the caller's barriers).
    pub unsafe fn dispatch(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        pipeline: &crate::gpu::ComputePipeline,
        writes: &[vk::WriteDescriptorSet],
        push: &[u8],
    ) -> Result<()> {
        let list = [self.list];
        let mut all: Vec<vk::WriteDescriptorSet> = writes.to_vec();
        all.push(pipeline.buffer(TILES.0, &list)?);
        // SAFETY: this function's contract.
        unsafe { pipeline.dispatch_indirect(ctx, cmd, &all, push, self.args, self.args_offset) };
        Ok(())
    }
}

/// Tiles of `extent` along x and y.
pub fn tile_count(extent: vk::Extent2D) -> [u32; 2] {
    [
        extent.width.div_ceil(LOCAL_SIZE[0]),
        extent.height.div_ceil(LOCAL_SIZE[1]),
    ]
}

fn args_bytes(materials: u32) -> u64 {
    u64::from(materials) * (ARGS_STRIDE + 4)
}

/// What `classify` reads and writes (layouts in the module docs).
pub struct ClassifyInputs<'a> {
    /// The host's G-buffer depth.
    pub depth: vk::ImageView,
    /// The host's G-buffer frame (its material field).
    pub frame: vk::ImageView,
    /// The hit buffer.
    pub hit: ViewRef,
    /// Whether the hit texels of pixels without displacement are written (not when the
    /// hit buffer holds the host's hits).
    pub write_hits: bool,
    /// The corrected depth (`None` when the output is off).
    pub hit_depth: Option<vk::ImageView>,
    /// The slot's lists.
    pub lists: &'a TileLists,
    /// Per table entry: whether it holds a material (`lists.materials()` entries).
    pub live: &'a [bool],
}

/// The classification pipelines (without and with the corrected depth).
pub struct ClassifyPass {
    plain: FetchPipeline,
    depth: FetchPipeline,
}

impl ClassifyPass {
    /// The bindings of the variant with (`hit_depth`) or without the corrected depth, as
    /// its shader declares them (reflected): what its dispatch reads and writes.
    pub fn bindings(&self, hit_depth: bool) -> &'static [crate::shaders::ShaderBinding] {
        if hit_depth {
            self.depth.pipeline.bindings
        } else {
            self.plain.pipeline.bindings
        }
    }

    /// Builds both pipelines.
    pub fn new(ctx: &Context) -> Result<Self> {
        let size = std::mem::size_of::<ClassifyParams>() as u32;
        let base = [
            ("u_depth", SAMPLED),
            ("u_frame", SAMPLED),
            ("u_hit", STORAGE),
            ("u_tiles", BUFFER),
            ("u_args", BUFFER),
        ];
        let plain = FetchPipeline::new(ctx, "classify", &shaders::CLASSIFY_COMP, &base, size)?;
        let mut with_depth = base.to_vec();
        with_depth.push(("u_hit_depth", STORAGE));
        match FetchPipeline::new(
            ctx,
            "classify[depth]",
            &shaders::CLASSIFY_COMP_DEPTH,
            &with_depth,
            size,
        ) {
            Ok(depth) => Ok(ClassifyPass { plain, depth }),
            Err(e) => {
                let mut plain = plain;
                // SAFETY: built above and never used by a command.
                unsafe { plain.destroy(ctx) };
                Err(e)
            }
        }
    }

    /// Records the reset of the lists' arguments: a transfer write of `inputs.lists`'
    /// argument buffer (the materials' counts zeroed, each live material's dispatch made
    /// one workgroup high), which [`ClassifyPass::record`] then reads and writes.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * Earlier accesses of the argument buffer are ordered before this transfer write
    ///   (the caller's barrier), and it stays alive until the command buffer has executed.
    pub unsafe fn record_reset(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: &ClassifyInputs,
    ) {
        let lists = inputs.lists;
        let n = lists.materials as usize;
        let mut init = Vec::with_capacity(n * 5);
        for m in 0..n {
            let live = u32::from(inputs.live.get(m).copied().unwrap_or(false));
            init.extend_from_slice(&[0, 0, 1, live]);
        }
        init.resize(n * 5, 0);
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the update is `args_bytes(materials)` bytes (a multiple of 4, at most
        // 20 * MAX_MATERIALS < 65536) of a live TRANSFER_DST buffer.
        unsafe {
            ctx.device()
                .cmd_update_buffer(cmd, lists.args.raw, 0, bytemuck::cast_slice(&init))
        };
    }

    /// Records the classification: the tile lists (and, with `write_hits`, the hit texels
    /// of pixels without displacement; with `hit_depth`, their corrected depth), after
    /// [`ClassifyPass::record_reset`]. Its accesses are its shader's bindings
    /// ([`ClassifyPass::bindings`]); the caller's barriers order them.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * The views belong to that device, with the formats and usages of the module's
    ///   table, of the lists' extent; when the command buffer executes they are in the
    ///   layouts of the module's table, and earlier accesses of every binding (the reset
    ///   included) are ordered before and visible to this dispatch's (the caller's
    ///   barriers).
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: &ClassifyInputs,
    ) -> Result<()> {
        let lists = inputs.lists;
        let pipeline = if inputs.hit_depth.is_some() {
            &self.depth
        } else {
            &self.plain
        };
        let fetch = |view| pipeline.fetch_view(view);
        let (depth, frame) = (fetch(inputs.depth), fetch(inputs.frame));
        let hits = storage_view(inputs.hit.view);
        let tiles = [vk::DescriptorBufferInfo {
            buffer: lists.tiles.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }];
        let args = [vk::DescriptorBufferInfo {
            buffer: lists.args.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }];
        let hit_depth = inputs.hit_depth.map(storage_view);
        let p = &pipeline.pipeline;
        let mut writes = vec![
            p.image("u_depth", &depth)?,
            p.image("u_frame", &frame)?,
            p.image("u_hit", &hits)?,
            p.buffer("u_tiles", &tiles)?,
            p.buffer("u_args", &args)?,
        ];
        if let Some(d) = &hit_depth {
            writes.push(p.image("u_hit_depth", d)?);
        }
        let extent = inputs.hit.extent;
        let push = ClassifyParams {
            frame_size: [extent.width, extent.height],
            material_count: lists.materials,
            tile_capacity: lists.capacity,
            flags: if inputs.write_hits {
                FLAG_WRITE_HITS
            } else {
                0
            },
            pad: [0; 3],
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 and name live resources in the
        // layouts of the module's table, their earlier accesses ordered before; the push
        // constants are the `ClassifyParams` the layout was built with.
        unsafe {
            pipeline.pipeline.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(&push),
                extent.width,
                extent.height,
            );
        }
        Ok(())
    }
}

impl Destroy for ClassifyPass {
    /// Destroys both pipelines. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.plain.destroy(ctx);
            self.depth.destroy(ctx);
        }
    }
}
