//! The presenter's window-system objects: the surface, the swapchain (created, recreated
//! for a new window size, destroyed) and the command pool, fence, semaphores and queries
//! every frame reuses.

use super::Presenter;
use anyhow::{Context as _, Result, bail};
use ash::vk;
use dispmap::context::Context;
use dispmap::gpu::owned::Destroy;
use dispmap::passes::shade::COLOR_FORMAT;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};

impl Presenter {
    /// Creates the surface of `window` and a swapchain of `size` (clamped to what the
    /// surface allows). The context must have been created with
    /// [`instance_extensions`](super::instance_extensions) and `VK_KHR_swapchain`.
    pub fn new(
        ctx: &Context,
        window: &(impl HasDisplayHandle + HasWindowHandle),
        size: [u32; 2],
    ) -> Result<Self> {
        let display = window.display_handle().context("no display handle")?;
        let handle = window.window_handle().context("no window handle")?;
        // SAFETY: the entry and instance are the context's (created with the surface
        // extensions the display needs); the window outlives the presenter (the viewer
        // destroys the presenter before it drops the window).
        let surface = unsafe {
            ash_window::create_surface(
                ctx.entry(),
                ctx.instance(),
                display.as_raw(),
                handle.as_raw(),
                None,
            )
        }
        .context("cannot create a Vulkan surface for the window")?;
        let surface_fn = ash::khr::surface::Instance::new(ctx.entry(), ctx.instance());
        let swapchain_fn = ash::khr::swapchain::Device::new(ctx.instance(), ctx.device());
        let mut p = Presenter {
            surface_fn,
            swapchain_fn,
            surface,
            swapchain: vk::SwapchainKHR::null(),
            images: Vec::new(),
            views: Vec::new(),
            queries: vk::QueryPool::null(),
            rendered: Vec::new(),
            acquired: vk::Semaphore::null(),
            format: vk::Format::UNDEFINED,
            extent: vk::Extent2D::default(),
            present_mode: vk::PresentModeKHR::FIFO,
            pool: vk::CommandPool::null(),
            cmd: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            upload: None,
            composite: None,
            readback: None,
        };
        // From here on `destroy` cleans up whatever was made.
        match p.init(ctx, size) {
            Ok(()) => Ok(p),
            Err(e) => {
                // SAFETY: nothing was submitted with the half-made presenter; the window
                // is the caller's, alive.
                unsafe { p.destroy(ctx) };
                Err(e)
            }
        }
    }

    fn init(&mut self, ctx: &Context, size: [u32; 2]) -> Result<()> {
        // SAFETY: the physical device and surface belong to this instance.
        let supported = unsafe {
            self.surface_fn.get_physical_device_surface_support(
                ctx.physical_device(),
                ctx.queue_family_index(),
                self.surface,
            )
        }
        .context("vkGetPhysicalDeviceSurfaceSupportKHR")?;
        if !supported {
            bail!(
                "device {}: its queue family {} cannot present to this window",
                ctx.info().name,
                ctx.queue_family_index()
            );
        }
        // SAFETY: as above.
        let formats = unsafe {
            self.surface_fn
                .get_physical_device_surface_formats(ctx.physical_device(), self.surface)
        }
        .context("vkGetPhysicalDeviceSurfaceFormatsKHR")?;
        // The renderer's colour holds sRGB-encoded values in a UNORM image: a UNORM
        // swapchain shows them as they are (an sRGB one would encode them twice).
        let format = [vk::Format::B8G8R8A8_UNORM, vk::Format::R8G8B8A8_UNORM]
            .into_iter()
            .find(|f| {
                formats
                    .iter()
                    .any(|s| s.format == *f && s.color_space == vk::ColorSpaceKHR::SRGB_NONLINEAR)
            })
            .with_context(|| {
                format!(
                    "the window's surface offers no B8G8R8A8_UNORM or R8G8B8A8_UNORM format \
                     (it offers {:?})",
                    formats.iter().map(|f| f.format).collect::<Vec<_>>()
                )
            })?;
        // The blit from the renderer's colour image into the swapchain image.
        let require = |format: vk::Format, feature: vk::FormatFeatureFlags, role: &str| {
            // SAFETY: plain query of a physical device of this instance.
            let props = unsafe {
                ctx.instance()
                    .get_physical_device_format_properties(ctx.physical_device(), format)
            };
            if props.optimal_tiling_features.contains(feature) {
                Ok(())
            } else {
                Err(anyhow::anyhow!(
                    "device {}: {format:?} cannot be a blit {role}",
                    ctx.info().name
                ))
            }
        };
        require(format, vk::FormatFeatureFlags::BLIT_DST, "destination")?;
        require(COLOR_FORMAT, vk::FormatFeatureFlags::BLIT_SRC, "source")?;
        self.format = format;
        // SAFETY: as above.
        let modes = unsafe {
            self.surface_fn
                .get_physical_device_surface_present_modes(ctx.physical_device(), self.surface)
        }
        .context("vkGetPhysicalDeviceSurfacePresentModesKHR")?;
        // Frames are paced by rendering (one in flight), not by the display: mailbox or
        // immediate where offered, else FIFO (always offered).
        self.present_mode = [vk::PresentModeKHR::MAILBOX, vk::PresentModeKHR::IMMEDIATE]
            .into_iter()
            .find(|m| modes.contains(m))
            .unwrap_or(vk::PresentModeKHR::FIFO);

        let device = ctx.device();
        // SAFETY: valid device and create infos; the objects are destroyed in `destroy`.
        unsafe {
            self.pool = device
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(ctx.queue_family_index())
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .context("vkCreateCommandPool")?;
            self.cmd = device
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(self.pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .context("vkAllocateCommandBuffers")?[0];
            self.fence = device
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .context("vkCreateFence")?;
            self.acquired = device
                .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
                .context("vkCreateSemaphore")?;
            self.queries = device
                .create_query_pool(
                    &vk::QueryPoolCreateInfo::default()
                        .query_type(vk::QueryType::TIMESTAMP)
                        .query_count(2),
                    None,
                )
                .context("vkCreateQueryPool")?;
        }
        ctx.set_name(self.queries, "viewer.overlay_timestamps");
        ctx.set_name(self.pool, "viewer.pool");
        ctx.set_name(self.cmd, "viewer.cmd");
        ctx.set_name(self.fence, "viewer.fence");
        ctx.set_name(self.acquired, "viewer.acquired");
        self.recreate(ctx, size)?;
        Ok(())
    }

    /// (Re)creates the swapchain for a window of `size`; the old one is retired into
    /// the new one's creation and destroyed. Nothing of the presenter may be in flight
    /// (every frame is waited for). Returns false when the surface has a zero side
    /// (minimised): nothing can be presented until it changes.
    pub fn recreate(&mut self, ctx: &Context, size: [u32; 2]) -> Result<bool> {
        // SAFETY: the physical device and surface belong to this instance.
        let caps = unsafe {
            self.surface_fn
                .get_physical_device_surface_capabilities(ctx.physical_device(), self.surface)
        }
        .context("vkGetPhysicalDeviceSurfaceCapabilitiesKHR")?;
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: size[0].clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: size[1].clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        if extent.width == 0 || extent.height == 0 {
            self.extent = extent;
            return Ok(false);
        }
        let usage = vk::ImageUsageFlags::TRANSFER_DST
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::COLOR_ATTACHMENT;
        if !caps.supported_usage_flags.contains(usage) {
            bail!(
                "the window's swapchain images cannot be copy destinations, sources and \
                 colour attachments (supported usage {:?})",
                caps.supported_usage_flags
            );
        }
        let count = if caps.max_image_count == 0 {
            caps.min_image_count + 1
        } else {
            (caps.min_image_count + 1).min(caps.max_image_count)
        };
        let alpha = [
            vk::CompositeAlphaFlagsKHR::OPAQUE,
            vk::CompositeAlphaFlagsKHR::INHERIT,
            vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
            vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
        ]
        .into_iter()
        .find(|a| caps.supported_composite_alpha.contains(*a))
        .unwrap_or(vk::CompositeAlphaFlagsKHR::OPAQUE);
        let old = self.swapchain;
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(self.surface)
            .min_image_count(count)
            .image_format(self.format)
            .image_color_space(vk::ColorSpaceKHR::SRGB_NONLINEAR)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(usage)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(alpha)
            .present_mode(self.present_mode)
            .clipped(true)
            .old_swapchain(old);
        // SAFETY: valid create info for this device's surface; `old` (if any) is not in
        // use (every frame was waited for) and is destroyed right after.
        let swapchain = unsafe { self.swapchain_fn.create_swapchain(&info, None) }
            .context("vkCreateSwapchainKHR")?;
        // SAFETY: as above: nothing of the old swapchain is pending; its images were
        // presented and their present semaphores waited for by the completed frames.
        unsafe {
            ctx.device()
                .device_wait_idle()
                .context("vkDeviceWaitIdle")?;
            if old != vk::SwapchainKHR::null() {
                self.swapchain_fn.destroy_swapchain(old, None);
            }
            for s in self.rendered.drain(..) {
                ctx.device().destroy_semaphore(s, None);
            }
            for v in self.views.drain(..) {
                ctx.device().destroy_image_view(v, None);
            }
        }
        self.swapchain = swapchain;
        // SAFETY: the swapchain was just created.
        self.images = unsafe { self.swapchain_fn.get_swapchain_images(swapchain) }
            .context("vkGetSwapchainImagesKHR")?;
        for i in 0..self.images.len() {
            // SAFETY: valid device.
            let s = unsafe {
                ctx.device()
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }
            .context("vkCreateSemaphore")?;
            ctx.set_name(s, &format!("viewer.rendered{i}"));
            self.rendered.push(s);
            let view_info = vk::ImageViewCreateInfo::default()
                .image(self.images[i])
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(self.format)
                .subresource_range(dispmap::gpu::image::full_range(self.format, 1));
            // SAFETY: the image belongs to the swapchain just created; the view is
            // destroyed before the swapchain (here on the next recreate, or `destroy`).
            let view = unsafe { ctx.device().create_image_view(&view_info, None) }
                .context("vkCreateImageView")?;
            ctx.set_name(view, &format!("viewer.swapchain_view{i}"));
            self.views.push(view);
        }
        self.extent = extent;
        log::info!(
            "swapchain {}x{} {:?} {:?}, {} images",
            extent.width,
            extent.height,
            self.format,
            self.present_mode,
            self.images.len()
        );
        Ok(true)
    }

    /// Destroys everything, after waiting for the device; idempotent (each handle is
    /// nulled or taken).
    ///
    /// # Safety
    /// No other thread submits work using the presenter's objects meanwhile (the wait
    /// covers what was submitted before the call), and the window is still alive (the
    /// surface is destroyed before it).
    pub unsafe fn destroy(&mut self, ctx: &Context) {
        let device = ctx.device();
        // SAFETY: this function's contract and the wait below: nothing is pending; each
        // handle is destroyed once (nulled or taken after).
        unsafe {
            let _ = device.device_wait_idle();
            for s in self.rendered.drain(..) {
                device.destroy_semaphore(s, None);
            }
            for v in self.views.drain(..) {
                device.destroy_image_view(v, None);
            }
            if self.queries != vk::QueryPool::null() {
                device.destroy_query_pool(self.queries, None);
                self.queries = vk::QueryPool::null();
            }
            if self.acquired != vk::Semaphore::null() {
                device.destroy_semaphore(self.acquired, None);
                self.acquired = vk::Semaphore::null();
            }
            if self.fence != vk::Fence::null() {
                device.destroy_fence(self.fence, None);
                self.fence = vk::Fence::null();
            }
            if self.pool != vk::CommandPool::null() {
                device.destroy_command_pool(self.pool, None);
                self.pool = vk::CommandPool::null();
            }
            if self.swapchain != vk::SwapchainKHR::null() {
                self.swapchain_fn.destroy_swapchain(self.swapchain, None);
                self.swapchain = vk::SwapchainKHR::null();
            }
            if self.surface != vk::SurfaceKHR::null() {
                self.surface_fn.destroy_surface(self.surface, None);
                self.surface = vk::SurfaceKHR::null();
            }
        }
        for b in [self.upload.take(), self.readback.take()]
            .into_iter()
            .flatten()
        {
            let mut b = b;
            // SAFETY: the caller's contract: nothing is pending.
            unsafe { b.destroy(ctx) };
        }
        if let Some(mut c) = self.composite.take() {
            // SAFETY: the caller's contract: nothing is pending.
            unsafe { c.destroy(ctx) };
        }
    }
}
