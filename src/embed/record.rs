//! Recording a frame: `[upload] -> [pyramid] -> [cone] -> [dig_corners] -> trace -> [shadow] ->
//! [shade] -> [hit_depth]`. Each stage is one method that places its own barriers next
//! to its dispatch, from the state the stage before it left (the module docs' table).

use super::{
    DepthCamera, DisplacementPass, Fill, FrameInputs, MAX_QUERIES, RecordedFrame, ShadeTarget,
    Timestamps,
};
use crate::abi::ShadeParams;
use crate::error::{Error, Result};
use crate::gpu::ViewRef;
use crate::gpu::sync::{self, Access};
use crate::passes::PassName;
use crate::passes::hit_depth::HitDepthInputs;
use crate::passes::shade::ShadeInputs;
use crate::passes::shadow::{ShadowInputs, ShadowPass};
use crate::passes::trace::TraceInputs;
use crate::timing::ScopeWriter;
use ash::vk;

/// Before a pass-owned per-slot image whose contents are discarded and that only the
/// pass's compute shaders accessed.
const DISCARD_COMPUTE: Access = Access {
    stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
    ..Access::UNDEFINED
};

/// Before a pass-owned per-slot image whose contents are discarded and that the host
/// may have accessed in any stage and left in any layout (the corrected depth).
const DISCARD_ANY: Access = Access {
    stage: vk::PipelineStageFlags2::ALL_COMMANDS,
    ..Access::UNDEFINED
};

impl DisplacementPass {
    /// Records the pass into the host's command buffer `cmd`: the uploads (height map,
    /// material maps) and the pyramid build when pending, the DIG corner pass, `trace`
    /// into `inputs.hit` and, with `inputs.shade`, `[shadow] -> shade`, and with the
    /// corrected depth on, `hit_depth`; each pass between debug labels and, unless
    /// `timestamps` is [`Timestamps::Off`], timestamps. Returns the passes and their
    /// queries.
    ///
    /// Resources that must not be in use by the GPU: those of `inputs.frame_slot` (its
    /// corner grid and owned timestamp range, the hit buffer and colour image passed in)
    /// and the pass's retired resources: the slot contract of the module docs guarantees
    /// both. The shared height texture and pyramid may be read by frames in flight.
    ///
    /// # Safety
    /// * `cmd` is a primary command buffer of the context's device in the recording state,
    ///   outside a render pass, for a queue of the context's queue family; it is submitted
    ///   (after any command buffer recorded earlier with this pass) to that queue.
    /// * The views in `inputs` are alive until the frame completes, belong to the
    ///   device, have the formats, usages, extent and entry layouts/accesses of the module
    ///   docs; the slot contract holds.
    /// * With [`Timestamps::Host`], `pool` is a live timestamp pool of the device with at
    ///   least `first_query + MAX_QUERIES` queries, not used by other commands of the
    ///   frame.
    pub unsafe fn record(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        // SAFETY: this function's contract.
        unsafe { self.record_frame(cmd, inputs, None, timestamps) }
    }

    /// [`DisplacementPass::record`] with the frame's camera for the corrected depth
    /// ([`DisplacementPass::set_depth_output`]), for a host that has no [`ShadeTarget`]
    /// (shades from the hit buffer itself). With a `ShadeTarget` its `view_proj` and
    /// `camera_pos` are the camera and `camera` is ignored.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    pub unsafe fn record_with_camera(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        camera: &DepthCamera,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        // SAFETY: this function's contract.
        unsafe { self.record_frame(cmd, inputs, Some(*camera), timestamps) }
    }

    /// Shades hits the host wrote into `inputs.hit` (e.g. exact reference hits) exactly
    /// as a frame shades the method's: pending uploads and builds, then, with
    /// self-shadowing on, `shadow` on those hits (unless `visibility` is given), then
    /// `shade` into `inputs.shade`'s colour image (required). `visibility`: a light
    /// visibility to shade with instead of the `shadow` pass's (an `R16_SFLOAT` storage
    /// view of the frame's size, `GENERAL`, visible to compute-shader storage reads;
    /// self-shadowing must be on). Runs no `trace`, corner pass or `hit_depth`.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`], except that the hit buffer enters with the
    /// host's hits: `GENERAL`, its writes visible to `COMPUTE_SHADER`
    /// `SHADER_STORAGE_READ`; the same holds for `visibility`.
    pub unsafe fn record_shading(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        visibility: Option<vk::ImageView>,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        let target = inputs.shade.ok_or_else(|| {
            Error::invalid("shade", "record_shading needs a ShadeTarget to shade into")
        })?;
        if visibility.is_some() && !self.shadows.is_on() {
            return Err(Error::invalid(
                "visibility",
                "self-shadowing is off: nothing to shade with",
            ));
        }
        // SAFETY: this function's contract is `begin`'s.
        let mut w = unsafe { self.begin(cmd, inputs, timestamps)? };
        // SAFETY: this function's contract; `begin` reset the writer's queries.
        unsafe { self.record_builds(cmd, &mut w, inputs.frame_slot) };
        let params = self.shade_params(&target);
        let visibility = match visibility {
            Some(v) => Some(v),
            // SAFETY: this function's contract: the host's hits are visible to storage
            // reads.
            None => unsafe { self.record_shadow(cmd, &mut w, inputs, &params)? },
        };
        // SAFETY: this function's contract: the host's hits and a given visibility are
        // visible to storage reads; `record_shadow`'s visibility is made so by its exit
        // barrier.
        unsafe { self.record_shade(cmd, &mut w, inputs, &target, &params, visibility)? };
        Ok(self.finish(inputs.frame_slot, w, timestamps))
    }

    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_frame(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        camera: Option<DepthCamera>,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        let camera = match &inputs.shade {
            Some(t) => Some(DepthCamera {
                view_proj: t.view_proj,
                eye: t.camera_pos,
            }),
            None => camera,
        };
        if self.depth.is_some() && camera.is_none() {
            return Err(Error::invalid(
                "depth output",
                "the corrected depth needs the frame's camera: pass a ShadeTarget or use \
                 record_with_camera",
            ));
        }
        // SAFETY: this function's contract is `begin`'s.
        let mut w = unsafe { self.begin(cmd, inputs, timestamps)? };
        let slot = inputs.frame_slot;
        // SAFETY: this function's contract; `begin` reset the writer's queries, and each
        // stage follows the state the previous one left (builds, then the corner grid
        // `trace` reads).
        unsafe {
            self.record_builds(cmd, &mut w, slot);
            self.record_corners(cmd, &mut w, inputs);
            self.record_trace(cmd, &mut w, inputs)?;
        }
        if inputs.shade.is_some() || self.depth.is_some() {
            // The hit buffer stays in GENERAL: a memory barrier orders trace's writes
            // before the reads of shadow, shade and hit_depth.
            let hit_barrier = [vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
                .src_access_mask(vk::AccessFlags2::SHADER_STORAGE_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::COMPUTE_SHADER)
                .dst_access_mask(vk::AccessFlags2::SHADER_STORAGE_READ)];
            let dep = vk::DependencyInfo::default().memory_barriers(&hit_barrier);
            // SAFETY: `cmd` is recording outside a render pass (this function's contract).
            unsafe { self.ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
        }
        if let Some(target) = &inputs.shade {
            let params = self.shade_params(target);
            // SAFETY: this function's contract; the hits are visible to storage reads (the
            // memory barrier above), and `shade` reads the visibility `record_shadow`
            // left readable.
            unsafe {
                let visibility = self.record_shadow(cmd, &mut w, inputs, &params)?;
                self.record_shade(cmd, &mut w, inputs, target, &params, visibility)?;
            }
        }
        if let Some(camera) = camera {
            // SAFETY: this function's contract; the hits are visible to storage reads (the
            // memory barrier above, recorded whenever the depth output is on).
            unsafe { self.record_hit_depth(cmd, &mut w, inputs, &camera) };
        }
        Ok(self.finish(slot, w, timestamps))
    }

    /// Checks the frame's inputs and the pass's state, releases what the slot's previous
    /// frame kept alive and starts the frame's timestamps.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn begin(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        timestamps: Timestamps,
    ) -> Result<ScopeWriter> {
        self.check_alive()?;
        let slot = inputs.frame_slot;
        if slot >= self.settings.frames_in_flight {
            return Err(Error::invalid(
                "frame_slot",
                format!(
                    "{slot} is not below frames_in_flight ({})",
                    self.settings.frames_in_flight
                ),
            ));
        }
        let extent = self.settings.extent;
        if inputs.gbuffer.extent != extent {
            return Err(Error::invalid(
                "gbuffer",
                format!(
                    "extent {}x{} differs from the pass's {}x{} (call resize)",
                    inputs.gbuffer.extent.width,
                    inputs.gbuffer.extent.height,
                    extent.width,
                    extent.height
                ),
            ));
        }
        if self.shadows.is_on() && self.shadow.is_none() {
            return Err(Error::invalid(
                "shadows",
                "self-shadowing is on but its resources are missing (a failed set_shadows, \
                 set_method, resize or set_height_map: call set_shadows again)",
            ));
        }
        let (pool, first) = match timestamps {
            Timestamps::Off => (None, 0),
            Timestamps::Owned => (Some(self.owned_pool()?), slot * MAX_QUERIES),
            Timestamps::Host { pool, first_query } => (Some(pool), first_query),
        };
        // Slot `slot`'s previous frame has completed: nothing retired before now is
        // read by it any more.
        self.retired.release(&self.ctx, slot);
        let w = ScopeWriter::new(pool, first, MAX_QUERIES);
        // SAFETY: this function's contract (a live pool with the range).
        unsafe { w.reset(&self.ctx, cmd) };
        Ok(w)
    }

    /// The frame's record: the scopes kept for [`DisplacementPass::timings`].
    fn finish(&mut self, slot: u32, w: ScopeWriter, timestamps: Timestamps) -> RecordedFrame {
        let frame = RecordedFrame {
            passes: w.passes,
            timestamps: w.scopes,
        };
        self.slot_scopes[slot as usize] = if matches!(timestamps, Timestamps::Owned) {
            frame.timestamps.clone()
        } else {
            Vec::new()
        };
        frame
    }

    /// The pending work of earlier changes: the `upload` scope (a new height map, the
    /// height texture refilled for level of detail, material maps) and the `pyramid`
    /// scope (the method's pyramid and the shadow stage's own cell pyramid). Each fill
    /// leaves its image readable by compute shaders.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_builds(&mut self, cmd: vk::CommandBuffer, w: &mut ScopeWriter, slot: u32) {
        let ctx = self.ctx.clone();
        let fill = self.pending_fill.take();
        let material = self.pending_material.take();
        if fill.is_some() || material.is_some() {
            // SAFETY: `record`'s contract: `cmd` is recording outside a render pass on the
            // context's queue family, after `begin` reset the writer's queries (the scope's
            // contract). In the body (inside this block): a `Fill::Upload` staging buffer
            // came with `self.height` from `create_for_upload`, a `Fill::Copy` source is
            // the previous texture of the same map (`create_like`), its level 0
            // sampled-readable as every fill leaves it; the material staging came with
            // `self.material` from `create_for_upload`; the new images have never been
            // accessed. The staging data and sources are retired below until the frames
            // reading them have completed, and the textures live until the pass is
            // destroyed after its frames.
            unsafe {
                w.scope(&ctx, cmd, PassName::Upload, |cmd| {
                    match &fill {
                        Some(Fill::Upload(staging)) => {
                            self.height.record_upload(&ctx, cmd, staging)
                        }
                        Some(Fill::Copy(source)) => self.height.record_copy_from(&ctx, cmd, source),
                        None => {}
                    }
                    if let (Some(textures), Some(staging)) = (&self.material, &material) {
                        textures.record_upload(&ctx, cmd, staging);
                    }
                })
            };
        }
        match fill {
            // Read by this frame's copy only: destroyed when this slot is next recorded.
            Some(Fill::Upload(staging)) => self.retired.retire_for_slot(slot, staging),
            // Read by this frame's copy and by frames in flight in other slots: kept
            // until every slot has been recorded again.
            Some(Fill::Copy(source)) => self.retired.retire(source),
            None => {}
        }
        if let Some(staging) = material {
            self.retired.retire_for_slot(slot, staging);
        }

        let method_pyramid = match (&self.pyramid_pass, &self.pyramid, self.pyramid_built) {
            (Some(pass), Some(pyramid), false) => Some((pass, pyramid)),
            _ => None,
        };
        let shadow_pyramid = match &self.shadow {
            Some(s) if !s.own_built => s.own_pyramid.as_ref().map(|(pass, p)| (pass, p)),
            _ => None,
        };
        if method_pyramid.is_some() || shadow_pyramid.is_some() {
            // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
            // queries reset by `begin`). In the body (inside this block): the height texture
            // is sampled-readable (filled in the upload scope above or by an earlier frame);
            // a pyramid is built only while unbuilt, so no frame has read it; the pass and
            // pyramids live until they are retired after the frames that use them.
            unsafe {
                w.scope(&ctx, cmd, PassName::Pyramid, |cmd| {
                    for (pass, pyramid) in method_pyramid.into_iter().chain(shadow_pyramid) {
                        pass.record(&ctx, cmd, &self.height, pyramid);
                    }
                })
            };
        }
        self.pyramid_built = self.pyramid.is_some();
        if let Some(s) = &mut self.shadow {
            s.own_built = s.own_pyramid.is_some();
        }
        // SAFETY: `record`'s contract, as above.
        unsafe { self.record_cone(w, cmd) };
    }

    /// The `cone` scope (cone methods): the cone map from the (built) cell pyramid, when
    /// unbuilt.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_cone(&mut self, w: &mut ScopeWriter, cmd: vk::CommandBuffer) {
        let (Some(pass), Some(cone), Some(pyramid), false) = (
            &self.cone_pass,
            &self.cone,
            self.pyramid.as_ref().filter(|_| self.pyramid_built),
            self.cone_built,
        ) else {
            return;
        };
        let ctx = &*self.ctx;
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body: the height texture and the pyramid are
        // sampled-readable (their fill and build, recorded before this in the same command
        // buffer or by an earlier frame); the cone map is built only while unbuilt, so no
        // frame has read it; the pass, pyramid and map live until they are retired after
        // the frames that use them.
        unsafe {
            w.scope(ctx, cmd, PassName::Cone, |cmd| {
                pass.record(ctx, cmd, &self.height, pyramid, cone);
            })
        };
        self.cone_built = true;
        // What only the build read (a relaxed map's falls pyramids) goes once this
        // command buffer's frame has executed.
        if let Some(cone) = &mut self.cone {
            let scratch = cone.take_scratch();
            if !scratch.is_empty() {
                self.retired.retire(scratch);
            }
        }
    }

    /// The DIG corner pass (DIG methods only): the slot's grid discarded -> storage
    /// write, the pass, then -> sampled by `trace`.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_corners(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
    ) {
        let ctx = &*self.ctx;
        let grid = self.corners.get(inputs.frame_slot as usize);
        let (Some(pass), Some(grid)) = (&self.corner_pass, grid) else {
            return;
        };
        let image = &grid.image;
        // The slot's previous frame (the last reader) has completed: discarded.
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the grid is
        // the slot's, alive until retired after the slot's frames, and by the slot
        // contract its last reader has completed, so it may be discarded.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                image,
                DISCARD_COMPUTE,
                Access::COMPUTE_STORAGE_WRITE,
            )
        };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the host's G-buffer
        // is in its entry state (sampled-readable, `record`'s contract), the height
        // texture sampled-readable (its fill), the grid in `GENERAL` for storage writes
        // (the transition above) and made for this extent.
        unsafe {
            w.scope(ctx, cmd, PassName::DigCorners, |cmd| {
                pass.record(
                    ctx,
                    cmd,
                    inputs.gbuffer,
                    &self.height,
                    grid,
                    self.settings.params.steps,
                )
            })
        };
        // SAFETY: `record`'s contract; the grid is in `GENERAL`, written by the corner
        // pass.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                image,
                Access::COMPUTE_STORAGE_WRITE,
                Access::COMPUTE_SAMPLED,
            )
        };
    }

    /// The method into the hit buffer (which enters discarded in `GENERAL`: the host's
    /// barrier).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_trace(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let hit = ViewRef {
            view: inputs.hit,
            extent: self.settings.extent,
        };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the G-buffer is in
        // its entry state and the hit buffer discarded in `GENERAL` (the host's barriers,
        // `record`'s contract); the height texture and pyramid are sampled-readable
        // (their builds), the slot's corner grid too (`record_corners`).
        unsafe {
            w.scope(ctx, cmd, PassName::Trace, |cmd| {
                self.trace.record(
                    ctx,
                    cmd,
                    TraceInputs {
                        gbuffer: inputs.gbuffer,
                        height: &self.height,
                        hit,
                        pyramid: self.pyramid.as_ref(),
                        corners: self.corners.get(inputs.frame_slot as usize),
                        cone: self.cone.as_ref(),
                    },
                    &self.settings.params,
                    self.settings.depth_scale,
                )
            })
        }
    }

    /// The shading constants of a frame lit as `target` says.
    fn shade_params(&self, target: &ShadeTarget) -> ShadeParams {
        let e = self.settings.extent;
        ShadeParams::new(
            target.view_proj,
            target.camera_pos,
            target.light_dir,
            target.light_intensity,
            [e.width, e.height],
            self.height.size(),
            self.settings.depth_scale,
        )
    }

    /// Self-shadowing (when on): the slot's visibility image discarded -> storage write,
    /// the `shadow` pass over the hits, then -> storage read by `shade`. Returns the
    /// visibility view (`None` when self-shadowing is off).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits are visible to storage reads.
    unsafe fn record_shadow(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        params: &ShadeParams,
    ) -> Result<Option<vk::ImageView>> {
        let ctx = &*self.ctx;
        let Some(stage) = &self.shadow else {
            return Ok(None);
        };
        let image = &stage.visibility[inputs.frame_slot as usize];
        // The slot's previous frame (the last reader) has completed: discarded.
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the
        // visibility image is the slot's, alive until retired after the slot's frames,
        // and by the slot contract its last reader has completed, so it may be discarded.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                image,
                DISCARD_COMPUTE,
                Access::COMPUTE_STORAGE_WRITE,
            )
        };
        let shadow_params = ShadowPass::params(
            &self.shadows,
            self.settings.params.steps,
            params,
            self.settings.addressing,
        );
        let pyramid = match &stage.own_pyramid {
            Some((_, p)) => Some(p),
            None => self.pyramid.as_ref(),
        };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits are visible
        // to storage reads (this function's contract), the G-buffer is in its entry
        // state, the height texture and pyramid sampled-readable (their builds), the
        // visibility in `GENERAL` for storage writes (the transition above).
        unsafe {
            w.scope(ctx, cmd, PassName::Shadow, |cmd| {
                stage.pass.record(
                    ctx,
                    cmd,
                    ShadowInputs {
                        hit: inputs.hit,
                        gbuffer: inputs.gbuffer,
                        height: &self.height,
                        pyramid,
                        visibility: image.view_ref(),
                    },
                    &shadow_params,
                )
            })?
        };
        // SAFETY: `record`'s contract; the visibility is in `GENERAL`, written by the
        // shadow pass.
        unsafe {
            sync::transition(
                ctx,
                cmd,
                image,
                Access::COMPUTE_STORAGE_WRITE,
                Access::COMPUTE_STORAGE_READ,
            )
        };
        Ok(Some(image.view))
    }

    /// `shade`: the hits (and the visibility) lit into the target's colour image, which
    /// enters discarded in `GENERAL` (the host's barrier).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits and the visibility are visible to
    /// storage reads.
    unsafe fn record_shade(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        target: &ShadeTarget,
        params: &ShadeParams,
        visibility: Option<vk::ImageView>,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits and the
        // visibility are visible to storage reads (this function's contract), the
        // G-buffer is in its entry state and the colour image discarded in `GENERAL` (the
        // host's barriers), the height texture and material maps sampled-readable (their
        // uploads).
        unsafe {
            w.scope(ctx, cmd, PassName::Shade, |cmd| {
                self.shade.record(
                    ctx,
                    cmd,
                    ShadeInputs {
                        hit: inputs.hit,
                        gbuffer: inputs.gbuffer,
                        height: &self.height,
                        material: self.material.as_ref(),
                        color: ViewRef {
                            view: target.color,
                            extent: self.settings.extent,
                        },
                        visibility,
                    },
                    params,
                )
            })
        }
    }

    /// The corrected depth: the slot's image discarded (the host may have left it in any
    /// layout) -> storage write, then `hit_depth`.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits are visible to storage reads.
    unsafe fn record_hit_depth(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        camera: &DepthCamera,
    ) {
        let ctx = &*self.ctx;
        let Some(depth) = &self.depth else {
            return;
        };
        let image = &depth.images[inputs.frame_slot as usize];
        // Discarded: the host's reads of the slot's previous frame (any stage) have
        // completed by the slot contract; the barrier also orders them (WAR).
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the image is
        // the slot's, alive until retired after the slot's frames, and may be discarded
        // (the slot contract).
        unsafe { sync::transition(ctx, cmd, image, DISCARD_ANY, Access::COMPUTE_STORAGE_WRITE) };
        let e = self.settings.extent;
        let params = crate::abi::HitDepthParams::new(
            camera.view_proj,
            camera.eye,
            [e.width, e.height],
            self.settings.depth_scale,
        );
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits are visible
        // to storage reads (this function's contract), the G-buffer is in its entry
        // state, the corrected depth in `GENERAL` for storage writes (the transition
        // above).
        unsafe {
            w.scope(ctx, cmd, PassName::HitDepth, |cmd| {
                depth.pass.record(
                    ctx,
                    cmd,
                    HitDepthInputs {
                        hit: inputs.hit,
                        gbuffer: inputs.gbuffer,
                        hit_depth: image.view_ref(),
                    },
                    &params,
                )
            })
        };
    }
}
