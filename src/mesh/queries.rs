//! Queries on a mesh's triangles, in f64: the distance to the nearest triangle and whether
//! a point is inside a closed mesh (a scene's eye checks), and whether the mesh is convex
//! (a renderer's behind layer, which a convex mesh alone never needs).

use super::Mesh;
use glam::Vec3;

/// The most vertex-plane tests [`Mesh::is_convex`] makes (a tenth of a second or so): the
/// generated sphere takes 9216 x 4753.
const MAX_CONVEXITY_TESTS: usize = 1 << 27;

impl Mesh {
    /// The triangles' corners in f64.
    fn triangles_f64(&self) -> impl Iterator<Item = [glam::DVec3; 3]> + '_ {
        self.indices.chunks_exact(3).filter_map(|t| {
            let p = |i: u32| {
                self.vertices
                    .get(i as usize)
                    .map(|v| Vec3::from(v.position).as_dvec3())
            };
            Some([p(t[0])?, p(t[1])?, p(t[2])?])
        })
    }

    /// The distance from `point` to the nearest point of the mesh's triangles, in f64
    /// (infinite for a mesh without triangles).
    pub fn distance_to(&self, point: glam::DVec3) -> f64 {
        self.triangles_f64()
            .map(|[a, b, c]| (closest_on_triangle(point, a, b, c) - point).length())
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether `point` is inside the mesh taken as a closed surface (the generated cube,
    /// sphere and torus are): a ray from it crosses an odd number of its triangles. The
    /// ray's direction is one no edge or face of the generated meshes lies along.
    pub fn encloses(&self, point: glam::DVec3) -> bool {
        let dir = glam::DVec3::new(0.5773, 0.3317, 0.7453).normalize();
        let crossings = self
            .triangles_f64()
            .filter(|&[a, b, c]| {
                // Moller-Trumbore: the ray point + t dir, t > 0, through the triangle.
                let (e1, e2) = (b - a, c - a);
                let p = dir.cross(e2);
                let det = e1.dot(p);
                if det.abs() < 1e-300 {
                    return false;
                }
                let s = point - a;
                let u = s.dot(p) / det;
                let q = s.cross(e1);
                let v = dir.dot(q) / det;
                let t = e2.dot(q) / det;
                (0.0..=1.0).contains(&u) && v >= 0.0 && u + v <= 1.0 && t > 0.0
            })
            .count();
        crossings % 2 == 1
    }

    /// Whether every vertex has the same normal, bit for bit (a quad, a flat-shaded
    /// plane): the interpolated normal then never changes, so the curvature curved
    /// tracing reads from the G-buffer is zero everywhere and the mesh traces as its
    /// tangent planes whether traced curved or not ([`crate::renderer::Renderer::set_curved`]
    /// leaves such an object's material flat). A mesh without vertices has none.
    pub fn has_one_normal(&self) -> bool {
        let bits = |v: &super::Vertex| v.normal.map(f32::to_bits);
        self.vertices
            .first()
            .is_some_and(|first| self.vertices.iter().all(|v| bits(v) == bits(first)))
    }

    /// Whether the mesh is convex: every vertex lies on the inner side of the plane of
    /// every triangle (degenerate ones aside), each plane oriented by its corners'
    /// normals (the side the surface faces, as the G-buffer pass orients a triangle's own
    /// plane), within a millionth of the mesh's extent (the positions' f32 rounding: a
    /// UV sphere's quads are planar only up to it). Then no ray meets the mesh's
    /// front-facing triangles twice: seen alone, nothing of it lies behind its own
    /// surface (the generated cube and sphere are convex; the torus and a vase are not).
    /// It need not be closed. `O(triangles x vertices)`: a mesh that would take more than
    /// 2^27 vertex-plane tests (a tenth of a second or so) is taken as not convex (`false`), the
    /// answer that costs nothing but time where it is wrong (the behind layer is drawn).
    pub fn is_convex(&self) -> bool {
        if (self.indices.len() / 3).saturating_mul(self.vertices.len()) > MAX_CONVEXITY_TESTS {
            return false;
        }
        let mut points: Vec<glam::DVec3> = self
            .vertices
            .iter()
            .map(|v| Vec3::from(v.position).as_dvec3())
            .collect();
        if points.iter().any(|p| !p.is_finite()) {
            return false;
        }
        // Welded by their bits (a seam's or a pole's copies are one point).
        points.sort_by(|a, b| {
            a.x.total_cmp(&b.x)
                .then(a.y.total_cmp(&b.y))
                .then(a.z.total_cmp(&b.z))
        });
        points.dedup();
        let (lo, hi) = points.iter().fold(
            (
                glam::DVec3::splat(f64::INFINITY),
                glam::DVec3::splat(-f64::INFINITY),
            ),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let extent = (hi - lo).max_element();
        if extent <= 0.0 {
            return true;
        }
        let tolerance = 1e-6 * extent;
        self.indices.chunks_exact(3).all(|t| {
            let vertex = |i: u32| self.vertices.get(i as usize);
            let (Some(a), Some(b), Some(c)) = (vertex(t[0]), vertex(t[1]), vertex(t[2])) else {
                return true;
            };
            let p = |v: &super::Vertex| Vec3::from(v.position).as_dvec3();
            let (pa, pb, pc) = (p(a), p(b), p(c));
            let mut n = (pb - pa).cross(pc - pa);
            let length = n.length();
            // Degenerate (a pole's collapsed corner): no plane.
            if length <= 1e-12 * extent * extent {
                return true;
            }
            n /= length;
            let facing = [a, b, c]
                .iter()
                .map(|v| Vec3::from(v.normal).as_dvec3())
                .sum::<glam::DVec3>();
            if n.dot(facing) < 0.0 {
                n = -n;
            }
            let offset = n.dot(pa) + tolerance;
            points.iter().all(|q| n.dot(*q) <= offset)
        })
    }
}

/// The point of triangle `abc` nearest to `p` (Ericson, Real-Time Collision Detection,
/// 5.1.5), in f64.
fn closest_on_triangle(
    p: glam::DVec3,
    a: glam::DVec3,
    b: glam::DVec3,
    c: glam::DVec3,
) -> glam::DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < 1e-300 {
        // A degenerate triangle: its nearest corner.
        return [a, b, c]
            .into_iter()
            .min_by(|x, y| (*x - p).length().total_cmp(&(*y - p).length()))
            .unwrap_or(a);
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The eye checks of a scene of several objects: inside the closed generated meshes
    /// by a crossing count, and the distance to the nearest triangle.
    #[test]
    fn meshes_enclose_points_inside_and_measure_distances() {
        use glam::DVec3;
        let cube = Mesh::cube();
        assert!(cube.encloses(DVec3::ZERO));
        assert!(cube.encloses(DVec3::new(0.0, 0.25, 0.433)));
        assert!(!cube.encloses(DVec3::new(0.0, 3.0, 0.0)));
        for mesh in [Mesh::sphere(), Mesh::torus()] {
            assert!(!mesh.encloses(DVec3::new(0.0, 5.0, 0.0)), "{}", mesh.label);
        }
        assert!(Mesh::sphere().encloses(DVec3::new(0.1, 0.2, 0.0)));
        // The torus's hole is outside it.
        assert!(!Mesh::torus().encloses(DVec3::ZERO));
        let quad = Mesh::quad();
        let d = quad.distance_to(DVec3::new(0.5, 0.3, 0.5));
        assert!((d - 0.3).abs() < 1e-6, "{d}");
        let d = quad.distance_to(DVec3::new(2.0, 0.0, 0.5));
        assert!((d - 1.0).abs() < 1e-6, "{d}");
    }

    /// Convexity: the generated cube, sphere and quad are convex, the torus is not, nor
    /// a sphere with one vertex pushed in (the check can fail on a nearly convex mesh).
    #[test]
    fn convexity_of_the_generated_meshes() {
        assert!(Mesh::cube().is_convex());
        assert!(Mesh::sphere().is_convex());
        assert!(Mesh::quad().is_convex());
        assert!(!Mesh::torus().is_convex());
        let mut dented = Mesh::sphere();
        let i = dented.vertices.len() / 2 + 7;
        let p = Vec3::from(dented.vertices[i].position);
        dented.vertices[i].position = (p * 0.99).into();
        assert!(!dented.is_convex());
        let mut empty = Mesh::sphere();
        empty.indices.clear();
        assert!(
            empty.is_convex(),
            "no triangle: nothing lies behind anything"
        );
    }

    /// One normal: the quad, placed anywhere, has it; the cube (six), the sphere and the
    /// torus do not, nor a quad with one normal nudged by an ulp, nor a mesh without
    /// vertices.
    #[test]
    fn one_normal_of_the_generated_meshes() {
        assert!(Mesh::quad().has_one_normal());
        let placement = crate::scene::Placement {
            position: Vec3::new(-1.0, -0.3, -1.0),
            scale: 2.0,
            rotation_deg: Vec3::new(10.0, 30.0, 0.0),
        };
        assert!(Mesh::quad().placed(&placement, 1).has_one_normal());
        for mesh in [Mesh::cube(), Mesh::sphere(), Mesh::torus()] {
            assert!(!mesh.has_one_normal(), "{}", mesh.label);
        }
        let mut nudged = Mesh::quad();
        nudged.vertices[2].normal[1] = f32::from_bits(nudged.vertices[2].normal[1].to_bits() - 1);
        assert!(!nudged.has_one_normal());
        let mut empty = Mesh::quad();
        empty.vertices.clear();
        assert!(!empty.has_one_normal());
    }
}
