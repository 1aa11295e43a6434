//! The window's side of the viewer: a Vulkan surface and swapchain, and one submission
//! per frame that copies the renderer's colour image(s) (or a frame composed on the CPU)
//! into the acquired swapchain image and presents it.
//!
//! One frame in flight: every frame's submission is waited for (its fence) before the
//! next frame renders, so the renderer's images, the upload buffer and the composite
//! image are free again when the next frame starts. The swapchain is recreated when the
//! surface reports it out of date or suboptimal and when the window's size changes;
//! nothing is presented while the window has a zero side (minimised).

use anyhow::{Context as _, Result, bail};
use ash::vk;
use dispmap::context::Context;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Buffer, Image};
use dispmap::passes::shade::COLOR_FORMAT;
use gpu_allocator::MemoryLocation;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use std::ffi::CStr;

/// Width in pixels of the split view's divider.
pub const DIVIDER_PX: u32 = 2;

/// The divider's colour (RGBA8, also the CPU composition's).
pub const DIVIDER_RGBA: [u8; 4] = [255, 255, 255, 255];

/// One piece of a frame: the columns `[src_x0, src_x1)` of a side's image (all its
/// rows) placed at column `dst_x` of the frame, unscaled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Part {
    /// Which side's image: 0 left (or only), 1 right.
    pub side: usize,
    /// First column taken.
    pub src_x0: u32,
    /// One past the last column taken.
    pub src_x1: u32,
    /// Column of the frame it goes to.
    pub dst_x: u32,
}

/// How the sides' images make up the frame: the parts, over the divider's colour where
/// no part lands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The frame's size (the window's).
    pub frame: vk::Extent2D,
    /// The pieces, in order.
    pub parts: Vec<Part>,
}

impl Layout {
    /// True when the parts leave columns uncovered (the divider, or the gap between
    /// two halves).
    pub fn has_gaps(&self) -> bool {
        let covered: u32 = self.parts.iter().map(|p| p.src_x1 - p.src_x0).sum();
        covered < self.frame.width
    }
}

/// What a frame shows.
pub enum Source<'a> {
    /// The sides' colour images (in the renderer's post-frame state,
    /// [`dispmap::renderer::Renderer::color_image`], and returned to it), put together
    /// by `layout`.
    Gpu {
        /// Left (or only) and right images.
        images: [Option<&'a Image>; 2],
        /// Where their columns go.
        layout: &'a Layout,
    },
    /// A frame composed on the CPU: RGBA8 (sRGB-encoded, as the renderer's), row by row,
    /// `extent` pixels.
    Cpu {
        /// The pixels.
        rgba: &'a [u8],
        /// Their size.
        extent: vk::Extent2D,
    },
}

/// Something drawn over the copied frame inside a dynamic-rendering pass on the
/// swapchain image (the viewer's panel).
pub trait Overlay {
    /// Records the drawing into `cmd`, inside a rendering pass whose one colour
    /// attachment is the swapchain image (loaded, `extent` pixels, the presenter's
    /// format).
    fn record(&mut self, ctx: &Context, cmd: vk::CommandBuffer, extent: vk::Extent2D)
    -> Result<()>;
}

/// What [`Presenter::present`] did.
pub struct Presented {
    /// False when nothing was presented (the swapchain was out of date, the window
    /// minimised): the caller renders the frame again.
    pub shown: bool,
    /// The presented image as RGBA8, row by row, when a screenshot was asked for.
    pub screenshot: Option<(vk::Extent2D, Vec<u8>)>,
    /// GPU milliseconds of the overlay's drawing (its timestamps), when one was drawn.
    pub overlay_gpu_ms: Option<f64>,
}

/// The overlay's colour attachment: blended over (read and written).
const ATTACHMENT_BLEND: Access = Access {
    stage: vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
    access: vk::AccessFlags2::from_raw(
        vk::AccessFlags2::COLOR_ATTACHMENT_READ.as_raw()
            | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE.as_raw(),
    ),
    layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
};

/// The instance extensions a surface for `window` needs.
pub fn instance_extensions(window: &impl HasDisplayHandle) -> Result<Vec<&'static CStr>> {
    let display = window
        .display_handle()
        .context("the window system gave no display handle")?;
    let names = ash_window::enumerate_required_extensions(display.as_raw())
        .context("this window system has no Vulkan surface extension")?;
    Ok(names
        .iter()
        // SAFETY: ash-window returns pointers to the static, NUL-terminated extension
        // name constants of ash.
        .map(|&p| unsafe { CStr::from_ptr(p) })
        .collect())
}

/// Surface, swapchain and the per-frame submission.
pub struct Presenter {
    surface_fn: ash::khr::surface::Instance,
    swapchain_fn: ash::khr::swapchain::Device,
    surface: vk::SurfaceKHR,
    swapchain: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    /// One colour view per swapchain image (the overlay's attachment).
    views: Vec<vk::ImageView>,
    /// Two timestamps around the overlay's drawing.
    queries: vk::QueryPool,
    /// One per swapchain image: signalled by the frame's submission, waited by present.
    rendered: Vec<vk::Semaphore>,
    acquired: vk::Semaphore,
    format: vk::Format,
    extent: vk::Extent2D,
    present_mode: vk::PresentModeKHR,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    /// Host-visible: the CPU-composed frame on its way to `composite`.
    upload: Option<Buffer>,
    /// Device image the CPU-composed frame is copied into, then blitted from.
    composite: Option<Image>,
    /// Host-visible: the screenshot's copy of the presented image.
    readback: Option<Buffer>,
}

impl Presenter {
    /// Creates the surface of `window` and a swapchain of `size` (clamped to what the
    /// surface allows). The context must have been created with
    /// [`instance_extensions`] and `VK_KHR_swapchain`.
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
                p.destroy(ctx);
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

    /// The swapchain's size.
    pub fn extent(&self) -> vk::Extent2D {
        self.extent
    }

    /// The swapchain's format.
    pub fn format(&self) -> vk::Format {
        self.format
    }

    /// The present mode in use.
    pub fn present_mode(&self) -> vk::PresentModeKHR {
        self.present_mode
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

    /// Copies `source` into the next swapchain image (blitted to the swapchain's size
    /// when they differ, nearest texel; an identity copy when they are equal), draws
    /// `overlay` over it (timed) and presents it; with `screenshot` also reads the
    /// presented image back. Waits for the submission. Out-of-date and suboptimal
    /// swapchains are recreated for `size`.
    pub fn present(
        &mut self,
        ctx: &Context,
        source: Source<'_>,
        mut overlay: Option<&mut dyn Overlay>,
        screenshot: bool,
        size: [u32; 2],
    ) -> Result<Presented> {
        let not_shown = Presented {
            shown: false,
            screenshot: None,
            overlay_gpu_ms: None,
        };
        if self.extent.width == 0 || self.extent.height == 0 {
            return Ok(not_shown);
        }
        // SAFETY: the swapchain and semaphore are alive; the semaphore is unsignalled
        // (the previous frame's submission, which waited on it, completed).
        let acquired = unsafe {
            self.swapchain_fn.acquire_next_image(
                self.swapchain,
                u64::MAX,
                self.acquired,
                vk::Fence::null(),
            )
        };
        let index = match acquired {
            Ok((index, _suboptimal)) => index,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.recreate(ctx, size)?;
                return Ok(not_shown);
            }
            Err(e) => return Err(e).context("vkAcquireNextImageKHR"),
        };
        let image = self.images[index as usize];
        let extent = self.extent;
        let device = ctx.device();
        if let Source::Cpu { rgba, extent } = source {
            self.stage_cpu(ctx, rgba, extent)?;
        }
        if screenshot {
            let bytes = 4 * u64::from(extent.width) * u64::from(extent.height);
            if self.readback.as_ref().is_none_or(|b| b.size != bytes) {
                if let Some(mut old) = self.readback.take() {
                    // SAFETY: each presented frame is waited for (its fence) before `present` returns: nothing reads the old buffer.
                    unsafe { old.destroy(ctx) };
                }
                self.readback = Some(Buffer::new(
                    ctx,
                    "viewer.screenshot",
                    bytes,
                    vk::BufferUsageFlags::TRANSFER_DST,
                    MemoryLocation::GpuToCpu,
                )?);
            }
        }
        let cmd = self.cmd;
        // SAFETY: the command buffer's previous submission was waited for (its fence).
        unsafe {
            device
                .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .context("vkResetCommandBuffer")?;
            device
                .begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .context("vkBeginCommandBuffer")?;
        }
        let color_range = dispmap::gpu::image::full_range(self.format, 1);
        // The acquire semaphore is waited at ALL_TRANSFER: the swapchain image's layout
        // change is ordered after it by that stage.
        let acquire_wait = Access {
            stage: vk::PipelineStageFlags2::ALL_TRANSFER,
            access: vk::AccessFlags2::NONE,
            layout: vk::ImageLayout::UNDEFINED,
        };
        // The renderer's images (or the composite) as blit sources.
        let mut sources: Vec<(&Image, Access)> = Vec::new();
        match &source {
            Source::Gpu { images, .. } => {
                for img in images.iter().flatten() {
                    sources.push((img, Access::COMPUTE_STORAGE_WRITE));
                }
            }
            Source::Cpu { .. } => {
                let composite = self.composite.as_ref().context("no composite image")?;
                sources.push((composite, Access::TRANSFER_WRITE));
            }
        }
        let mut before: Vec<_> = sources
            .iter()
            .map(|(img, state)| {
                sync::image_barrier(img.raw, img.range(), *state, Access::TRANSFER_READ)
            })
            .collect();
        before.push(sync::image_barrier(
            image,
            color_range,
            acquire_wait,
            Access::TRANSFER_WRITE,
        ));
        // SAFETY: `cmd` is recording outside a render pass on the context's queue
        // family; the images are alive until the fence wait below; the sources are in
        // their stated states (the renderer's post-frame state, or the composite's
        // upload copy recorded by `stage_cpu` in this command buffer); the swapchain
        // image's contents are discarded.
        unsafe {
            if overlay.is_some() {
                device.cmd_reset_query_pool(cmd, self.queries, 0, 2);
            }
            if let Source::Cpu { .. } = source {
                self.record_cpu_copy(ctx, cmd);
            }
            sync::record(ctx, cmd, &before);
        }
        let full = |e: vk::Extent2D| [0, 0, e.width, e.height];
        let mut blits: Vec<(&Image, [u32; 4], [u32; 4])> = Vec::new();
        match &source {
            Source::Gpu { images, layout } => {
                // Columns of the frame map to columns of the swapchain image by scale
                // (they differ only while a resize is on its way).
                let frame_w = layout.frame.width.max(1);
                let scale =
                    |x: u32| (u64::from(x) * u64::from(extent.width) / u64::from(frame_w)) as u32;
                for part in &layout.parts {
                    let src = images[part.side].context("a layout part has no image")?;
                    let x1 = part.src_x1.min(src.extent.width);
                    if part.src_x0 >= x1 {
                        continue;
                    }
                    let dst_x1 = part.dst_x + (x1 - part.src_x0);
                    blits.push((
                        src,
                        [part.src_x0, 0, x1, src.extent.height],
                        [scale(part.dst_x), 0, scale(dst_x1), extent.height],
                    ));
                }
                if layout.has_gaps() {
                    let clear = vk::ClearColorValue {
                        float32: DIVIDER_RGBA.map(|c| f32::from(c) / 255.0),
                    };
                    // SAFETY: `cmd` is recording; the swapchain image is in
                    // TRANSFER_DST_OPTIMAL (barrier above); the blits below write after
                    // the clear (same stage, ordered by the barrier that follows).
                    unsafe {
                        device.cmd_clear_color_image(
                            cmd,
                            image,
                            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                            &clear,
                            &[color_range],
                        );
                        sync::record(
                            ctx,
                            cmd,
                            &[sync::image_barrier(
                                image,
                                color_range,
                                Access::TRANSFER_WRITE,
                                Access::TRANSFER_WRITE,
                            )],
                        );
                    }
                }
            }
            Source::Cpu { .. } => {
                let composite = self.composite.as_ref().context("no composite image")?;
                blits.push((composite, full(composite.extent), full(extent)));
            }
        }
        let offsets = |r: [u32; 4]| {
            [
                vk::Offset3D {
                    x: r[0] as i32,
                    y: r[1] as i32,
                    z: 0,
                },
                vk::Offset3D {
                    x: r[2] as i32,
                    y: r[3] as i32,
                    z: 1,
                },
            ]
        };
        let layers = vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        };
        for (src, s, d) in &blits {
            let region = vk::ImageBlit::default()
                .src_subresource(layers)
                .src_offsets(offsets(*s))
                .dst_subresource(layers)
                .dst_offsets(offsets(*d));
            // SAFETY: `cmd` is recording; the source is in TRANSFER_SRC_OPTIMAL and the
            // swapchain image in TRANSFER_DST_OPTIMAL (barriers above); both regions lie
            // within their images; the formats are blit source and destination formats
            // (R8G8B8A8_UNORM: the core's requirements; the swapchain's: checked).
            unsafe {
                device.cmd_blit_image(
                    cmd,
                    src.raw,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    image,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[region],
                    vk::Filter::NEAREST,
                )
            };
        }
        // The swapchain image's last use: the blits, or the overlay drawn over them.
        let mut written = Access::TRANSFER_WRITE;
        if let Some(overlay) = overlay.as_deref_mut() {
            // SAFETY: `cmd` is recording outside a render pass; the swapchain image was
            // last written by the blits (barrier from that state); its view is of this
            // image (made with it in `recreate`); the query pool holds the two queries,
            // reset at the start of this command buffer.
            unsafe {
                sync::record(
                    ctx,
                    cmd,
                    &[sync::image_barrier(
                        image,
                        color_range,
                        Access::TRANSFER_WRITE,
                        ATTACHMENT_BLEND,
                    )],
                );
                device.cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    self.queries,
                    0,
                );
                let attachments = [vk::RenderingAttachmentInfo::default()
                    .image_view(self.views[index as usize])
                    .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                    .load_op(vk::AttachmentLoadOp::LOAD)
                    .store_op(vk::AttachmentStoreOp::STORE)];
                device.cmd_begin_rendering(
                    cmd,
                    &vk::RenderingInfo::default()
                        .render_area(vk::Rect2D {
                            offset: vk::Offset2D::default(),
                            extent,
                        })
                        .layer_count(1)
                        .color_attachments(&attachments),
                );
            }
            let recorded = overlay.record(ctx, cmd, extent);
            // SAFETY: the rendering pass begun above is ended whatever the overlay did,
            // so the command buffer stays consistent; on an error it is never submitted.
            unsafe {
                device.cmd_end_rendering(cmd);
                device.cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    self.queries,
                    1,
                );
            }
            recorded?;
            written = ATTACHMENT_BLEND;
        }
        let present = Access {
            stage: vk::PipelineStageFlags2::NONE,
            access: vk::AccessFlags2::NONE,
            layout: vk::ImageLayout::PRESENT_SRC_KHR,
        };
        // The sources go back to their states: the renderer's images to its post-frame
        // state (compute storage write in GENERAL), the composite stays a copy source.
        let mut after: Vec<_> = sources
            .iter()
            .filter(|(_, state)| *state == Access::COMPUTE_STORAGE_WRITE)
            .map(|(img, _)| {
                sync::image_barrier(
                    img.raw,
                    img.range(),
                    Access::TRANSFER_READ,
                    Access::COMPUTE_STORAGE_WRITE,
                )
            })
            .collect();
        if let (true, Some(readback)) = (screenshot, &self.readback) {
            after.push(sync::image_barrier(
                image,
                color_range,
                written,
                Access::TRANSFER_READ,
            ));
            let copy = vk::BufferImageCopy::default()
                .image_subresource(layers)
                .image_extent(vk::Extent3D {
                    width: extent.width,
                    height: extent.height,
                    depth: 1,
                });
            // SAFETY: `cmd` is recording outside a render pass; the images are alive
            // until the fence wait; the barriers match their states (above); the
            // readback buffer holds the whole image (sized above).
            unsafe {
                sync::record(ctx, cmd, &after);
                device.cmd_copy_image_to_buffer(
                    cmd,
                    image,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    readback.raw,
                    &[copy],
                );
                sync::record(
                    ctx,
                    cmd,
                    &[sync::image_barrier(
                        image,
                        color_range,
                        Access::TRANSFER_READ,
                        present,
                    )],
                );
            }
        } else {
            after.push(sync::image_barrier(image, color_range, written, present));
            // SAFETY: as above.
            unsafe { sync::record(ctx, cmd, &after) };
        }
        let waits = [vk::SemaphoreSubmitInfo::default()
            .semaphore(self.acquired)
            .stage_mask(vk::PipelineStageFlags2::ALL_TRANSFER)];
        let signals = [vk::SemaphoreSubmitInfo::default()
            .semaphore(self.rendered[index as usize])
            .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
        let submit = [vk::SubmitInfo2::default()
            .wait_semaphore_infos(&waits)
            .command_buffer_infos(&cmds)
            .signal_semaphore_infos(&signals)];
        // SAFETY: the command buffer was begun above; the semaphores and fence are
        // alive and unsignalled; the queue is used only from this thread.
        unsafe {
            device
                .end_command_buffer(cmd)
                .context("vkEndCommandBuffer")?;
            device
                .queue_submit2(ctx.queue(), &submit, self.fence)
                .context("vkQueueSubmit2")?;
        }
        let wait_semaphores = [self.rendered[index as usize]];
        let swapchains = [self.swapchain];
        let indices = [index];
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&wait_semaphores)
            .swapchains(&swapchains)
            .image_indices(&indices);
        // SAFETY: the image was acquired above and is in PRESENT_SRC_KHR once the
        // submission that signals the waited semaphore completes.
        let presented = unsafe { self.swapchain_fn.queue_present(ctx.queue(), &info) };
        // SAFETY: the fence belongs to the submission above.
        unsafe {
            device
                .wait_for_fences(&[self.fence], true, u64::MAX)
                .context("vkWaitForFences")?;
            device
                .reset_fences(&[self.fence])
                .context("vkResetFences")?;
        }
        let overlay_gpu_ms = if overlay.is_some() {
            let mut stamps = [0u64; 2];
            // SAFETY: both queries were written by the submission waited for above.
            unsafe {
                device.get_query_pool_results(
                    self.queries,
                    0,
                    &mut stamps,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .context("vkGetQueryPoolResults")?;
            let bits = ctx.info().timestamp_valid_bits;
            let mask = if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            };
            let ticks = (stamps[1] & mask).wrapping_sub(stamps[0] & mask) & mask;
            Some(ticks as f64 * f64::from(ctx.info().timestamp_period_ns) * 1e-6)
        } else {
            None
        };
        match presented {
            Ok(false) => {}
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.recreate(ctx, size)?;
            }
            Err(e) => return Err(e).context("vkQueuePresentKHR"),
        }
        let shot = match (screenshot, &self.readback) {
            (true, Some(buffer)) => {
                let bytes = buffer
                    .mapped()
                    .context("the readback buffer is not mapped")?;
                let mut rgba = bytes.to_vec();
                if self.format == vk::Format::B8G8R8A8_UNORM {
                    for px in rgba.chunks_exact_mut(4) {
                        px.swap(0, 2);
                    }
                }
                Some((extent, rgba))
            }
            _ => None,
        };
        Ok(Presented {
            shown: true,
            screenshot: shot,
            overlay_gpu_ms,
        })
    }

    /// Writes a CPU-composed frame into the upload buffer and makes sure the composite
    /// image has its size (the copy itself is recorded by [`Presenter::record_cpu_copy`]).
    fn stage_cpu(&mut self, ctx: &Context, rgba: &[u8], extent: vk::Extent2D) -> Result<()> {
        let bytes = 4 * u64::from(extent.width) * u64::from(extent.height);
        if rgba.len() as u64 != bytes {
            bail!(
                "a composed frame of {} bytes is not {}x{} RGBA8",
                rgba.len(),
                extent.width,
                extent.height
            );
        }
        if self.upload.as_ref().is_none_or(|b| b.size != bytes) {
            if let Some(mut old) = self.upload.take() {
                // SAFETY: each presented frame is waited for (its fence) before `present` returns: nothing reads the old buffer.
                unsafe { old.destroy(ctx) };
            }
            self.upload = Some(Buffer::new(
                ctx,
                "viewer.upload",
                bytes,
                vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::CpuToGpu,
            )?);
        }
        if self.composite.as_ref().is_none_or(|c| c.extent != extent) {
            if let Some(mut old) = self.composite.take() {
                // SAFETY: each presented frame is waited for (its fence) before `present` returns: nothing reads the old image.
                unsafe { old.destroy(ctx) };
            }
            self.composite = Some(Image::new(
                ctx,
                "viewer.composite",
                COLOR_FORMAT,
                extent,
                1,
                // SAMPLED only because `Image` always makes a view, which needs a
                // usage that views allow; the image is only copied into and blitted from.
                vk::ImageUsageFlags::TRANSFER_DST
                    | vk::ImageUsageFlags::TRANSFER_SRC
                    | vk::ImageUsageFlags::SAMPLED,
            )?);
        }
        let upload = self.upload.as_mut().context("no upload buffer")?;
        upload
            .mapped_mut()
            .context("the upload buffer is not mapped")?
            .copy_from_slice(rgba);
        Ok(())
    }

    /// Records the upload buffer's copy into the composite image (discarding what it
    /// held), leaving it in TRANSFER_DST_OPTIMAL after a transfer write.
    ///
    /// # Safety
    /// `cmd` is this presenter's command buffer, recording outside a render pass;
    /// [`Presenter::stage_cpu`] ran for this frame; the previous frame was waited for.
    unsafe fn record_cpu_copy(&self, ctx: &Context, cmd: vk::CommandBuffer) {
        let (Some(upload), Some(composite)) = (&self.upload, &self.composite) else {
            return;
        };
        let copy = vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width: composite.extent.width,
                height: composite.extent.height,
                depth: 1,
            });
        let discard = Access {
            stage: vk::PipelineStageFlags2::ALL_TRANSFER,
            access: vk::AccessFlags2::NONE,
            layout: vk::ImageLayout::UNDEFINED,
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording; the buffer and
        // image are alive and were last used by the previous (completed) frame; the
        // buffer holds the whole image (`stage_cpu`).
        unsafe {
            sync::transition(ctx, cmd, composite, discard, Access::TRANSFER_WRITE);
            ctx.device().cmd_copy_buffer_to_image(
                cmd,
                upload.raw,
                composite.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[copy],
            );
        }
    }

    /// Destroys everything (the caller waits for the device first; the window is still
    /// alive).
    pub fn destroy(&mut self, ctx: &Context) {
        let device = ctx.device();
        // SAFETY: the caller's contract: nothing is pending; each handle is destroyed
        // once (nulled or taken after).
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
