//! wgpu textures as the pass's host images: the format and usage translated to Vulkan,
//! the raw view taken through `as_hal`, and the texture checked.

use crate::{Error, Result, Vulkan};
use dispmap::ash::vk;
use dispmap::embed::HostView;

/// A wgpu texture and the view the pass reads or writes (a 2D view of mip level 0 and
/// array layer 0 with the texture's format, e.g. `texture.create_view(&Default::default())`
/// of a texture with one mip level and one layer).
#[derive(Clone, Copy, Debug)]
pub struct WgpuImage<'a> {
    /// The texture.
    pub texture: &'a wgpu::Texture,
    /// Its view.
    pub view: &'a wgpu::TextureView,
}

/// The Vulkan format of a wgpu texture format, for the formats the pass's images use
/// (`None` for any other).
pub fn vk_format(format: wgpu::TextureFormat) -> Option<vk::Format> {
    use wgpu::TextureFormat as F;
    Some(match format {
        F::Rgba32Float => vk::Format::R32G32B32A32_SFLOAT,
        F::Rg32Uint => vk::Format::R32G32_UINT,
        F::Rg32Float => vk::Format::R32G32_SFLOAT,
        F::Rg16Float => vk::Format::R16G16_SFLOAT,
        F::R32Float => vk::Format::R32_SFLOAT,
        F::R16Float => vk::Format::R16_SFLOAT,
        F::Rgba8Unorm => vk::Format::R8G8B8A8_UNORM,
        F::Depth32Float => vk::Format::D32_SFLOAT,
        _ => return None,
    })
}

/// The Vulkan usage flags that a wgpu texture usage implies (the image has at least
/// these).
pub fn vk_usage(usage: wgpu::TextureUsages, format: wgpu::TextureFormat) -> vk::ImageUsageFlags {
    use wgpu::TextureUsages as U;
    let mut flags = vk::ImageUsageFlags::empty();
    if usage.contains(U::COPY_SRC) {
        flags |= vk::ImageUsageFlags::TRANSFER_SRC;
    }
    if usage.contains(U::COPY_DST) {
        flags |= vk::ImageUsageFlags::TRANSFER_DST;
    }
    if usage.contains(U::TEXTURE_BINDING) {
        flags |= vk::ImageUsageFlags::SAMPLED;
    }
    if usage.contains(U::STORAGE_BINDING) {
        flags |= vk::ImageUsageFlags::STORAGE;
    }
    if usage.contains(U::RENDER_ATTACHMENT) {
        flags |= if format.is_depth_stencil_format() {
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
        } else {
            vk::ImageUsageFlags::COLOR_ATTACHMENT
        };
    }
    flags
}

/// The pass's [`HostView`] of a wgpu texture: its raw `VkImageView`, format, size and
/// usage. Refused, naming the texture by `role` (the host's name for it): a texture that is not
/// 2D, has more than one mip level, array layer or sample, or a format the pass's images
/// never have; a texture or view not of the Vulkan backend. The pass itself then checks
/// the format, usage and size against the image's role (`record`'s error names the
/// role: `gbuffer.ray`, `hit.uv`, `color`).
///
/// The handle is valid while `image.view` is alive.
pub fn host_view(image: WgpuImage<'_>, role: &str) -> Result<HostView> {
    let t = image.texture;
    // wgpu gives no texture's label back: the host names it (its label or its role).
    let label = || role.to_string();
    let refuse = |what: String| Error::Texture {
        label: label(),
        what,
    };
    if t.dimension() != wgpu::TextureDimension::D2 {
        return Err(refuse(format!("dimension {:?}, not 2D", t.dimension())));
    }
    if t.mip_level_count() != 1 || t.depth_or_array_layers() != 1 || t.sample_count() != 1 {
        return Err(refuse(format!(
            "{} mip levels, {} layers, {} samples (the pass needs 1 of each)",
            t.mip_level_count(),
            t.depth_or_array_layers(),
            t.sample_count()
        )));
    }
    let format = vk_format(t.format()).ok_or_else(|| {
        refuse(format!(
            "format {:?} is none of the pass's (Rgba32Float, Rg32Uint, Rg32Float, \
             Rg16Float, R32Float, R16Float, Rgba8Unorm, Depth32Float)",
            t.format()
        ))
    })?;
    // SAFETY: the guard is dropped at the end of this block; only the handle is kept,
    // valid while the view is alive (this function's documented condition).
    let view = unsafe {
        let hal = image
            .view
            .as_hal::<Vulkan>()
            .ok_or_else(|| Error::NotVulkan(format!("the view of texture {}", label())))?;
        hal.raw_handle()
    };
    Ok(HostView {
        view,
        format,
        extent: vk::Extent2D {
            width: t.width(),
            height: t.height(),
        },
        usage: vk_usage(t.usage(), t.format()),
    })
}

/// The raw `VkImage` of a wgpu texture.
pub(crate) fn raw_image(texture: &wgpu::Texture, role: &str) -> Result<vk::Image> {
    // SAFETY: only the handle is kept; the caller keeps the texture alive while it is used.
    unsafe {
        let hal = texture
            .as_hal::<Vulkan>()
            .ok_or_else(|| Error::NotVulkan(format!("texture {role}")))?;
        Ok(hal.raw_handle())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_and_usages_translate() {
        assert_eq!(
            vk_format(wgpu::TextureFormat::Rgba32Float),
            Some(dispmap::passes::gbuffer::RAY_FORMAT)
        );
        assert_eq!(
            vk_format(wgpu::TextureFormat::Rg32Uint),
            Some(dispmap::passes::gbuffer::FRAME_FORMAT)
        );
        assert_eq!(
            vk_format(wgpu::TextureFormat::Depth32Float),
            Some(dispmap::embed::DEPTH_FORMAT)
        );
        assert_eq!(vk_format(wgpu::TextureFormat::Bgra8Unorm), None);
        let u = vk_usage(
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            wgpu::TextureFormat::Depth32Float,
        );
        assert_eq!(
            u,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | vk::ImageUsageFlags::SAMPLED
        );
        let u = vk_usage(
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            wgpu::TextureFormat::Rgba32Float,
        );
        assert_eq!(
            u,
            vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC
        );
    }
}
