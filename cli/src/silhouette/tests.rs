//! The tessellated reference against the tangent-space reference on a flat quad, against
//! the base mesh where the map is at the top, against the inward offset where it is at the
//! bottom, and the outline band on hand-made masks.

use super::*;
use crate::reference::{Ray, Reference};

fn flat(value: f32) -> HeightField {
    HeightField::from_heights(4, 4, vec![value; 16], "flat").unwrap()
}

/// A smooth map, so that one vertex per texel follows the bilinear surface closely.
fn waves(size: u32) -> HeightField {
    let n = size as usize;
    let values = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f32 / n as f32, (k / n) as f32 / n as f32);
            let tau = std::f32::consts::TAU;
            0.5 + 0.25 * (tau * x).sin() * (tau * 2.0 * y).cos() + 0.2 * (tau * (x + y)).cos()
        })
        .collect();
    HeightField::from_heights(size, size, values, "waves").unwrap()
}

/// The first hit of the base mesh itself, by brute force over its triangles.
fn base_hit(mesh: &Mesh, origin: DVec3, dir: DVec3) -> Option<f64> {
    let p = |i: u32| DVec3::from(mesh.vertices[i as usize].position.map(f64::from));
    mesh.indices
        .chunks_exact(3)
        .filter_map(|t| hit_triangle(origin, dir, p(t[0]), p(t[1]), p(t[2]), f64::INFINITY))
        .min_by(f64::total_cmp)
}

#[test]
fn on_a_flat_quad_it_agrees_with_the_tangent_space_reference() {
    // The quad spans uv [0, 1]² on y = 0 (x = u, z = v, one uv unit = one world unit), so
    // the world depth is the depth scale and a world ray has the tangent-space ray
    // uv0 = its entry's (x, z), P = its (x, z) offset while it descends the depth.
    let field = waves(32);
    let depth = 0.1;
    let mesh = Mesh::quad();
    let surface = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &field, Addressing::Repeat, depth);
    let reference = Reference::new(&field, Addressing::Repeat);
    let origin = DVec3::new(0.2, 1.0, -0.6);
    let mut compared = 0;
    for k in 0..400 {
        let target = DVec3::new(
            0.2 + 0.03 * (k % 20) as f64,
            0.0,
            0.2 + 0.03 * (k / 20) as f64,
        );
        let dir = (target - origin).normalize();
        let entry = -origin.y / dir.y;
        let descent = depth / -dir.y;
        let ray = Ray {
            uv0: [target.x, target.z],
            parallax: [dir.x * descent, dir.z * descent],
        };
        let exact = reference
            .intersect(&ray)
            .expect("a repeat map is always hit");
        let want = entry + (1.0 - exact.height) * descent;
        // Rays that would leave the quad before the hit are not comparable (the quad ends).
        let hit_point = origin + dir * want;
        if !(0.01..0.99).contains(&hit_point.x) || !(0.01..0.99).contains(&hit_point.z) {
            continue;
        }
        let got = surface
            .first_hit(origin, dir)
            .expect("the displaced quad is hit");
        // One vertex per texel on a smooth map: the hit within a tenth of a texel along
        // the surface (a texel is 1/32 world units here).
        let along = (got - want).abs() * (dir.x * dir.x + dir.z * dir.z).sqrt();
        assert!(along < 0.1 / 32.0, "ray {k}: {got} against {want}");
        compared += 1;
    }
    assert!(compared > 300, "only {compared} rays compared");
}

#[test]
fn a_map_at_the_top_is_the_base_mesh() {
    let field = flat(1.0);
    let mesh = Mesh::sphere();
    let surface = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &field, Addressing::Repeat, 0.1);
    let origin = DVec3::new(0.3, 0.4, 3.0);
    for k in 0..64 {
        let target = DVec3::new(-0.9 + 0.03 * k as f64, 0.35 - 0.011 * k as f64, 0.0);
        let dir = (target - origin).normalize();
        let want = base_hit(&mesh, origin, dir);
        let got = surface.first_hit(origin, dir);
        match (got, want) {
            (Some(g), Some(w)) => assert!((g - w).abs() < 1e-9, "ray {k}: {g} against {w}"),
            (g, w) => assert_eq!(g.is_some(), w.is_some(), "ray {k}: {g:?} against {w:?}"),
        }
    }
}

#[test]
fn a_map_at_the_bottom_carves_the_outline() {
    // A ray in the equator's plane passing 0.98 R from the sphere's centre crosses the
    // base mesh (its equator's facets reach cos(pi / 96) R) but not the offset surface,
    // about 0.13 (depth 0.1 times the uv scale 2 pi R / 4) further in.
    let mesh = Mesh::sphere();
    let r = f64::from(dispmap::mesh::SPHERE_RADIUS);
    let (top, bottom) = (flat(1.0), flat(0.0));
    let origin = DVec3::new(0.98 * r, 0.0, 3.0);
    let dir = DVec3::new(0.0, 0.0, -1.0);
    let at = |field: &HeightField| {
        DisplacedMesh::new(&mesh, DMat4::IDENTITY, field, Addressing::Repeat, 0.1)
            .first_hit(origin, dir)
    };
    assert!(at(&top).is_some());
    assert_eq!(at(&bottom), None);
    // Through the centre the offset surface is met about 0.13 below the base.
    let centre = DVec3::new(0.0, 0.0, 3.0);
    let hit = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &bottom, Addressing::Repeat, 0.1)
        .first_hit(centre, dir)
        .unwrap();
    let inset = hit - (3.0 - r);
    let expected = 0.1 * std::f64::consts::TAU * r / 4.0;
    assert!(
        (inset - expected).abs() < 0.01 * expected,
        "{inset} against {expected}"
    );
}

#[test]
fn the_outline_band_counts_disagreement_near_edges_only() {
    let (w, h) = (20, 14);
    // A filled rectangle, and the same rectangle one column narrower.
    let rect = |x1: usize| -> Vec<bool> {
        (0..w * h)
            .map(|k| (5..x1).contains(&(k % w)) && (5..9).contains(&(k / w)))
            .collect()
    };
    let same = outline_agreement(&rect(12), &rect(12), w, h);
    assert_eq!(same.agreeing, same.band);
    assert!(same.band > 0 && same.band < w * h);
    let narrower = outline_agreement(&rect(12), &rect(11), w, h);
    assert_eq!(
        narrower.band - narrower.agreeing,
        4,
        "column 11 of rows 5 to 8"
    );
    assert!(narrower.share() < 1.0);
    let empty = outline_agreement(&[false; 280], &[false; 280], w, h);
    assert_eq!((empty.band, empty.share()), (0, 1.0));
}

#[test]
fn the_uv_scales_are_the_meshes_own() {
    // The reference computes its vertices' uv scales itself; they are the model's
    // (`Vertex::scale`, which the G-buffer's curve output interpolates).
    for mesh in [Mesh::cube(), Mesh::sphere(), Mesh::torus()] {
        let positions: Vec<DVec3> = mesh
            .vertices
            .iter()
            .map(|v| DVec3::from(v.position.map(f64::from)))
            .collect();
        for (v, s) in mesh.vertices.iter().zip(uv_scales(&mesh, &positions)) {
            assert!(
                (f64::from(v.scale) - s).abs() <= 1e-6 * s.max(1.0),
                "{}: {v:?} against {s}",
                mesh.label
            );
        }
    }
}

#[test]
fn a_surface_met_from_behind_is_not_a_hit() {
    // The unit cube with the map at the bottom: each face's offset lies 0.1 inside it. A
    // ray entering the top face near its front edge and heading down and forward crosses
    // the front face's offset (z = 0.4) from inside the cube at y = 0.47, within the top
    // face's shell: that is the back of the front face's relief, not a visible surface; it
    // leaves through the front face without meeting the top face's offset (y = 0.4).
    let mesh = Mesh::cube();
    let bottom = flat(0.0);
    let surface = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &bottom, Addressing::Clamp, 0.1);
    let dir = DVec3::new(0.0, -0.3, 1.0).normalize();
    let entry = DVec3::new(0.0, 0.5, 0.3);
    assert_eq!(surface.first_hit(entry - dir, dir), None);
    // The same ray reversed meets the front face's offset from outside.
    let back = -dir;
    let t = surface
        .first_hit(DVec3::new(0.0, 0.44, 0.5) - back, back)
        .unwrap();
    let p = DVec3::new(0.0, 0.44, 0.5) - back + back * t;
    assert!((p.z - 0.4).abs() < 1e-9, "{p}");
}

#[test]
fn a_two_sided_mesh_is_displaced_from_both_sides() {
    // The quad (y = 0, facing +y), map at the bottom, depth 0.1: seen from above its
    // displaced surface is 0.1 below it; two-sided, seen from below, 0.1 above it.
    let mut mesh = Mesh::quad();
    let bottom = flat(0.0);
    let down = DVec3::new(0.0, -1.0, 0.0);
    let origin = DVec3::new(0.5, 2.0, 0.5);
    let one = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &bottom, Addressing::Clamp, 0.1);
    assert!((one.first_hit(origin, down).unwrap() - 2.1).abs() < 1e-9);
    let below = DVec3::new(0.5, -2.0, 0.5);
    assert_eq!(
        one.first_hit(below, -down),
        None,
        "one-sided: the back is not seen"
    );
    mesh.two_sided = true;
    let two = DisplacedMesh::new(&mesh, DMat4::IDENTITY, &bottom, Addressing::Clamp, 0.1);
    assert!((two.first_hit(origin, down).unwrap() - 2.1).abs() < 1e-9);
    assert!((two.first_hit(below, -down).unwrap() - 2.1).abs() < 1e-9);
    // A ray from above that passes just beside the quad's edge (outside the base) and
    // under it turns back up does not meet the back side's relief standing above it: it
    // never crossed the base.
    let beside = DVec3::new(1.05, 0.05, 0.5);
    let slant = DVec3::new(-1.0, 0.02, 0.0).normalize();
    assert_eq!(two.first_hit(beside, slant), None);
}
