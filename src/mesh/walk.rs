//! The meshes the curved `exact` trace walks (`glsl/common/walk.glsl`): their triangles
//! with each one's neighbours across its edges, and a grid that finds the triangle under a
//! pixel's entry point, packed into one storage buffer.
//!
//! Neighbours are matched by position (vertices closer than a millionth of the meshes'
//! extent are one), not by index, so a walk crosses the uv seams and hard edges where a
//! mesh repeats a vertex with another uv or normal. An edge that no other triangle of the
//! same mesh shares, or that more than two share, is a boundary: a ray whose foot crosses
//! it leaves the shell. Triangles without area (a UV sphere's pole rows) are left out.

use super::Mesh;
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::Buffer;
use crate::gpu::owned::Destroy;
use ash::vk;
use glam::Vec3;
use gpu_allocator::MemoryLocation;
use std::collections::HashMap;

/// Words of a triangle in the buffer (`WALK_TRIANGLE_WORDS` in `walk.glsl`): per corner
/// its position, local uv scale, normal and uv (9), its three neighbours, its surface id,
/// the first and count of its overlapping triangles in the overlap list, its flatness bits
/// ([`FLAT`], [`FLAT_EDGE`]), and the first and count of its overlapping triangles' planes
/// in the plane list ([`PLANE_WORDS`] each).
pub(super) const TRIANGLE_WORDS: usize = 36;
/// Words of a plane of the plane list: its unit normal (along the triangle's vertex
/// normals), its offset `n . p`, and the largest local uv scale of the triangles on it.
pub(super) const PLANE_WORDS: usize = 5;
/// A flatness bit: the triangle's three normals and local uv scales are equal, so its
/// shell is a straight prism and a ray's path in its uv and depth is straight.
pub(super) const FLAT: u32 = 1;
/// A flatness bit (shifted by the edge's index): the neighbour across the edge is flat
/// with the same normal, scale and affine uv map (the two halves of a cube's face), so a
/// path stays straight across the edge.
pub(super) const FLAT_EDGE: u32 = 2;
/// A triangle with no neighbour across an edge (`WALK_NONE`).
pub(super) const NONE: u32 = u32::MAX;
/// Words of the header (see `walk.glsl`).
const HEADER_WORDS: usize = 16;
/// Cells along the grid's longest side at most.
const MAX_CELLS: usize = 64;

/// The walk buffer's words for `meshes` (world space, as the G-buffer draws them). With
/// no triangle the buffer is the header alone, its triangle count 0: the curved trace
/// then takes its per-pixel circle model everywhere.
pub fn walk_words(meshes: &[&Mesh]) -> Vec<u32> {
    let mut triangles: Vec<[u32; TRIANGLE_WORDS]> = Vec::new();
    let mut overlaps: Vec<Vec<u32>> = Vec::new();
    let mut bounds: Vec<(Vec3, Vec3)> = Vec::new();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for mesh in meshes {
        for v in &mesh.vertices {
            lo = lo.min(Vec3::from(v.position));
            hi = hi.max(Vec3::from(v.position));
        }
    }
    let extent = (hi - lo).max_element();
    if !extent.is_finite() {
        return header(Vec3::ZERO, 1.0, [0; 3], 0, 0);
    }
    let weld = extent.max(1e-30) * 1e-6;
    for mesh in meshes {
        let first = triangles.len();
        let ids = welded(mesh, weld);
        let mut kept: Vec<[u32; 3]> = Vec::new();
        for tri in mesh.indices.chunks_exact(3) {
            let p = |k: usize| Vec3::from(mesh.vertices[tri[k] as usize].position);
            let area = (p(1) - p(0)).cross(p(2) - p(0)).length();
            let distinct = ids[tri[0] as usize] != ids[tri[1] as usize]
                && ids[tri[1] as usize] != ids[tri[2] as usize]
                && ids[tri[0] as usize] != ids[tri[2] as usize];
            if area > extent * extent * 1e-12 && distinct {
                kept.push([tri[0], tri[1], tri[2]]);
            }
        }
        // Edge (welded ids, sorted) -> the triangles (of this mesh) and their edge index.
        let mut edges: HashMap<(u32, u32), Vec<(usize, usize)>> = HashMap::new();
        for (t, tri) in kept.iter().enumerate() {
            for e in 0..3 {
                let (a, b) = (
                    ids[tri[(e + 1) % 3] as usize],
                    ids[tri[(e + 2) % 3] as usize],
                );
                edges.entry((a.min(b), a.max(b))).or_default().push((t, e));
            }
        }
        // The triangles whose shells overlap this one's: those sharing a corner's position
        // where the two normals part (across a crease, a cube's edges and corners).
        let mut at_vertex: HashMap<u32, Vec<(usize, u32)>> = HashMap::new();
        for (t, tri) in kept.iter().enumerate() {
            for &i in tri {
                at_vertex.entry(ids[i as usize]).or_default().push((t, i));
            }
        }
        let normal = |i: u32| Vec3::from(mesh.vertices[i as usize].normal);
        for (t, tri) in kept.iter().enumerate() {
            let mut list: Vec<u32> = Vec::new();
            for &i in tri {
                for &(o, j) in &at_vertex[&ids[i as usize]] {
                    let index = (first + o) as u32;
                    if o != t && (normal(i) - normal(j)).length() > 1e-4 && !list.contains(&index) {
                        list.push(index);
                    }
                }
            }
            overlaps.push(list);
        }
        for (t, tri) in kept.iter().enumerate() {
            let mut words = [0u32; TRIANGLE_WORDS];
            let mut lo_t = Vec3::splat(f32::INFINITY);
            let mut hi_t = Vec3::splat(f32::NEG_INFINITY);
            for (c, &i) in tri.iter().enumerate() {
                let v = &mesh.vertices[i as usize];
                let w = &mut words[c * 9..c * 9 + 9];
                let values = [
                    v.position[0],
                    v.position[1],
                    v.position[2],
                    v.scale,
                    v.normal[0],
                    v.normal[1],
                    v.normal[2],
                    v.uv[0],
                    v.uv[1],
                ];
                for (w, value) in w.iter_mut().zip(values) {
                    *w = value.to_bits();
                }
                lo_t = lo_t.min(Vec3::from(v.position));
                hi_t = hi_t.max(Vec3::from(v.position));
            }
            let flat = flat_triangle(mesh, tri);
            let mut flags = if flat { FLAT } else { 0 };
            for e in 0..3 {
                let (a, b) = (
                    ids[tri[(e + 1) % 3] as usize],
                    ids[tri[(e + 2) % 3] as usize],
                );
                let shared = &edges[&(a.min(b), a.max(b))];
                words[27 + e] = match shared.as_slice() {
                    [x, y] => {
                        let other = if x.0 == t { y.0 } else { x.0 };
                        if flat && continues_flat(mesh, tri, &kept[other]) {
                            flags |= FLAT_EDGE << e;
                        }
                        (first + other) as u32
                    }
                    _ => NONE,
                };
            }
            words[30] = mesh.vertices[tri[0] as usize].surface.round().max(0.0) as u32;
            words[33] = flags;
            triangles.push(words);
            bounds.push((lo_t, hi_t));
        }
    }
    if triangles.is_empty() {
        return header(Vec3::ZERO, 1.0, [0; 3], 0, 0);
    }
    // The grid: cubic cells, about two per triangle along the longest side's cube root.
    let size = hi - lo;
    let along = ((triangles.len() as f32).cbrt() * 2.0)
        .ceil()
        .clamp(1.0, MAX_CELLS as f32);
    let cell = (size.max_element() / along).max(extent * 1e-6);
    // Widened by a cell's hundredth so that points on the extremes fall inside.
    let lo = lo - Vec3::splat(cell * 0.01);
    let dims = ((size + Vec3::splat(cell * 0.02)) / cell)
        .ceil()
        .clamp(Vec3::ONE, Vec3::splat(MAX_CELLS as f32));
    let dims = [dims.x as usize, dims.y as usize, dims.z as usize];
    let cell_of = |p: Vec3| {
        let c = ((p - lo) / cell).floor();
        [0, 1, 2].map(|a| (c[a].max(0.0) as usize).min(dims[a] - 1))
    };
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
    // A triangle is listed in every cell its box (widened like the grid) meets.
    let pad = Vec3::splat(cell * 0.01);
    for (t, (a, b)) in bounds.iter().enumerate() {
        let (c0, c1) = (cell_of(*a - pad), cell_of(*b + pad));
        for z in c0[2]..=c1[2] {
            for y in c0[1]..=c1[1] {
                for x in c0[0]..=c1[0] {
                    lists[(z * dims[1] + y) * dims[0] + x].push(t as u32);
                }
            }
        }
    }
    let mut offset = 0u32;
    for (words, list) in triangles.iter_mut().zip(&overlaps) {
        words[31] = offset;
        words[32] = list.len() as u32;
        offset += list.len() as u32;
    }
    // The distinct planes of each triangle's overlapping triangles (a cube's face is two
    // triangles on one plane): what the walk's cheap test of a flat path reads.
    let f = |t: usize, i: usize| f32::from_bits(triangles[t][i]);
    let corner = |t: usize, c: usize| Vec3::new(f(t, c * 9), f(t, c * 9 + 1), f(t, c * 9 + 2));
    let mut planes: Vec<Vec<[f32; PLANE_WORDS]>> = Vec::with_capacity(triangles.len());
    for list in &overlaps {
        let mut distinct: Vec<[f32; PLANE_WORDS]> = Vec::new();
        for &o in list {
            let o = o as usize;
            let (p0, p1, p2) = (corner(o, 0), corner(o, 1), corner(o, 2));
            let mut n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
            if n.dot(Vec3::new(f(o, 4), f(o, 5), f(o, 6))) < 0.0 {
                n = -n;
            }
            let scale = f(o, 3).max(f(o, 12)).max(f(o, 21));
            let offset = n.dot(p0);
            match distinct.iter_mut().find(|q| {
                (Vec3::new(q[0], q[1], q[2]) - n).length() <= 1e-5
                    && (q[3] - offset).abs() <= 1e-5 * extent
            }) {
                Some(q) => q[4] = q[4].max(scale),
                None => distinct.push([n.x, n.y, n.z, offset, scale]),
            }
        }
        planes.push(distinct);
    }
    let mut first_plane = 0u32;
    for (words, list) in triangles.iter_mut().zip(&planes) {
        words[34] = first_plane;
        words[35] = list.len() as u32;
        first_plane += list.len() as u32;
    }
    let tri_base = HEADER_WORDS;
    let cell_base = tri_base + triangles.len() * TRIANGLE_WORDS;
    let list_base = cell_base + lists.len() + 1;
    let overlap_base = list_base + lists.iter().map(Vec::len).sum::<usize>();
    let plane_base = overlap_base + overlaps.iter().map(Vec::len).sum::<usize>();
    let mut words = header(
        lo,
        1.0 / cell,
        dims.map(|d| d as u32),
        triangles.len() as u32,
        tri_base,
    );
    words[9] = cell_base as u32;
    words[10] = list_base as u32;
    words[11] = overlap_base as u32;
    words[12] = plane_base as u32;
    words.extend(triangles.iter().flatten());
    let mut offset = 0u32;
    for list in &lists {
        words.push(offset);
        offset += list.len() as u32;
    }
    words.push(offset);
    words.extend(lists.iter().flatten());
    words.extend(overlaps.iter().flatten());
    words.extend(planes.iter().flatten().flatten().map(|x| x.to_bits()));
    // The flat regions (super::regions), from the next whole texel.
    words.resize(words.len().div_ceil(4) * 4, 0);
    let table = words.len() / 4;
    let (entries, texels) =
        super::regions::region_texels(&triangles, &overlaps, &planes, extent, table);
    if entries > 0 {
        words[13] = table as u32;
        words[14] = entries as u32;
        words.extend(texels.iter().flatten());
    }
    words
}

fn header(lo: Vec3, inv_cell: f32, dims: [u32; 3], count: u32, tri_base: usize) -> Vec<u32> {
    let mut words = vec![0u32; HEADER_WORDS];
    words[0] = lo.x.to_bits();
    words[1] = lo.y.to_bits();
    words[2] = lo.z.to_bits();
    words[3] = inv_cell.to_bits();
    words[4..7].copy_from_slice(&dims);
    words[7] = count;
    words[8] = tri_base as u32;
    words
}

/// Whether the triangle's normals and local uv scales are equal (its shell a straight
/// prism).
fn flat_triangle(mesh: &Mesh, tri: &[u32; 3]) -> bool {
    let v = |k: usize| &mesh.vertices[tri[k] as usize];
    (1..3).all(|k| {
        (Vec3::from(v(k).normal) - Vec3::from(v(0).normal)).length() <= 1e-6
            && (v(k).scale - v(0).scale).abs() <= 1e-6 * v(0).scale.abs().max(1e-30)
    })
}

/// Whether `other` (sharing an edge with the flat `tri`) is flat with the same normal and
/// scale and carries the same affine uv map: its corners' uvs are those `tri`'s map gives
/// their positions (to 1e-5 of a tile), so a straight path stays straight across.
fn continues_flat(mesh: &Mesh, tri: &[u32; 3], other: &[u32; 3]) -> bool {
    let v = |i: u32| &mesh.vertices[i as usize];
    if !flat_triangle(mesh, other)
        || (Vec3::from(v(other[0]).normal) - Vec3::from(v(tri[0]).normal)).length() > 1e-6
        || (v(other[0]).scale - v(tri[0]).scale).abs() > 1e-6 * v(tri[0]).scale.abs().max(1e-30)
    {
        return false;
    }
    let p = |i: u32| Vec3::from(v(i).position).as_dvec3();
    let uv = |i: u32| glam::Vec2::from(v(i).uv).as_dvec2();
    let (p0, e1, e2) = (p(tri[0]), p(tri[1]) - p(tri[0]), p(tri[2]) - p(tri[0]));
    let n = e1.cross(e2);
    let area2 = n.length_squared();
    if area2 <= 0.0 {
        return false;
    }
    other.iter().all(|&i| {
        let r = p(i) - p0;
        let (b1, b2) = (r.cross(e2).dot(n) / area2, e1.cross(r).dot(n) / area2);
        let predicted =
            uv(tri[0]) + b1 * (uv(tri[1]) - uv(tri[0])) + b2 * (uv(tri[2]) - uv(tri[0]));
        (predicted - uv(i)).abs().max_element() <= 1e-5 && r.dot(n).abs() <= 1e-6 * area2.sqrt()
    })
}

/// One id per position: vertices of `mesh` within `tolerance` of each other (along every
/// axis) share the smallest index among them.
fn welded(mesh: &Mesh, tolerance: f32) -> Vec<u32> {
    let key = |p: [f32; 3]| p.map(|x| (x / tolerance).floor() as i64);
    let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    let mut ids = Vec::with_capacity(mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        let k = key(v.position);
        let p = Vec3::from(v.position);
        let mut found = None;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let Some(list) = cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                        continue;
                    };
                    for &j in list {
                        let q = Vec3::from(mesh.vertices[j as usize].position);
                        if (p - q).abs().max_element() <= tolerance {
                            found = Some(ids[j as usize]);
                            break 'search;
                        }
                    }
                }
            }
        }
        ids.push(found.unwrap_or(i as u32));
        cells.entry(k).or_default().push(i as u32);
    }
    ids
}

/// The walk buffer on the GPU (host-visible: written once when made, then only read), read
/// by the shaders as a uniform texel buffer of `R32G32B32A32_UINT` texels, four words each:
/// a CPU driver gathers a texel for its lanes at once where it reads a storage buffer one
/// lane and one word at a time (lavapipe; every load of the walk's code costs that, run
/// or not, as its lanes execute in lockstep).
pub struct WalkMeshes {
    /// The buffer ([`walk_words`], padded to whole texels).
    pub buffer: Buffer,
    /// Its texel view (`R32G32B32A32_UINT`).
    pub view: vk::BufferView,
    /// How many triangles it holds (0: none, the circle model everywhere).
    pub triangles: u32,
}

/// The texel format of the walk buffer's view.
const TEXEL_FORMAT: vk::Format = vk::Format::R32G32B32A32_UINT;

impl WalkMeshes {
    /// The walk buffer of `meshes` (world space), written through its mapping: visible to
    /// every later submission (a queue submission makes earlier host writes available).
    /// Fails with [`Error::Unsupported`] when it holds more texels than the device's
    /// `maxTexelBufferElements` (at least 65,536 texels: about 7,000 triangles; 2^27 on
    /// lavapipe and the common desktop drivers).
    pub fn new(ctx: &Context, meshes: &[&Mesh]) -> Result<Self> {
        Self::from_words(ctx, walk_words(meshes))
    }

    /// The walk buffer of `meshes` without its flat regions' table (the first trace then
    /// sends every pixel it cannot keep to the triage, the per-triangle path): what the
    /// tests compare the regions' steps with.
    #[cfg(test)]
    pub(crate) fn without_regions(ctx: &Context, meshes: &[&Mesh]) -> Result<Self> {
        let mut words = walk_words(meshes);
        words[13] = 0;
        words[14] = 0;
        Self::from_words(ctx, words)
    }

    /// The walk buffer holding `words` ([`WalkMeshes::new`]).
    fn from_words(ctx: &Context, mut words: Vec<u32>) -> Result<Self> {
        words.resize(words.len().div_ceil(4) * 4, 0);
        let texels = words.len() / 4;
        let limit = ctx.info().max_texel_buffer_elements;
        if texels as u64 > u64::from(limit) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                what: format!(
                    "a mesh walk buffer of {texels} texels (the curved meshes' {} triangles; \
                     maxTexelBufferElements is {limit})",
                    words[7]
                ),
            });
        }
        let bytes: &[u8] = bytemuck::cast_slice(&words);
        let mut buffer = Buffer::new(
            ctx,
            "walk meshes",
            bytes.len() as u64,
            vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        let Some(mapped) = buffer.mapped_mut() else {
            // SAFETY: just made, never used by the GPU.
            unsafe { buffer.destroy(ctx) };
            return Err(Error::Internal(
                "the walk buffer's memory is not host-visible".into(),
            ));
        };
        mapped[..bytes.len()].copy_from_slice(bytes);
        let info = vk::BufferViewCreateInfo::default()
            .buffer(buffer.raw)
            .format(TEXEL_FORMAT)
            .offset(0)
            .range(vk::WHOLE_SIZE);
        // SAFETY: a live buffer of this device made with UNIFORM_TEXEL_BUFFER usage; the
        // format has the uniform texel buffer feature on every device (a format Vulkan
        // requires it for) and the texel count is within the device's limit (above).
        let view = match unsafe { ctx.device().create_buffer_view(&info, None) } {
            Ok(v) => v,
            Err(e) => {
                // SAFETY: just made, never used by the GPU.
                unsafe { buffer.destroy(ctx) };
                return Err(Error::Vulkan {
                    call: "vkCreateBufferView",
                    result: e,
                });
            }
        };
        Ok(WalkMeshes {
            buffer,
            view,
            triangles: words[7],
        })
    }
}

impl Destroy for WalkMeshes {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses the view or the buffer); the
        // view is destroyed before its buffer and nulled.
        unsafe {
            if self.view != vk::BufferView::null() {
                ctx.device().destroy_buffer_view(self.view, None);
                self.view = vk::BufferView::null();
            }
            self.buffer.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.buffer.bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri_words(words: &[u32], t: usize) -> &[u32] {
        let base = words[8] as usize + t * TRIANGLE_WORDS;
        &words[base..base + TRIANGLE_WORDS]
    }

    #[test]
    fn a_closed_mesh_has_a_neighbour_across_every_edge() {
        for mesh in [Mesh::sphere(), Mesh::torus(), Mesh::cube()] {
            let words = walk_words(&[&mesh]);
            let n = words[7] as usize;
            assert!(n > 0, "{}", mesh.label);
            let overlapping: usize = (0..n).map(|t| tri_words(&words, t)[32] as usize).sum();
            for t in 0..n {
                let w = tri_words(&words, t);
                for e in 0..3 {
                    let other = w[27 + e];
                    assert_ne!(other, NONE, "{} triangle {t} edge {e}", mesh.label);
                    // The neighbour has this triangle as a neighbour too.
                    let back = &tri_words(&words, other as usize)[27..30];
                    assert!(back.contains(&(t as u32)), "{} {t} <-> {other}", mesh.label);
                }
            }
            // A cube's triangle overlaps those of the faces that meet at its corners; the
            // smooth meshes' shells meet without overlapping.
            if mesh.label == "cube" {
                assert!((0..n).all(|t| tri_words(&words, t)[32] >= 4), "cube");
            } else {
                assert_eq!(overlapping, 0, "{}", mesh.label);
            }
        }
    }

    #[test]
    fn a_cube_face_is_flat_across_its_diagonal_only() {
        let words = walk_words(&[&Mesh::cube()]);
        for t in 0..words[7] as usize {
            let flags = tri_words(&words, t)[33];
            // Its overlapping triangles lie on the 4 faces around it.
            assert_eq!(tri_words(&words, t)[35], 4, "triangle {t}");
            assert_eq!(flags & FLAT, FLAT, "triangle {t}");
            // One edge (the diagonal) continues flat; the face's two outer edges are creases.
            let continuing = (0..3).filter(|e| flags & (FLAT_EDGE << e) != 0).count();
            assert_eq!(continuing, 1, "triangle {t}");
        }
        let sphere = walk_words(&[&Mesh::sphere()]);
        assert!((0..sphere[7] as usize).all(|t| tri_words(&sphere, t)[33] & FLAT == 0));
    }

    #[test]
    fn the_pole_rows_without_area_are_left_out() {
        let mesh = Mesh::sphere();
        let words = walk_words(&[&mesh]);
        // 96 x 48 quads, two triangles each, less one degenerate triangle per quad of the
        // two pole rows.
        assert_eq!(words[7] as usize, 96 * 48 * 2 - 2 * 96);
    }

    #[test]
    fn an_open_mesh_has_boundary_edges() {
        let words = walk_words(&[&Mesh::quad()]);
        assert_eq!(words[7], 2);
        let none = (0..2)
            .flat_map(|t| tri_words(&words, t)[27..30].to_vec())
            .filter(|&a| a == NONE)
            .count();
        assert_eq!(none, 4, "a quad's 4 outer edges");
    }

    #[test]
    fn every_triangle_is_listed_in_the_cell_of_its_centre() {
        let mesh = Mesh::torus();
        let words = walk_words(&[&mesh]);
        let f = |i: usize| f32::from_bits(words[i]);
        let lo = Vec3::new(f(0), f(1), f(2));
        let inv = f(3);
        let dims = [words[4], words[5], words[6]].map(|d| d as usize);
        let (cells, lists) = (words[9] as usize, words[10] as usize);
        for t in 0..words[7] as usize {
            let w = tri_words(&words, t);
            let p = |c: usize| {
                Vec3::new(
                    f32::from_bits(w[c * 9]),
                    f32::from_bits(w[c * 9 + 1]),
                    f32::from_bits(w[c * 9 + 2]),
                )
            };
            let centre = (p(0) + p(1) + p(2)) / 3.0;
            let c = ((centre - lo) * inv).floor();
            let index = (c.z as usize * dims[1] + c.y as usize) * dims[0] + c.x as usize;
            let (a, b) = (
                words[cells + index] as usize,
                words[cells + index + 1] as usize,
            );
            assert!(
                words[lists + a..lists + b].contains(&(t as u32)),
                "triangle {t}"
            );
        }
    }

    #[test]
    fn no_mesh_is_an_empty_walk() {
        let words = walk_words(&[]);
        assert_eq!(words.len(), HEADER_WORDS);
        assert_eq!(words[7], 0);
    }
}
