//! 2-D images with one view, backed by gpu-allocator memory.

use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use crate::gpu::owned::Destroy;
use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};

/// A 2-D image, its memory and a view of all its mip levels.
pub struct Image {
    /// The Vulkan image.
    pub raw: vk::Image,
    /// A view of every mip level.
    pub view: vk::ImageView,
    /// Pixel format.
    pub format: vk::Format,
    /// Size of mip level 0.
    pub extent: vk::Extent2D,
    /// Number of mip levels.
    pub mip_levels: u32,
    /// The usage it was created with.
    pub usage: vk::ImageUsageFlags,
    allocation: Option<Allocation>,
    name: String,
}

/// A view of a 2-D image and the size of the image behind it: one of dispmap's own
/// images or a host engine's (the passes bind views, never own them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ViewRef {
    /// The image view.
    pub view: vk::ImageView,
    /// Size of the viewed mip level.
    pub extent: vk::Extent2D,
}

/// A host image the displacement pass writes ([`crate::embed::FrameInputs`]'s hit buffer,
/// [`crate::embed::ShadeTarget`]'s colour image, [`crate::embed::FrameMotion`]'s motion
/// image), with what the pass checks before it records anything: a Vulkan view does not
/// say its image's format, size or usage, and a storage image of the wrong format is
/// written without an error or a validation message. The host fills it from its own
/// `VkImageCreateInfo` (the view must show the whole of mip level 0, in `format`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostView {
    /// The image view.
    pub view: vk::ImageView,
    /// The view's format.
    pub format: vk::Format,
    /// The image's size (mip level 0).
    pub extent: vk::Extent2D,
    /// The image's usage flags.
    pub usage: vk::ImageUsageFlags,
}

impl HostView {
    /// Checks the image named `name` against what the pass needs: one of `formats`, the
    /// `usage` flags, the frame's `extent`; the error names the image and the mismatch.
    pub fn check(
        &self,
        name: &str,
        formats: &[vk::Format],
        usage: vk::ImageUsageFlags,
        extent: vk::Extent2D,
    ) -> crate::error::Result<()> {
        let invalid = |m: String| Err(crate::error::Error::invalid(name, m));
        if self.view == vk::ImageView::null() {
            return invalid("a null image view".into());
        }
        if !formats.contains(&self.format) {
            let wanted = match formats {
                [one] => format!("{one:?}"),
                many => format!("one of {many:?}"),
            };
            return invalid(format!("format {:?}; the pass needs {wanted}", self.format));
        }
        if !self.usage.contains(usage) {
            return invalid(format!("usage {:?} lacks {usage:?}", self.usage));
        }
        if self.extent != extent {
            return invalid(format!(
                "extent {}x{} differs from the pass's {}x{}",
                self.extent.width, self.extent.height, extent.width, extent.height
            ));
        }
        Ok(())
    }
}

/// The aspect a view of `format` covers.
pub fn aspect_of(format: vk::Format) -> vk::ImageAspectFlags {
    match format {
        vk::Format::D32_SFLOAT | vk::Format::D16_UNORM => vk::ImageAspectFlags::DEPTH,
        _ => vk::ImageAspectFlags::COLOR,
    }
}

/// Bytes per texel of the formats dispmap uses.
pub fn texel_size(format: vk::Format) -> Option<u32> {
    Some(match format {
        vk::Format::R8_UNORM => 1,
        vk::Format::R16_UNORM | vk::Format::R16_SFLOAT => 2,
        vk::Format::R32_SFLOAT
        | vk::Format::R32_UINT
        | vk::Format::D32_SFLOAT
        | vk::Format::R16G16_SFLOAT
        | vk::Format::R8G8B8A8_UNORM
        | vk::Format::R8G8B8A8_SRGB => 4,
        vk::Format::R16G16B16A16_SFLOAT | vk::Format::R32G32_SFLOAT | vk::Format::R32G32_UINT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        _ => return None,
    })
}

impl Image {
    /// Creates an image named `name` with `mip_levels` levels in device-local memory.
    pub fn new(
        ctx: &Context,
        name: &str,
        format: vk::Format,
        extent: vk::Extent2D,
        mip_levels: u32,
        usage: vk::ImageUsageFlags,
    ) -> Result<Self> {
        let max = ctx.info().max_image_dimension_2d;
        if extent.width == 0 || extent.height == 0 || extent.width > max || extent.height > max {
            return Err(Error::invalid(
                name,
                format!(
                    "{}x{} is outside what the device allows (1..={max} per side)",
                    extent.width, extent.height
                ),
            ));
        }
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent.width,
                height: extent.height,
                depth: 1,
            })
            .mip_levels(mip_levels)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid device and create info; the format's features were checked by
        // `Context::check_device`.
        let raw = unsafe { ctx.device().create_image(&info, None) }.vk("vkCreateImage")?;
        // SAFETY: `raw` was just created on this device.
        let requirements = unsafe { ctx.device().get_image_memory_requirements(raw) };
        let allocation = ctx
            .allocator()
            .lock()
            .map_err(|_| {
                Error::Internal(
                    "the allocator's mutex is poisoned (a thread panicked holding it)".into(),
                )
            })?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            });
        let allocation = match allocation {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: not bound or used yet.
                unsafe { ctx.device().destroy_image(raw, None) };
                return Err(Error::Allocation {
                    name: name.into(),
                    source,
                });
            }
        };
        // SAFETY: memory and offset come from the allocator for these requirements.
        unsafe {
            ctx.device()
                .bind_image_memory(raw, allocation.memory(), allocation.offset())
        }
        .vk("vkBindImageMemory")?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(full_range(format, mip_levels));
        // SAFETY: the image is bound to memory and the view matches its format and levels.
        let view =
            unsafe { ctx.device().create_image_view(&view_info, None) }.vk("vkCreateImageView")?;
        ctx.set_name(raw, name);
        ctx.set_name(view, &format!("{name}.view"));
        Ok(Image {
            raw,
            view,
            format,
            extent,
            mip_levels,
            usage,
            allocation: Some(allocation),
            name: name.into(),
        })
    }

    /// A host engine's image seen through a view dispmap made, `view` (of every level),
    /// with no memory of its own: [`Destroy::destroy`] leaves image and view alone (their
    /// owner, e.g. [`crate::gpu::HeightTexture`], destroys the view it made; the host
    /// the image).
    pub(crate) fn borrowed(
        raw: vk::Image,
        view: vk::ImageView,
        format: vk::Format,
        extent: vk::Extent2D,
        mip_levels: u32,
        usage: vk::ImageUsageFlags,
        name: &str,
    ) -> Self {
        Image {
            raw,
            view,
            format,
            extent,
            mip_levels,
            usage,
            allocation: None,
            name: name.into(),
        }
    }

    /// Creates a view of the one mip level `level`, named `name` (the caller destroys it
    /// before the image).
    pub fn level_view(&self, ctx: &Context, level: u32, name: &str) -> Result<vk::ImageView> {
        let range = vk::ImageSubresourceRange {
            base_mip_level: level,
            level_count: 1,
            ..full_range(self.format, 1)
        };
        let info = vk::ImageViewCreateInfo::default()
            .image(self.raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(self.format)
            .subresource_range(range);
        if level >= self.mip_levels {
            return Err(Error::invalid(
                name,
                format!("{} has no mip level {level}", self.name),
            ));
        }
        // SAFETY: the image is alive and has this level; the view matches its format.
        let view =
            unsafe { ctx.device().create_image_view(&info, None) }.vk("vkCreateImageView")?;
        ctx.set_name(view, name);
        Ok(view)
    }

    /// The view of every level and the size of level 0.
    pub fn view_ref(&self) -> ViewRef {
        ViewRef {
            view: self.view,
            extent: self.extent,
        }
    }

    /// Its view as a host image of the embedding API (view, format, size and usage).
    pub fn host_view(&self) -> HostView {
        HostView {
            view: self.view,
            format: self.format,
            extent: self.extent,
            usage: self.usage,
        }
    }

    /// The debug name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Every mip level of the image.
    pub fn range(&self) -> vk::ImageSubresourceRange {
        full_range(self.format, self.mip_levels)
    }
}

impl Destroy for Image {
    /// Destroys view, image and memory. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            if let Some(allocation) = self.allocation.take() {
                ctx.device().destroy_image_view(self.view, None);
                ctx.device().destroy_image(self.raw, None);
                if let Ok(mut a) = ctx.allocator().lock() {
                    let _ = a.free(allocation);
                }
                self.raw = vk::Image::null();
                self.view = vk::ImageView::null();
            }
        }
    }

    fn bytes(&self) -> u64 {
        self.allocation.as_ref().map_or(0, |a| a.size())
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        if self.allocation.is_some() {
            log::warn!("image '{}' dropped without destroy(): leaked", self.name);
        }
    }
}

/// All levels and the one layer of an image of `format`.
pub fn full_range(format: vk::Format, mip_levels: u32) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect_of(format),
        base_mip_level: 0,
        level_count: mip_levels,
        base_array_layer: 0,
        layer_count: 1,
    }
}
