//! The frames-in-flight plumbing every test host shares: one command buffer and fence per
//! slot, following the slot contract of `dispmap::embed` (slot `s` is recorded again only
//! after waiting on its previous fence; buffers are submitted in recording order), and
//! the host's G-buffer raster pass with the transitions into the pass's entry state.

use ash::vk;
use dispmap::Context;
use dispmap::abi::{GBufferParams, PixelRayParams};
use dispmap::gpu::sync::Access;
use dispmap::gpu::track::Tracker;
use dispmap::passes::gbuffer::{GBuffer, GBufferPass};
use std::sync::Arc;

/// Before an image whose contents are discarded: every earlier access (the slot's
/// previous frame, a read-back copy) has finished before the new writes (WAR).
pub const DISCARD: Access = Access {
    stage: vk::PipelineStageFlags2::ALL_COMMANDS,
    access: vk::AccessFlags2::NONE,
    layout: vk::ImageLayout::UNDEFINED,
};

/// A command pool and, per slot, a command buffer, a fence and whether the slot's last
/// frame was submitted and not yet waited for.
pub struct FrameSlots {
    ctx: Arc<Context>,
    pool: vk::CommandPool,
    cmds: Vec<vk::CommandBuffer>,
    fences: Vec<vk::Fence>,
    submitted: Vec<bool>,
}

impl FrameSlots {
    /// `slots` command buffers and fences (named `host.cmd{s}`, `host.fence{s}`).
    pub fn new(ctx: Arc<Context>, slots: usize) -> FrameSlots {
        let dev = ctx.device();
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family_index())
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and create info.
        let pool = unsafe { dev.create_command_pool(&info, None) }.unwrap();
        ctx.set_name(pool, "host.pool");
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(slots as u32);
        // SAFETY: `pool` is valid.
        let cmds = unsafe { dev.allocate_command_buffers(&alloc) }.unwrap();
        let fences = (0..slots)
            .map(|s| {
                // SAFETY: valid device.
                let fence =
                    unsafe { dev.create_fence(&vk::FenceCreateInfo::default(), None) }.unwrap();
                ctx.set_name(cmds[s], &format!("host.cmd{s}"));
                ctx.set_name(fence, &format!("host.fence{s}"));
                fence
            })
            .collect();
        FrameSlots {
            ctx,
            pool,
            cmds,
            fences,
            submitted: vec![false; slots],
        }
    }

    /// Number of slots.
    pub fn len(&self) -> usize {
        self.cmds.len()
    }

    /// Whether slot `s`'s last frame was submitted and not waited for.
    pub fn in_flight(&self, s: usize) -> bool {
        self.submitted[s]
    }

    /// Whether every slot has a frame in flight.
    pub fn all_in_flight(&self) -> bool {
        self.submitted.iter().all(|&b| b)
    }

    /// Whether some slot has a frame in flight.
    pub fn any_in_flight(&self) -> bool {
        self.submitted.iter().any(|&b| b)
    }

    /// Waits for slot `s`'s last frame (the slot contract).
    pub fn wait(&mut self, s: usize) {
        if self.submitted[s] {
            let dev = self.ctx.device();
            // SAFETY: the fence was submitted with the slot's last frame.
            unsafe {
                dev.wait_for_fences(&[self.fences[s]], true, u64::MAX)
                    .unwrap();
                dev.reset_fences(&[self.fences[s]]).unwrap();
            }
            self.submitted[s] = false;
        }
    }

    /// Waits for every slot.
    pub fn wait_all(&mut self) {
        for s in 0..self.len() {
            self.wait(s);
        }
    }

    /// Waits for slot `s`'s last frame, then resets and begins its command buffer.
    pub fn begin(&mut self, s: usize) -> vk::CommandBuffer {
        self.wait(s);
        let cmd = self.cmds[s];
        let dev = self.ctx.device();
        // SAFETY: the slot's last frame completed (waited above), so its buffer may be
        // reset.
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
        cmd
    }

    /// Ends slot `s`'s command buffer (begun by [`FrameSlots::begin`]) and submits it
    /// with the slot's fence, without waiting.
    pub fn submit(&mut self, s: usize) {
        let cmd = self.cmds[s];
        let dev = self.ctx.device();
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
        let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
        // SAFETY: the buffer was begun by `begin`; the fence is unsignalled (reset in
        // `wait`, which `begin` called).
        unsafe {
            dev.end_command_buffer(cmd).unwrap();
            dev.queue_submit2(self.ctx.queue(), &submit, self.fences[s])
                .unwrap();
        }
        self.submitted[s] = true;
    }

    /// Waits for every slot, then destroys the fences and the pool.
    pub fn destroy(mut self) {
        self.wait_all();
        let dev = self.ctx.device();
        for &fence in &self.fences {
            // SAFETY: the slot's frame completed (`wait_all`).
            unsafe { dev.destroy_fence(fence, None) };
        }
        // SAFETY: nothing recorded from the pool is pending (`wait_all`).
        unsafe { dev.destroy_command_pool(self.pool, None) };
    }
}

/// Records the host's G-buffer: every image discarded into its attachment layout, the
/// raster pass with `params`, then the entry state of `dispmap::embed`'s pass (every
/// image sampled by compute shaders).
///
/// # Safety
/// `cmd` is a command buffer of `ctx`'s device in the recording state, outside a render
/// pass instance, for a queue of the context's queue family; no access of `g`'s images
/// is pending when it executes (their contents are discarded); `g` and `pass` stay alive
/// until it has executed.
pub unsafe fn record_gbuffer(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    pass: &GBufferPass,
    g: &GBuffer,
    params: &GBufferParams,
    rays: &PixelRayParams,
) {
    // The images enter discarded; a tracker places the barriers from the declared uses.
    let mut t = Tracker::new();
    g.enter(&mut t, DISCARD, DISCARD);
    g.declare(
        &mut t,
        Access::COLOR_ATTACHMENT_WRITE,
        Access::DEPTH_ATTACHMENT_WRITE,
    )
    .unwrap();
    // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
    // pass; the G-buffer is alive and its contents may be discarded; its images have
    // attachment usage (`GBuffer::new`).
    unsafe { t.record(ctx, cmd).unwrap() };
    // SAFETY: as above; the G-buffer is in the attachment layouts (the barriers above).
    unsafe { pass.record(ctx, cmd, g, params, rays).unwrap() };
    g.declare(&mut t, Access::COMPUTE_SAMPLED, Access::COMPUTE_SAMPLED)
        .unwrap();
    // SAFETY: as above; the G-buffer was written in the attachment layouts.
    unsafe { t.record(ctx, cmd).unwrap() };
}

/// A test host's hit images of one frame slot: the hit uv and hit height images the pass
/// writes (`dispmap::embed::HitImages`).
pub struct HitPair {
    /// `HIT_UV_FORMAT`.
    pub uv: dispmap::gpu::Image,
    /// `HIT_HEIGHT_FORMAT`.
    pub height: dispmap::gpu::Image,
}

impl HitPair {
    /// Both images of `extent`, named `{name}.uv` / `{name}.height`, with `usage`.
    pub fn new(
        ctx: &Context,
        name: &str,
        extent: vk::Extent2D,
        usage: vk::ImageUsageFlags,
    ) -> Self {
        use dispmap::embed::{HIT_HEIGHT_FORMAT, HIT_UV_FORMAT};
        let image = |part: &str, format| {
            dispmap::gpu::Image::new(ctx, &format!("{name}.{part}"), format, extent, 1, usage)
                .unwrap()
        };
        HitPair {
            uv: image("uv", HIT_UV_FORMAT),
            height: image("height", HIT_HEIGHT_FORMAT),
        }
    }

    /// The frame size.
    pub fn extent(&self) -> vk::Extent2D {
        self.uv.extent
    }

    /// The images as `FrameInputs::hit`.
    pub fn host(&self) -> dispmap::embed::HitImages {
        dispmap::embed::HitImages {
            uv: self.uv.host_view(),
            height: self.height.host_view(),
        }
    }

    /// Records the pass's entry state of both: contents discarded -> `GENERAL`, ordered
    /// before compute-shader storage writes.
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue family; every
    /// earlier access of the images has completed or is ordered by the submission order.
    pub unsafe fn discard(&self, ctx: &Context, cmd: vk::CommandBuffer) {
        for image in [&self.uv, &self.height] {
            // SAFETY: this function's contract.
            unsafe {
                dispmap::gpu::sync::transition(
                    ctx,
                    cmd,
                    image,
                    DISCARD,
                    Access::COMPUTE_STORAGE_WRITE,
                )
            };
        }
    }

    /// The hits after a frame (waited for), one texel per pixel: `u`, `v`, height and the
    /// count of `iterations` (the pass's image of the slot; 0 without one). The images were
    /// last accessed as `access`, the iteration image written by the pass.
    pub fn read(
        &self,
        ctx: &Context,
        shot: &dispmap::gpu::OneShot,
        access: Access,
        iterations: Option<&dispmap::gpu::Image>,
    ) -> Vec<[f32; 4]> {
        use dispmap::gpu::commands::read_image;
        let uv = read_image(ctx, shot, &self.uv, access).unwrap();
        let height = read_image(ctx, shot, &self.height, access).unwrap();
        let counts =
            iterations.map(|i| read_image(ctx, shot, i, Access::COMPUTE_STORAGE_WRITE).unwrap());
        dispmap::passes::trace::join_hits(&uv, &height, counts.as_deref())
    }

    /// Destroys both.
    ///
    /// # Safety
    /// No pending command buffer uses them.
    pub unsafe fn destroy(&mut self, ctx: &Context) {
        use dispmap::gpu::owned::Destroy;
        // SAFETY: this function's contract.
        unsafe {
            self.uv.destroy(ctx);
            self.height.destroy(ctx);
        }
    }
}
