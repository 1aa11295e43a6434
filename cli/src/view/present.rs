//! The window's side of the viewer: a Vulkan surface and swapchain, and one submission
//! per frame that copies the renderer's colour image(s) (or a frame composed on the CPU)
//! into the acquired swapchain image and presents it.
//!
//! One frame in flight: every frame's submission is waited for (its fence) before the
//! next frame renders, so the renderer's images, the upload buffer and the composite
//! image are free again when the next frame starts. The swapchain is recreated when the
//! surface reports it out of date or suboptimal and when the window's size changes;
//! nothing is presented while the window has a zero side (minimised).
//!
//! This file holds what the viewer hands the presenter and gets back; [`swapchain`]
//! makes, remakes and destroys the window's objects, [`frame`] records and presents one
//! frame.

use anyhow::{Context as _, Result};
use ash::vk;
use dispmap::context::Context;
use dispmap::gpu::{Buffer, Image};
use raw_window_handle::HasDisplayHandle;
use std::ffi::CStr;

mod frame;
mod swapchain;

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
}
