//! A minimal test "host engine" around `dispmap::embed::DisplacementPass` whose G-buffer
//! is either *uploaded* (chosen rays, copied into the images from a buffer) or
//! *rasterised* by dispmap's own `GBufferPass` with any `GBufferParams` (a camera below
//! the surface, UVs offset by many tiles). It is the route the hard-case matrix takes to
//! trace exact view directions: the trace pass reads only the G-buffer, so filling it
//! with chosen rays tests the methods on exactly those rays, with the same code path a
//! host engine uses. Frames-in-flight slots (hit image, command buffer, fence) follow the
//! slot contract of `dispmap::embed`.

use ash::vk;
use dispmap::Context;
use dispmap::abi::GBufferParams;
use dispmap::embed::{
    DEPTH_FORMAT, DisplacementPass, FRAME_FORMAT, FrameInputs, HIT_FORMAT, RAY_FORMAT, Timestamps,
};
use dispmap::gpu::commands::{read_image, upload_image};
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Image, OneShot};
use dispmap::passes::gbuffer::{GBuffer, GBufferPass};
use dispmap::reference::Ray;
use std::sync::Arc;

/// Before an image whose contents are discarded: every earlier access has finished.
const DISCARD: Access = Access {
    stage: vk::PipelineStageFlags2::ALL_COMMANDS,
    access: vk::AccessFlags2::NONE,
    layout: vk::ImageLayout::UNDEFINED,
};

/// `1.0` as an IEEE half float (the normal and tangent images are `R16G16B16A16_SFLOAT`).
const HALF_ONE: u16 = 0x3C00;

/// The surface id the uploaded G-buffer gives every covered pixel (DIG's same-surface test).
pub const SURFACE_ID: f32 = 1.0;

/// One frame-in-flight slot.
struct Slot {
    hit: Image,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    submitted: bool,
}

/// The test host: one G-buffer (read-only while frames are in flight), per-slot hit
/// images, command buffers and fences, and a one-shot for uploads and read-backs.
pub struct RayHost {
    ctx: Arc<Context>,
    /// Frame size.
    pub extent: vk::Extent2D,
    gbuffer: GBuffer,
    gbuffer_pass: Option<GBufferPass>,
    shot: OneShot,
    pool: vk::CommandPool,
    slots: Vec<Slot>,
}

impl RayHost {
    /// A host of `slots` frames in flight for `extent` frames.
    pub fn new(ctx: Arc<Context>, extent: vk::Extent2D, slots: usize) -> RayHost {
        let c = &*ctx;
        let color = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST;
        let gbuffer = GBuffer {
            ray: Image::new(c, "host.ray", RAY_FORMAT, extent, 1, color).unwrap(),
            normal: Image::new(c, "host.normal", FRAME_FORMAT, extent, 1, color).unwrap(),
            tangent: Image::new(c, "host.tangent", FRAME_FORMAT, extent, 1, color).unwrap(),
            depth: Image::new(
                c,
                "host.depth",
                DEPTH_FORMAT,
                extent,
                1,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC
                    | vk::ImageUsageFlags::TRANSFER_DST,
            )
            .unwrap(),
        };
        let dev = c.device();
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(c.queue_family_index())
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and create info.
        let pool = unsafe { dev.create_command_pool(&info, None) }.unwrap();
        c.set_name(pool, "host.pool");
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(slots as u32);
        // SAFETY: `pool` is valid.
        let cmds = unsafe { dev.allocate_command_buffers(&alloc) }.unwrap();
        let slots = cmds
            .into_iter()
            .enumerate()
            .map(|(s, cmd)| {
                // SAFETY: valid device.
                let fence =
                    unsafe { dev.create_fence(&vk::FenceCreateInfo::default(), None) }.unwrap();
                c.set_name(cmd, &format!("host.cmd{s}"));
                c.set_name(fence, &format!("host.fence{s}"));
                let hit = Image::new(
                    c,
                    &format!("host.hit{s}"),
                    HIT_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
                )
                .unwrap();
                Slot {
                    hit,
                    cmd,
                    fence,
                    submitted: false,
                }
            })
            .collect();
        let shot = OneShot::new(c, "host.shot").unwrap();
        RayHost {
            ctx,
            extent,
            gbuffer,
            gbuffer_pass: None,
            shot,
            pool,
            slots,
        }
    }

    /// Pixels per frame.
    pub fn pixels(&self) -> usize {
        self.extent.width as usize * self.extent.height as usize
    }

    /// Uploads one ray per pixel (row by row; `None`: no geometry) as the G-buffer: `ray`
    /// = `(uv0, P)`, depth 0.5 where covered (0: none), normal `+y` with surface id
    /// [`SURFACE_ID`], tangent `+x`. Needs no frame in flight.
    pub fn set_rays(&mut self, rays: &[Option<([f32; 2], [f32; 2])>]) {
        assert_eq!(rays.len(), self.pixels(), "one ray per pixel");
        self.wait_all();
        let ray: Vec<[f32; 4]> = rays
            .iter()
            .map(|r| r.map_or([0.0; 4], |(uv, p)| [uv[0], uv[1], p[0], p[1]]))
            .collect();
        let depth: Vec<f32> = rays
            .iter()
            .map(|r| if r.is_some() { 0.5 } else { 0.0 })
            .collect();
        let normal: Vec<[u16; 4]> = rays
            .iter()
            .map(|r| {
                if r.is_some() {
                    [0, HALF_ONE, 0, HALF_ONE]
                } else {
                    [0; 4]
                }
            })
            .collect();
        let tangent: Vec<[u16; 4]> = rays
            .iter()
            .map(|r| {
                if r.is_some() {
                    [HALF_ONE, 0, 0, HALF_ONE]
                } else {
                    [0; 4]
                }
            })
            .collect();
        let c = &*self.ctx;
        let g = &self.gbuffer;
        let after = Access::COMPUTE_SAMPLED;
        upload_image(c, &self.shot, &g.ray, bytemuck::cast_slice(&ray), after).unwrap();
        upload_image(c, &self.shot, &g.depth, bytemuck::cast_slice(&depth), after).unwrap();
        upload_image(
            c,
            &self.shot,
            &g.normal,
            bytemuck::cast_slice(&normal),
            after,
        )
        .unwrap();
        upload_image(
            c,
            &self.shot,
            &g.tangent,
            bytemuck::cast_slice(&tangent),
            after,
        )
        .unwrap();
    }

    /// Rasterises the G-buffer with dispmap's `GBufferPass` and `params`. Needs no frame
    /// in flight.
    pub fn rasterise(&mut self, params: &GBufferParams) {
        self.wait_all();
        let c = &*self.ctx;
        if self.gbuffer_pass.is_none() {
            self.gbuffer_pass = Some(GBufferPass::new(c).unwrap());
        }
        let g = &self.gbuffer;
        let cmd = self.shot.begin(c).unwrap();
        let mut before: Vec<_> = g
            .colors()
            .iter()
            .map(|i| sync::image_barrier(i.raw, i.range(), DISCARD, Access::COLOR_ATTACHMENT_WRITE))
            .collect();
        before.push(sync::image_barrier(
            g.depth.raw,
            g.depth.range(),
            DISCARD,
            Access::DEPTH_ATTACHMENT_WRITE,
        ));
        sync::record(c, cmd, &before);
        self.gbuffer_pass
            .as_ref()
            .expect("created above")
            .record(c, cmd, g, params);
        let mut after: Vec<_> = g
            .colors()
            .iter()
            .map(|i| {
                sync::image_barrier(
                    i.raw,
                    i.range(),
                    Access::COLOR_ATTACHMENT_WRITE,
                    Access::COMPUTE_SAMPLED,
                )
            })
            .collect();
        after.push(sync::image_barrier(
            g.depth.raw,
            g.depth.range(),
            Access::DEPTH_ATTACHMENT_WRITE,
            Access::COMPUTE_SAMPLED,
        ));
        sync::record(c, cmd, &after);
        self.shot.submit_and_wait(c).unwrap();
    }

    /// The G-buffer's rays as the reference reads them (`None`: no geometry).
    pub fn read_rays(&self) -> Vec<Option<Ray>> {
        let c = &*self.ctx;
        let g = &self.gbuffer;
        let ray = read_image(c, &self.shot, &g.ray, Access::COMPUTE_SAMPLED).unwrap();
        let depth = read_image(c, &self.shot, &g.depth, Access::COMPUTE_SAMPLED).unwrap();
        let ray: &[[f32; 4]] = bytemuck::cast_slice(&ray);
        let depth: &[f32] = bytemuck::cast_slice(&depth);
        ray.iter()
            .zip(depth)
            .map(|(r, &d)| {
                (d > 0.0).then(|| Ray {
                    uv0: [f64::from(r[0]), f64::from(r[1])],
                    parallax: [f64::from(r[2]), f64::from(r[3])],
                })
            })
            .collect()
    }

    /// Waits for slot `s`'s last frame (the slot contract).
    pub fn wait(&mut self, s: usize) {
        let slot = &mut self.slots[s];
        if slot.submitted {
            // SAFETY: the fence was submitted with the slot's last frame.
            unsafe {
                let dev = self.ctx.device();
                dev.wait_for_fences(&[slot.fence], true, u64::MAX).unwrap();
                dev.reset_fences(&[slot.fence]).unwrap();
            }
            slot.submitted = false;
        }
    }

    /// Waits for every slot.
    pub fn wait_all(&mut self) {
        for s in 0..self.slots.len() {
            self.wait(s);
        }
    }

    /// Records `pass` into slot `s` (after waiting for the slot's last frame) and submits
    /// it without waiting.
    pub fn submit(&mut self, pass: &mut DisplacementPass, s: usize) {
        self.wait(s);
        let ctx = self.ctx.clone();
        let dev = ctx.device();
        let slot = &mut self.slots[s];
        let cmd = slot.cmd;
        // SAFETY: the slot's last frame completed (waited above).
        unsafe {
            dev.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .unwrap();
            dev.begin_command_buffer(
                cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .unwrap();
        }
        sync::record(
            &ctx,
            cmd,
            &[sync::image_barrier(
                slot.hit.raw,
                slot.hit.range(),
                DISCARD,
                Access::COMPUTE_STORAGE_WRITE,
            )],
        );
        let inputs = FrameInputs {
            frame_slot: s as u32,
            gbuffer: self.gbuffer.views(),
            hit: slot.hit.view,
            shade: None,
        };
        // SAFETY: `cmd` is recording outside a render pass on the context's queue
        // family; the G-buffer is in SHADER_READ_ONLY_OPTIMAL after its upload or
        // rasterisation (completed: `set_rays` / `rasterise` wait), the hit image in
        // GENERAL; the views live until the frame completes; the slot contract holds
        // (`wait`) and the buffer is submitted below, in recording order.
        unsafe { pass.record(cmd, &inputs, Timestamps::Off) }.unwrap();
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
        let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
        // SAFETY: the buffer was begun above; the fence is unsignalled (reset in `wait`).
        unsafe {
            dev.end_command_buffer(cmd).unwrap();
            dev.queue_submit2(ctx.queue(), &submit, slot.fence).unwrap();
        }
        slot.submitted = true;
    }

    /// The hit buffer of slot `s` after its last frame (waits for it).
    pub fn hits(&mut self, s: usize) -> Vec<[f32; 4]> {
        self.wait(s);
        let bytes = read_image(
            &self.ctx,
            &self.shot,
            &self.slots[s].hit,
            Access::COMPUTE_STORAGE_WRITE,
        )
        .unwrap();
        bytemuck::cast_slice::<u8, [f32; 4]>(&bytes).to_vec()
    }

    /// One frame in slot 0, waited for: its hit buffer.
    pub fn trace(&mut self, pass: &mut DisplacementPass) -> Vec<[f32; 4]> {
        self.submit(pass, 0);
        self.hits(0)
    }

    /// Destroys everything the host created (waits for its frames first).
    pub fn destroy(mut self) {
        self.wait_all();
        let ctx = self.ctx.clone();
        for slot in &mut self.slots {
            slot.hit.destroy(&ctx);
            // SAFETY: the slot's frame completed (`wait_all`).
            unsafe { ctx.device().destroy_fence(slot.fence, None) };
        }
        // SAFETY: nothing recorded from the pool is pending (`wait_all`).
        unsafe { ctx.device().destroy_command_pool(self.pool, None) };
        if let Some(p) = &mut self.gbuffer_pass {
            p.destroy(&ctx);
        }
        self.gbuffer.destroy(&ctx);
        self.shot.destroy(&ctx);
    }
}
