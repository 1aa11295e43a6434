//! The G-buffer's `frame` texel (`R32G32_UINT`) on the CPU: the same packing as
//! `dispmap_frame_pack` / `dispmap_frame_unpack` in `glsl/include/dispmap_gbuffer.glsl`,
//! for readbacks (the CPU reference shades with the decoded frame) and for hosts and tests
//! that write a G-buffer from the CPU.
//!
//! | bits | field |
//! |---|---|
//! | `x` 0-13, 14-27 | the normal's octahedral coordinates, snorm with 14 bits (`-1`, `0`, `1` exact) |
//! | `x` 28-31, `y` 25-31 | surface id − 1 (11 bits: ids 1 to 2048) |
//! | `y` 0-12 | the tangent's angle about the normal, 8192 steps a turn, from the basis [`basis`] builds from the decoded normal |
//! | `y` 13 | handedness (set: −1) |
//! | `y` 14-24 | material + 1 (0: not displaced) |
//!
//! Axis-aligned frames (the plane, the quad, the cube) decode exactly; any other normal
//! within 2.5e-4 rad, any other tangent within 4.3e-4 rad (`tests` below).

use glam::Vec3;

/// Steps of the tangent's angle per turn.
const TANGENT_STEPS: f32 = 8192.0;

/// A decoded frame texel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Unit world normal `N`.
    pub normal: Vec3,
    /// Unit world tangent `T` (along `+u`), orthogonal to `N`.
    pub tangent: Vec3,
    /// `+1` or `-1`: `B = handedness N x T`.
    pub handedness: f32,
    /// Material index + 1; 0 = not displaced.
    pub material_plus_one: u32,
    /// Surface id, 1 to 2048.
    pub surface_id: u32,
}

impl Frame {
    /// The unit bitangent `B` (along `+v`).
    pub fn bitangent(&self) -> Vec3 {
        self.handedness * self.normal.cross(self.tangent)
    }
}

fn sign_not_zero(x: f32) -> f32 {
    if x >= 0.0 { 1.0 } else { -1.0 }
}

fn oct_encode(n: Vec3) -> [f32; 2] {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs());
    if n.z < 0.0 {
        [
            (1.0 - n.y.abs()) * sign_not_zero(n.x),
            (1.0 - n.x.abs()) * sign_not_zero(n.y),
        ]
    } else {
        [n.x, n.y]
    }
}

fn oct_decode(p: [f32; 2]) -> Vec3 {
    let mut n = Vec3::new(p[0], p[1], 1.0 - p[0].abs() - p[1].abs());
    if n.z < 0.0 {
        let (x, y) = (n.x, n.y);
        n.x = (1.0 - y.abs()) * sign_not_zero(x);
        n.y = (1.0 - x.abs()) * sign_not_zero(y);
    }
    n.normalize()
}

/// Ties round to even, as the GLSL encoder's `roundEven` (Rust's `round` would take them
/// away from zero, GLSL's `round` as the implementation chooses).
fn snorm14(x: f32) -> u32 {
    ((x.clamp(-1.0, 1.0) * 8191.0).round_ties_even() as i32 + 8191) as u32
}

fn unsnorm14(q: u32) -> f32 {
    ((q & 0x3FFF) as i32 - 8191) as f32 / 8191.0
}

/// An orthonormal basis `(b1, b2)` of the plane of the unit vector `n` (Duff et al. 2017,
/// "Building an Orthonormal Basis, Revisited"): the reference of the tangent's angle.
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let sgn = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sgn + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x),
        Vec3::new(b, sgn + n.y * n.y * a, -n.y),
    )
}

/// Packs a frame (unit `normal` and `tangent`, the sign of `handedness`, `material_plus_one`
/// in 0..=1024, `surface_id` >= 1) as `dispmap_frame_pack` does.
pub fn pack(
    normal: Vec3,
    tangent: Vec3,
    handedness: f32,
    material_plus_one: u32,
    surface_id: u32,
) -> [u32; 2] {
    let p = oct_encode(normal);
    let (ou, ov) = (snorm14(p[0]), snorm14(p[1]));
    let n = oct_decode([unsnorm14(ou), unsnorm14(ov)]);
    let (b1, b2) = basis(n);
    let angle = tangent.dot(b2).atan2(tangent.dot(b1));
    let k = ((angle * (TANGENT_STEPS / std::f32::consts::TAU)).round_ties_even() as i32 as u32)
        & 0x1FFF;
    let id = surface_id.wrapping_sub(1) & 0x7FF;
    let x = ou | (ov << 14) | ((id & 0xF) << 28);
    let y = k
        | if handedness < 0.0 { 1 << 13 } else { 0 }
        | (material_plus_one.min(0x7FF) << 14)
        | ((id >> 4) << 25);
    [x, y]
}

/// Unpacks a frame texel as `dispmap_frame_unpack` does (the GPU's `cos`, `sin` and
/// `normalize` may differ from the CPU's in the last bits where the frame is not
/// axis-aligned).
pub fn unpack(bits: [u32; 2]) -> Frame {
    let [x, y] = bits;
    let normal = oct_decode([unsnorm14(x), unsnorm14(x >> 14)]);
    let (b1, b2) = basis(normal);
    let k = y & 0x1FFF;
    let a = (k & 0x7FF) as f32 * (std::f32::consts::TAU / TANGENT_STEPS);
    let (c, s) = (a.cos(), a.sin());
    let (c, s) = match k >> 11 {
        0 => (c, s),
        1 => (-s, c),
        2 => (-c, -s),
        _ => (s, -c),
    };
    Frame {
        normal,
        tangent: c * b1 + s * b2,
        handedness: if y & (1 << 13) != 0 { -1.0 } else { 1.0 },
        material_plus_one: (y >> 14) & 0x7FF,
        surface_id: ((x >> 28) | ((y >> 25) << 4)) + 1,
    }
}

/// The material + 1 of a frame texel (0: not displaced).
pub fn material_plus_one(bits: [u32; 2]) -> u32 {
    (bits[1] >> 14) & 0x7FF
}

/// `bits` with its material + 1 replaced (0: not displaced), every other field kept.
pub fn with_material(bits: [u32; 2], material_plus_one: u32) -> [u32; 2] {
    [
        bits[0],
        (bits[1] & !(0x7FF << 14)) | (material_plus_one.min(0x7FF) << 14),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_aligned_frames_round_trip_exactly() {
        let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
        for n in axes {
            for t in axes {
                if n.dot(t) != 0.0 {
                    continue;
                }
                for (h, m, id) in [(1.0, 1, 1), (-1.0, 1024, 2048), (1.0, 0, 6)] {
                    let f = unpack(pack(n, t, h, m, id));
                    assert_eq!(f.normal, n, "{n} {t}");
                    assert_eq!(f.tangent.abs(), t.abs(), "{n} {t}");
                    assert!(f.tangent.abs_diff_eq(t, 0.0), "{n} {t}: {}", f.tangent);
                    assert_eq!(
                        (f.handedness, f.material_plus_one, f.surface_id),
                        (h, m, id)
                    );
                }
            }
        }
    }

    /// A coordinate whose scaled value is a tie (k + 0.5 exactly in f32) quantises to the
    /// even neighbour on both sides of zero, as the shader's `roundEven` does; `round`
    /// would take 0.5 to 1 and -2.5 to -3.
    #[test]
    fn ties_round_to_even() {
        let mut ties = 0;
        for k in -200i32..200 {
            let scaled = k as f32 + 0.5;
            let x = scaled / 8191.0;
            if x * 8191.0 != scaled {
                continue;
            }
            ties += 1;
            let even = if k % 2 == 0 { k } else { k + 1 };
            assert_eq!(snorm14(x) as i32 - 8191, even, "x = {x} ({scaled} / 8191)");
        }
        assert!(ties > 50, "only {ties} exact ties");
    }

    /// The angle between two vectors, in f64 (f32's `acos` near 1 resolves 3e-4 rad).
    fn angle(a: Vec3, b: Vec3) -> f32 {
        let (a, b) = (a.as_dvec3(), b.as_dvec3());
        a.cross(b).length().atan2(a.dot(b)) as f32
    }

    #[test]
    fn any_frame_decodes_within_its_quantisation() {
        // A deterministic spread of frames over the sphere and the tangent circle.
        let (mut worst_n, mut worst_t) = (0.0f32, 0.0f32);
        // What the former R16G16B16A16_SFLOAT normal and tangent kept, for comparison.
        let (mut half_n, mut half_t) = (0.0f32, 0.0f32);
        let half = |v: Vec3| v.to_array().map(|c| half::f16::from_f32(c).to_f32());
        for i in 0..4000 {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / 4000.0;
            let phi = i as f32 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            let (b1, b2) = basis(n);
            let psi = i as f32 * 0.7137;
            let t = (psi.cos() * b1 + psi.sin() * b2).normalize();
            let f = unpack(pack(n, t, -1.0, 7, 3));
            worst_n = worst_n.max(angle(f.normal, n));
            worst_t = worst_t.max(angle(f.tangent, t));
            half_n = half_n.max(angle(Vec3::from(half(n)), n));
            half_t = half_t.max(angle(Vec3::from(half(t)), t));
            assert!(f.normal.dot(f.tangent).abs() < 1e-6);
            assert_eq!(
                (f.handedness, f.material_plus_one, f.surface_id),
                (-1.0, 7, 3)
            );
        }
        eprintln!(
            "worst normal {worst_n:e} rad, tangent {worst_t:e} rad (as f16 x 3: {half_n:e}, \
             {half_t:e})"
        );
        // Measured 2.44e-4 and 4.26e-4 rad (f16 x 3: 3.59e-4 and 3.44e-4).
        assert!(worst_n < 2.5e-4, "normal {worst_n}");
        assert!(worst_t < 4.3e-4, "tangent {worst_t}");
    }
}
