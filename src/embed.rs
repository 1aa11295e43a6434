//! The displacement pass inside a host engine's Vulkan frame.
//!
//! The host owns the instance, device, queue, allocator, command buffers and the G-buffer.
//! It wraps its handles in a [`Context`] with [`Context::from_handles`], builds one
//! [`DisplacementPass`], and each frame calls [`DisplacementPass::record`], which only
//! *records* `[height_upload] -> [pyramid] -> [dig_corners] -> trace -> [shadow] ->
//! [shade] -> [hit_depth]` into the host's command buffer. On this path dispmap never creates a device, a command pool or a
//! fence, and never submits: the host submits with its own fence.
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
//!    [`DisplacementPass::set_depth_output`] any time between records, with frames in
//!    flight (what they replace is retired, see below; for `resize` the host's images of
//!    the new size are used from the next record on). Self-shadowing and the corrected
//!    depth are off after `new` and nothing of them is built until they are turned on.
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

use crate::abi::ShadeParams;
use crate::context::{Context, requirements as context_requirements};
use crate::error::{Error, Result, VkContext};
use crate::gpu::Image;
use crate::gpu::sync::{self, Access};
use crate::gpu::{Buffer, HeightTexture, ViewRef};
use crate::heightfield::{Addressing, HeightField};
use crate::method::PyramidKind;
use crate::method::{Method, MethodParams, Needs};
use crate::passes::dig::{CornerGrid, DigCornerPass};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::hit_depth::{HitDepthInputs, HitDepthPass};
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::passes::shade::{ShadeInputs, ShadePass};
use crate::passes::shadow::{ShadowInputs, ShadowPass, ShadowTrace};
use crate::passes::trace::{TraceInputs, TracePass};
use ash::vk;
use glam::{Mat4, Vec3};
use std::ffi::CStr;
use std::sync::Arc;

pub use crate::passes::gbuffer::{DEPTH_FORMAT, FRAME_FORMAT, RAY_FORMAT};
pub use crate::passes::hit_depth::HIT_DEPTH_FORMAT;
pub use crate::passes::shade::COLOR_FORMAT;
pub use crate::passes::shadow::{ShadowMode, ShadowSettings, VISIBILITY_FORMAT};
pub use crate::passes::trace::HIT_FORMAT;

/// Timestamp queries one [`DisplacementPass::record`] writes at most: a begin/end pair
/// for each of `height_upload`, `pyramid`, `dig_corners`, `trace`, `shadow`, `shade` and
/// `hit_depth`.
pub const MAX_QUERIES: u32 = 14;

/// Largest `frames_in_flight` a pass accepts.
pub const MAX_FRAMES_IN_FLIGHT: u32 = 16;

/// The push-constant bytes the largest pass uses (`shade`: [`ShadeParams`]).
pub const PUSH_CONSTANT_BYTES: u32 = std::mem::size_of::<ShadeParams>() as u32;

/// Descriptors the largest pass pushes: the shaded `shade` variant of self-shadowing (8:
/// bindings 0 to 7; `trace` of the DIG methods pushes 7). Every Vulkan device with
/// `VK_KHR_push_descriptor` has at least 32.
pub const PUSH_DESCRIPTORS: u32 = 8;

/// What the pass needs from the host's device (see [`requirements`]).
#[derive(Clone, Debug)]
pub struct Requirements {
    /// Minimum `VkPhysicalDeviceProperties::apiVersion`.
    pub api_version: u32,
    /// Device extensions to enable.
    pub device_extensions: &'static [&'static CStr],
    /// `VkPhysicalDeviceVulkan13Features` members to enable (by their Vulkan names).
    pub vulkan13_features: &'static [&'static str],
    /// Minimum `maxPushConstantsSize`, bytes.
    pub max_push_constants_size: u32,
    /// Minimum `VkPhysicalDevicePushDescriptorPropertiesKHR::maxPushDescriptors`.
    pub max_push_descriptors: u32,
    /// `timestampComputeAndGraphics` must be true (the pass's timestamps).
    pub timestamp_compute_and_graphics: bool,
    /// Formats and the optimal-tiling features each needs.
    pub formats: &'static [(vk::Format, vk::FormatFeatureFlags)],
}

impl Requirements {
    /// Sets the required members of a `VkPhysicalDeviceVulkan13Features` the host chains
    /// into its `VkDeviceCreateInfo` (keeping what the host enabled itself, e.g. its own
    /// `dynamicRendering`).
    pub fn enable_vulkan13<'a>(
        &self,
        features: vk::PhysicalDeviceVulkan13Features<'a>,
    ) -> vk::PhysicalDeviceVulkan13Features<'a> {
        features.synchronization2(true)
    }
}

/// The device features, extensions and limits the displacement pass needs.
///
/// Only what the pass records needs to be *enabled*: `VK_KHR_push_descriptor` (every
/// pass pushes its descriptors) and `synchronization2` (every barrier and timestamp).
/// `dynamicRendering` is not listed: only dispmap's own G-buffer pass (the standalone
/// [`crate::renderer::Renderer`]) uses it, and the host enables it only if its own
/// rendering does.
///
/// What is *checked on the physical device* ([`check_physical_device`], and
/// [`Context::from_handles`] again) stays the standalone set of
/// [`Context::check_device`], which also asks for `dynamicRendering` *support* and the
/// attachment features of the G-buffer formats: both checks then accept the same
/// devices. This excludes no Vulkan 1.3 device that could run the pass with a
/// rasterised G-buffer: `dynamicRendering` support is mandatory in Vulkan 1.3, and the
/// host renders its G-buffer into those formats as attachments itself.
pub fn requirements() -> Requirements {
    Requirements {
        api_version: context_requirements::API_VERSION,
        device_extensions: context_requirements::DEVICE_EXTENSIONS,
        vulkan13_features: &["synchronization2"],
        max_push_constants_size: PUSH_CONSTANT_BYTES,
        max_push_descriptors: PUSH_DESCRIPTORS,
        timestamp_compute_and_graphics: true,
        formats: context_requirements::FORMATS,
    }
}

/// Checks that a physical device *supports* everything in [`requirements`]; the error
/// ([`Error::Unsupported`]) lists every missing item by its Vulkan name.
///
/// # Safety
/// `physical_device` must have been enumerated from `instance`, which must be alive.
pub unsafe fn check_physical_device(
    instance: &ash::Instance,
    physical_device: vk::PhysicalDevice,
) -> Result<()> {
    let mut missing = Vec::new();
    if let Err(m) = Context::check_device(instance, physical_device) {
        missing.push(m);
    }
    let wanted = requirements();
    let mut push = vk::PhysicalDevicePushDescriptorPropertiesKHR::default();
    let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut push);
    // SAFETY: the caller guarantees the handles; the chain outlives the call.
    unsafe { instance.get_physical_device_properties2(physical_device, &mut props) };
    let limits = props.properties.limits;
    let name = props
        .properties
        .device_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    if limits.max_push_constants_size < wanted.max_push_constants_size {
        missing.push(format!(
            "maxPushConstantsSize >= {} (has {})",
            wanted.max_push_constants_size, limits.max_push_constants_size
        ));
    }
    if push.max_push_descriptors < wanted.max_push_descriptors {
        missing.push(format!(
            "maxPushDescriptors >= {} (has {})",
            wanted.max_push_descriptors, push.max_push_descriptors
        ));
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(Error::Unsupported {
            device: name,
            what: missing.join(", "),
        })
    }
}

/// Checks that the host's `VkDeviceCreateInfo` *enables* what the pass needs: the
/// extensions of [`requirements`] and `synchronization2` (in a chained
/// `VkPhysicalDeviceVulkan13Features` or `VkPhysicalDeviceSynchronization2Features`;
/// `dynamicRendering` is not needed by the pass). Call it with the same create info
/// before (or after) `vkCreateDevice`: a device created without them would only show
/// validation errors later. The error lists every missing item.
///
/// # Safety
/// `info` must be a valid `VkDeviceCreateInfo`: its extension-name array and `pNext`
/// chain must point to live, correctly typed Vulkan structures.
pub unsafe fn check_device_create_info(info: &vk::DeviceCreateInfo) -> Result<()> {
    let mut missing = Vec::new();
    let names: Vec<&CStr> = (0..info.enabled_extension_count as usize)
        .map(|i| {
            // SAFETY: the caller guarantees `pp_enabled_extension_names` holds
            // `enabled_extension_count` NUL-terminated strings.
            unsafe { CStr::from_ptr(*info.pp_enabled_extension_names.add(i)) }
        })
        .collect();
    for want in requirements().device_extensions {
        if !names.contains(want) {
            missing.push(want.to_string_lossy().into_owned());
        }
    }
    let mut sync2 = false;
    let mut next = info.p_next as *const vk::BaseInStructure<'_>;
    while !next.is_null() {
        // SAFETY: every structure of a valid pNext chain starts with sType and pNext.
        let base = unsafe { &*next };
        match base.s_type {
            vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_3_FEATURES => {
                // SAFETY: the sType says which structure this is.
                let f = unsafe { &*(next as *const vk::PhysicalDeviceVulkan13Features<'_>) };
                sync2 |= f.synchronization2 == vk::TRUE;
            }
            vk::StructureType::PHYSICAL_DEVICE_SYNCHRONIZATION_2_FEATURES => {
                // SAFETY: as above.
                let f =
                    unsafe { &*(next as *const vk::PhysicalDeviceSynchronization2Features<'_>) };
                sync2 |= f.synchronization2 == vk::TRUE;
            }
            _ => {}
        }
        next = base.p_next;
    }
    if !sync2 {
        missing.push("synchronization2 (not enabled)".into());
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(Error::Unsupported {
            device: "the host's VkDeviceCreateInfo".into(),
            what: missing.join(", "),
        })
    }
}

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

/// One timed pass of a recorded frame: its name and its begin/end queries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimestampScope {
    /// `height_upload`, `pyramid`, `dig_corners`, `trace`, `shadow`, `shade` or
    /// `hit_depth`.
    pub name: &'static str,
    /// The pool holding the queries.
    pub pool: vk::QueryPool,
    /// Query written before the pass.
    pub begin_query: u32,
    /// Query written after the pass.
    pub end_query: u32,
}

/// What [`DisplacementPass::record`] recorded.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RecordedFrame {
    /// The passes recorded, in order.
    pub passes: Vec<&'static str>,
    /// Their timestamp queries (empty with [`Timestamps::Off`]).
    pub timestamps: Vec<TimestampScope>,
}

/// Per-pass milliseconds of a frame's timestamps, in recording order.
///
/// # Safety
/// The pools in `scopes` must be alive and belong to `ctx`'s device, and the frame that
/// wrote them must have completed (its fence signalled) and not been re-recorded since.
pub unsafe fn read_timestamps(
    ctx: &Context,
    scopes: &[TimestampScope],
) -> Result<Vec<(&'static str, f64)>> {
    let bits = ctx.info().timestamp_valid_bits;
    let mask = if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let period = ctx.info().timestamp_period_ns as f64;
    scopes
        .iter()
        .map(|s| {
            let mut begin = [0u64; 1];
            let mut end = [0u64; 1];
            // SAFETY: the caller guarantees the pool and that the frame completed; without
            // WAIT an unavailable query is reported (NOT_READY), never waited for.
            unsafe {
                let dev = ctx.device();
                dev.get_query_pool_results(
                    s.pool,
                    s.begin_query,
                    &mut begin,
                    vk::QueryResultFlags::TYPE_64,
                )
                .vk("vkGetQueryPoolResults")?;
                dev.get_query_pool_results(
                    s.pool,
                    s.end_query,
                    &mut end,
                    vk::QueryResultFlags::TYPE_64,
                )
                .vk("vkGetQueryPoolResults")?;
            }
            let ticks = (end[0] & mask).wrapping_sub(begin[0] & mask) & mask;
            Ok((s.name, ticks as f64 * period / 1e6))
        })
        .collect()
}

/// A height texture's contents not yet recorded.
enum Fill {
    /// A new map's staging buffer.
    Upload(Buffer),
    /// The texture it replaces (level of detail switched on or off: the mip chain added
    /// or dropped), whose level 0 is copied; frames in flight may still sample it.
    Copy(HeightTexture),
}

/// A resource replaced while frames may still read it; destroyed once every slot in
/// `pending` has been recorded again.
struct Retired {
    pending: u64,
    resource: Resource,
}

enum Resource {
    Buffer(Buffer),
    Height(HeightTexture),
    Pyramid(Pyramid),
    Corners(CornerGrid),
    Trace(TracePass),
    PyramidPass(PyramidPass),
    CornerPass(DigCornerPass),
    Shade(ShadePass),
    Shadow(ShadowParts),
    Depth(DepthParts),
}

impl Resource {
    fn destroy(&mut self, ctx: &Context) {
        match self {
            Resource::Buffer(b) => b.destroy(ctx),
            Resource::Height(h) => h.destroy(ctx),
            Resource::Pyramid(p) => p.destroy(ctx),
            Resource::Corners(c) => c.destroy(ctx),
            Resource::Trace(t) => t.destroy(ctx),
            Resource::PyramidPass(p) => p.destroy(ctx),
            Resource::CornerPass(p) => p.destroy(ctx),
            Resource::Shade(p) => p.destroy(ctx),
            Resource::Shadow(s) => s.destroy(ctx),
            Resource::Depth(d) => d.destroy(ctx),
        }
    }
}

/// The displacement pass for a host engine (see the module docs for the contract).
///
/// Owns its pipelines, the height texture (and pyramid when the method needs one), one
/// DIG corner grid per frame slot (DIG methods) and, with [`Timestamps::Owned`], a query
/// pool. Destroy it explicitly with [`DisplacementPass::destroy`]; in debug builds one
/// dropped without it logs a warning (and leaks its objects).
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
    pyramid: Option<Pyramid>,
    pyramid_built: bool,
    /// One grid per frame slot (empty unless the method is a DIG).
    corners: Vec<CornerGrid>,
    query_pool: Option<vk::QueryPool>,
    /// The owned-pool scopes each slot recorded last.
    slot_scopes: Vec<Vec<TimestampScope>>,
    retired: Vec<Retired>,
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
}

impl ShadowParts {
    fn new(ctx: &Context, key: ShadowKey, frames: u32, addressing: Addressing) -> Result<Self> {
        let pass = ShadowPass::new(ctx, key.trace)?;
        let mut parts = ShadowParts {
            pass,
            visibility: Vec::new(),
            own_pyramid: None,
            own_built: false,
            key,
        };
        let result = (|| {
            for s in 0..frames {
                parts.visibility.push(Image::new(
                    ctx,
                    &format!("embed.visibility{s}"),
                    VISIBILITY_FORMAT,
                    key.extent,
                    1,
                    vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
                )?);
            }
            if key.own_pyramid {
                let mut pass = PyramidPass::new(ctx)?;
                match Pyramid::new(ctx, key.map, PyramidKind::Cell, addressing) {
                    Ok(p) => parts.own_pyramid = Some((pass, p)),
                    Err(e) => {
                        pass.destroy(ctx);
                        return Err(e);
                    }
                }
            }
            Ok(())
        })();
        match result {
            Ok(()) => Ok(parts),
            Err(e) => {
                parts.destroy(ctx);
                Err(e)
            }
        }
    }

    fn destroy(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        for mut v in self.visibility.drain(..) {
            v.destroy(ctx);
        }
        if let Some((mut pass, mut pyramid)) = self.own_pyramid.take() {
            pass.destroy(ctx);
            pyramid.destroy(ctx);
        }
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
        let mut parts = DepthParts {
            pass: HitDepthPass::new(ctx)?,
            images: Vec::new(),
        };
        for s in 0..frames {
            let image = Image::new(
                ctx,
                &format!("embed.hit_depth{s}"),
                HIT_DEPTH_FORMAT,
                extent,
                1,
                vk::ImageUsageFlags::STORAGE
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            );
            match image {
                Ok(i) => parts.images.push(i),
                Err(e) => {
                    parts.destroy(ctx);
                    return Err(e);
                }
            }
        }
        Ok(parts)
    }

    fn destroy(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        for mut i in self.images.drain(..) {
            i.destroy(ctx);
        }
    }
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

impl DisplacementPass {
    /// Builds the pipelines and the per-slot resources and stages `field` for upload
    /// (the first [`DisplacementPass::record`] copies it and builds the pyramid). Records
    /// and submits nothing.
    pub fn new(ctx: Arc<Context>, field: &HeightField, settings: PassSettings) -> Result<Self> {
        validate(&ctx, &settings)?;
        let needs = settings.method.needs();
        let c = &*ctx;
        // Built in order; on failure everything built so far is destroyed (`Partial`).
        let mut p = Partial::default();
        let result = (|| {
            p.trace = Some(TracePass::new(c, settings.method)?);
            p.shade = Some(ShadePass::new(c)?);
            let (height, staging) = HeightTexture::create_for_upload(
                c,
                field,
                settings.addressing,
                settings.params.lod_threshold.is_some(),
            )?;
            p.height = Some(height);
            p.staging = Some(staging);
            if let Some(kind) = needs.pyramid {
                p.pyramid_pass = Some(PyramidPass::new(c)?);
                p.pyramid = Some(Pyramid::new(
                    c,
                    field_size(field),
                    kind,
                    settings.addressing,
                )?);
            }
            if needs.dig_corners {
                p.corner_pass = Some(DigCornerPass::new(c)?);
                p.corners = corner_grids(c, &settings)?;
            }
            Ok(())
        })();
        if let Err(e) = result {
            p.destroy(c);
            return Err(e);
        }
        let built = "built above";
        Ok(DisplacementPass {
            settings,
            needs,
            trace: p.trace.take().expect(built),
            shade: p.shade.take().expect(built),
            pyramid_pass: p.pyramid_pass.take(),
            corner_pass: p.corner_pass.take(),
            height: p.height.take().expect(built),
            pending_fill: p.staging.take().map(Fill::Upload),
            pyramid: p.pyramid.take(),
            pyramid_built: false,
            corners: std::mem::take(&mut p.corners),
            query_pool: None,
            slot_scopes: vec![Vec::new(); settings.frames_in_flight as usize],
            retired: Vec::new(),
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
        self.pending_fill.is_some() || (self.pyramid.is_some() && !self.pyramid_built)
    }

    /// Records the pass into the host's command buffer `cmd`: the height-map upload and
    /// the pyramid build when pending, the DIG corner pass, `trace` into `inputs.hit`
    /// and, with `inputs.shade`, `shade`; each pass between debug labels and, unless
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

    /// # Safety
    /// As [`DisplacementPass::record`].
    unsafe fn record_frame(
        &mut self,
        cmd: vk::CommandBuffer,
        inputs: &FrameInputs,
        camera: Option<DepthCamera>,
        timestamps: Timestamps,
    ) -> Result<RecordedFrame> {
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
        self.release_retired(slot);
        let ctx = &*self.ctx;
        let mut timer = ScopeWriter {
            pool,
            first,
            frame: RecordedFrame::default(),
        };
        timer.reset(ctx, cmd);

        match self.pending_fill.take() {
            Some(Fill::Upload(staging)) => {
                timer.scope(ctx, cmd, "height_upload", |cmd| {
                    self.height.record_upload(ctx, cmd, &staging)
                });
                // Read by this frame's copy: destroyed when this slot is next recorded.
                self.retired.push(Retired {
                    pending: 1 << slot,
                    resource: Resource::Buffer(staging),
                });
            }
            Some(Fill::Copy(source)) => {
                timer.scope(ctx, cmd, "height_upload", |cmd| {
                    self.height.record_copy_from(ctx, cmd, &source)
                });
                // Read by this frame's copy and by frames in flight in other slots: kept
                // until every slot has been recorded again.
                self.retired.push(Retired {
                    pending: self.all_slots(),
                    resource: Resource::Height(source),
                });
            }
            None => {}
        }
        let method_pyramid = match (&self.pyramid_pass, &self.pyramid, self.pyramid_built) {
            (Some(pass), Some(pyramid), false) => Some((pass, pyramid)),
            _ => None,
        };
        // The shadow stage's own cell pyramid (hard shadows of `pyramid`) is built in the
        // same scope, as the standalone renderer does.
        let shadow_pyramid = match &self.shadow {
            Some(ShadowParts {
                own_pyramid: Some((pass, pyramid)),
                own_built: false,
                ..
            }) => Some((pass, pyramid)),
            _ => None,
        };
        if method_pyramid.is_some() || shadow_pyramid.is_some() {
            timer.scope(ctx, cmd, "pyramid", |cmd| {
                for (pass, pyramid) in method_pyramid.into_iter().chain(shadow_pyramid) {
                    pass.record(ctx, cmd, &self.height, pyramid);
                }
            });
            if self.pyramid.is_some() {
                self.pyramid_built = true;
            }
            if let Some(s) = &mut self.shadow {
                s.own_built = s.own_pyramid.is_some();
            }
        }
        let grid = self.corners.get(slot as usize);
        if let (Some(pass), Some(grid)) = (&self.corner_pass, grid) {
            let discard = Access {
                stage: vk::PipelineStageFlags2::COMPUTE_SHADER,
                ..Access::UNDEFINED
            };
            sync::record(
                ctx,
                cmd,
                &[sync::image_barrier(
                    grid.image.raw,
                    grid.image.range(),
                    discard,
                    Access::COMPUTE_STORAGE_WRITE,
                )],
            );
            timer.scope(ctx, cmd, "dig_corners", |cmd| {
                pass.record(
                    ctx,
                    cmd,
                    inputs.gbuffer,
                    &self.height,
                    grid,
                    self.settings.params.steps,
                )
            });
            sync::record(
                ctx,
                cmd,
                &[sync::image_barrier(
                    grid.image.raw,
                    grid.image.range(),
                    Access::COMPUTE_STORAGE_WRITE,
                    Access::COMPUTE_SAMPLED,
                )],
            );
        }
        let hit = ViewRef {
            view: inputs.hit,
            extent,
        };
        let mut traced = Ok(());
        timer.scope(ctx, cmd, "trace", |cmd| {
            traced = self.trace.record(
                ctx,
                cmd,
                TraceInputs {
                    gbuffer: inputs.gbuffer,
                    height: &self.height,
                    hit,
                    pyramid: self.pyramid.as_ref(),
                    corners: grid,
                },
                &self.settings.params,
                self.settings.depth_scale,
            )
        });
        traced?;
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
            unsafe { ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
        }
        if let Some(target) = &inputs.shade {
            let params = ShadeParams {
                inv_view_proj: target.view_proj.inverse(),
                camera_pos: target.camera_pos.extend(1.0),
                light_dir: target.light_dir.extend(target.light_intensity),
                frame_size: [extent.width, extent.height],
                map_size: self.height.size(),
                depth_scale: self.settings.depth_scale,
                ambient: 0.18,
                specular: 0.25,
                shininess: 48.0,
            };
            let visibility = self
                .shadow
                .as_ref()
                .map(|stage| &stage.visibility[slot as usize]);
            if let (Some(stage), Some(image)) = (&self.shadow, visibility) {
                // Slot `slot`'s previous frame has completed (the slot contract): the
                // visibility image's contents are discarded.
                sync::record(
                    ctx,
                    cmd,
                    &[sync::image_barrier(
                        image.raw,
                        image.range(),
                        DISCARD_COMPUTE,
                        Access::COMPUTE_STORAGE_WRITE,
                    )],
                );
                let shadow_params = ShadowPass::params(
                    &self.shadows,
                    self.settings.params.steps,
                    &params,
                    self.settings.addressing,
                );
                let pyramid = match &stage.own_pyramid {
                    Some((_, p)) => Some(p),
                    None => self.pyramid.as_ref(),
                };
                let mut shadowed = Ok(());
                timer.scope(ctx, cmd, "shadow", |cmd| {
                    shadowed = stage.pass.record(
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
                });
                shadowed?;
                sync::record(
                    ctx,
                    cmd,
                    &[sync::image_barrier(
                        image.raw,
                        image.range(),
                        Access::COMPUTE_STORAGE_WRITE,
                        Access::COMPUTE_STORAGE_READ,
                    )],
                );
            }
            let mut shaded = Ok(());
            timer.scope(ctx, cmd, "shade", |cmd| {
                shaded = self.shade.record(
                    ctx,
                    cmd,
                    ShadeInputs {
                        hit: inputs.hit,
                        gbuffer: inputs.gbuffer,
                        height: &self.height,
                        color: ViewRef {
                            view: target.color,
                            extent,
                        },
                        visibility: visibility.map(|v| v.view),
                    },
                    &params,
                )
            });
            shaded?;
        }
        if let (Some(depth), Some(camera)) = (&self.depth, camera) {
            let image = &depth.images[slot as usize];
            // Discarded: the host's reads of the slot's previous frame (any stage) have
            // completed by the slot contract; the barrier also orders them (WAR).
            sync::record(
                ctx,
                cmd,
                &[sync::image_barrier(
                    image.raw,
                    image.range(),
                    DISCARD_ANY,
                    Access::COMPUTE_STORAGE_WRITE,
                )],
            );
            let params = crate::abi::HitDepthParams::new(
                camera.view_proj,
                camera.eye,
                [extent.width, extent.height],
                self.settings.depth_scale,
            );
            timer.scope(ctx, cmd, "hit_depth", |cmd| {
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
            });
        }
        let frame = timer.frame;
        if matches!(timestamps, Timestamps::Owned) {
            self.slot_scopes[slot as usize] = frame.timestamps.clone();
        } else {
            self.slot_scopes[slot as usize].clear();
        }
        Ok(frame)
    }

    /// Per-pass milliseconds of the last frame recorded in `frame_slot` with
    /// [`Timestamps::Owned`] (empty if it recorded none). Call after that frame's fence
    /// signalled and before the slot is recorded again; an unfinished frame gives an
    /// error (`VK_NOT_READY`), never a wait.
    pub fn timings(&self, frame_slot: u32) -> Result<Vec<(&'static str, f64)>> {
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
        let all = self.all_slots();
        let ctx = &*self.ctx;
        let (height, staging) = HeightTexture::create_for_upload(
            ctx,
            field,
            self.settings.addressing,
            self.settings.params.lod_threshold.is_some(),
        )?;
        let pyramid = match self.needs.pyramid {
            Some(kind) => {
                match Pyramid::new(ctx, field_size(field), kind, self.settings.addressing) {
                    Ok(p) => Some(p),
                    Err(e) => {
                        let (mut h, mut s) = (height, staging);
                        h.destroy(ctx);
                        s.destroy(ctx);
                        return Err(e);
                    }
                }
            }
            None => None,
        };
        let old_height = std::mem::replace(&mut self.height, height);
        self.retired.push(Retired {
            pending: all,
            resource: Resource::Height(old_height),
        });
        match self.pending_fill.replace(Fill::Upload(staging)) {
            // Never recorded: no frame reads it.
            Some(Fill::Upload(mut old)) => old.destroy(ctx),
            // The texture frames in flight may still read.
            Some(Fill::Copy(old)) => self.retired.push(Retired {
                pending: all,
                resource: Resource::Height(old),
            }),
            None => {}
        }
        if let Some(old) = std::mem::replace(&mut self.pyramid, pyramid) {
            self.retired.push(Retired {
                pending: all,
                resource: Resource::Pyramid(old),
            });
        }
        self.pyramid_built = false;
        // A cell pyramid of the shadow stage's own is of the old map: rebuilt (the old
        // one is retired with its stage).
        let own = self
            .shadow
            .as_ref()
            .is_some_and(|s| s.own_pyramid.is_some());
        self.sync_shadows(own)
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
        let all = self.all_slots();
        for old in std::mem::replace(&mut self.corners, grids) {
            self.retired.push(Retired {
                pending: all,
                resource: Resource::Corners(old),
            });
        }
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
    /// from the old one's level 0 (in its `height_upload` scope).
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
        let ctx = &*self.ctx;
        let needs = method.needs();
        let settings = PassSettings {
            method,
            params,
            ..self.settings
        };
        // Build everything new first; on failure destroy it and leave the pass as it was.
        let mut p = Partial::default();
        let chain = params.lod_threshold.is_some();
        let result = (|| {
            if method != self.trace.method() {
                p.trace = Some(TracePass::new(ctx, method)?);
            }
            if self.height.differs_for(ctx, chain) {
                p.height = Some(self.height.create_like(ctx, chain)?);
            }
            if let Some(kind) = needs.pyramid {
                if self.pyramid_pass.is_none() {
                    p.pyramid_pass = Some(PyramidPass::new(ctx)?);
                }
                if self.pyramid.as_ref().is_none_or(|old| old.kind != kind) {
                    let map = self.height.size();
                    p.pyramid = Some(Pyramid::new(ctx, map, kind, self.settings.addressing)?);
                }
            }
            if needs.dig_corners {
                if self.corner_pass.is_none() {
                    p.corner_pass = Some(DigCornerPass::new(ctx)?);
                }
                let same_grids = !self.corners.is_empty()
                    && self.corners.iter().all(|g| g.block == params.block);
                if !same_grids {
                    p.corners = corner_grids(ctx, &settings)?;
                }
            }
            Ok(())
        })();
        if let Err(e) = result {
            p.destroy(ctx);
            return Err(e);
        }
        // Commit: swap in what was built, retire what the new method does not use.
        let all = self.all_slots();
        let mut retire = Vec::new();
        if let Some(trace) = p.trace.take() {
            retire.push(Resource::Trace(std::mem::replace(&mut self.trace, trace)));
        }
        if let Some(height) = p.height.take() {
            // The mip chain follows level of detail; level 0 (the map) is unchanged.
            let old = std::mem::replace(&mut self.height, height);
            if self.pending_fill.is_some() {
                // `old` was never filled (its fill is still pending and now fills the
                // new texture): no frame reads it.
                retire.push(Resource::Height(old));
            } else {
                self.pending_fill = Some(Fill::Copy(old));
            }
        }
        if let Some(pass) = p.pyramid_pass.take() {
            self.pyramid_pass = Some(pass);
        }
        if let Some(pyramid) = p.pyramid.take() {
            retire.extend(self.pyramid.replace(pyramid).map(Resource::Pyramid));
            self.pyramid_built = false;
        }
        if needs.pyramid.is_none() {
            retire.extend(self.pyramid.take().map(Resource::Pyramid));
            retire.extend(self.pyramid_pass.take().map(Resource::PyramidPass));
            self.pyramid_built = false;
        }
        if let Some(pass) = p.corner_pass.take() {
            self.corner_pass = Some(pass);
        }
        if !p.corners.is_empty() {
            let old = std::mem::replace(&mut self.corners, std::mem::take(&mut p.corners));
            retire.extend(old.into_iter().map(Resource::Corners));
        }
        if !needs.dig_corners {
            retire.extend(self.corners.drain(..).map(Resource::Corners));
            retire.extend(self.corner_pass.take().map(Resource::CornerPass));
        }
        self.retired
            .extend(retire.into_iter().map(|resource| Retired {
                pending: all,
                resource,
            }));
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
            (false, true) => {
                let all = self.all_slots();
                if let Some(old) = self.depth.take() {
                    self.retired.push(Retired {
                        pending: all,
                        resource: Resource::Depth(old),
                    });
                }
            }
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
        let all = self.all_slots();
        let ctx = &*self.ctx;
        if self.shade.is_shadowed() != on {
            let new = if on {
                ShadePass::shadowed(ctx)
            } else {
                ShadePass::new(ctx)
            };
            match new {
                Ok(new) => {
                    let old = std::mem::replace(&mut self.shade, new);
                    self.retired.push(Retired {
                        pending: all,
                        resource: Resource::Shade(old),
                    });
                }
                Err(e) => {
                    if let Some(old) = self.shadow.take() {
                        self.retired.push(Retired {
                            pending: all,
                            resource: Resource::Shadow(old),
                        });
                    }
                    return Err(e);
                }
            }
        }
        if want == have && !(force && have.is_some()) {
            return Ok(());
        }
        let built = match want {
            Some(key) => ShadowParts::new(
                ctx,
                key,
                self.settings.frames_in_flight,
                self.settings.addressing,
            )
            .map(Some),
            None => Ok(None),
        };
        if let Some(old) = self.shadow.take() {
            self.retired.push(Retired {
                pending: all,
                resource: Resource::Shadow(old),
            });
        }
        self.shadow = built?;
        Ok(())
    }

    /// Destroys every object and frees every allocation the pass made. Afterwards any
    /// other call returns an error.
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
        for mut r in self.retired.drain(..) {
            r.resource.destroy(ctx);
        }
        if let Some(mut s) = self.shadow.take() {
            s.destroy(ctx);
        }
        if let Some(mut d) = self.depth.take() {
            d.destroy(ctx);
        }
        match self.pending_fill.take() {
            Some(Fill::Upload(mut b)) => b.destroy(ctx),
            Some(Fill::Copy(mut h)) => h.destroy(ctx),
            None => {}
        }
        for mut c in self.corners.drain(..) {
            c.destroy(ctx);
        }
        if let Some(mut p) = self.pyramid.take() {
            p.destroy(ctx);
        }
        self.height.destroy(ctx);
        if let Some(mut p) = self.corner_pass.take() {
            p.destroy(ctx);
        }
        if let Some(mut p) = self.pyramid_pass.take() {
            p.destroy(ctx);
        }
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
            Err(Error::invalid("DisplacementPass", "used after destroy()"))
        } else {
            Ok(())
        }
    }

    fn all_slots(&self) -> u64 {
        (1u64 << self.settings.frames_in_flight) - 1
    }

    fn release_retired(&mut self, slot: u32) {
        let ctx = &*self.ctx;
        self.retired.retain_mut(|r| {
            r.pending &= !(1u64 << slot);
            if r.pending == 0 {
                r.resource.destroy(ctx);
                false
            } else {
                true
            }
        });
    }

    fn owned_pool(&mut self) -> Result<vk::QueryPool> {
        if let Some(pool) = self.query_pool {
            return Ok(pool);
        }
        if self.ctx.info().timestamp_valid_bits == 0 {
            return Err(Error::Unsupported {
                device: self.ctx.info().name.clone(),
                what: "timestamps on the queue family in use (timestampValidBits = 0)".into(),
            });
        }
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(MAX_QUERIES * self.settings.frames_in_flight);
        // SAFETY: valid device and create info.
        let pool =
            unsafe { self.ctx.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        self.ctx.set_name(pool, "embed.timestamps");
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
    let mut grids = Vec::new();
    for _ in 0..s.frames_in_flight {
        match CornerGrid::new(ctx, [s.extent.width, s.extent.height], s.params.block) {
            Ok(g) => grids.push(g),
            Err(e) => {
                for mut g in grids {
                    g.destroy(ctx);
                }
                return Err(e);
            }
        }
    }
    Ok(grids)
}

/// Writes the begin/end timestamps of each pass into the chosen range.
struct ScopeWriter {
    pool: Option<vk::QueryPool>,
    first: u32,
    frame: RecordedFrame,
}

impl ScopeWriter {
    fn reset(&self, ctx: &Context, cmd: vk::CommandBuffer) {
        if let Some(pool) = self.pool {
            // SAFETY: `cmd` is recording outside a render pass and the range exists
            // (`record`'s contract); the frame writes these queries after the reset.
            unsafe {
                ctx.device()
                    .cmd_reset_query_pool(cmd, pool, self.first, MAX_QUERIES)
            };
        }
    }

    /// Records `body` between a debug label and, with a pool, two timestamps.
    fn scope(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        name: &'static str,
        body: impl FnOnce(vk::CommandBuffer),
    ) {
        ctx.begin_label(cmd, name);
        let queries = self.pool.map(|pool| {
            let begin = self.first + 2 * self.frame.timestamps.len() as u32;
            (pool, begin, begin + 1)
        });
        if let Some((pool, begin, _)) = queries {
            // SAFETY: `cmd` is recording; the query was reset by `reset` in this frame.
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    pool,
                    begin,
                )
            };
        }
        body(cmd);
        if let Some((pool, begin_query, end_query)) = queries {
            // SAFETY: as above.
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    pool,
                    end_query,
                )
            };
            self.frame.timestamps.push(TimestampScope {
                name,
                pool,
                begin_query,
                end_query,
            });
        }
        ctx.end_label(cmd);
        self.frame.passes.push(name);
    }
}

/// The pass's parts while [`DisplacementPass::new`] builds them.
#[derive(Default)]
struct Partial {
    trace: Option<TracePass>,
    shade: Option<ShadePass>,
    height: Option<HeightTexture>,
    staging: Option<Buffer>,
    pyramid_pass: Option<PyramidPass>,
    pyramid: Option<Pyramid>,
    corner_pass: Option<DigCornerPass>,
    corners: Vec<CornerGrid>,
}

impl Partial {
    fn destroy(&mut self, ctx: &Context) {
        for mut c in self.corners.drain(..) {
            c.destroy(ctx);
        }
        if let Some(mut p) = self.corner_pass.take() {
            p.destroy(ctx);
        }
        if let Some(mut p) = self.pyramid.take() {
            p.destroy(ctx);
        }
        if let Some(mut p) = self.pyramid_pass.take() {
            p.destroy(ctx);
        }
        if let Some(mut b) = self.staging.take() {
            b.destroy(ctx);
        }
        if let Some(mut h) = self.height.take() {
            h.destroy(ctx);
        }
        if let Some(mut s) = self.shade.take() {
            s.destroy(ctx);
        }
        if let Some(mut t) = self.trace.take() {
            t.destroy(ctx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn create_info_without_the_extension_or_features_is_a_clear_error() {
        let info = vk::DeviceCreateInfo::default();
        // SAFETY: a default create info has no extensions and no chain.
        let err = unsafe { check_device_create_info(&info) }
            .unwrap_err()
            .to_string();
        assert!(err.contains("VK_KHR_push_descriptor"), "{err}");
        assert!(err.contains("synchronization2"), "{err}");

        let exts = [ash::khr::push_descriptor::NAME.as_ptr()];
        let mut f13 = requirements().enable_vulkan13(vk::PhysicalDeviceVulkan13Features::default());
        let info = vk::DeviceCreateInfo::default()
            .enabled_extension_names(&exts)
            .push_next(&mut f13);
        // SAFETY: the names and the chain live on this stack frame.
        unsafe { check_device_create_info(&info) }.unwrap();
        assert_eq!(
            f13.dynamic_rendering,
            vk::FALSE,
            "the pass needs no dynamicRendering"
        );
        assert_eq!(requirements().vulkan13_features, ["synchronization2"]);

        // synchronization2 through its own (pre-1.3 extension) structure counts too.
        let mut sync2 =
            vk::PhysicalDeviceSynchronization2Features::default().synchronization2(true);
        let info = vk::DeviceCreateInfo::default()
            .enabled_extension_names(&exts)
            .push_next(&mut sync2);
        // SAFETY: as above.
        unsafe { check_device_create_info(&info) }.unwrap();
    }

    #[test]
    fn requirements_cover_the_largest_pass() {
        let r = requirements();
        assert_eq!(r.max_push_constants_size, 128);
        assert!(
            r.device_extensions
                .contains(&ash::khr::push_descriptor::NAME)
        );
        assert!(r.formats.iter().any(|(f, _)| *f == HIT_FORMAT));
        // The shaded shade variant (self-shadowing) pushes bindings 0..=7.
        assert_eq!(r.max_push_descriptors, 8);
        let largest = [
            std::mem::size_of::<crate::abi::ShadowParams>(),
            std::mem::size_of::<crate::abi::HitDepthParams>(),
            std::mem::size_of::<crate::abi::TraceParams>(),
        ];
        assert!(
            largest
                .iter()
                .all(|&b| b as u32 <= r.max_push_constants_size)
        );
    }
}
