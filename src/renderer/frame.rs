//! Recording, submitting and timing one frame of the standalone renderer: the G-buffer,
//! the background, the displacement pass and the renderer's own barriers around them.

use super::*;
use crate::gpu::track::{Handle, Tracker};

impl Renderer {
    /// Renders one frame and returns its per-pass GPU times (one-off passes included
    /// when this frame ran them).
    pub fn render(&mut self) -> Result<PassTimes> {
        let ctx = &*self.ctx;
        let (camera, target) = self.frame_target();
        let gbuffer_params = self.settings.scene.gbuffer_params(&camera);
        let draws = self.object_draws(&camera)?;
        let cmd = self.shot.begin(ctx)?;
        let mut w = ScopeWriter::new(Some(self.timestamps.0), 0, GBUFFER_QUERIES);
        // SAFETY: `cmd` was just begun; the pool is alive with the range.
        unsafe { w.reset(ctx, cmd) };

        // The frame's images enter discarded (their previous frame was waited for); the
        // tracker places every barrier from the accesses declared below.
        let mut t = Tracker::new();
        self.gbuffer.enter(&mut t, DISCARD, DISCARD);
        for image in [&self.hit.uv, &self.hit.height, &self.color] {
            t.enter(Handle::image(image), DISCARD);
        }
        self.gbuffer.declare(
            &mut t,
            Access::COLOR_ATTACHMENT_WRITE,
            Access::DEPTH_ATTACHMENT_WRITE,
        )?;
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below, while the
        // images live; they entered as the tracker knows; the G-buffer's images have
        // attachment usage (`GBuffer::new`).
        unsafe { t.record(ctx, cmd)? };
        // SAFETY: `cmd` is recording outside a render pass and `w.reset` was recorded
        // above (the scope's contract). In the body (inside this block): the G-buffer is
        // in the attachment layouts (the barriers above); it, the pass and the mesh's
        // buffers live until the submission below has completed.
        unsafe {
            w.scope(ctx, cmd, PassName::GBuffer, |cmd| {
                match (&draws, &self.mesh) {
                    (Some(draws), _) => crate::passes::gbuffer::record_draws(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        draws,
                        &camera.pixel_ray_params(),
                    ),
                    (None, Some(mesh)) => self.gbuffer_pass.record_mesh(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        &gbuffer_params,
                        mesh,
                    ),
                    (None, None) => self.gbuffer_pass.record(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        &gbuffer_params,
                        &camera.pixel_ray_params(),
                    ),
                }
            })?
        };

        // The pass's entry contract: G-buffer sampled by compute, hit images discarded in
        // GENERAL, colour in GENERAL with the host's background (below).
        self.gbuffer
            .declare(&mut t, Access::COMPUTE_SAMPLED, Access::COMPUTE_SAMPLED)?;
        for image in [&self.hit.uv, &self.hit.height, &self.color] {
            t.declare(Handle::image(image), Access::COMPUTE_STORAGE_WRITE)?;
        }
        // SAFETY: `cmd` is recording outside a render pass (begun above, submitted
        // below); the images are alive and in the states the tracker knows.
        unsafe { t.record(ctx, cmd)? };
        // SAFETY: `cmd` is recording outside a render pass and submitted below; the
        // G-buffer is sampled-readable and the colour image in GENERAL for storage writes
        // (the barriers above).
        unsafe { self.record_background(cmd, &target, &mut t)? };
        let mut inputs = self.frame_inputs(Some(target));
        let current = DepthCamera {
            view_proj: target.view_proj,
            eye: target.camera_pos,
        };
        if let Some(m) = &self.motion {
            // SAFETY: `cmd` is recording outside a render pass and submitted (and waited
            // for) below; the G-buffer depth is sampled-readable (the entry barriers); the
            // image's previous frame was waited for.
            inputs.motion = Some(unsafe { m.record(ctx, cmd, self.gbuffer.depth.view, current)? });
        }
        // SAFETY: `cmd` is recording outside a render pass on the context's queue and is
        // submitted below; the views are the renderer's, in the entry states; one slot,
        // whose previous frame was waited for; the pool has the queries after the
        // G-buffer's.
        let frame = unsafe {
            self.pass.record(
                cmd,
                &inputs,
                Timestamps::Host {
                    pool: self.timestamps.0,
                    first_query: GBUFFER_QUERIES,
                },
            )?
        };
        // SAFETY: `cmd` is recording outside a render pass, after the first record, and is
        // submitted and waited for below; the behind layer's previous frame was waited for.
        let behind = unsafe { self.record_behind(cmd, &camera, &target, inputs.motion)? };
        let ctx = &*self.ctx;
        self.shot.submit_and_wait(ctx)?;
        if behind.is_none() && self.pass.settings().frames_in_flight > behind::BEHIND_SLOT {
            // SAFETY: every frame of this renderer was waited for (the one just above).
            unsafe { self.pass.release_slot(behind::BEHIND_SLOT)? };
        }
        self.depth_written |= self.pass.depth_output();
        if let Some(m) = &mut self.motion {
            m.previous = Some(current);
        }
        self.rays_frame = Some((self.settings.scene, camera));
        self.forward_frame = false;
        let mut times = self.frame_times(&w, &frame)?;
        if let Some(b) = behind {
            // SAFETY: the pool is alive and the frame completed (waited for above).
            times.extend(unsafe { read_timestamps(&self.ctx, &b.scopes)? });
        }
        Ok(times)
    }

    /// The per-pass times of a completed frame (the renderer's scopes, then the pass's),
    /// and the builds it ran kept for [`Renderer::build_ms`].
    pub(super) fn frame_times(
        &mut self,
        own: &ScopeWriter,
        frame: &crate::embed::RecordedFrame,
    ) -> Result<PassTimes> {
        let scopes: Vec<_> = own
            .scopes
            .iter()
            .chain(&frame.timestamps)
            .copied()
            .collect();
        // SAFETY: the pool is alive and the frame completed (the caller waited for it).
        let times = unsafe { read_timestamps(&self.ctx, &scopes)? };
        for &(name, ms) in &times {
            if matches!(name, PassName::Pyramid | PassName::Cone) {
                self.builds.retain(|(n, _)| *n != name);
                self.builds.push((name, ms));
            }
        }
        Ok(times)
    }

    /// The GPU milliseconds of the last pyramid build (the method's, or hard shadows'
    /// cell pyramid), while the renderer has one.
    pub fn pyramid_ms(&self) -> Option<f64> {
        self.build_ms(PassName::Pyramid)
    }

    /// The GPU milliseconds of the last build of a one-off map, [`PassName::Pyramid`] or
    /// [`PassName::Cone`], while the renderer has it (`None` for other passes).
    pub fn build_ms(&self, pass: PassName) -> Option<f64> {
        self.builds
            .iter()
            .find(|(n, _)| *n == pass)
            .map(|&(_, ms)| ms)
    }

    /// The draws of a frame of several objects (`None` for one geometry): each object's
    /// push constants with its material (`camera_pos.w` = index + 1, 0 flat), the
    /// material's current depth scale and addressing.
    pub(super) fn object_draws(
        &self,
        camera: &crate::scene::FrameCamera,
    ) -> Result<Option<Vec<GBufferDraw<'_>>>> {
        let Some(objects) = &self.objects else {
            return Ok(None);
        };
        let plane = Scene {
            geometry: Geometry::TiledPlane,
            ..self.settings.scene
        }
        .gbuffer_params(camera);
        let mesh = Scene {
            geometry: Geometry::Quad,
            ..self.settings.scene
        }
        .gbuffer_params(camera);
        let mut draws = Vec::with_capacity(objects.meshes.len());
        for (buffers, material) in objects.meshes.iter().zip(&objects.materials) {
            let mut params = if buffers.is_some() { mesh } else { plane };
            params.camera_pos.w = 0.0;
            // Only a material traced curved reads the curve image (a method with a curved
            // path, the material set curved).
            let mut curve = false;
            if let Some(id) = material {
                let m = self.pass.material_settings(*id)?;
                curve = m.method.traces_curved() && self.pass.material_curved(*id)?;
                params.camera_pos.w = (id.index() + 1) as f32;
                params.depth_scale = m.depth_scale;
                params.addressing = crate::scene::addressing_code(m.addressing);
            }
            let pass = match (buffers, &objects.mesh_pass, &objects.two_sided_pass) {
                (Some(b), _, Some(p)) if b.two_sided => p,
                (Some(_), Some(p), _) => p,
                _ => &self.gbuffer_pass,
            };
            draws.push(GBufferDraw {
                pass,
                params,
                mesh: buffers.as_ref(),
                curve,
            });
        }
        Ok(Some(draws))
    }

    /// The frame's camera and what `shade` lights it with.
    pub(super) fn frame_target(&self) -> (crate::scene::FrameCamera, ShadeTarget) {
        let scene = &self.settings.scene;
        let (w, h) = (self.settings.width, self.settings.height);
        let camera = match &self.objects {
            None => scene.frame_camera(w, h),
            Some(Objects {
                framing: Some((target, distance)),
                ..
            }) => {
                scene.camera_looking_at(w, h, *target, scene.camera.distance.unwrap_or(*distance))
            }
            Some(_) => Scene {
                geometry: Geometry::TiledPlane,
                ..*scene
            }
            .frame_camera(w, h),
        };
        let target = ShadeTarget {
            color: self.color.host_view(),
            view_proj: camera.view_proj,
            camera_pos: camera.eye,
            light_dir: scene.light_direction(),
            light_intensity: scene.light.intensity,
        };
        (camera, target)
    }

    /// The background pass's constants of a frame lit as `target` says (both layers').
    pub(super) fn background_params(&self, target: &ShadeTarget) -> crate::abi::ShadeParams {
        let e = self.settings.extent();
        crate::abi::ShadeParams::new(
            target.view_proj,
            target.camera_pos,
            target.light_dir,
            target.light_intensity,
            [e.width, e.height],
            [1, 1],
            0.0,
        )
    }

    /// The host's background (sky, flat geometry) into the colour image, then the
    /// colour's barrier for `shade`'s writes of the displaced pixels (declared in `t`).
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue and is submitted
    /// (and waited for) while the renderer lives; when it executes, the G-buffer is
    /// sampled-readable by compute and the colour image in `GENERAL`, earlier accesses
    /// ordered before compute-shader storage writes, as `t` knows it (its last declared
    /// access a compute-shader storage write, recorded).
    pub(super) unsafe fn record_background(
        &self,
        cmd: vk::CommandBuffer,
        target: &ShadeTarget,
        t: &mut Tracker<Handle>,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let params = self.background_params(target);
        // SAFETY: this function's contract; the views are the renderer's, alive.
        unsafe {
            self.background.record(
                ctx,
                cmd,
                self.gbuffer.views(),
                self.color.view_ref(),
                &params,
            )?;
            // `shade` writes the displaced pixels after the background's writes.
            t.declare(Handle::image(&self.color), Access::COMPUTE_STORAGE_WRITE)?;
            t.record(ctx, cmd)?;
        }
        Ok(())
    }

    pub(super) fn frame_inputs(&self, shade: Option<ShadeTarget>) -> FrameInputs {
        FrameInputs {
            frame_slot: 0,
            gbuffer: self.gbuffer.views(),
            hit: self.hit.host(),
            shade,
            motion: None,
        }
    }
}
