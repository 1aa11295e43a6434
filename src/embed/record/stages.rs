//! The per-frame stages of a record, one method each with the barriers it places:
//! `classify`, the DIG corners, `trace`, `shadow`, `shade`, `hit_depth` and `motion`.

use super::*;

impl DisplacementPass {
    /// The `classify` scope: the slot's tile lists (and, with `write_hits`, the hit
    /// texels of pixels without displacement; with `hit_depth`, their corrected depth).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `hit_depth` (the slot's corrected depth) is in
    /// `GENERAL`, earlier accesses ordered before compute-shader storage writes.
    pub(super) unsafe fn record_classify(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        write_hits: bool,
        hit_depth: Option<vk::ImageView>,
    ) {
        let ctx = &*self.ctx;
        let lists = &self.slots[inputs.frame_slot as usize].tiles;
        let mut live: Vec<bool> = self.materials.iter().map(Option::is_some).collect();
        live.resize(lists.materials() as usize, false);
        let classify = ClassifyInputs {
            depth: inputs.gbuffer.depth.view,
            tangent: inputs.gbuffer.tangent.view,
            hit: ViewRef {
                view: inputs.hit.view,
                extent: self.frame.extent,
            },
            write_hits,
            hit_depth,
            lists,
            live: &live,
        };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body: the G-buffer is in its entry state, the
        // hit buffer in `GENERAL` (the host's barrier), the corrected depth transitioned by
        // the caller; the slot's lists were last read by the slot's previous frame, which
        // has completed (the slot contract).
        unsafe {
            w.scope(ctx, cmd, PassName::Classify, |cmd| {
                self.classify.record(ctx, cmd, &classify)
            })
        };
    }

    /// The DIG corner pass of each DIG material: its slot's grid discarded -> storage
    /// write, the pass, then -> sampled by `trace`.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    pub(super) unsafe fn record_corners(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
    ) {
        let ctx = &*self.ctx;
        let slot = inputs.frame_slot as usize;
        let Some(pass) = &self.corner_pass else {
            return;
        };
        let grids: Vec<_> = self
            .live(inputs.frame_slot)
            .into_iter()
            .filter_map(|(t, m, map)| Some((t.material, m.corners.get(slot)?, map, m)))
            .collect();
        if grids.is_empty() {
            return;
        }
        for (_, grid, _, _) in &grids {
            // The slot's previous frame (the last reader) has completed: discarded.
            // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the grid
            // is the slot's, alive until retired after the slot's frames, and by the slot
            // contract its last reader has completed, so it may be discarded.
            unsafe {
                sync::transition(
                    ctx,
                    cmd,
                    &grid.image,
                    DISCARD_COMPUTE,
                    Access::COMPUTE_STORAGE_WRITE,
                )
            };
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the host's G-buffer
        // is in its entry state (sampled-readable, `record`'s contract), the height
        // textures sampled-readable (their fill), the grids in `GENERAL` for storage writes
        // (the transitions above) and made for this extent.
        unsafe {
            w.scope(ctx, cmd, PassName::DigCorners, |cmd| {
                for (material, grid, map, m) in &grids {
                    pass.record(
                        ctx,
                        cmd,
                        inputs.gbuffer,
                        &map.texture,
                        grid,
                        CornerRun {
                            steps: m.settings.params.steps,
                            material: *material,
                        },
                    );
                }
            })
        };
        for (_, grid, _, _) in &grids {
            // SAFETY: `record`'s contract; the grid is in `GENERAL`, written by the corner
            // pass.
            unsafe {
                sync::transition(
                    ctx,
                    cmd,
                    &grid.image,
                    Access::COMPUTE_STORAGE_WRITE,
                    Access::COMPUTE_SAMPLED,
                )
            };
        }
    }

    /// Each material's method into the hit buffer over its tiles (the buffer enters in
    /// `GENERAL`: the host's barrier; `classify`'s writes ordered before by its exit
    /// barrier).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    pub(super) unsafe fn record_trace(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let hit = ViewRef {
            view: inputs.hit.view,
            extent: self.frame.extent,
        };
        let slot = inputs.frame_slot as usize;
        let live = self.live(inputs.frame_slot);
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the G-buffer is in
        // its entry state and the hit buffer in `GENERAL` (the host's barriers, `record`'s
        // contract); the height textures, pyramids and cone maps are sampled-readable
        // (their builds), the slot's corner grids too (`record_corners`); the tile lists
        // are the classification's.
        unsafe {
            w.scope(ctx, cmd, PassName::Trace, |cmd| {
                for (tiles, m, map) in &live {
                    let s = &m.settings;
                    let needs = s.method.needs();
                    let Some(trace) = self.traces.iter().find(|t| t.method() == s.method) else {
                        return Err(Error::Internal(format!(
                            "no trace pipeline for {}",
                            s.method.name()
                        )));
                    };
                    trace.record(
                        ctx,
                        cmd,
                        TraceInputs {
                            gbuffer: inputs.gbuffer,
                            height: &map.texture,
                            hit,
                            pyramid: needs.pyramid.and_then(|k| map.pyramid(k)),
                            corners: m.corners.get(slot),
                            cone: needs.cone.and_then(|k| map.cone(k)),
                            tiles: *tiles,
                        },
                        &s.params,
                        s.depth_scale,
                    )?;
                }
                Ok(())
            })
        }
    }

    /// The shading constants of a frame lit as `target` says, for a material on `map`.
    pub(super) fn shade_params(
        &self,
        target: &ShadeTarget,
        m: &MaterialEntry,
        map: &MapEntry,
    ) -> ShadeParams {
        let e = self.frame.extent;
        ShadeParams::new(
            target.view_proj,
            target.camera_pos,
            target.light_dir,
            target.light_intensity,
            [e.width, e.height],
            map.texture.size(),
            m.settings.depth_scale,
        )
    }

    /// Self-shadowing (when on): the slot's visibility image discarded -> storage write,
    /// the `shadow` pass of each material over its hits, then -> storage read by `shade`.
    /// Returns the visibility view (`None` when self-shadowing is off).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits are visible to storage reads.
    pub(super) unsafe fn record_shadow(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        target: &ShadeTarget,
    ) -> Result<Option<vk::ImageView>> {
        let ctx = &*self.ctx;
        let Some(image) = &self.slots[inputs.frame_slot as usize].visibility else {
            return Ok(None);
        };
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
        let live = self.live(inputs.frame_slot);
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits are visible
        // to storage reads (this function's contract), the G-buffer is in its entry
        // state, the height textures and pyramids sampled-readable (their builds), the
        // visibility in `GENERAL` for storage writes (the transition above).
        unsafe {
            w.scope(ctx, cmd, PassName::Shadow, |cmd| {
                for (tiles, m, map) in &live {
                    let s = &m.settings;
                    let trace = ShadowTrace::for_method(self.shadows.mode, s.method);
                    let Some(pass) = self.shadow_passes.iter().find(|p| p.trace() == trace) else {
                        return Err(Error::Internal("no shadow pipeline".into()));
                    };
                    let params = ShadowPass::params(
                        &self.shadows,
                        s.params.steps,
                        &self.shade_params(target, m, map),
                        s.addressing,
                    );
                    pass.record(
                        ctx,
                        cmd,
                        ShadowInputs {
                            hit: inputs.hit.view,
                            gbuffer: inputs.gbuffer,
                            height: &map.texture,
                            pyramid: map.pyramid(PyramidKind::Cell),
                            visibility: image.view_ref(),
                            tiles: *tiles,
                        },
                        &params,
                    )?;
                }
                Ok(())
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

    /// `shade`: each material's hits (and the visibility) lit into the target's colour
    /// image, which enters in `GENERAL` with the host's colour (kept where nothing is
    /// displaced; the host's barrier).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits and the visibility are visible to
    /// storage reads.
    pub(super) unsafe fn record_shade(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        target: &ShadeTarget,
        visibility: Option<vk::ImageView>,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let live = self.live(inputs.frame_slot);
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits and the
        // visibility are visible to storage reads (this function's contract), the
        // G-buffer is in its entry state and the colour image in `GENERAL` (the host's
        // barriers), the height textures and material maps sampled-readable (their
        // uploads).
        unsafe {
            w.scope(ctx, cmd, PassName::Shade, |cmd| {
                for (tiles, m, map) in &live {
                    self.shade.record(
                        ctx,
                        cmd,
                        ShadeInputs {
                            hit: inputs.hit.view,
                            gbuffer: inputs.gbuffer,
                            height: &map.texture,
                            material: m.shading.as_ref(),
                            color: ViewRef {
                                view: target.color.view,
                                extent: self.frame.extent,
                            },
                            visibility,
                            tiles: *tiles,
                        },
                        &self.shade_params(target, m, map),
                    )?;
                }
                Ok(())
            })
        }
    }

    /// The corrected depth of each material's pixels (`classify` wrote the others').
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits are visible to storage reads; the slot's
    /// image is in `GENERAL`, earlier accesses ordered before storage writes.
    pub(super) unsafe fn record_hit_depth(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        camera: &DepthCamera,
    ) {
        let ctx = &*self.ctx;
        let (Some(depth), Some(image)) = (
            &self.depth,
            &self.slots[inputs.frame_slot as usize].hit_depth,
        ) else {
            return;
        };
        let e = self.frame.extent;
        let live = self.live(inputs.frame_slot);
        // The frame's matrices once; each material sets its depth scale.
        let base =
            crate::abi::HitDepthParams::new(camera.view_proj, camera.eye, [e.width, e.height], 0.0);
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits are visible
        // to storage reads (this function's contract), the G-buffer is in its entry
        // state, the corrected depth in `GENERAL` for storage writes (this function's
        // contract).
        unsafe {
            w.scope(ctx, cmd, PassName::HitDepth, |cmd| {
                for (tiles, m, _) in &live {
                    let params = crate::abi::HitDepthParams {
                        depth_scale: m.settings.depth_scale,
                        ..base
                    };
                    depth.record(
                        ctx,
                        cmd,
                        HitDepthInputs {
                            hit: inputs.hit.view,
                            gbuffer: inputs.gbuffer,
                            hit_depth: image.view_ref(),
                            tiles: *tiles,
                        },
                        &params,
                    );
                }
            })
        };
    }

    /// Records `motion` (with the motion output on): one dispatch per live material,
    /// writing the host's motion image in place.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; the hits are visible to compute-shader storage
    /// reads (the barrier after `trace`), and the host's motion image is in `GENERAL`, its
    /// writes visible to compute-shader storage reads and writes (the entry contract).
    pub(super) unsafe fn record_motion(
        &mut self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        inputs: &FrameInputs,
        camera: &DepthCamera,
    ) {
        let ctx = &*self.ctx;
        let (Some(pass), Some(frame), Some(settings)) =
            (&self.motion, &inputs.motion, &self.motion_on)
        else {
            return;
        };
        let e = self.frame.extent;
        let live = self.live(inputs.frame_slot);
        // The frame's matrices once; each material sets its depth scale.
        let base = crate::abi::MotionParams::new(
            camera.view_proj,
            camera.eye,
            frame.previous.view_proj,
            [e.width, e.height],
            0.0,
            settings,
        );
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the hits are visible
        // to storage reads and the motion image is in `GENERAL` with the host's writes
        // visible (this function's contract), the G-buffer in its entry state.
        unsafe {
            w.scope(ctx, cmd, PassName::Motion, |cmd| {
                for (tiles, m, _) in &live {
                    let params = crate::abi::MotionParams {
                        depth_scale: m.settings.depth_scale,
                        ..base
                    };
                    pass.record(
                        ctx,
                        cmd,
                        MotionInputs {
                            hit: inputs.hit.view,
                            gbuffer: inputs.gbuffer,
                            motion: frame.image.view,
                            tiles: *tiles,
                        },
                        &params,
                    );
                }
            })
        };
    }
}
