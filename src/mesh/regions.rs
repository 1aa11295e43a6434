//! The walk buffer's flat regions: what the walked material's first trace reads to tell,
//! per pixel and in a few texel fetches, that the flat trace it just ran is the walk's
//! own result (`walk_first` in `glsl/common/walk.glsl`), and what the overlap step
//! intersects where that trace's path passes the shells of other regions
//! (`walk_region_overlaps`).
//!
//! A region is a maximal set of flat triangles joined across edges that continue them flat
//! ([`super::walk`]'s `FLAT_EDGE`: one plane, one local uv scale, one affine uv map, such
//! as the two halves of a cube's face), kept only where it is convex and its vertex
//! normals are its plane's. Inside its prism a pixel's ray is straight in uv and depth, so
//! where the ray's path from its entry down to the flat trace's hit stays in the region's
//! prism (both ends inside its edges: it is convex) and away from the slabs of every
//! overlapping triangle's plane (`walk_planes_near`'s test, on the planes of all its
//! triangles), the walk would follow that same path and meet that same hit. Where the path
//! stays in the prism but passes such a slab, and every triangle overlapping the region is
//! in a listed region, the overlap step intersects the path with those regions' relief
//! (each region's shell a straight prism, its uv map affine: one clip and one traversal a
//! region, no solve). Every other pixel goes on to the triage.
//!
//! Texels (four words each), found from the header's words 13 (the table's first texel, 0
//! with no region) and 14 (the table's entries):
//! * the table, one texel per surface id `0..entries`: the first texel of the surface's
//!   regions and how many there are (0 where it has none or more than [`MAX_PER_SURFACE`]),
//!   and [`CURVED`] where the surface has no flat triangle (its pixels go from the first
//!   trace straight to the walk, which the triage would send every one of them to);
//! * a region: `(n, o)` its unit normal and offset `n . p`, `(s, E, P, O)` its local uv
//!   scale (bits) and counts, its affine uv map `(U, u0)`, `(V, v0)` (`u = U . X + u0`,
//!   `U` and `V` in the plane, so a point reads its foot's uv), `E` edge texels `(m, c)`
//!   (inside: `m . X >= c`, `m` in the plane, so the test holds for the whole column under
//!   a point), then `P` plane pairs `(n, o)`, `(scale, above, below, 0)`: the plane
//!   list's, with the slab's reach above the plane and below it in depths (a 1024th past
//!   the exact `[-1, 0]` where every overlapping triangle on the plane is flat, its shell
//!   a straight prism; else the walk's eighth of a depth to each side), then the first
//!   texels of the `O` regions its triangles' overlapping triangles are in, four a texel;
//!   `O`'s bit [`UNLISTED`]: an overlapping triangle is in no listed region (the overlap
//!   step cannot take the region's pixels).

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
/// A region's overlapping regions at most (the overlap step's mask of them is 32 bits);
/// with more, its pixels go to the triage.
pub const MAX_OVERLAPPING: usize = 32;
/// A table entry's word 2 for a surface without a flat triangle (`WALK_SURFACE_CURVED`).
pub const CURVED: u32 = 1;
/// The bit of a region's count of overlapping regions that says an overlapping triangle
/// is in no listed region (`WALK_REGION_UNLISTED`).
pub const UNLISTED: u32 = 1 << 31;

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
    // Per region (by its root) its texels but the overlapping regions' list, and per
    // surface id its regions.
    let mut built: Vec<Option<Vec<[u32; 4]>>> = vec![None; n];
    let mut by_surface: Vec<Vec<usize>> = Vec::new();
    for (r, list) in members.iter().enumerate().filter(|(_, l)| !l.is_empty()) {
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
        built[r] = Some(region);
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
            by_surface[s].push(r);
        }
    }
    // The surfaces without a flat triangle: their pixels go from the first trace straight
    // to the walk (the triage would list them all).
    let mut curved: Vec<bool> = Vec::new();
    let mut has_flat: Vec<bool> = Vec::new();
    for words in triangles {
        let s = words[30];
        if (1..=MAX_SURFACE).contains(&s) {
            let s = s as usize;
            if curved.len() <= s {
                curved.resize(s + 1, false);
                has_flat.resize(s + 1, false);
            }
            curved[s] = true;
            has_flat[s] |= words[33] & FLAT != 0;
        }
    }
    for (c, f) in curved.iter_mut().zip(&has_flat) {
        *c &= !f;
    }
    if by_surface.is_empty() && !curved.contains(&true) {
        return (0, Vec::new());
    }
    by_surface.resize(by_surface.len().max(curved.len()), Vec::new());
    // The listed regions: those of the surfaces with at most MAX_PER_SURFACE (a region
    // of several surfaces is listed under each).
    let listed_surface =
        |regions: &Vec<usize>| !regions.is_empty() && regions.len() <= MAX_PER_SURFACE;
    let mut listed = vec![false; n];
    for r in by_surface.iter().filter(|l| listed_surface(l)).flatten() {
        listed[*r] = true;
    }
    // Each listed region's overlapping regions (by root), or None where an overlapping
    // triangle is in no listed region or there are more than MAX_OVERLAPPING.
    let overlapping: Vec<Option<Vec<usize>>> = (0..n)
        .map(|r| {
            if !listed[r] {
                return None;
            }
            let mut out: Vec<usize> = Vec::new();
            for &o in members[r].iter().flat_map(|&t| &overlaps[t]) {
                let o = o as usize;
                if triangles[o][33] & FLAT == 0 {
                    return None;
                }
                let q = root(&mut parent, o);
                if !listed[q] {
                    return None;
                }
                if q != r && !out.contains(&q) {
                    out.push(q);
                }
            }
            (out.len() <= MAX_OVERLAPPING).then_some(out)
        })
        .collect();
    let texels_of = |r: usize| {
        let base = built[r].as_ref().map_or(0, Vec::len);
        base + overlapping[r].as_ref().map_or(0, |o| o.len().div_ceil(4))
    };
    // The layout: the table, then each listed surface's regions; a region's first texel
    // (for the lists of the regions it overlaps) is that of its first copy.
    let mut table = vec![[0u32; 4]; by_surface.len()];
    let mut at = first + by_surface.len();
    let mut first_texel = vec![u32::MAX; n];
    for (s, regions) in by_surface.iter().enumerate() {
        if curved.get(s) == Some(&true) {
            table[s][2] = CURVED;
        }
        if !listed_surface(regions) {
            continue;
        }
        table[s] = [at as u32, regions.len() as u32, 0, 0];
        for &r in regions {
            if first_texel[r] == u32::MAX {
                first_texel[r] = at as u32;
            }
            at += texels_of(r);
        }
    }
    let entries = table.len();
    let mut out = table;
    for regions in by_surface.iter().filter(|l| listed_surface(l)) {
        for &r in regions {
            let mut texels = built[r].clone().unwrap_or_default();
            match &overlapping[r] {
                Some(list) => {
                    texels[1][3] = list.len() as u32;
                    let firsts: Vec<u32> = list.iter().map(|&q| first_texel[q]).collect();
                    for four in firsts.chunks(4) {
                        let mut t = [0u32; 4];
                        t[..four.len()].copy_from_slice(four);
                        texels.push(t);
                    }
                }
                None => texels[1][3] = UNLISTED,
            }
            out.extend(texels);
        }
    }
    debug_assert_eq!(out.len(), at - first);
    (entries, out)
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
    // The affine uv map of t0 (every triangle of the region carries it): U . e1 = du1,
    // U . e2 = du2, U . n = 0 (and V), solved by Cramer's rule.
    let uv = |c: usize| DVec2::new(f(t0, c * 9 + 7), f(t0, c * 9 + 8));
    let (e1, e2) = (p1 - p0, p2 - p0);
    let det = e1.dot(e2.cross(n));
    if det.abs() <= 1e-300 {
        return None;
    }
    let (du1, du2) = (uv(1) - uv(0), uv(2) - uv(0));
    let solve = |a: f64, b: f64| (e2.cross(n) * a + n.cross(e1) * b) / det;
    let (mu, mv) = (solve(du1.x, du2.x), solve(du1.y, du2.y));
    let mut texels = vec![
        [bits(n.x), bits(n.y), bits(n.z), bits(offset)],
        [bits(f(t0, 3)), hull.len() as u32, distinct.len() as u32, 0],
        [
            bits(mu.x),
            bits(mu.y),
            bits(mu.z),
            bits(uv(0).x - mu.dot(p0)),
        ],
        [
            bits(mv.x),
            bits(mv.y),
            bits(mv.z),
            bits(uv(0).y - mv.dot(p0)),
        ],
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
                // Its plane, counts and uv map; its edges, plane pairs and overlapping
                // regions.
                let listed = if head[3] & UNLISTED != 0 { 0 } else { head[3] };
                let len = 4 + head[1] + 2 * head[2] + listed.div_ceil(4);
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
                let reach = &r[8 + 2 * plane + 1][1..3];
                assert_eq!(
                    reach,
                    [1.0f32 / 1024.0, 1.0 + 1.0 / 1024.0].map(f32::to_bits)
                );
            }
            let n = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(r[0][k]))));
            // Every edge's inward normal lies in the face's plane.
            for e in &r[4..8] {
                let m = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(e[k]))));
                assert!(m.dot(n).abs() < 1e-6 && (m.length() - 1.0).abs() < 1e-6);
            }
            // The face's centre is inside every edge.
            let o = f64::from(f32::from_bits(r[0][3]));
            let centre = n * o;
            for e in &r[4..8] {
                let m = DVec3::from([0, 1, 2].map(|k| f64::from(f32::from_bits(e[k]))));
                assert!(
                    m.dot(centre) > f64::from(f32::from_bits(e[3])),
                    "face {face}"
                );
            }
            // Its four overlapping regions are the faces around it: each listed, each
            // a plane of the region's plane list.
            assert_eq!(r[1][3], 4, "face {face}");
            let firsts: Vec<usize> = r[16].iter().map(|&t| t as usize).collect();
            let texel = |i: usize| [0, 1, 2, 3].map(|k| words[i * 4 + k]);
            let plane = |t: [u32; 4]| [0, 1, 2, 3].map(|k| f64::from(f32::from_bits(t[k])));
            for p in 0..4 {
                let mine = plane(r[8 + 2 * p]);
                let matching = firsts
                    .iter()
                    .filter(|&&t| {
                        let theirs = plane(texel(t));
                        (0..4).all(|k| (theirs[k] - mine[k]).abs() < 1e-6)
                    })
                    .count();
                assert_eq!(matching, 1, "face {face}, plane {p}");
            }
        }
    }

    /// A region's uv map gives its corners' uvs (the cube's faces, each one affine map),
    /// and is constant along the normal (a point reads its foot's uv).
    #[test]
    fn a_region_reads_its_corners_uvs() {
        let cube = Mesh::cube();
        let words = walk_words(&[&cube]);
        let f = |w: u32| f64::from(f32::from_bits(w));
        let v3 = |t: [u32; 4]| DVec3::new(f(t[0]), f(t[1]), f(t[2]));
        let mut checked = 0;
        for face in 1..=6 {
            let r = &regions_of(&words, face)[0];
            let n = v3(r[0]);
            let uv =
                |p: DVec3| DVec2::new(v3(r[2]).dot(p) + f(r[2][3]), v3(r[3]).dot(p) + f(r[3][3]));
            for v in cube.vertices.iter().filter(|v| v.surface as usize == face) {
                let p = DVec3::from(v.position.map(f64::from));
                let want = DVec2::from(v.uv.map(f64::from));
                assert!((uv(p) - want).abs().max_element() < 1e-5, "face {face}");
                assert!(
                    (uv(p - 0.3 * n) - want).abs().max_element() < 1e-5,
                    "face {face}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, cube.vertices.len());
    }

    #[test]
    fn curved_meshes_have_no_region_and_their_surfaces_are_marked_curved() {
        for mesh in [Mesh::sphere(), Mesh::torus()] {
            let words = walk_words(&[&mesh]);
            let (table, entries) = (words[13] as usize, words[14] as usize);
            assert!(table > 0 && entries > 1, "{}", mesh.label);
            let surfaces: Vec<usize> = mesh.vertices.iter().map(|v| v.surface as usize).collect();
            for s in 0..entries {
                let entry = &words[(table + s) * 4..(table + s) * 4 + 4];
                assert_eq!(entry[1], 0, "{}: no region", mesh.label);
                let flag = if surfaces.contains(&s) { CURVED } else { 0 };
                assert_eq!(entry[2], flag, "{}, surface {s}", mesh.label);
            }
        }
        // A cube's faces are flat.
        let cube = walk_words(&[&Mesh::cube()]);
        let table = cube[13] as usize;
        assert!((1..=6).all(|s| cube[(table + s) * 4 + 2] == 0));
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
