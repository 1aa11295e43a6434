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
//!   `load_normal_map` (the `decode` feature) flips green unless told the map is
//!   green-down (DirectX); a host handing over its texels ([`RgbaMap::new`]) flips it
//!   itself.
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

/// An RGBA8 map the shade pass samples: `width x height` texels of four bytes (R, G, B,
/// A; alpha is ignored), row by row from row 0 (`v = 0`), tightly packed. Built from
/// texels the caller holds ([`RgbaMap::new`], no file decoding) or, with the `decode`
/// feature, from a file (`load_albedo`, `load_normal_map`) or an
/// `image::RgbaImage` (`From`). A clone shares the texels (one copy in memory however
/// many materials use the map).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RgbaMap {
    width: u32,
    height: u32,
    texels: std::sync::Arc<Vec<u8>>,
}

impl RgbaMap {
    /// A map of `width x height` texels from `texels` (4 bytes each: R, G, B, A, rows
    /// tightly packed). `label` names the map in the error when the size is empty or
    /// does not match the byte count.
    pub fn new(width: u32, height: u32, texels: Vec<u8>, label: &str) -> Result<Self> {
        let expected = (width as usize)
            .checked_mul(height as usize)
            .and_then(|n| n.checked_mul(4));
        if width == 0 || height == 0 || expected != Some(texels.len()) {
            return Err(Error::invalid(
                label,
                format!(
                    "{} bytes do not make a {width}x{height} RGBA8 map (4 bytes per texel)",
                    texels.len()
                ),
            ));
        }
        Ok(RgbaMap {
            width,
            height,
            texels: std::sync::Arc::new(texels),
        })
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The texels, 4 bytes each, row by row.
    pub fn texels(&self) -> &[u8] {
        &self.texels
    }

    /// Texel `(x, y)` as `[r, g, b, a]`; `None` outside the map.
    pub fn texel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let k = 4 * (y as usize * self.width as usize + x as usize);
        self.texels[k..k + 4].try_into().ok()
    }
}

#[cfg(feature = "decode")]
impl From<image::RgbaImage> for RgbaMap {
    /// The image's texels as they are (an empty image gives an empty map, which the
    /// upload refuses naming the map).
    fn from(image: image::RgbaImage) -> Self {
        RgbaMap {
            width: image.width(),
            height: image.height(),
            texels: std::sync::Arc::new(image.into_raw()),
        }
    }
}

/// The maps of a material (RGBA8, alpha ignored).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialImages {
    /// The albedo in sRGB.
    pub albedo: Option<RgbaMap>,
    /// The tangent-space normal map with green along `+v` (down the image).
    pub normal_map: Option<RgbaMap>,
}

#[cfg(feature = "decode")]
fn load_rgba(path: &std::path::Path) -> Result<RgbaMap> {
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
    Ok(image.to_rgba8().into())
}

/// Loads an albedo map (PNG or JPEG, sRGB). Needs the `decode` feature.
#[cfg(feature = "decode")]
pub fn load_albedo(path: &std::path::Path) -> Result<RgbaMap> {
    load_rgba(path)
}

/// Loads a tangent-space normal map; `green_up`: the file's green points up the image
/// (OpenGL convention, flipped here), else down (DirectX convention, kept). Needs the
/// `decode` feature.
#[cfg(feature = "decode")]
pub fn load_normal_map(path: &std::path::Path, green_up: bool) -> Result<RgbaMap> {
    let mut map = load_rgba(path)?;
    if green_up {
        // Just decoded: the only holder of its texels (no copy is made).
        for texel in std::sync::Arc::make_mut(&mut map.texels).chunks_exact_mut(4) {
            texel[1] = 255 - texel[1];
        }
    }
    Ok(map)
}

/// What makes two uploaded maps the same image: a 64-bit hash of the texels, the size
/// and the format (an albedo and a normal map of one file differ by format).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct MapKey {
    hash: u64,
    size: [u32; 2],
    format: vk::Format,
}

impl MapKey {
    fn of(map: &RgbaMap, format: vk::Format) -> Self {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        map.texels().hash(&mut h);
        MapKey {
            hash: h.finish(),
            size: [map.width(), map.height()],
            format,
        }
    }
}

/// One uploaded map, held by every material whose map has the same key: one GPU image
/// however many materials (objects) name the same texels.
struct SharedImage {
    key: MapKey,
    image: Image,
}

impl Destroy for SharedImage {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract, passed on.
        unsafe { self.image.destroy(ctx) };
    }

    fn bytes(&self) -> u64 {
        self.image.bytes()
    }
}

/// One holder's share of a shared value's bytes (the holders' shares sum to the value's
/// bytes, give or take their rounding down).
fn share<T: Destroy>(shared: &Option<std::sync::Arc<T>>) -> u64 {
    shared
        .as_ref()
        .map_or(0, |v| v.bytes() / std::sync::Arc::strong_count(v) as u64)
}

/// Releases one holder's share of `shared`: the value is destroyed by its last holder.
///
/// # Safety
/// Destroy's contract for this holder: no pending command uses the value through it.
/// Every holder is released under the same contract, so when the last one is, no
/// pending command uses the value through any of them.
unsafe fn release<T: Destroy>(shared: &mut Option<std::sync::Arc<T>>, ctx: &Context) {
    if let Some(mut last) = shared.take().and_then(std::sync::Arc::into_inner) {
        // SAFETY: this function's contract; this was the last holder.
        unsafe { last.destroy(ctx) };
    }
}

/// The uploaded maps and their sampler. Materials whose maps have the same texels (and
/// format) share one image ([`MaterialTextures::create_sharing`]).
pub struct MaterialTextures {
    albedo: Option<std::sync::Arc<SharedImage>>,
    normal_map: Option<std::sync::Arc<SharedImage>>,
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
        Self::create_sharing(ctx, images, addressing, std::iter::empty())
    }

    /// [`MaterialTextures::create_for_upload`], sharing the image of a map that one of
    /// `others` (textures of other materials, each with its staging while its upload is
    /// still to be recorded) already has with the same texels and format instead of
    /// making a second one: its staging is shared too while pending, and the record
    /// uploads it once ([`MaterialStaging::drop_repeats`]).
    pub fn create_sharing<'a>(
        ctx: &Context,
        images: &MaterialImages,
        addressing: Addressing,
        others: impl Iterator<Item = (&'a MaterialTextures, Option<&'a MaterialStaging>)> + Clone,
    ) -> Result<Option<(Self, MaterialStaging)>> {
        if images.albedo.is_none() && images.normal_map.is_none() {
            return Ok(None);
        }
        let mode = match addressing {
            Addressing::Repeat => vk::SamplerAddressMode::REPEAT,
            Addressing::Clamp => vk::SamplerAddressMode::CLAMP_TO_EDGE,
        };
        let sampler =
            crate::gpu::pipeline::sampler(ctx, "material.sampler", vk::Filter::LINEAR, mode)?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut textures = unsafe {
            Guard::new(
                ctx,
                MaterialTextures {
                    albedo: None,
                    normal_map: None,
                    sampler,
                },
            )
        };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let mut staging = unsafe { Guard::new(ctx, MaterialStaging([None, None])) };
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
            let key = MapKey::of(map, format);
            let existing = others.clone().find_map(|(t, pending)| {
                let (image, staged) = [&t.albedo, &t.normal_map]
                    .into_iter()
                    .zip(pending.map_or([None, None], |p| [p.0[0].as_ref(), p.0[1].as_ref()]))
                    .find(|(image, _)| image.as_ref().is_some_and(|i| i.key == key))?;
                Some((image.clone()?, staged.cloned()))
            });
            let (image, buffer) = match existing {
                Some(shared) => shared,
                None => {
                    let (image, buffer) = create_map(ctx, map, format, name)?;
                    (
                        std::sync::Arc::new(SharedImage { key, image }),
                        Some(std::sync::Arc::new(buffer)),
                    )
                }
            };
            if k == 0 {
                textures.albedo = Some(image);
            } else {
                textures.normal_map = Some(image);
            }
            staging.0[k] = buffer;
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
    ) -> Result<()> {
        for (image, buffer) in [&self.albedo, &self.normal_map].into_iter().zip(&staging.0) {
            if let (Some(image), Some(buffer)) = (image, buffer) {
                // SAFETY: this function's contract.
                unsafe {
                    record_upload_level0(ctx, cmd, buffer, &image.image, Access::COMPUTE_SAMPLED)?
                };
            }
        }
        Ok(())
    }

    /// Descriptors of bindings 5 (albedo) and 6 (normal map) of the shade pass; a missing
    /// map is replaced by `fallback` (module docs).
    pub fn descriptors(
        this: Option<&Self>,
        fallback: &HeightTexture,
    ) -> [[vk::DescriptorImageInfo; 1]; 2] {
        let of = |image: Option<&std::sync::Arc<SharedImage>>, sampler| match image {
            Some(image) => vk::DescriptorImageInfo {
                sampler,
                image_view: image.image.view,
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
}

impl Destroy for MaterialTextures {
    /// Destroys the sampler and releases the images (each destroyed by the last
    /// material holding it). The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            release(&mut self.albedo, ctx);
            release(&mut self.normal_map, ctx);
            ctx.device().destroy_sampler(self.sampler, None);
            self.sampler = vk::Sampler::null();
        }
    }

    /// This holder's share of the images (materials with the same map share one).
    fn bytes(&self) -> u64 {
        share(&self.albedo) + share(&self.normal_map)
    }
}

/// The staging buffers of [`MaterialTextures::create_for_upload`] (albedo, normal map),
/// shared with the materials that share the image they fill.
pub struct MaterialStaging([Option<std::sync::Arc<Buffer>>; 2]);

impl MaterialStaging {
    /// Keeps one copy of each staging buffer in `stagings` (the record's pending uploads):
    /// a buffer shared by several materials fills their one image once (two copies into
    /// one image would be a write-after-write hazard). What is dropped is a second
    /// holder of a buffer still held by the one kept.
    pub fn drop_repeats<'a>(stagings: impl Iterator<Item = &'a mut MaterialStaging>) {
        let mut seen: Vec<*const Buffer> = Vec::new();
        for slot in stagings.flat_map(|s| s.0.iter_mut()) {
            if let Some(buffer) = slot {
                let ptr = std::sync::Arc::as_ptr(buffer);
                if seen.contains(&ptr) {
                    *slot = None;
                } else {
                    seen.push(ptr);
                }
            }
        }
    }
}

impl Destroy for MaterialStaging {
    /// Releases the buffers (each destroyed by its last holder). The GPU must be done
    /// with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.0.iter_mut().for_each(|b| release(b, ctx));
        }
    }

    /// This holder's share of the buffers.
    fn bytes(&self) -> u64 {
        self.0.iter().map(share).sum()
    }
}

fn create_map(
    ctx: &Context,
    map: &RgbaMap,
    format: vk::Format,
    name: &str,
) -> Result<(Image, Buffer)> {
    let max = ctx.info().max_image_dimension_2d;
    if map.width() == 0 || map.height() == 0 {
        return Err(Error::invalid(name, "the map has no texels"));
    }
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
    let mut bytes = map.texels().to_vec();
    for texel in bytes.chunks_exact_mut(4) {
        texel[3] = 0; // alpha 0 marks a present map
    }
    // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
    let image = unsafe {
        Guard::new(
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
        )
    };
    let staging = staging_for(ctx, &image, &bytes)?;
    Ok((image.keep(), staging))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgba_maps_from_texels() {
        let map = RgbaMap::new(2, 1, vec![1, 2, 3, 4, 5, 6, 7, 8], "albedo").unwrap();
        assert_eq!((map.width(), map.height()), (2, 1));
        assert_eq!(map.texel(1, 0), Some([5, 6, 7, 8]));
        assert_eq!(map.texel(2, 0), None);
        for (w, h, bytes) in [(2, 2, 12), (0, 1, 0), (u32::MAX, u32::MAX, 4)] {
            match RgbaMap::new(w, h, vec![0; bytes], "wall albedo") {
                Err(Error::InvalidInput { name, message }) => {
                    assert_eq!(name, "wall albedo");
                    assert_eq!(
                        message,
                        format!(
                            "{bytes} bytes do not make a {w}x{h} RGBA8 map (4 bytes per texel)"
                        )
                    );
                }
                other => panic!("expected InvalidInput, got {other:?}"),
            }
        }
    }
}
