//! What a host hands the displacement pass and gets back: the pass's and a material's
//! settings, a frame's inputs and shading target, where timestamps go, what a record
//! recorded, and material handles.

use super::*;

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
    /// Frame size in pixels (the G-buffer's, hit images' and colour image's size).
    pub extent: vk::Extent2D,
    /// Frames the host keeps in flight (1..=[`MAX_FRAMES_IN_FLIGHT`]): the number of
    /// slots of the per-frame resources the pass owns.
    pub frames_in_flight: u32,
}

/// What `shade` needs to light the hits (only when the host wants dispmap's colour).
#[derive(Clone, Copy, Debug)]
pub struct ShadeTarget {
    /// The colour image (`R8G8B8A8_UNORM`, `STORAGE` usage, the frame's size; see the
    /// module table).
    pub color: HostView,
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
    /// The hit images this frame writes (`STORAGE` usage, the frame's size).
    pub hit: HitImages,
    /// Shade the hits into a colour image (`None`: the host shades from the hit images).
    pub shade: Option<ShadeTarget>,
    /// The host's motion image and previous camera: required while the motion output is
    /// on ([`DisplacementPass::set_motion_output`]), refused while it is off.
    pub motion: Option<FrameMotion>,
}

/// The host's hit images of one frame slot: each displaced pixel's hit, written by the
/// pass (layouts and access on entry and exit: module docs). The pass's iteration counts
/// are its own optional output ([`DisplacementPass::set_iterations_output`]).
#[derive(Clone, Copy, Debug)]
pub struct HitImages {
    /// The hit's `u`, `v` ([`HIT_UV_FORMAT`], `R32G32_SFLOAT`).
    pub uv: HostView,
    /// The hit's height in `[0, 1]`, `NO_HIT_HEIGHT` (-1) for a ray that met nothing,
    /// [`NOT_DISPLACED_HEIGHT`] for flat geometry ([`HIT_HEIGHT_FORMAT`], `R32_SFLOAT`).
    pub height: HostView,
}

impl HitImages {
    /// The views the passes bind.
    pub fn views(&self) -> crate::passes::trace::HitViews {
        crate::passes::trace::HitViews {
            uv: self.uv.view,
            height: self.height.view,
        }
    }
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

/// The settings of one displaced material (one entry of the pass's material table).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialSettings {
    /// The intersection method.
    pub method: Method,
    /// Its parameters.
    pub params: MethodParams,
    /// Displacement depth in uv (tile) units: the value the host's G-buffer used for `P`
    /// on this material's pixels.
    pub depth_scale: f32,
    /// Height-map addressing: `Repeat` for tiled surfaces, `Clamp` for decals (must match
    /// the `addressing` the host's G-buffer shader used for `uv0`). Fixed for a material's
    /// life ([`DisplacementPass::set_material_settings`] refuses a change).
    pub addressing: Addressing,
}

impl PassSettings {
    /// The settings of the material [`DisplacementPass::new`] makes from these.
    pub fn material(&self) -> MaterialSettings {
        MaterialSettings {
            method: self.method,
            params: self.params,
            depth_scale: self.depth_scale,
            addressing: self.addressing,
        }
    }
}

/// A handle to one material of a [`DisplacementPass`]'s table. Its
/// [`MaterialId::index`] is the value the host's G-buffer writes for the material's
/// pixels (`glsl/include/dispmap_gbuffer.glsl`: the frame's material `index + 1`). A removed
/// material's handle is refused by every call, also after its index is reused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MaterialId {
    pub(super) index: u32,
    pub(super) generation: u32,
}

impl MaterialId {
    /// The material's index in the table: what the G-buffer encodes.
    pub fn index(self) -> u32 {
        self.index
    }
}
