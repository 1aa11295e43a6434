//! Point queries on a mesh's triangles, in f64: the distance to the nearest triangle and
//! whether a point is inside a closed mesh (a scene's eye checks).

use super::Mesh;
use glam::Vec3;

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
}
