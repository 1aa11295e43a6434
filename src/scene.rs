//! Camera, light and macro geometry, and the per-frame constants they give the passes.
//!
//! World space is y-up; the macro surface lies on the `y = 0` plane with `u` along `+x`
//! and `v` along `+z`; one tile (one repeat of the height map) is one world unit, and the
//! displacement depth `depth_scale` is in the same units.
//!
//! The other geometries (cube, sphere, torus, a loaded mesh: see [`crate::mesh`]) are
//! meshes centred on the origin inside the unit sphere; the orbit camera looks at the
//! origin from far enough to frame that sphere, and `depth_scale` is in units of the
//! local uv scale (the `crate::mesh` docs say why).

use crate::abi::{ADDRESSING_CLAMP, ADDRESSING_REPEAT, GBufferParams, ShadeParams};
use crate::error::{Error, Result};
use crate::heightfield::Addressing;
use crate::passes::gbuffer::Ray;
use crate::pixel_rays::{PixelRays, PlaneRect};
use glam::{Mat4, Vec3, Vec4};

/// Half the side of the tiled plane, in tiles: "effectively infinite" (the plane's edge
/// is below 0.004 degrees above the horizon from the default camera height).
pub const PLANE_HALF_EXTENT: f32 = 4096.0;
/// Cells of the tiled plane's grid on each side of the eye along each axis (the plane is
/// drawn as `2n x 2n` cells growing geometrically from about the eye's height across under
/// the eye to [`PLANE_HALF_EXTENT`]: a factor of about 2 per cell from the default
/// height). Each cell spans depths within a small ratio, which keeps the rasterised depth
/// and uv at f32 precision up to the horizon and leaves no pixel uncovered (two triangles
/// 8192 tiles wide gave depths off by up to 4.3e-3 at the horizon and gaps at the frame's
/// edge on close-ups).
pub const PLANE_GRID_CELLS: u32 = 16;
/// Near plane distance (world units); the far plane is at infinity (reverse-Z).
pub const NEAR: f32 = 0.005;
/// Lower bound of `-V.z` in the G-buffer: beyond it the parallax vector is clamped so it
/// stays finite (|P| <= depth_scale / MIN_COS) at grazing angles.
pub const MIN_COS: f32 = 1e-4;

/// The macro geometry the height field displaces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Geometry {
    /// An effectively infinite plane tiled with the map (repeat addressing).
    TiledPlane,
    /// One unit quad carrying the map once (clamp addressing: rays that leave it are
    /// discarded, giving silhouettes).
    Quad,
    /// A unit cube, each face carrying the map once, one surface id per face (clamp
    /// addressing by default: each face is a decal with displaced silhouettes at its
    /// edges, as in Yerex & Jagersand's figure).
    Cube,
    /// A sphere, the map tiled 4 x 2 times (repeat addressing).
    Sphere,
    /// A torus, the map tiled 7 x 3 times (repeat addressing).
    Torus,
    /// A mesh loaded from a file (OBJ), given to the renderer as a
    /// [`crate::mesh::Mesh`] (repeat addressing by default).
    Mesh,
}

impl Geometry {
    /// The name scene files and `--geometry` use (`plane` for the tiled plane).
    pub fn name(self) -> &'static str {
        match self {
            Geometry::TiledPlane => "plane",
            Geometry::Quad => "quad",
            Geometry::Cube => "cube",
            Geometry::Sphere => "sphere",
            Geometry::Torus => "torus",
            Geometry::Mesh => "mesh",
        }
    }

    /// The addressing this geometry implies unless the scene says otherwise.
    pub fn addressing(self) -> Addressing {
        match self {
            Geometry::TiledPlane | Geometry::Sphere | Geometry::Torus | Geometry::Mesh => {
                Addressing::Repeat
            }
            Geometry::Quad | Geometry::Cube => Addressing::Clamp,
        }
    }

    /// Whether it is drawn from a vertex buffer (everything but the plane and the quad).
    pub fn is_mesh(self) -> bool {
        !matches!(self, Geometry::TiledPlane | Geometry::Quad)
    }

    /// The generated mesh of the cube, sphere or torus (`None` for the plane, the quad
    /// and a loaded mesh).
    pub fn generated_mesh(self) -> Option<crate::mesh::Mesh> {
        match self {
            Geometry::Cube => Some(crate::mesh::Mesh::cube()),
            Geometry::Sphere => Some(crate::mesh::Mesh::sphere()),
            Geometry::Torus => Some(crate::mesh::Mesh::torus()),
            _ => None,
        }
    }
}

impl std::str::FromStr for Geometry {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "plane" | "tiled-plane" => Ok(Geometry::TiledPlane),
            "quad" => Ok(Geometry::Quad),
            "cube" => Ok(Geometry::Cube),
            "sphere" => Ok(Geometry::Sphere),
            "torus" => Ok(Geometry::Torus),
            "mesh" => Ok(Geometry::Mesh),
            other => Err(Error::invalid(
                "geometry",
                format!("'{other}' is not one of: plane, quad, cube, sphere, torus, mesh"),
            )),
        }
    }
}

/// An orbit camera looking at the geometry's centre.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Camera {
    /// Angle in degrees between the central view ray and the plane (90 = straight down).
    pub elevation_deg: f32,
    /// Rotation about the vertical axis, degrees.
    pub azimuth_deg: f32,
    /// Vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Eye height above the macro surface for the tiled plane (tiles); the quad uses
    /// a distance that frames it.
    pub height: f32,
    /// Distance from the eye to the centre the camera orbits, for the quad and the
    /// meshes (world units); `None`: the distance that frames the geometry. The tiled
    /// plane's distance follows from `height` and ignores this.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub distance: Option<f32>,
}

/// An angle in degrees reduced to `(-360, 360)` in f64, then rounded to f32 once: the
/// remainder of a float is exact, so every stage of the camera (the raster camera in
/// f32, the pixel rays in f64) turns by the same angle however large the one given
/// (3e9 degrees included), and an angle already in the range is kept bit for bit. A
/// non-finite angle is kept (and refused by [`Scene::validate`]).
pub fn reduce_degrees(degrees: f64) -> f32 {
    if degrees.is_finite() {
        (degrees % 360.0) as f32
    } else {
        // Kept as given, for the range check to name.
        degrees as f32
    }
}

impl Camera {
    /// The same camera with its azimuth reduced ([`reduce_degrees`]): what
    /// [`Scene::frame_camera`] and [`Scene::camera_looking_at`] build from.
    pub fn reduced(&self) -> Camera {
        Camera {
            azimuth_deg: reduce_degrees(f64::from(self.azimuth_deg)),
            ..*self
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            elevation_deg: 30.0,
            azimuth_deg: 0.0,
            fov_y_deg: 45.0,
            height: 0.25,
            distance: None,
        }
    }
}

/// A directional light.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Light {
    /// Angle above the plane, degrees.
    pub elevation_deg: f32,
    /// Rotation about the vertical axis, degrees.
    pub azimuth_deg: f32,
    /// Intensity.
    pub intensity: f32,
}

impl Default for Light {
    fn default() -> Self {
        Light {
            elevation_deg: 35.0,
            azimuth_deg: 60.0,
            intensity: 1.0,
        }
    }
}

/// Everything about the frame except the height field and the method.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Scene {
    /// Macro geometry.
    pub geometry: Geometry,
    /// Displacement depth in tile units (default 0.1).
    pub depth_scale: f32,
    /// Camera.
    pub camera: Camera,
    /// Light.
    pub light: Light,
    /// The height field's addressing; `None`: the geometry's ([`Geometry::addressing`]).
    pub addressing: Option<Addressing>,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            geometry: Geometry::TiledPlane,
            depth_scale: 0.1,
            camera: Camera::default(),
            light: Light::default(),
            addressing: None,
        }
    }
}

fn direction(elevation_deg: f32, azimuth_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}

/// View and projection of one frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameCamera {
    /// Eye position.
    pub eye: Vec3,
    /// World to clip.
    pub view_proj: Mat4,
    /// Eye-relative world (`world - eye`) to clip: `view_proj * translation(eye)`, built
    /// from the rotation alone so that no precision is lost far from the origin (the
    /// G-buffer pass transforms eye-relative positions).
    pub view_proj_eye: Mat4,
    /// The same camera in f64: each pixel's centre ray, the entry on the analytic
    /// surfaces ([`Scene::analytic_rays`]) and the G-buffer's double-float uniform
    /// ([`FrameCamera::pixel_ray_params`]).
    pub rays: PixelRays,
}

impl FrameCamera {
    /// The G-buffer's uniform of this frame's pixel rays (`glsl/gbuffer.frag`, and a host
    /// drawing dispmap's plane with `dispmap_plane_pixel_ray`).
    pub fn pixel_ray_params(&self) -> crate::abi::PixelRayParams {
        self.rays.params()
    }
}

impl Scene {
    /// Checks every number; the error names the field.
    pub fn validate(&self) -> Result<()> {
        let c = &self.camera;
        let checks: [(&str, f32, f32, f32); 6] = [
            ("depth-scale", self.depth_scale, 0.0, 1e3),
            ("camera-elevation", c.elevation_deg, 1e-3, 90.0),
            ("camera-fov", c.fov_y_deg, 1.0, 170.0),
            ("camera-height", c.height, 1e-3, 1e4),
            ("light-elevation", self.light.elevation_deg, -90.0, 90.0),
            ("light-intensity", self.light.intensity, 0.0, 1e3),
        ];
        for (name, value, lo, hi) in checks {
            if !value.is_finite() || value < lo || value > hi {
                return Err(Error::invalid(
                    name,
                    format!("{value} is outside [{lo}, {hi}]"),
                ));
            }
        }
        if let Some(d) = c.distance
            && !(d.is_finite() && (1e-3..=1e4).contains(&d))
        {
            return Err(Error::invalid(
                "camera-distance",
                format!("{d} is outside [0.001, 10000]"),
            ));
        }
        for (name, value) in [
            ("camera-azimuth", c.azimuth_deg),
            ("light-azimuth", self.light.azimuth_deg),
        ] {
            if !value.is_finite() {
                return Err(Error::invalid(name, format!("{value} is not a number")));
            }
        }
        // The flat surface's nearest point in the frame beyond the near plane (else the
        // bottom of the frame shows sky where the surface is): the tiled plane at the
        // eye height, the quad at the orbit distance's height above it.
        let (name, value, height) = match (self.geometry, c.distance) {
            (Geometry::TiledPlane, _) => ("camera-height", c.height, f64::from(c.height)),
            (Geometry::Quad, Some(d)) => (
                "camera-distance",
                d,
                f64::from(d) * f64::from(c.elevation_deg).to_radians().sin(),
            ),
            _ => return Ok(()),
        };
        let least = min_plane_height(c);
        if height < least {
            return Err(Error::invalid(
                name,
                format!(
                    "{value} puts the eye {height:.4} above the surface, which then comes \
                     nearer than the near plane ({NEAR}) at the frame's bottom edge and is \
                     cut away there: at elevation {} and field of view {} degrees the eye \
                     must be at least {least:.4} above it",
                    c.elevation_deg, c.fov_y_deg
                ),
            ));
        }
        Ok(())
    }

    /// Addressing of the height field: the scene's, else the geometry's.
    pub fn addressing(&self) -> Addressing {
        self.addressing
            .unwrap_or_else(|| self.geometry.addressing())
    }

    /// Distance from the eye to the point the camera orbits: from the eye height on the
    /// tiled plane, else [`Camera::distance`] or the distance that frames the geometry.
    pub fn orbit_distance(&self) -> f32 {
        let c = &self.camera;
        match self.geometry {
            Geometry::TiledPlane => c.height / c.elevation_deg.to_radians().sin().max(1e-6),
            Geometry::Quad => c.distance.unwrap_or(1.4),
            // Meshes fit the unit sphere: frame it vertically with a small margin.
            _ => c
                .distance
                .unwrap_or_else(|| 1.08 / (c.fov_y_deg.to_radians() / 2.0).sin().max(1e-3)),
        }
    }

    /// [`Scene::orbit_distance`] in f64 (the tiled plane's `height / sin e` rounded
    /// once, not twice).
    pub fn orbit_distance_f64(&self) -> f64 {
        let c = &self.camera;
        match self.geometry {
            Geometry::TiledPlane => {
                f64::from(c.height) / f64::from(c.elevation_deg).to_radians().sin().max(1e-6)
            }
            _ => f64::from(self.orbit_distance()),
        }
    }

    /// Eye and view-projection for a `width x height` frame.
    pub fn frame_camera(&self, width: u32, height: u32) -> FrameCamera {
        let target = match self.geometry {
            Geometry::Quad => Vec3::new(0.5, 0.0, 0.5),
            _ => Vec3::ZERO,
        };
        let distance = self.orbit_distance();
        let mut camera = self.camera_looking_at(width, height, target, distance);
        let c = &self.camera.reduced();
        camera.rays = PixelRays::orbit(
            c.elevation_deg,
            c.azimuth_deg,
            c.fov_y_deg,
            target.as_dvec3(),
            self.orbit_distance_f64(),
            width,
            height,
        );
        camera
    }

    /// The orbit camera of [`Scene::camera`] around `target` at `distance` (world units)
    /// for a `width x height` frame: what [`Scene::frame_camera`] uses with the
    /// geometry's target and distance, and a scene of several objects with the sphere
    /// around them ([`framing_distance`]).
    pub fn camera_looking_at(
        &self,
        width: u32,
        height: u32,
        target: Vec3,
        distance: f32,
    ) -> FrameCamera {
        let c = &self.camera.reduced();
        let to_eye = direction(c.elevation_deg, c.azimuth_deg);
        let eye = target + distance * to_eye;
        let forward = -to_eye;
        // Looking straight down, "up" on screen is the horizontal forward direction.
        let horizontal = Vec3::new(
            -c.azimuth_deg.to_radians().sin(),
            0.0,
            -c.azimuth_deg.to_radians().cos(),
        );
        let right = forward.cross(Vec3::Y);
        let right = if right.length_squared() < 1e-8 {
            horizontal.cross(Vec3::Y)
        } else {
            right.normalize()
        };
        let up = right.cross(forward);
        let view = glam::camera::rh::view::look_to_mat4(eye, forward, up);
        let view_eye = glam::camera::rh::view::look_to_mat4(Vec3::ZERO, forward, up);
        let aspect = width as f32 / height as f32;
        // Vulkan clip space (y down, depth in [0, 1]), reverse-Z with the far plane at
        // infinity: depth 1 at the near plane, 0 at the horizon and in the cleared sky.
        let proj = glam::camera::rh::proj::vulkan::perspective_infinite_reverse(
            c.fov_y_deg.to_radians(),
            aspect,
            NEAR,
        );
        FrameCamera {
            eye,
            view_proj: proj * view,
            view_proj_eye: proj * view_eye,
            rays: PixelRays::orbit(
                c.elevation_deg,
                c.azimuth_deg,
                c.fov_y_deg,
                target.as_dvec3(),
                f64::from(distance),
                width,
                height,
            ),
        }
    }

    /// The rectangle and uv mapping of the analytic surface of [`Scene::gbuffer_params`]
    /// (the tiled plane's square about the eye's tile, or the quad), in f64; `None` for
    /// meshes.
    pub fn analytic_rect(&self, camera: &FrameCamera) -> Option<PlaneRect> {
        if !matches!(self.geometry, Geometry::TiledPlane | Geometry::Quad) {
            return None;
        }
        let p = self.gbuffer_params(camera);
        Some(PlaneRect {
            world: p.world_rect.as_dvec4(),
            uv: p.uv_rect.as_dvec4(),
            repeat: self.addressing() == Addressing::Repeat,
        })
    }

    /// Each pixel's own ray on the analytic macro surface (the tiled plane, the quad), in
    /// f64 from the camera's f64 model: what the G-buffer computes in double-float
    /// (`glsl/gbuffer.frag`) and the reference traces. `None` for meshes, whose entry is
    /// the rasteriser's interpolation.
    pub fn analytic_rays(&self, camera: &FrameCamera) -> Option<Vec<Option<Ray>>> {
        let rect = self.analytic_rect(camera)?;
        Some(
            camera
                .rays
                .plane_rays(&rect, f64::from(self.depth_scale), f64::from(MIN_COS)),
        )
    }

    /// Push constants of the G-buffer pass.
    pub fn gbuffer_params(&self, camera: &FrameCamera) -> GBufferParams {
        let (world_rect, uv_rect, plane_cells) = match self.geometry {
            Geometry::TiledPlane => {
                // Centred on the eye's tile so UVs stay small (and precise) near the eye.
                let (cx, cz) = (camera.eye.x.floor(), camera.eye.z.floor());
                let r = PLANE_HALF_EXTENT;
                (
                    Vec4::new(cx - r, cz - r, cx + r, cz + r),
                    Vec4::new(-r, -r, r, r),
                    PLANE_GRID_CELLS,
                )
            }
            // The quad (two triangles); meshes do not read the rectangles.
            _ => (
                Vec4::new(0.0, 0.0, 1.0, 1.0),
                Vec4::new(0.0, 0.0, 1.0, 1.0),
                0,
            ),
        };
        GBufferParams {
            view_proj: camera.view_proj_eye,
            camera_pos: camera.eye.extend(1.0),
            world_rect,
            uv_rect,
            depth_scale: self.depth_scale,
            min_cos: MIN_COS,
            addressing: addressing_code(self.addressing()),
            plane_cells,
        }
    }

    /// The unit vector towards the light, world space.
    pub fn light_direction(&self) -> Vec3 {
        direction(
            self.light.elevation_deg,
            reduce_degrees(f64::from(self.light.azimuth_deg)),
        )
    }

    /// The shading constants of `camera`'s frame ([`ShadeParams::new`]).
    pub fn shade_params(
        &self,
        camera: &FrameCamera,
        frame_size: [u32; 2],
        map_size: [u32; 2],
    ) -> ShadeParams {
        ShadeParams::new(
            camera.view_proj,
            camera.eye,
            self.light_direction(),
            self.light.intensity,
            frame_size,
            map_size,
            self.depth_scale,
        )
    }
}

/// The least eye height above a flat surface at which the surface's nearest point in
/// the frame (on its bottom edge: view depth `h cos(fov/2) / sin(e + fov/2)`) is beyond
/// the near plane [`NEAR`], in f64.
pub fn min_plane_height(camera: &Camera) -> f64 {
    let e = f64::from(camera.elevation_deg).to_radians();
    let half = f64::from(camera.fov_y_deg).to_radians() / 2.0;
    f64::from(NEAR) * (e + half).sin() / half.cos()
}

/// The orbit distance that frames a sphere of `radius` (world units) with a vertical
/// field of view of `fov_y_deg` and a small margin: meshes, which fit the unit sphere, are
/// framed at `framing_distance(1.0, fov)`.
pub fn framing_distance(radius: f32, fov_y_deg: f32) -> f32 {
    1.08 * radius / (fov_y_deg.to_radians() / 2.0).sin().max(1e-3)
}

/// Where an object of a scene with several objects sits: scaled by `scale` (uniform, so
/// the uv stretch and the depth in units of the local uv scale keep their meaning),
/// rotated by `rotation_deg` (degrees about the fixed x, then y, then z axis), then moved
/// to `position`. The generated meshes and loaded meshes fit the unit sphere about the
/// origin before placement; the quad spans `[0, 1]` in x and z on `y = 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Translation (world units).
    pub position: Vec3,
    /// Uniform scale (> 0).
    pub scale: f32,
    /// Rotation about the x, y and z axes in that order, degrees.
    pub rotation_deg: Vec3,
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            position: Vec3::ZERO,
            scale: 1.0,
            rotation_deg: Vec3::ZERO,
        }
    }
}

impl Placement {
    /// Checks every number; the error names the field.
    pub fn validate(&self) -> Result<()> {
        if !self.position.is_finite() || self.position.abs().max_element() > 1e4 {
            return Err(Error::invalid(
                "position",
                format!("{} is outside [-1e4, 1e4] per axis", self.position),
            ));
        }
        if !(self.scale.is_finite() && self.scale >= 1e-3 && self.scale <= 1e4) {
            return Err(Error::invalid(
                "scale",
                format!("{} is outside [1e-3, 1e4]", self.scale),
            ));
        }
        if !self.rotation_deg.is_finite() {
            return Err(Error::invalid(
                "rotation",
                format!("{} is not finite", self.rotation_deg),
            ));
        }
        Ok(())
    }

    /// The rotation alone.
    pub fn rotation(&self) -> glam::Quat {
        let r = self.rotation_deg;
        glam::Quat::from_rotation_z(r.z.to_radians())
            * glam::Quat::from_rotation_y(r.y.to_radians())
            * glam::Quat::from_rotation_x(r.x.to_radians())
    }

    /// Object to world.
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            self.rotation(),
            self.position,
        )
    }
}

/// The shader code of an addressing mode.
pub fn addressing_code(a: Addressing) -> u32 {
    match a {
        Addressing::Repeat => ADDRESSING_REPEAT,
        Addressing::Clamp => ADDRESSING_CLAMP,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_names_parse_back() {
        for g in [
            Geometry::TiledPlane,
            Geometry::Quad,
            Geometry::Cube,
            Geometry::Sphere,
            Geometry::Torus,
            Geometry::Mesh,
        ] {
            assert_eq!(g.name().parse::<Geometry>().unwrap(), g);
        }
    }

    #[test]
    fn central_ray_has_the_requested_elevation() {
        for elevation in [5.0f32, 30.0, 89.0, 90.0] {
            let scene = Scene {
                camera: Camera {
                    elevation_deg: elevation,
                    ..Camera::default()
                },
                ..Scene::default()
            };
            let cam = scene.frame_camera(256, 144);
            // The centre of the screen projects the plane's target point (the origin).
            let clip = cam.view_proj * Vec4::new(0.0, 0.0, 0.0, 1.0);
            let ndc = clip.truncate() / clip.w;
            assert!(
                ndc.x.abs() < 1e-4 && ndc.y.abs() < 1e-4,
                "{elevation}: {ndc}"
            );
            let down = (-cam.eye).normalize();
            let measured = (-down.y).asin().to_degrees();
            assert!(
                (measured - elevation).abs() < 1e-2,
                "{elevation} vs {measured}"
            );
        }
    }

    #[test]
    fn bad_numbers_are_rejected_by_name() {
        let mut scene = Scene {
            depth_scale: f32::NAN,
            ..Scene::default()
        };
        let err = scene.validate().unwrap_err().to_string();
        assert!(err.contains("depth-scale"), "{err}");
        scene.depth_scale = 0.1;
        scene.camera.elevation_deg = 0.0;
        assert!(
            scene
                .validate()
                .unwrap_err()
                .to_string()
                .contains("camera-elevation")
        );
    }
}
