//! The displacement pass inside a host engine's Vulkan frame.
//!
//! The host owns the instance, device, queue, allocator, command buffers and the G-buffer.
//! It wraps its handles in a [`Context`] with [`Context::from_handles`], builds one
//! [`DisplacementPass`] for all its displaced materials, and each frame calls
//! [`DisplacementPass::record`] once, which only *records* `[upload] -> [pyramid] ->
//! [cone] -> classify -> [dig_corners] -> trace -> [shadow] -> [shade] -> [hit_depth] ->
//! [motion]`
//! into the host's command buffer. On this path dispmap never
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
//! 3. [`DisplacementPass::new`] (pipelines, per-slot resources and the first material,
//!    index 0), then [`DisplacementPass::add_material`] for every other displaced
//!    material: each has its own height map, method, parameters, depth scale, addressing
//!    and material maps ([`DisplacementPass::set_material_maps`]); its
//!    [`MaterialId::index`] is what the G-buffer writes for its pixels.
//! 4. Per frame: the host renders its G-buffer (formats and channels in
//!    [`crate::passes::gbuffer`] and `glsl/include/dispmap_gbuffer.glsl`), places the
//!    entry barriers below, calls [`DisplacementPass::record`], places its own barriers for
//!    what follows, submits and later waits on its fence; then it may read the timestamps
//!    ([`DisplacementPass::timings`] or [`read_timestamps`]). A host that draws dispmap's
//!    tiled plane (or quad) itself uses `dispmap_plane_vertex` from
//!    `glsl/include/dispmap_plane.glsl`, the function dispmap's own `gbuffer.vert` calls:
//!    with the values of [`crate::scene::Scene::gbuffer_params`] (rectangles, `plane_cells`,
//!    eye), [`crate::abi::GBufferParams::vertex_count`] vertices from `gl_VertexIndex` and
//!    the eye-relative view-projection ([`crate::scene::FrameCamera::view_proj_eye`]), and
//!    in its fragment shader `dispmap_plane_pixel_ray` (each pixel's own centre ray, from
//!    [`crate::scene::FrameCamera::pixel_ray_params`] in a uniform buffer) and
//!    `dispmap_plane_pixel_depth`, its vertices, rays, depths and hits are bit-identical to
//!    the standalone renderer's (`examples/host_engine.rs`, `tests/host_engine.rs`).
//! 5. [`DisplacementPass::add_material`] / [`DisplacementPass::remove_material`] /
//!    [`DisplacementPass::set_material_settings`] /
//!    [`DisplacementPass::set_material_height_map`] /
//!    [`DisplacementPass::set_height_map`] / [`DisplacementPass::resize`] /
//!    [`DisplacementPass::set_method`] / [`DisplacementPass::set_shadows`] /
//!    [`DisplacementPass::set_depth_output`] / [`DisplacementPass::set_motion_output`] /
//!    [`DisplacementPass::set_material`] (albedo
//!    and normal maps for `shade`) / [`DisplacementPass::set_depth_scale`] any time
//!    between records, with frames in
//!    flight (what they replace is retired, see below; for `resize` the host's images of
//!    the new size are used from the next record on). Self-shadowing and the corrected
//!    depth are off after `new` and nothing of them is built until they are turned on.
//!    To shade hits of its own (e.g. exact reference hits) exactly as a frame shades the
//!    method's, a host records [`DisplacementPass::record_shading`] instead of `record`.
//! 6. With the motion output on ([`DisplacementPass::set_motion_output`]): every record
//!    gets [`FrameInputs::motion`] (the host's motion image and its previous frame's
//!    camera) and writes the displaced pixels' motion into that image in place (see
//!    "Motion vectors" below).
//! 7. With the corrected depth on: after `record`, the host reads
//!    [`DisplacementPass::hit_depth`] of the frame's slot, e.g. to write it into its own
//!    `D32_SFLOAT` attachment (see "Corrected depth" below).
//! 8. After the device is idle (or every fence of a frame recorded with the pass has
//!    signalled): [`DisplacementPass::destroy`], then drop the context, then the host
//!    destroys its own objects.
//!
//! # Images: layout and access on entry and exit
//!
//! | image | owner | entry (the host's barrier makes it so) | exit |
//! |---|---|---|---|
//! | G-buffer `ray`, `frame` | host | `SHADER_READ_ONLY_OPTIMAL`, writes visible to `COMPUTE_SHADER` / `SHADER_SAMPLED_READ` (the barrier's `dstStageMask` / `dstAccessMask`; add `FRAGMENT_SHADER` for the `frame` when the host records the depth resolve) | unchanged; last access `COMPUTE_SHADER` sampled read |
//! | G-buffer `depth` | host | as above (depth aspect) | as above |
//! | G-buffer `curve` (`R16G16_SFLOAT`; only while a material is traced curved, [`DisplacementPass::set_material_curved`]) | host | as `ray` | as `ray` |
//! | hit uv (`R32G32_SFLOAT`) and hit height (`R32_SFLOAT`), `STORAGE` ([`HitImages`]) | host | `GENERAL`, contents discarded: the host's image barrier on each has `oldLayout = UNDEFINED`, `newLayout = GENERAL`, `srcStageMask`/`srcAccessMask` its last access, `dstStageMask = COMPUTE_SHADER`, `dstAccessMask = SHADER_STORAGE_WRITE` (the layout transition must be ordered before the pass's writes: a barrier without a destination access is a write-after-write hazard to synchronization validation) | `GENERAL`; every pixel written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (trace; classify for pixels without displacement: `NO_HIT_HEIGHT` without geometry, [`NOT_DISPLACED_HEIGHT`] for flat geometry), read by `SHADER_STORAGE_READ` (shade) |
//! | colour (`R8G8B8A8_UNORM`, `STORAGE`; only with [`ShadeTarget`]) | host | `GENERAL` with the host's colour (kept wherever nothing is displaced): the host's barrier has `srcStageMask`/`srcAccessMask` its last write, `dstStageMask = COMPUTE_SHADER`, `dstAccessMask = SHADER_STORAGE_WRITE` | `GENERAL`; displaced pixels written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (sRGB-encoded values), every other pixel as it entered |
//! | motion (`R16G16_SFLOAT` or `R32G32_SFLOAT` as [`MotionSettings::format`], `STORAGE`; only with [`DisplacementPass::set_motion_output`] on) | host | `GENERAL` with the host's motion of every pixel (source `Surface`; any contents for `Camera`): the host's barrier has `srcStageMask`/`srcAccessMask` its last write, `dstStageMask = COMPUTE_SHADER`, `dstAccessMask = SHADER_STORAGE_READ \| SHADER_STORAGE_WRITE` | `GENERAL`; displaced pixels with a hit written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE`, every other pixel as it entered |
//! | height maps, pyramids, cone maps, DIG corner grids, tile lists | pass | (internal) | (internal; read-only for the host) |
//! | host height map ([`HostHeightMap`], only for [`DisplacementPass::add_host_material`]) | host | `SHADER_READ_ONLY_OPTIMAL`, every mip level, its writes visible to `COMPUTE_SHADER` `SHADER_SAMPLED_READ` whenever a frame or preparation recorded with a material on it executes (see "Height maps the host owns") | unchanged; read only by `COMPUTE_SHADER` `SHADER_SAMPLED_READ` |
//! | visibility (`R16_SFLOAT`, one per slot; only with [`DisplacementPass::set_shadows`] on and a [`ShadeTarget`]) | pass | (internal: discarded by the pass) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (shadow), last read by `SHADER_STORAGE_READ` (shade); read-only for the host ([`DisplacementPass::visibility`]) |
//! | corrected depth (`R32_SFLOAT`, one per slot; only with [`DisplacementPass::set_depth_output`] on) | pass | any layout: the pass discards it, its barrier waits for every earlier access (`ALL_COMMANDS`) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (hit_depth); the host may read it (after its own barrier from that state) and leave it in any layout |
//! | iteration counts (`R32_UINT`, one per slot; only with [`DisplacementPass::set_iterations_output`] on) | pass | any layout: the pass discards it, its barrier waits for every earlier access (`ALL_COMMANDS`) | `GENERAL`; written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE` (trace; classify for pixels without displacement: 0) by `record`; `record_shading` leaves it alone; the host may read it (after its own barrier from that state) and leave it in any layout |
//!
//! Every host image comes as a [`HostView`] (view, format, size, usage): `record` checks
//! each against this table and the pass's frame size before it records anything, and
//! refuses a mismatch with [`Error::InvalidInput`] naming the image (`gbuffer.ray`, `hit.uv`,
//! `color`, `motion`, ...). A view's format is not visible to Vulkan's validation of a
//! storage write, so a wrong one would otherwise render garbage without a message.
//!
//! The pass places every barrier between its own passes: each stage declares what its
//! dispatches read and write (its shaders' reflected bindings) and one tracker derives
//! the barriers from each resource's last access (`src/embed/graph.rs`,
//! [`crate::gpu::track`]); the hit images', being known by their views only, are global
//! memory barriers. docs/embedding.md's table of entry and exit states is computed from
//! the same declarations (a test checks it).
//!
//! # Materials and the G-buffer
//!
//! The G-buffer's frame says which material a pixel is: `index + 1`, 0 = not displaced (`glsl/include/dispmap_gbuffer.glsl`:
//! `dispmap_gbuffer_encode_material`, `dispmap_gbuffer_encode_flat`). Each frame,
//! `classify` ([`crate::passes::classify`]) sorts the frame's 8x8 tiles into one list per
//! material, and every per-material pass (`trace`, `shadow`, `shade`, `hit_depth`) is
//! one indirect dispatch over its material's tiles with that material's map, method and
//! depth scale: a frame costs what its displaced pixels cost, not its size times its
//! materials. Pixels that are not displaced (no geometry, material 0 in the frame, an index with
//! no material in the table) are never traced or shaded. One dispatch per material with
//! push descriptors, rather than one for all through descriptor indexing: the methods are
//! different pipelines anyway, push descriptors need no descriptor pools or update-after-
//! bind, and a material's dispatch costs one indirect dispatch of its tiles (an empty list
//! dispatches no workgroup). DIG's corner grid is per material; a block with a corner of
//! another material falls back to the unconstrained search, as at a surface boundary.
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
//! # Height maps the host owns
//!
//! [`DisplacementPass::add_host_material`] (and
//! [`DisplacementPass::set_material_host_height_map`]) takes a [`HostHeightMap`]: the
//! host's own sampled image, its mip chain, and which channel holds the heights, in one of
//! [`HOST_HEIGHT_FORMATS`] (`R8`/`R16` unorm, `R16F`, `R32F`, `BC4` unorm, or a channel of
//! an `RG8`, `RGBA8`, `BGRA8`, `RGBA16` unorm, `RGBA16F`, `BC3`, `BC5` or `BC7` image, such
//! as a normal map's alpha). The pass makes two views of it (every level, and level 0
//! alone) whose component mapping puts the channel in `r` (`g`, `b` 0, `a` 1) and a linear
//! sampler with the material's addressing; it uploads, hashes and reads back nothing.
//! Every preparation (the pyramids, the cone maps) and every pass samples those views, so
//! the methods see the map exactly as the GPU decodes it, and `exact` is exact against
//! that decoding. Level of detail samples the host's mip chain as it is (one level: level 0
//! only); every other read is of level 0. Materials on the same image, channel and levels
//! with the same addressing share one map and its preparations.
//!
//! The host's contract for the image:
//!
//! * **Creation**: a 2-D image of the context's device with one array layer, `SAMPLED`
//!   usage, `VK_SHARING_MODE_EXCLUSIVE` (or ownership transferred to the context's queue
//!   family before a frame uses it), a format the device samples with linear filtering
//!   (checked: [`Error::Unsupported`]), heights in `[0, 1]` (1 = the macro surface; NaN or
//!   values outside are the host's error: dispmap never sees them on the CPU).
//! * **Layout and queue**: every level in `SHADER_READ_ONLY_OPTIMAL` with the host's
//!   writes visible to `COMPUTE_SHADER` `SHADER_SAMPLED_READ` (its barrier's
//!   `dstStageMask` / `dstAccessMask`) before any command buffer recorded with a material
//!   on it executes on the context's queue; the pass never changes its layout and only
//!   reads it (`COMPUTE_SHADER` sampled reads), so the host's next write needs only an
//!   execution dependency on `COMPUTE_SHADER`.
//! * **Lifetime**: alive and unchanged while a frame or preparation recorded with a
//!   material on it may execute, and until the material is removed or given another map
//!   and every slot has been recorded again (or the pass destroyed).
//! * **Changing it**: either a new image through
//!   [`DisplacementPass::set_material_host_height_map`] (what the old one needed is
//!   retired as a replaced map's), or the same image rewritten in place once no pending
//!   command buffer reads it (the host waited for the fences of the frames recorded with
//!   it), followed by [`DisplacementPass::host_height_map_changed`] before the next
//!   record: the pass then builds new preparations of it (the old ones are retired), in
//!   the next record or in a preparation the host records after its write.
//!
//! # Preparation the host schedules
//!
//! By default the first record after a change builds what it left pending: the `upload`,
//! `pyramid` and `cone` scopes at the start of the frame (a 4096² map's pyramid takes over
//! a second on lavapipe). [`DisplacementPass::record_preparation`] records that work into
//! a command buffer of the host's choosing instead, before the frame that first uses it
//! (the same command buffer before `record`, or an earlier submission on the context's
//! queue): `record` then finds it done, and the frame's passes and timings hold none of
//! it. [`DisplacementPass::preparation_pending`] says whether there is any. What the
//! preparation reads (staging buffers, replaced textures) and whatever is retired before
//! the next record stays alive until that frame and every slot after it have been
//! recorded again: the next frame's fence covers the preparation submitted before it.
//!
//! # Self-shadowing
//!
//! [`DisplacementPass::set_shadows`] with [`ShadowSettings`] (`off`, `hard`, `soft`;
//! [`crate::passes::shadow`] documents the light ray and the query each method gets)
//! makes every record with a [`ShadeTarget`] run `shadow` between `trace` and `shade`,
//! with the target's `light_dir`, and shade with the visibility (`u_visibility` of the
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
//! The image holds every pixel: displaced ones their corrected depth (each material with
//! its own depth scale), the others the G-buffer's own depth. To make the rest of the
//! host's frame (later geometry, fog, SSAO) meet the displaced surface, the host merges it
//! into its own `D32_SFLOAT` depth attachment (displaced pixels only: the others keep the
//! attachment's depth) with
//! [`crate::passes::depth_resolve::DepthResolvePass`] (a graphics pipeline; the host's
//! device needs `dynamicRendering`, which [`requirements`] does not list), in the same
//! command buffer after `record`:
//!
//! 1. barrier on [`DisplacementPass::hit_depth`]'s image: `GENERAL`, `COMPUTE_SHADER`
//!    `SHADER_STORAGE_WRITE` -> `SHADER_READ_ONLY_OPTIMAL`, `FRAGMENT_SHADER`
//!    `SHADER_SAMPLED_READ`; the G-buffer `frame` visible to `FRAGMENT_SHADER`
//!    `SHADER_SAMPLED_READ` (`SHADER_READ_ONLY_OPTIMAL`); barrier on the host's depth
//!    image: (its last access) -> `DEPTH_ATTACHMENT_OPTIMAL`, `EARLY/LATE_FRAGMENT_TESTS`
//!    depth read and write (contents kept: the attachment is loaded);
//! 2. `DepthResolvePass::record(ctx, cmd, image.view, frame_view, host_depth_view,
//!    extent)` (it begins and ends its own dynamic rendering);
//! 3. the host's barrier for what reads its depth next. The pass's image may be left in
//!    `SHADER_READ_ONLY_OPTIMAL`: the next record of the slot discards it.
//!
//! The host builds `DepthResolvePass::new(&ctx)` once and destroys it itself.
//!
//! # Motion vectors
//!
//! TAA, TSR, DLSS and FSR need each pixel's screen motion, and a displaced pixel moves as
//! the displaced surface does, not as the flat macro surface under it (at 1 degree of
//! elevation and a 1.7-degree camera turn the flat motion is up to 35 pixels off on the
//! method scenes; `tests/motion.rs`). [`DisplacementPass::set_motion_output`] with
//! [`MotionSettings`] makes every record run `motion` last: for each displaced pixel with
//! a hit it writes the motion of the displaced point into the host's own motion image
//! ([`FrameMotion::image`]), in place, in the host's units and direction; every other
//! pixel keeps the host's value. The previous camera is [`FrameMotion::previous`]; the
//! current one is the frame's ([`ShadeTarget`] or [`DisplacementPass::record_with_camera`]).
//! [`crate::passes::motion`] documents the formulas: exact for a static world (source
//! `Camera`, or `Surface` where the host's motion is the camera's), and for a surface
//! moving on its own (source `Surface`) exact for translations parallel to the image
//! plane, with a measured error for turning surfaces. The displaced point comes from
//! `glsl/include/dispmap_displace.glsl`, which a host's own shaders can include
//! (`DEP_DISPMAP_INCLUDE`) for the same point: the corrected depth uses it too.

mod device;
mod entries;
mod graph;
mod host_map;
mod inputs;
mod map_preparations;
mod materials;
mod memory;
mod plan;
mod prepare;
mod record;

pub use device::{
    MAX_FRAMES_IN_FLIGHT, MAX_QUERIES, PUSH_CONSTANT_BYTES, PUSH_DESCRIPTORS, Requirements,
    check_device_create_info, check_physical_device, requirements,
};

use crate::context::Context;
use crate::error::{Error, Result};
pub use crate::gpu::HostView;
use crate::gpu::Image;
use crate::gpu::owned::{Destroy, Guard, RetireQueue};
use crate::heightfield::{Addressing, HeightField};
use crate::material::{MaterialImages, MaterialTextures};
use crate::method::{Method, MethodParams};
use crate::passes::classify::ClassifyPass;
use crate::passes::cone::{ConeMap, ConePass};
use crate::passes::dig::{CornerGrid, DigCornerPass};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::hit_depth::HitDepthPass;
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::passes::shade::ShadePass;
use crate::passes::shadow::ShadowPass;
use crate::passes::trace::TracePass;
use ash::vk;
use glam::{Mat4, Vec3};
use std::sync::Arc;

pub use crate::abi::{MAX_MATERIALS, NOT_DISPLACED_HEIGHT};
pub use crate::passes::PassName;
pub use crate::passes::gbuffer::{DEPTH_FORMAT, FRAME_FORMAT, RAY_FORMAT};
pub use crate::passes::hit_depth::HIT_DEPTH_FORMAT;
pub use crate::passes::motion::{
    DepthCamera, FrameMotion, MOTION_FORMATS, MotionDirection, MotionSettings, MotionSource,
    MotionUnits,
};
pub use crate::passes::shade::COLOR_FORMAT;
pub use crate::passes::shadow::{ShadowMode, ShadowSettings, VISIBILITY_FORMAT};
pub use crate::passes::trace::{HIT_HEIGHT_FORMAT, HIT_UV_FORMAT, HitViews, ITERATIONS_FORMAT};
pub use crate::timing::{TimestampScope, read_timestamps};
pub use host_map::{HOST_HEIGHT_FORMATS, HeightChannel, HostHeightMap};
pub use inputs::{
    FrameInputs, HitImages, MaterialId, MaterialSettings, PassSettings, RecordedFrame, ShadeTarget,
    Timestamps,
};
pub use memory::{MaterialMemory, MemoryReport};

/// The frame-wide settings: the frame size and the frames in flight.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrameSettings {
    extent: vk::Extent2D,
    frames_in_flight: u32,
}

/// The displacement pass for a host engine (see the module docs for the contract), and
/// the one orchestrator of dispmap's compute passes: the standalone
/// [`crate::renderer::Renderer`] is a host of it like any engine.
///
/// Holds a table of displaced materials ([`DisplacementPass::add_material`]), each with
/// its height map, method and depth scale, and builds for each only what its method
/// needs (shared between materials with the same map); one set of per-slot images for the
/// whole frame. Destroy it explicitly with [`DisplacementPass::destroy`]; in debug builds
/// one dropped without it logs a warning (and leaks its objects).
pub struct DisplacementPass {
    /// The context (`None` once destroyed: the pass keeps no `Arc<Context>` after
    /// [`DisplacementPass::destroy`]).
    ctx: Option<Arc<Context>>,
    frame: FrameSettings,
    /// The first material's settings and the frame's (what [`DisplacementPass::settings`]
    /// returns), kept in step with the table.
    primary_settings: PassSettings,
    /// The handle of the material `new` made.
    primary: MaterialId,
    materials: Vec<Option<plan::MaterialEntry>>,
    maps: Vec<Option<plan::MapEntry>>,
    next_generation: u32,
    traces: Vec<TracePass>,
    shade: ShadePass,
    classify: ClassifyPass,
    pyramid_pass: Option<PyramidPass>,
    corner_pass: Option<DigCornerPass>,
    cone_passes: Vec<ConePass>,
    /// The pipelines of the map preparations with a map to prepare.
    prepare_passes: Vec<plan::PreparePass>,
    /// The map preparations the host asked for (indices of
    /// [`crate::passes::prepare::KINDS`]; [`DisplacementPass::set_map_preparation`]).
    prepare_requested: Vec<usize>,
    shadow_passes: Vec<ShadowPass>,
    /// What each frame in flight owns, by frame slot (built by the first sync).
    slots: Vec<plan::Slot>,
    /// The corrected-depth pipeline (`None` when off; its images are the slots').
    depth: Option<HitDepthPass>,
    /// Whether the corrected depth is requested.
    depth_on: bool,
    /// Whether the iteration counts are requested.
    iterations_on: bool,
    /// The motion pass (`None` when off).
    motion: Option<crate::passes::motion::MotionPass>,
    /// The motion output as requested.
    motion_on: Option<MotionSettings>,
    /// The frame size the frame-sized resources were built for.
    built_extent: vk::Extent2D,
    query_pool: Option<vk::QueryPool>,
    retired: RetireQueue,
    /// The retire queue's length when a preparation was recorded since the last frame
    /// ([`DisplacementPass::record_preparation`]).
    prepared_mark: Option<usize>,
    /// Self-shadowing as set by [`DisplacementPass::set_shadows`].
    shadows: ShadowSettings,
    /// The meshes the curved `exact` trace walks
    /// ([`DisplacementPass::set_curved_meshes`]; empty by default).
    walk: crate::mesh::walk::WalkMeshes,
}

impl DisplacementPass {
    /// Builds the pipelines and the per-slot resources, and a table with one material
    /// (`field` with `settings`' method, parameters, depth scale and addressing; its
    /// handle is [`DisplacementPass::primary`], index 0), staged for upload (the first
    /// [`DisplacementPass::record`] copies it and builds what its method needs). Records
    /// and submits nothing.
    pub fn new(ctx: Arc<Context>, field: &HeightField, settings: PassSettings) -> Result<Self> {
        Self::with_iterations(ctx, field, settings, false)
    }

    /// [`DisplacementPass::new`] with the iteration-count output on from the start
    /// ([`DisplacementPass::set_iterations_output`]), so that the trace pipelines are
    /// built once, in their variant that writes the counts.
    pub fn with_iterations(
        ctx: Arc<Context>,
        field: &HeightField,
        settings: PassSettings,
        iterations: bool,
    ) -> Result<Self> {
        validate_frame(&ctx, settings.extent, settings.frames_in_flight)?;
        validate_material(&ctx, &settings.material())?;
        let c = &*ctx;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let shade = unsafe { Guard::new(c, ShadePass::new(c)?) };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let classify = unsafe { Guard::new(c, ClassifyPass::new(c)?) };
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let walk = unsafe { Guard::new(c, crate::mesh::walk::WalkMeshes::new(c, &[])?) };
        let mut pass = DisplacementPass {
            frame: FrameSettings {
                extent: settings.extent,
                frames_in_flight: settings.frames_in_flight,
            },
            primary_settings: settings,
            primary: MaterialId {
                index: 0,
                generation: 0,
            },
            materials: Vec::new(),
            maps: Vec::new(),
            next_generation: 0,
            traces: Vec::new(),
            shade: shade.keep(),
            classify: classify.keep(),
            pyramid_pass: None,
            corner_pass: None,
            cone_passes: Vec::new(),
            prepare_passes: Vec::new(),
            prepare_requested: Vec::new(),
            shadow_passes: Vec::new(),
            slots: Vec::new(),
            depth: None,
            depth_on: false,
            iterations_on: iterations,
            motion: None,
            motion_on: None,
            built_extent: vk::Extent2D::default(),
            query_pool: None,
            retired: RetireQueue::new(settings.frames_in_flight),
            prepared_mark: None,
            shadows: ShadowSettings::default(),
            walk: walk.keep(),
            ctx: Some(ctx),
        };
        match pass.add_material(field, settings.material()) {
            Ok(id) => {
                pass.primary = id;
                Ok(pass)
            }
            Err(e) => {
                // SAFETY: nothing was recorded with the pass.
                unsafe { pass.destroy() };
                Err(e)
            }
        }
    }

    /// The settings of the first material ([`DisplacementPass::primary`]) and the frame.
    pub fn settings(&self) -> &PassSettings {
        &self.primary_settings
    }

    /// The context the pass was built with ([`Error::Destroyed`] after
    /// [`DisplacementPass::destroy`], which lets go of it).
    pub fn context(&self) -> Result<&Arc<Context>> {
        self.ctx
            .as_ref()
            .ok_or(Error::Destroyed("DisplacementPass"))
    }

    /// The handle of the material [`DisplacementPass::new`] made (the one the
    /// single-material calls such as [`DisplacementPass::set_method`] act on).
    pub fn primary(&self) -> MaterialId {
        self.primary
    }

    /// Whether the next [`DisplacementPass::record`] fills a height texture (a new map, or
    /// the mip chain added or dropped with level of detail) or builds a pyramid or cone
    /// map.
    pub fn rebuild_pending(&self) -> bool {
        self.maps.iter().flatten().any(plan::MapEntry::pending)
    }

    /// Per-pass milliseconds of the last frame recorded in `frame_slot` with
    /// [`Timestamps::Owned`] (empty if it recorded none). Call after that frame's fence
    /// signalled and before the slot is recorded again; an unfinished frame gives an
    /// error (`VK_NOT_READY`), never a wait.
    pub fn timings(&self, frame_slot: u32) -> Result<Vec<(PassName, f64)>> {
        let slot = self
            .slots
            .get(frame_slot as usize)
            .ok_or_else(|| Error::invalid("frame_slot", format!("no slot {frame_slot}")))?;
        // SAFETY: the scopes name the pass's own live pool; reading without WAIT cannot
        // block, and an unwritten or unfinished query is an error, not undefined.
        unsafe { read_timestamps(self.context()?, &slot.scopes) }
    }

    /// [`DisplacementPass::set_material_height_map`] of the first material
    /// ([`DisplacementPass::primary`]).
    pub fn set_height_map(&mut self, field: &HeightField) -> Result<()> {
        self.set_material_height_map(self.primary, field)
    }

    /// [`DisplacementPass::set_material_maps`] of the first material.
    pub fn set_material(&mut self, images: &MaterialImages) -> Result<()> {
        self.set_material_maps(self.primary, images)
    }

    /// Changes the first material's displacement depth (uv units; the value the host's
    /// G-buffer used for `P`) from the next record on. Builds nothing.
    pub fn set_depth_scale(&mut self, depth_scale: f32) -> Result<()> {
        let settings = MaterialSettings {
            depth_scale,
            ..self.material_settings(self.primary)?
        };
        self.set_material_settings(self.primary, settings)
    }

    /// Switches the first material's method and parameters
    /// ([`DisplacementPass::set_material_settings`] with its depth scale and addressing).
    pub fn set_method(&mut self, method: Method, params: MethodParams) -> Result<()> {
        let settings = MaterialSettings {
            method,
            params,
            ..self.material_settings(self.primary)?
        };
        self.set_material_settings(self.primary, settings)
    }

    /// Changes the frame size (the host's G-buffer, hit images and colour image must
    /// have the new size from the next record on). Frame-sized resources of the old size
    /// (tile lists, DIG grids, visibility, corrected depth) are retired, not destroyed at
    /// once, so this needs no GPU idle. On error the pass is unchanged.
    pub fn resize(&mut self, extent: vk::Extent2D) -> Result<()> {
        self.check_alive()?;
        validate_frame(self.context()?, extent, self.frame.frames_in_flight)?;
        let old = self.frame.extent;
        self.frame.extent = extent;
        if let Err(e) = self.sync() {
            self.frame.extent = old;
            return Err(e);
        }
        self.primary_settings.extent = extent;
        Ok(())
    }

    /// Switches self-shadowing (see [`crate::passes::shadow`] for the modes) for every
    /// material. On, the pass builds what it lacks: the `shadow` pipeline of each
    /// material's query, one `R16_SFLOAT` visibility image per frame slot, the shaded
    /// variant of `shade` (`u_visibility`) and, for hard shadows of the methods answered by
    /// the cell pyramid, a cell pyramid of the material's map (built by the next record,
    /// in its `pyramid` scope). Off, all of it is retired and the plain `shade` pipeline
    /// is used again: nothing is built while it is off. The stage follows later changes
    /// of the table.
    ///
    /// The `shadow` pass runs only in frames recorded with a [`ShadeTarget`] (it
    /// darkens dispmap's colour; a host shading from the hit images itself gets no
    /// visibility). Its light is the frame's `ShadeTarget::light_dir`.
    ///
    /// GPU-use contract: as [`DisplacementPass::set_material_settings`]. On error
    /// (invalid samples, an allocation or pipeline failure) the pass is unchanged.
    pub fn set_shadows(&mut self, shadows: ShadowSettings) -> Result<()> {
        self.check_alive()?;
        shadows.validate()?;
        let old = self.shadows;
        self.shadows = shadows;
        if let Err(e) = self.sync() {
            self.shadows = old;
            return Err(e);
        }
        Ok(())
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
        let old = self.depth_on;
        self.depth_on = on;
        if let Err(e) = self.sync() {
            self.depth_on = old;
            return Err(e);
        }
        Ok(())
    }

    /// Whether the corrected-depth output is on.
    pub fn depth_output(&self) -> bool {
        self.depth.is_some()
    }

    /// Turns the iteration-count output on (every trace pipeline is rebuilt in its
    /// variant that also writes each pixel's iteration count, the height-field or pyramid
    /// fetches its method spent, and the pass owns one [`ITERATIONS_FORMAT`] image per
    /// frame slot; every later `record` or `record_with_camera` writes it, 0 at pixels
    /// without displacement) or off (retires them; the default: a host that does not
    /// profile its methods holds no such image). Read it with
    /// [`DisplacementPass::iterations`]. Needs no GPU idle. On error (an allocation or
    /// pipeline failure) the pass is unchanged.
    pub fn set_iterations_output(&mut self, on: bool) -> Result<()> {
        self.check_alive()?;
        let old = self.iterations_on;
        self.iterations_on = on;
        if let Err(e) = self.sync() {
            self.iterations_on = old;
            return Err(e);
        }
        Ok(())
    }

    /// Whether the iteration-count output is on.
    pub fn iterations_output(&self) -> bool {
        self.iterations_on
    }

    /// The iteration counts of `frame_slot` (`R32_UINT`, [`ITERATIONS_FORMAT`]: each
    /// displaced pixel's height-field or pyramid fetches, 0 at every other pixel);
    /// `None` when the output is off. After a `record` or `record_with_camera` of that
    /// slot it is in `GENERAL`, last written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE`
    /// (`record_shading` leaves it alone); usage `STORAGE | TRANSFER_SRC | TRANSFER_DST`. The host may
    /// read it (after its own barrier from that state) and leave it in any layout: the
    /// next record of the slot discards it.
    pub fn iterations(&self, frame_slot: u32) -> Option<&Image> {
        self.slots.get(frame_slot as usize)?.iterations.as_ref()
    }

    /// Turns the motion output on with `settings` (builds the `motion` pipeline for the
    /// settings' image format; every later record then writes the motion of each
    /// displaced pixel into [`FrameInputs::motion`]'s image, after `hit_depth`) or off
    /// (`None`; retires it). [`crate::passes::motion`] documents the image's contract,
    /// the units, and the approximation for moving objects. Needs no GPU idle. On error
    /// (a format that is not one of [`MOTION_FORMATS`] or that the device cannot store
    /// to, a pipeline failure) the pass is unchanged.
    pub fn set_motion_output(&mut self, settings: Option<MotionSettings>) -> Result<()> {
        self.check_alive()?;
        if let Some(m) = &settings {
            m.validate(self.context()?)?;
        }
        let old = self.motion_on;
        self.motion_on = settings;
        if let Err(e) = self.sync() {
            self.motion_on = old;
            return Err(e);
        }
        Ok(())
    }

    /// The motion output's settings (`None`: off).
    pub fn motion_output(&self) -> Option<MotionSettings> {
        self.motion_on
    }

    /// The corrected depth of `frame_slot` (`R32_SFLOAT`, reverse-Z clip depth of each
    /// displaced pixel's hit, 0 without one, and the G-buffer's own depth for every other
    /// pixel; [`crate::passes::hit_depth`]); `None` when the output is off. After a record
    /// of that slot it is in `GENERAL`, last written by `COMPUTE_SHADER`
    /// `SHADER_STORAGE_WRITE`; usage `STORAGE | SAMPLED | TRANSFER_SRC | TRANSFER_DST`. The host may read
    /// it in the same frame (after its own barrier from that state) and leave it in any
    /// layout: the next record of the slot discards it. To merge it into the host's
    /// `D32_SFLOAT` attachment, record [`crate::passes::depth_resolve::DepthResolvePass`]
    /// (module docs: "Corrected depth").
    pub fn hit_depth(&self, frame_slot: u32) -> Option<&Image> {
        self.slots.get(frame_slot as usize)?.hit_depth.as_ref()
    }

    /// The tiles of each live material in `frame_slot`'s lists, as the slot's last
    /// `classify` wrote them (the lists' buffers stay written until the slot is recorded
    /// again): for a pass over the displaced pixels of a recorded frame (the standalone
    /// renderer's missed tiles, `crate::passes::behind_tiles`). After a record the tile
    /// buffer and the arguments were last written by `COMPUTE_SHADER`
    /// `SHADER_STORAGE_WRITE`.
    pub(crate) fn live_tiles(
        &self,
        frame_slot: u32,
    ) -> Vec<crate::passes::classify::MaterialTiles> {
        if (frame_slot as usize) >= self.slots.len() {
            return Vec::new();
        }
        self.live(frame_slot)
            .into_iter()
            .map(|(t, _, _)| t)
            .collect()
    }

    /// The light visibility of `frame_slot` (`R16_SFLOAT`, 1 = lit; written by the
    /// `shadow` pass of frames with a [`ShadeTarget`] for displaced pixels); `None` when
    /// self-shadowing is off. After such a record it is in `GENERAL`, last read by
    /// `COMPUTE_SHADER` `SHADER_STORAGE_READ` (shade); usage `STORAGE | TRANSFER_SRC`.
    /// Read-only for the host, and only until the slot is recorded again.
    pub fn visibility(&self, frame_slot: u32) -> Option<&Image> {
        self.slots.get(frame_slot as usize)?.visibility.as_ref()
    }

    /// The first material's DIG corner grid of `frame_slot` (`None` unless its method is
    /// a DIG). After a record of that slot it is `SHADER_READ_ONLY_OPTIMAL`, last read by
    /// `COMPUTE_SHADER` sampled reads; read-only for the host, and only until the slot is
    /// recorded again.
    pub fn corner_grid(&self, frame_slot: u32) -> Option<&CornerGrid> {
        self.material_corner_grid(self.primary, frame_slot)
    }

    /// A material's DIG corner grid of `frame_slot` (as [`DisplacementPass::corner_grid`]).
    pub fn material_corner_grid(&self, id: MaterialId, frame_slot: u32) -> Option<&CornerGrid> {
        let i = self.entry_index(id).ok()?;
        self.slots.get(frame_slot as usize)?.corner_grid(i)
    }

    /// The first material's method pyramid once a record has built it (`None` for
    /// methods without one, or before the build). `SHADER_READ_ONLY_OPTIMAL`, read by
    /// compute shaders; read-only for the host.
    pub fn pyramid(&self) -> Option<&Pyramid> {
        let m = self.entry(self.primary).ok()?;
        let kind = m.settings.method.needs().pyramid?;
        self.maps[m.map].as_ref()?.pyramid(kind)
    }

    /// The first material's cone map once a record has built it (`None` for methods
    /// without one).
    pub fn cone_map(&self) -> Option<&ConeMap> {
        let m = self.entry(self.primary).ok()?;
        let kind = m.settings.method.needs().cone?;
        self.maps[m.map].as_ref()?.cone(kind)
    }

    /// The size of the first material's height map in texels.
    pub fn map_size(&self) -> [u32; 2] {
        self.entry(self.primary)
            .ok()
            .and_then(|m| self.maps[m.map].as_ref())
            .map_or([0, 0], |m| m.texture.size())
    }

    /// The number of distinct height textures the table holds (materials with the same
    /// map and addressing share one).
    pub fn map_count(&self) -> usize {
        self.maps.iter().flatten().count()
    }

    /// Destroys every object and frees every allocation the pass made, and lets go of
    /// the context (the host's `Arc::into_inner` succeeds without dropping the pass).
    /// Afterwards any other call returns [`Error::Destroyed`] (or an empty value).
    ///
    /// # Safety
    /// No GPU work recorded with this pass may be pending: every frame recorded with it
    /// has completed (the host waited on all their fences, or for the device to idle),
    /// or was never submitted.
    pub unsafe fn destroy(&mut self) {
        let Some(ctx) = self.ctx.take() else {
            return;
        };
        let ctx = &*ctx;
        // SAFETY: this function's contract: no frame recorded with the pass is pending.
        unsafe {
            self.retired.destroy_all(ctx);
            self.materials.destroy(ctx);
            self.maps.destroy(ctx);
            self.depth.destroy(ctx);
            self.motion.destroy(ctx);
            self.slots.destroy(ctx);
            self.shadow_passes.destroy(ctx);
            self.cone_passes.destroy(ctx);
            self.prepare_passes.destroy(ctx);
            self.corner_pass.destroy(ctx);
            self.pyramid_pass.destroy(ctx);
            self.classify.destroy(ctx);
            self.shade.destroy(ctx);
            self.traces.destroy(ctx);
            self.walk.destroy(ctx);
        }
        if let Some(pool) = self.query_pool.take() {
            // SAFETY: this function's contract: no pending use.
            unsafe { ctx.device().destroy_query_pool(pool, None) };
        }
    }

    /// Destroys `value`, made for the pass, at once (nothing if the pass is destroyed: it
    /// then holds no context, and nothing it made is alive).
    ///
    /// # Safety
    /// No command buffer uses `value` (it was never recorded).
    unsafe fn destroy_unused(&self, mut value: impl Destroy) {
        if let Some(ctx) = &self.ctx {
            // SAFETY: this function's contract.
            unsafe { value.destroy(ctx) };
        }
    }

    fn check_alive(&self) -> Result<()> {
        self.context().map(|_| ())
    }

    fn owned_pool(&mut self) -> Result<vk::QueryPool> {
        if let Some(pool) = self.query_pool {
            return Ok(pool);
        }
        let pool = crate::timing::timestamp_pool(
            self.context()?,
            "embed.timestamps",
            MAX_QUERIES * self.frame.frames_in_flight,
        )?;
        self.query_pool = Some(pool);
        Ok(pool)
    }
}

impl Drop for DisplacementPass {
    fn drop(&mut self) {
        #[cfg(debug_assertions)]
        if self.ctx.is_some() {
            log::warn!(
                "DisplacementPass dropped without destroy(): its Vulkan objects and \
                 allocations leak (call destroy() once the GPU is done with it)"
            );
        }
    }
}

fn validate_material(ctx: &Context, s: &MaterialSettings) -> Result<()> {
    s.params.validate()?;
    if let Some(limit) = ctx.info().loop_limit {
        s.method.check_loop_limit(&s.params, limit)?;
    }
    if !s.depth_scale.is_finite() || s.depth_scale < 0.0 {
        return Err(Error::invalid(
            "depth_scale",
            format!("{} is not a finite value >= 0", s.depth_scale),
        ));
    }
    Ok(())
}

fn validate_frame(ctx: &Context, e: vk::Extent2D, frames_in_flight: u32) -> Result<()> {
    if !(1..=MAX_FRAMES_IN_FLIGHT).contains(&frames_in_flight) {
        return Err(Error::invalid(
            "frames_in_flight",
            format!("{frames_in_flight} is outside 1..={MAX_FRAMES_IN_FLIGHT}"),
        ));
    }
    let max = ctx.info().max_image_dimension_2d;
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
