//! The `motion` pass: the screen motion of each displaced pixel, written in place into the
//! host's motion-vector image (the one its TAA, TSR, DLSS or FSR reads), so that displaced
//! pixels move as the displaced surface does rather than as the flat macro surface under
//! them (`glsl/motion.comp`).
//!
//! # Contract
//!
//! * **The image**: the host's, `R16G16_SFLOAT` or `R32G32_SFLOAT` ([`MOTION_FORMATS`]),
//!   `STORAGE` usage, the frame's size; `GENERAL` on entry with the host's writes visible
//!   to `COMPUTE_SHADER` `SHADER_STORAGE_READ | SHADER_STORAGE_WRITE`; on exit `GENERAL`,
//!   displaced pixels written by `COMPUTE_SHADER` `SHADER_STORAGE_WRITE`, every other pixel
//!   as it entered (flat geometry, the sky, pixels of a material without a hit).
//! * **Units and direction** ([`MotionSettings`]): pixels, uv (pixels / frame size) or
//!   Vulkan NDC (2 × uv), +y down as the framebuffer; previous minus current position
//!   (where the surface seen at the pixel was in the previous frame: DLSS's and FSR's
//!   default) or its opposite.
//! * **The previous camera**: the host gives the previous frame's view-projection (world to
//!   clip) and eye ([`FrameMotion`]); the current camera is the frame's
//!   ([`crate::embed::ShadeTarget`] or [`DepthCamera`]), the one its G-buffer
//!   was drawn with.
//! * **Source** ([`MotionSource`]):
//!   - `Camera`: the world is static at displaced pixels. Motion = `prev_px(p_hit) -
//!     centre`: exact (the displaced point `p_hit` seen through the pixel, projected with
//!     the previous camera). The image's contents at displaced pixels are ignored. With a
//!     jittered projection the result includes the jitter difference, as any motion
//!     computed from the two matrices does.
//!   - `Surface`: the image holds the macro surface's motion `m_entry` at every pixel (the
//!     host's G-buffer pass writes it, as an engine's velocity buffer does). Its part that
//!     the camera does not explain, `own = m_entry - (prev_px(p_entry) - centre)`, is the
//!     surface's own move in the previous frame's screen; the pass takes it as a
//!     translation `t` of the surface at constant previous view depth (the one 3D move
//!     that shows as `own` and keeps the previous clip `w`), moves the displaced point
//!     with it and projects: motion = `prev_px(p_hit + t) - centre`.
//!     * A static surface (`own` = 0): `Camera`'s exact motion, up to the image's
//!       precision; the jitter of a jittered projection cancels in `own`.
//!     * A surface translating parallel to the previous image plane: exact.
//!     * A move in depth, or a turn of the surface by `θ` in the frame: the displacement
//!       offset `d = p_hit - p_entry` is taken as unturned, so the error is about `θ |d|`
//!       projected (`|d|` is at most `depth_scale` plus the hit's lateral reach), plus a
//!       second-order term of the move in depth. Measured by `tests/motion.rs` (a
//!       192x108 frame, rocks at depth 0.1 on a tilted patch 1.5 to 2 tiles from the
//!       eye, still camera): a slide of 0.025 tiles per frame, error max 0.0025 px (the
//!       flat surface's motion: 0.12 px); a turn of 2 degrees per frame, max 0.30 px
//!       (flat: 0.23 px); both at once, max 0.30 px (flat: 0.32 px). A host that knows a
//!       surface's rotation can write the exact motion into the image itself for those
//!       pixels after the pass.
//!
//! `p_hit` and `p_entry` come from `glsl/include/dispmap_displace.glsl`, the same code as
//! the corrected depth's (`hit_depth`).
//!
//! Bindings: [`crate::passes::hit_resolve`] (`u_motion`: the host's motion image, storage,
//! read and written).

use crate::abi::MotionParams;
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::HostView;
use crate::gpu::owned::Destroy;
use crate::passes::classify::MaterialTiles;
use crate::passes::gbuffer::GBufferViews;
use crate::passes::hit_resolve::{HitResolvePipeline, ResolveViews};
use crate::shaders;
use ash::vk;
use glam::{DMat4, Mat4, Vec3};

/// The formats the motion image may have.
pub const MOTION_FORMATS: [vk::Format; 2] = [vk::Format::R16G16_SFLOAT, vk::Format::R32G32_SFLOAT];

/// The units of the motion image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MotionUnits {
    /// Framebuffer pixels.
    #[default]
    Pixels,
    /// Pixels divided by the frame size (uv of the frame).
    Uv,
    /// Vulkan NDC: twice the uv (+y down).
    Ndc,
}

/// Which way the motion points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MotionDirection {
    /// Previous minus current position: from the pixel to where its surface was (DLSS's
    /// and FSR's default).
    #[default]
    ToPrevious,
    /// Current minus previous position.
    ToCurrent,
}

/// What the motion of a displaced pixel is built from (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MotionSource {
    /// A static world: the previous camera alone (the image's contents at displaced
    /// pixels are ignored).
    Camera,
    /// The macro surface's motion the host wrote into the image (moving objects: the
    /// surface's own move taken as a translation, the displacement offset unturned).
    #[default]
    Surface,
}

/// The motion output's inputs of one frame ([`crate::passes::motion`] documents the
/// contract).
#[derive(Clone, Copy, Debug)]
pub struct FrameMotion {
    /// The host's motion image (the format of the pass's [`MotionSettings`], one of
    /// [`MOTION_FORMATS`]; `STORAGE` usage; the frame's size), read and written in place.
    pub image: HostView,
    /// The camera the host drew its previous frame with (world to clip and eye).
    pub previous: DepthCamera,
}

/// The camera of a frame for the corrected depth when the frame has no
/// [`crate::embed::ShadeTarget`] (see [`crate::embed::DisplacementPass::record_with_camera`]).
#[derive(Clone, Copy, Debug)]
pub struct DepthCamera {
    /// World to clip of the frame (the G-buffer's; reverse-Z).
    pub view_proj: Mat4,
    /// Eye position, world space.
    pub eye: Vec3,
}

/// How the motion output writes the host's image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MotionSettings {
    /// The image's format (one of [`MOTION_FORMATS`]).
    pub format: vk::Format,
    /// The units of its values.
    pub units: MotionUnits,
    /// Their direction.
    pub direction: MotionDirection,
    /// Static world or the host's surface motion.
    pub source: MotionSource,
}

impl Default for MotionSettings {
    /// `R16G16_SFLOAT`, pixels, previous minus current, the host's surface motion.
    fn default() -> Self {
        MotionSettings {
            format: vk::Format::R16G16_SFLOAT,
            units: MotionUnits::default(),
            direction: MotionDirection::default(),
            source: MotionSource::default(),
        }
    }
}

impl MotionSettings {
    /// Checks the format (one of [`MOTION_FORMATS`], with storage support on `ctx`'s
    /// device: `R32G32_SFLOAT` storage is not mandatory in Vulkan).
    pub fn validate(&self, ctx: &Context) -> Result<()> {
        if !MOTION_FORMATS.contains(&self.format) {
            return Err(Error::invalid(
                "motion format",
                format!("{:?} is not one of {MOTION_FORMATS:?}", self.format),
            ));
        }
        let needed = vk::FormatFeatureFlags::STORAGE_IMAGE;
        if !ctx.format_features(self.format).contains(needed) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                what: format!("{:?} with {needed:?} (the motion image)", self.format),
            });
        }
        Ok(())
    }

    /// The flags of `MotionParams::material` (bits 16-31, `glsl/motion.comp`).
    fn flags(&self) -> u32 {
        let mut f = 0;
        if self.source == MotionSource::Surface {
            f |= 0x1_0000;
        }
        f |= match self.units {
            MotionUnits::Pixels => 0,
            MotionUnits::Uv => 0x2_0000,
            MotionUnits::Ndc => 0x4_0000,
        };
        if self.direction == MotionDirection::ToCurrent {
            f |= 0x8_0000;
        }
        f
    }
}

/// The images the pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct MotionInputs {
    /// The hit images (read).
    pub hit: crate::passes::trace::HitViews,
    /// The G-buffer (ray, depth and frame are read).
    pub gbuffer: GBufferViews,
    /// The host's motion image (read and written in place).
    pub motion: vk::ImageView,
    /// The material and its tiles.
    pub tiles: MaterialTiles,
}

impl MotionParams {
    /// The push constants for a frame drawn with `view_proj` from `eye` whose previous
    /// frame was drawn with `prev_view_proj` (world to clip), for a material of
    /// `depth_scale` tile units, written as `settings` says.
    ///
    /// Composed in f64 and eye-relative (as [`crate::abi::HitDepthParams::new`]): the
    /// previous matrix is `prev_view_proj * translation(eye)`, applied to offsets from the
    /// current eye, so neither frame's large world coordinates cancel in f32.
    pub fn new(
        view_proj: Mat4,
        eye: Vec3,
        prev_view_proj: Mat4,
        frame_size: [u32; 2],
        depth_scale: f32,
        settings: &MotionSettings,
    ) -> Self {
        let to_eye = DMat4::from_translation(eye.as_dvec3());
        let inv = (view_proj.as_dmat4() * to_eye).inverse();
        let prev = prev_view_proj.as_dmat4() * to_eye;
        MotionParams {
            inv_eye_clip: inv.as_mat4(),
            prev_x_row: prev.row(0).as_vec4(),
            prev_y_row: prev.row(1).as_vec4(),
            prev_w_row: prev.row(3).as_vec4(),
            frame_size,
            depth_scale,
            material: settings.flags(),
        }
    }
}

/// The motion pass of one image format.
pub struct MotionPass {
    pipeline: HitResolvePipeline,
    /// The format its pipeline writes.
    pub format: vk::Format,
}

impl MotionPass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.bindings()
    }

    /// Builds the pipeline for a motion image of `format` (one of [`MOTION_FORMATS`]).
    pub fn new(ctx: &Context, format: vk::Format) -> Result<Self> {
        let (name, shader) = if format == vk::Format::R32G32_SFLOAT {
            ("motion_rg32f", &shaders::MOTION_COMP_WIDE)
        } else {
            ("motion", &shaders::MOTION_COMP)
        };
        Ok(MotionPass {
            pipeline: HitResolvePipeline::new(
                ctx,
                name,
                shader,
                "u_motion",
                std::mem::size_of::<MotionParams>() as u32,
            )?,
            format,
        })
    }

    /// Records the dispatch over the material's tiles.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `inputs`' views belong to that device and have the formats and usages of the
    ///   module docs (the motion image of this pass's format); all have the frame's size.
    /// * When the command buffer executes, the images are in the layouts of the module
    ///   docs: the hit images in `GENERAL`, their writes visible to compute-shader storage
    ///   reads; the G-buffer in `SHADER_READ_ONLY_OPTIMAL`, its writes visible to
    ///   compute-shader sampled reads; the motion image in `GENERAL`, its writes visible
    ///   to compute-shader storage reads and writes; the tile list written by a `classify`
    ///   recorded before in the same command buffer.
    /// * The images behind `inputs` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: MotionInputs,
        params: &MotionParams,
    ) -> Result<()> {
        let MotionInputs {
            hit,
            gbuffer,
            motion,
            tiles,
        } = inputs;
        let push = MotionParams {
            material: (params.material & !0xFFFF) | tiles.material,
            ..*params
        };
        // SAFETY: this function's # Safety contract is `HitResolvePipeline::record`'s (the
        // motion image as its output, read and written), with the `MotionParams` the
        // pipeline was built with (the material in their low bits).
        unsafe {
            self.pipeline.record(
                ctx,
                cmd,
                ResolveViews {
                    hit,
                    gbuffer,
                    out: motion,
                },
                tiles,
                bytemuck::bytes_of(&push),
            )
        }
    }
}

impl Destroy for MotionPass {
    /// Destroys the pipeline and sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}
