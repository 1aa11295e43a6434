//! The standalone renderer: the first host of [`DisplacementPass`], the one orchestrator
//! of the compute passes. It owns only what a host owns: the G-buffer pass and images,
//! the mesh, the hit and colour images, a timestamp pool, and one-shot submission with
//! read-back. Each frame it records exactly what `examples/host_engine.rs` records:
//!
//! 1. G-buffer images: discarded (`UNDEFINED`, after last frame's compute reads and
//!    read-back copies) -> attachment layouts; `gbuffer` clears and writes them (timed
//!    in the renderer's own scope).
//! 2. G-buffer -> `SHADER_READ_ONLY_OPTIMAL` for compute; hit buffer and colour:
//!    discarded -> `GENERAL` for storage writes (the pass's entry contract).
//! 3. [`DisplacementPass::record`] with a [`ShadeTarget`]: `[upload] -> [pyramid] ->
//!    [dig_corners] -> trace -> [shadow] -> shade -> [hit_depth]`, each stage placing its
//!    own barriers, timed into the renderer's pool after the G-buffer's queries.
//!
//! After a frame the hit buffer is in `GENERAL` (last access: storage read), the colour
//! in `GENERAL` (last access: storage write), the G-buffer in
//! `SHADER_READ_ONLY_OPTIMAL`, and the pass's images as its module docs say; the
//! read-back helpers use exactly those states. The renderer keeps one frame slot and
//! waits for each frame, so what the pass retires is destroyed by the next frame.

mod forward;

use crate::context::Context;
use crate::embed::{
    DepthCamera, DisplacementPass, FrameInputs, MAX_QUERIES, MaterialId, MaterialSettings,
    MotionSettings, PassSettings, ShadeTarget, Timestamps,
};
use crate::error::{Error, Result};
use crate::gpu::commands::{read_image, upload_image};
use crate::gpu::owned::{Destroy, Guard};
use crate::gpu::sync::{self, Access};
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
use crate::passes::trace::{HIT_FORMAT, HitTexel};
use crate::scene::{Geometry, Placement, Scene};
use crate::timing::{QueryPool, ScopeWriter, read_timestamps};
use ash::vk;
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

/// Discarded contents, after compute reads or read-back copies of an earlier frame.
const DISCARD: Access = Access {
    stage: vk::PipelineStageFlags2::from_raw(
        vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw() | vk::PipelineStageFlags2::COPY.as_raw(),
    ),
    access: vk::AccessFlags2::NONE,
    layout: vk::ImageLayout::UNDEFINED,
};

/// The G-buffer's `normal` and `tangent` texels of a frame ([`Renderer::read_frames`]).
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
    hit: Image,
    color: Image,
    gbuffer_pass: GBufferPass,
    /// The host's shading of what the pass leaves alone: sky and flat geometry.
    background: BackgroundPass,
    /// The macro geometry's vertex and index buffers (meshes only).
    mesh: Option<MeshBuffers>,
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
}

/// The displaced material of one object of [`Renderer::with_objects`].
#[derive(Clone, Copy, Debug)]
pub struct ObjectMaterial<'a> {
    /// Its height map.
    pub field: &'a HeightField,
    /// Its method, parameters, depth scale and addressing.
    pub settings: MaterialSettings,
    /// Its albedo and normal map (empty: none).
    pub images: &'a MaterialImages,
}

/// One object of a frame of several objects ([`Renderer::with_objects`]).
#[derive(Clone, Copy, Debug)]
pub struct SceneObject<'a> {
    /// Its geometry: the tiled plane (which has no placement: `placement` must be the
    /// default), a quad, a generated mesh or a loaded one.
    pub geometry: Geometry,
    /// Where it sits.
    pub placement: Placement,
    /// The loaded mesh of [`Geometry::Mesh`] (needed there, ignored elsewhere).
    pub mesh: Option<&'a Mesh>,
    /// Its displaced material; `None`: drawn flat (not displaced, shaded by the
    /// renderer's background pass).
    pub material: Option<ObjectMaterial<'a>>,
}

/// Largest number of objects of [`Renderer::with_objects`].
pub const MAX_OBJECTS: usize = 256;

/// The objects of a frame of several objects: what the G-buffer pass draws.
struct Objects {
    /// The meshes' pipeline (the plane's is `Renderer::gbuffer_pass`), when an object
    /// is not the tiled plane.
    mesh_pass: Option<GBufferPass>,
    /// The two-sided meshes' pipeline, when an object is a two-sided mesh
    /// ([`crate::mesh::Mesh::two_sided`]).
    two_sided_pass: Option<GBufferPass>,
    /// Per object: its vertex buffers (`None`: the tiled plane, drawn by the plane
    /// pipeline) ...
    meshes: Vec<Option<MeshBuffers>>,
    /// ... and its material (`None`: flat).
    materials: Vec<Option<MaterialId>>,
    /// The camera's target and orbit distance (`None`: the tiled plane's camera, when a
    /// plane is among the objects).
    framing: Option<(glam::Vec3, f32)>,
}

impl crate::gpu::owned::Destroy for Objects {
    fn destroy(&mut self, ctx: &Context) {
        self.mesh_pass.destroy(ctx);
        self.two_sided_pass.destroy(ctx);
        self.meshes.destroy(ctx);
    }
}

/// `settings` as a renderer of several objects keeps them: the method, parameters,
/// depth scale, addressing and geometry of its primary material (`geometry` and
/// `material`: the first displaced object's).
fn objects_settings(
    mut settings: RenderSettings,
    geometry: Geometry,
    material: &MaterialSettings,
) -> RenderSettings {
    settings.method = material.method;
    settings.params = material.params;
    settings.scene.depth_scale = material.depth_scale;
    settings.scene.addressing = Some(material.addressing);
    settings.scene.geometry = geometry;
    settings
}

impl SceneAssets {
    /// `settings` as [`Renderer::with_assets`] keeps them with these assets: unchanged
    /// for one geometry; for several objects, with the first displaced object's
    /// geometry, method, parameters, depth scale and addressing (its material is the
    /// pass's primary one).
    pub fn settings(&self, settings: RenderSettings) -> RenderSettings {
        match self
            .objects
            .iter()
            .find_map(|o| o.material.as_ref().map(|m| (o.geometry, m.1)))
        {
            Some((geometry, material)) => objects_settings(settings, geometry, &material),
            None => settings,
        }
    }
}

/// Refuses a camera of a frame of several objects (`framing`: the orbit's target and
/// distance, `None` with the tiled plane's camera) whose eye is inside a closed object
/// (the cube, sphere or torus: it would cover no pixel) or nearer to an object's
/// surface than the near plane (it would be cut away there); `placed`: each object's
/// mesh as placed (`None` for the tiled plane). The error names the object.
fn check_eye(
    settings: &RenderSettings,
    framing: Option<(glam::Vec3, f32)>,
    objects: &[SceneObject<'_>],
    placed: &[Option<Mesh>],
) -> Result<()> {
    let scene = &settings.scene;
    let (w, h) = (settings.width, settings.height);
    let camera = match framing {
        Some((target, distance)) => {
            scene.camera_looking_at(w, h, target, scene.camera.distance.unwrap_or(distance))
        }
        None => Scene {
            geometry: Geometry::TiledPlane,
            ..*scene
        }
        .frame_camera(w, h),
    };
    let eye = camera.rays.eye;
    let near = f64::from(crate::scene::NEAR);
    for (i, (o, mesh)) in objects.iter().zip(placed).enumerate() {
        let Some(mesh) = mesh else {
            continue;
        };
        let closed = matches!(
            o.geometry,
            Geometry::Cube | Geometry::Sphere | Geometry::Torus
        );
        let at = format!("({:.4}, {:.4}, {:.4})", eye.x, eye.y, eye.z);
        if closed && mesh.encloses(eye) {
            return Err(Error::invalid(
                "camera",
                format!(
                    "the eye at {at} is inside object {} (a {}), which then covers no \
                     pixel: move the camera (its height, distance, elevation or azimuth) \
                     or the object",
                    i + 1,
                    format!("{:?}", o.geometry).to_lowercase()
                ),
            ));
        }
        let d = mesh.distance_to(eye);
        if d < near {
            return Err(Error::invalid(
                "camera",
                format!(
                    "the eye at {at} is {d:.4} from object {}'s surface, nearer than the \
                     near plane ({near}), which cuts it away: move the camera or the object",
                    i + 1
                ),
            ));
        }
    }
    Ok(())
}

/// The sphere around the objects (each generated or loaded mesh fits the unit sphere
/// before its placement; the quad spans `[0, 1]²`): its centre and radius.
fn bounding_sphere(objects: &[SceneObject<'_>]) -> (glam::Vec3, f32) {
    let spheres: Vec<(glam::Vec3, f32)> = objects
        .iter()
        .map(|o| {
            let p = &o.placement;
            match o.geometry {
                Geometry::Quad => (
                    p.matrix().transform_point3(glam::Vec3::new(0.5, 0.0, 0.5)),
                    p.scale * std::f32::consts::FRAC_1_SQRT_2,
                ),
                _ => (p.position, p.scale),
            }
        })
        .collect();
    let centre = spheres.iter().map(|s| s.0).sum::<glam::Vec3>() / spheres.len().max(1) as f32;
    let radius = spheres
        .iter()
        .map(|(c, r)| (*c - centre).length() + r)
        .fold(0.0f32, f32::max);
    (centre, radius)
}

/// What a scene brings besides the height field and the settings: a loaded mesh (for
/// [`crate::scene::Geometry::Mesh`]) and the material maps. The generated cube, sphere
/// and torus need no mesh here.
#[derive(Clone, Debug, Default)]
pub struct SceneAssets {
    /// The loaded mesh.
    pub mesh: Option<Mesh>,
    /// Albedo and normal map.
    pub material: MaterialImages,
    /// A scene of several objects: when not empty, [`Renderer::with_assets`] draws these
    /// ([`Renderer::with_objects`]) instead of the one geometry (its field, mesh and
    /// maps are then unused).
    pub objects: Vec<ObjectAssets>,
}

/// One object of a scene of several objects, owned ([`SceneAssets::objects`]).
#[derive(Clone, Debug)]
pub struct ObjectAssets {
    /// Its geometry.
    pub geometry: Geometry,
    /// Where it sits.
    pub placement: Placement,
    /// The loaded mesh of [`Geometry::Mesh`].
    pub mesh: Option<Mesh>,
    /// Its displacement (`None`: flat): height map, settings, material maps.
    pub material: Option<(HeightField, MaterialSettings, MaterialImages)>,
}

impl ObjectAssets {
    /// The object as [`Renderer::with_objects`] takes it.
    pub fn as_object(&self) -> SceneObject<'_> {
        SceneObject {
            geometry: self.geometry,
            placement: self.placement,
            mesh: self.mesh.as_ref(),
            material: self
                .material
                .as_ref()
                .map(|(field, settings, images)| ObjectMaterial {
                    field,
                    settings: *settings,
                    images,
                }),
        }
    }
}

impl Renderer {
    /// Uploads `field` and builds what `settings` needs (no loaded mesh, no material
    /// maps: see [`Renderer::with_assets`]).
    pub fn new(ctx: &Arc<Context>, field: &HeightField, settings: RenderSettings) -> Result<Self> {
        Self::with_assets(ctx, field, settings, &SceneAssets::default())
    }

    /// [`Renderer::new`] with a scene's mesh and material maps. Builds only what the
    /// scene uses: vertex buffers only for mesh geometry, textures only for given maps.
    /// The map (and the maps) are staged here and copied by the first frame.
    pub fn with_assets(
        ctx: &Arc<Context>,
        field: &HeightField,
        settings: RenderSettings,
        assets: &SceneAssets,
    ) -> Result<Self> {
        if !assets.objects.is_empty() {
            let objects: Vec<_> = assets.objects.iter().map(ObjectAssets::as_object).collect();
            return Self::with_objects(ctx, settings, &objects);
        }
        settings.validate()?;
        let geometry = settings.scene.geometry;
        let mesh = match (geometry.generated_mesh(), &assets.mesh) {
            (Some(generated), _) => Some(std::borrow::Cow::Owned(generated)),
            (None, Some(loaded)) if geometry == crate::scene::Geometry::Mesh => {
                Some(std::borrow::Cow::Borrowed(loaded))
            }
            (None, None) if geometry == crate::scene::Geometry::Mesh => {
                return Err(Error::invalid(
                    "geometry",
                    "'mesh' needs a loaded mesh (a scene file's `mesh` key)",
                ));
            }
            _ => None,
        };
        let max = ctx.info().max_image_dimension_2d;
        if field.width() > max || field.height() > max {
            return Err(Error::invalid(
                field.label(),
                format!(
                    "{}x{} exceeds the device's maxImageDimension2D ({max})",
                    field.width(),
                    field.height()
                ),
            ));
        }
        let extent = settings.extent();
        let c = &**ctx;
        // Built in order; a failure destroys what the guards hold.
        let host = HostParts::new(c, extent)?;
        let gbuffer_pass = Guard::new(
            c,
            if let Some(m) = &mesh {
                if m.two_sided {
                    GBufferPass::new_mesh_two_sided(c)?
                } else {
                    GBufferPass::new_mesh(c)?
                }
            } else {
                GBufferPass::new(c)?
            },
        );
        let mesh = Guard::new(
            c,
            mesh.map(|m| MeshBuffers::upload(c, &host.shot, &m))
                .transpose()?,
        );
        let mut pass = DisplacementPass::new(
            ctx.clone(),
            field,
            PassSettings {
                method: settings.method,
                params: settings.params,
                depth_scale: settings.scene.depth_scale,
                addressing: settings.scene.addressing(),
                extent,
                frames_in_flight: 1,
            },
        )?;
        let configured = pass
            .set_shadows(settings.shadows)
            .and_then(|()| pass.set_material(&assets.material));
        if let Err(e) = configured {
            // SAFETY: nothing was recorded with the pass.
            unsafe { pass.destroy() };
            return Err(e);
        }
        Ok(host.keep(ctx, settings, gbuffer_pass.keep(), mesh.keep(), None, pass))
    }

    /// A renderer of several objects in one G-buffer: each object drawn with its own
    /// placement and, when it has a material, that material's index in `tangent.w`, depth
    /// scale and addressing (the per-draw push constants: `camera_pos.w` carries the
    /// material, see [`crate::abi::GBufferParams`]); objects without one are drawn flat
    /// (`tangent.w = 0`) and shaded by the background pass. Mesh vertices are placed on
    /// the CPU once here (positions transformed, frames rotated, surface ids shifted so
    /// that no two objects share one). Each displaced object is one material of the pass
    /// (maps with equal content and addressing are shared by the pass), except that
    /// objects given the very same `field` and `images` (the same references) and equal
    /// settings share one material: the first
    /// displaced object's is the pass's primary material, and `settings`' method,
    /// parameters, depth scale, addressing and geometry are replaced by its own (so
    /// [`Renderer::set_method`] and [`Renderer::set_scene`]'s depth scale act on it).
    /// `settings`' camera orbits the centre of the sphere around the objects at its
    /// [`crate::scene::Camera::distance`] or else the distance that frames the sphere, or, with a tiled plane among them, is the plane's camera (the eye
    /// `height` above the plane, looking at the origin). At least one object needs a
    /// material.
    pub fn with_objects(
        ctx: &Arc<Context>,
        settings: RenderSettings,
        objects: &[SceneObject<'_>],
    ) -> Result<Self> {
        if objects.is_empty() || objects.len() > MAX_OBJECTS {
            return Err(Error::invalid(
                "objects",
                format!(
                    "{} objects: a frame takes 1 to {MAX_OBJECTS}",
                    objects.len()
                ),
            ));
        }
        let Some((first, primary)) = objects
            .iter()
            .find_map(|o| o.material.map(|m| (o.geometry, m)))
        else {
            return Err(Error::invalid(
                "objects",
                "no object has a height map: at least one must be displaced",
            ));
        };
        let settings = objects_settings(settings, first, &primary.settings);
        settings.validate()?;
        let mut placed = Vec::with_capacity(objects.len());
        let mut surface_offset = 0u32;
        for (i, o) in objects.iter().enumerate() {
            let name = |e: Error| match e {
                Error::InvalidInput { name, message } => {
                    Error::invalid(format!("object {} {name}", i + 1), message)
                }
                other => other,
            };
            o.placement.validate().map_err(name)?;
            let mesh = match o.geometry {
                Geometry::TiledPlane => {
                    if o.placement != Placement::default() {
                        return Err(name(Error::invalid(
                            "placement",
                            "the tiled plane has no position, scale or rotation",
                        )));
                    }
                    surface_offset += 1;
                    None
                }
                Geometry::Quad => Some(Mesh::quad()),
                Geometry::Mesh => Some(
                    o.mesh
                        .ok_or_else(|| {
                            name(Error::invalid(
                                "mesh",
                                "geometry 'mesh' needs a loaded mesh",
                            ))
                        })?
                        .clone(),
                ),
                g => g.generated_mesh(),
            };
            placed.push(mesh.map(|m| {
                let m = m.placed(&o.placement, surface_offset);
                surface_offset += m.max_surface_id().max(1);
                m
            }));
            if let Some(m) = &o.material {
                let max = ctx.info().max_image_dimension_2d;
                if m.field.width() > max || m.field.height() > max {
                    return Err(name(Error::invalid(
                        m.field.label(),
                        format!("exceeds the device's maxImageDimension2D ({max})"),
                    )));
                }
            }
        }
        let framing = if objects.iter().any(|o| o.geometry == Geometry::TiledPlane) {
            None
        } else {
            let (centre, radius) = bounding_sphere(objects);
            Some((
                centre,
                crate::scene::framing_distance(radius, settings.scene.camera.fov_y_deg),
            ))
        };
        check_eye(&settings, framing, objects, &placed)?;
        let extent = settings.extent();
        let c = &**ctx;
        let host = HostParts::new(c, extent)?;
        let gbuffer_pass = Guard::new(c, GBufferPass::new(c)?);
        let mut drawn = Guard::new(
            c,
            Objects {
                mesh_pass: None,
                two_sided_pass: None,
                meshes: Vec::new(),
                materials: Vec::new(),
                framing: None,
            },
        );
        // Only the pipelines the objects need.
        if placed.iter().flatten().any(|m| !m.two_sided) {
            drawn.mesh_pass = Some(GBufferPass::new_mesh(c)?);
        }
        if placed.iter().flatten().any(|m| m.two_sided) {
            drawn.two_sided_pass = Some(GBufferPass::new_mesh_two_sided(c)?);
        }
        for mesh in &placed {
            let buffers = mesh
                .as_ref()
                .map(|m| MeshBuffers::upload(c, &host.shot, m))
                .transpose()?;
            drawn.meshes.push(buffers);
        }
        drawn.framing = framing;
        // A material's refusal (its loop budget, its maps) names its object.
        let of_object = |i: usize| {
            move |e: Error| match e {
                Error::InvalidInput { name, message } => {
                    Error::invalid(format!("object {} {name}", i + 1), message)
                }
                other => other,
            }
        };
        let primary_index = objects
            .iter()
            .position(|o| o.material.is_some())
            .unwrap_or(0);
        let mut pass = DisplacementPass::new(
            ctx.clone(),
            primary.field,
            PassSettings {
                method: primary.settings.method,
                params: primary.settings.params,
                depth_scale: primary.settings.depth_scale,
                addressing: primary.settings.addressing,
                extent,
                frames_in_flight: 1,
            },
        )
        .map_err(of_object(primary_index))?;
        let mut first_material = true;
        let mut configure = |pass: &mut DisplacementPass| -> Result<()> {
            pass.set_shadows(settings.shadows)?;
            for (i, o) in objects.iter().enumerate() {
                // An object given the very same map, settings and maps as an earlier one
                // shares its material.
                let same = |a: &ObjectMaterial<'_>, b: &ObjectMaterial<'_>| {
                    std::ptr::eq(a.field, b.field)
                        && a.settings == b.settings
                        && std::ptr::eq(a.images, b.images)
                };
                let shared = o.material.as_ref().and_then(|m| {
                    objects[..i]
                        .iter()
                        .zip(&drawn.materials)
                        .find_map(|(e, id)| e.material.as_ref().filter(|e| same(e, m)).and(*id))
                });
                let id = match &o.material {
                    None => None,
                    Some(_) if shared.is_some() => shared,
                    Some(m) if first_material => {
                        first_material = false;
                        pass.set_material(m.images).map_err(of_object(i))?;
                        Some(pass.primary())
                    }
                    Some(m) => {
                        let id = pass
                            .add_material(m.field, m.settings)
                            .map_err(of_object(i))?;
                        pass.set_material_maps(id, m.images).map_err(of_object(i))?;
                        Some(id)
                    }
                };
                drawn.materials.push(id);
            }
            Ok(())
        };
        if let Err(e) = configure(&mut pass) {
            // SAFETY: nothing was recorded with the pass.
            unsafe { pass.destroy() };
            return Err(e);
        }
        Ok(host.keep(
            ctx,
            settings,
            gbuffer_pass.keep(),
            None,
            Some(drawn.keep()),
            pass,
        ))
    }

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

    /// Changes the frame size: a new G-buffer, hit buffer and colour image of `width` x
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
        let (gbuffer, hit, color) = frame_images(c, extent)?;
        if let Some(m) = &mut self.motion {
            m.resize(c, extent)?;
        }
        self.pass.resize(extent)?;
        let mut old = (
            std::mem::replace(&mut self.gbuffer, gbuffer.keep()),
            (
                std::mem::replace(&mut self.hit, hit.keep()),
                std::mem::replace(&mut self.color, color.keep()),
            ),
        );
        old.destroy(c);
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
                let motion = Guard::new(c, CameraMotion::new(c, self.settings.extent())?);
                self.pass.set_motion_output(Some(MotionSettings {
                    format: CAMERA_MOTION_FORMAT,
                    ..MotionSettings::default()
                }))?;
                self.motion = Some(motion.keep());
            }
            (false, Some(_)) => {
                self.pass.set_motion_output(None)?;
                // Every frame of this renderer was waited for.
                self.motion.destroy(c);
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

    /// Renders one frame and returns its per-pass GPU times (one-off passes included
    /// when this frame ran them).
    pub fn render(&mut self) -> Result<PassTimes> {
        let ctx = &*self.ctx;
        let (camera, target) = self.frame_target();
        let gbuffer_params = self.settings.scene.gbuffer_params(&camera);
        let draws = self.object_draws(&camera)?;
        let cmd = self.shot.begin(ctx)?;
        let mut w = ScopeWriter::new(Some(self.timestamps.0), 0, GBUFFER_QUERIES);
        // SAFETY: `cmd` was just begun; the pool is alive with the range.
        unsafe { w.reset(ctx, cmd) };

        let to_attachments = self.gbuffer.barriers(
            (DISCARD, Access::COLOR_ATTACHMENT_WRITE),
            (DISCARD, Access::DEPTH_ATTACHMENT_WRITE),
        );
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below, while the
        // G-buffer lives; its previous frame was waited for, so the contents may be
        // discarded; the images have attachment usage (`GBuffer::new`).
        unsafe { sync::record(ctx, cmd, &to_attachments) };
        // SAFETY: `cmd` is recording outside a render pass and `w.reset` was recorded
        // above (the scope's contract). In the body (inside this block): the G-buffer is
        // in the attachment layouts (the barriers above); it, the pass and the mesh's
        // buffers live until the submission below has completed.
        unsafe {
            w.scope(ctx, cmd, PassName::GBuffer, |cmd| {
                match (&draws, &self.mesh) {
                    (Some(draws), _) => crate::passes::gbuffer::record_draws(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        draws,
                        &camera.pixel_ray_params(),
                    ),
                    (None, Some(mesh)) => self.gbuffer_pass.record_mesh(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        &gbuffer_params,
                        mesh,
                    ),
                    (None, None) => self.gbuffer_pass.record(
                        ctx,
                        cmd,
                        &self.gbuffer,
                        &gbuffer_params,
                        &camera.pixel_ray_params(),
                    ),
                }
            })
        };

        // The pass's entry contract: G-buffer sampled by compute, hit buffer discarded in
        // GENERAL, colour in GENERAL with the host's background (below).
        let mut entry = self.gbuffer.barriers(
            (Access::COLOR_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
            (Access::DEPTH_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
        );
        for image in [&self.hit, &self.color] {
            entry.push(sync::image_barrier(
                image.raw,
                image.range(),
                DISCARD,
                Access::COMPUTE_STORAGE_WRITE,
            ));
        }
        // SAFETY: `cmd` is recording outside a render pass (begun above, submitted
        // below); the G-buffer was written as attachments by the scope above; the hit and
        // colour images are the renderer's, alive, and their previous frame was waited
        // for, so they may be discarded.
        unsafe { sync::record(ctx, cmd, &entry) };
        // SAFETY: `cmd` is recording outside a render pass and submitted below; the
        // G-buffer is sampled-readable and the colour image in GENERAL for storage writes
        // (the barriers above).
        unsafe { self.record_background(cmd, &target) };
        let mut inputs = self.frame_inputs(Some(target));
        let current = DepthCamera {
            view_proj: target.view_proj,
            eye: target.camera_pos,
        };
        if let Some(m) = &self.motion {
            // SAFETY: `cmd` is recording outside a render pass and submitted (and waited
            // for) below; the G-buffer depth is sampled-readable (the entry barriers); the
            // image's previous frame was waited for.
            inputs.motion = Some(unsafe { m.record(ctx, cmd, self.gbuffer.depth.view, current) });
        }
        // SAFETY: `cmd` is recording outside a render pass on the context's queue and is
        // submitted below; the views are the renderer's, in the entry states; one slot,
        // whose previous frame was waited for; the pool has the queries after the
        // G-buffer's.
        let frame = unsafe {
            self.pass.record(
                cmd,
                &inputs,
                Timestamps::Host {
                    pool: self.timestamps.0,
                    first_query: GBUFFER_QUERIES,
                },
            )?
        };
        self.shot.submit_and_wait(ctx)?;
        self.depth_written |= self.pass.depth_output();
        if let Some(m) = &mut self.motion {
            m.previous = Some(current);
        }
        self.rays_frame = Some((self.settings.scene, camera));
        self.frame_times(&w, &frame)
    }

    /// The per-pass times of a completed frame (the renderer's scopes, then the pass's),
    /// and the builds it ran kept for [`Renderer::build_ms`].
    fn frame_times(
        &mut self,
        own: &ScopeWriter,
        frame: &crate::embed::RecordedFrame,
    ) -> Result<PassTimes> {
        let scopes: Vec<_> = own
            .scopes
            .iter()
            .chain(&frame.timestamps)
            .copied()
            .collect();
        // SAFETY: the pool is alive and the frame completed (the caller waited for it).
        let times = unsafe { read_timestamps(&self.ctx, &scopes)? };
        for &(name, ms) in &times {
            if matches!(name, PassName::Pyramid | PassName::Cone) {
                self.builds.retain(|(n, _)| *n != name);
                self.builds.push((name, ms));
            }
        }
        Ok(times)
    }

    /// The GPU milliseconds of the last pyramid build (the method's, or hard shadows'
    /// cell pyramid), while the renderer has one.
    pub fn pyramid_ms(&self) -> Option<f64> {
        self.build_ms(PassName::Pyramid)
    }

    /// The GPU milliseconds of the last build of a one-off map, [`PassName::Pyramid`] or
    /// [`PassName::Cone`], while the renderer has it (`None` for other passes).
    pub fn build_ms(&self, pass: PassName) -> Option<f64> {
        self.builds
            .iter()
            .find(|(n, _)| *n == pass)
            .map(|&(_, ms)| ms)
    }

    /// The draws of a frame of several objects (`None` for one geometry): each object's
    /// push constants with its material (`camera_pos.w` = index + 1, 0 flat), the
    /// material's current depth scale and addressing.
    fn object_draws(
        &self,
        camera: &crate::scene::FrameCamera,
    ) -> Result<Option<Vec<GBufferDraw<'_>>>> {
        let Some(objects) = &self.objects else {
            return Ok(None);
        };
        let plane = Scene {
            geometry: Geometry::TiledPlane,
            ..self.settings.scene
        }
        .gbuffer_params(camera);
        let mesh = Scene {
            geometry: Geometry::Quad,
            ..self.settings.scene
        }
        .gbuffer_params(camera);
        let mut draws = Vec::with_capacity(objects.meshes.len());
        for (buffers, material) in objects.meshes.iter().zip(&objects.materials) {
            let mut params = if buffers.is_some() { mesh } else { plane };
            params.camera_pos.w = 0.0;
            if let Some(id) = material {
                let m = self.pass.material_settings(*id)?;
                params.camera_pos.w = (id.index() + 1) as f32;
                params.depth_scale = m.depth_scale;
                params.addressing = crate::scene::addressing_code(m.addressing);
            }
            let pass = match (buffers, &objects.mesh_pass, &objects.two_sided_pass) {
                (Some(b), _, Some(p)) if b.two_sided => p,
                (Some(_), Some(p), _) => p,
                _ => &self.gbuffer_pass,
            };
            draws.push(GBufferDraw {
                pass,
                params,
                mesh: buffers.as_ref(),
            });
        }
        Ok(Some(draws))
    }

    /// The frame's camera and what `shade` lights it with.
    fn frame_target(&self) -> (crate::scene::FrameCamera, ShadeTarget) {
        let scene = &self.settings.scene;
        let (w, h) = (self.settings.width, self.settings.height);
        let camera = match &self.objects {
            None => scene.frame_camera(w, h),
            Some(Objects {
                framing: Some((target, distance)),
                ..
            }) => {
                scene.camera_looking_at(w, h, *target, scene.camera.distance.unwrap_or(*distance))
            }
            Some(_) => Scene {
                geometry: Geometry::TiledPlane,
                ..*scene
            }
            .frame_camera(w, h),
        };
        let target = ShadeTarget {
            color: self.color.host_view(),
            view_proj: camera.view_proj,
            camera_pos: camera.eye,
            light_dir: scene.light_direction(),
            light_intensity: scene.light.intensity,
        };
        (camera, target)
    }

    /// The host's background (sky, flat geometry) into the colour image, then the
    /// colour's barrier for `shade`'s writes of the displaced pixels.
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass on the context's queue and is submitted
    /// (and waited for) while the renderer lives; when it executes, the G-buffer is
    /// sampled-readable by compute and the colour image in `GENERAL`, earlier accesses
    /// ordered before compute-shader storage writes.
    unsafe fn record_background(&self, cmd: vk::CommandBuffer, target: &ShadeTarget) {
        let ctx = &*self.ctx;
        let e = self.settings.extent();
        let params = crate::abi::ShadeParams::new(
            target.view_proj,
            target.camera_pos,
            target.light_dir,
            target.light_intensity,
            [e.width, e.height],
            [1, 1],
            0.0,
        );
        // SAFETY: this function's contract; the views are the renderer's, alive.
        unsafe {
            self.background.record(
                ctx,
                cmd,
                self.gbuffer.views(),
                self.color.view_ref(),
                &params,
            );
            sync::transition(
                ctx,
                cmd,
                &self.color,
                Access::COMPUTE_STORAGE_WRITE,
                Access::COMPUTE_STORAGE_WRITE,
            );
        }
    }

    fn frame_inputs(&self, shade: Option<ShadeTarget>) -> FrameInputs {
        FrameInputs {
            frame_slot: 0,
            gbuffer: self.gbuffer.views(),
            hit: self.hit.host_view(),
            shade,
            motion: None,
        }
    }

    /// The last frame's light visibility (1 = lit), row by row; `None` when
    /// self-shadowing is off.
    pub fn read_visibility(&self) -> Result<Option<Vec<f32>>> {
        let Some(image) = self.pass.visibility(0) else {
            return Ok(None);
        };
        let bytes = read_image(&self.ctx, &self.shot, image, Access::COMPUTE_STORAGE_READ)?;
        Ok(Some(
            bytes
                .chunks_exact(2)
                .map(|b| crate::passes::shadow::f16_to_f32(u16::from_le_bytes([b[0], b[1]])))
                .collect(),
        ))
    }

    /// The last frame's DIG corner grid (`None` unless the method is a DIG): the grid size
    /// in corners and the corners row by row.
    pub fn read_corners(&self) -> Result<Option<([u32; 2], Vec<Corner>)>> {
        match self.pass.corner_grid(0) {
            Some(c) => Ok(Some((
                c.size(),
                c.read(&self.ctx, &self.shot, Access::COMPUTE_SAMPLED)?,
            ))),
            None => Ok(None),
        }
    }

    /// The pyramid's levels (logical sizes, row by row); `None` unless the method uses
    /// one and a frame has built it.
    pub fn read_pyramid(&self) -> Result<Option<Vec<Vec<f32>>>> {
        self.pass
            .pyramid()
            .map(|p| p.read_levels(&self.ctx, &self.shot))
            .transpose()
    }

    /// The cone map, `(M, w)` per cell row by row (see [`crate::passes::cone`]); `None`
    /// unless the method uses one and a frame has built it.
    pub fn read_cone_map(&self) -> Result<Option<Vec<[f32; 2]>>> {
        self.pass
            .cone_map()
            .map(|c| c.read(&self.ctx, &self.shot))
            .transpose()
    }

    /// The corrected-depth image (`R32_SFLOAT`, reverse-Z clip depth of each pixel's hit,
    /// 0 without one; see [`crate::passes::hit_depth`]) once a frame has been rendered
    /// with the output on. It is in `GENERAL`, last written by a compute-shader storage
    /// write; a caller that reads it in its own submission (e.g.
    /// [`crate::passes::depth_resolve`]) places the barrier from that state and returns
    /// it there.
    pub fn hit_depth(&self) -> Option<&Image> {
        self.pass.hit_depth(0).filter(|_| self.depth_written)
    }

    /// The corrected depth of the last [`Renderer::render`]'s hits, row by row (`None`
    /// when the output is off; an error when no frame has been rendered since it was
    /// turned on). [`Renderer::shade_hits`] does not update it.
    pub fn read_depth(&self) -> Result<Option<Vec<f32>>> {
        if !self.pass.depth_output() {
            return Ok(None);
        }
        let image = self.hit_depth().ok_or_else(|| {
            Error::invalid(
                "depth output",
                "no frame has been rendered since the depth output was turned on",
            )
        })?;
        let bytes = read_image(&self.ctx, &self.shot, image, Access::COMPUTE_STORAGE_WRITE)?;
        Ok(Some(bytemuck::cast_slice::<u8, f32>(&bytes).to_vec()))
    }

    /// Each pixel's ray from the last frame's G-buffer (`None` where there is no
    /// geometry). An error after a forward frame ([`Renderer::render_forward`] writes no
    /// rays) or before the first frame.
    pub fn read_rays(&self) -> Result<Vec<Option<Ray>>> {
        if self.rays_frame.is_none() {
            return Err(Error::invalid(
                "rays",
                "the last frame wrote no rays (none rendered yet, or a forward frame): \
                 render a frame with Renderer::render first",
            ));
        }
        let ray = read_image(
            &self.ctx,
            &self.shot,
            &self.gbuffer.ray,
            Access::COMPUTE_SAMPLED,
        )?;
        let depth = self.read_macro_depth()?;
        let ray: &[[f32; 4]] = bytemuck::cast_slice(&ray);
        Ok(ray
            .iter()
            .zip(depth)
            .map(|(r, d)| {
                (d > 0.0).then(|| Ray {
                    uv0: [r[0] as f64, r[1] as f64],
                    parallax: [r[2] as f64, r[3] as f64],
                })
            })
            .collect())
    }

    /// The rays a CPU reference traces for the last frame: each pixel's own f64 centre
    /// ray where the macro surface is analytic (the tiled plane or the quad, drawn
    /// alone: [`crate::scene::Scene::analytic_rays`]), else the G-buffer's
    /// ([`Renderer::read_rays`]: meshes and scenes of several objects interpolate their
    /// entry). Pixels where the G-buffer and the centre ray disagree on coverage are
    /// listed: see [`ReferenceRays`].
    pub fn reference_rays(&self) -> Result<ReferenceRays> {
        let drawn = self.read_rays()?;
        let analytic = match (&self.rays_frame, &self.objects, &self.mesh) {
            (Some((scene, camera)), None, None) => scene.analytic_rays(camera),
            _ => None,
        };
        let Some(rays) = analytic else {
            return Ok(ReferenceRays {
                rays: drawn,
                analytic: false,
                drawn_only: Vec::new(),
                ray_only: Vec::new(),
            });
        };
        let (mut drawn_only, mut ray_only) = (Vec::new(), Vec::new());
        for (i, (d, r)) in drawn.iter().zip(&rays).enumerate() {
            match (d.is_some(), r.is_some()) {
                (true, false) => drawn_only.push(i),
                (false, true) => ray_only.push(i),
                _ => {}
            }
        }
        Ok(ReferenceRays {
            rays,
            analytic: true,
            drawn_only,
            ray_only,
        })
    }

    /// The last frame's G-buffer depth (reverse-Z depth of the macro surface, 0 where
    /// there is no geometry), row by row.
    pub fn read_macro_depth(&self) -> Result<Vec<f32>> {
        let depth = read_image(
            &self.ctx,
            &self.shot,
            &self.gbuffer.depth,
            Access::COMPUTE_SAMPLED,
        )?;
        Ok(bytemuck::cast_slice::<u8, f32>(&depth).to_vec())
    }

    /// Each pixel's material index from the last frame's G-buffer (`tangent.w` =
    /// handedness * (index + 1)): `None` where there is no geometry or the geometry is
    /// flat (not displaced).
    pub fn read_materials(&self) -> Result<Vec<Option<u32>>> {
        let (_, tangent) = self.read_frames()?;
        let depth = self.read_macro_depth()?;
        Ok(tangent
            .iter()
            .zip(depth)
            .map(|(t, d)| {
                let m = t[3].abs().round();
                (d > 0.0 && m >= 1.0).then(|| m as u32 - 1)
            })
            .collect())
    }

    /// The last frame's G-buffer `normal` and `tangent` texels (RGBA16F decoded), row by
    /// row.
    pub fn read_frames(&self) -> Result<TangentFrames> {
        let read = |image: &Image| -> Result<Vec<[f32; 4]>> {
            let bytes = read_image(&self.ctx, &self.shot, image, Access::COMPUTE_SAMPLED)?;
            Ok(crate::passes::shadow::decode_rgba16f(&bytes))
        };
        Ok((read(&self.gbuffer.normal)?, read(&self.gbuffer.tangent)?))
    }

    /// The last frame's hit buffer.
    pub fn read_hits(&self) -> Result<Vec<HitTexel>> {
        let bytes = read_image(
            &self.ctx,
            &self.shot,
            &self.hit,
            Access::COMPUTE_STORAGE_READ,
        )?;
        Ok(bytemuck::cast_slice::<u8, HitTexel>(&bytes).to_vec())
    }

    /// The last frame's colour image (RGBA8, sRGB-encoded).
    pub fn read_color(&self) -> Result<Vec<u8>> {
        read_image(
            &self.ctx,
            &self.shot,
            &self.color,
            Access::COMPUTE_STORAGE_WRITE,
        )
    }

    /// Shades `hits` (one texel per pixel) with the current G-buffer and returns the
    /// colour. Overwrites the hit buffer. With self-shadowing on, the `shadow` pass runs
    /// on `hits` first.
    pub fn shade_hits(&mut self, hits: &[HitTexel]) -> Result<Vec<u8>> {
        self.shade_hits_with(hits, None)
    }

    /// [`Renderer::shade_hits`] with the light visibility given (one value per pixel;
    /// self-shadowing must be on) instead of computed by the `shadow` pass
    /// ([`DisplacementPass::record_shading`]).
    pub fn shade_hits_with(
        &mut self,
        hits: &[HitTexel],
        visibility: Option<&[f32]>,
    ) -> Result<Vec<u8>> {
        let ctx = &*self.ctx;
        if visibility.is_some() && !self.settings.shadows.is_on() {
            return Err(Error::invalid(
                "visibility",
                "self-shadowing is off: nothing to shade with",
            ));
        }
        let given = visibility
            .map(|values| -> Result<Image> {
                let image = Guard::new(
                    ctx,
                    Image::new(
                        ctx,
                        "given_visibility",
                        VISIBILITY_FORMAT,
                        self.settings.extent(),
                        1,
                        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST,
                    )?,
                );
                upload_image(
                    ctx,
                    &self.shot,
                    &image,
                    &crate::passes::shadow::encode_visibility(values),
                    Access::COMPUTE_STORAGE_READ,
                )?;
                Ok(image.keep())
            })
            .transpose()?;
        let mut given = Guard::new(ctx, given);
        upload_image(
            ctx,
            &self.shot,
            &self.hit,
            bytemuck::cast_slice(hits),
            Access::COMPUTE_STORAGE_READ,
        )?;
        let (_, target) = self.frame_target();
        let inputs = self.frame_inputs(Some(target));
        let cmd = self.shot.begin(ctx)?;
        let color = &self.color;
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below; the colour image
        // is the renderer's, alive, and its previous frame was waited for, so it may be
        // discarded; the G-buffer is sampled-readable since the frame that drew it.
        unsafe {
            sync::transition(ctx, cmd, color, DISCARD, Access::COMPUTE_STORAGE_WRITE);
            self.record_background(cmd, &target);
        }
        // SAFETY: `cmd` is recording and submitted below; the hits (and the given
        // visibility) were uploaded and made visible to storage reads; one slot, whose
        // previous frame was waited for.
        unsafe {
            self.pass.record_shading(
                cmd,
                &inputs,
                given.as_ref().map(|v| v.view),
                Timestamps::Off,
            )?
        };
        self.shot.submit_and_wait(ctx)?;
        given.destroy(ctx);
        self.read_color()
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
        self.mesh.destroy(ctx);
        self.objects.destroy(ctx);
        self.forward.destroy(ctx);
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

/// What both constructors build for the renderer as a host, each guarded until
/// [`HostParts::keep`] assembles the renderer: the one-shot, the timestamp pool, the
/// frame-sized images and the background pass.
struct HostParts<'c> {
    shot: Guard<'c, OneShot>,
    timestamps: Guard<'c, QueryPool>,
    gbuffer: Guard<'c, GBuffer>,
    hit: Guard<'c, Image>,
    color: Guard<'c, Image>,
    background: Guard<'c, BackgroundPass>,
}

impl<'c> HostParts<'c> {
    /// Builds them in order; a failure destroys what was built.
    fn new(c: &'c Context, extent: vk::Extent2D) -> Result<Self> {
        let shot = Guard::new(c, OneShot::new(c, "renderer")?);
        let timestamps = Guard::new(
            c,
            QueryPool(crate::timing::timestamp_pool(
                c,
                "renderer.timestamps",
                GBUFFER_QUERIES + MAX_QUERIES,
            )?),
        );
        let (gbuffer, hit, color) = frame_images(c, extent)?;
        let background = Guard::new(c, BackgroundPass::new(c)?);
        Ok(HostParts {
            shot,
            timestamps,
            gbuffer,
            hit,
            color,
            background,
        })
    }

    /// The renderer of these parts and the rest.
    fn keep(
        self,
        ctx: &Arc<Context>,
        settings: RenderSettings,
        gbuffer_pass: GBufferPass,
        mesh: Option<MeshBuffers>,
        objects: Option<Objects>,
        pass: DisplacementPass,
    ) -> Renderer {
        Renderer {
            ctx: ctx.clone(),
            settings,
            shot: self.shot.keep(),
            timestamps: self.timestamps.keep(),
            gbuffer: self.gbuffer.keep(),
            hit: self.hit.keep(),
            color: self.color.keep(),
            gbuffer_pass,
            background: self.background.keep(),
            mesh,
            objects,
            pass,
            depth_written: false,
            motion: None,
            builds: Vec::new(),
            forward: None,
            rays_frame: None,
        }
    }
}

/// The images sized by the frame: the G-buffer, the hit image and the colour image, each
/// guarded until the caller keeps it (creation and `resize`).
fn frame_images(
    c: &Context,
    extent: vk::Extent2D,
) -> Result<(Guard<'_, GBuffer>, Guard<'_, Image>, Guard<'_, Image>)> {
    let gbuffer = Guard::new(c, GBuffer::new(c, extent)?);
    let hit = Guard::new(
        c,
        Image::new(
            c,
            "hits",
            HIT_FORMAT,
            extent,
            1,
            // COLOR_ATTACHMENT: the forward path writes it from its fragment shader.
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        )?,
    );
    let color = Guard::new(
        c,
        Image::new(
            c,
            "color",
            COLOR_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
        )?,
    );
    Ok((gbuffer, hit, color))
}
