//! The `classify` pass: sorts the frame's 8x8 tiles by material, so that every later
//! per-material pass (`dig_corners` aside, `trace`, `shadow`, `shade`, `hit_depth`) is
//! one indirect dispatch over the tiles that hold the material's pixels
//! (`glsl/classify.comp`, `glsl/classify_offsets.comp`, `glsl/classify_scatter.comp`,
//! `glsl/classify_mixed.comp`, `glsl/common/tiles.glsl`). A frame's cost then follows its displaced pixels, not its
//! size times its materials: this is the tile classification of deferred engines'
//! material and lighting passes.
//!
//! A pixel's material is its G-buffer frame's material field (index + 1, 0 = not
//! displaced; read through `glsl/common/gbuffer.glsl`, packed by `glsl/include/dispmap_gbuffer.glsl`). Pixels of no
//! live material (no geometry, flat geometry, an index past the table or of a removed
//! material) are not traced: `classify` writes their hit texels (uv `(0, 0)`, height
//! `NO_HIT_HEIGHT` without geometry, [`NOT_DISPLACED_HEIGHT`] for flat geometry), with the
//! corrected depth on their corrected depth (the G-buffer's own depth), and with the
//! iteration output on their iteration count (0).
//!
//! Every material's list lives in one buffer per frame slot whose size follows the frame
//! alone ([`TileLists::bytes_for`]): a tile holds at most 64 distinct materials, so the
//! lists of a frame hold at most 64 entries per tile whatever the table's length. Four
//! dispatches ([`ClassifyStep`]) fill it: `Count` counts the tiles of each material (and
//! keeps a summary per tile, and a list of the tiles of several materials), `Offsets`
//! places each list by a prefix sum of the counts and writes the dispatch arguments,
//! `Scatter` (one invocation per tile) writes the entries of tiles of one material, and
//! `Mixed` (an indirect dispatch over the tiles of several materials, which it reads
//! again) the others'. Adding or removing materials changes none of its buffers: the
//! arguments have room for [`MAX_MATERIALS`] entries.
//!
//! Bindings (set 0, push descriptors), mirrored by the shaders:
//!
//! | binding (GLSL name; the shaders number them) | resource | steps | layout on entry |
//! |---|---|---|---|
//! | `u_depth` | G-buffer `depth` (sampled) | count, mixed | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_frame` | G-buffer `frame` (sampled) | count, mixed | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_hit_uv`, `u_hit_height` | hit images (storage, written for pixels without displacement) | count | `GENERAL` |
//! | `u_tiles` | the tile buffer (storage buffer, written) | all | |
//! | `u_args` | the dispatch arguments and counts (storage buffer, read and written) | all | |
//! | `u_hit_depth` | corrected depth (`DEPTH` variants; storage, written) | count | `GENERAL` |
//! | `u_iterations` | iteration counts (`ITERATIONS` variants; storage, written) | count | `GENERAL` |
//!
//! A per-material pass binds the slot's tile buffer at binding [`TILES`] (`u_tiles`) and
//! finds its material's list in the buffer's header (`glsl/common/tiles.glsl`).

use crate::abi::ClassifyParams;
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::Buffer;
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::pipeline::{FetchPipeline, LOCAL_SIZE, storage_view};
use crate::passes::trace::HitViews;
use crate::shaders;
use ash::vk;
use gpu_allocator::MemoryLocation;

pub use crate::abi::{MAX_MATERIALS, NOT_DISPLACED_HEIGHT};

/// The binding of a per-material pass's tile list (`u_tiles` in
/// `glsl/common/tiles.glsl`), as the passes declare it.
pub const TILES: (&str, vk::DescriptorType) = ("u_tiles", vk::DescriptorType::STORAGE_BUFFER);

/// `CLASSIFY_FLAG_WRITE_HITS` in `glsl/classify.comp`.
const FLAG_WRITE_HITS: u32 = 1;

/// Invocations of a workgroup: a tile's pixels, and the most distinct materials a tile
/// holds.
const TILE_PIXELS: u64 = (LOCAL_SIZE[0] * LOCAL_SIZE[1]) as u64;

/// Words of the tile buffer's header: per table entry its list's first entry and length
/// (`TILE_HEADER_WORDS` in `glsl/common/tiles.glsl`).
const HEADER_WORDS: u64 = 2 * MAX_MATERIALS as u64;

/// Bytes of one table entry's arguments: a `VkDispatchIndirectCommand`, its live flag, its
/// count and cursor, two words of padding (`ARGS_WORDS` in `glsl/common/tiles.glsl`).
const ARGS_STRIDE: u64 = 32;

/// Bytes of the argument buffer: [`MAX_MATERIALS`] entries and the list of tiles of
/// several materials (`ARGS_MIXED`).
const ARGS_BYTES: u64 = (MAX_MATERIALS as u64 + 1) * ARGS_STRIDE;

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;
const BUFFER: vk::DescriptorType = vk::DescriptorType::STORAGE_BUFFER;

/// The tile lists of one frame slot: one buffer holding every material's list, and the
/// materials' indirect dispatch arguments. Their sizes follow the frame's size only.
pub struct TileLists {
    /// The tile buffer: the lists' header (per table entry its list's first entry and
    /// length), a summary per tile, the list of tiles of several materials, then the
    /// entries (at most 64 per tile).
    pub tiles: Buffer,
    /// Per table entry ([`MAX_MATERIALS`] of them) a `VkDispatchIndirectCommand`, a live
    /// flag, its count and the scatter's cursor (32 bytes); then the same for the list of
    /// tiles of several materials.
    pub args: Buffer,
    tile_count: u32,
    extent: vk::Extent2D,
}

impl TileLists {
    /// Lists for a frame of `extent`, for any table of up to [`MAX_MATERIALS`] entries.
    pub fn new(ctx: &Context, name: &str, extent: vk::Extent2D) -> Result<Self> {
        let [tx, ty] = tile_count(extent);
        let tiles = Buffer::new(
            ctx,
            &format!("{name}.tiles"),
            tile_buffer_bytes(extent),
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        let args = Buffer::new(
            ctx,
            &format!("{name}.args"),
            ARGS_BYTES,
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
            tile_count: tx * ty,
            extent,
        })
    }

    /// The bytes the lists of one frame slot of `extent` take ([`TileLists::new`]'s two
    /// buffers): `4 * (2048 + 66 * tiles) + 32 * 1025` with `tiles` the frame's 8x8
    /// tiles (8.19 MiB at 1920x1080), whatever the number of materials.
    pub fn bytes_for(extent: vk::Extent2D) -> u64 {
        tile_buffer_bytes(extent) + ARGS_BYTES
    }

    /// The bytes these lists take (their buffers' sizes).
    pub fn bytes(&self) -> u64 {
        self.tiles.size + self.args.size
    }

    /// The frame size the lists are for.
    pub fn extent(&self) -> vk::Extent2D {
        self.extent
    }

    /// The tile buffer, for the binding [`TILES`]: every material's list (each pass
    /// finds its own in the header).
    pub fn list(&self) -> [vk::DescriptorBufferInfo; 1] {
        [vk::DescriptorBufferInfo {
            buffer: self.tiles.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
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
            list: self.list()[0],
            args: self.args.raw,
            args_offset: self.args_offset(m),
        }
    }

    /// The word of the tile buffer where the entries start (after the header, the tile
    /// summaries and the list of tiles of several materials).
    fn entries_base(&self) -> u32 {
        HEADER_WORDS as u32 + 2 * self.tile_count
    }
}

/// Bytes of the tile buffer of a frame of `extent`: the header, a summary word and a
/// mixed-list word per tile and 64 entry words per tile.
fn tile_buffer_bytes(extent: vk::Extent2D) -> u64 {
    let [tx, ty] = tile_count(extent);
    let tiles = u64::from(tx) * u64::from(ty);
    4 * (HEADER_WORDS + tiles * (2 + TILE_PIXELS))
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

    fn bytes(&self) -> u64 {
        TileLists::bytes(self)
    }
}

/// One material's tiles: what a per-material pass dispatches over.
#[derive(Clone, Copy, Debug)]
pub struct MaterialTiles {
    /// The material (its index in the pass's table).
    pub material: u32,
    /// The slot's tile buffer (every material's list), bound at [`TILES`].
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

/// The four dispatches of `classify`, in their order (the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClassifyStep {
    /// Counts each material's tiles, lists the tiles of several materials, writes the hit
    /// texels (and corrected depth and iteration count) of pixels without displacement (`glsl/classify.comp`).
    Count,
    /// Places each list and writes the dispatch arguments (`glsl/classify_offsets.comp`).
    Offsets,
    /// Writes the entries of tiles of one material (`glsl/classify_scatter.comp`).
    Scatter,
    /// Writes the entries of tiles of several materials: an indirect dispatch, whose
    /// arguments `Offsets` wrote (`glsl/classify_mixed.comp`).
    Mixed,
}

impl ClassifyStep {
    /// The steps in their order.
    pub const ALL: [ClassifyStep; 4] = [
        ClassifyStep::Count,
        ClassifyStep::Offsets,
        ClassifyStep::Scatter,
        ClassifyStep::Mixed,
    ];
}

/// What `classify` reads and writes (layouts in the module docs).
pub struct ClassifyInputs<'a> {
    /// The host's G-buffer depth.
    pub depth: vk::ImageView,
    /// The host's G-buffer frame (its material field).
    pub frame: vk::ImageView,
    /// The hit images.
    pub hit: HitViews,
    /// The frame's size.
    pub extent: vk::Extent2D,
    /// Whether the hit texels of pixels without displacement are written (not when the
    /// hit images hold the host's hits).
    pub write_hits: bool,
    /// The corrected depth (`None` when the output is off).
    pub hit_depth: Option<vk::ImageView>,
    /// The iteration counts (`None` when the output is off).
    pub iterations: Option<vk::ImageView>,
    /// The slot's lists.
    pub lists: &'a TileLists,
    /// Per table entry: whether it holds a material (the table's length, at most
    /// [`MAX_MATERIALS`]).
    pub live: &'a [bool],
}

/// The classification pipelines (the counting step without and with the corrected
/// depth and the iteration counts, the offsets, the scatter and the mixed tiles'
/// scatter).
pub struct ClassifyPass {
    /// The counting step's variants, by `depth as usize + 2 * iterations as usize`.
    count: [FetchPipeline; 4],
    /// Their `LISTED` variants, built on first use ([`ClassifyPass::prepare_listed`]).
    listed: [Option<FetchPipeline>; 4],
    offsets: FetchPipeline,
    scatter: FetchPipeline,
    mixed: FetchPipeline,
}

impl ClassifyPass {
    /// The bindings of `step` (of the counting step's variant with or without the
    /// corrected depth, `hit_depth`, and the iteration counts, `iterations`), as its
    /// shader declares them (reflected): what its dispatch reads and writes.
    pub fn bindings(
        &self,
        step: ClassifyStep,
        hit_depth: bool,
        iterations: bool,
    ) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline(step, hit_depth, iterations).pipeline.bindings
    }

    /// As [`ClassifyPass::bindings`], of the `LISTED` counting step when `listed`
    /// (built by [`ClassifyPass::prepare_listed`]).
    pub(crate) fn bindings_of(
        &self,
        step: ClassifyStep,
        hit_depth: bool,
        iterations: bool,
        listed: bool,
    ) -> Result<&'static [crate::shaders::ShaderBinding]> {
        Ok(self
            .pipeline_of(step, hit_depth, iterations, listed)?
            .pipeline
            .bindings)
    }

    fn pipeline(&self, step: ClassifyStep, hit_depth: bool, iterations: bool) -> &FetchPipeline {
        match step {
            ClassifyStep::Count => {
                &self.count[usize::from(hit_depth) + 2 * usize::from(iterations)]
            }
            ClassifyStep::Offsets => &self.offsets,
            ClassifyStep::Scatter => &self.scatter,
            ClassifyStep::Mixed => &self.mixed,
        }
    }

    fn pipeline_of(
        &self,
        step: ClassifyStep,
        hit_depth: bool,
        iterations: bool,
        listed: bool,
    ) -> Result<&FetchPipeline> {
        if !(listed && step == ClassifyStep::Count) {
            return Ok(self.pipeline(step, hit_depth, iterations));
        }
        self.listed[usize::from(hit_depth) + 2 * usize::from(iterations)]
            .as_ref()
            .ok_or_else(|| Error::Internal("the listed classify was not prepared".into()))
    }

    /// Builds the `LISTED` counting step (a classification of listed tiles only,
    /// [`ListedTiles`]) with or without the corrected depth and the iteration counts, once.
    pub(crate) fn prepare_listed(
        &mut self,
        ctx: &Context,
        hit_depth: bool,
        iterations: bool,
    ) -> Result<()> {
        let i = usize::from(hit_depth) + 2 * usize::from(iterations);
        if self.listed[i].is_some() {
            return Ok(());
        }
        let (name, shader) = match (hit_depth, iterations) {
            (false, false) => ("classify[listed]", &shaders::CLASSIFY_COMP_LISTED),
            (true, false) => (
                "classify[listed,depth]",
                &shaders::CLASSIFY_COMP_LISTED_DEPTH,
            ),
            (false, true) => (
                "classify[listed,iterations]",
                &shaders::CLASSIFY_COMP_LISTED_ITERATIONS,
            ),
            (true, true) => (
                "classify[listed,depth,iterations]",
                &shaders::CLASSIFY_COMP_LISTED_DEPTH_ITERATIONS,
            ),
        };
        let mut bindings = vec![
            ("u_depth", SAMPLED),
            ("u_frame", SAMPLED),
            ("u_hit_uv", STORAGE),
            ("u_hit_height", STORAGE),
            ("u_tiles", BUFFER),
            ("u_args", BUFFER),
            (LISTED, BUFFER),
        ];
        if hit_depth {
            bindings.push(("u_hit_depth", STORAGE));
        }
        if iterations {
            bindings.push(("u_iterations", STORAGE));
        }
        let size = std::mem::size_of::<ClassifyParams>() as u32;
        self.listed[i] = Some(FetchPipeline::new(ctx, name, shader, &bindings, size)?);
        Ok(())
    }

    /// Builds the pipelines.
    pub fn new(ctx: &Context) -> Result<Self> {
        let size = std::mem::size_of::<ClassifyParams>() as u32;
        let base = [
            ("u_depth", SAMPLED),
            ("u_frame", SAMPLED),
            ("u_hit_uv", STORAGE),
            ("u_hit_height", STORAGE),
            ("u_tiles", BUFFER),
            ("u_args", BUFFER),
        ];
        let with = |extra: &[(&'static str, vk::DescriptorType)]| {
            let mut b = base.to_vec();
            b.extend_from_slice(extra);
            b
        };
        let depth = ("u_hit_depth", STORAGE);
        let iterations = ("u_iterations", STORAGE);
        let lists = [("u_tiles", BUFFER), ("u_args", BUFFER)];
        let mixed = [
            ("u_depth", SAMPLED),
            ("u_frame", SAMPLED),
            ("u_tiles", BUFFER),
            ("u_args", BUFFER),
        ];
        let new = |name, shader, bindings: &[(&str, vk::DescriptorType)]| {
            // SAFETY: nothing records with the pipeline before it is kept below.
            Ok::<_, Error>(unsafe {
                Guard::new(ctx, FetchPipeline::new(ctx, name, shader, bindings, size)?)
            })
        };
        let plain = new("classify", &shaders::CLASSIFY_COMP, &base)?;
        let with_depth = new(
            "classify[depth]",
            &shaders::CLASSIFY_COMP_DEPTH,
            &with(&[depth]),
        )?;
        let with_iterations = new(
            "classify[iterations]",
            &shaders::CLASSIFY_COMP_ITERATIONS,
            &with(&[iterations]),
        )?;
        let with_both = new(
            "classify[depth,iterations]",
            &shaders::CLASSIFY_COMP_DEPTH_ITERATIONS,
            &with(&[depth, iterations]),
        )?;
        let offsets = new("classify_offsets", &shaders::CLASSIFY_OFFSETS_COMP, &lists)?;
        let scatter = new("classify_scatter", &shaders::CLASSIFY_SCATTER_COMP, &lists)?;
        let mixed = new("classify_mixed", &shaders::CLASSIFY_MIXED_COMP, &mixed)?;
        Ok(ClassifyPass {
            count: [
                plain.keep(),
                with_depth.keep(),
                with_iterations.keep(),
                with_both.keep(),
            ],
            listed: [None, None, None, None],
            offsets: offsets.keep(),
            scatter: scatter.keep(),
            mixed: mixed.keep(),
        })
    }

    /// Records the reset of the lists' arguments: transfer writes of `inputs.lists`'
    /// argument buffer (each table entry's dispatch `(0, 0, 1)`, its live flag, its count
    /// zeroed; the same for the list of tiles of several materials), which
    /// [`ClassifyPass::record`] then reads and writes.
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
        let n = material_count(inputs) as usize;
        let words = (ARGS_STRIDE / 4) as usize;
        let mut init = vec![0u32; n * words];
        for (m, entry) in init.chunks_exact_mut(words).enumerate() {
            entry[2] = 1;
            entry[3] = u32::from(inputs.live[m]);
        }
        let mut mixed = [0u32; 8];
        mixed[2] = 1;
        let args = inputs.lists.args.raw;
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; each update is a multiple of 4 bytes, not 0 and under 65536 (at most
        // 32 * MAX_MATERIALS = 32768), inside the live TRANSFER_DST buffer of
        // 32 * (MAX_MATERIALS + 1) bytes.
        unsafe {
            if n > 0 {
                dev.cmd_update_buffer(cmd, args, 0, bytemuck::cast_slice(&init));
            }
            dev.cmd_update_buffer(
                cmd,
                args,
                u64::from(MAX_MATERIALS) * ARGS_STRIDE,
                bytemuck::cast_slice(&mixed),
            );
        }
    }

    /// Records `step` of the classification (the module docs; `Count` also writes, with
    /// `write_hits`, the hit texels of pixels without displacement, with `hit_depth` their
    /// corrected depth and with `iterations` their iteration count), after [`ClassifyPass::record_reset`] and the steps before
    /// it. Its accesses are its shader's bindings ([`ClassifyPass::bindings`]); the
    /// caller's barriers order them.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * The views belong to that device, with the formats and usages of the module's
    ///   table, of the lists' extent; when the command buffer executes they are in the
    ///   layouts of the module's table, and earlier accesses of every binding (the reset
    ///   and the earlier steps included) are ordered before and visible to this dispatch's
    ///   (the caller's barriers).
    /// * Everything stays alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: &ClassifyInputs,
        step: ClassifyStep,
    ) -> Result<()> {
        // SAFETY: this function's contract.
        unsafe { self.record_step(ctx, cmd, inputs, step, None) }
    }

    /// Records the frame start of a classification of `listed` tiles only, after
    /// [`ClassifyPass::record_reset`]: every tile's summary `TILE_EMPTY` (a transfer fill
    /// of the tile buffer, which the `LISTED` counting step then overwrites for the listed
    /// tiles). The pixels of the other tiles get no hit texels (nor corrected depth or
    /// iteration count): the caller gives them theirs.
    ///
    /// # Safety
    /// As [`ClassifyPass::record_reset`], for the tile buffer too.
    pub(crate) unsafe fn record_listed_reset(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: &ClassifyInputs,
    ) {
        let lists = inputs.lists;
        // SAFETY: this function's contract; the summaries lie inside the live
        // TRANSFER_DST buffer (after the header), a multiple of 4 bytes.
        unsafe {
            ctx.device().cmd_fill_buffer(
                cmd,
                lists.tiles.raw,
                4 * HEADER_WORDS,
                4 * u64::from(lists.tile_count.max(1)),
                u32::MAX,
            )
        };
    }

    /// [`ClassifyPass::record`], the counting step over `listed` tiles only (after
    /// [`ClassifyPass::record_listed_reset`] and [`ClassifyPass::prepare_listed`]).
    ///
    /// # Safety
    /// As [`ClassifyPass::record`]; the list and its dispatch were written before and are
    /// visible to compute-shader storage reads and indirect reads, and stay alive until
    /// the command buffer has executed.
    pub(crate) unsafe fn record_step(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: &ClassifyInputs,
        step: ClassifyStep,
        listed: Option<&ListedTiles>,
    ) -> Result<()> {
        let lists = inputs.lists;
        let pipeline = self.pipeline_of(
            step,
            inputs.hit_depth.is_some(),
            inputs.iterations.is_some(),
            listed.is_some(),
        )?;
        let fetch = |view| pipeline.fetch_view(view);
        let (depth, frame) = (fetch(inputs.depth), fetch(inputs.frame));
        let (hit_uv, hit_height) = (storage_view(inputs.hit.uv), storage_view(inputs.hit.height));
        let tiles = lists.list();
        let args = [vk::DescriptorBufferInfo {
            buffer: lists.args.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }];
        let hit_depth = inputs.hit_depth.map(storage_view);
        let iterations = inputs.iterations.map(storage_view);
        let p = &pipeline.pipeline;
        let mut writes = vec![p.buffer("u_tiles", &tiles)?, p.buffer("u_args", &args)?];
        if matches!(step, ClassifyStep::Count | ClassifyStep::Mixed) {
            writes.push(p.image("u_depth", &depth)?);
            writes.push(p.image("u_frame", &frame)?);
        }
        if step == ClassifyStep::Count {
            writes.push(p.image("u_hit_uv", &hit_uv)?);
            writes.push(p.image("u_hit_height", &hit_height)?);
            if let Some(d) = &hit_depth {
                writes.push(p.image("u_hit_depth", d)?);
            }
            if let Some(i) = &iterations {
                writes.push(p.image("u_iterations", i)?);
            }
        }
        let listed_info = listed.map(|l| [l.list]);
        if step == ClassifyStep::Count
            && let Some(info) = &listed_info
        {
            writes.push(p.buffer(LISTED, info)?);
        }
        let extent = inputs.extent;
        let push = ClassifyParams {
            frame_size: [extent.width, extent.height],
            material_count: material_count(inputs),
            entries_base: lists.entries_base(),
            flags: if inputs.write_hits {
                FLAG_WRITE_HITS
            } else {
                0
            },
            tile_count: lists.tile_count,
            pad: [0; 2],
        };
        let push = bytemuck::bytes_of(&push);
        // Count: one workgroup per tile; offsets: one workgroup; scatter: one invocation
        // per tile; mixed: one workgroup per listed tile.
        let [tx, ty] = tile_count(extent);
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 and name live resources in the
        // layouts of the module's table, their earlier accesses ordered before (for the
        // mixed step, `Offsets`' write of its dispatch too); the push constants are the
        // `ClassifyParams` the layout was built with; the argument buffer has
        // INDIRECT_BUFFER usage and the mixed list's command at its offset.
        unsafe {
            match step {
                ClassifyStep::Count => match listed {
                    Some(l) => p.dispatch_indirect(ctx, cmd, &writes, push, l.dispatch, l.offset),
                    None => p.dispatch(ctx, cmd, &writes, push, extent.width, extent.height),
                },
                ClassifyStep::Offsets => p.dispatch(ctx, cmd, &writes, push, 1, 1),
                ClassifyStep::Scatter => p.dispatch(ctx, cmd, &writes, push, tx, ty),
                ClassifyStep::Mixed => p.dispatch_indirect(
                    ctx,
                    cmd,
                    &writes,
                    push,
                    lists.args.raw,
                    u64::from(MAX_MATERIALS) * ARGS_STRIDE,
                ),
            }
        }
        Ok(())
    }
}

/// The GLSL name of the `LISTED` counting step's tile list.
const LISTED: &str = "u_listed";

/// The tiles a classification runs over when not the whole frame
/// ([`ClassifyPass::record_step`]): a buffer range holding a `VkDispatchIndirectCommand`
/// (one workgroup per listed tile, in rows of 65,535), the count, then the tiles packed
/// `x | y << 16` (`u_listed` in `glsl/classify.comp`), and where its dispatch is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ListedTiles {
    /// The list.
    pub list: vk::DescriptorBufferInfo,
    /// The buffer holding its dispatch (`INDIRECT_BUFFER` usage) ...
    pub dispatch: vk::Buffer,
    /// ... at this offset.
    pub offset: u64,
}

/// The table entries classified: `inputs.live`'s length, at most [`MAX_MATERIALS`].
fn material_count(inputs: &ClassifyInputs) -> u32 {
    (inputs.live.len() as u32).min(MAX_MATERIALS)
}

impl Destroy for ClassifyPass {
    /// Destroys the pipelines. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            for p in &mut self.count {
                p.destroy(ctx);
            }
            for p in &mut self.listed {
                p.destroy(ctx);
            }
            self.offsets.destroy(ctx);
            self.scatter.destroy(ctx);
            self.mixed.destroy(ctx);
        }
    }
}
