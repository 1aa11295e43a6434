//! An independent reference for the outlines of displaced meshes: the displaced surface of
//! a mesh tessellated at the height map's texel resolution and ray-traced in `f64`, by code
//! that shares nothing with the traces (neither the GPU passes nor [`crate::reference`],
//! which solves the tangent-space ray of each pixel).
//!
//! # The model
//!
//! Vertex `i` of the mesh has its position `p_i`, unit normal `n_i`, uv `uv_i` and local uv
//! scale `s_i = sqrt(|dP/du| |dP/dv|)` (the world length of one uv unit, the area-weighted
//! mean over the triangles at its position; the unit of `depth_scale` on meshes, see
//! `dispmap::mesh`). At barycentric `b` of a triangle the base point is `p = Σ b_i p_i`, the
//! normal `n = normalize(Σ b_i n_i)` (the interpolated normal, as the G-buffer's), the uv
//! `uv = Σ b_i uv_i`, the world depth `d = depth_scale Σ b_i s_i`, and the displaced point
//!
//! ```text
//! q = p - (1 - H(uv)) d n
//! ```
//!
//! with `H` the map's bilinear height in `[0, 1]` (texel centres at `uv = (i + 0.5) / W`,
//! wrapped for repeat addressing, clamped to the edge texels for clamp). So the displaced
//! surface lies between the base mesh (`H = 1`) and its inward offset along the interpolated
//! normal (`H = 0`); where the normals of a vertex differ between triangles (a cube's
//! edges) the offsets part and a ray can pass between them: a miss, which is what a carved
//! edge shows.
//!
//! The displaced surface is oriented: its outside is the side the base normal points to,
//! and a ray from the eye meets a surface from outside, so only hits on the side a piece
//! faces count. Where the offsets of two faces cross (inside the shell along a cube's
//! edge) a ray that leaves one face's shell can meet the other face's offset from behind,
//! inside the solid that face bounds: not a visible surface, so the ray goes on. A
//! two-sided mesh (`Mesh::two_sided`) is displaced from both sides, as the passes draw
//! it: its back side is the mirrored surface `q = p + (1 - H(uv)) d n`, facing `-n`,
//! carved into the wall from the side the eye sees it from, so it counts only for a ray
//! whose last crossing of the base mesh before it passed from the back side (a ray that
//! skims past the base outline never meets the back side's relief standing outside it).
//!
//! # Tessellation and tracing
//!
//! Each triangle is cut into `k²` sub-triangles, `k` its longest edge in texels (at least
//! one vertex per texel along every edge, at most [`MAX_SPLIT`]), only when a ray first
//! reaches its bound (a box around its base and offset corners widened by the depth), and
//! kept. A ray tests the triangles whose bound it enters in order of entry, each
//! triangle's sub-triangles in blocks with boxes of their own, and stops once the nearest
//! hit lies before the next bound's entry. Ray-triangle tests are Möller-Trumbore in `f64`,
//! a hit counted where the sub-triangle faces the ray (its winding oriented by its base
//! triangle's normals).

use dispmap::glam::{DMat4, DVec2, DVec3};
use dispmap::heightfield::{Addressing, HeightField};
use dispmap::mesh::Mesh;
use rayon::prelude::*;
use std::sync::OnceLock;

/// The most sub-triangles along a triangle's edge.
pub const MAX_SPLIT: usize = 1024;

/// Sub-triangle rows and columns per block of a tessellated triangle.
const BLOCK: usize = 8;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    lo: DVec3,
    hi: DVec3,
}

impl Aabb {
    fn empty() -> Self {
        Aabb {
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
        }
    }

    fn grow(&mut self, p: DVec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }

    /// The ray's entry parameter into the box (clamped at 0), if it meets it before `t_max`.
    fn entry(&self, origin: DVec3, inv_dir: DVec3, t_max: f64) -> Option<f64> {
        let a = (self.lo - origin) * inv_dir;
        let b = (self.hi - origin) * inv_dir;
        let near = a.min(b);
        let far = a.max(b);
        // NaN (0 * inf on a face) counts as "no constraint" through max/min's NaN rules.
        let t0 = near.x.max(near.y).max(near.z).max(0.0);
        let t1 = far.x.min(far.y).min(far.z).min(t_max);
        (t0 <= t1).then_some(t0)
    }
}

/// One macro triangle's data in `f64`.
struct Corner {
    p: DVec3,
    n: DVec3,
    uv: DVec2,
    depth: f64,
}

/// A tessellated triangle: its displaced vertices on a triangular grid and its blocks.
struct Tessellation {
    k: usize,
    vertices: Vec<DVec3>,
    /// `(box, first row, first column)` of each block of sub-triangles.
    blocks: Vec<(Aabb, usize, usize)>,
}

impl Tessellation {
    /// Index of grid vertex `(i, j)` (`i + j <= k`): row `j`, column `i`.
    fn at(&self, i: usize, j: usize) -> usize {
        // Rows hold k + 1, k, ..., 1 vertices.
        j * (self.k + 1) - j * j.saturating_sub(1) / 2 + i
    }
}

/// The displaced surface of one mesh (see the module docs).
pub struct DisplacedMesh<'a> {
    triangles: Vec<[Corner; 3]>,
    /// Each triangle's orientation: +1 where its winding's normal points along its
    /// corners' normals (its sub-triangles' outside), -1 where against.
    facing: Vec<f64>,
    /// The mesh's own triangles (the first `sides` of `triangles`); the rest, for a
    /// two-sided mesh, are their back sides.
    sides: usize,
    bounds: Vec<Aabb>,
    splits: Vec<usize>,
    cache: Vec<OnceLock<Tessellation>>,
    field: &'a HeightField,
    addressing: Addressing,
}

/// The bilinear height at `uv` (texel centres at `(i + 0.5) / W`).
fn height(field: &HeightField, addressing: Addressing, uv: DVec2) -> f64 {
    let (w, h) = (field.width() as i64, field.height() as i64);
    let x = uv.x * w as f64 - 0.5;
    let y = uv.y * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let texel = |i: i64, j: i64| -> f64 {
        let (i, j) = match addressing {
            Addressing::Repeat => (i.rem_euclid(w), j.rem_euclid(h)),
            Addressing::Clamp => (i.clamp(0, w - 1), j.clamp(0, h - 1)),
        };
        f64::from(field.texel(i as u32, j as u32))
    };
    let (i, j) = (x0 as i64, y0 as i64);
    let top = texel(i, j) * (1.0 - fx) + texel(i + 1, j) * fx;
    let bottom = texel(i, j + 1) * (1.0 - fx) + texel(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Möller-Trumbore (either face; the caller picks the side): the ray parameter of the hit
/// in `(0, t_max)`.
fn hit_triangle(
    origin: DVec3,
    dir: DVec3,
    a: DVec3,
    b: DVec3,
    c: DVec3,
    t_max: f64,
) -> Option<f64> {
    let e1 = b - a;
    let e2 = c - a;
    let pv = dir.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let tv = origin - a;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qv = tv.cross(e1);
    let v = dir.dot(qv) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qv) * inv;
    (t > 0.0 && t < t_max).then_some(t)
}

/// The local uv scale `s_i` of each vertex: the area-weighted mean of
/// `sqrt(|dP/du| |dP/dv|)` over the triangles at its position (vertices that differ only
/// in uv or normal, at seams and edges, share it).
fn uv_scales(mesh: &Mesh, positions: &[DVec3]) -> Vec<f64> {
    use std::collections::HashMap;
    let key = |p: &[f32; 3]| p.map(f32::to_bits);
    let mut sums: HashMap<[u32; 3], (f64, f64)> = HashMap::new();
    for tri in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(|i| i as usize);
        let (e1, e2) = (positions[b] - positions[a], positions[c] - positions[a]);
        let uv = |i: usize| DVec2::from(mesh.vertices[i].uv.map(f64::from));
        let (d1, d2) = (uv(b) - uv(a), uv(c) - uv(a));
        let det = d1.x * d2.y - d2.x * d1.y;
        let area = e1.cross(e2).length() / 2.0;
        if det == 0.0 || area == 0.0 {
            continue;
        }
        let dpdu = (e1 * d2.y - e2 * d1.y) / det;
        let dpdv = (e2 * d1.x - e1 * d2.x) / det;
        let s = (dpdu.length() * dpdv.length()).sqrt();
        if !s.is_finite() {
            continue;
        }
        for i in [a, b, c] {
            let e = sums.entry(key(&mesh.vertices[i].position)).or_default();
            e.0 += s * area;
            e.1 += area;
        }
    }
    mesh.vertices
        .iter()
        .map(|v| match sums.get(&key(&v.position)) {
            Some(&(sum, weight)) if weight > 0.0 => sum / weight,
            _ => 0.0,
        })
        .collect()
}

impl<'a> DisplacedMesh<'a> {
    /// The displaced surface of `mesh` (its vertices mapped by `transform`, normals by its
    /// inverse transpose) with `field` at `depth_scale` (in local uv units, as the passes).
    pub fn new(
        mesh: &Mesh,
        transform: DMat4,
        field: &'a HeightField,
        addressing: Addressing,
        depth_scale: f64,
    ) -> Self {
        let normal_matrix = transform.inverse().transpose();
        let positions: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| transform.transform_point3(DVec3::from(v.position.map(f64::from))))
            .collect();
        let scales = uv_scales(mesh, &positions);
        let (w, h) = (f64::from(field.width()), f64::from(field.height()));
        let mut triangles = Vec::with_capacity(mesh.indices.len() / 3);
        let mut bounds = Vec::with_capacity(mesh.indices.len() / 3);
        let mut splits = Vec::with_capacity(mesh.indices.len() / 3);
        let mut facing = Vec::with_capacity(mesh.indices.len() / 3);
        // A two-sided mesh's back side: the same triangles with their normals reversed.
        let sides: &[f64] = if mesh.two_sided { &[1.0, -1.0] } else { &[1.0] };
        for (tri, side) in sides
            .iter()
            .flat_map(|&side| mesh.indices.chunks_exact(3).map(move |tri| (tri, side)))
        {
            let corner = |i: u32| {
                let v = &mesh.vertices[i as usize];
                let n = side
                    * normal_matrix
                        .transform_vector3(DVec3::from(v.normal.map(f64::from)))
                        .normalize_or_zero();
                Corner {
                    p: positions[i as usize],
                    n,
                    uv: DVec2::from(v.uv.map(f64::from)),
                    depth: depth_scale * scales[i as usize],
                }
            };
            let corners = [corner(tri[0]), corner(tri[1]), corner(tri[2])];
            let mut bound = Aabb::empty();
            let depth = corners.iter().map(|c| c.depth).fold(0.0, f64::max);
            for c in &corners {
                bound.grow(c.p);
                bound.grow(c.p - c.n * c.depth);
            }
            // The normalised interpolated normal and the interpolated depth bulge past the
            // corners' hull by less than the depth: widen by it.
            bound.lo -= DVec3::splat(depth);
            bound.hi += DVec3::splat(depth);
            let texels = |a: DVec2, b: DVec2| ((a - b) * DVec2::new(w, h)).abs().max_element();
            let longest = texels(corners[0].uv, corners[1].uv)
                .max(texels(corners[1].uv, corners[2].uv))
                .max(texels(corners[2].uv, corners[0].uv));
            splits.push((longest.ceil() as usize).clamp(1, MAX_SPLIT));
            let winding = (corners[1].p - corners[0].p).cross(corners[2].p - corners[0].p);
            let normals = corners[0].n + corners[1].n + corners[2].n;
            facing.push(if winding.dot(normals) < 0.0 {
                -1.0
            } else {
                1.0
            });
            triangles.push(corners);
            bounds.push(bound);
        }
        let cache = (0..triangles.len()).map(|_| OnceLock::new()).collect();
        DisplacedMesh {
            triangles,
            facing,
            sides: mesh.indices.len() / 3,
            bounds,
            splits,
            cache,
            field,
            addressing,
        }
    }

    /// The displaced point at barycentric `(b1, b2)` of triangle `tri`.
    fn displaced(&self, tri: &[Corner; 3], b1: f64, b2: f64) -> DVec3 {
        let b0 = 1.0 - b1 - b2;
        let p = tri[0].p * b0 + tri[1].p * b1 + tri[2].p * b2;
        let n = (tri[0].n * b0 + tri[1].n * b1 + tri[2].n * b2).normalize_or_zero();
        let uv = tri[0].uv * b0 + tri[1].uv * b1 + tri[2].uv * b2;
        let d = tri[0].depth * b0 + tri[1].depth * b1 + tri[2].depth * b2;
        p - n * d * (1.0 - height(self.field, self.addressing, uv))
    }

    fn tessellation(&self, t: usize) -> &Tessellation {
        self.cache[t].get_or_init(|| {
            let k = self.splits[t];
            let tri = &self.triangles[t];
            let mut vertices = Vec::with_capacity((k + 1) * (k + 2) / 2);
            for j in 0..=k {
                for i in 0..=k - j {
                    vertices.push(self.displaced(tri, i as f64 / k as f64, j as f64 / k as f64));
                }
            }
            let mut tess = Tessellation {
                k,
                vertices,
                blocks: Vec::new(),
            };
            for j0 in (0..k).step_by(BLOCK) {
                for i0 in (0..k - j0).step_by(BLOCK) {
                    let mut bound = Aabb::empty();
                    for j in j0..(j0 + BLOCK + 1).min(k + 1) {
                        for i in i0..(i0 + BLOCK + 1).min(k + 1 - j) {
                            bound.grow(tess.vertices[tess.at(i, j)]);
                        }
                    }
                    tess.blocks.push((bound, j0, i0));
                }
            }
            tess
        })
    }

    /// The ray parameter of the first hit of `origin + t dir` (`t > 0`), if any.
    pub fn first_hit(&self, origin: DVec3, dir: DVec3) -> Option<f64> {
        let inv = dir.recip();
        let mut candidates: Vec<(f64, usize)> = self
            .bounds
            .iter()
            .enumerate()
            .filter_map(|(t, b)| b.entry(origin, inv, f64::INFINITY).map(|e| (e, t)))
            .collect();
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        // A two-sided mesh's base crossings along the ray, each with whether it passes
        // from the side the normals point to (the back sides' rule).
        let mut crossings: Vec<(f64, bool)> = if self.triangles.len() > self.sides {
            candidates
                .iter()
                .filter(|&&(_, t)| t < self.sides)
                .filter_map(|&(_, t)| {
                    let [a, b, c] = &self.triangles[t];
                    let inward = (b.p - a.p).cross(c.p - a.p).dot(dir) * self.facing[t] < 0.0;
                    hit_triangle(origin, dir, a.p, b.p, c.p, f64::INFINITY).map(|h| (h, inward))
                })
                .collect()
        } else {
            Vec::new()
        };
        // A ray through an edge or a vertex crosses once, whatever the triangles there
        // report.
        crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
        crossings.dedup_by(|b, a| (b.0 - a.0).abs() <= 1e-9 * a.0.abs().max(1.0));
        // Whether the last crossing before `h` passed from the back side (into the side
        // the normals point to): where the back side's relief is seen.
        let behind_base = |h: f64| {
            crossings
                .iter()
                .rev()
                .find(|c| c.0 < h)
                .is_some_and(|c| !c.1)
        };
        let mut best = f64::INFINITY;
        for (entry, t) in candidates {
            if entry >= best {
                break;
            }
            let tess = self.tessellation(t);
            let facing = self.facing[t];
            // A hit from outside: the ray against the sub-triangle's oriented normal.
            let outside =
                |a: DVec3, b: DVec3, c: DVec3| (b - a).cross(c - a).dot(dir) * facing < 0.0;
            let back_side = t >= self.sides;
            let counts = |h: f64| !back_side || behind_base(h);
            for &(bound, j0, i0) in &tess.blocks {
                if bound.entry(origin, inv, best).is_none() {
                    continue;
                }
                for j in j0..(j0 + BLOCK).min(tess.k) {
                    for i in i0..(i0 + BLOCK).min(tess.k - j) {
                        // The upward sub-triangle (i, j), (i + 1, j), (i, j + 1) and, where
                        // it exists, the downward one beside it.
                        let a = tess.vertices[tess.at(i, j)];
                        let b = tess.vertices[tess.at(i + 1, j)];
                        let c = tess.vertices[tess.at(i, j + 1)];
                        if outside(a, b, c)
                            && let Some(h) = hit_triangle(origin, dir, a, b, c, best)
                            && counts(h)
                        {
                            best = h;
                        }
                        if i + j + 1 < tess.k {
                            let d = tess.vertices[tess.at(i + 1, j + 1)];
                            if outside(b, d, c)
                                && let Some(h) = hit_triangle(origin, dir, b, d, c, best)
                                && counts(h)
                            {
                                best = h;
                            }
                        }
                    }
                }
            }
        }
        best.is_finite().then_some(best)
    }

    /// [`DisplacedMesh::first_hit`] of many rays in parallel.
    pub fn first_hits(&self, rays: &[(DVec3, DVec3)]) -> Vec<Option<f64>> {
        rays.par_iter()
            .map(|&(o, d)| self.first_hit(o, d))
            .collect()
    }
}

/// How a frame's hit-or-miss agrees with the reference's near the outlines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutlineAgreement {
    /// Pixels within [`OUTLINE_BAND`] pixels of an outline of either image.
    pub band: usize,
    /// Of those, the pixels whose hit-or-miss equals the reference's.
    pub agreeing: usize,
}

/// The band around the outlines, in pixels (Chebyshev distance).
pub const OUTLINE_BAND: usize = 2;

impl OutlineAgreement {
    /// The agreeing share of the band (1 for an empty band).
    pub fn share(&self) -> f64 {
        if self.band == 0 {
            1.0
        } else {
            self.agreeing as f64 / self.band as f64
        }
    }
}

/// Compares two hit masks of a `width x height` frame within [`OUTLINE_BAND`] pixels of any
/// outline (a pixel whose value differs from a 4-neighbour's in either mask).
pub fn outline_agreement(
    reference: &[bool],
    frame: &[bool],
    width: usize,
    height: usize,
) -> OutlineAgreement {
    assert_eq!(reference.len(), width * height);
    assert_eq!(frame.len(), width * height);
    let edge = |m: &[bool], x: usize, y: usize| {
        let v = m[y * width + x];
        (x > 0 && m[y * width + x - 1] != v)
            || (x + 1 < width && m[y * width + x + 1] != v)
            || (y > 0 && m[(y - 1) * width + x] != v)
            || (y + 1 < height && m[(y + 1) * width + x] != v)
    };
    let mut outline = vec![false; width * height];
    for y in 0..height {
        for x in 0..width {
            outline[y * width + x] = edge(reference, x, y) || edge(frame, x, y);
        }
    }
    let (mut band, mut agreeing) = (0, 0);
    let r = OUTLINE_BAND;
    for y in 0..height {
        for x in 0..width {
            let near = (y.saturating_sub(r)..(y + r + 1).min(height)).any(|yy| {
                (x.saturating_sub(r)..(x + r + 1).min(width)).any(|xx| outline[yy * width + xx])
            });
            if near {
                band += 1;
                if reference[y * width + x] == frame[y * width + x] {
                    agreeing += 1;
                }
            }
        }
    }
    OutlineAgreement { band, agreeing }
}

#[cfg(test)]
mod tests;
