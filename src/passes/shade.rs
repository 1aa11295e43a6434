//! The `shade` pass: lights each pixel's hit and writes an RGBA8 image.
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/shade.comp`:
//!
//! | binding | resource | layout on entry |
//! |---|---|---|
//! | 0 | hit buffer (storage, read) | `GENERAL` |
//! | 1 | G-buffer `normal` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 2 | G-buffer `tangent` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 3 | height field (bilinear sampler) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 4 | colour (`R8G8B8A8_UNORM` storage, written, sRGB-encoded values) | `GENERAL` |
//! | 5 | albedo map, or the height field when there is none (`crate::material`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 6 | normal map, or the height field when there is none | `SHADER_READ_ONLY_OPTIMAL` |

use crate::abi::ShadeParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::pipeline::{FetchPipeline, image_write, storage_view};
use crate::gpu::{HeightTexture, ViewRef};
use crate::passes::gbuffer::GBufferViews;
use crate::shaders;
use ash::vk;

/// Format of the colour output.
pub const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

const BINDINGS: [vk::DescriptorType; 7] = [
    vk::DescriptorType::STORAGE_IMAGE,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::STORAGE_IMAGE,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
];

/// The images the shade pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct ShadeInputs<'a> {
    /// The hit buffer (read).
    pub hit: vk::ImageView,
    /// The G-buffer (normal and tangent are read).
    pub gbuffer: GBufferViews,
    /// The height field.
    pub height: &'a HeightTexture,
    /// The colour output (written; the frame's size).
    pub color: ViewRef,
}

/// The shade pass.
pub struct ShadePass {
    pipeline: FetchPipeline,
}

impl ShadePass {
    /// Builds the pipeline.
    pub fn new(ctx: &Context) -> Result<Self> {
        Ok(ShadePass {
            pipeline: FetchPipeline::new(
                ctx,
                "shade",
                &shaders::SHADE_COMP,
                &crate::gpu::pipeline::numbered(&BINDINGS),
                std::mem::size_of::<ShadeParams>() as u32,
            )?,
        })
    }

    /// Records the dispatch over the whole frame (no albedo or normal map).
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: ShadeInputs,
        params: &ShadeParams,
    ) {
        self.record_with_material(ctx, cmd, inputs, None, params);
    }

    /// Records the dispatch with the maps of `material` (bindings 5 and 6).
    pub fn record_with_material(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: ShadeInputs,
        material: Option<&crate::material::MaterialTextures>,
        params: &ShadeParams,
    ) {
        let ShadeInputs {
            hit,
            gbuffer,
            height,
            color,
        } = inputs;
        let hits = storage_view(hit);
        let normal = self.pipeline.fetch_view(gbuffer.normal);
        let tangent = self.pipeline.fetch_view(gbuffer.tangent);
        let heights = [height.descriptor()];
        let colors = storage_view(color.view);
        let [albedo, normal_map] = crate::material::MaterialTextures::descriptors(material, height);
        let writes = [
            image_write(0, BINDINGS[0], &hits),
            image_write(1, BINDINGS[1], &normal),
            image_write(2, BINDINGS[2], &tangent),
            image_write(3, BINDINGS[3], &heights),
            image_write(4, BINDINGS[4], &colors),
            image_write(5, BINDINGS[5], &albedo),
            image_write(6, BINDINGS[6], &normal_map),
        ];
        self.pipeline.pipeline.dispatch(
            ctx,
            cmd,
            &writes,
            bytemuck::bytes_of(params),
            color.extent.width,
            color.extent.height,
        );
    }

    /// Destroys the pipeline and sampler.
    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
