//! The on-screen panel's plumbing: egui's context, its winit input (egui-winit) and its
//! Vulkan renderer for ash (egui-ash-renderer), which draws the tessellated panel into
//! the swapchain image after the frame's copy ([`Overlay`]).
//!
//! One frame in flight, as the presenter: the renderer keeps one vertex and index buffer
//! set, rewritten each frame after the previous frame's fence; egui's texture uploads
//! (the font atlas) are submitted and waited for by the renderer itself before the frame
//! is recorded; textures egui frees are freed after the frame's fence.
//!
//! egui updates its font atlas in patches when new glyphs appear. The renderer records
//! a patch's upload with the image's old contents discarded (a transition from
//! `UNDEFINED`), which a GPU may honour; so the viewer keeps a copy of each texture,
//! patches the copy and uploads it whole.

use super::present::Overlay;
use anyhow::{Context as _, Result};
use ash::vk;
use dispmap::context::Context;
use egui_ash_renderer::allocator::GpuAllocator;
use egui_ash_renderer::{DynamicRendering, Options, RenderMode, Renderer};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Instant;
use winit::event::WindowEvent;
use winit::window::Window;

/// egui with its input and renderer.
pub struct Gui {
    /// The egui context (the panel's code draws with it).
    pub egui: egui::Context,
    input: egui_winit::State,
    renderer: Option<Renderer<GpuAllocator>>,
    /// For the renderer's texture uploads.
    pool: vk::CommandPool,
    /// The last [`Gui::run`]'s output, drawn by [`Overlay::record`].
    primitives: Vec<egui::ClippedPrimitive>,
    pixels_per_point: f32,
    /// Textures egui freed in the last run: freed after that frame was drawn.
    to_free: Vec<egui::TextureId>,
    /// The contents of each egui texture (module docs).
    copies: HashMap<egui::TextureId, egui::ColorImage>,
    /// CPU milliseconds of the last frame's panel: egui's run, tessellation, texture
    /// uploads and recording.
    pub cpu_ms: f64,
}

impl Gui {
    /// egui for `window`, drawing into images of `format`.
    pub fn new(ctx: &Context, window: &Window, format: vk::Format) -> Result<Self> {
        let egui = egui::Context::default();
        // Compact: the panel shares the window with the frame it describes.
        egui.all_styles_mut(|style| {
            use egui::{FontFamily, FontId, TextStyle};
            for (text, size, family) in [
                (TextStyle::Heading, 14.0, FontFamily::Proportional),
                (TextStyle::Body, 12.0, FontFamily::Proportional),
                (TextStyle::Button, 12.0, FontFamily::Proportional),
                (TextStyle::Small, 10.0, FontFamily::Proportional),
                (TextStyle::Monospace, 11.0, FontFamily::Monospace),
            ] {
                style.text_styles.insert(text, FontId::new(size, family));
            }
            style.spacing.item_spacing = egui::vec2(6.0, 2.0);
            style.spacing.interact_size = egui::vec2(32.0, 16.0);
            style.spacing.slider_width = 100.0;
            style.spacing.window_margin = egui::Margin::same(6);
        });
        let input = egui_winit::State::new(
            egui.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            None,
            None,
        );
        let device = ctx.device();
        // SAFETY: valid device and create info; destroyed in `destroy`.
        let pool = unsafe {
            device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(ctx.queue_family_index())
                    .flags(vk::CommandPoolCreateFlags::TRANSIENT),
                None,
            )
        }
        .context("vkCreateCommandPool")?;
        ctx.set_name(pool, "viewer.ui_pool");
        let renderer = Renderer::with_gpu_allocator(
            ctx.allocator().clone(),
            device.clone(),
            RenderMode::DynamicRendering(DynamicRendering {
                color_attachment_format: format,
                depth_attachment_format: None,
                stencil_attachment_format: None,
            }),
            Options {
                in_flight_frames: 1,
                enable_depth_test: false,
                enable_depth_write: false,
                // The swapchain is UNORM holding sRGB-encoded values (the renderer's
                // colour, copied as it is): egui's shader encodes its colours.
                srgb_framebuffer: false,
            },
        );
        let renderer = match renderer {
            Ok(r) => r,
            Err(e) => {
                // SAFETY: the pool was made above and holds nothing in use.
                unsafe { device.destroy_command_pool(pool, None) };
                return Err(anyhow::anyhow!("cannot create the panel's renderer: {e}"));
            }
        };
        Ok(Gui {
            egui,
            input,
            renderer: Some(renderer),
            pool,
            primitives: Vec::new(),
            pixels_per_point: 1.0,
            to_free: Vec::new(),
            copies: HashMap::new(),
            cpu_ms: 0.0,
        })
    }

    /// Passes a window event to egui; true when egui used it (a click on the panel, a
    /// drag of a slider), so the viewer's own controls leave it alone.
    pub fn on_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        self.input.on_window_event(window, event).consumed
    }

    /// True while the pointer is over the panel or one of its controls is dragged.
    pub fn wants_pointer(&self) -> bool {
        self.egui.egui_wants_pointer_input() || self.egui.is_pointer_over_egui()
    }

    /// True while a text field of the panel has the keyboard.
    pub fn wants_keyboard(&self) -> bool {
        self.egui.egui_wants_keyboard_input()
    }

    /// Runs the panel's code for this frame, tessellates it and uploads egui's new
    /// textures (each upload is submitted and waited for by the renderer).
    pub fn run(
        &mut self,
        ctx: &Context,
        window: &Window,
        mut draw: impl FnMut(&egui::Context),
    ) -> Result<()> {
        let start = Instant::now();
        let raw = self.input.take_egui_input(window);
        let output = self.egui.run_ui(raw, |ui| draw(ui.ctx()));
        self.input
            .handle_platform_output(window, output.platform_output);
        let renderer = self.renderer.as_mut().context("the panel is destroyed")?;
        // Taken out of the delta first: it must be empty when dropped.
        let mut textures = output.textures_delta;
        let set: Vec<_> = textures.set.drain().collect();
        self.to_free = textures.free.drain().collect();
        for (id, deltas) in set {
            for delta in &deltas {
                let egui::ImageData::Color(image) = &delta.image;
                let whole = match delta.pos {
                    None => {
                        self.copies.insert(id, (**image).clone());
                        delta.clone()
                    }
                    Some([x0, y0]) => {
                        let copy = self.copies.get_mut(&id).with_context(|| {
                            format!("egui patched its texture {id:?} before setting it")
                        })?;
                        let [w, h] = image.size;
                        let width = copy.size[0];
                        if x0 + w > width || y0 + h > copy.size[1] {
                            anyhow::bail!("egui's patch of texture {id:?} lies outside it");
                        }
                        for row in 0..h {
                            let at = (y0 + row) * width + x0;
                            copy.pixels[at..at + w]
                                .copy_from_slice(&image.pixels[row * w..(row + 1) * w]);
                        }
                        egui::epaint::ImageDelta::partial(
                            [0, 0],
                            Arc::new(copy.clone()),
                            delta.options,
                        )
                    }
                };
                renderer
                    .set_texture(ctx.queue(), self.pool, id, &whole)
                    .map_err(|e| anyhow::anyhow!("the panel's texture upload failed: {e}"))?;
            }
        }
        self.pixels_per_point = output.pixels_per_point;
        self.primitives = self.egui.tessellate(output.shapes, output.pixels_per_point);
        self.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Frees what egui gave up in the last run; the frame that drew it was waited for.
    pub fn after_frame(&mut self) -> Result<()> {
        let ids = std::mem::take(&mut self.to_free);
        if let Some(r) = self.renderer.as_mut() {
            for id in ids {
                self.copies.remove(&id);
                r.free_texture(id)
                    .map_err(|e| anyhow::anyhow!("freeing the panel's textures: {e}"))?;
            }
        }
        Ok(())
    }

    /// Destroys the renderer and the pool.
    ///
    /// # Safety
    /// The device is idle: no pending command buffer uses the panel's pipeline, buffers,
    /// textures or command pool.
    pub unsafe fn destroy(&mut self, ctx: &Context) {
        // Dropping the renderer destroys its pipeline, buffers and textures.
        self.renderer = None;
        if self.pool != vk::CommandPool::null() {
            // SAFETY: the device is idle (the caller's contract); the pool's command
            // buffers were freed by the renderer after each upload.
            unsafe { ctx.device().destroy_command_pool(self.pool, None) };
            self.pool = vk::CommandPool::null();
        }
    }
}

impl Overlay for Gui {
    fn record(
        &mut self,
        _ctx: &Context,
        cmd: vk::CommandBuffer,
        extent: vk::Extent2D,
    ) -> Result<()> {
        let start = Instant::now();
        let renderer = self.renderer.as_mut().context("the panel is destroyed")?;
        renderer
            .cmd_draw(cmd, extent, self.pixels_per_point, &self.primitives)
            .map_err(|e| anyhow::anyhow!("recording the panel failed: {e}"))?;
        self.cpu_ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }
}
