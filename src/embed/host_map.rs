//! Height maps the host keeps on the GPU: a material whose heights are one channel of the
//! host's own sampled image (R8/R16 unorm, R16F/R32F, BC4, or a channel of an RGBA or
//! BC3/BC5/BC7 image such as a normal map's alpha) and its mip chain. dispmap makes views
//! of the image (the channel swizzled into `r`) and never reads it back: every
//! preparation (pyramid, cone map) and every pass samples those views, so the methods
//! see the map exactly as the GPU decodes it. The host's contract is in the module docs
//! ("Height maps the host owns") and in `docs/embedding.md`.

use super::*;
use crate::gpu::HeightTexture;

/// Which channel of a [`HostHeightMap`]'s image holds the heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HeightChannel {
    /// Red (the one channel of `R8`, `R16`, `R16F`, `R32F`, `BC4`).
    R,
    /// Green.
    G,
    /// Blue.
    B,
    /// Alpha (e.g. the height in a normal map's alpha).
    A,
}

impl HeightChannel {
    fn swizzle(self) -> vk::ComponentSwizzle {
        match self {
            HeightChannel::R => vk::ComponentSwizzle::R,
            HeightChannel::G => vk::ComponentSwizzle::G,
            HeightChannel::B => vk::ComponentSwizzle::B,
            HeightChannel::A => vk::ComponentSwizzle::A,
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// A height map the host owns on the GPU: a 2-D image of its device with one array
/// layer, in one of [`HOST_HEIGHT_FORMATS`], and which channel holds the heights (in
/// `[0, 1]`, 1 = the macro surface, as a [`HeightField`]'s texels). The host fills it
/// from its own `VkImageCreateInfo`; dispmap cannot query it, so a wrong description is
/// the host's error (what can be checked is checked by
/// [`DisplacementPass::add_host_material`]).
///
/// Contract (the module docs, "Height maps the host owns"): created with `SAMPLED` usage,
/// `VK_SHARING_MODE_EXCLUSIVE` on the context's queue family; every mip level in
/// `SHADER_READ_ONLY_OPTIMAL`, its writes visible to `COMPUTE_SHADER`
/// `SHADER_SAMPLED_READ`, whenever a command buffer recorded with a material on it
/// executes; alive and unchanged until those have completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostHeightMap {
    /// The host's image.
    pub image: vk::Image,
    /// Its format (dispmap's views have the same format).
    pub format: vk::Format,
    /// Size of mip level 0 in texels.
    pub extent: vk::Extent2D,
    /// Its mip levels (1 up to the full chain): level of detail samples them as they
    /// are, every other read is of level 0.
    pub mip_levels: u32,
    /// The usage it was created with (must contain `SAMPLED`).
    pub usage: vk::ImageUsageFlags,
    /// The channel holding the heights.
    pub channel: HeightChannel,
}

/// The formats a [`HostHeightMap`] may have: one-channel maps (`R8`/`R16` unorm, `R16F`,
/// `R32F`, `BC4` unorm) and the channels of two- and four-channel images (normal maps
/// with a height channel: `RG8`, `RGBA8`, `BGRA8`, `RGBA16` unorm, `RGBA16F`, `BC3`,
/// `BC5`, `BC7` unorm). sRGB and signed formats are not heights. The device must also
/// support sampling the format with linear filtering.
pub const HOST_HEIGHT_FORMATS: [vk::Format; 13] = [
    vk::Format::R8_UNORM,
    vk::Format::R16_UNORM,
    vk::Format::R16_SFLOAT,
    vk::Format::R32_SFLOAT,
    vk::Format::BC4_UNORM_BLOCK,
    vk::Format::R8G8_UNORM,
    vk::Format::R8G8B8A8_UNORM,
    vk::Format::B8G8R8A8_UNORM,
    vk::Format::R16G16B16A16_UNORM,
    vk::Format::R16G16B16A16_SFLOAT,
    vk::Format::BC3_UNORM_BLOCK,
    vk::Format::BC5_UNORM_BLOCK,
    vk::Format::BC7_UNORM_BLOCK,
];

impl HostHeightMap {
    /// The channels the format has, and the format whose texels hold every value such a
    /// channel samples as exactly (an 8- or 16-bit unorm channel; the format itself
    /// otherwise: block-compressed channels decode at the GPU's precision).
    fn format_facts(format: vk::Format) -> Option<(usize, vk::Format)> {
        use vk::Format as F;
        Some(match format {
            F::R8_UNORM => (1, F::R8_UNORM),
            F::R16_UNORM => (1, F::R16_UNORM),
            F::R16_SFLOAT | F::R32_SFLOAT | F::BC4_UNORM_BLOCK => (1, format),
            F::R8G8_UNORM => (2, F::R8_UNORM),
            F::BC5_UNORM_BLOCK => (2, format),
            F::R8G8B8A8_UNORM | F::B8G8R8A8_UNORM => (4, F::R8_UNORM),
            F::R16G16B16A16_UNORM => (4, F::R16_UNORM),
            F::R16G16B16A16_SFLOAT | F::BC3_UNORM_BLOCK | F::BC7_UNORM_BLOCK => (4, format),
            _ => return None,
        })
    }

    /// Checks what dispmap can check (module docs) and returns the format whose texels
    /// hold the channel's values exactly (see `format_facts`).
    pub(super) fn check(&self, ctx: &Context) -> Result<vk::Format> {
        let name = "host height map";
        let invalid = |m: String| Err(Error::invalid(name, m));
        if self.image == vk::Image::null() {
            return invalid("a null image".into());
        }
        let Some((channels, texel_format)) = Self::format_facts(self.format) else {
            return invalid(format!(
                "format {:?} is not one of {HOST_HEIGHT_FORMATS:?}",
                self.format
            ));
        };
        if self.channel.index() >= channels {
            return invalid(format!(
                "format {:?} has no channel {:?}",
                self.format, self.channel
            ));
        }
        if !self.usage.contains(vk::ImageUsageFlags::SAMPLED) {
            return invalid(format!("usage {:?} lacks SAMPLED", self.usage));
        }
        let max = ctx.info().max_image_dimension_2d;
        let vk::Extent2D { width, height } = self.extent;
        if width == 0 || height == 0 || width > max || height > max {
            return invalid(format!(
                "{width}x{height} is outside 1..={max} per side (maxImageDimension2D)"
            ));
        }
        let chain = 32 - width.max(height).leading_zeros();
        if !(1..=chain).contains(&self.mip_levels) {
            return invalid(format!(
                "{} mip levels; a {width}x{height} image has 1..={chain}",
                self.mip_levels
            ));
        }
        let needed = vk::FormatFeatureFlags::SAMPLED_IMAGE
            | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR;
        if !ctx.format_features(self.format).contains(needed) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                what: format!("{:?} with {needed:?} (a host height map)", self.format),
            });
        }
        Ok(texel_format)
    }

    /// dispmap's texture of it (views and sampler; nothing recorded).
    fn texture(
        &self,
        ctx: &Context,
        texel_format: vk::Format,
        addressing: Addressing,
    ) -> Result<HeightTexture> {
        HeightTexture::from_host(
            ctx,
            &format!("heightfield[host {:?} {:?}]", self.image, self.channel),
            self.image,
            self.format,
            self.extent,
            self.mip_levels,
            self.usage,
            self.channel.swizzle(),
            texel_format,
            addressing,
        )
    }
}

impl DisplacementPass {
    /// Adds a displaced material whose height map is the host's own image ([`HostHeightMap`]:
    /// one channel of a sampled image and its mip chain, shared with a material that
    /// already has the same map and addressing). As [`DisplacementPass::add_material`]
    /// otherwise: the next record (or [`DisplacementPass::record_preparation`]) builds
    /// what its method needs from the image as the GPU samples it; nothing is uploaded,
    /// hashed or read back. The host keeps the image as the module docs say ("Height
    /// maps the host owns") while a material uses it. On error the pass is unchanged.
    pub fn add_host_material(
        &mut self,
        map: &HostHeightMap,
        settings: MaterialSettings,
    ) -> Result<MaterialId> {
        self.check_alive()?;
        validate_material(self.context()?, &settings)?;
        let index = self.free_index()?;
        let (entry, new_map) = self.host_map_for(map, settings.addressing, None)?;
        self.insert_material(index, settings, entry, new_map)
    }

    /// Swaps in the host's image `map` as a material's height map (as
    /// [`DisplacementPass::set_material_height_map`]: what only the old map used is
    /// retired; the next record or preparation builds what the method needs). On error
    /// the pass is unchanged.
    pub fn set_material_host_height_map(
        &mut self,
        id: MaterialId,
        map: &HostHeightMap,
    ) -> Result<()> {
        self.check_alive()?;
        let i = self.entry_index(id)?;
        let addressing = self.entry(id)?.settings.addressing;
        let (entry, new_map) = self.host_map_for(map, addressing, None)?;
        self.swap_material_map(i, entry, new_map)
    }

    /// The host changed the contents of `image` (a [`HostHeightMap`]'s image): every map of
    /// the table on it gets new preparations (pyramids, cone maps), built by the next
    /// record or [`DisplacementPass::record_preparation`]; the old ones are retired (frames
    /// in flight may still read them). The host may write the image only while no
    /// command buffer recorded with a material on it is pending, and makes its writes
    /// visible before the next preparation or frame executes (module docs). Frames
    /// recorded after this call and before the rebuild executes would read the old
    /// preparations with the new image: the rebuild is recorded first, in the same
    /// command buffer or an earlier one. An image no material uses changes nothing. On
    /// error the pass is unchanged.
    pub fn host_height_map_changed(&mut self, image: vk::Image) -> Result<()> {
        self.check_alive()?;
        let stale: Vec<usize> = (self.maps.iter().enumerate())
            .filter_map(|(i, m)| {
                let source = m.as_ref()?.key.host_source()?;
                matches!(source, plan::MapSource::Host { map, .. } if map.image == image)
                    .then_some(i)
            })
            .collect();
        // (old entry, new entry) of each stale map.
        let mut swaps = Vec::new();
        for &old in &stale {
            let Some(m) = &self.maps[old] else { continue };
            let Some(plan::MapSource::Host { map, version }) = m.key.host_source() else {
                continue;
            };
            let addressing = m.key.addressing;
            match self.host_map_for(&map, addressing, Some(version + 1)) {
                Ok((new, _)) => swaps.push((old, new)),
                Err(e) => {
                    for (_, new) in swaps {
                        let unused = self.maps[new].take();
                        // SAFETY: never recorded: made above.
                        unsafe { self.destroy_unused(unused) };
                    }
                    return Err(e);
                }
            }
        }
        let repoint = |materials: &mut Vec<Option<plan::MaterialEntry>>,
                       from_to: &[(usize, usize)]| {
            for m in materials.iter_mut().flatten() {
                if let Some(&(_, to)) = from_to.iter().find(|(from, _)| *from == m.map) {
                    m.map = to;
                }
            }
        };
        repoint(&mut self.materials, &swaps);
        if let Err(e) = self.sync() {
            let back: Vec<(usize, usize)> = swaps.iter().map(|&(a, b)| (b, a)).collect();
            repoint(&mut self.materials, &back);
            for (_, new) in swaps {
                let unused = self.maps[new].take();
                // SAFETY: the failed sync recorded nothing with the new map.
                unsafe { self.destroy_unused(unused) };
            }
            return Err(e);
        }
        Ok(())
    }

    /// The map table entry for the host's `map` with `addressing`: an existing one of the
    /// same image, channel and levels, or (`true`) a new one; `version`: always a new one,
    /// with this version of the contents.
    fn host_map_for(
        &mut self,
        map: &HostHeightMap,
        addressing: Addressing,
        version: Option<u64>,
    ) -> Result<(usize, bool)> {
        let texel_format = map.check(self.context()?)?;
        let size = [map.extent.width, map.extent.height];
        if version.is_none()
            && let Some(i) = self.maps.iter().position(|m| {
                m.as_ref().is_some_and(|m| {
                    m.key.addressing == addressing
                        && matches!(m.key.host_source(), Some(plan::MapSource::Host { map: k, .. }) if k == *map)
                })
            })
        {
            return Ok((i, false));
        }
        let key = plan::MapKey::host(
            plan::MapSource::Host {
                map: *map,
                version: version.unwrap_or(0),
            },
            size,
            map.format,
            addressing,
        );
        let texture = map.texture(&self.context()?.clone(), texel_format, addressing)?;
        let entry = plan::MapEntry::new_host(key, texture);
        Ok((self.push_map(entry), true))
    }
}
