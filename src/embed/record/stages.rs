//! The per-frame stages of a record, one method each: `classify`, the DIG corners,
//! `trace`, `shadow`, `shade`, `hit_depth` and `motion`. Each declares its dispatches to
//! the frame graph, which records the barriers they need before the stage.

use super::*;
use crate::passes::trace::WalkStep;

impl DisplacementPass {
    /// The `classify` scope: the slot's tile lists (and, with `write_hits`, the hit
    /// texels of pixels without displacement, with them their corrected depth and
    /// iteration count when those outputs are on).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_classify(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        write_hits: bool,
        listed: Option<&crate::passes::classify::ListedTiles>,
    ) -> Result<()> {
        let slot = inputs.frame_slot;
        let hit_depth_image = self.hit_depth(slot).filter(|_| write_hits);
        let iterations_image = self.iterations(slot).filter(|_| write_hits);
        let hit_depth = hit_depth_image.map(|i| i.view);
        let iterations = iterations_image.map(|i| i.view);
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let lists = &self.slots[inputs.frame_slot as usize].tiles;
        let live: Vec<bool> = self.materials.iter().map(Option::is_some).collect();
        let classify = ClassifyInputs {
            depth: inputs.gbuffer.depth.view,
            frame: inputs.gbuffer.frame.view,
            hit: inputs.hit.views(),
            extent: self.frame.extent,
            write_hits,
            hit_depth,
            iterations,
            lists,
            live: &live,
        };
        let skip: &[Res] = if write_hits {
            &[]
        } else {
            &[Res::HitUv, Res::HitHeight]
        };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`; a list as `record_listed` says). In the body: the
        // graph's barriers order the reset (and a listed record's clears, of the slot's
        // images with TRANSFER_DST usage) after the lists' and images' last users (the
        // slot's previous frame), each step after the reset, the steps before it and the
        // earlier accesses of its images.
        unsafe {
            w.scope(ctx, cmd, PassName::Classify, |cmd| {
                g.declare(Res::Args, super::super::graph::ARGS_RESET)?;
                // A listed record: the summaries reset, the slot's iteration counts and
                // corrected depth cleared (the listed tiles' are written below).
                let clears: Vec<(Res, &crate::gpu::Image)> = [
                    (Res::Iterations, iterations_image),
                    (Res::HitDepth, hit_depth_image),
                ]
                .into_iter()
                .filter_map(|(r, i)| Some((r, i?)))
                .filter(|_| listed.is_some())
                .collect();
                if listed.is_some() {
                    g.declare(Res::Tiles, super::super::graph::ARGS_RESET)?;
                }
                for (res, _) in &clears {
                    g.declare(*res, crate::gpu::sync::Access::TRANSFER_WRITE)?;
                }
                g.flush(ctx, cmd, PassName::Classify)?;
                self.classify.record_reset(ctx, cmd, &classify);
                if listed.is_some() {
                    self.classify.record_listed_reset(ctx, cmd, &classify);
                }
                for (_, image) in &clears {
                    ctx.device().cmd_clear_color_image(
                        cmd,
                        image.raw,
                        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                        &vk::ClearColorValue::default(),
                        &[image.range()],
                    );
                }
                for step in ClassifyStep::ALL {
                    let bindings = self.classify.bindings_of(
                        step,
                        hit_depth.is_some(),
                        iterations.is_some(),
                        listed.is_some(),
                    )?;
                    g.dispatch(bindings, 0, skip)?;
                    if step == ClassifyStep::Mixed {
                        g.declare(Res::Args, super::super::graph::INDIRECT)?;
                    }
                    g.flush(ctx, cmd, PassName::Classify)?;
                    self.classify
                        .record_step(ctx, cmd, &classify, step, listed)?;
                }
                Ok(())
            })
        }
    }

    /// The DIG corner pass of each DIG material into its slot's grid (which `trace` then
    /// samples).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_corners(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let slot = inputs.frame_slot as usize;
        let Some(pass) = &self.corner_pass else {
            return Ok(());
        };
        let grids: Vec<_> = self
            .live(inputs.frame_slot)
            .into_iter()
            .filter_map(|(t, m, map)| {
                let grid = self.slots[slot].corner_grid(t.material as usize)?;
                Some((t.material, grid, map, m))
            })
            .collect();
        if grids.is_empty() {
            return Ok(());
        }
        for (material, _, _, _) in &grids {
            g.dispatch(pass.bindings(), *material, &[])?;
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the grids
        // are the slot's (alive until retired after the slot's frames; their last reader,
        // the slot's previous frame, has completed).
        unsafe { g.flush(ctx, cmd, PassName::DigCorners)? };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the G-buffer in its entry state, the height
        // textures sampled-readable, the grids in `GENERAL` for storage writes); the grids
        // are made for this extent.
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
                    )?;
                }
                Ok(())
            })
        }
    }

    /// Each material's method into the hit images (and the slot's iteration counts)
    /// over its tiles.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_trace(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        camera: Option<&DepthCamera>,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let view = camera.map(|c| crate::passes::trace::TraceView::new(c.view_proj, c.eye));
        let hit = inputs.hit.views();
        let slot = inputs.frame_slot as usize;
        let iterations = self.slots[slot].iterations.as_ref().map(|i| i.view);
        let walk_list = self.slots[slot].walk_list.as_ref();
        let mut live = Vec::new();
        let mut walks = Vec::new();
        for (tiles, m, map) in self.live(inputs.frame_slot) {
            let method = m.settings.method;
            let key = (
                method,
                m.curved && method.traces_curved(),
                iterations.is_some(),
            );
            let Some(trace) = self.traces.iter().find(|t| t.key() == key) else {
                return Err(Error::Internal(format!(
                    "no trace pipeline for {}",
                    method.name()
                )));
            };
            // A material whose meshes the pass walks (`exact` traced curved, given meshes)
            // is traced by the walk's four steps below instead (unless a level-of-detail
            // blend keeps its curved trace).
            let walked = m.curved
                && view.is_some()
                && trace.walk_bindings(WalkStep::First).is_some()
                && self.walk.triangles > 0
                && walk_list.is_some()
                && m.settings.params.lod_threshold.is_none();
            if walked {
                walks.push((tiles, m, map, trace));
                continue;
            }
            g.dispatch(trace.bindings(), tiles.material, &[])?;
            live.push((tiles, m, map, trace));
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass).
        unsafe { g.flush(ctx, cmd, PassName::Trace)? };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the G-buffer in its entry state, the hit images
        // and tile lists ordered after the classification, the maps sampled-readable, the
        // slot's corner grids sampled-readable after `record_corners`).
        // (A closure whose result borrows its map argument: its lifetime named.)
        fn borrowing<'a, F>(f: F) -> F
        where
            F: Fn(&MaterialTiles, &MaterialEntry, &'a MapEntry) -> TraceInputs<'a>,
        {
            f
        }
        let inputs_of = borrowing(|tiles: &MaterialTiles, m: &MaterialEntry, map| {
            let needs = m.settings.method.needs();
            TraceInputs {
                gbuffer: inputs.gbuffer,
                height: &map.texture,
                hit,
                iterations,
                extent: self.frame.extent,
                pyramid: needs.pyramid.and_then(|k| map.pyramid(k)),
                corners: self.slots[slot].corner_grid(tiles.material as usize),
                cone: needs.cone.and_then(|k| map.cone(k)),
                tiles: *tiles,
                curved: view.filter(|_| m.curved),
                walk: Some(self.walk.view),
                walk_list: walk_list.map(|b| b.raw),
            }
        });
        // The mesh walks, after the other traces: per material, the walk list's reset,
        // the first trace (flat, listing the pixels it cannot tell are the walk's), the
        // overlap step and the triage (which read its hit heights; the triage lists the
        // pixels to walk) and the walk over the pixels listed for it, each declared and flushed after the one before, so the graph orders
        // them after each other (and the walk list's reuse by the next material after
        // the walk before).
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the G-buffer in its entry state, the hit images
        // and tile lists ordered after the classification, the maps sampled-readable, the
        // slot's corner grids sampled-readable after `record_corners`); each walk step's
        // flush orders it after the steps before.
        unsafe {
            w.scope(ctx, cmd, PassName::Trace, |cmd| {
                for (tiles, m, map, trace) in &live {
                    let s = &m.settings;
                    trace.record(ctx, cmd, inputs_of(tiles, m, map), &s.params, s.depth_scale)?;
                }
                let Some(list) = walk_list else {
                    return Ok(());
                };
                for (tiles, m, map, trace) in &walks {
                    let s = &m.settings;
                    g.declare(Res::WalkList, super::super::graph::ARGS_RESET)?;
                    g.flush(ctx, cmd, PassName::Trace)?;
                    ctx.device().cmd_update_buffer(
                        cmd,
                        list.raw,
                        0,
                        bytemuck::cast_slice(&crate::passes::trace::WALK_LIST_RESET),
                    );
                    for step in WalkStep::ALL {
                        let Some(bindings) = trace.walk_bindings(step) else {
                            continue;
                        };
                        g.dispatch(bindings, tiles.material, &[])?;
                        g.flush(ctx, cmd, PassName::Trace)?;
                        trace.record_walk(
                            step,
                            ctx,
                            cmd,
                            inputs_of(tiles, m, map),
                            &s.params,
                            s.depth_scale,
                        )?;
                    }
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

    /// Self-shadowing (when on): the `shadow` pass of each material over its hits into
    /// the slot's visibility image, which `shade` then reads. Returns the visibility view
    /// (`None` when self-shadowing is off).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_shadow(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        target: &ShadeTarget,
    ) -> Result<Option<vk::ImageView>> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let Some(image) = &self.slots[inputs.frame_slot as usize].visibility else {
            return Ok(None);
        };
        let mut live = Vec::new();
        for (tiles, m, map) in self.live(inputs.frame_slot) {
            let trace = ShadowTrace::for_method(self.shadows.mode, m.settings.method);
            let Some(pass) = self.shadow_passes.iter().find(|p| p.trace() == trace) else {
                return Err(Error::Internal("no shadow pipeline".into()));
            };
            g.dispatch(pass.bindings(), tiles.material, &[])?;
            live.push((tiles, m, map, pass));
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the
        // visibility image is the slot's, alive until retired after the slot's frames, and
        // its last reader has completed (the slot contract).
        unsafe { g.flush(ctx, cmd, PassName::Shadow)? };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the hits visible to storage reads, the
        // visibility in `GENERAL` for storage writes, the maps sampled-readable).
        unsafe {
            w.scope(ctx, cmd, PassName::Shadow, |cmd| {
                for (tiles, m, map, pass) in &live {
                    let s = &m.settings;
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
                            hit: inputs.hit.views(),
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
        Ok(Some(image.view))
    }

    /// `shade`: each material's hits (and the visibility) lit into the target's colour
    /// image, which enters in `GENERAL` with the host's colour (kept where nothing is
    /// displaced; the host's barrier).
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph, in which
    /// `visibility` (if any) is [`Res::Visibility`].
    pub(super) unsafe fn record_shade(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        target: &ShadeTarget,
        visibility: Option<vk::ImageView>,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let live = self.live(inputs.frame_slot);
        for (tiles, _, _) in &live {
            g.dispatch(self.shade.bindings(), tiles.material, &[])?;
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass).
        unsafe { g.flush(ctx, cmd, PassName::Shade)? };
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the hits and the visibility visible to storage
        // reads, the colour image in `GENERAL` with the host's colour, the G-buffer in its
        // entry state, the maps sampled-readable).
        unsafe {
            w.scope(ctx, cmd, PassName::Shade, |cmd| {
                for (tiles, m, map) in &live {
                    self.shade.record(
                        ctx,
                        cmd,
                        ShadeInputs {
                            hit: inputs.hit.views(),
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
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_hit_depth(
        &self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        camera: &DepthCamera,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let (Some(depth), Some(image)) = (
            &self.depth,
            &self.slots[inputs.frame_slot as usize].hit_depth,
        ) else {
            return Ok(());
        };
        let e = self.frame.extent;
        let live = self.live(inputs.frame_slot);
        for (tiles, _, _) in &live {
            g.dispatch(depth.bindings(), tiles.material, &[])?;
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass); the image is
        // the slot's, alive until retired after the slot's frames.
        unsafe { g.flush(ctx, cmd, PassName::HitDepth)? };
        // The frame's matrices once; each material sets its depth scale.
        let base =
            crate::abi::HitDepthParams::new(camera.view_proj, camera.eye, [e.width, e.height], 0.0);
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the hits visible to storage reads, the
        // corrected depth in `GENERAL` after the classification's writes, the G-buffer in
        // its entry state).
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
                            hit: inputs.hit.views(),
                            gbuffer: inputs.gbuffer,
                            hit_depth: image.view_ref(),
                            tiles: *tiles,
                        },
                        &params,
                    )?;
                }
                Ok(())
            })
        }
    }

    /// Records `motion` (with the motion output on): one dispatch per live material,
    /// writing the host's motion image in place.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; `g` is this record's graph.
    pub(super) unsafe fn record_motion(
        &mut self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        g: &mut FrameGraph,
        inputs: &FrameInputs,
        camera: &DepthCamera,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        let (Some(pass), Some(frame), Some(settings)) =
            (&self.motion, &inputs.motion, &self.motion_on)
        else {
            return Ok(());
        };
        let e = self.frame.extent;
        let live = self.live(inputs.frame_slot);
        for (tiles, _, _) in &live {
            g.dispatch(pass.bindings(), tiles.material, &[])?;
        }
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass).
        unsafe { g.flush(ctx, cmd, PassName::Motion)? };
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
        // queries reset by `begin`). In the body (inside this block): the graph's barriers
        // above made every binding ready (the hits visible to storage reads, the motion
        // image in `GENERAL` with the host's writes visible, the G-buffer in its entry
        // state).
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
                            hit: inputs.hit.views(),
                            gbuffer: inputs.gbuffer,
                            motion: frame.image.view,
                            tiles: *tiles,
                        },
                        &params,
                    )?;
                }
                Ok(())
            })
        }
    }
}
