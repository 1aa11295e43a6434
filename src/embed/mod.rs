//! The displacement pass inside a host engine's Vulkan frame.
//!
//! The host owns the instance, device, queue, allocator, command buffers and the G-buffer.
//! It wraps its handles in a [`Context`] with [`Context::from_handles`], builds one
//! [`DisplacementPass`], and each frame calls [`DisplacementPass::record`], which only
//! *records* `[upload] -> [pyramid] -> [dig_corners] -> trace -> [shadow] ->
//! [shade] -> [hit_depth]` into the host's command buffer. On this path dispmap never
//! creates a device, a command pool or a fence, and never submits: the host submits with
//! its own fence. This is the one orchestrator of the compute passes: dispmap's own
//! standalone [`crate::renderer::Renderer`] is a host of it like any engine.
//!
//! # Call sequence
//!
//! 1. Before `vkCreateDevice`: [`requirements`] lists what to enable,
//!    [`check_physical_device`] and [`check_device_create_info`] turn a missing feature,
//!    extension or limit into an [`Error::Unsupported`] naming it (not a validation
//!    message later).
//! 2. [`Context::from_handles`] with the host's handles and `Arc<Mutex<Allocator>>`.
//! 3. [`DisplacementPass::new`] (pipelines, the height texture, per-slot resources).
//! 4. Per frame: the host renders its G-buffer (formats and channels in
//!    [`crate::passes::gbuffer`] and `glsl/include/dispmap_gbuffer.glsl`), places the
//!    entry barriers below, calls [`DisplacementPass::record`], places its own barriers for
//!    what follows, submits and later waits on its fence; then it may read the timestamps
//!    ([`DisplacementPass::timings`] or [`read_timestamps`]). A host that draws dispmap's
//!    tiled plane (or quad) itself uses `dispmap_plane_vertex` from
//!    `glsl/include/dispmap_plane.glsl`, the function dispmap's own `gbuffer.vert` calls:
//!    with the values of [`crate::scene::Scene::gbuffer_params`] (rectangles, `plane_cells`,
//!    eye), [`crate::abi::GBufferParams::vertex_count`] vertices from `gl_VertexIndex` and
//!    the eye-relative view-projection ([`crate::scene::FrameCamera::view_proj_eye`]) its
//!    vertices, rays and hits are bit-identical to the standalone renderer's
//!    (`examples/host_engine.rs`, `tests/host_engine.rs`).
//! 5. [`DisplacementPass::set_height_map`] / [`DisplacementPass::resize`] /
//!    [`DisplacementPass::set_method`] / [`DisplacementPass::set_shadows`] /
//!    [`DisplacementPass::set_depth_output`] / [`DisplacementPass::set_material`] (albedo
//!    and normal maps for `shade`) / [`DisplacementPass::set_depth_scale`] any time
//!    between records, with frames in
//!    flight (what they replace is retired, see below; for `resize` the host's images of
//!    the new size are used from the next record on). Self-shadowing and the corrected
//!    depth are off after `new` and nothing of them is built until they are turned on.
//!    To shade hits of its own (e.g. exact reference hits) exactly as a frame shades the
//!    method's, a host records [`DisplacementPass::record_shading`] instead of `record`.
//! 6. With the corrected depth on: after `record`, the host reads
//!    [`DisplacementPass::hit_depth`] of the frame's slot, e.g. to write it into its own
//!    `D32_SFLOAT` attachment (see "Corrected depth" below).
//! 7. After the device is idle (or every fence of a frame recorded with the pass has
//!    signalled): [`DisplacementPass::destroy`], then drop the context, then the host
//!    destroys its own objects.
//!
//! # Images: layout and access on entry and exit
//!
//! | image | owner | entry (the host's barrier makes it so) | exit |
//! |---|---|---|---|
//! | G-buffer `ray`, `normal`, `tangent` | host | `SHADER_READ_ONLY_OPTIMAL`, writes visible to `COMPUTE_SHADER` / `SHADER_SAMPLED_READ` | unchanged; last access `COMPUTE_SHADER` sampled read |
//! | G-buffer `depth` | host | as above (depth aspect) | as above |
//! | hit buffer (`R32G32B32A32_SFLOAT`, `STORAGE`) | host | `GENERAL`, contents discarded, earlier accesses finished before `COMPUTE_SHADER` (a WAR dependency) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (trace), read by `SHADER_STORAGE_READ` (shade) |
//! | colour (`R8G8B8A8_UNORM`, `STORAGE`; only with [`ShadeTarget`]) | host | `GENERAL`, contents discarded, earlier accesses finished before `COMPUTE_SHADER` | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (sRGB-encoded values) |
//! | height map, pyramid, DIG corner grid | pass | (internal) | (internal; read-only for the host) |
//! | visibility (`R16_SFLOAT`, one per slot; only with [`DisplacementPass::set_shadows`] on and a [`ShadeTarget`]) | pass | (internal: discarded by the pass) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (shadow), last read by `SHADER_STORAGE_READ` (shade); read-only for the host ([`DisplacementPass::visibility`]) |
//! | corrected depth (`R32_SFLOAT`, one per slot; only with [`DisplacementPass::set_depth_output`] on) | pass | any layout: the pass discards it, its barrier waits for every earlier access (`ALL_COMMANDS`) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (hit_depth); the host may read it (after its own barrier from that state) and leave it in any layout |
//!
//! The pass places every barrier between its own passes, including the hit buffer's
//! write -> read before `shade` (a global memory barrier, so it needs no `vk::Image`).
//! Every image it binds must have been created on the context's queue family with
//! `VK_SHARING_MODE_EXCLUSIVE` and used on that family.
//!
//! # Frames in flight
//!
//! Descriptors are *pushed* (`VK_KHR_push_descriptor`, see [`crate::gpu::pipeline`]):
//! they are recorded into the command buffer itself, so no descriptor set is shared
//! between frames and recording frame N+1 never touches what frame N's GPU work reads.
//! Resources a frame *writes* are per frame-in-flight slot: the host supplies the hit
//! buffer and colour image of each slot; the pass owns one DIG corner grid and one range
//! of its own timestamp queries per slot. The height map and the pyramid are shared and
//! only read by frames; a new height map gets new images, and the old ones are retired
//! and destroyed only once every slot has been recorded again (so every frame that could
//! read them has finished, by the slot contract below). `resize` retires the old corner
//! grids and `set_method` what the old method used (its `trace` pipeline, pyramid and
//! grids it no longer needs) the same way.
//!
//! With self-shadowing on, each slot also has its visibility image; with the corrected
//! depth on, its depth image: both are per slot for the same reason (a frame writes
//! them), and switching either feature retires them like a replaced method.
//!
//! **The slot contract**: `FrameInputs::frame_slot` is in `0..frames_in_flight`, and when
//! `record` is called with slot `s`, the GPU work of the previous frame recorded with
//! slot `s` has completed (the host waited on that frame's fence), as in any
//! frames-in-flight loop. Command buffers recorded by `record` are submitted to the
//! context's queue in the order they were recorded (the pyramid built in one frame is
//! read by the next), and every recorded command buffer is submitted.
//!
//! # Self-shadowing
//!
//! [`DisplacementPass::set_shadows`] with [`ShadowSettings`] (`off`, `hard`, `soft`;
//! [`crate::passes::shadow`] documents the light ray and the query each method gets)
//! makes every record with a [`ShadeTarget`] run `shadow` between `trace` and `shade`,
//! with the target's `light_dir`, and shade with the visibility (binding 7 of the
//! shaded `shade` variant): the colour then equals the standalone renderer's with the
//! same [`ShadowSettings`] bit for bit. Without a `ShadeTarget` nothing is shadowed.
//!
//! # Corrected depth
//!
//! [`DisplacementPass::set_depth_output`] makes every record run `hit_depth` last: it
//! writes the reverse-Z clip depth of each pixel's displaced hit (0 without a hit) into
//! the slot's [`HIT_DEPTH_FORMAT`] image, which the pass owns (one per slot, so a frame
//! in flight never shares it; chosen over a host-provided view so the pass can discard
//! and re-create it on `resize` like its other per-slot images). The camera is the
//! frame's [`ShadeTarget`] (`view_proj`, `camera_pos`) or, without one,
//! [`DisplacementPass::record_with_camera`]'s [`DepthCamera`]: it must be the camera of
//! the host's G-buffer.
//!
//! To make the rest of the host's frame (later geometry, fog, SSAO) meet the displaced
//! surface, the host writes it into its own `D32_SFLOAT` depth attachment with
//! [`crate::passes::depth_resolve::DepthResolvePass`] (a graphics pipeline; the host's
//! device needs `dynamicRendering`, which [`requirements`] does not list), in the same
//! command buffer after `record`:
//!
//! 1. barrier on [`DisplacementPass::hit_depth`]'s image: `GENERAL`, `COMPUTE_SHADER`
//!    `SHADER_STORAGE_WRITE` -> `SHADER_READ_ONLY_OPTIMAL`, `FRAGMENT_SHADER`
//!    `SHADER_SAMPLED_READ`; barrier on the host's depth image: (its last access) ->
//!    `DEPTH_ATTACHMENT_OPTIMAL`, `EARLY/LATE_FRAGMENT_TESTS` depth write (contents
//!    discarded);
//! 2. `DepthResolvePass::record(ctx, cmd, image.view, host_depth_view, extent)` (it
//!    begins and ends its own dynamic rendering);
//! 3. the host's barrier for what reads its depth next. The pass's image may be left in
//!    `SHADER_READ_ONLY_OPTIMAL`: the next record of the slot discards it.
//!
//! The host builds `DepthResolvePass::new(&ctx)` once and destroys it itself.

mod device;
mod record;

pub use device::{
    MAX_FRAMES_IN_FLIGHT, MAX_QUERIES, PUSH_CONSTANT_BYTES, PUSH_DESCRIPTORS, Requirements,
    check_device_create_info, check_physical_device, requirements,
};

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::owned::{Destroy, Guard, RetireQueue};
use crate::gpu::{Buffer, HeightTexture, Image};
use crate::heightfield::{Addressing, HeightField};
use crate::material::{MaterialImages, MaterialStaging, MaterialTextures};
use crate::method::{Method, MethodParams, Needs, PyramidKind};
use crate::passes::cone::{ConeMap, ConePass};
use crate::passes::dig::{CornerGrid, DigCornerPass};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::hit_depth::HitDepthPass;
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::passes::shade::ShadePass;
use crate::passes::shadow::{ShadowPass, ShadowTrace};
use crate::passes::trace::TracePass;
use ash::vk;
use glam::{Mat4, Vec3};
use std::sync::Arc;

pub use crate::passes::PassName;
pub use crate::passes::gbuffer::{DEPTH_FORMAT, FRAME_FORMAT, RAY_FORMAT};
pub use crate::passes::hit_depth::HIT_DEPTH_FORMAT;
pub use crate::passes::shade::COLOR_FORMAT;
pub use crate::passes::shadow::{ShadowMode, ShadowSettings, VISIBILITY_FORMAT};
pub use crate::passes::trace::HIT_FORMAT;
pub use crate::timing::{TimestampScope, read_timestamps};

/// How the pass is configured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassSettings {
    /// The intersection method.
    pub method: Method,
    /// Its parameters.
    pub params: MethodParams,
    /// Displacement depth in uv (tile) units: the value the host's G-buffer used for `P`.
    pub depth_scale: f32,
    /// Height-map addressing: `Repeat` for tiled surfaces, `Clamp` for decals (must match
    /// the `addressing` the host's G-buffer shader used for `uv0`).
    pub addressing: Addressing,
    /// Frame size in pixels (the G-buffer's, hit buffer's and colour image's size).
    pub extent: vk::Extent2D,
    /// Frames the host keeps in flight (1..=[`MAX_FRAMES_IN_FLIGHT`]): the number of
    /// slots of the per-frame resources the pass owns.
    pub frames_in_flight: u32,
}

/// What `shade` needs to light the hits (only when the host wants dispmap's colour).
#[derive(Clone, Copy, Debug)]
pub struct ShadeTarget {
    /// The colour image view (`R8G8B8A8_UNORM`, storage usage; see the module table).
    pub color: vk::ImageView,
    /// World to clip of the frame (the inverse gives each pixel's view ray).
    pub view_proj: Mat4,
    /// Eye position, world space.
    pub camera_pos: Vec3,
    /// Unit vector towards a directional light, world space.
    pub light_dir: Vec3,
    /// Light intensity.
    pub light_intensity: f32,
}

/// One frame's host images (layouts and access on entry and exit: module docs).
#[derive(Clone, Copy, Debug)]
pub struct FrameInputs {
    /// The frame-in-flight slot, `0..frames_in_flight` (the slot contract: module docs).
    pub frame_slot: u32,
    /// The host's G-buffer views; `extent` must equal the pass's.
    pub gbuffer: GBufferViews,
    /// The hit buffer view this frame writes (`R32G32B32A32_SFLOAT`, storage usage).
    pub hit: vk::ImageView,
    /// Shade the hits into a colour image (`None`: the host shades from the hit buffer).
    pub shade: Option<ShadeTarget>,
}

/// Where [`DisplacementPass::record`] writes its timestamps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timestamps {
    /// No timestamps.
    Off,
    /// The pass's own query pool (one range per frame slot, created on first use);
    /// read with [`DisplacementPass::timings`] after the frame's fence.
    Owned,
    /// The host's `TIMESTAMP` query pool: the pass resets, in the command buffer, and
    /// writes queries `first_query .. first_query + MAX_QUERIES` (the host must not use
    /// them in the same frame); read with [`read_timestamps`] or the host's profiler.
    Host {
        /// A `VK_QUERY_TYPE_TIMESTAMP` pool of the host's device.
        pool: vk::QueryPool,
        /// First of the [`MAX_QUERIES`] queries the pass may use.
        first_query: u32,
    },
}

/// What [`DisplacementPass::record`] recorded.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordedFrame {
    /// The passes recorded, in order.
    pub passes: Vec<PassName>,
    /// Their timestamp queries (empty with [`Timestamps::Off`]).
    pub timestamps: Vec<TimestampScope>,
}

/// The camera of a frame for the corrected depth when the frame has no
/// [`ShadeTarget`] (see [`DisplacementPass::record_with_camera`]).
#[derive(Clone, Copy, Debug)]
pub struct DepthCamera {
    /// World to clip of the frame (the G-buffer's; reverse-Z).
    pub view_proj: Mat4,
    /// Eye position, world space.
    pub eye: Vec3,
}

/// A height texture's contents not yet recorded.
enum Fill {
    /// A new map's staging buffer.
    Upload(Buffer),
    /// The texture it replaces (level of detail switched on or off: the mip chain added
    /// or dropped), whose level 0 is copied; frames in flight may still sample it.
    Copy(HeightTexture),
}

impl Destroy for Fill {
    fn destroy(&mut self, ctx: &Context) {
        match self {
            Fill::Upload(b) => b.destroy(ctx),
            Fill::Copy(h) => h.destroy(ctx),
        }
    }
}

/// The displacement pass for a host engine (see the module docs for the contract), and
/// the one orchestrator of dispmap's compute passes: the standalone
/// [`crate::renderer::Renderer`] is a host of it like any engine.
///
/// Owns its pipelines, the height texture (and pyramid when the method needs one), the
/// material maps when set, one DIG corner grid per frame slot (DIG methods) and, with
/// [`Timestamps::Owned`], a query pool. Destroy it explicitly with
/// [`DisplacementPass::destroy`]; in debug builds one dropped without it logs a warning
/// (and leaks its objects).
pub struct DisplacementPass {
    ctx: Arc<Context>,
    settings: PassSettings,
    needs: Needs,
    trace: TracePass,
    shade: ShadePass,
    pyramid_pass: Option<PyramidPass>,
    corner_pass: Option<DigCornerPass>,
    height: HeightTexture,
    /// How `height` is still to be filled (the next `record` records it); `None` once
    /// filled.
    pending_fill: Option<Fill>,
    /// Albedo and normal map ([`DisplacementPass::set_material`]).
    material: Option<MaterialTextures>,
    /// Their staging buffers until a record copies them.
    pending_material: Option<MaterialStaging>,
    pyramid: Option<Pyramid>,
    pyramid_built: bool,
    /// The cone-map pipeline and the map (cone methods).
    cone_pass: Option<ConePass>,
    cone: Option<ConeMap>,
    cone_built: bool,
    /// One grid per frame slot (empty unless the method is a DIG).
    corners: Vec<CornerGrid>,
    query_pool: Option<vk::QueryPool>,
    /// The owned-pool scopes each slot recorded last.
    slot_scopes: Vec<Vec<TimestampScope>>,
    retired: RetireQueue,
    /// Self-shadowing as set by [`DisplacementPass::set_shadows`].
    shadows: ShadowSettings,
    /// What self-shadowing needs (`None` when off).
    shadow: Option<ShadowParts>,
    /// The corrected-depth output (`None` when off).
    depth: Option<DepthParts>,
    destroyed: bool,
}

/// What self-shadowing adds to the pass: the `shadow` pipeline of the method's query,
/// one visibility image per frame slot and, for hard shadows of the `pyramid` method
/// (whose own pyramid is not a cell pyramid), a cell pyramid with its pass.
struct ShadowParts {
    pass: ShadowPass,
    visibility: Vec<Image>,
    own_pyramid: Option<(PyramidPass, Pyramid)>,
    own_built: bool,
    /// What it was built for: the query, the frame size and the height map's size.
    key: ShadowKey,
}

#[derive(Clone, Copy, PartialEq, Eq)]
struct ShadowKey {
    trace: ShadowTrace,
    own_pyramid: bool,
    extent: vk::Extent2D,
    map: [u32; 2],
    /// The height texture's format (the pyramid's compact copy follows it).
    format: vk::Format,
}

impl ShadowParts {
    fn new(ctx: &Context, key: ShadowKey, frames: u32, addressing: Addressing) -> Result<Self> {
        let pass = Guard::new(ctx, ShadowPass::new(ctx, key.trace)?);
        let visibility = Guard::new(
            ctx,
            per_slot(ctx, frames, |s| {
                Image::new(
                    ctx,
                    &format!("embed.visibility{s}"),
                    VISIBILITY_FORMAT,
                    key.extent,
                    1,
                    vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
                )
            })?,
        );
        let own_pyramid = if key.own_pyramid {
            let pass = Guard::new(ctx, PyramidPass::new(ctx)?);
            let pyramid = Pyramid::new(ctx, key.map, PyramidKind::Cell, addressing, key.format)?;
            Some((pass.keep(), pyramid))
        } else {
            None
        };
        Ok(ShadowParts {
            pass: pass.keep(),
            visibility: visibility.keep(),
            own_pyramid,
            own_built: false,
            key,
        })
    }
}

impl Destroy for ShadowParts {
    fn destroy(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.visibility.destroy(ctx);
        self.own_pyramid.destroy(ctx);
    }
}

/// The corrected-depth output: the `hit_depth` pipeline and one `R32_SFLOAT` image per
/// frame slot.
struct DepthParts {
    pass: HitDepthPass,
    images: Vec<Image>,
}

impl DepthParts {
    fn new(ctx: &Context, extent: vk::Extent2D, frames: u32) -> Result<Self> {
        let pass = Guard::new(ctx, HitDepthPass::new(ctx)?);
        let images = per_slot(ctx, frames, |s| {
            Image::new(
                ctx,
                &format!("embed.hit_depth{s}"),
                HIT_DEPTH_FORMAT,
                extent,
                1,
                vk::ImageUsageFlags::STORAGE
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            )
        })?;
        Ok(DepthParts {
            pass: pass.keep(),
            images,
        })
    }
}

impl Destroy for DepthParts {
    fn destroy(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.images.destroy(ctx);
    }
}

/// One value per frame slot from `make`; on a failure the ones made are destroyed.
fn per_slot<T: Destroy>(
    ctx: &Context,
    frames: u32,
    mut make: impl FnMut(u32) -> Result<T>,
) -> Result<Vec<T>> {
    let mut made = Guard::new(ctx, Vec::new());
    for s in 0..frames {
        made.push(make(s)?);
    }
    Ok(made.keep())
}

impl DisplacementPass {
    /// Builds the pipelines and the per-slot resources and stages `field` for upload
    /// (the first [`DisplacementPass::record`] copies it and builds the pyramid). Records
    /// and submits nothing.
    pub fn new(ctx: Arc<Context>, field: &HeightField, settings: PassSettings) -> Result<Self> {
        validate(&ctx, &settings)?;
        let needs = settings.method.needs();
        let c = &*ctx;
        // Built in order; a failure destroys what the guards hold.
        let trace = Guard::new(c, TracePass::new(c, settings.method)?);
        let shade = Guard::new(c, ShadePass::new(c)?);
        let (height, staging) = HeightTexture::create_for_upload(
            c,
            field,
            settings.addressing,
            settings.params.lod_threshold.is_some(),
        )?;
        let height = Guard::new(c, height);
        let staging = Guard::new(c, staging);
        let pyramid_pass = Guard::new(c, needs.pyramid.map(|_| PyramidPass::new(c)).transpose()?);
        let pyramid = Guard::new(
            c,
            needs
                .pyramid
                .map(|kind| {
                    Pyramid::new(
                        c,
                        field_size(field),
                        kind,
                        settings.addressing,
                        field.format(),
                    )
                })
                .transpose()?,
        );
        let cone_pass = Guard::new(
            c,
            needs.cone.map(|kind| ConePass::new(c, kind)).transpose()?,
        );
        let cone = Guard::new(
            c,
            needs
                .cone
                .map(|kind| {
                    ConeMap::new(
                        c,
                        field_size(field),
                        settings.addressing,
                        kind,
                        field.format(),
                    )
                })
                .transpose()?,
        );
        let corner_pass = Guard::new(
            c,
            needs
                .dig_corners
                .then(|| DigCornerPass::new(c))
                .transpose()?,
        );
        let corners = if needs.dig_corners {
            corner_grids(c, &settings)?
        } else {
            Vec::new()
        };
        Ok(DisplacementPass {
            settings,
            needs,
            trace: trace.keep(),
            shade: shade.keep(),
            pyramid_pass: pyramid_pass.keep(),
            corner_pass: corner_pass.keep(),
            height: height.keep(),
            pending_fill: Some(Fill::Upload(staging.keep())),
            material: None,
            pending_material: None,
            pyramid: pyramid.keep(),
            pyramid_built: false,
            cone_pass: cone_pass.keep(),
            cone: cone.keep(),
            cone_built: false,
            corners,
            query_pool: None,
            slot_scopes: vec![Vec::new(); settings.frames_in_flight as usize],
            retired: RetireQueue::new(settings.frames_in_flight),
            shadows: ShadowSettings::default(),
            shadow: None,
            depth: None,
            destroyed: false,
            ctx,
        })
    }

    /// The settings in use.
    pub fn settings(&self) -> &PassSettings {
        &self.settings
    }

    /// The context the pass was built with.
    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
    }

    /// Whether the next [`DisplacementPass::record`] fills the height texture (a new map,
    /// or the mip chain added or dropped with level of detail) or (for the pyramid
    /// methods) rebuilds the pyramid.
    pub fn rebuild_pending(&self) -> bool {
        self.pending_fill.is_some()
            || (self.pyramid.is_some() && !self.pyramid_built)
            || (self.cone.is_some() && !self.cone_built)
    }

    /// Per-pass milliseconds of the last frame recorded in `frame_slot` with
    /// [`Timestamps::Owned`] (empty if it recorded none). Call after that frame's fence
    /// signalled and before the slot is recorded again; an unfinished frame gives an
    /// error (`VK_NOT_READY`), never a wait.
    pub fn timings(&self, frame_slot: u32) -> Result<Vec<(PassName, f64)>> {
        let scopes = self
            .slot_scopes
            .get(frame_slot as usize)
            .ok_or_else(|| Error::invalid("frame_slot", format!("no slot {frame_slot}")))?;
        // SAFETY: the scopes name the pass's own live pool; reading without WAIT cannot
        // block, and an unwritten or unfinished query is an error, not undefined.
        unsafe { read_timestamps(&self.ctx, scopes) }
    }

    /// Swaps in a new height map (any size; same addressing). The next
    /// [`DisplacementPass::record`] uploads it and, for the pyramid methods, rebuilds the
    /// pyramid (the min-reduce chain, timed as its own `pyramid` pass). The old texture
    /// and pyramid stay alive for frames in flight and are destroyed once every slot has
    /// been recorded again. Needs no GPU idle.
    pub fn set_height_map(&mut self, field: &HeightField) -> Result<()> {
        self.check_alive()?;
        let ctx = self.ctx.clone();
        let (height, staging) = HeightTexture::create_for_upload(
            &ctx,
            field,
            self.settings.addressing,
            self.settings.params.lod_threshold.is_some(),
        )?;
        let height = Guard::new(&ctx, height);
        let staging = Guard::new(&ctx, staging);
        let pyramid = self
            .needs
            .pyramid
            .map(|kind| {
                Pyramid::new(
                    &ctx,
                    field_size(field),
                    kind,
                    self.settings.addressing,
                    field.format(),
                )
            })
            .transpose()?;
        let pyramid = Guard::new(&ctx, pyramid);
        let cone = self
            .needs
            .cone
            .map(|kind| {
                ConeMap::new(
                    &ctx,
                    field_size(field),
                    self.settings.addressing,
                    kind,
                    field.format(),
                )
            })
            .transpose()?;
        let pyramid = pyramid.keep();
        self.retired
            .retire(std::mem::replace(&mut self.height, height.keep()));
        match self.pending_fill.replace(Fill::Upload(staging.keep())) {
            // Never recorded: no frame reads it.
            Some(Fill::Upload(mut old)) => old.destroy(&ctx),
            // The texture frames in flight may still read.
            Some(Fill::Copy(old)) => self.retired.retire(old),
            None => {}
        }
        if let Some(old) = std::mem::replace(&mut self.pyramid, pyramid) {
            self.retired.retire(old);
        }
        self.pyramid_built = false;
        if let Some(old) = std::mem::replace(&mut self.cone, cone) {
            self.retired.retire(old);
        }
        self.cone_built = false;
        // A cell pyramid of the shadow stage's own is of the old map: rebuilt (the old
        // one is retired with its stage).
        let own = self
            .shadow
            .as_ref()
            .is_some_and(|s| s.own_pyramid.is_some());
        self.sync_shadows(own)
    }

    /// Sets the material maps `shade` reads at each hit (an albedo and a tangent-space
    /// normal map, addressed like the height map; [`crate::material`] has their
    /// conventions); empty [`MaterialImages`] remove them. The next record uploads them
    /// (in its `upload` scope); replaced maps are retired like a replaced height map.
    /// On error the pass keeps its old maps.
    pub fn set_material(&mut self, images: &MaterialImages) -> Result<()> {
        self.check_alive()?;
        let ctx = self.ctx.clone();
        let created = MaterialTextures::create_for_upload(&ctx, images, self.settings.addressing)?;
        let (material, staging) = created.unzip();
        if let Some(old) = std::mem::replace(&mut self.material, material) {
            self.retired.retire(old);
        }
        // Staging never recorded: no frame reads it.
        std::mem::replace(&mut self.pending_material, staging).destroy(&ctx);
        Ok(())
    }

    /// Changes the displacement depth (uv units; the value the host's G-buffer used for
    /// `P`) from the next record on. Builds nothing.
    pub fn set_depth_scale(&mut self, depth_scale: f32) -> Result<()> {
        self.check_alive()?;
        let settings = PassSettings {
            depth_scale,
            ..self.settings
        };
        validate(&self.ctx, &settings)?;
        self.settings = settings;
        Ok(())
    }

    /// Changes the frame size (the host's G-buffer, hit buffer and colour image must
    /// have the new size from the next record on). Per-slot resources of the old size are
    /// retired, not destroyed at once, so this needs no GPU idle.
    pub fn resize(&mut self, extent: vk::Extent2D) -> Result<()> {
        self.check_alive()?;
        let settings = PassSettings {
            extent,
            ..self.settings
        };
        validate(&self.ctx, &settings)?;
        let grids = if self.needs.dig_corners {
            corner_grids(&self.ctx, &settings)?
        } else {
            Vec::new()
        };
        let old = std::mem::replace(&mut self.corners, grids);
        self.retired.retire(old);
        self.settings = settings;
        // The visibility and corrected-depth images of the old size are retired too.
        self.sync_shadows(false)?;
        if self.depth.is_some() {
            self.set_depth_output(false)?;
            self.set_depth_output(true)?;
        }
        Ok(())
    }

    /// Switches the intersection method and its parameters, building only what the new
    /// method needs that the pass does not have yet: its `trace` pipeline, the pyramid
    /// pipeline and a pyramid of the new kind (built by the next
    /// [`DisplacementPass::record`], timed as its `pyramid` pass), the DIG corner pipeline
    /// and one corner grid per slot (new grids also when `params.block` changed). What is
    /// kept (the height map, a pyramid of the same kind, grids of the same block) is
    /// reused; `depth_scale`, addressing, extent and `frames_in_flight` stay. The height
    /// texture has a mip chain only while level of detail is on (`params.lod_threshold`):
    /// switching it on or off makes a new texture that the next record fills on the GPU
    /// from the old one's level 0 (in its `upload` scope).
    ///
    /// GPU-use contract: needs no GPU idle. What the old method used and the new one does
    /// not (pipelines, pyramid, grids) may still be read by frames in flight, so it is
    /// retired like a replaced height map: destroyed once every slot has been recorded
    /// again (by the slot contract, every frame that could use it has completed), or by
    /// [`DisplacementPass::destroy`]. Frames recorded before the call keep the old method;
    /// every `record` after it uses the new one.
    ///
    /// On error (invalid `params`, an allocation or pipeline failure) the pass is
    /// unchanged and keeps its old method. One exception: with self-shadowing on, the
    /// shadow stage of the new method is built after the switch; if that fails the
    /// method is switched, the error returned, and records are refused until a
    /// successful [`DisplacementPass::set_shadows`].
    pub fn set_method(&mut self, method: Method, params: MethodParams) -> Result<()> {
        self.check_alive()?;
        params.validate()?;
        let ctx = self.ctx.clone();
        let c = &*ctx;
        let needs = method.needs();
        let settings = PassSettings {
            method,
            params,
            ..self.settings
        };
        validate(c, &settings)?;
        // Build everything new first (guarded: a failure destroys it and leaves the pass
        // as it was), then commit.
        let chain = params.lod_threshold.is_some();
        let trace = Guard::new(
            c,
            (method != self.trace.method())
                .then(|| TracePass::new(c, method))
                .transpose()?,
        );
        let height = Guard::new(
            c,
            self.height
                .differs_for(c, chain)
                .then(|| self.height.create_like(c, chain))
                .transpose()?,
        );
        let pyramid_pass = Guard::new(
            c,
            (needs.pyramid.is_some() && self.pyramid_pass.is_none())
                .then(|| PyramidPass::new(c))
                .transpose()?,
        );
        let new_pyramid = needs
            .pyramid
            .filter(|&kind| self.pyramid.as_ref().is_none_or(|old| old.kind != kind));
        let pyramid = Guard::new(
            c,
            new_pyramid
                .map(|kind| {
                    Pyramid::new(
                        c,
                        self.height.size(),
                        kind,
                        self.settings.addressing,
                        self.height.image.format,
                    )
                })
                .transpose()?,
        );
        // A cone map of the other kind is replaced (and rebuilt), as a pyramid is.
        let cone_pass = Guard::new(
            c,
            needs
                .cone
                .filter(|&kind| self.cone_pass.as_ref().is_none_or(|p| p.kind != kind))
                .map(|kind| ConePass::new(c, kind))
                .transpose()?,
        );
        let cone = Guard::new(
            c,
            needs
                .cone
                .filter(|&kind| self.cone.as_ref().is_none_or(|m| m.kind != kind))
                .map(|kind| {
                    ConeMap::new(
                        c,
                        self.height.size(),
                        self.settings.addressing,
                        kind,
                        self.height.image.format,
                    )
                })
                .transpose()?,
        );
        let corner_pass = Guard::new(
            c,
            (needs.dig_corners && self.corner_pass.is_none())
                .then(|| DigCornerPass::new(c))
                .transpose()?,
        );
        let same_grids =
            !self.corners.is_empty() && self.corners.iter().all(|g| g.block == params.block);
        let corners = if needs.dig_corners && !same_grids {
            Some(corner_grids(c, &settings)?)
        } else {
            None
        };

        // Commit: swap in what was built, retire what the new method does not use.
        if let Some(trace) = trace.keep() {
            self.retired
                .retire(std::mem::replace(&mut self.trace, trace));
        }
        if let Some(height) = height.keep() {
            // The mip chain follows level of detail; level 0 (the map) is unchanged.
            let old = std::mem::replace(&mut self.height, height);
            if self.pending_fill.is_some() {
                // `old` was never filled (its fill is still pending and now fills the
                // new texture): no frame reads it.
                self.retired.retire(old);
            } else {
                self.pending_fill = Some(Fill::Copy(old));
            }
        }
        if let Some(pass) = pyramid_pass.keep() {
            self.pyramid_pass = Some(pass);
        }
        if let Some(pyramid) = pyramid.keep() {
            self.retired.retire(self.pyramid.replace(pyramid));
            self.pyramid_built = false;
        }
        if needs.pyramid.is_none() {
            self.retired.retire(self.pyramid.take());
            self.retired.retire(self.pyramid_pass.take());
            self.pyramid_built = false;
        }
        if let Some(pass) = cone_pass.keep() {
            self.retired.retire(self.cone_pass.replace(pass));
        }
        if let Some(cone) = cone.keep() {
            self.retired.retire(self.cone.replace(cone));
            self.cone_built = false;
        }
        if needs.cone.is_none() {
            self.retired.retire(self.cone.take());
            self.retired.retire(self.cone_pass.take());
            self.cone_built = false;
        }
        if let Some(pass) = corner_pass.keep() {
            self.corner_pass = Some(pass);
        }
        if let Some(grids) = corners {
            let old = std::mem::replace(&mut self.corners, grids);
            self.retired.retire(old);
        }
        if !needs.dig_corners {
            self.retired.retire(std::mem::take(&mut self.corners));
            self.retired.retire(self.corner_pass.take());
        }
        self.settings = settings;
        self.needs = needs;
        // The shadow query follows the method's family (ShadowTrace::for_method).
        self.sync_shadows(false)
    }

    /// Switches self-shadowing (see [`crate::passes::shadow`] for the modes). On, the
    /// pass builds what it lacks: the `shadow` pipeline of the method's query, one
    /// `R16_SFLOAT` visibility image per frame slot, the shaded variant of `shade`
    /// (binding 7) and, for hard shadows of the `pyramid` method, a cell pyramid of its
    /// own (built by the next record, in its `pyramid` scope). Off, all of it is retired
    /// and the plain `shade` pipeline is used again: nothing is built while it is off.
    /// The stage follows later [`DisplacementPass::set_method`],
    /// [`DisplacementPass::resize`] and [`DisplacementPass::set_height_map`] calls.
    ///
    /// The `shadow` pass runs only in frames recorded with a [`ShadeTarget`] (it
    /// darkens dispmap's colour; a host shading from the hit buffer itself gets no
    /// visibility). Its light is the frame's `ShadeTarget::light_dir`.
    ///
    /// GPU-use contract: as [`DisplacementPass::set_method`] (needs no GPU idle; what is
    /// replaced is retired until every slot has been recorded again). On an invalid
    /// `shadows` (samples) the pass is unchanged; on an allocation or pipeline failure
    /// self-shadowing stays off until a later successful call.
    pub fn set_shadows(&mut self, shadows: ShadowSettings) -> Result<()> {
        self.check_alive()?;
        shadows.validate()?;
        let old = self.shadows;
        self.shadows = shadows;
        let result = self.sync_shadows(false);
        if result.is_err() {
            self.shadows = ShadowSettings {
                mode: ShadowMode::Off,
                ..old
            };
            // Back to the plain shade pipeline where the shaded one was built.
            let _ = self.sync_shadows(false);
        }
        result
    }

    /// The self-shadowing settings in use.
    pub fn shadows(&self) -> ShadowSettings {
        self.shadows
    }

    /// Turns the corrected-depth output on (builds the `hit_depth` pipeline and one
    /// [`HIT_DEPTH_FORMAT`] image per frame slot, owned by the pass; every later record
    /// runs `hit_depth` last) or off (retires them). See the module docs for the image's
    /// layouts and [`DisplacementPass::hit_depth`] for reading it. Needs no GPU idle
    /// (what is dropped is retired like a replaced method's resources).
    pub fn set_depth_output(&mut self, on: bool) -> Result<()> {
        self.check_alive()?;
        match (on, self.depth.is_some()) {
            (true, false) => {
                self.depth = Some(DepthParts::new(
                    &self.ctx,
                    self.settings.extent,
                    self.settings.frames_in_flight,
                )?);
            }
            (false, true) => self.retired.retire(self.depth.take()),
            _ => {}
        }
        Ok(())
    }

    /// Whether the corrected-depth output is on.
    pub fn depth_output(&self) -> bool {
        self.depth.is_some()
    }

    /// The corrected depth of `frame_slot` (`R32_SFLOAT`, reverse-Z clip depth of each
    /// pixel's hit, 0 without one; [`crate::passes::hit_depth`]); `None` when the output
    /// is off. After a record of that slot it is in `GENERAL`, last written by
    /// `COMPUTE_SHADER` `SHADER_STORAGE_WRITE`; usage `STORAGE | SAMPLED | TRANSFER_SRC`.
    /// The host may read it in the same frame (after its own barrier from that state)
    /// and leave it in any layout: the next record of the slot discards it. To write it
    /// into the host's `D32_SFLOAT` attachment, record
    /// [`crate::passes::depth_resolve::DepthResolvePass`] (module docs: "Corrected
    /// depth").
    pub fn hit_depth(&self, frame_slot: u32) -> Option<&Image> {
        self.depth
            .as_ref()
            .and_then(|d| d.images.get(frame_slot as usize))
    }

    /// The light visibility of `frame_slot` (`R16_SFLOAT`, 1 = lit; written by the
    /// `shadow` pass of frames with a [`ShadeTarget`]); `None` when self-shadowing is
    /// off. After such a record it is in `GENERAL`, last read by `COMPUTE_SHADER`
    /// `SHADER_STORAGE_READ` (shade); usage `STORAGE | TRANSFER_SRC`. Read-only for the
    /// host, and only until the slot is recorded again.
    pub fn visibility(&self, frame_slot: u32) -> Option<&Image> {
        self.shadow
            .as_ref()
            .and_then(|s| s.visibility.get(frame_slot as usize))
    }

    /// The DIG corner grid of `frame_slot` (`None` unless the method is a DIG). After a
    /// record of that slot it is `SHADER_READ_ONLY_OPTIMAL`, last read by `COMPUTE_SHADER`
    /// sampled reads; read-only for the host, and only until the slot is recorded again.
    pub fn corner_grid(&self, frame_slot: u32) -> Option<&CornerGrid> {
        self.corners.get(frame_slot as usize)
    }

    /// The method's pyramid once a record has built it (`None` for methods without one,
    /// or before the build). `SHADER_READ_ONLY_OPTIMAL`, read by compute shaders;
    /// read-only for the host.
    pub fn pyramid(&self) -> Option<&Pyramid> {
        self.pyramid.as_ref().filter(|_| self.pyramid_built)
    }

    /// The cone map once a record has built it (`None` for methods without one).
    pub fn cone_map(&self) -> Option<&ConeMap> {
        self.cone.as_ref().filter(|_| self.cone_built)
    }

    /// The size of the height map in texels.
    pub fn map_size(&self) -> [u32; 2] {
        self.height.size()
    }

    /// What the shadow stage must be for the current settings (`None`: off).
    fn shadow_key(&self) -> Option<ShadowKey> {
        self.shadows.is_on().then(|| {
            let trace = ShadowTrace::for_method(self.shadows.mode, self.settings.method);
            ShadowKey {
                trace,
                own_pyramid: trace == ShadowTrace::Pyramid
                    && self.needs.pyramid != Some(PyramidKind::Cell),
                extent: self.settings.extent,
                map: self.height.size(),
                format: self.height.image.format,
            }
        })
    }

    /// Builds, keeps or retires the shadow stage and the shade variant so they fit the
    /// settings (`force`: rebuild the stage even when it fits). On failure the stage is
    /// retired (self-shadowing without resources: `record` refuses until a later
    /// successful call) and the error returned.
    fn sync_shadows(&mut self, force: bool) -> Result<()> {
        let on = self.shadows.is_on();
        let want = self.shadow_key();
        let have = self.shadow.as_ref().map(|s| s.key);
        let ctx = self.ctx.clone();
        if self.shade.is_shadowed() != on {
            let new = if on {
                ShadePass::shadowed(&ctx)
            } else {
                ShadePass::new(&ctx)
            };
            match new {
                Ok(new) => self.retired.retire(std::mem::replace(&mut self.shade, new)),
                Err(e) => {
                    self.retired.retire(self.shadow.take());
                    return Err(e);
                }
            }
        }
        if want == have && !(force && have.is_some()) {
            return Ok(());
        }
        let built = want
            .map(|key| {
                ShadowParts::new(
                    &ctx,
                    key,
                    self.settings.frames_in_flight,
                    self.settings.addressing,
                )
            })
            .transpose();
        self.retired.retire(self.shadow.take());
        self.shadow = built?;
        Ok(())
    }

    /// Destroys every object and frees every allocation the pass made. Afterwards any
    /// other call returns [`Error::Destroyed`].
    ///
    /// # Safety
    /// No GPU work recorded with this pass may be pending: every frame recorded with it
    /// has completed (the host waited on all their fences, or for the device to idle),
    /// or was never submitted.
    pub unsafe fn destroy(&mut self) {
        if self.destroyed {
            return;
        }
        let ctx = &*self.ctx;
        self.retired.destroy_all(ctx);
        self.shadow.destroy(ctx);
        self.depth.destroy(ctx);
        self.pending_fill.destroy(ctx);
        self.pending_material.destroy(ctx);
        self.material.destroy(ctx);
        self.corners.destroy(ctx);
        self.cone.destroy(ctx);
        self.pyramid.destroy(ctx);
        self.height.destroy(ctx);
        self.corner_pass.destroy(ctx);
        self.cone_pass.destroy(ctx);
        self.pyramid_pass.destroy(ctx);
        self.shade.destroy(ctx);
        self.trace.destroy(ctx);
        if let Some(pool) = self.query_pool.take() {
            // SAFETY: this function's contract: no pending use.
            unsafe { ctx.device().destroy_query_pool(pool, None) };
        }
        self.destroyed = true;
    }

    fn check_alive(&self) -> Result<()> {
        if self.destroyed {
            Err(Error::Destroyed("DisplacementPass"))
        } else {
            Ok(())
        }
    }

    fn owned_pool(&mut self) -> Result<vk::QueryPool> {
        if let Some(pool) = self.query_pool {
            return Ok(pool);
        }
        let pool = crate::timing::timestamp_pool(
            &self.ctx,
            "embed.timestamps",
            MAX_QUERIES * self.settings.frames_in_flight,
        )?;
        self.query_pool = Some(pool);
        Ok(pool)
    }
}

impl Drop for DisplacementPass {
    fn drop(&mut self) {
        #[cfg(debug_assertions)]
        if !self.destroyed {
            log::warn!(
                "DisplacementPass dropped without destroy(): its Vulkan objects and \
                 allocations leak (call destroy() once the GPU is done with it)"
            );
        }
    }
}

fn validate(ctx: &Context, s: &PassSettings) -> Result<()> {
    s.params.validate()?;
    if let Some(limit) = ctx.info().loop_limit {
        s.method.check_loop_limit(&s.params, limit)?;
    }
    if !(1..=MAX_FRAMES_IN_FLIGHT).contains(&s.frames_in_flight) {
        return Err(Error::invalid(
            "frames_in_flight",
            format!(
                "{} is outside 1..={MAX_FRAMES_IN_FLIGHT}",
                s.frames_in_flight
            ),
        ));
    }
    if !s.depth_scale.is_finite() || s.depth_scale < 0.0 {
        return Err(Error::invalid(
            "depth_scale",
            format!("{} is not a finite value >= 0", s.depth_scale),
        ));
    }
    let max = ctx.info().max_image_dimension_2d;
    let e = s.extent;
    if e.width == 0 || e.height == 0 || e.width > max || e.height > max {
        return Err(Error::invalid(
            "extent",
            format!(
                "{}x{} is outside 1..={max} per side (maxImageDimension2D)",
                e.width, e.height
            ),
        ));
    }
    Ok(())
}

fn field_size(field: &HeightField) -> [u32; 2] {
    [field.width(), field.height()]
}

fn corner_grids(ctx: &Context, s: &PassSettings) -> Result<Vec<CornerGrid>> {
    per_slot(ctx, s.frames_in_flight, |_| {
        CornerGrid::new(ctx, [s.extent.width, s.extent.height], s.params.block)
    })
}
