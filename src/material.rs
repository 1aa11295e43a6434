//! Optional surface maps the shade pass reads at the hit uv: an albedo (colour) map and a
//! tangent-space normal map, both addressed like the height field.
//!
//! * **Albedo**: an sRGB colour image (`R8G8B8A8_SRGB`, so the sampler returns linear
//!   colour); it replaces the default stone colour, and the shade pass multiplies the lit
//!   colour by it (the depth-darkening cavity term stays).
//! * **Normal map**: `R8G8B8A8_UNORM`, `n = 2 rgb - 1` in the tangent frame
//!   `(T along +u, B along +v, N)`; it replaces the normal derived from the height field.
//!   Since `v` grows *down* the image (the height map's row 0 is `v = 0`), green must point
//!   down the image; most tools write green up (the OpenGL convention), so
//!   [`load_normal_map`] flips green unless told the map is green-down (DirectX).
//! * **Presence without a flag.** Maps are uploaded with alpha 0. The shade pass binds the
//!   height texture instead of a missing map (`R8`/`R16`/`R32F` sample with alpha 1), so
//!   `alpha < 0.5` tells the shader a map is present: no push-constant change, and the
//!   existing frames (no maps) are shaded exactly as before.

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::commands::{record_upload_level0, staging_for};
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::sync::Access;
use crate::gpu::{Buffer, HeightTexture, Image};
use crate::heightfield::Addressing;
use ash::vk;
use image::RgbaImage;
use std::path::Path;

/// The maps of a material, decoded (RGBA8, alpha ignored).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialImages {
    /// The albedo in sRGB.
    pub albedo: Option<RgbaImage>,
    /// The tangent-space normal map with green along `+v` (down the image).
    pub normal_map: Option<RgbaImage>,
}

fn load_rgba(path: &Path) -> Result<RgbaImage> {
    let bytes = crate::heightfield::read_checked(path)?;
    crate::heightfield::png_palette_complete(&bytes).map_err(|message| Error::Image {
        path: path.to_owned(),
        message,
    })?;
    let image = image::load_from_memory(&bytes).map_err(|e| Error::Image {
        path: path.to_owned(),
        message: format!("cannot decode: {e}"),
    })?;
    // Float images (OpenEXR) would turn NaN into 0 silently in the 8-bit conversion.
    let float = match &image {
        image::DynamicImage::ImageRgb32F(i) => Some((i.as_raw(), 3)),
        image::DynamicImage::ImageRgba32F(i) => Some((i.as_raw(), 4)),
        _ => None,
    };
    if let Some((values, channels)) = float
        && let Some(k) = values.iter().position(|v| !v.is_finite())
    {
        let pixel = k / channels;
        return Err(Error::Image {
            path: path.to_owned(),
            message: format!(
                "non-finite value {} at pixel ({}, {})",
                values[k],
                pixel % image.width() as usize,
                pixel / image.width() as usize
            ),
        });
    }
    if image.width() == 0 || image.height() == 0 {
        return Err(Error::Image {
            path: path.to_owned(),
            message: "empty image".into(),
        });
    }
    Ok(image.to_rgba8())
}

/// Loads an albedo map (PNG or JPEG, sRGB).
pub fn load_albedo(path: &Path) -> Result<RgbaImage> {
    load_rgba(path)
}

/// Loads a tangent-space normal map; `green_up`: the file's green points up the image
/// (OpenGL convention, flipped here), else down (DirectX convention, kept).
pub fn load_normal_map(path: &Path, green_up: bool) -> Result<RgbaImage> {
    let mut image = load_rgba(path)?;
    if green_up {
        for p in image.pixels_mut() {
            p.0[1] = 255 - p.0[1];
        }
    }
    Ok(image)
}

/// The uploaded maps and their sampler.
pub struct MaterialTextures {
    albedo: Option<Image>,
    normal_map: Option<Image>,
    sampler: vk::Sampler,
}

impl MaterialTextures {
    /// Creates the present maps' images and sampler (none: nothing is created) and
    /// their filled staging buffers, without touching a queue: the contents arrive when
    /// [`MaterialTextures::record_upload`] is recorded and executed.
    pub fn create_for_upload(
        ctx: &Context,
        images: &MaterialImages,
        addressing: Addressing,
    ) -> Result<Option<(Self, MaterialStaging)>> {
        if images.albedo.is_none() && images.normal_map.is_none() {
            return Ok(None);
        }
        let mode = match addressing {
            Addressing::Repeat => vk::SamplerAddressMode::REPEAT,
            Addressing::Clamp => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        };
        let sampler = crate::passes::sampler(ctx, "material.sampler", vk::Filter::LINEAR, mode)?;
        let mut textures = Guard::new(
            ctx,
            MaterialTextures {
                albedo: None,
                normal_map: None,
                sampler,
            },
        );
        let mut staging = Guard::new(ctx, MaterialStaging([None, None]));
        let maps = [
            (&images.albedo, vk::Format::R8G8B8A8_SRGB, "material.albedo"),
            (
                &images.normal_map,
                vk::Format::R8G8B8A8_UNORM,
                "material.normal_map",
            ),
        ];
        for (k, (map, format, name)) in maps.into_iter().enumerate() {
            let Some(map) = map else { continue };
            let (image, buffer) = create_map(ctx, map, format, name)?;
            if k == 0 {
                textures.albedo = Some(image);
            } else {
                textures.normal_map = Some(image);
            }
            staging.0[k] = Some(buffer);
        }
        Ok(Some((textures.keep(), staging.keep())))
    }

    /// Records the copies of `staging` (from [`MaterialTextures::create_for_upload`])
    /// into the maps, which end readable by compute shaders
    /// ([`Access::COMPUTE_SAMPLED`]).
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass; `staging` came with these textures; both
    /// stay alive until the command buffer has executed.
    pub unsafe fn record_upload(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        staging: &MaterialStaging,
    ) {
        for (image, buffer) in [&self.albedo, &self.normal_map].into_iter().zip(&staging.0) {
            if let (Some(image), Some(buffer)) = (image, buffer) {
                // SAFETY: this function's contract.
                unsafe { record_upload_level0(ctx, cmd, buffer, image, Access::COMPUTE_SAMPLED) };
            }
        }
    }

    /// Descriptors of bindings 5 (albedo) and 6 (normal map) of the shade pass; a missing
    /// map is replaced by `fallback` (module docs).
    pub fn descriptors(
        this: Option<&Self>,
        fallback: &HeightTexture,
    ) -> [[vk::DescriptorImageInfo; 1]; 2] {
        let of = |image: Option<&Image>, sampler| match image {
            Some(image) => vk::DescriptorImageInfo {
                sampler,
                image_view: image.view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            },
            None => fallback.descriptor(),
        };
        match this {
            Some(m) => [
                [of(m.albedo.as_ref(), m.sampler)],
                [of(m.normal_map.as_ref(), m.sampler)],
            ],
            None => [[fallback.descriptor()], [fallback.descriptor()]],
        }
    }

    /// Destroys images and sampler. The GPU must be done with them.
    pub fn destroy(&mut self, ctx: &Context) {
        for image in [&mut self.albedo, &mut self.normal_map]
            .into_iter()
            .flatten()
        {
            image.destroy(ctx);
        }
        self.albedo = None;
        self.normal_map = None;
        // SAFETY: caller guarantees no pending use.
        unsafe { ctx.device().destroy_sampler(self.sampler, None) };
        self.sampler = vk::Sampler::null();
    }
}

/// The staging buffers of [`MaterialTextures::create_for_upload`] (albedo, normal map).
pub struct MaterialStaging([Option<Buffer>; 2]);

impl MaterialStaging {
    /// Destroys the buffers. The GPU must be done with them.
    pub fn destroy(&mut self, ctx: &Context) {
        self.0.iter_mut().for_each(|b| b.destroy(ctx));
    }
}

fn create_map(
    ctx: &Context,
    map: &RgbaImage,
    format: vk::Format,
    name: &str,
) -> Result<(Image, Buffer)> {
    let max = ctx.info().max_image_dimension_2d;
    if map.width() > max || map.height() > max {
        return Err(Error::invalid(
            name,
            format!(
                "{}x{} exceeds the device's maxImageDimension2D ({max})",
                map.width(),
                map.height()
            ),
        ));
    }
    let mut bytes = map.as_raw().clone();
    for texel in bytes.chunks_exact_mut(4) {
        texel[3] = 0; // alpha 0 marks a present map
    }
    let image = Guard::new(
        ctx,
        Image::new(
            ctx,
            name,
            format,
            vk::Extent2D {
                width: map.width(),
                height: map.height(),
            },
            1,
            vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST,
        )?,
    );
    let staging = staging_for(ctx, &image, &bytes)?;
    Ok((image.keep(), staging))
}
