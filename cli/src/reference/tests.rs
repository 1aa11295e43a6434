//! The reference and its shadow query against brute force and hand-made cases (flat maps,
//! ramps, walls, clamped decals, grazing and non-finite rays, degenerate quadratics).

use super::*;

/// SplitMix64: a small deterministic generator for test data.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn random_field(w: u32, h: u32, lo: f32, hi: f32, rng: &mut Rng) -> HeightField {
    let values = (0..w * h)
        .map(|_| rng.range(lo as f64, hi as f64) as f32)
        .collect();
    HeightField::from_heights(w, h, values, "random").unwrap()
}

/// Independent bilinear evaluation at `uv` (no cells, no pyramid).
fn bilinear(field: &HeightField, addressing: Addressing, uv: [f64; 2]) -> f64 {
    let (w, h) = (field.width() as i64, field.height() as i64);
    let x = uv[0] * w as f64 - 0.5;
    let y = uv[1] * h as f64 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let fetch = |i: i64, j: i64| {
        let (i, j) = match addressing {
            Addressing::Repeat => (i.rem_euclid(w), j.rem_euclid(h)),
            Addressing::Clamp => (i.clamp(0, w - 1), j.clamp(0, h - 1)),
        };
        field.texel(i as u32, j as u32) as f64
    };
    let (i, j) = (x0 as i64, y0 as i64);
    let top = fetch(i, j) * (1.0 - fx) + fetch(i + 1, j) * fx;
    let bottom = fetch(i, j + 1) * (1.0 - fx) + fetch(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// Brute force: dense sampling of `f(t)` from `t = 0`, then bisection of the first
/// sign change. Returns `t`.
fn brute_force(field: &HeightField, addressing: Addressing, ray: &Ray) -> Option<f64> {
    let uv = |t: f64| {
        [
            ray.uv0[0] + t * ray.parallax[0],
            ray.uv0[1] + t * ray.parallax[1],
        ]
    };
    let f = |t: f64| bilinear(field, addressing, uv(t)) - (1.0 - t);
    let mut t_end: f64 = 1.0;
    if addressing == Addressing::Clamp {
        if ray.uv0.iter().any(|u| !(0.0..=1.0).contains(u)) {
            return None;
        }
        for a in 0..2 {
            let p = ray.parallax[a];
            if p > 0.0 {
                t_end = t_end.min((1.0 - ray.uv0[a]) / p);
            } else if p < 0.0 {
                t_end = t_end.min(-ray.uv0[a] / p);
            }
        }
    }
    if f(0.0) >= 0.0 {
        return Some(0.0);
    }
    let n = 100_000;
    let mut prev = 0.0;
    for k in 1..=n {
        let t = t_end * k as f64 / n as f64;
        if f(t) >= 0.0 {
            let (mut lo, mut hi) = (prev, t);
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if f(mid) >= 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            return Some(hi);
        }
        prev = t;
    }
    None
}

fn t_of(hit: &Hit) -> f64 {
    1.0 - hit.height
}

fn assert_hit(hit: Option<Hit>, ray: &Ray, t: f64, tol: f64) {
    let hit = hit.unwrap_or_else(|| panic!("no hit for {ray:?}, expected t = {t}"));
    assert!(
        (t_of(&hit) - t).abs() <= tol,
        "{ray:?}: t = {} expected {t}",
        t_of(&hit)
    );
    for a in 0..2 {
        let u = ray.uv0[a] + t * ray.parallax[a];
        assert!(
            (hit.uv[a] - u).abs() <= tol * (1.0 + ray.parallax[a].abs()),
            "{ray:?}: uv {:?}, expected {u} on axis {a}",
            hit.uv
        );
    }
}

#[test]
fn flat_map_hits_at_its_height() {
    let h0 = 0.37f32;
    let field = HeightField::from_heights(8, 6, vec![h0; 48], "flat").unwrap();
    let h0 = h0 as f64;
    let repeat = Reference::new(&field, Addressing::Repeat);
    let clamp = Reference::new(&field, Addressing::Clamp);
    let parallaxes = [
        [0.0, 0.0],
        [0.3, 0.1],
        [-0.2, 0.45],
        [1.0, -1.0],
        [37.5, -12.25],
        [1e3, -7e2],
        [-6e3, 8e3],
    ];
    let starts = [[0.5, 0.5], [0.0, 0.0], [1.0, 0.25], [0.123, 0.987]];
    for p in parallaxes {
        for uv0 in starts {
            let ray = Ray { uv0, parallax: p };
            let hit = repeat.intersect(&ray).unwrap();
            assert!((hit.height - h0).abs() < 1e-12, "{ray:?}: {hit:?}");
            assert_hit(Some(hit), &ray, 1.0 - h0, 1e-12);
            let end = [uv0[0] + (1.0 - h0) * p[0], uv0[1] + (1.0 - h0) * p[1]];
            let inside = end.iter().all(|u| (0.0..=1.0).contains(u));
            match clamp.intersect(&ray) {
                Some(hit) => {
                    assert!(inside, "{ray:?} should leave the decal");
                    assert!((hit.height - h0).abs() < 1e-12, "{ray:?}: {hit:?}");
                }
                None => assert!(!inside, "{ray:?} should hit"),
            }
        }
    }
}

#[test]
fn linear_ramp_has_the_closed_form_hit() {
    // h_i = (1 + i) / 32 (exact in f32): between the first and last texel centres the
    // bilinear surface is exactly H(x) = (1 + x) / 32.
    let (w, h) = (16u32, 4u32);
    let values = (0..w * h).map(|k| (1 + k % w) as f32 / 32.0).collect();
    let field = HeightField::from_heights(w, h, values, "ramp").unwrap();
    let reference = Reference::new(&field, Addressing::Clamp);
    let rays = [
        Ray {
            uv0: [0.5, 0.5],
            parallax: [-0.3, 0.05],
        },
        Ray {
            uv0: [0.5, 0.3],
            parallax: [0.2, 0.1],
        },
        Ray {
            uv0: [0.8, 0.6],
            parallax: [-0.45, -0.2],
        },
        Ray {
            uv0: [0.2, 0.4],
            parallax: [0.6, 0.0],
        },
    ];
    for ray in rays {
        let x0 = ray.uv0[0] * w as f64 - 0.5;
        let dx = ray.parallax[0] * w as f64;
        // (1 + x0 + t dx) / 32 = 1 - t.
        let t = (31.0 - x0) / (32.0 + dx);
        let x = x0 + t * dx;
        assert!(
            (0.0..=(w - 1) as f64).contains(&x),
            "{ray:?} leaves the ramp"
        );
        assert_hit(reference.intersect(&ray), &ray, t, 1e-12);
    }
}

#[test]
fn step_edge_is_hit_on_the_wall() {
    // Left half 0.25, right half 0.75: between the texel centres x = 3 and x = 4 the
    // surface is the wall H(x) = 0.25 + 0.5 (x - 3).
    let (w, h) = (8u32, 2u32);
    let values = (0..w * h)
        .map(|k| if k % w < w / 2 { 0.25 } else { 0.75 })
        .collect();
    let field = HeightField::from_heights(w, h, values, "step").unwrap();
    for addressing in [Addressing::Clamp, Addressing::Repeat] {
        let reference = Reference::new(&field, addressing);
        for (x0, dx) in [(1.0, 5.0), (0.5, 4.0), (0.0, 4.5)] {
            let ray = Ray {
                uv0: [(x0 + 0.5) / w as f64, 0.5],
                parallax: [dx / w as f64, 0.0],
            };
            // 0.25 + 0.5 (x0 + t dx - 3) = 1 - t.
            let t = (0.75 + 0.5 * (3.0 - x0)) / (1.0 + 0.5 * dx);
            let x = x0 + t * dx;
            assert!((3.0..=4.0).contains(&x), "{ray:?}: x = {x} not on the wall");
            assert!(
                1.0 - t > 0.25 + 1e-3,
                "the plateau must not be reached first"
            );
            assert_hit(reference.intersect(&ray), &ray, t, 1e-12);
        }
    }
}

#[test]
fn vertical_ray_hits_below_its_entry() {
    let mut rng = Rng(7);
    let field = random_field(9, 7, 0.0, 1.0, &mut rng);
    for addressing in [Addressing::Repeat, Addressing::Clamp] {
        let reference = Reference::new(&field, addressing);
        for _ in 0..200 {
            let uv0 = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
            let ray = Ray {
                uv0,
                parallax: [0.0, 0.0],
            };
            let expected = bilinear(&field, addressing, uv0);
            let hit = reference.intersect(&ray).unwrap();
            assert!(
                (hit.height - expected).abs() < 1e-12,
                "{ray:?}: {hit:?} vs {expected}"
            );
            assert_eq!(hit.uv, uv0);
        }
    }
}

#[test]
fn clamp_discards_a_ray_that_leaves_and_repeat_wraps_it() {
    let field = HeightField::from_heights(4, 4, vec![0.25; 16], "flat").unwrap();
    let clamp = Reference::new(&field, Addressing::Clamp);
    let repeat = Reference::new(&field, Addressing::Repeat);
    let ray = Ray {
        uv0: [0.875, 0.5],
        parallax: [1.0, 0.0],
    };
    assert_eq!(clamp.intersect(&ray), None);
    let hit = repeat.intersect(&ray).unwrap();
    assert_eq!(
        hit,
        Hit {
            uv: [1.625, 0.5],
            height: 0.25
        }
    );
    // An entry outside the decal is a miss in clamp mode only.
    let outside = Ray {
        uv0: [1.2, 0.5],
        parallax: [0.0, 0.0],
    };
    assert_eq!(clamp.intersect(&outside), None);
    assert!(repeat.intersect(&outside).is_some());
    // A hit exactly on the border counts.
    let border = Ray {
        uv0: [0.25, 0.5],
        parallax: [1.0, 0.0],
    };
    assert_eq!(
        clamp.intersect(&border),
        Some(Hit {
            uv: [1.0, 0.5],
            height: 0.25
        })
    );
}

#[test]
fn agrees_with_brute_force_on_random_maps() {
    let mut rng = Rng(42);
    for (w, h) in [(7u32, 5u32), (16, 16), (1, 3), (1, 1)] {
        let field = random_field(w, h, 0.0, 1.0, &mut rng);
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let reference = Reference::new(&field, addressing);
            let mut hits = 0;
            for k in 0..150 {
                let scale = [0.05, 0.5, 3.0][k % 3];
                let ray = Ray {
                    uv0: [rng.range(0.0, 1.0), rng.range(0.0, 1.0)],
                    parallax: [rng.range(-scale, scale), rng.range(-scale, scale)],
                };
                let exact = reference.intersect(&ray);
                let brute = brute_force(&field, addressing, &ray);
                match (exact, brute) {
                    (Some(hit), Some(t)) => {
                        hits += 1;
                        assert_hit(Some(hit), &ray, t, 1e-9);
                        let surface = bilinear(&field, addressing, hit.uv);
                        assert!((surface - hit.height).abs() < 1e-9 || t == 0.0);
                    }
                    (None, None) => {}
                    other => panic!("{w}x{h} {addressing:?} {ray:?}: {other:?}"),
                }
            }
            assert!(hits > 30, "{w}x{h} {addressing:?}: only {hits} hits");
        }
    }
}

#[test]
fn grazing_rays_stay_finite() {
    let mut rng = Rng(3);
    let field = random_field(16, 16, 0.0, 0.9, &mut rng);
    // Mostly flat at 0 with a single spike: the ray descends through many tiles.
    let mut spike = vec![0.0f32; 256];
    spike[5 * 16 + 9] = 0.9;
    let spike = HeightField::from_heights(16, 16, spike, "spike").unwrap();
    for field in [field, spike] {
        let reference = Reference::new(&field, Addressing::Repeat);
        for parallax in [[8e3, 6e3], [-1e4, 0.0], [0.0, 1e4], [-7071.0, -7071.0]] {
            let ray = Ray {
                uv0: [0.25, 0.75],
                parallax,
            };
            let hit = reference.intersect(&ray).unwrap();
            assert!(hit.height.is_finite() && hit.uv.iter().all(|u| u.is_finite()));
            assert!((0.0..=0.9).contains(&hit.height), "{hit:?}");
            // The hit lies on the surface (or at the very bottom).
            let surface = bilinear(&field, Addressing::Repeat, hit.uv);
            assert!(surface >= hit.height - 1e-6, "{hit:?} below {surface}");
        }
        let clamp = Reference::new(&field, Addressing::Clamp);
        let ray = Ray {
            uv0: [0.5, 0.5],
            parallax: [1e4, 3.0],
        };
        assert_eq!(clamp.intersect(&ray), None);
    }
}

#[test]
fn non_finite_rays_are_rejected() {
    let field = HeightField::from_heights(2, 2, vec![0.5; 4], "flat").unwrap();
    let reference = Reference::new(&field, Addressing::Repeat);
    for ray in [
        Ray {
            uv0: [f64::NAN, 0.0],
            parallax: [0.0, 0.0],
        },
        Ray {
            uv0: [0.0, 0.0],
            parallax: [f64::INFINITY, 0.0],
        },
        Ray {
            uv0: [0.0, 0.0],
            parallax: [1e300, 0.0],
        },
    ] {
        assert_eq!(reference.intersect(&ray), None);
    }
    let traced = reference.trace(&[
        None,
        Some(Ray {
            uv0: [0.5, 0.5],
            parallax: [0.0, 0.0],
        }),
    ]);
    assert_eq!(traced[0], None);
    assert!((traced[1].unwrap().height - 0.5).abs() < 1e-12);
}

/// Unit light direction (towards the light) from `(x, y, z)`.
fn light(x: f64, y: f64, z: f64) -> [f64; 3] {
    let n = (x * x + y * y + z * z).sqrt();
    [x / n, y / n, z / n]
}

#[test]
fn a_flat_map_never_shadows_itself() {
    let mut rng = Rng(11);
    let field = HeightField::from_heights(8, 8, vec![0.4; 64], "flat").unwrap();
    for addressing in [Addressing::Repeat, Addressing::Clamp] {
        let reference = Reference::new(&field, addressing);
        for _ in 0..300 {
            let uv = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
            let l = light(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(1e-3, 1.0),
            );
            assert!(!reference.occluded(uv, 0.4, l, 0.1), "{uv:?} {l:?}");
            // The macro surface facing away from the light: shadowed.
            assert!(reference.occluded(uv, 0.4, [l[0], l[1], -l[2]], 0.1));
        }
        assert!(reference.occluded([0.5, 0.5], 0.4, [1.0, 0.0, 0.0], 0.1));
    }
}

/// Left half 0.25, right half 0.75 (16 x 2): the wall rises between the texel
/// centres x = 7 and x = 8.
fn wall() -> HeightField {
    let values = (0..32)
        .map(|k| if k % 16 < 8 { 0.25 } else { 0.75 })
        .collect();
    HeightField::from_heights(16, 2, values, "wall").unwrap()
}

#[test]
fn a_wall_shadows_the_side_behind_it_only() {
    // Light towards +x with L.z / L.x = 0.2 and depth 0.1: the climb is 0.5 uv =
    // 8 texels per unit height. From (x_p, 0.25) the ray reaches 0.75 at x_p + 4, so
    // it is blocked by the wall exactly when x_p > 4 (x_p = 4 grazes its top edge).
    let field = wall();
    let towards_wall = light(1.0, 0.0, 0.2);
    let away = light(-1.0, 0.0, 0.2);
    for addressing in [Addressing::Repeat, Addressing::Clamp] {
        let reference = Reference::new(&field, addressing);
        let uv = |x: f64| [(x + 0.5) / 16.0, 0.5];
        for x in [1.0, 2.0, 3.0, 3.9] {
            assert!(
                !reference.occluded(uv(x), 0.25, towards_wall, 0.1),
                "{addressing:?} x = {x} is lit over the wall"
            );
        }
        for x in [4.1, 5.0, 6.0, 6.9] {
            assert!(
                reference.occluded(uv(x), 0.25, towards_wall, 0.1),
                "{addressing:?} x = {x} is behind the wall"
            );
        }
        // The top plateau is lit from both sides.
        for x in [8.5, 10.0, 14.0] {
            assert!(!reference.occluded(uv(x), 0.75, towards_wall, 0.1));
            assert!(!reference.occluded(uv(x), 0.75, away, 0.1));
        }
    }
    // Light from the other side over the low plateau (clamp: no wrap to the wall
    // of the next tile): lit; the wall's face towards the light: lit.
    let clamp = Reference::new(&field, Addressing::Clamp);
    for x in [1.0, 4.0, 6.9] {
        assert!(!clamp.occluded([(x + 0.5) / 16.0, 0.5], 0.25, away, 0.1));
    }
    let face = 0.25 + 0.5 * 0.5; // x = 7.5, on the wall
    assert!(!clamp.occluded([8.0 / 16.0, 0.5], face, away, 0.1));
    // Its back, seen from the light on the +x side: in its own shadow.
    assert!(clamp.occluded([8.0 / 16.0, 0.5], face, towards_wall, 0.1));
}

#[test]
fn a_clamp_light_ray_enters_the_decal_from_outside() {
    // A low light: the ray reaches h = 1 far beyond the decal (u + 0.75 * 2 > 1); the
    // part inside the decal still meets the wall.
    let reference = Reference::new(&wall(), Addressing::Clamp);
    let low = light(1.0, 0.0, 0.05);
    for x in [2.0, 5.0] {
        let uv = [(x + 0.5) / 16.0, 0.5];
        assert!(reference.occluded(uv, 0.25, low, 0.1), "x = {x}");
    }
    // The top plateau: its ray leaves the decal without meeting anything.
    assert!(!reference.occluded([0.75, 0.5], 0.75, low, 0.1));
}

/// Brute force: dense samples of the light ray from `h + SHADOW_BIAS` to 1 (clamp:
/// inside the decal). Returns the largest `H - h_ray` seen.
fn brute_occlusion(
    field: &HeightField,
    addressing: Addressing,
    uv: [f64; 2],
    h: f64,
    climb: [f64; 2],
) -> f64 {
    let n = 20_000;
    let start = h + SHADOW_BIAS;
    let mut worst = f64::NEG_INFINITY;
    for k in 0..=n {
        let hr = start + (1.0 - start) * f64::from(k) / f64::from(n);
        let p = [uv[0] + (hr - h) * climb[0], uv[1] + (hr - h) * climb[1]];
        if addressing == Addressing::Clamp && p.iter().any(|u| !(0.0..=1.0).contains(u)) {
            continue;
        }
        worst = worst.max(bilinear(field, addressing, p) - hr);
    }
    worst
}

#[test]
fn occlusion_agrees_with_brute_force_on_random_maps() {
    let mut rng = Rng(5);
    for (w, h) in [(9u32, 7u32), (16, 16)] {
        let field = random_field(w, h, 0.0, 1.0, &mut rng);
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let reference = Reference::new(&field, addressing);
            let (mut shadowed, mut lit) = (0, 0);
            for _ in 0..300 {
                let uv = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
                let height = bilinear(&field, addressing, uv);
                let l = light(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(0.05, 1.0),
                );
                let depth = [0.05, 0.1, 0.3][rng.next() as usize % 3];
                let climb = [depth * l[0] / l[2], depth * l[1] / l[2]];
                let worst = brute_occlusion(&field, addressing, uv, height, climb);
                if worst.abs() < 1e-4 {
                    continue; // a graze: the sampling cannot decide it
                }
                let exact = reference.occluded(uv, height, l, depth);
                assert_eq!(
                    exact,
                    worst > 0.0,
                    "{w}x{h} {addressing:?} uv {uv:?} h {height} L {l:?}: brute {worst}"
                );
                if exact {
                    shadowed += 1;
                } else {
                    lit += 1;
                }
            }
            assert!(shadowed > 30 && lit > 30, "{shadowed} shadowed, {lit} lit");
        }
    }
}

#[test]
fn first_root_handles_degenerate_quadratics() {
    // Linear: s + c.
    assert_eq!(first_root(0.0, 1.0, -0.25, 1.0), Some(0.25));
    // Constant below zero: never.
    assert_eq!(first_root(0.0, 0.0, -0.25, 1.0), None);
    // Already above.
    assert_eq!(first_root(1.0, -5.0, 0.0, 1.0), Some(0.0));
    // Concave, touching later: -(s - 0.5)^2 + 0.01 -> roots 0.4, 0.6.
    let s = first_root(-1.0, 1.0, -0.24, 1.0).unwrap();
    assert!((s - 0.4).abs() < 1e-12, "{s}");
    // Convex, first falling then rising through zero at the larger root.
    let s = first_root(1.0, -0.9, 0.14 - 0.2, 1.0).unwrap();
    let expected = (0.9 + (0.81f64 - 4.0 * (0.14 - 0.2)).sqrt()) / 2.0;
    assert!((s - expected).abs() < 1e-12, "{s} vs {expected}");
    // Root beyond the interval.
    assert_eq!(first_root(0.0, 1.0, -2.0, 1.0), None);
}
