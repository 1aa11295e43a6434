//! The behind layer's draws in pieces the GPU culls: each mesh's triangles split into
//! clusters of consecutive triangles (their index ranges and world-space bounds, made
//! once from the mesh), each cluster's bounds projected per frame into a conservative
//! screen rectangle of 8x8 tiles ([`crate::passes::behind_tiles::DrawSource`]); the
//! layer then draws a cluster only where its rectangle meets a tile whose first-layer
//! trace missed. The pieces keep the triangles' order, so the layer's images are those
//! of drawing each mesh whole.

use crate::mesh::Mesh;
use crate::passes::behind_tiles::{DrawSource, NO_RECT};
use ash::vk;
use glam::{Mat4, Vec3, Vec4};

/// Triangles of a cluster (the last one of a mesh may have fewer).
const CLUSTER_TRIANGLES: u32 = 32;

/// Pixels a projected rectangle is widened by on each side (the GPU's vertex transform
/// rounds differently from this one's).
const MARGIN: f32 = 2.0;

/// Consecutive triangles of a mesh and their bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Cluster {
    /// Its first index and index count in the mesh's index buffer.
    pub first: u32,
    pub count: u32,
    /// The world-space box of its vertices.
    pub min: Vec3,
    pub max: Vec3,
}

/// `mesh`'s clusters, in index order.
pub(super) fn clusters(mesh: &Mesh) -> Vec<Cluster> {
    let per = 3 * CLUSTER_TRIANGLES as usize;
    mesh.indices
        .chunks(per)
        .enumerate()
        .map(|(i, chunk)| {
            let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for &v in chunk {
                let p = Vec3::from(mesh.vertices[v as usize].position);
                min = min.min(p);
                max = max.max(p);
            }
            Cluster {
                first: (i * per) as u32,
                count: chunk.len() as u32,
                min,
                max,
            }
        })
        .collect()
}

/// `clusters` merged `factor` at a time (consecutive ones: one range, the union box).
pub(super) fn coarsen(clusters: &[Cluster], factor: usize) -> Vec<Cluster> {
    clusters
        .chunks(factor.max(1))
        .map(|group| Cluster {
            first: group[0].first,
            count: group.iter().map(|c| c.count).sum(),
            min: group
                .iter()
                .fold(Vec3::splat(f32::INFINITY), |m, c| m.min(c.min)),
            max: group
                .iter()
                .fold(Vec3::splat(f32::NEG_INFINITY), |m, c| m.max(c.max)),
        })
        .collect()
}

/// Every tile of a frame of `extent`.
pub(super) fn whole_frame(extent: vk::Extent2D) -> [u32; 4] {
    let [tx, ty] = crate::passes::classify::tile_count(extent);
    [0, 0, tx - 1, ty - 1]
}

/// Relative margin of a box's farthest depth (the GPU's depths round differently).
const DEPTH_MARGIN: f32 = 1e-3;

/// The tiles a box `[min, max]` can cover in a frame of `extent` seen through
/// `view_proj` (eye-relative, as the G-buffer's vertex stages use it) from `eye`, and a
/// reverse-Z depth at or behind all of it: the rectangle of its corners' projections
/// widened by [`MARGIN`] and their smallest depth lowered by [`DEPTH_MARGIN`] (a
/// projective map of a box: its extremes are at corners); the whole frame and depth 0
/// when a corner is not in front of the eye; [`NO_RECT`] when it lies off the frame.
pub(super) fn tile_rect(
    view_proj: Mat4,
    eye: Vec3,
    min: Vec3,
    max: Vec3,
    extent: vk::Extent2D,
) -> ([u32; 4], f32) {
    if !min.is_finite() || !max.is_finite() {
        return (NO_RECT, 0.0);
    }
    let mut depth = f32::INFINITY;
    let (w, h) = (extent.width as f32, extent.height as f32);
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for corner in 0..8 {
        let p = Vec3::new(
            if corner & 1 == 0 { min.x } else { max.x },
            if corner & 2 == 0 { min.y } else { max.y },
            if corner & 4 == 0 { min.z } else { max.z },
        );
        let c: Vec4 = view_proj * (p - eye).extend(1.0);
        if !c.is_finite() || c.w <= 1e-6 {
            return (whole_frame(extent), 0.0);
        }
        depth = depth.min(c.z / c.w);
        let px = [(c.x / c.w * 0.5 + 0.5) * w, (c.y / c.w * 0.5 + 0.5) * h];
        for a in 0..2 {
            lo[a] = lo[a].min(px[a]);
            hi[a] = hi[a].max(px[a]);
        }
    }
    let (lo, hi) = (
        [lo[0] - MARGIN, lo[1] - MARGIN],
        [hi[0] + MARGIN, hi[1] + MARGIN],
    );
    if hi[0] < 0.0 || hi[1] < 0.0 || lo[0] >= w || lo[1] >= h {
        return (NO_RECT, 0.0);
    }
    let [tx, ty] = crate::passes::classify::tile_count(extent);
    let size = crate::gpu::pipeline::LOCAL_SIZE;
    let tile = |v: f32, n: u32, s: u32| ((v.max(0.0) / s as f32) as u32).min(n - 1);
    let depth = if depth.is_finite() {
        (depth * (1.0 - DEPTH_MARGIN)).max(0.0)
    } else {
        0.0
    };
    (
        [
            tile(lo[0], tx, size[0]),
            tile(lo[1], ty, size[1]),
            tile(hi[0], tx, size[0]),
            tile(hi[1], ty, size[1]),
        ],
        depth,
    )
}

/// The sources of one mesh draw's clusters this frame, `own` the materials whose misses
/// it cannot show ([`DrawSource::own`]).
pub(super) fn mesh_sources(
    clusters: &[Cluster],
    view_proj: Mat4,
    eye: Vec3,
    extent: vk::Extent2D,
    own: u32,
) -> impl Iterator<Item = DrawSource> + '_ {
    clusters.iter().map(move |c| {
        let (rect, depth) = tile_rect(view_proj, eye, c.min, c.max, extent);
        DrawSource {
            rect,
            count: c.count,
            first: c.first,
            depth,
            own,
        }
    })
}

/// Per object (its material index, `None`: flat; whether it is a one-sided convex mesh),
/// the materials whose misses its draw cannot show ([`DrawSource::own`]): a convex
/// object's own material where no other object has it (another object of the same
/// material could lie behind its misses), else none.
pub(super) fn own_bits(materials: &[Option<u32>], convex: &[bool]) -> Vec<u32> {
    materials
        .iter()
        .zip(convex.iter().chain(std::iter::repeat(&false)))
        .map(|(m, &convex)| match m {
            Some(m) if convex && materials.iter().filter(|&&o| o == Some(*m)).count() == 1 => {
                crate::passes::behind_tiles::material_bit(*m)
            }
            _ => 0,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only a convex object whose material no other object shares is spared its own
    /// misses, by the bit of its material; from material 31 on no bit can be its own.
    #[test]
    fn only_a_convex_object_with_its_own_material_skips_its_own_misses() {
        let materials = [Some(0), Some(1), Some(2), Some(2), None, Some(3), Some(31)];
        let convex = [true, false, true, true, true, true, true];
        assert_eq!(
            own_bits(&materials, &convex),
            [1, 0, 0, 0, 0, 1 << 3, 0],
            "floor (convex), torus (not), two spheres sharing material 2, a flat cube, \
             a convex mesh of material 3, one of material 31"
        );
        // Missing convexity flags count as not convex.
        assert_eq!(own_bits(&[Some(0), Some(1)], &[true]), [1, 0]);
    }
}
