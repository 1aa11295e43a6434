//! The objects a standalone renderer draws: their meshes and displaced materials
//! ([`SceneObject`], [`SceneAssets`], [`ObjectAssets`]) and the G-buffer draws they
//! become.

use super::*;

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
pub(super) struct Objects {
    /// The meshes' pipeline (the plane's is `Renderer::gbuffer_pass`), when an object
    /// is not the tiled plane.
    pub(super) mesh_pass: Option<GBufferPass>,
    /// The two-sided meshes' pipeline, when an object is a two-sided mesh
    /// ([`crate::mesh::Mesh::two_sided`]).
    pub(super) two_sided_pass: Option<GBufferPass>,
    /// Per object: its vertex buffers (`None`: the tiled plane, drawn by the plane
    /// pipeline) ...
    pub(super) meshes: Vec<Option<MeshBuffers>>,
    /// ... its clusters, which the behind layer culls (empty for the tiled plane:
    /// `super::behind_draws`) ...
    pub(super) clusters: Vec<Vec<super::behind_draws::Cluster>>,
    /// ... whether its mesh has one normal ([`crate::mesh::Mesh::has_one_normal`]: a
    /// quad; `false` for the tiled plane), which curved tracing leaves flat ...
    pub(super) one_normal: Vec<bool>,
    /// ... whether it is a one-sided convex displaced mesh
    /// ([`crate::mesh::Mesh::is_convex`]; nothing of it lies behind its own surface, so
    /// the behind layer need not draw it where only its own pixels missed) ...
    pub(super) convex: Vec<bool>,
    /// ... and its material (`None`: flat).
    pub(super) materials: Vec<Option<MaterialId>>,
    /// The camera's target and orbit distance (`None`: the tiled plane's camera, when a
    /// plane is among the objects).
    pub(super) framing: Option<(glam::Vec3, f32)>,
}

impl crate::gpu::owned::Destroy for Objects {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.mesh_pass.destroy(ctx);
            self.two_sided_pass.destroy(ctx);
            self.meshes.destroy(ctx);
        }
    }
}

/// `settings` as a renderer of several objects keeps them: the method, parameters,
/// depth scale, addressing and geometry of its primary material (`geometry` and
/// `material`: the first displaced object's).
pub(super) fn objects_settings(
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
pub(super) fn check_eye(
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
pub(super) fn bounding_sphere(objects: &[SceneObject<'_>]) -> (glam::Vec3, f32) {
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
