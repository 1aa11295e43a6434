//! Each pixel's own centre ray in f64: the one source of the rays on the analytic macro
//! surfaces (the tiled plane and the quad), from which the G-buffer's double-float
//! uniform ([`PixelRayParams`], `dispmap_plane_pixel_ray` in
//! `glsl/include/dispmap_plane.glsl`) and the CPU reference's rays
//! ([`PixelRays::plane_rays`]) are both formed.
//!
//! The camera model is docs/design.md's "Camera and frame": the orbit eye
//! `target + dist (cos e sin a, sin e, cos e cos a)`, forward towards the target,
//! right = `forward x +y`, up = `right x forward`, and pixel `(x, y)`'s centre ray
//! `forward + sx tan(fov_y / 2) aspect right - sy tan(fov_y / 2) up` with
//! `(sx, sy) = ((x + 0.5) / W * 2 - 1, (y + 0.5) / H * 2 - 1)` (row 0 at the top). Every
//! value is computed in f64 from the scene's f32 inputs.

use crate::abi::PixelRayParams;
use crate::passes::gbuffer::Ray;
use glam::{DVec3, DVec4};

/// The f64 camera of one frame (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelRays {
    /// The eye (world).
    pub eye: DVec3,
    /// Unit view direction.
    pub forward: DVec3,
    /// Unit right vector (`forward x +y`, normalised).
    pub right: DVec3,
    /// Unit up vector (`right x forward`).
    pub up: DVec3,
    /// `tan(fov_y / 2)`.
    pub tan_half_fov_y: f64,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
}

/// The rectangle of the analytic surface on `y = 0` and its uvs: `world = (x0, z0, x1,
/// z1)`, `uv = (u0, v0, u1, v1)` at those corners (`GBufferParams::world_rect`,
/// `uv_rect`), and whether the addressing repeats (uv reduced to `[0, 1)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneRect {
    /// `x0, z0, x1, z1`.
    pub world: DVec4,
    /// `u0, v0, u1, v1`.
    pub uv: DVec4,
    /// Repeat addressing: the entry's uv is reduced to `[0, 1)`.
    pub repeat: bool,
}

/// Splits `x` into an f32 and the f32 rounding of what it left out.
fn hi_lo(x: f64) -> (f32, f32) {
    let hi = x as f32;
    (hi, (x - f64::from(hi)) as f32)
}

fn split3(v: DVec3) -> ([f32; 4], [f32; 4]) {
    let (x, y, z) = (hi_lo(v.x), hi_lo(v.y), hi_lo(v.z));
    ([x.0, y.0, z.0, 0.0], [x.1, y.1, z.1, 0.0])
}

impl PixelRays {
    /// The orbit camera of elevation `elevation_deg`, azimuth `azimuth_deg` and vertical
    /// field of view `fov_y_deg` around `target` at `distance`, for a `width x height`
    /// frame (the model of [`crate::scene::Scene::camera_looking_at`], in f64).
    pub fn orbit(
        elevation_deg: f32,
        azimuth_deg: f32,
        fov_y_deg: f32,
        target: DVec3,
        distance: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let e = f64::from(elevation_deg).to_radians();
        let a = f64::from(azimuth_deg).to_radians();
        let to_eye = DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos());
        let eye = target + distance * to_eye;
        let forward = -to_eye;
        let right = forward.cross(DVec3::Y);
        // Straight down (as the f32 camera decides it): up on screen is the horizontal
        // forward direction.
        let right = if (right.as_vec3()).length_squared() < 1e-8 {
            DVec3::new(-a.sin(), 0.0, -a.cos()).cross(DVec3::Y)
        } else {
            right.normalize()
        };
        let up = right.cross(forward);
        PixelRays {
            eye,
            forward,
            right,
            up,
            tan_half_fov_y: (f64::from(fov_y_deg).to_radians() / 2.0).tan(),
            width,
            height,
        }
    }

    /// The direction (not normalised) of pixel `(x, y)`'s centre ray.
    pub fn direction(&self, x: u32, y: u32) -> DVec3 {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let sx = (f64::from(x) + 0.5) / w * 2.0 - 1.0;
        let sy = (f64::from(y) + 0.5) / h * 2.0 - 1.0;
        let ty = self.tan_half_fov_y;
        self.forward + self.right * (sx * ty * w / h) - self.up * (sy * ty)
    }

    /// Where pixel `(x, y)`'s centre ray meets `y = 0` inside `rect` from above: the entry
    /// point and the ray's direction (`None`: the ray points at or above the horizon,
    /// the eye is not above the plane, or the entry lies outside the rectangle).
    pub fn plane_entry(&self, x: u32, y: u32, rect: &PlaneRect) -> Option<(DVec3, DVec3)> {
        let d = self.direction(x, y);
        if !(d.y < 0.0 && self.eye.y > 0.0) {
            return None;
        }
        let t = self.eye.y / -d.y;
        let rel = d * t;
        let p = DVec3::new(self.eye.x + rel.x, 0.0, self.eye.z + rel.z);
        let w = rect.world;
        let inside = rel.x >= w.x - self.eye.x
            && rel.x <= w.z - self.eye.x
            && rel.z >= w.y - self.eye.z
            && rel.z <= w.w - self.eye.z;
        inside.then_some((p, d))
    }

    /// Pixel `(x, y)`'s ray on the analytic surface `rect`, as the G-buffer encodes it
    /// (`glsl/include/dispmap_gbuffer.glsl`): the entry's uv (reduced to `[0, 1)` with
    /// repeat addressing) and the parallax vector `depth_scale V_ts.xy / max(-V_ts.z,
    /// min_cos)` (tangent +x, bitangent +z, normal +y), in f64.
    pub fn plane_ray(
        &self,
        x: u32,
        y: u32,
        rect: &PlaneRect,
        depth_scale: f64,
        min_cos: f64,
    ) -> Option<Ray> {
        let (p, d) = self.plane_entry(x, y, rect)?;
        let (w, uvr) = (rect.world, rect.uv);
        let ku = (uvr.z - uvr.x) / (w.z - w.x);
        let kv = (uvr.w - uvr.y) / (w.w - w.y);
        let mut uv = [uvr.x + (p.x - w.x) * ku, uvr.y + (p.z - w.y) * kv];
        if rect.repeat {
            uv = uv.map(|u| {
                let f = u.rem_euclid(1.0);
                if f >= 1.0 { 0.0 } else { f }
            });
        }
        let v = d.normalize();
        let denom = (-v.y).max(min_cos);
        Some(Ray {
            uv0: uv,
            parallax: [depth_scale * v.x / denom, depth_scale * v.z / denom],
        })
    }

    /// Every pixel's [`PixelRays::plane_ray`], row by row (`None`: the centre ray misses
    /// the surface).
    pub fn plane_rays(&self, rect: &PlaneRect, depth_scale: f64, min_cos: f64) -> Vec<Option<Ray>> {
        (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| self.plane_ray(x, y, rect, depth_scale, min_cos))
            .collect()
    }

    /// The G-buffer's form of these rays: every value as an f32 pair `hi + lo`.
    pub fn params(&self) -> PixelRayParams {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let ty = self.tan_half_fov_y;
        let step_x = self.right * (ty * w / h * 2.0 / w);
        let step_y = -self.up * (ty * 2.0 / h);
        let (mut eye_hi, mut eye_lo) = split3(self.eye);
        eye_hi[3] = (w / 2.0) as f32;
        eye_lo[3] = (h / 2.0) as f32;
        let (dir_hi, dir_lo) = split3(self.forward);
        let (step_x_hi, step_x_lo) = split3(step_x);
        let (step_y_hi, step_y_lo) = split3(step_y);
        PixelRayParams {
            eye_hi,
            eye_lo,
            dir_hi,
            dir_lo,
            step_x_hi,
            step_x_lo,
            step_y_hi,
            step_y_lo,
        }
    }
}
