//! The `shade` pass: lights each pixel's hit and writes an RGBA8 image.
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/shade.comp`:
//!
//! | binding (GLSL name; the shader numbers it) | resource | layout on entry |
//! |---|---|---|
//! | `u_hit_uv`, `u_hit_height` | hit images (storage, read) | `GENERAL` |
//! | `u_frame` | G-buffer `frame` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_height` | height field (bilinear sampler) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_color` | colour (`R8G8B8A8_UNORM` storage, written, sRGB-encoded values) | `GENERAL` |
//! | `u_albedo` | albedo map, or the height field when there is none (`crate::material`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_normal_map` | normal map, or the height field when there is none | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_visibility` | light visibility (`R16_SFLOAT` storage, read; [`ShadePass::shadowed`] only) | `GENERAL` |
//! | `u_depth` | G-buffer `depth` (sampled: which pixels have geometry) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_tiles` | the material's tile list ([`crate::passes::classify`]) | |
//!
//! One dispatch shades one material (its `ShadeParams::camera_pos.w`): a workgroup per
//! tile of its list, an invocation per pixel of the material; every other pixel keeps the
//! colour image's contents (the host's).
//!
//! Without self-shadowing the pipeline has no `u_visibility` (the `shadow` pass and its image
//! are not built); with it ([`ShadePass::shadowed`], the shader's `SHADOWS` variant) the
//! visibility written by [`crate::passes::shadow`] scales the direct light.

use crate::abi::ShadeParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::gpu::{HeightTexture, ViewRef};
use crate::passes::classify::{MaterialTiles, TILES};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::trace::HitViews;
use crate::shaders;
use ash::vk;

/// Format of the colour output.
pub const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

/// What both variants bind, by GLSL name (`glsl/shade.comp` numbers them).
const BINDINGS: [(&str, vk::DescriptorType); 9] = [
    ("u_hit_uv", vk::DescriptorType::STORAGE_IMAGE),
    ("u_hit_height", vk::DescriptorType::STORAGE_IMAGE),
    ("u_frame", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_color", vk::DescriptorType::STORAGE_IMAGE),
    ("u_albedo", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_normal_map", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    ("u_depth", vk::DescriptorType::COMBINED_IMAGE_SAMPLER),
    TILES,
];

/// What the shadowed variant binds besides.
const VISIBILITY: (&str, vk::DescriptorType) = ("u_visibility", vk::DescriptorType::STORAGE_IMAGE);

/// The images the shade pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct ShadeInputs<'a> {
    /// The hit images (read).
    pub hit: HitViews,
    /// The G-buffer (its frame is read).
    pub gbuffer: GBufferViews,
    /// The height field.
    pub height: &'a HeightTexture,
    /// Albedo and normal map (bindings 5 and 6; `None`: the height texture stands in,
    /// which the shader reads as "no map", see [`crate::material`]).
    pub material: Option<&'a crate::material::MaterialTextures>,
    /// The colour output (written; the frame's size).
    pub color: ViewRef,
    /// The light visibility of the `shadow` pass (read); required by a
    /// [`ShadePass::shadowed`] pass, ignored otherwise.
    pub visibility: Option<vk::ImageView>,
    /// The material and its tiles.
    pub tiles: MaterialTiles,
}

/// The shade pass.
pub struct ShadePass {
    pipeline: FetchPipeline,
    shadowed: bool,
}

impl ShadePass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// Builds the pipeline (no self-shadowing).
    pub fn new(ctx: &Context) -> Result<Self> {
        Self::build(ctx, false)
    }

    /// Builds the pipeline that reads the `shadow` pass's visibility (`u_visibility`).
    pub fn shadowed(ctx: &Context) -> Result<Self> {
        Self::build(ctx, true)
    }

    fn build(ctx: &Context, shadowed: bool) -> Result<Self> {
        let (name, shader) = if shadowed {
            ("shade[shadows]", &shaders::SHADE_COMP_SHADOWS)
        } else {
            ("shade", &shaders::SHADE_COMP)
        };
        let mut bindings = BINDINGS.to_vec();
        if shadowed {
            bindings.push(VISIBILITY);
        }
        Ok(ShadePass {
            pipeline: FetchPipeline::new(
                ctx,
                name,
                shader,
                &bindings,
                std::mem::size_of::<ShadeParams>() as u32,
            )?,
            shadowed,
        })
    }

    /// Whether this pass reads the light visibility ([`ShadePass::shadowed`]).
    pub fn is_shadowed(&self) -> bool {
        self.shadowed
    }

    /// Records the dispatch over the material's tiles. Fails (recording nothing) when a
    /// shadowed pass gets no visibility image.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `inputs`' views belong to that device and have the formats and usages of the
    ///   module's table; the hit images, the G-buffer and the visibility are of
    ///   `inputs.color`'s size.
    /// * When the command buffer executes, the images are in the layouts of the module's
    ///   table: the hit images and the visibility in `GENERAL`, their writes visible to
    ///   compute-shader storage reads; the G-buffer, `height` and the material maps in
    ///   `SHADER_READ_ONLY_OPTIMAL`, their writes visible to compute-shader sampled
    ///   reads; the colour image in `GENERAL`, earlier accesses ordered before
    ///   compute-shader storage writes (the caller's barriers); the tile list written by a
    ///   `classify` recorded before in the same command buffer.
    /// * The images behind `inputs` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: ShadeInputs,
        params: &ShadeParams,
    ) -> Result<()> {
        let ShadeInputs {
            hit,
            gbuffer,
            height,
            material,
            color,
            visibility,
            tiles,
        } = inputs;
        let visibility = match (self.shadowed, visibility) {
            (true, Some(v)) => Some(storage_view(v)),
            (true, None) => {
                return Err(crate::error::Error::invalid(
                    "shade inputs",
                    "the shadowed shade pass needs the visibility image",
                ));
            }
            (false, _) => None,
        };
        let (hit_uv, hit_height) = (storage_view(hit.uv), storage_view(hit.height));
        let frame = self.pipeline.fetch_view(gbuffer.frame.view);
        let depth = self.pipeline.fetch_view(gbuffer.depth.view);
        let heights = [height.descriptor()];
        let colors = storage_view(color.view);
        let [albedo, normal_map] = crate::material::MaterialTextures::descriptors(material, height);
        let p = &self.pipeline.pipeline;
        let mut writes = vec![
            p.image("u_hit_uv", &hit_uv)?,
            p.image("u_hit_height", &hit_height)?,
            p.image("u_frame", &frame)?,
            p.image("u_height", &heights)?,
            p.image("u_color", &colors)?,
            p.image("u_albedo", &albedo)?,
            p.image("u_normal_map", &normal_map)?,
            p.image("u_depth", &depth)?,
        ];
        if let Some(v) = &visibility {
            writes.push(p.image(VISIBILITY.0, v)?);
        }
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 (`u_visibility` exactly for the shadowed
        // variant, checked above) and name live views in the layouts of the module's table;
        // the push constants are the `ShadeParams` the layout was built with (`camera_pos.w`
        // set to the material here); the pipeline lives as long as this pass; the list is
        // the classification's (this function's contract).
        let mut params = *params;
        params.camera_pos.w = tiles.material as f32;
        unsafe {
            tiles.dispatch(
                ctx,
                cmd,
                &self.pipeline.pipeline,
                &writes,
                bytemuck::bytes_of(&params),
            )
        }
    }
}

impl Destroy for ShadePass {
    /// Destroys the pipeline and sampler.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
