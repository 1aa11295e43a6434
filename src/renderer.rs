//! The standalone renderer: the first host of [`DisplacementPass`], the one orchestrator
//! of the compute passes. It owns only what a host owns: the G-buffer pass and images,
//! the mesh, the hit and colour images, a timestamp pool, and one-shot submission with
//! read-back. Each frame it records exactly what `examples/host_engine.rs` records:
//!
//! 1. G-buffer images: discarded (`UNDEFINED`, after last frame's compute reads and
//!    read-back copies) -> attachment layouts; `gbuffer` clears and writes them (timed
//!    in the renderer's own scope).
//! 2. G-buffer -> `SHADER_READ_ONLY_OPTIMAL` for compute; hit images and colour:
//!    discarded -> `GENERAL` for storage writes (the pass's entry contract).
//! 3. [`DisplacementPass::record`] with a [`ShadeTarget`]: `[upload] -> [pyramid] ->
//!    [dig_corners] -> trace -> [shadow] -> shade -> [hit_depth]`, each stage placing its
//!    own barriers, timed into the renderer's pool after the G-buffer's queries.
//!
//! After a frame the hit images are in `GENERAL` (last access: storage read), the colour
//! in `GENERAL` (last access: storage write), the G-buffer in
//! `SHADER_READ_ONLY_OPTIMAL`, and the pass's images as its module docs say; the
//! read-back helpers use exactly those states. The renderer turns the pass's iteration counts on
//! ([`DisplacementPass::with_iterations`]: its read-backs, metrics and benchmark use them),
//! keeps one frame slot and
//! waits for each frame, so what the pass retires is destroyed by the next frame.

mod behind;
mod behind_draws;
mod build;
#[cfg(test)]
mod curve_draw_tests;
mod forward;
mod frame;
mod objects;
mod readback;
#[cfg(test)]
mod test_support;
#[cfg(test)]
mod walk_tests;

pub use objects::{MAX_OBJECTS, ObjectAssets, ObjectMaterial, SceneAssets, SceneObject};
use objects::{Objects, bounding_sphere, check_eye, objects_settings};

use crate::context::Context;
use crate::embed::{
    DepthCamera, DisplacementPass, FrameInputs, HitImages, MAX_QUERIES, MaterialId,
    MaterialSettings, MotionSettings, PassSettings, ShadeTarget, Timestamps,
};
use crate::error::{Error, Result};
use crate::gpu::commands::{read_image, upload_image};
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::sync::Access;
use crate::gpu::{Image, OneShot};
use crate::heightfield::HeightField;
use crate::material::MaterialImages;
use crate::mesh::{Mesh, MeshBuffers};
use crate::method::{Method, MethodParams};
use crate::passes::PassName;
use crate::passes::background::BackgroundPass;
use crate::passes::camera_motion::{CAMERA_MOTION_FORMAT, CameraMotion};
use crate::passes::dig::Corner;
use crate::passes::gbuffer::{GBuffer, GBufferDraw, GBufferPass, Ray};
use crate::passes::shade::COLOR_FORMAT;
use crate::passes::shadow::{ShadowSettings, VISIBILITY_FORMAT};
use crate::passes::trace::{HIT_HEIGHT_FORMAT, HIT_UV_FORMAT, HitTexel};
use crate::scene::{Geometry, Placement, Scene};
use crate::timing::{QueryPool, ScopeWriter, read_timestamps};
use ash::vk;
use build::Hits;
use std::sync::Arc;

/// Largest frame side the CLI accepts (a sanity bound; the device's limit applies too).
pub const MAX_FRAME_SIDE: u32 = 16384;

/// The rays of [`Renderer::reference_rays`], row by row (`None`: nothing to trace).
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceRays {
    /// Each pixel's ray: on an analytic surface the pixel's own f64 centre ray wherever
    /// it meets the surface, whether the G-buffer drew the pixel or not; else the
    /// G-buffer's.
    pub rays: Vec<Option<Ray>>,
    /// Whether the rays are the analytic centre rays.
    pub analytic: bool,
    /// Pixels the G-buffer drew whose f64 centre ray misses the surface (tangent to the
    /// horizon or the rectangle's edge within the G-buffer's double-float precision):
    /// the reference has no ray there, so they are not compared.
    pub drawn_only: Vec<usize>,
    /// Pixels whose f64 centre ray meets the surface but that the G-buffer left empty
    /// (the rasteriser's coverage ends within a pixel of the horizon or the edge): the
    /// reference traces them and a method, having no ray, misses them (an artifact).
    pub ray_only: Vec<usize>,
}

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// The intersection method.
    pub method: Method,
    /// Its parameters.
    pub params: MethodParams,
    /// Camera, light, geometry, depth scale.
    pub scene: Scene,
    /// Self-shadowing (default: off).
    pub shadows: ShadowSettings,
}

impl RenderSettings {
    /// The frame size.
    pub fn extent(&self) -> vk::Extent2D {
        vk::Extent2D {
            width: self.width,
            height: self.height,
        }
    }

    /// Checks every value; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0
            || self.height == 0
            || self.width > MAX_FRAME_SIDE
            || self.height > MAX_FRAME_SIDE
        {
            return Err(Error::invalid(
                "size",
                format!(
                    "{}x{} is outside 1..={MAX_FRAME_SIDE} per side",
                    self.width, self.height
                ),
            ));
        }
        self.params.validate()?;
        self.shadows.validate()?;
        self.scene.validate()
    }
}

/// Per-pass GPU milliseconds of one frame, in pass order.
pub type PassTimes = Vec<(PassName, f64)>;

/// Discarded contents, after compute or fragment reads (the behind layer's reads of the
/// first layer) or read-back copies of an earlier frame.
const DISCARD: Access = Access {
    stage: vk::PipelineStageFlags2::from_raw(
        vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw()
            | vk::PipelineStageFlags2::FRAGMENT_SHADER.as_raw()
            | vk::PipelineStageFlags2::COPY.as_raw(),
    ),
    access: vk::AccessFlags2::NONE,
    layout: vk::ImageLayout::UNDEFINED,
};

/// The G-buffer's frame decoded into `normal` and `tangent` texels ([`Renderer::read_frames`]).
pub type TangentFrames = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// Timestamp queries of the renderer's own scope (the G-buffer), before the pass's.
const GBUFFER_QUERIES: u32 = 2;

/// A host of [`DisplacementPass`] with its own G-buffer, for one frame size.
pub struct Renderer {
    ctx: Arc<Context>,
    settings: RenderSettings,
    shot: OneShot,
    timestamps: QueryPool,
    gbuffer: GBuffer,
    hit: Hits,
    color: Image,
    gbuffer_pass: GBufferPass,
    /// The host's shading of what the pass leaves alone: sky and flat geometry.
    background: BackgroundPass,
    /// The macro geometry's vertex and index buffers (meshes only).
    mesh: Option<MeshBuffers>,
    /// That mesh's clusters, which the behind layer culls ([`behind_draws`]).
    mesh_clusters: Vec<behind_draws::Cluster>,
    /// A frame of several objects ([`Renderer::with_objects`]); `None`: the one geometry
    /// of the settings.
    objects: Option<Objects>,
    pass: DisplacementPass,
    /// Whether a frame has written the corrected depth since it was turned on.
    depth_written: bool,
    /// The motion output (`None`: off).
    motion: Option<CameraMotion>,
    /// GPU milliseconds of the last build of each one-off map (pyramid, cone map).
    builds: Vec<(PassName, f64)>,
    /// The forward path ([`Renderer::enable_forward`]), once enabled.
    forward: Option<forward::Forward>,
    /// The scene and camera of the last frame, when it wrote the G-buffer's rays (a
    /// forward frame does not): what [`Renderer::reference_rays`] forms the centre rays
    /// of, even after a later `set_scene`.
    rays_frame: Option<(Scene, crate::scene::FrameCamera)>,
    /// The behind layer ([`Renderer::set_behind`]), while on and drawn.
    behind: Option<behind::Behind>,
    /// The behind layer is on but drawn empty: the frame's one object is a convex
    /// one-sided mesh (`convex_alone`), behind whose misses nothing can show,
    /// so no layer is allocated or recorded (its hits read as misses).
    behind_empty: bool,
    /// The frame's one geometry is a one-sided mesh that is convex
    /// ([`crate::mesh::Mesh::is_convex`], decided once when the renderer is built).
    convex_alone: bool,
    /// Whether a convex mesh alone draws its behind layer empty
    /// ([`Renderer::set_behind_convex_skip`], on by default).
    convex_skip: bool,
    /// The displaced meshes in world space, which the curved `exact` trace walks
    /// ([`crate::embed::DisplacementPass::set_curved_meshes`], given when curved tracing
    /// is first turned on).
    curved_meshes: Vec<crate::mesh::Mesh>,
    /// Whether the last frame was a forward frame ([`Renderer::render_forward`]): its
    /// iteration counts are the forward path's, not the pass's.
    forward_frame: bool,
}

impl Renderer {
    /// The material of each object of [`Renderer::with_objects`] (`None`: flat), in the
    /// objects' order; one entry, the primary material, for a renderer of one geometry.
    pub fn object_materials(&self) -> Vec<Option<MaterialId>> {
        match &self.objects {
            Some(o) => o.materials.clone(),
            None => vec![Some(self.pass.primary())],
        }
    }

    /// The G-buffer of the last frame (after [`Renderer::render`]: sampled-readable by
    /// compute shaders, `SHADER_READ_ONLY_OPTIMAL`), e.g. its tangent for the depth
    /// resolve.
    pub fn gbuffer(&self) -> &GBuffer {
        &self.gbuffer
    }

    /// The settings in use.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// The displacement pass this renderer hosts (read-only: its images and state).
    pub fn pass(&self) -> &DisplacementPass {
        &self.pass
    }

    /// The context.
    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
    }

    /// Changes the frame size: a new G-buffer, hit images and colour image of `width` x
    /// `height`, and the pass's [`DisplacementPass::resize`]; the map, method, shadows
    /// and scene stay. Every frame of this renderer was waited for, so the old images
    /// are destroyed here; a caller that recorded work of its own on
    /// [`Renderer::color_image`] must have waited for it first. On error the renderer
    /// keeps its old size.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<()> {
        let settings = RenderSettings {
            width,
            height,
            ..self.settings
        };
        settings.validate()?;
        let extent = settings.extent();
        if extent == self.settings.extent() {
            return Ok(());
        }
        let c = &*self.ctx;
        let curve = self.gbuffer.curve.is_some();
        let (gbuffer, hit, color) = build::frame_images(c, extent, curve)?;
        let behind_images = match &self.behind {
            Some(_) => Some(behind::Behind::images(c, extent, curve)?),
            None => None,
        };
        if let Some(m) = &mut self.motion {
            // SAFETY: every frame of this renderer was waited for (`render` submits and
            // waits): nothing reads the old motion image.
            unsafe { m.resize(c, extent)? };
        }
        self.pass.resize(extent)?;
        let mut old = (
            std::mem::replace(&mut self.gbuffer, gbuffer.keep()),
            (
                std::mem::replace(&mut self.hit, hit.keep()),
                std::mem::replace(&mut self.color, color.keep()),
            ),
        );
        // SAFETY: every frame of this renderer was waited for (`render` submits and waits).
        unsafe { old.destroy(c) };
        if let (Some(b), Some((g, h))) = (&mut self.behind, behind_images) {
            let mut old = b.swap_images((g.keep(), h.keep()));
            // SAFETY: as above.
            unsafe {
                old.0.destroy(c);
                old.1.destroy(c);
            }
        }
        self.settings = settings;
        self.depth_written = false;
        self.rays_frame = None;
        Ok(())
    }

    /// The colour image (`R8G8B8A8_UNORM` holding sRGB-encoded values, the frame size)
    /// that [`Renderer::render`] shades into, for a caller that copies or blits it in a
    /// submission of its own (a viewer presenting the frame). After `render` returns the
    /// frame has completed and the image is in `GENERAL`, last written by a compute
    /// storage write ([`Access::COMPUTE_STORAGE_WRITE`]); it has `TRANSFER_SRC` usage.
    /// The caller places its barrier from that state, returns the image to it before
    /// the renderer's next use (`render` discards it; the `read_*` helpers read it), and
    /// waits for its submission before [`Renderer::resize`] or dropping the renderer.
    pub fn color_image(&self) -> &Image {
        &self.color
    }

    /// Switches the method (and its parameters); the G-buffer and map stay. On error
    /// the renderer keeps its old method (as [`DisplacementPass::set_method`]).
    pub fn set_method(&mut self, method: Method, params: MethodParams) -> Result<()> {
        let result = self.pass.set_method(method, params);
        // The pass is the state: it may have switched even on an error (its shadow
        // stage's exception), so the settings follow it either way.
        let pass = *self.pass.settings();
        self.settings.method = pass.method;
        self.settings.params = pass.params;
        if pass.method.needs().pyramid.is_none() && !self.settings.shadows.is_on() {
            self.builds.retain(|(name, _)| *name != PassName::Pyramid);
        }
        if pass.method.needs().cone.is_none() {
            self.builds.retain(|(name, _)| *name != PassName::Cone);
        }
        result
    }

    /// Traces the displaced meshes as curved geometry (`on`) or as their tangent planes
    /// (the default): [`DisplacementPass::set_material_curved`] on the material of every
    /// displaced mesh object (a single-geometry scene's when it is a mesh). The tiled
    /// plane and the quad are never curved, nor an object whose mesh has one normal
    /// ([`crate::mesh::Mesh::has_one_normal`]: nothing to bend). On, the G-buffer gets its curve image (4
    /// bytes a pixel, the layers' pipelines rebuilt with their `CURVE` variants), whatever
    /// the methods, so a later method change that traces curved finds it; off, it goes.
    pub fn set_curved(&mut self, on: bool) -> Result<()> {
        let materials: Vec<MaterialId> = match &self.objects {
            Some(o) => o
                .meshes
                .iter()
                .zip(&o.materials)
                .zip(&o.one_normal)
                .filter_map(|((mesh, m), one)| mesh.as_ref().filter(|_| !one).and(*m))
                .collect(),
            None if matches!(
                self.settings.scene.geometry,
                Geometry::TiledPlane | Geometry::Quad
            ) =>
            {
                Vec::new()
            }
            None => vec![self.pass.primary()],
        };
        if materials.is_empty() {
            return Ok(());
        }
        // The G-buffer gets (or drops) its curve image first, then the materials follow;
        // a failure of either leaves the renderer as it was.
        if on && self.pass.curved_mesh_triangles() == 0 && !self.curved_meshes.is_empty() {
            let meshes: Vec<&crate::mesh::Mesh> = self.curved_meshes.iter().collect();
            self.pass.set_curved_meshes(&meshes)?;
        }
        let was = self.gbuffer.curve.is_some();
        self.set_curve_image(on)?;
        let mut done = Vec::new();
        for &m in &materials {
            let old = self.pass.material_curved(m)?;
            if let Err(e) = self.pass.set_material_curved(m, on) {
                for &(m, old) in done.iter().rev() {
                    let _ = self.pass.set_material_curved(m, old);
                }
                let _ = self.set_curve_image(was);
                return Err(e);
            }
            done.push((m, old));
        }
        Ok(())
    }

    /// Gives the G-buffer its curve image (`on`: what curved tracing reads) or takes it
    /// away, with the pipelines that draw into it (the behind layer's too). On error
    /// nothing changes.
    fn set_curve_image(&mut self, on: bool) -> Result<()> {
        if self.gbuffer.curve.is_some() == on {
            return Ok(());
        }
        let ctx = self.ctx.clone();
        let c = &*ctx;
        let extent = self.settings.extent();
        let gbuffer = if on {
            GBuffer::new_curved(c, extent)?
        } else {
            GBuffer::new(c, extent)?
        };
        // SAFETY: no command has used the guarded values yet; they are kept below.
        let gbuffer = unsafe { Guard::new(c, gbuffer) };
        // The objects' mesh pipelines also get the twin that leaves the curve uncomputed
        // where a draw can use it (a mesh drawn alone is always curved).
        let zero = on && self.draws_skip_curve()?;
        let pipeline = |p: &GBufferPass, zero: bool| {
            GBufferPass::new_layer_with(c, p.is_mesh(), p.is_two_sided(), false, on, zero)
        };
        // SAFETY: as above.
        let gbuffer_pass = unsafe { Guard::new(c, pipeline(&self.gbuffer_pass, false)?) };
        let (mesh_pass, two_sided_pass) = match &self.objects {
            Some(o) => (
                o.mesh_pass
                    .as_ref()
                    .map(|p| pipeline(p, zero))
                    .transpose()?,
                o.two_sided_pass
                    .as_ref()
                    .map(|p| pipeline(p, zero))
                    .transpose()?,
            ),
            None => (None, None),
        };
        // SAFETY: as above.
        let (mesh_pass, two_sided_pass) =
            unsafe { (Guard::new(c, mesh_pass), Guard::new(c, two_sided_pass)) };
        if let Some(b) = &mut self.behind {
            // SAFETY: every frame of this renderer was waited for (`render` submits and
            // waits): nothing pending uses the layer.
            unsafe { b.set_curve(c, extent, on, zero)? };
        }
        let mut old_gbuffer = std::mem::replace(&mut self.gbuffer, gbuffer.keep());
        let mut old_pass = std::mem::replace(&mut self.gbuffer_pass, gbuffer_pass.keep());
        let (mut old_mesh, mut old_two_sided) = match &mut self.objects {
            Some(o) => (
                std::mem::replace(&mut o.mesh_pass, mesh_pass.keep()),
                std::mem::replace(&mut o.two_sided_pass, two_sided_pass.keep()),
            ),
            None => (None, None),
        };
        // SAFETY: every frame of this renderer was waited for: nothing pending uses the
        // old G-buffer and pipelines.
        unsafe {
            old_gbuffer.destroy(c);
            old_pass.destroy(c);
            old_mesh.destroy(c);
            old_two_sided.destroy(c);
        }
        Ok(())
    }

    /// Whether a G-buffer draw of a curved frame can leave the curve uncomputed
    /// ([`GBufferDraw::curve`] false): a scene of several objects with a mesh that is not
    /// displaced, drawn with one normal (never traced curved) or of a method without a
    /// curved path.
    fn draws_skip_curve(&self) -> Result<bool> {
        let Some(o) = &self.objects else {
            return Ok(false);
        };
        for ((mesh, material), &one) in o.meshes.iter().zip(&o.materials).zip(&o.one_normal) {
            if mesh.is_none() {
                continue;
            }
            match material {
                None => return Ok(true),
                Some(id) if one || !self.pass.material_settings(*id)?.method.traces_curved() => {
                    return Ok(true);
                }
                Some(_) => {}
            }
        }
        Ok(false)
    }

    /// Switches self-shadowing (builds or drops the `shadow` pass and its image).
    pub fn set_shadows(&mut self, shadows: ShadowSettings) -> Result<()> {
        self.pass.set_shadows(shadows)?;
        self.settings.shadows = shadows;
        Ok(())
    }

    /// Changes camera, light or depth scale (the geometry and addressing must stay).
    pub fn set_scene(&mut self, scene: Scene) -> Result<()> {
        scene.validate()?;
        if scene.geometry != self.settings.scene.geometry {
            return Err(Error::invalid(
                "geometry",
                "changing the geometry needs a new renderer",
            ));
        }
        if scene.addressing() != self.pass.settings().addressing {
            return Err(Error::invalid(
                "geometry",
                "changing the addressing needs a new renderer",
            ));
        }
        self.pass.set_depth_scale(scene.depth_scale)?;
        self.settings.scene = scene;
        Ok(())
    }

    /// Turns the corrected-depth output on (the pass's `hit_depth` stage; every later
    /// [`Renderer::render`] runs it after `shade`) or off.
    pub fn set_depth_output(&mut self, on: bool) -> Result<()> {
        if on != self.pass.depth_output() {
            self.pass.set_depth_output(on)?;
            self.depth_written = false;
        }
        Ok(())
    }

    /// Turns the motion output on or off. On, every later [`Renderer::render`] writes the
    /// motion of every pixel (pixels, previous minus current position: the renderer's
    /// static world through the camera of the frame before, which is the frame's own for
    /// the first frame) into an `R32G32_SFLOAT` image: its `camera_motion` pass writes the
    /// macro surface's, then the pass's `motion` stage (source
    /// [`crate::embed::MotionSource::Surface`]) corrects the displaced pixels.
    pub fn set_motion_output(&mut self, on: bool) -> Result<()> {
        let c = &*self.ctx;
        match (on, &mut self.motion) {
            (true, None) => {
                // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
                let motion =
                    unsafe { Guard::new(c, CameraMotion::new(c, self.settings.extent())?) };
                self.pass.set_motion_output(Some(MotionSettings {
                    format: CAMERA_MOTION_FORMAT,
                    ..MotionSettings::default()
                }))?;
                self.motion = Some(motion.keep());
            }
            (false, Some(_)) => {
                self.pass.set_motion_output(None)?;
                // Every frame of this renderer was waited for.
                // SAFETY: every frame of this renderer was waited for (`render` submits and waits).
                unsafe { self.motion.destroy(c) };
            }
            _ => {}
        }
        Ok(())
    }

    /// The last frame's motion vectors (pixels, previous minus current), row by row;
    /// `None` when the output is off or no frame has been rendered with it.
    pub fn read_motion(&self) -> Result<Option<Vec<[f32; 2]>>> {
        let Some(m) = self.motion.as_ref().filter(|m| m.previous.is_some()) else {
            return Ok(None);
        };
        let bytes = read_image(
            &self.ctx,
            &self.shot,
            &m.image,
            Access::COMPUTE_STORAGE_WRITE,
        )?;
        Ok(Some(bytemuck::cast_slice::<u8, [f32; 2]>(&bytes).to_vec()))
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        let ctx = &*self.ctx;
        // SAFETY: every submission was waited for; idle makes sure of it on error paths.
        unsafe {
            let _ = ctx.device().device_wait_idle();
        }
        // SAFETY: the device is idle: no frame recorded with the pass is pending.
        unsafe { self.pass.destroy() };
        // SAFETY: the device is idle: no submission uses these objects.
        unsafe {
            self.mesh.destroy(ctx);
            self.objects.destroy(ctx);
            self.forward.destroy(ctx);
            self.behind.destroy(ctx);
            self.gbuffer_pass.destroy(ctx);
            self.background.destroy(ctx);
            self.motion.destroy(ctx);
            self.color.destroy(ctx);
            self.hit.destroy(ctx);
            self.gbuffer.destroy(ctx);
            self.timestamps.destroy(ctx);
            self.shot.destroy(ctx);
        }
    }
}
