//! The `dig_corners` pass: the Depth Interval Grid of Judnich & Ling (section 4), one
//! ray per block corner (`glsl/dig_corners.comp`). The `dig` and `dig-guarded` trace
//! shaders then constrain each pixel's search to its block's interval.
//!
//! Bindings (set 0, push descriptors):
//!
//! | binding (GLSL name; the shader numbers it) | resource | layout on entry |
//! |---|---|---|
//! | `u_ray` | G-buffer `ray` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_depth` | G-buffer `depth` | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_frame` | G-buffer `frame` (the surface id and the material) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_height` | height field | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_corners` | corner grid (`R32G32B32A32_SFLOAT` storage, written) | `GENERAL` |
//!
//! Each DIG material has its own grid; a corner whose pixel is of another material (or
//! flat) is stored as no surface, so a block that straddles two materials falls back as
//! at a surface boundary.
//!
//! Each corner holds `(ray height at the last sample above the surface, surface id,
//! iterations, 0)`; see the shader for the details. The grid has
//! `(ceil(W / bx) + 1) x (ceil(H / by) + 1)` corners: the paper's `(W/bx + 1) x (H/by + 1)`
//! for frame sizes that are multiples of the block, one more partial block otherwise.

use crate::abi::CornerParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::commands::read_image;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage};
use crate::gpu::sync::Access;
use crate::gpu::{HeightTexture, Image, OneShot};
use crate::passes::gbuffer::GBufferViews;
use crate::scene::addressing_code;
use crate::shaders;
use ash::vk;

/// Format of the corner grid.
pub const CORNER_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// What the pass binds, by GLSL name (`glsl/dig_corners.comp` numbers them).
const BINDINGS: [(&str, vk::DescriptorType); 5] = [
    ("u_ray", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_depth", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_frame", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_corners", vk::DescriptorType::STORAGE_IMAGE),
];

/// What one corner dispatch marches: the method's steps, for one material's grid.
#[derive(Clone, Copy, Debug)]
pub struct CornerRun {
    /// Linear steps over the full depth (the method's).
    pub steps: u32,
    /// The material whose corners are marched (the others are stored as no surface).
    pub material: u32,
}

/// Corner-grid size for a frame and block size.
pub fn corner_size(frame: [u32; 2], block: [u32; 2]) -> [u32; 2] {
    [
        frame[0].div_ceil(block[0].max(1)) + 1,
        frame[1].div_ceil(block[1].max(1)) + 1,
    ]
}

/// The corner grid of one frame and block size.
pub struct CornerGrid {
    /// The grid image.
    pub image: Image,
    /// Block size in pixels.
    pub block: [u32; 2],
}

/// One corner as read back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Normalised ray height of the last sample above the surface.
    pub height: f32,
    /// Surface id (0: no geometry or a silhouette).
    pub surface: f32,
    /// Height fetches spent.
    pub iterations: f32,
}

impl CornerGrid {
    /// Allocates the grid for `frame` pixels in blocks of `block`.
    pub fn new(ctx: &Context, frame: [u32; 2], block: [u32; 2]) -> Result<Self> {
        let [w, h] = corner_size(frame, block);
        let image = Image::new(
            ctx,
            "dig.corners",
            CORNER_FORMAT,
            vk::Extent2D {
                width: w,
                height: h,
            },
            1,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        Ok(CornerGrid { image, block })
    }

    /// Grid size in corners.
    pub fn size(&self) -> [u32; 2] {
        [self.image.extent.width, self.image.extent.height]
    }

    /// Reads the corners back (row by row); the grid is in `current`.
    pub fn read(&self, ctx: &Context, shot: &OneShot, current: Access) -> Result<Vec<Corner>> {
        let bytes = read_image(ctx, shot, &self.image, current)?;
        Ok(bytemuck::cast_slice::<u8, [f32; 4]>(&bytes)
            .iter()
            .map(|c| Corner {
                height: c[0],
                surface: c[1],
                iterations: c[2],
            })
            .collect())
    }
}

impl Destroy for CornerGrid {
    /// Destroys the image.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.image.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.image.bytes()
    }
}

/// The corner pass.
pub struct DigCornerPass {
    pipeline: FetchPipeline,
}

impl DigCornerPass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(DigCornerPass {
            pipeline: FetchPipeline::new(
                ctx,
                "dig_corners",
                &shaders::DIG_CORNERS_COMP,
                &BINDINGS,
                std::mem::size_of::<CornerParams>() as u32,
            )?,
        })
    }

    /// Records the corner dispatch of `material`'s grid (corners whose pixel is of
    /// another material are marked as no surface): the G-buffer and height field readable by compute,
    /// the grid in `GENERAL` ready for storage writes (see the module table).
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `gbuffer`'s views belong to that device and have the formats of
    ///   [`crate::passes::gbuffer`] (sampled usage) and the size `gbuffer.extent`, the
    ///   size `grid` was made for.
    /// * When the command buffer executes, the images are in the layouts of the module's
    ///   table: the G-buffer and `height` in `SHADER_READ_ONLY_OPTIMAL`, their writes
    ///   visible to compute-shader sampled reads; the grid in `GENERAL`, earlier accesses
    ///   ordered before compute-shader storage writes (the caller's barriers).
    /// * The G-buffer's images, `height`, `grid` and this pass stay alive until the
    ///   command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        gbuffer: GBufferViews,
        height: &HeightTexture,
        grid: &CornerGrid,
        run: CornerRun,
    ) -> Result<()> {
        let CornerRun { steps, material } = run;
        let fetch = |view: vk::ImageView| self.pipeline.fetch_view(view);
        let ray = fetch(gbuffer.ray.view);
        let depth = fetch(gbuffer.depth.view);
        let frame = fetch(gbuffer.frame.view);
        let heights = [height.descriptor()];
        let corners = storage(&grid.image);
        let p = &self.pipeline.pipeline;
        let writes = [
            p.image("u_ray", &ray)?,
            p.image("u_depth", &depth)?,
            p.image("u_frame", &frame)?,
            p.image("u_height", &heights)?,
            p.image("u_corners", &corners)?,
        ];
        let frame = gbuffer.extent;
        let size = grid.size();
        let push = CornerParams {
            frame_size: [frame.width, frame.height],
            corner_size: size,
            block: grid.block,
            steps,
            addressing: addressing_code(height.addressing),
            material,
            pad: [0; 3],
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match `BINDINGS` (the pipeline's set 0) and name live views in
        // the layouts of the module's table; the push constants are the `CornerParams` the
        // layout was built with; the pipeline lives as long as this pass.
        unsafe {
            self.pipeline.pipeline.dispatch(
                ctx,
                cmd,
                &writes,
                bytemuck::bytes_of(&push),
                size[0],
                size[1],
            )
        };
        Ok(())
    }
}

impl Destroy for DigCornerPass {
    /// Destroys the pipeline and sampler.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
