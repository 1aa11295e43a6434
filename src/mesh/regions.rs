//! The walk buffer's flat regions: what the walked material's first trace reads to tell,
//! per pixel and in a few texel fetches, that the flat trace it just ran is the walk's
//! own result (`walk_first_keep` in `glsl/common/walk.glsl`).
//!
//! A region is a maximal set of flat triangles joined across edges that continue them flat
//! ([`super::walk`]'s `FLAT_EDGE`: one plane, one local uv scale, one affine uv map, such
//! as the two halves of a cube's face), kept only where it is convex and its vertex
//! normals are its plane's. Inside its prism a pixel's ray is straight in uv and depth, so
//! where the ray's path from its entry down to the flat trace's hit stays in the region's
//! prism (both ends inside its edges: it is convex) and away from the slabs of every
//! overlapping triangle's plane (`walk_planes_near`'s test, on the planes of all its
//! triangles), the walk would follow that same path and meet that same hit. Every other
//! pixel goes on to the triage.
//!
//! Texels (four words each), found from the header's words 13 (the table's first texel, 0
//! with no region) and 14 (the table's entries):
//! * the table, one texel per surface id `0..entries`: the first texel of the surface's
//!   regions and how many there are (0 where it has none or more than [`MAX_PER_SURFACE`]);
//! * a region: `(n, o)` its unit normal and offset `n . p`, `(s, E, P, 0)` its local uv
//!   scale (bits) and counts, `E` edge texels `(m, c)` (inside: `m . X >= c`, `m` in the
//!   plane, so the test holds for the whole column under a point), then `P` plane pairs
//!   `(n, o)`, `(scale, above, below, 0)`: the plane list's, with the slab's reach above
//!   the plane and below it in depths (a 1024th past the exact `[-1, 0]` where every
//!   overlapping triangle on the plane is flat, its shell a straight prism; else the
//!   walk's eighth of a depth to each side).

use super::walk::{FLAT, FLAT_EDGE, NONE, PLANE_WORDS, TRIANGLE_WORDS};
use glam::{DVec2, DVec3};

/// A surface's regions the first trace tests at most (one loop over them per pixel);
/// a surface with more has none in the table (its pixels all go to the triage).
pub const MAX_PER_SURFACE: usize = 16;
/// A region's edges at most (its convex outline's).
pub const MAX_EDGES: usize = 16;
/// A region's overlapping planes at most.
pub const MAX_PLANES: usize = 16;
/// The largest surface id (the G-buffer keeps ids 1 to 2048).
const MAX_SURFACE: u32 = 2048;

/// The table and the regions' texels for the walk buffer's `triangles` (its words) with
/// their overlap lists `overlaps` and plane lists `planes`; `first` is the texel the table
/// will start at, `extent` the meshes' size: the table's entries (0 when no region is
/// kept) and every texel.
pub(super) fn region_texels(
    triangles: &[[u32; TRIANGLE_WORDS]],
    overlaps: &[Vec<u32>],
    planes: &[Vec<[f32; PLANE_WORDS]>],
    extent: f32,
    first: usize,
) -> (usize, Vec<[u32; 4]>) {
    let n = triangles.len();
    let f = |t: usize, i: usize| f64::from(f32::from_bits(triangles[t][i]));
    let corner = |t: usize, c: usize| DVec3::new(f(t, c * 9), f(t, c * 9 + 1), f(t, c * 9 + 2));
    // Union-find over the flat triangles, joined across their flat-continuing edges.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut t: usize) -> usize {
        while parent[t] != t {
            parent[t] = parent[parent[t]];
            t = parent[t];
        }
        t
    }
    for (t, words) in triangles.iter().enumerate() {
        let flags = words[33];
        for e in 0..3 {
            let other = words[27 + e];
            if flags & (FLAT_EDGE << e) != 0 && other != NONE {
                let (a, b) = (root(&mut parent, t), root(&mut parent, other as usize));
                parent[a] = b;
            }
        }
    }
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n];
    for t in (0..n).filter(|&t| triangles[t][33] & FLAT != 0) {
        let r = root(&mut parent, t);
        members[r].push(t);
    }
    // Per surface id, its regions' texels.
    let mut by_surface: Vec<Vec<Vec<[u32; 4]>>> = Vec::new();
    for list in members.iter().filter(|l| !l.is_empty()) {
        let flat = |p: &[f32; PLANE_WORDS]| {
            let n = DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
            list.iter()
                .flat_map(|&t| &overlaps[t])
                .map(|&o| o as usize)
                .filter(|&o| {
                    let (p0, p1, p2) = (corner(o, 0), corner(o, 1), corner(o, 2));
                    (p1 - p0).cross(p2 - p0).normalize_or_zero().dot(n).abs() > 1.0 - 1e-9
                        && (n.dot(p0) - f64::from(p[3])).abs() <= 1e-5 * f64::from(extent)
                })
                .all(|o| triangles[o][33] & FLAT != 0)
        };
        let Some(region) = region(list, &corner, &f, planes, &flat, extent) else {
            continue;
        };
        let mut surfaces: Vec<u32> = list.iter().map(|&t| triangles[t][30]).collect();
        surfaces.sort_unstable();
        surfaces.dedup();
        for s in surfaces
            .into_iter()
            .filter(|s| (1..=MAX_SURFACE).contains(s))
        {
            let s = s as usize;
            if by_surface.len() <= s {
                by_surface.resize(s + 1, Vec::new());
            }
            by_surface[s].push(region.clone());
        }
    }
    if by_surface.is_empty() {
        return (0, Vec::new());
    }
    let mut table = vec![[0u32; 4]; by_surface.len()];
    let mut data: Vec<[u32; 4]> = Vec::new();
    for (s, regions) in by_surface.iter().enumerate() {
        if regions.is_empty() || regions.len() > MAX_PER_SURFACE {
            continue;
        }
        table[s] = [
            (first + by_surface.len() + data.len()) as u32,
            regions.len() as u32,
            0,
            0,
        ];
        data.extend(regions.iter().flatten());
    }
    let entries = table.len();
    table.extend(data);
    (entries, table)
}

/// One region's texels (the module docs), or `None` where it cannot be tested cheaply:
/// not convex, its vertex normals off its plane's, or too many edges or planes.
fn region(
    list: &[usize],
    corner: &impl Fn(usize, usize) -> DVec3,
    f: &impl Fn(usize, usize) -> f64,
    planes: &[Vec<[f32; PLANE_WORDS]>],
    flat: &impl Fn(&[f32; PLANE_WORDS]) -> bool,
    extent: f32,
) -> Option<Vec<[u32; 4]>> {
    let t0 = list[0];
    let normal = DVec3::new(f(t0, 4), f(t0, 5), f(t0, 6)).normalize_or_zero();
    let (p0, p1, p2) = (corner(t0, 0), corner(t0, 1), corner(t0, 2));
    let mut n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
    if n.dot(normal) < 0.0 {
        n = -n;
    }
    if n == DVec3::ZERO || (n - normal).length() > 1e-4 {
        return None;
    }
    let offset = n.dot(p0);
    let tolerance = 1e-6 * f64::from(extent);
    // The plane's axes, and every corner in them.
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    let mut points: Vec<DVec2> = Vec::with_capacity(list.len() * 3);
    let mut area = 0.0;
    for &t in list {
        let c = [0, 1, 2].map(|k| corner(t, k));
        if c.iter().any(|p| (n.dot(*p) - offset).abs() > tolerance) {
            return None;
        }
        area += 0.5 * (c[1] - c[0]).cross(c[2] - c[0]).length();
        points.extend(c.iter().map(|p| DVec2::new(u.dot(*p), v.dot(*p))));
    }
    let hull = convex_hull(points);
    let hull_area = 0.5
        * (0..hull.len())
            .map(|i| hull[i].perp_dot(hull[(i + 1) % hull.len()]))
            .sum::<f64>();
    // Convex: the triangles fill their hull (no notch, no overlap).
    if hull.len() < 3 || hull.len() > MAX_EDGES || (hull_area - area).abs() > 1e-6 * hull_area {
        return None;
    }
    let mut distinct: Vec<[f32; PLANE_WORDS]> = Vec::new();
    for p in list.iter().flat_map(|&t| &planes[t]) {
        if !distinct.contains(p) {
            distinct.push(*p);
        }
    }
    if distinct.len() > MAX_PLANES {
        return None;
    }
    let bits = |x: f64| (x as f32).to_bits();
    let mut texels = vec![
        [bits(n.x), bits(n.y), bits(n.z), bits(offset)],
        [bits(f(t0, 3)), hull.len() as u32, distinct.len() as u32, 0],
    ];
    // The hull runs counter-clockwise about n (u x v = n): inside is to each edge's left.
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        let d = (b - a).normalize();
        let m2 = DVec2::new(-d.y, d.x);
        let m = u * m2.x + v * m2.y;
        texels.push([bits(m.x), bits(m.y), bits(m.z), bits(m2.dot(a))]);
    }
    for p in &distinct {
        let (above, below) = if flat(p) {
            (1.0 / 1024.0, 1.0 + 1.0 / 1024.0)
        } else {
            (0.125, 1.125)
        };
        texels.push([p[0], p[1], p[2], p[3]].map(f32::to_bits));
        texels.push([p[4], above, below, 0.0].map(f32::to_bits));
    }
    Some(texels)
}

/// The convex hull of `points`, counter-clockwise, without collinear points (Andrew's
/// monotone chain).
fn convex_hull(mut points: Vec<DVec2>) -> Vec<DVec2> {
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let mut hull: Vec<DVec2> = Vec::with_capacity(points.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let ordered: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in ordered {
            while hull.len() >= start + 2 {
                let (a, b) = (hull[hull.len() - 2], hull[hull.len() - 1]);
                if (b - a).perp_dot(p - a) > 0.0 {
                    break;
                }
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[cfg(test)]
mod tests {
    use super::super::Mesh;
    use super::super::walk::walk_words;
    use super::*;

    /// The texels of surface `s`'s regions in `words`.
    fn regions_of(words: &[u32], s: usize) -> Vec<Vec<[u32; 4]>> {
        let texel = |i: usize| [0, 1, 2, 3].map(|k| words[i * 4 + k]);
        let table = words[13] as usize;
        assert!(table > 0 && s < words[14] as usize);
        let [mut at, count, ..] = texel(table + s);
        (0..count)
            .map(|_| {
                let head = texel(at as usize + 1);
                let len = 2 + head[1] + 2 * head[2];
                let r = (at..at + len).map(|i| texel(i as usize)).collect();
                at += len;
                r
            })
            .collect()
    }

    #[test]
    fn a_cube_face_is_one_square_region_beside_four_planes() {
        let words = walk_words(&[&Mesh::cube()]);
        for face in 1..=6 {
            let regions = regions_of(&words, face);
            assert_eq!(regions.len(), 1, "face {face}");
            let r = &regions[0];
            // Its outline is the face's square, and the 4 faces around it overlap it, each
            // flat: their slabs reach a 1024th of a depth past their prisms.
            assert_eq!((r[1][1], r[1][2]), (4, 4), "face {face}");
            for plane in 0..4 {
                let reach = &r[6 + 2 * plane + 1][1..3];
                assert_eq!(
                    reach,
                    [1.0f32 / 1024.0, 1.0 + 1.0 / 1024.0].map(f32::to_bits)
                );
            }
            let n = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(r[0][k]))));
            // Every edge's inward normal lies in the face's plane.
            for e in &r[2..6] {
                let m = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(e[k]))));
                assert!(m.dot(n).abs() < 1e-6 && (m.length() - 1.0).abs() < 1e-6);
            }
            // The face's centre is inside every edge.
            let o = f64::from(f32::from_bits(r[0][3]));
            let centre = n * o;
            for e in &r[2..6] {
                let m = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(e[k]))));
                assert!(
                    m.dot(centre) > f64::from(f32::from_bits(e[3])),
                    "face {face}"
                );
            }
        }
    }

    #[test]
    fn curved_meshes_have_no_region() {
        for mesh in [Mesh::sphere(), Mesh::torus()] {
            assert_eq!(walk_words(&[&mesh])[13], 0, "{}", mesh.label);
        }
    }

    /// A flat mesh in the plane y = 0 of the unit squares at `cells` (two triangles each,
    /// shared corners, uv = (x, z)).
    fn squares(cells: &[(f32, f32)]) -> Mesh {
        let mut vertices: Vec<super::super::Vertex> = Vec::new();
        let mut indices = Vec::new();
        let mut at = |x: f32, z: f32| {
            let i = vertices
                .iter()
                .position(|v| v.position == [x, 0.0, z])
                .unwrap_or_else(|| {
                    vertices.push(super::super::Vertex {
                        position: [x, 0.0, z],
                        normal: [0.0, 1.0, 0.0],
                        tangent: [1.0, 0.0, 0.0, 1.0],
                        uv: [x, z],
                        stretch: 1.0,
                        surface: 1.0,
                        scale: 1.0,
                    });
                    vertices.len() - 1
                });
            i as u32
        };
        for &(x, z) in cells {
            let q = [
                at(x, z),
                at(x + 1.0, z),
                at(x + 1.0, z + 1.0),
                at(x, z + 1.0),
            ];
            indices.extend([q[0], q[2], q[1], q[0], q[3], q[2]]);
        }
        Mesh {
            vertices,
            indices,
            label: "squares".into(),
            two_sided: false,
        }
    }

    #[test]
    fn a_flat_rectangle_is_one_region_and_a_notched_outline_none() {
        let strip = walk_words(&[&squares(&[(0.0, 0.0), (1.0, 0.0)])]);
        let regions = regions_of(&strip, 1);
        assert_eq!(regions.len(), 1);
        // A rectangle's 4 edges (the collinear middle corners dropped); an open mesh
        // overlaps nothing.
        assert_eq!((regions[0][1][1], regions[0][1][2]), (4, 0));
        // An L of three squares: flat and continuous, but not convex.
        let l = walk_words(&[&squares(&[(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])]);
        assert_eq!(l[13], 0, "no region");
    }
}
