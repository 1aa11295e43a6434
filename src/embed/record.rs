//! Recording a frame: `[upload] -> [pyramid] -> [cone] -> classify -> [dig_corners] -> trace
//! -> [shadow] -> [shade] -> [hit_depth] -> [motion]`. Each per-frame stage declares what
//! its dispatches read and write (their shaders' reflected bindings) to the record's
//! [`FrameGraph`], which places the barriers between the stages (`graph.rs`); a
//! per-material stage records one indirect dispatch per live material over the material's
//! tiles, all in the stage's one timestamp scope.

use super::graph::{Entry, FrameGraph, HOST_VISIBILITY, Res};
use super::plan::{Fill, MapEntry, MaterialEntry};
use super::{
    DepthCamera, DisplacementPass, FrameInputs, MAX_QUERIES, RecordedFrame, ShadeTarget, Timestamps,
};
use crate::abi::ShadeParams;
use crate::error::{Error, Result};
use crate::gpu::ViewRef;
use crate::method::PyramidKind;
use crate::passes::PassName;
use crate::passes::classify::{ClassifyInputs, ClassifyStep, MaterialTiles};
use crate::passes::dig::CornerRun;
use crate::passes::hit_depth::HitDepthInputs;
use crate::passes::motion::MotionInputs;
use crate::passes::shade::ShadeInputs;
use crate::passes::shadow::{ShadowInputs, ShadowPass, ShadowTrace};
use crate::passes::trace::TraceInputs;
use crate::timing::ScopeWriter;
use ash::vk;

mod stages;

impl DisplacementPass {
    /// Releases what waits for `slot` without recording a frame in it: for a host that
    /// leaves a slot unrecorded for a while (the standalone renderer's behind layer, which
    /// records slot 1, turned off), so that what the pass retires is destroyed once the
    /// other slots have been recorded again instead of waiting for `slot`'s next frame.
    ///
    /// # Safety
    /// Every frame recorded in `slot` has completed on the GPU (the slot contract as for
    /// a record of `slot`), and `slot` is below `frames_in_flight`.
    pub unsafe fn release_slot(&mut self, slot: u32) -> Result<()> {
        let ctx = self.context()?.clone();
        // SAFETY: this function's contract; what was retired since a preparation that no
        // frame has followed yet keeps waiting for every slot (as in a record).
        unsafe {
            match self.prepared_mark {
                Some(mark) => self.retired.release_holding(&ctx, slot, mark),
                None => self.retired.release(&ctx, slot),
            }
        };
        Ok(())
    }

    /// Records the pass into the host's command buffer `cmd`: the uploads (height map,
    /// material maps) and the pyramid build when pending, the DIG corner pass, `trace`
    /// into `inputs.hit` (and, with the iteration output on, the slot's iteration
    /// counts) and, with `inputs.shade`, `[shadow] -> shade`, and with the
    /// corrected depth on, `hit_depth`; each pass between debug labels and, unless
    /// `timestamps` is [`Timestamps::Off`], timestamps. Returns the passes and their
    /// queries.
    ///
    /// Resources that must not be in use by the GPU: those of `inputs.frame_slot` (its
    /// corner grid and owned timestamp range, the hit images and colour image passed in)
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
        unsafe { self.record_frame(cmd, inputs, None, timestamps, None) }
    }

    /// [`DisplacementPass::record`] of a frame whose geometry lies only in `listed` tiles
    /// (the standalone renderer's behind layer: its missed tiles): `classify` runs over
    /// those tiles only; every other tile's pixels keep the hit texels the host gave them
    /// (it clears the hit images to no hit first), and the slot's iteration counts and
    /// corrected depth are cleared to 0 there.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`]; in addition the frame's geometry lies in the
    /// listed tiles only (the G-buffer outside them is not read: the behind layer's holds
    /// the blocking depth 1 and undefined colours there), the hit images hold `(0, 0)` and `NO_HIT_HEIGHT` there, and the
    /// list and its dispatch were written and made visible to compute-shader storage
    /// reads and indirect reads by the host, and stay alive until the frame completes.
    pub(crate) unsafe fn record_listed(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        listed: crate::passes::classify::ListedTiles,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
        let ctx = self.context()?.clone();
        let slot = inputs.frame_slot;
        let (depth, iterations) = (
            self.hit_depth(slot).is_some(),
            self.iterations(slot).is_some(),
        );
        self.classify.prepare_listed(&ctx, depth, iterations)?;
        // SAFETY: this function's contract.
        unsafe { self.record_frame(cmd, inputs, None, timestamps, Some(listed)) }
    }

    /// [`DisplacementPass::record`] with the frame's camera for the corrected depth
    /// ([`DisplacementPass::set_depth_output`]), for a host that has no [`ShadeTarget`]
    /// (shades from the hit images itself). With a `ShadeTarget` its `view_proj` and
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
        unsafe { self.record_frame(cmd, inputs, Some(*camera), timestamps, None) }
    }

    /// Shades hits the host wrote into `inputs.hit` (e.g. exact reference hits) exactly
    /// as a frame shades the method's: pending uploads and builds, then, with
    /// self-shadowing on, `shadow` on those hits (unless `visibility` is given), then
    /// `shade` into `inputs.shade`'s colour image (required). Writes no iteration counts.
    /// `visibility`: a light
    /// visibility to shade with instead of the `shadow` pass's (an `R16_SFLOAT` storage
    /// view of the frame's size, `GENERAL`, visible to compute-shader storage reads;
    /// self-shadowing must be on). Runs no `trace`, corner pass or `hit_depth`.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`], except that the hit images enter with the
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
        let mut g = self.graph(inputs, Entry::Shading, visibility.is_some());
        // SAFETY: this function's contract (the host's hits, and a given visibility, enter
        // visible to storage reads: `Entry::Shading`); `begin` reset the writer's queries;
        // the classification leaves the host's hits as they are (no hit writes); the graph
        // places the barriers between the stages.
        unsafe {
            self.record_builds(cmd, &mut w, Some(inputs.frame_slot))?;
            self.record_classify(cmd, &mut w, &mut g, inputs, false, None)?;
        }
        let visibility = match visibility {
            Some(v) => Some(v),
            // SAFETY: as above.
            None => unsafe { self.record_shadow(cmd, &mut w, &mut g, inputs, &target)? },
        };
        // SAFETY: as above.
        unsafe { self.record_shade(cmd, &mut w, &mut g, inputs, &target, visibility)? };
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
        listed: Option<crate::passes::classify::ListedTiles>,
    ) -> Result<RecordedFrame> {
        let camera = match &inputs.shade {
            Some(t) => Some(DepthCamera {
                view_proj: t.view_proj,
                eye: t.camera_pos,
            }),
            None => camera,
        };
        // A non-finite or singular camera would write NaN depths or motion.
        let cameras = camera.iter().map(|c| ("camera", c)).chain(
            inputs
                .motion
                .iter()
                .map(|m| ("motion.previous", &m.previous)),
        );
        for (name, c) in cameras {
            let finite = c.view_proj.is_finite() && c.eye.is_finite();
            if !finite || c.view_proj.determinant() == 0.0 {
                return Err(Error::invalid(
                    name,
                    "the view-projection and eye must be finite and the matrix invertible",
                ));
            }
        }
        if self.depth.is_some() && camera.is_none() {
            return Err(Error::invalid(
                "depth output",
                "the corrected depth needs the frame's camera: pass a ShadeTarget or use \
                 record_with_camera",
            ));
        }
        match (&self.motion, &inputs.motion) {
            (Some(_), None) => {
                return Err(Error::invalid(
                    "motion",
                    "the motion output is on: FrameInputs::motion must give the motion image \
                     and the previous camera",
                ));
            }
            (None, Some(_)) => {
                return Err(Error::invalid(
                    "motion",
                    "FrameInputs::motion is given but the motion output is off \
                     (set_motion_output)",
                ));
            }
            (Some(_), Some(_)) if camera.is_none() => {
                return Err(Error::invalid(
                    "motion output",
                    "the motion vectors need the frame's camera: pass a ShadeTarget or use \
                     record_with_camera",
                ));
            }
            _ => {}
        }
        // SAFETY: this function's contract is `begin`'s.
        let mut w = unsafe { self.begin(cmd, inputs, timestamps)? };
        let slot = inputs.frame_slot;
        let mut g = self.graph(inputs, Entry::Frame, false);
        if listed.is_some() {
            g.enter_host(Res::Listed, super::graph::LISTED_ENTRY);
        }
        // SAFETY: this function's contract (the host's images enter as the module docs'
        // table says, the slot's by the slot contract, a list as `record_listed` says);
        // `begin` reset the writer's queries; the builds leave every map sampled-readable,
        // and the graph places the barriers between the stages after them.
        unsafe {
            self.record_builds(cmd, &mut w, Some(slot))?;
            self.record_classify(cmd, &mut w, &mut g, inputs, true, listed.as_ref())?;
            self.record_corners(cmd, &mut w, &mut g, inputs)?;
            self.record_trace(cmd, &mut w, &mut g, inputs, camera.as_ref())?;
        }
        if let Some(target) = &inputs.shade {
            // SAFETY: as above.
            unsafe {
                let visibility = self.record_shadow(cmd, &mut w, &mut g, inputs, target)?;
                self.record_shade(cmd, &mut w, &mut g, inputs, target, visibility)?;
            }
        }
        if let Some(camera) = camera {
            // SAFETY: as above.
            unsafe {
                self.record_hit_depth(cmd, &mut w, &mut g, inputs, &camera)?;
                self.record_motion(cmd, &mut w, &mut g, inputs, &camera)?;
            }
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
        let frames = self.frame.frames_in_flight;
        if slot >= frames {
            return Err(Error::invalid(
                "frame_slot",
                format!("{slot} is not below frames_in_flight ({frames})"),
            ));
        }
        let extent = self.frame.extent;
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
        inputs.gbuffer.check(extent)?;
        if inputs.gbuffer.curve.is_none()
            && self
                .materials
                .iter()
                .flatten()
                .any(|m| m.curved && m.settings.method.traces_curved())
        {
            return Err(Error::invalid(
                "gbuffer.curve",
                "a material traced curved (set_material_curved) needs the G-buffer's curve image",
            ));
        }
        let storage = vk::ImageUsageFlags::STORAGE;
        inputs.hit.uv.check(
            "hit.uv",
            &[crate::passes::trace::HIT_UV_FORMAT],
            storage,
            extent,
        )?;
        inputs.hit.height.check(
            "hit.height",
            &[crate::passes::trace::HIT_HEIGHT_FORMAT],
            storage,
            extent,
        )?;
        if let Some(shade) = &inputs.shade {
            shade.color.check(
                "color",
                &[crate::passes::shade::COLOR_FORMAT],
                storage,
                extent,
            )?;
        }
        if let (Some(m), Some(settings)) = (&inputs.motion, &self.motion_on) {
            m.image
                .check("motion", &[settings.format], storage, extent)?;
        }
        let (pool, first) = match timestamps {
            Timestamps::Off => (None, 0),
            Timestamps::Owned => (Some(self.owned_pool()?), slot * MAX_QUERIES),
            Timestamps::Host { pool, first_query } => (Some(pool), first_query),
        };
        // Slot `slot`'s previous frame has completed: nothing retired before now is
        // read by it any more.
        // SAFETY: `record`'s slot contract: the slot's previous frame has completed.
        unsafe {
            match self.prepared_mark.take() {
                // A preparation was recorded since the last frame: what was retired since
                // then waits for this frame too (`record_preparation`).
                Some(mark) => self
                    .retired
                    .release_holding(&self.context()?.clone(), slot, mark),
                None => self.retired.release(&self.context()?.clone(), slot),
            }
        };
        let w = ScopeWriter::new(pool, first, MAX_QUERIES);
        // SAFETY: this function's contract (a live pool with the range).
        unsafe { w.reset(&self.context()?.clone(), cmd) };
        Ok(w)
    }

    /// The record's frame graph: the host's images as `entry` says (a visibility of the
    /// host's with `host_visibility`), the slot's visibility, corrected depth and corner
    /// grids and iteration counts discarded.
    fn graph(&self, inputs: &FrameInputs, entry: Entry, host_visibility: bool) -> FrameGraph {
        let slot = inputs.frame_slot as usize;
        let s = &self.slots[slot];
        let mut g = FrameGraph::new(entry, inputs.shade.is_some(), inputs.motion.is_some());
        match &s.visibility {
            _ if host_visibility => g.enter_host(Res::Visibility, HOST_VISIBILITY),
            Some(v) => g.own(Res::Visibility, v),
            None => {}
        }
        if let Some(d) = &s.hit_depth {
            g.own(Res::HitDepth, d);
        }
        if let Some(i) = &s.iterations {
            g.own(Res::Iterations, i);
        }
        for (i, grid) in s.corners.iter().enumerate() {
            if let Some(grid) = grid {
                g.own(Res::Corners(i as u32), &grid.image);
            }
        }
        g
    }

    /// The frame's record: the scopes kept for [`DisplacementPass::timings`].
    fn finish(&mut self, slot: u32, w: ScopeWriter, timestamps: Timestamps) -> RecordedFrame {
        let frame = RecordedFrame {
            passes: w.passes,
            timestamps: w.scopes,
        };
        self.slots[slot as usize].scopes = if matches!(timestamps, Timestamps::Owned) {
            frame.timestamps.clone()
        } else {
            Vec::new()
        };
        frame
    }

    /// The live materials: `(tiles, entry, map)` for each, by index.
    pub(super) fn live(&self, slot: u32) -> Vec<(MaterialTiles, &MaterialEntry, &MapEntry)> {
        let lists = &self.slots[slot as usize].tiles;
        self.materials
            .iter()
            .enumerate()
            .filter_map(|(i, m)| {
                let m = m.as_ref()?;
                let map = self.maps[m.map].as_ref()?;
                Some((lists.of(i as u32), m, map))
            })
            .collect()
    }

    /// The pending work of earlier changes: the `upload` scope (new height maps, height
    /// textures refilled for level of detail, material maps), the `pyramid` scope (every
    /// unbuilt pyramid) and the `cone` scope (every unbuilt cone map). Each fill leaves its
    /// image readable by compute shaders. `slot`: the frame's slot, `None` for a
    /// preparation outside the frames ([`DisplacementPass::record_preparation`]), whose
    /// staging waits for every slot.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    pub(super) unsafe fn record_builds(
        &mut self,
        cmd: vk::CommandBuffer,
        w: &mut ScopeWriter,
        slot: Option<u32>,
    ) -> Result<()> {
        let ctx = self.context()?.clone();
        let fills: Vec<(usize, Fill)> = (self.maps.iter_mut().enumerate())
            .filter_map(|(i, m)| Some((i, m.as_mut()?.pending_fill.take()?)))
            .collect();
        let mut shading: Vec<(usize, crate::material::MaterialStaging)> =
            (self.materials.iter_mut().enumerate())
                .filter_map(|(i, m)| Some((i, m.as_mut()?.pending_shading.take()?)))
                .collect();
        // A map shared by several materials is uploaded once.
        crate::material::MaterialStaging::drop_repeats(shading.iter_mut().map(|(_, s)| s));
        if !fills.is_empty() || !shading.is_empty() {
            // SAFETY: `record`'s contract: `cmd` is recording outside a render pass on the
            // context's queue family, after `begin` reset the writer's queries (the scope's
            // contract). In the body (inside this block): a `Fill::Upload` staging buffer
            // came with its map's texture from `create_for_upload`, a `Fill::Copy` source is
            // the previous texture of the same map (`create_like`), its level 0
            // sampled-readable as every fill leaves it; a material's staging came with its
            // textures from `create_for_upload`; the new images have never been accessed.
            // The staging data and sources are retired below until the frames reading them
            // have completed, and the textures live until they are retired after them.
            unsafe {
                w.scope(&ctx, cmd, PassName::Upload, |cmd| -> Result<()> {
                    for (i, fill) in &fills {
                        let Some(map) = &self.maps[*i] else { continue };
                        match fill {
                            Fill::Upload(staging) => {
                                map.texture.record_upload(&ctx, cmd, staging)?
                            }
                            Fill::Copy(source) => {
                                map.texture.record_copy_from(&ctx, cmd, source)?
                            }
                        }
                    }
                    for (i, staging) in &shading {
                        if let Some(textures) =
                            self.materials[*i].as_ref().and_then(|m| m.shading.as_ref())
                        {
                            textures.record_upload(&ctx, cmd, staging)?;
                        }
                    }
                    Ok(())
                })?
            };
        }
        for (_, fill) in fills {
            match (fill, slot) {
                // Read by this frame's copy only: destroyed when this slot is next recorded.
                (Fill::Upload(staging), Some(slot)) => self.retired.retire_for_slot(slot, staging),
                // Read by a preparation's copy: held past the next frame (`begin`).
                (Fill::Upload(staging), None) => self.retired.retire(staging),
                // Read by this frame's copy and by frames in flight in other slots: kept
                // until every slot has been recorded again.
                (Fill::Copy(source), _) => self.retired.retire(source),
            }
        }
        for (_, staging) in shading {
            match slot {
                Some(slot) => self.retired.retire_for_slot(slot, staging),
                None => self.retired.retire(staging),
            }
        }

        if self
            .maps
            .iter()
            .flatten()
            .any(|m| m.pyramids.iter().any(|p| !p.built))
        {
            let pass = self.pyramid_pass.as_ref();
            // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
            // queries reset by `begin`). In the body (inside this block): each height texture
            // is sampled-readable (filled in the upload scope above or by an earlier frame);
            // a pyramid is built only while unbuilt, so no frame has read it; the pass and
            // pyramids live until they are retired after the frames that use them.
            unsafe {
                w.scope(&ctx, cmd, PassName::Pyramid, |cmd| {
                    let Some(pass) = pass else { return Ok(()) };
                    for map in self.maps.iter().flatten() {
                        for p in map.pyramids.iter().filter(|p| !p.built) {
                            pass.record(&ctx, cmd, &map.texture, &p.value)?;
                        }
                    }
                    Ok(())
                })?
            };
            if pass.is_some() {
                for map in self.maps.iter_mut().flatten() {
                    for p in &mut map.pyramids {
                        p.built = true;
                    }
                }
            }
        }
        // SAFETY: `record`'s contract, as above.
        unsafe {
            self.record_cones(w, cmd)?;
            self.record_map_preparations(w, cmd)
        }
    }

    /// The `cone` scope (cone methods): each unbuilt cone map from its map's (built) cell
    /// pyramid.
    ///
    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_cones(&mut self, w: &mut ScopeWriter, cmd: vk::CommandBuffer) -> Result<()> {
        let ready = |map: &MapEntry| {
            map.cones.iter().any(|c| !c.built) && map.pyramid(PyramidKind::Cell).is_some()
        };
        if !self.maps.iter().flatten().any(ready) {
            return Ok(());
        }
        let ctx = self.context()?.clone();
        let ctx = &*ctx;
        // SAFETY: `record`'s contract (`cmd` recording outside a render pass; the writer's
        // queries reset by `begin`). In the body: each height texture and cell pyramid is
        // sampled-readable (their fill and build, recorded before this in the same command
        // buffer or by an earlier frame); a cone map is built only while unbuilt, so no
        // frame has read it; the passes, pyramids and maps live until they are retired
        // after the frames that use them.
        unsafe {
            w.scope(ctx, cmd, PassName::Cone, |cmd| {
                for map in self.maps.iter().flatten().filter(|m| ready(m)) {
                    let Some(pyramid) = map.pyramid(PyramidKind::Cell) else {
                        continue;
                    };
                    for cone in map.cones.iter().filter(|c| !c.built) {
                        let kind = cone.value.kind;
                        if let Some(pass) = self.cone_passes.iter().find(|p| p.kind == kind) {
                            pass.record(ctx, cmd, &map.texture, pyramid, &cone.value)?;
                        }
                    }
                }
                Ok(())
            })?
        };
        let mut scratch = Vec::new();
        for map in self.maps.iter_mut().flatten() {
            if map.pyramid(PyramidKind::Cell).is_none() {
                continue;
            }
            for cone in map.cones.iter_mut().filter(|c| !c.built) {
                cone.built = true;
                // What only the build read (a relaxed map's falls pyramids) goes once this
                // command buffer's frame has executed.
                scratch.extend(cone.value.take_scratch());
            }
        }
        if !scratch.is_empty() {
            self.retired.retire(scratch);
        }
        Ok(())
    }
}
