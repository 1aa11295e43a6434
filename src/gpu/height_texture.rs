//! The height field on the GPU: a sampled image at the map's precision and a linear
//! sampler with the map's addressing.

use super::commands::{OneShot, upload_image};
use super::sync::{self, Access};
use super::{Buffer, Image};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::heightfield::{Addressing, HeightField};
use ash::vk;
use gpu_allocator::MemoryLocation;

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
        let mode = address_mode(addressing);
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

    /// Creates the image and sampler without touching a queue, plus a filled staging
    /// buffer: the contents arrive when [`HeightTexture::record_upload`] is recorded and
    /// executed (the host-engine path, which never submits). The caller destroys the
    /// staging buffer once that copy has executed.
    pub fn create_for_upload(
        ctx: &Context,
        field: &HeightField,
        addressing: Addressing,
    ) -> Result<(Self, Buffer)> {
        let mut staging = Buffer::new(
            ctx,
            &format!("heightfield[{}].staging", field.label()),
            field.bytes().len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        match staging.mapped_mut() {
            Some(bytes) => bytes.copy_from_slice(field.bytes()),
            None => {
                staging.destroy(ctx);
                return Err(Error::invalid(
                    field.label(),
                    "staging buffer is not mapped",
                ));
            }
        }
        let texture = (|| {
            let mut image = Image::new(
                ctx,
                &format!("heightfield[{}]", field.label()),
                field.format(),
                vk::Extent2D {
                    width: field.width(),
                    height: field.height(),
                },
                1,
                vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
            )?;
            match crate::passes::sampler(
                ctx,
                "heightfield.sampler",
                vk::Filter::LINEAR,
                address_mode(addressing),
            ) {
                Ok(sampler) => Ok(HeightTexture {
                    image,
                    sampler,
                    addressing,
                }),
                Err(e) => {
                    image.destroy(ctx);
                    Err(e)
                }
            }
        })();
        match texture {
            Ok(t) => Ok((t, staging)),
            Err(e) => {
                staging.destroy(ctx);
                Err(e)
            }
        }
    }

    /// Records the copy of `staging` (from [`HeightTexture::create_for_upload`]) into the
    /// image: discarded -> `TRANSFER_DST_OPTIMAL`, copy, -> `SHADER_READ_ONLY_OPTIMAL`
    /// visible to compute-shader sampled reads.
    pub fn record_upload(&self, ctx: &Context, cmd: vk::CommandBuffer, staging: &Buffer) {
        let range = self.image.range();
        sync::record(
            ctx,
            cmd,
            &[sync::image_barrier(
                self.image.raw,
                range,
                Access::UNDEFINED,
                Access::TRANSFER_WRITE,
            )],
        );
        let region = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: range.aspect_mask,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width: self.image.extent.width,
                height: self.image.extent.height,
                depth: 1,
            });
        // SAFETY: `cmd` is recording outside a render pass (caller's contract); the buffer
        // holds the image's tightly packed level 0 and both are alive.
        unsafe {
            ctx.device().cmd_copy_buffer_to_image(
                cmd,
                staging.raw,
                self.image.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            )
        };
        sync::record(
            ctx,
            cmd,
            &[sync::image_barrier(
                self.image.raw,
                range,
                Access::TRANSFER_WRITE,
                Access::COMPUTE_SAMPLED,
            )],
        );
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

fn address_mode(addressing: Addressing) -> vk::SamplerAddressMode {
    match addressing {
        Addressing::Repeat => vk::SamplerAddressMode::REPEAT,
        Addressing::Clamp => vk::SamplerAddressMode::CLAMP_TO_EDGE,
    }
}
