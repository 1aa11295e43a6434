//! The cone maps of the cone-stepping methods (`src/passes/cone.rs`) against a brute-force
//! CPU generator: on small maps (a one-texel spike, a step edge, odd and degenerate sizes,
//! both addressings) no GPU cone is wider than the cone the brute force measures on a
//! dense sampling of the bilinear surface (which is itself at least as wide as the true
//! cone), and each test prints how much narrower the GPU cones are. The relaxed map the
//! same against the brute force of its own rule (only cells that are not monotone outward
//! bound it), never narrower than the conservative map; and along sampled rays a relaxed
//! step crosses the surface at most once, a conservative step never.

mod common;

use common::{finish, validated_context};
use dispmap::heightfield::{Addressing, HeightField};
use dispmap::method::{ConeKind, Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::passes::cone::CONE_RATIO_MAX;
use dispmap::passes::pyramid::{PyramidKind, cpu_build};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Geometry, Scene};

/// Samples per texel along each axis of the brute force (texel corners and edges
/// included: the bilinear maximum of a cell is at a corner).
const SAMPLES: i64 = 8;

/// Texel `(i, j)` of `field` with `addressing`, in f64.
fn texel_at(field: &HeightField, addressing: Addressing, i: i64, j: i64) -> f64 {
    let (w, h) = (i64::from(field.width()), i64::from(field.height()));
    let (i, j) = match addressing {
        Addressing::Repeat => (i.rem_euclid(w), j.rem_euclid(h)),
        Addressing::Clamp => (i.clamp(0, w - 1), j.clamp(0, h - 1)),
    };
    f64::from(field.texel(i as u32, j as u32))
}

/// Whether cell `(di, dj)` cells away from a cell (corners `a00`, `a10`, `a01`, `a11`,
/// x then y) is monotone outward: per axis non-decreasing away from the cell, constant
/// along the axis where the offset is 0 (the relaxed map's rule, `glsl/cone.comp`).
fn monotone_outward(di: i64, dj: i64, a: [f64; 4]) -> bool {
    let [a00, a10, a01, a11] = a;
    let x_ok = match di.signum() {
        1 => a00 <= a10 && a01 <= a11,
        -1 => a10 <= a00 && a11 <= a01,
        _ => a00 == a10 && a01 == a11,
    };
    let y_ok = match dj.signum() {
        1 => a00 <= a01 && a10 <= a11,
        -1 => a01 <= a00 && a11 <= a10,
        _ => a00 == a01 && a10 == a11,
    };
    x_ok && y_ok
}

/// The bilinear surface of `field` at texel-space point `(x, y)` (texel centres at
/// integers) with `addressing`, in f64.
fn surface(field: &HeightField, addressing: Addressing, x: f64, y: f64) -> f64 {
    let at = |i: i64, j: i64| texel_at(field, addressing, i, j);
    let (i, j) = (x.floor(), y.floor());
    let (fx, fy) = (x - i, y - j);
    let (i, j) = (i as i64, j as i64);
    let top = at(i, j) + (at(i + 1, j) - at(i, j)) * fx;
    let bottom = at(i, j + 1) + (at(i + 1, j + 1) - at(i, j + 1)) * fx;
    top + (bottom - top) * fy
}

/// The brute-force cone of cell `(ci, cj)` with maximum `m`: the smallest
/// `dist(q, cell) / (H(q) - m)` over the sampled surface points `q` above `m` (repeat:
/// the 3x3 tiles around the map; clamp: the decal), capped like the GPU's. Relaxed: only
/// the points of cells that are not monotone outward.
fn brute_cone(
    field: &HeightField,
    addressing: Addressing,
    kind: ConeKind,
    ci: i64,
    cj: i64,
    m: f64,
) -> f64 {
    let (w, h) = (i64::from(field.width()), i64::from(field.height()));
    let (x_range, y_range) = match addressing {
        // Texel-space [-W - 0.5, 2W - 0.5) etc. in steps of 1 / SAMPLES.
        Addressing::Repeat => (
            (-w * SAMPLES - SAMPLES / 2, 2 * w * SAMPLES - SAMPLES / 2),
            (-h * SAMPLES - SAMPLES / 2, 2 * h * SAMPLES - SAMPLES / 2),
        ),
        Addressing::Clamp => (
            (-SAMPLES / 2, w * SAMPLES - SAMPLES / 2),
            (-SAMPLES / 2, h * SAMPLES - SAMPLES / 2),
        ),
    };
    let mut best = f64::from(CONE_RATIO_MAX);
    for sy in y_range.0..=y_range.1 {
        let y = sy as f64 / SAMPLES as f64;
        let dy = (cj as f64 - y).max(y - (cj + 1) as f64).max(0.0);
        for sx in x_range.0..=x_range.1 {
            let x = sx as f64 / SAMPLES as f64;
            let rise = surface(field, addressing, x, y) - m;
            if rise <= 0.0 {
                continue;
            }
            if kind == ConeKind::Relaxed {
                let (di, dj) = (x.floor() as i64, y.floor() as i64);
                let corners = [
                    texel_at(field, addressing, di, dj),
                    texel_at(field, addressing, di + 1, dj),
                    texel_at(field, addressing, di, dj + 1),
                    texel_at(field, addressing, di + 1, dj + 1),
                ];
                if (di, dj) != (ci, cj) && monotone_outward(di - ci, dj - cj, corners) {
                    continue;
                }
            }
            let dx = (ci as f64 - x).max(x - (ci + 1) as f64).max(0.0);
            best = best.min(dx.hypot(dy) / rise);
        }
    }
    best
}

/// The method that builds a `kind` cone map.
fn method_of(kind: ConeKind) -> Method {
    match kind {
        ConeKind::Conservative => Method::Cone,
        ConeKind::Relaxed => Method::RelaxedCone,
    }
}

/// The GPU cone map of `field` with `addressing` built by a `method` renderer (as the
/// methods build it: lazily, once, timed as `cone`).
fn gpu_cone_map(
    ctx: &std::sync::Arc<dispmap::context::Context>,
    field: &HeightField,
    addressing: Addressing,
    method: Method,
) -> Vec<[f32; 2]> {
    let geometry = match addressing {
        Addressing::Repeat => Geometry::TiledPlane,
        Addressing::Clamp => Geometry::Quad,
    };
    let settings = RenderSettings {
        shadows: Default::default(),
        width: 16,
        height: 16,
        method,
        params: MethodParams::for_method(method),
        scene: Scene {
            geometry,
            ..Scene::default()
        },
    };
    let mut renderer = Renderer::new(ctx, field, settings).unwrap();
    assert!(renderer.read_cone_map().unwrap().is_none(), "built lazily");
    let times = renderer.render().unwrap();
    assert!(
        times.iter().any(|(n, _)| *n == PassName::Cone),
        "timed as `cone`"
    );
    let gpu = renderer.read_cone_map().unwrap().expect("built");
    // Built once: the next frame neither runs nor times it.
    let times = renderer.render().unwrap();
    assert!(times.iter().all(|(n, _)| *n != PassName::Cone));
    gpu
}

/// Builds the GPU cone map of `field` of `kind` with `addressing` and compares it with
/// the brute force; returns the mean ratio GPU / brute force over the cells whose
/// brute-force cone is finite (below the cap). A relaxed map is also compared with the
/// conservative one: never narrower.
fn check_map(
    ctx: &std::sync::Arc<dispmap::context::Context>,
    field: &HeightField,
    addressing: Addressing,
    kind: ConeKind,
) -> f64 {
    let mut gpu = gpu_cone_map(ctx, field, addressing, method_of(kind));
    if kind == ConeKind::Relaxed {
        // Stored negated exactly where wider than the conservative cone (the trace tests
        // the surface there only).
        let conservative = gpu_cone_map(ctx, field, addressing, Method::Cone);
        for (k, (r, c)) in gpu.iter_mut().zip(&conservative).enumerate() {
            let wider = r[1].abs() > c[1];
            assert!(
                r[0] == c[0] && r[1].abs() >= c[1] && (r[1] < 0.0) == wider,
                "{} {addressing:?} cell {k}: relaxed {r:?} against conservative {c:?}",
                field.label()
            );
            r[1] = r[1].abs();
        }
    }

    let (w, h) = (field.width() as usize, field.height() as usize);
    assert_eq!(gpu.len(), w * h);
    let cells = &cpu_build(field, addressing, PyramidKind::Cell)[0];
    let (mut ratios, mut worst, mut capped) = (Vec::new(), (f64::INFINITY, 0, 0), 0);
    for j in 0..h {
        for i in 0..w {
            let [m, cone] = gpu[j * w + i];
            assert!(
                m.is_finite() && cone.is_finite() && cone >= 0.0,
                "cell ({i}, {j}): {m} {cone}"
            );
            assert_eq!(
                m,
                cells[j * w + i],
                "cell ({i}, {j}): the maximum is the cell pyramid's"
            );
            let brute = brute_cone(field, addressing, kind, i as i64, j as i64, f64::from(m));
            // f32 rounding of the GPU's bound: a relative 1e-5 (the trace shortens every
            // step by 1.5e-5, `CONE_SHRINK`).
            assert!(
                f64::from(cone) <= brute * (1.0 + 1e-5),
                "{} {addressing:?} {kind:?} cell ({i}, {j}): GPU cone {cone} wider than the brute force {brute}",
                field.label()
            );
            if brute < f64::from(CONE_RATIO_MAX) {
                let r = f64::from(cone) / brute;
                if r < worst.0 {
                    worst = (r, i, j);
                }
                ratios.push(r);
            } else {
                capped += 1;
            }
        }
    }
    let mean = if ratios.is_empty() {
        1.0
    } else {
        ratios.iter().sum::<f64>() / ratios.len() as f64
    };
    eprintln!(
        "{:<12} {:>3}x{:<3} {:<6?} {:<12?} GPU / brute-force cone: mean {:.3}, min {:.3} at ({}, {}); {} of {} cells unbounded (flat)",
        field.label(),
        w,
        h,
        addressing,
        kind,
        mean,
        if ratios.is_empty() { 1.0 } else { worst.0 },
        worst.1,
        worst.2,
        capped,
        w * h
    );
    mean
}

fn maps() -> Vec<HeightField> {
    let spike = {
        let mut values = vec![0.1f32; 121];
        values[5 * 11 + 5] = 0.9;
        HeightField::from_heights(11, 11, values, "spike").unwrap()
    };
    let step = HeightField::from_heights(
        12,
        6,
        (0..72)
            .map(|k| if k % 12 < 6 { 0.2 } else { 0.8 })
            .collect(),
        "step edge",
    )
    .unwrap();
    let slope = HeightField::from_fn(16, 3, "slope", |u, _| 0.1 + 0.8 * u).unwrap();
    let bumps = HeightField::from_fn(23, 13, "bumps", |u, v| {
        0.5 + 0.45 * (u * 19.0).sin() * (v * 11.0 + u * 5.0).cos()
    })
    .unwrap();
    let one = HeightField::from_heights(1, 1, vec![0.4], "1x1").unwrap();
    let row =
        HeightField::from_heights(7, 1, vec![0.1, 0.9, 0.3, 0.3, 0.5, 0.0, 1.0], "7x1").unwrap();
    let column = HeightField::from_heights(1, 5, vec![0.2, 0.7, 0.1, 0.0, 0.6], "1x5").unwrap();
    vec![spike, step, slope, bumps, one, row, column]
}

/// Conservative on every map and both addressings: no GPU cone wider than the brute
/// force's (the mean ratio GPU / brute force, at most 1, is printed; how tight the cones
/// are is not asserted).
#[test]
fn gpu_cones_are_never_wider_than_the_brute_force() {
    let ctx = validated_context();
    for field in maps() {
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let mean = check_map(&ctx, &field, addressing, ConeKind::Conservative);
            assert!(mean > 0.0 && mean <= 1.0 + 1e-5);
        }
    }
    finish(ctx);
}

/// The relaxed map: never wider than the brute force of its rule, never narrower than the
/// conservative map, on the same maps.
#[test]
fn gpu_relaxed_cones_are_never_wider_than_the_brute_force() {
    let ctx = validated_context();
    for field in maps() {
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            let mean = check_map(&ctx, &field, addressing, ConeKind::Relaxed);
            assert!(mean > 0.0 && mean <= 1.0 + 1e-5);
        }
    }
    finish(ctx);
}

/// What the traces rely on, along rays: from points over each cell above its maximum, in
/// 16 directions at 3 slopes, a step to the cone's boundary (the trace's step) never goes
/// under the surface with the conservative map, and with the relaxed map once under it
/// stays under (one crossing at most: the height at the step's end decides). The surface
/// is sampled 512 times along each step, in f64.
#[test]
fn cone_steps_cross_the_surface_as_their_map_promises() {
    let ctx = validated_context();
    let maps = maps();
    let mut checked = 0usize;
    for field in maps.iter().filter(|f| f.width() > 1 && f.height() > 1) {
        for addressing in [Addressing::Repeat, Addressing::Clamp] {
            for kind in [ConeKind::Conservative, ConeKind::Relaxed] {
                let cones = gpu_cone_map(&ctx, field, addressing, method_of(kind));
                let (w, h) = (field.width() as i64, field.height() as i64);
                // Clamp: the decal only (a ray leaving it ends there).
                let inside = |x: f64, y: f64| {
                    addressing == Addressing::Repeat
                        || ((-0.5..=w as f64 - 0.5).contains(&x)
                            && (-0.5..=h as f64 - 0.5).contains(&y))
                };
                for cj in 0..h {
                    for ci in 0..w {
                        let [m, cone] = cones[(cj * w + ci) as usize];
                        let (m, cone) = (f64::from(m), f64::from(cone.abs()));
                        for start in [0.1, 0.3, 0.7] {
                            let h0 = m + start * (1.0 - m);
                            if h0 - m < 1e-3 {
                                continue;
                            }
                            for a in 0..16 {
                                let phi = a as f64 * std::f64::consts::TAU / 16.0 + 0.1;
                                for speed in [0.5, 3.0, 20.0] {
                                    let (dx, dy) = (speed * phi.cos(), speed * phi.sin());
                                    // The trace's step (t = depth), at most to h = 0.
                                    let s = (cone * (h0 - m) / (cone + speed)).min(h0);
                                    for (fx, fy) in [(0.1, 0.1), (0.5, 0.5), (0.9, 0.3)] {
                                        let (x0, y0) = (ci as f64 + fx, cj as f64 + fy);
                                        if !inside(x0, y0) {
                                            continue;
                                        }
                                        let mut under = false;
                                        for k in 0..=512 {
                                            let t = s * k as f64 / 512.0;
                                            if !inside(x0 + t * dx, y0 + t * dy) {
                                                break;
                                            }
                                            let gap = surface(
                                                field,
                                                addressing,
                                                x0 + t * dx,
                                                y0 + t * dy,
                                            ) - (h0 - t);
                                            match kind {
                                                ConeKind::Conservative => assert!(
                                                    gap < 1e-6,
                                                    "{} {addressing:?} cell ({ci}, {cj}): a conservative step meets the surface",
                                                    field.label()
                                                ),
                                                ConeKind::Relaxed => {
                                                    assert!(
                                                        !under || gap > -1e-6,
                                                        "{} {addressing:?} cell ({ci}, {cj}) from ({x0}, {y0}, {h0}) dir ({dx}, {dy}): a relaxed step leaves the surface again",
                                                        field.label()
                                                    );
                                                    under |= gap >= 0.0;
                                                }
                                            }
                                        }
                                        checked += 1;
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    eprintln!("{checked} steps checked");
    assert!(checked > 10_000);
    finish(ctx);
}

/// Thin walls (one texel of height 1 every 8 texels, both axes, on a floor at 0: each
/// wall a ridge two texels wide at its foot) seen across at low elevations: a cone step
/// ends on its cone's boundary, so a step that went any further (a cone ratio or step
/// scaled up) jumps over a wall whole and hits a later one. The traces of `cone`,
/// `relaxed-cone` and `cone-exact` match the exact reference there (the band's samples at
/// 256 steps are a quarter texel apart, so the marcher's own thin-feature error stays
/// out of the measurement); the bound, 0.5% of the covered pixels, is what a skim of the
/// ridge tips may cost (measured: see the printed table).
#[test]
fn cone_steps_never_jump_over_a_thin_wall() {
    use dispmap_cli::measure::Measure as _;
    use dispmap_cli::reference::Reference;
    let ctx = validated_context();
    let n = 64u32;
    let walls = HeightField::from_heights(
        n,
        n,
        (0..n * n)
            .map(|k| {
                if k % n % 8 == 3 || k / n % 8 == 3 {
                    1.0
                } else {
                    0.0
                }
            })
            .collect(),
        "thin walls",
    )
    .unwrap();
    let reference = Reference::new(&walls, Addressing::Repeat);
    for elevation in [8.0f32, 20.0] {
        for method in [Method::Cone, Method::RelaxedCone, Method::ConeExact] {
            let settings = RenderSettings {
                shadows: Default::default(),
                width: 128,
                height: 72,
                method,
                params: MethodParams {
                    steps: 256,
                    ..MethodParams::for_method(method)
                },
                scene: Scene {
                    geometry: Geometry::TiledPlane,
                    depth_scale: 0.05,
                    camera: dispmap::scene::Camera {
                        elevation_deg: elevation,
                        azimuth_deg: 20.0,
                        ..Default::default()
                    },
                    ..Scene::default()
                },
            };
            let mut renderer = Renderer::new(&ctx, &walls, settings).unwrap();
            let frame_ref = renderer.reference(&reference).unwrap();
            let m = renderer.measure(&frame_ref, 1).unwrap();
            eprintln!(
                "thin walls {elevation:>4} deg {:<12} artifacts {:.3}% of {} pixels, p99 {:.3} texels",
                method.name(),
                100.0 * m.error.artifact_fraction,
                m.error.compared_pixels,
                m.error.p99_texels
            );
            assert_eq!(m.error.nonfinite_pixels, 0);
            assert!(
                m.error.compared_pixels > 4000,
                "{}",
                m.error.compared_pixels
            );
            assert!(
                m.error.artifact_fraction <= 0.005,
                "{} at {elevation} deg: {:.3}% artifacts on thin walls",
                method.name(),
                100.0 * m.error.artifact_fraction
            );
        }
    }
    finish(ctx);
}
