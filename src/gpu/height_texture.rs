//! The height field on the GPU: a sampled image at the map's precision and a linear
//! sampler with the map's addressing.

use super::Image;
use super::commands::{OneShot, upload_image};
use super::sync::Access;
use crate::context::Context;
use crate::error::Result;
use crate::heightfield::{Addressing, HeightField};
use ash::vk;

/// The uploaded height field.
pub struct HeightTexture {
    /// The image (`R8_UNORM`, `R16_UNORM` or `R32_SFLOAT`), in
    /// `SHADER_READ_ONLY_OPTIMAL` after upload.
    pub image: Image,
    /// Bilinear sampler with the addressing mode (repeat or clamp to edge).
    pub sampler: vk::Sampler,
    /// The addressing mode.
    pub addressing: Addressing,
}

impl HeightTexture {
    /// Uploads `field` and leaves it readable by compute shaders.
    pub fn upload(
        ctx: &Context,
        shot: &OneShot,
        field: &HeightField,
        addressing: Addressing,
    ) -> Result<Self> {
        let extent = vk::Extent2D {
            width: field.width(),
            height: field.height(),
        };
        let mut image = Image::new(
            ctx,
            &format!("heightfield[{}]", field.label()),
            field.format(),
            extent,
            1,
            vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
        )?;
        if let Err(e) = upload_image(ctx, shot, &image, field.bytes(), Access::COMPUTE_SAMPLED) {
            image.destroy(ctx);
            return Err(e);
        }
        let mode = match addressing {
            Addressing::Repeat => vk::SamplerAddressMode::REPEAT,
            Addressing::Clamp => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        };
        let sampler =
            match crate::passes::sampler(ctx, "heightfield.sampler", vk::Filter::LINEAR, mode) {
                Ok(s) => s,
                Err(e) => {
                    image.destroy(ctx);
                    return Err(e);
                }
            };
        Ok(HeightTexture {
            image,
            sampler,
            addressing,
        })
    }

    /// Size in texels.
    pub fn size(&self) -> [u32; 2] {
        [self.image.extent.width, self.image.extent.height]
    }

    /// Descriptor info for a combined image sampler.
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.image.view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Destroys image and sampler.
    pub fn destroy(&mut self, ctx: &Context) {
        self.image.destroy(ctx);
        // SAFETY: caller guarantees no pending use.
        unsafe { ctx.device().destroy_sampler(self.sampler, None) };
        self.sampler = vk::Sampler::null();
    }
}
