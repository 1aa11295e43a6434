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
use dispmap::abi::{GBufferParams, PixelRayParams};
use dispmap::embed::{
    DEPTH_FORMAT, DisplacementPass, FRAME_FORMAT, FrameInputs, HIT_HEIGHT_FORMAT, HIT_UV_FORMAT,
    HitImages, RAY_FORMAT, Timestamps,
};
use dispmap::gpu::commands::{read_image, upload_image};
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Image, OneShot};
use dispmap::passes::gbuffer::{GBuffer, GBufferPass};
use dispmap_cli::reference::Ray;
use std::sync::Arc;

use super::frames::{DISCARD, FrameSlots, record_gbuffer};

/// The surface id the uploaded G-buffer gives every covered pixel (DIG's same-surface test).
pub const SURFACE_ID: f32 = 1.0;

/// The test host: one G-buffer (read-only while frames are in flight), per-slot hit
/// images, command buffers and fences, and a one-shot for uploads and read-backs.
pub struct RayHost {
    ctx: Arc<Context>,
    /// Frame size.
    pub extent: vk::Extent2D,
    gbuffer: GBuffer,
    gbuffer_pass: Option<GBufferPass>,
    shot: OneShot,
    slots: FrameSlots,
    /// The hit images (uv, height) of each slot.
    hits: Vec<[Image; 2]>,
    /// One colour image per slot (`submit_shaded`).
    colors: Vec<Image>,
    /// Where the next record writes its timestamps (`Off` but in `submit_shaded_timed`).
    timestamps: Timestamps,
    /// What the last record recorded.
    recorded: Option<dispmap::embed::RecordedFrame>,
}

/// The G-buffer's texels as uploaded or read back: `ray` (f32 x 4), `depth` (f32),
/// `frame` (`R32G32_UINT`, `dispmap::passes::gbuffer::frame`).
#[derive(Clone)]
pub struct GBufferTexels {
    pub ray: Vec<[f32; 4]>,
    pub depth: Vec<f32>,
    pub frame: Vec<[u32; 2]>,
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
            frame: Image::new(c, "host.frame", FRAME_FORMAT, extent, 1, color).unwrap(),
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
            curve: None,
        };
        let colors = (0..slots)
            .map(|s| {
                Image::new(
                    c,
                    &format!("host.color{s}"),
                    dispmap::embed::COLOR_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE
                        | vk::ImageUsageFlags::TRANSFER_SRC
                        | vk::ImageUsageFlags::TRANSFER_DST,
                )
                .unwrap()
            })
            .collect();
        let hits = (0..slots)
            .map(|s| {
                [("uv", HIT_UV_FORMAT), ("height", HIT_HEIGHT_FORMAT)].map(|(part, format)| {
                    Image::new(
                        c,
                        &format!("host.hit{s}.{part}"),
                        format,
                        extent,
                        1,
                        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
                    )
                    .unwrap()
                })
            })
            .collect();
        let slots = FrameSlots::new(ctx.clone(), slots);
        let shot = OneShot::new(c, "host.shot").unwrap();
        RayHost {
            ctx,
            extent,
            gbuffer,
            gbuffer_pass: None,
            shot,
            slots,
            hits,
            colors,
            timestamps: Timestamps::Off,
            recorded: None,
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
        let covered = dispmap::passes::gbuffer::frame::pack(
            glam::Vec3::Y,
            glam::Vec3::X,
            1.0,
            1,
            SURFACE_ID as u32,
        );
        let frame: Vec<[u32; 2]> = rays
            .iter()
            .map(|r| if r.is_some() { covered } else { [0; 2] })
            .collect();
        let c = &*self.ctx;
        let g = &self.gbuffer;
        let after = Access::COMPUTE_SAMPLED;
        upload_image(c, &self.shot, &g.ray, bytemuck::cast_slice(&ray), after).unwrap();
        upload_image(c, &self.shot, &g.depth, bytemuck::cast_slice(&depth), after).unwrap();
        upload_image(c, &self.shot, &g.frame, bytemuck::cast_slice(&frame), after).unwrap();
    }

    /// Rasterises the G-buffer with dispmap's `GBufferPass` and `params`. Needs no frame
    /// in flight.
    pub fn rasterise(&mut self, params: &GBufferParams, rays: &PixelRayParams) {
        self.wait_all();
        let c = &*self.ctx;
        if self.gbuffer_pass.is_none() {
            self.gbuffer_pass = Some(GBufferPass::new(c).unwrap());
        }
        let cmd = self.shot.begin(c).unwrap();
        let pass = self.gbuffer_pass.as_ref().expect("created above");
        // SAFETY: `cmd` was begun by `shot.begin` above and is submitted and waited for
        // below, while the G-buffer and the pass live; no frame is in flight
        // (`wait_all` above), so the G-buffer may be discarded.
        unsafe { record_gbuffer(c, cmd, pass, &self.gbuffer, params, rays) };
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

    /// The G-buffer's texels (needs no frame in flight).
    pub fn read_gbuffer(&mut self) -> GBufferTexels {
        self.wait_all();
        let c = &*self.ctx;
        let g = &self.gbuffer;
        let read =
            |image: &Image| read_image(c, &self.shot, image, Access::COMPUTE_SAMPLED).unwrap();
        GBufferTexels {
            ray: bytemuck::cast_slice(&read(&g.ray)).to_vec(),
            depth: bytemuck::cast_slice(&read(&g.depth)).to_vec(),
            frame: bytemuck::cast_slice(&read(&g.frame)).to_vec(),
        }
    }

    /// Uploads `texels` as the G-buffer (needs no frame in flight).
    pub fn upload_gbuffer(&mut self, texels: &GBufferTexels) {
        self.wait_all();
        let c = &*self.ctx;
        let g = &self.gbuffer;
        let after = Access::COMPUTE_SAMPLED;
        upload_image(
            c,
            &self.shot,
            &g.ray,
            bytemuck::cast_slice(&texels.ray),
            after,
        )
        .unwrap();
        upload_image(
            c,
            &self.shot,
            &g.depth,
            bytemuck::cast_slice(&texels.depth),
            after,
        )
        .unwrap();
        upload_image(
            c,
            &self.shot,
            &g.frame,
            bytemuck::cast_slice(&texels.frame),
            after,
        )
        .unwrap();
    }

    /// As [`RayHost::submit`] with a `ShadeTarget` whose colour image the host filled with
    /// `fill` (RGBA8) first; `light_dir` lights it.
    pub fn submit_shaded(
        &mut self,
        pass: &mut DisplacementPass,
        s: usize,
        camera: (glam::Mat4, glam::Vec3),
        fill: [u8; 4],
    ) {
        let pixels: Vec<[u8; 4]> = vec![fill; self.pixels()];
        self.slots.wait(s);
        upload_image(
            &self.ctx,
            &self.shot,
            &self.colors[s],
            bytemuck::cast_slice(&pixels),
            Access::COMPUTE_STORAGE_WRITE,
        )
        .unwrap();
        // The colour image holds the host's fill in GENERAL, visible to compute-shader
        // storage writes (the upload above, completed).
        let shade = dispmap::embed::ShadeTarget {
            color: self.colors[s].host_view(),
            view_proj: camera.0,
            camera_pos: camera.1,
            light_dir: glam::Vec3::new(0.3, 0.8, 0.5).normalize(),
            light_intensity: 1.0,
        };
        self.record_slot(pass, s, Some(shade));
    }

    /// The colour image of slot `s` after its last frame (waits for it).
    pub fn colors(&mut self, s: usize) -> Vec<[u8; 4]> {
        bytemuck::cast_slice::<u8, [u8; 4]>(&self.read_slot(s)).to_vec()
    }

    /// Slot `s`'s colour image after its last frame (waits for it).
    fn read_slot(&mut self, s: usize) -> Vec<u8> {
        self.slots.wait(s);
        read_image(
            &self.ctx,
            &self.shot,
            &self.colors[s],
            Access::COMPUTE_STORAGE_WRITE,
        )
        .unwrap()
    }

    /// Waits for the frame of slot `s`.
    pub fn wait(&mut self, s: usize) {
        self.slots.wait(s);
    }

    /// The one-shot for read-backs.
    pub fn shot(&self) -> &OneShot {
        &self.shot
    }

    /// Waits for every slot.
    pub fn wait_all(&mut self) {
        self.slots.wait_all();
    }

    /// Records `pass` into slot `s` (after waiting for the slot's last frame) and submits
    /// it without waiting.
    pub fn submit(&mut self, pass: &mut DisplacementPass, s: usize) {
        self.record_slot(pass, s, None);
    }

    /// Records `pass` into slot `s` with the corrected depth's and the motion's camera
    /// (`record_with_camera`) and `motion` (its image in `GENERAL`, the host's writes
    /// visible to compute-shader storage reads and writes, e.g. after `upload_image`), and
    /// submits it without waiting.
    pub fn submit_with_motion(
        &mut self,
        pass: &mut DisplacementPass,
        s: usize,
        camera: dispmap::embed::DepthCamera,
        motion: dispmap::embed::FrameMotion,
    ) {
        self.record_slot_with(pass, s, None, Some((camera, motion)));
    }

    /// Records `pass` into slot `s` (after waiting for the slot's last frame) with
    /// `shade`, and submits it without waiting.
    fn record_slot(
        &mut self,
        pass: &mut DisplacementPass,
        s: usize,
        shade: Option<dispmap::embed::ShadeTarget>,
    ) {
        self.record_slot_with(pass, s, shade, None);
    }

    /// [`RayHost::submit_shaded`] with the pass's own timestamps
    /// ([`dispmap::embed::Timestamps::Owned`]): what the record recorded.
    pub fn submit_shaded_timed(
        &mut self,
        pass: &mut DisplacementPass,
        s: usize,
        camera: (glam::Mat4, glam::Vec3),
        fill: [u8; 4],
    ) -> dispmap::embed::RecordedFrame {
        self.timestamps = Timestamps::Owned;
        self.submit_shaded(pass, s, camera, fill);
        self.timestamps = Timestamps::Off;
        self.recorded.take().expect("a frame was recorded")
    }

    /// [`RayHost::record_slot`], with a camera and motion inputs when given.
    fn record_slot_with(
        &mut self,
        pass: &mut DisplacementPass,
        s: usize,
        shade: Option<dispmap::embed::ShadeTarget>,
        motion: Option<(dispmap::embed::DepthCamera, dispmap::embed::FrameMotion)>,
    ) {
        let ctx = self.ctx.clone();
        let cmd = self.slots.begin(s);
        let [uv, height] = &self.hits[s];
        for hit in [uv, height] {
            // SAFETY: `cmd` was begun by `slots.begin` above (outside a render pass, on the
            // context's queue family) and is submitted below; the hit images live until the
            // host is destroyed after `wait_all`; the slot's last frame completed (`begin`
            // waited), so their contents may be discarded.
            unsafe { sync::transition(&ctx, cmd, hit, DISCARD, Access::COMPUTE_STORAGE_WRITE) };
        }
        let inputs = FrameInputs {
            frame_slot: s as u32,
            gbuffer: self.gbuffer.views(),
            hit: HitImages {
                uv: uv.host_view(),
                height: height.host_view(),
            },
            shade,
            motion: motion.map(|(_, m)| m),
        };
        // SAFETY: `cmd` is recording outside a render pass on the context's queue
        // family; the G-buffer is in SHADER_READ_ONLY_OPTIMAL after its upload or
        // rasterisation (completed: `set_rays` / `rasterise` wait), the hit image in
        // GENERAL, a shade target's colour image too (`submit_shaded`), a motion image
        // with the host's writes visible (`submit_with_motion`'s contract); the views live
        // until the frame completes; the slot contract holds (`begin` waited) and the
        // buffer is submitted below, in recording order.
        let timestamps = self.timestamps;
        let recorded = unsafe {
            match motion {
                Some((camera, _)) => pass.record_with_camera(cmd, &inputs, &camera, timestamps),
                None => pass.record(cmd, &inputs, timestamps),
            }
        };
        self.recorded = Some(recorded.unwrap());
        self.slots.submit(s);
    }

    /// The hits of slot `s` after its last frame (waits for it): `u`, `v`, height and 0
    /// (the pass's iteration output is off).
    pub fn hits(&mut self, s: usize) -> Vec<[f32; 4]> {
        self.slots.wait(s);
        let [uv, height] = &self.hits[s]
            .each_ref()
            .map(|i| read_image(&self.ctx, &self.shot, i, Access::COMPUTE_STORAGE_WRITE).unwrap());
        dispmap::passes::trace::join_hits(uv, height, None)
    }

    /// One frame in slot 0, waited for: its hit buffer.
    pub fn trace(&mut self, pass: &mut DisplacementPass) -> Vec<[f32; 4]> {
        self.submit(pass, 0);
        self.hits(0)
    }

    /// Destroys everything the host created (waits for its frames first).
    pub fn destroy(mut self) {
        self.slots.destroy();
        let ctx = self.ctx.clone();
        for hit in self.hits.iter_mut().flatten() {
            // SAFETY: `slots.destroy()` waited for every frame.
            unsafe { hit.destroy(&ctx) };
        }
        for color in &mut self.colors {
            // SAFETY: `slots.destroy()` waited for every frame.
            unsafe { color.destroy(&ctx) };
        }
        if let Some(p) = &mut self.gbuffer_pass {
            // SAFETY: `slots.destroy()` waited for every frame.
            unsafe { p.destroy(&ctx) };
        }
        // SAFETY: `slots.destroy()` waited for every frame.
        unsafe {
            self.gbuffer.destroy(&ctx);
            self.shot.destroy(&ctx);
        }
    }
}
