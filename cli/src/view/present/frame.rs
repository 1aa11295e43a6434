//! One frame on the window: the sides' images (or a frame composed on the CPU) copied into
//! the acquired swapchain image, the overlay drawn over it and timed, the screenshot read
//! back, the submission waited for and the image presented.

use super::{DIVIDER_RGBA, Overlay, Presented, Presenter, Source};
use anyhow::{Context as _, Result, bail};
use ash::vk;
use dispmap::context::Context;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Buffer, Image};
use dispmap::passes::shade::COLOR_FORMAT;
use gpu_allocator::MemoryLocation;

/// The overlay's colour attachment: blended over (read and written).
const ATTACHMENT_BLEND: Access = Access {
    stage: vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
    access: vk::AccessFlags2::from_raw(
        vk::AccessFlags2::COLOR_ATTACHMENT_READ.as_raw()
            | vk::AccessFlags2::COLOR_ATTACHMENT_WRITE.as_raw(),
    ),
    layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
};

impl Presenter {
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
}
