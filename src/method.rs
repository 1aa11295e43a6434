//! The intersection methods and what each one is: its name, shader, loop bound, what it
//! needs built and which parameters it reads (the parameters themselves and their limits
//! are in `method/params.rs`).
//!
//! Adding a method: write `glsl/trace/<name>.comp` (include `trace.glsl`, define
//! `Hit trace_ray(Ray ray)`), add a variant here with its name and shader, and, if it
//! needs a pre-pass (a pyramid, a corner grid), say so in [`Method::needs`] and add the
//! pass under `src/passes/`.

use crate::error::{Error, Result};
use crate::shaders::{self, Shader};

pub use crate::context::LOOP_LIMIT;

mod params;
pub use params::{
    CONE_BUDGET, MAX_BLOCK, MAX_LOD_THRESHOLD, MAX_SEGMENTS, MAX_STEPS, MaxLevel, MethodParams,
    TRAVERSAL_CAP,
};

/// An intersection method (CLI `--method` names in [`Method::name`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Method {
    /// One fetch at the entry point: the cost floor (plain bump mapping).
    Bump,
    /// Fixed-step linear march with early exit (steep parallax mapping).
    Linear,
    /// Linear march then binary search (relief mapping).
    Relief,
    /// Parallax occlusion mapping (Tatarchuk 2006): view-dependent step count,
    /// piecewise-linear intersection of the last two samples.
    Pom,
    /// Ray casting with secant refinement (Yerex & Jagersand 2004), optionally in
    /// `segments` passes.
    Secant,
    /// Depth interval grid (Judnich & Ling): corner pass, then a constrained march.
    Dig,
    /// DIG made exact by the cell pyramid: the traversal clears the ray before the
    /// interval, then continues from the interval's top (beyond the papers).
    DigGuarded,
    /// Pyramidal displacement mapping (Oh, Ki & Lee 2006).
    Pyramid,
    /// Conservative cell-max pyramid traversal with the exact ray/bilinear-patch
    /// intersection in the leaf (beyond the papers; after Tevs et al. 2008).
    Exact,
    /// Robust cone step mapping (Dummer 2006; Bán, Valasek, Bálint & Vad 2024): cone
    /// steps over the conservative cone map of the bilinear surface with the robust
    /// minimum step, a sampled band below each cell's maximum, then a binary search.
    Cone,
    /// Robust cone steps until the ray may meet its cell's bilinear patch, then `exact`'s
    /// ray/patch solve (beyond the papers).
    ConeExact,
    /// Relaxed cone stepping (Policarpo & Oliveira 2007) over a relaxed cone map of the
    /// bilinear surface generated with Bán et al.'s falling-edge correction: a step may
    /// end inside the surface, having crossed it at most once; the height at its end
    /// tells, then a binary search over the step.
    RelaxedCone,
}

/// Which cone map a cone method steps over (see [`crate::passes::cone`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ConeKind {
    /// No surface point rises into the cone (`cone`, `cone-exact`).
    Conservative,
    /// The surface may rise into the cone only where a ray stepping through it crosses
    /// the surface at most once (`relaxed-cone`).
    Relaxed,
}

/// What the finest level of a max-height pyramid bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PyramidKind {
    /// Level 0 texel `(i, j)` bounds the bilinear surface over the texel's footprint
    /// `[i, i + 1] x [j, j + 1] / size` (the quadtree of Oh et al., made conservative
    /// for the bilinear surface).
    Footprint,
    /// Level 0 texel `(i, j)` bounds the bilinear *cell* between texel centres `(i, j)`
    /// and `(i + 1, j + 1)`: the max of its 4 corner texels (exact traversal).
    Cell,
    /// Level 0 texel `(i, j)` is the max of cell `(i, j)`'s 4 corner texels where the
    /// cell's bilinear patch *falls* along the quadrant direction (x: `+1`, or `-1` with
    /// `neg_x`; y likewise: some edge decreases along x or y going that way), else 0. The
    /// relaxed cone map's bound beyond its window ([`crate::passes::cone`]); built for
    /// its generation only.
    Falls {
        /// The quadrant's x direction is `-1`.
        neg_x: bool,
        /// The quadrant's y direction is `-1`.
        neg_y: bool,
    },
}

impl PyramidKind {
    /// The four [`PyramidKind::Falls`] quadrants, `(+x, +y)`, `(-x, +y)`, `(+x, -y)`,
    /// `(-x, -y)` (the order of the relaxed cone generation's bindings).
    pub const FALLS: [PyramidKind; 4] = [
        PyramidKind::Falls {
            neg_x: false,
            neg_y: false,
        },
        PyramidKind::Falls {
            neg_x: true,
            neg_y: false,
        },
        PyramidKind::Falls {
            neg_x: false,
            neg_y: true,
        },
        PyramidKind::Falls {
            neg_x: true,
            neg_y: true,
        },
    ];
}

/// Which of [`MethodParams`]' quality parameters a method reads ([`Method::reads`];
/// docs/methods.md's table). `lod_threshold` applies to every method and is not listed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reads {
    /// [`MethodParams::steps`] (a setting the benchmark sweeps).
    pub steps: bool,
    /// [`MethodParams::refine_steps`].
    pub refine_steps: bool,
    /// [`MethodParams::min_steps`].
    pub min_steps: bool,
    /// [`MethodParams::segments`].
    pub segments: bool,
    /// [`MethodParams::block`] and [`MethodParams::eps`] (DIG's corner grid).
    pub block: bool,
    /// [`MethodParams::max_level`].
    pub max_level: bool,
}

/// Pre-passes and resources a method needs beyond the G-buffer and the height map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    /// The max-height pyramid (min-reduce chain) and what its finest level bounds.
    pub pyramid: Option<PyramidKind>,
    /// The DIG corner grid (`dig_corners` pass).
    pub dig_corners: bool,
    /// The cone map (`cone` pass, built from the cell pyramid) and its kind.
    pub cone: Option<ConeKind>,
}

impl Method {
    /// Every method, in report order (cheapest first, then the papers, then beyond).
    pub const ALL: &'static [Method] = &[
        Method::Bump,
        Method::Linear,
        Method::Relief,
        Method::Pom,
        Method::Secant,
        Method::Dig,
        Method::DigGuarded,
        Method::Pyramid,
        Method::Exact,
        Method::Cone,
        Method::ConeExact,
        Method::RelaxedCone,
    ];

    /// CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Bump => "bump",
            Method::Linear => "linear",
            Method::Relief => "relief",
            Method::Pom => "pom",
            Method::Secant => "secant",
            Method::Dig => "dig",
            Method::DigGuarded => "dig-guarded",
            Method::Pyramid => "pyramid",
            Method::Exact => "exact",
            Method::Cone => "cone",
            Method::ConeExact => "cone-exact",
            Method::RelaxedCone => "relaxed-cone",
        }
    }

    /// The paper (or family) the method follows.
    pub fn paper(self) -> &'static str {
        match self {
            Method::Bump => "bump mapping (cost floor)",
            Method::Linear => "steep parallax mapping (McGuire & McGuire 2005)",
            Method::Relief => "relief mapping (Policarpo, Oliveira & Comba 2005)",
            Method::Pom => "parallax occlusion mapping (Tatarchuk 2006)",
            Method::Secant => "displacement ray casting (Yerex & Jagersand 2004)",
            Method::Dig => "depth interval grids (Judnich & Ling)",
            Method::DigGuarded => "depth interval grids + pyramid guard (beyond the papers)",
            Method::Pyramid => "pyramidal displacement mapping (Oh, Ki & Lee 2006)",
            Method::Exact => "maximum-mipmap traversal + exact bilinear patch (beyond the papers)",
            Method::Cone => "robust cone step mapping (Dummer 2006; Bán et al. 2024)",
            Method::ConeExact => "robust cone steps + exact bilinear patch (beyond the papers)",
            Method::RelaxedCone => {
                "relaxed cone stepping (Policarpo & Oliveira 2007; Bán et al. 2024)"
            }
        }
    }

    /// The compute shader of the method's trace pass.
    pub fn shader(self) -> Shader {
        match self {
            Method::Bump => shaders::TRACE_BUMP_COMP,
            Method::Linear => shaders::TRACE_LINEAR_COMP,
            Method::Relief => shaders::TRACE_RELIEF_COMP,
            Method::Pom => shaders::TRACE_POM_COMP,
            Method::Secant => shaders::TRACE_SECANT_COMP,
            Method::Dig => shaders::TRACE_DIG_COMP,
            Method::DigGuarded => shaders::TRACE_DIG_GUARDED_COMP,
            Method::Pyramid => shaders::TRACE_PYRAMID_COMP,
            Method::Exact => shaders::TRACE_EXACT_COMP,
            Method::Cone => shaders::TRACE_CONE_COMP,
            Method::ConeExact => shaders::TRACE_CONE_EXACT_COMP,
            Method::RelaxedCone => shaders::TRACE_CONE_COMP_RELAXED,
        }
    }

    /// The method's trace shader in its `ITERATIONS` variant: [`Method::shader`] that
    /// also writes each pixel's iteration count.
    pub fn iterations_shader(self) -> Shader {
        match self {
            Method::Bump => shaders::TRACE_BUMP_COMP_ITERATIONS,
            Method::Linear => shaders::TRACE_LINEAR_COMP_ITERATIONS,
            Method::Relief => shaders::TRACE_RELIEF_COMP_ITERATIONS,
            Method::Pom => shaders::TRACE_POM_COMP_ITERATIONS,
            Method::Secant => shaders::TRACE_SECANT_COMP_ITERATIONS,
            Method::Dig => shaders::TRACE_DIG_COMP_ITERATIONS,
            Method::DigGuarded => shaders::TRACE_DIG_GUARDED_COMP_ITERATIONS,
            Method::Pyramid => shaders::TRACE_PYRAMID_COMP_ITERATIONS,
            Method::Exact => shaders::TRACE_EXACT_COMP_ITERATIONS,
            Method::Cone => shaders::TRACE_CONE_COMP_ITERATIONS,
            Method::ConeExact => shaders::TRACE_CONE_EXACT_COMP_ITERATIONS,
            Method::RelaxedCone => shaders::TRACE_CONE_COMP_RELAXED_ITERATIONS,
        }
    }

    /// The fragment shader of the method's forward path ([`crate::passes::forward`]: the
    /// march inside the G-buffer pass, as engines run relief mapping and POM): `relief`
    /// and `pom`; `None` for the others.
    pub fn forward_shader(self) -> Option<Shader> {
        match self {
            Method::Relief => Some(shaders::FORWARD_RELIEF_FRAG),
            Method::Pom => Some(shaders::FORWARD_POM_FRAG),
            _ => None,
        }
    }

    /// Whether the method is of the exact family: it keeps the exact reference's first hit,
    /// up to rays that skim the surface within f32 precision (`exact`, `dig-guarded`,
    /// `cone-exact`; docs/methods.md).
    pub fn is_exact(self) -> bool {
        matches!(self, Method::Exact | Method::DigGuarded | Method::ConeExact)
    }

    /// The method's trace shader in its `CURVED` variant (with `iterations`, its
    /// `CURVED+ITERATIONS` one): the curved path of `glsl/common/curved.glsl`, which
    /// reads the G-buffer's curve image; `None` for a method without one.
    pub fn curved_shader(self, iterations: bool) -> Option<Shader> {
        Some(match (self, iterations) {
            (Method::Exact, false) => shaders::TRACE_EXACT_COMP_CURVED,
            (Method::Exact, true) => shaders::TRACE_EXACT_COMP_CURVED_ITERATIONS,
            (Method::Relief, false) => shaders::TRACE_RELIEF_COMP_CURVED,
            (Method::Relief, true) => shaders::TRACE_RELIEF_COMP_CURVED_ITERATIONS,
            (Method::Pom, false) => shaders::TRACE_POM_COMP_CURVED,
            (Method::Pom, true) => shaders::TRACE_POM_COMP_CURVED_ITERATIONS,
            _ => return None,
        })
    }

    /// Whether the method traces curved macro geometry when the pass is asked to
    /// (`glsl/common/curved.glsl`: each pixel's ray follows the curvature of its base
    /// surface and misses when it leaves the shell): the methods with a
    /// [`Method::curved_shader`] (`exact`, `relief` and `pom`). The others trace every
    /// pixel's tangent plane.
    pub fn traces_curved(self) -> bool {
        self.curved_shader(false).is_some()
    }

    /// The shader of the method's mesh walk (`glsl/common/walk.glsl`,
    /// [`crate::embed::DisplacementPass::set_curved_meshes`]), with the iteration output
    /// or without: the last of the three dispatches that replace the curved trace (after
    /// [`Method::walk_first_shader`] and [`Method::walk_triage_shader`]), which follows a
    /// listed pixel's ray through the shell of the mesh's own triangles (the circle model
    /// for a pixel on none of them). `exact` only, whose curved trace is then exact
    /// against the displaced mesh (each sample's foot solved on its triangle); `relief`
    /// and `pom` keep the per-pixel circle model, which costs a few multiply-adds a sample
    /// where the walk costs a solve.
    pub fn walk_shader(self, iterations: bool) -> Option<Shader> {
        Some(match (self, iterations) {
            (Method::Exact, false) => shaders::TRACE_EXACT_COMP_CURVED_WALK,
            (Method::Exact, true) => shaders::TRACE_EXACT_COMP_CURVED_WALK_ITERATIONS,
            _ => return None,
        })
    }

    /// The mesh walk's first trace ([`Method::walk_shader`]'s companion), with the
    /// iteration output or without: the method's flat trace over the material's tiles,
    /// which lists for the triage the pixels it cannot tell, from the walk buffer's flat
    /// regions, that its hit is the walk's.
    pub fn walk_first_shader(self, iterations: bool) -> Option<Shader> {
        self.walks_meshes().then_some(if iterations {
            shaders::TRACE_EXACT_COMP_WALK_FIRST_ITERATIONS
        } else {
            shaders::TRACE_EXACT_COMP_WALK_FIRST
        })
    }

    /// The mesh walk's triage ([`Method::walk_shader`]'s companion): over the pixels the
    /// first trace listed, lists those whose walk can differ from the first trace, the
    /// pixels the walk then runs on.
    pub fn walk_triage_shader(self) -> Option<Shader> {
        self.walks_meshes()
            .then_some(shaders::TRACE_EXACT_COMP_CURVED_WALK_TRIAGE)
    }

    /// The mesh walk's overlap step ([`Method::walk_shader`]'s companion): over the pixels
    /// the first trace found on a flat region whose path passes overlapping flat regions'
    /// shells (a cube's edges), those regions' relief along the path.
    pub fn walk_overlap_shader(self) -> Option<Shader> {
        self.walks_meshes()
            .then_some(shaders::TRACE_EXACT_COMP_CURVED_WALK_OVERLAP)
    }

    /// Whether the method's curved trace walks the mesh's own triangles where it is given
    /// them ([`Method::walk_shader`]).
    pub fn walks_meshes(self) -> bool {
        self.walk_shader(false).is_some()
    }

    /// Whether the method is in the default method lists: `dispmap bench`'s default
    /// `--methods` and map-size sweep, and the `demo`'s table. Every method stays
    /// available by name. `cone-exact` is out: it has `exact`'s accuracy at 1.2x to 3.7x
    /// `exact`'s time on every bundled map on lavapipe, and 0.98x (bricks) to 1.67x on an
    /// H100 (BENCHMARKS.md, docs/cones.md), so a default list would show a method nobody
    /// should pick.
    pub fn in_defaults(self) -> bool {
        !matches!(self, Method::ConeExact)
    }

    /// The methods of the default lists ([`Method::in_defaults`]), in [`Method::ALL`]'s
    /// order.
    pub fn defaults() -> Vec<Method> {
        Method::ALL
            .iter()
            .copied()
            .filter(|m| m.in_defaults())
            .collect()
    }

    /// The most loop iterations one invocation of the method's passes can run with
    /// `params`, when the parameters alone bound it: the trace pass per pixel and, for
    /// the DIG methods, the corner pass per corner (the larger). `None` for `bump` (no
    /// loop) and the traversal methods (`pyramid`, `exact`; `dig-guarded`'s traversal),
    /// whose traversal caps its own steps (`glsl/common/pyramid.glsl`, `TRAVERSAL_CAP`)
    /// below [`LOOP_LIMIT`]; `dig-guarded`'s corner pass is bounded like `dig`'s. The
    /// cone methods' march (cone steps, band samples, leaf tests) stops after
    /// [`CONE_BUDGET`] steps and hands over to the pyramid traversal ([`TRAVERSAL_CAP`]
    /// steps), declared here with `cone`'s bisection.
    ///
    /// DIG's march below its interval keeps the interval's step `len / I_L`, where the
    /// interval is at least `eps` long and `I_L <= 4 max(ceil(len steps), 1)`: the step
    /// is at least `min(1 / (8 steps), eps / 4)`, so reaching `h = 0` takes at most
    /// `max(8 steps, 4 / eps)` samples; `eps = 0` leaves it unbounded.
    pub fn loop_bound(self, params: &MethodParams) -> Option<u64> {
        let steps = u64::from(params.steps.max(1));
        let refine = u64::from(params.refine_steps);
        let march = steps + 1;
        match self {
            Method::Bump | Method::Pyramid | Method::Exact => None,
            // The march and its bands, the pyramid traversal after them, the bisection.
            Method::Cone | Method::RelaxedCone => Some(CONE_BUDGET + TRAVERSAL_CAP + refine),
            Method::ConeExact => Some(CONE_BUDGET + TRAVERSAL_CAP),
            Method::DigGuarded => Some(march),
            Method::Linear => Some(march),
            Method::Relief => Some(march + refine),
            Method::Pom => Some(steps.max(u64::from(params.min_steps)) + 1),
            Method::Secant => Some(u64::from(params.segments) * steps + u64::from(params.segments)),
            Method::Dig => {
                let eps = f64::from(params.dig_eps());
                let below = if eps > 0.0 {
                    (8 * steps).max((4.0 / eps).ceil() as u64)
                } else {
                    u64::MAX / 2
                };
                Some((below + 1).max(march) + refine)
            }
        }
    }

    /// Refuses `params` when [`Method::loop_bound`] exceeds `limit`, the loop
    /// iterations a device lets one invocation run ([`crate::context::DeviceInfo`]'s
    /// `loop_limit`): past it lavapipe ends the invocation silently, with a wrong hit.
    /// The error names the option to lower.
    pub fn check_loop_limit(self, params: &MethodParams, limit: u32) -> Result<()> {
        let Some(bound) = self.loop_bound(params) else {
            return Ok(());
        };
        if bound <= u64::from(limit) {
            return Ok(());
        }
        let (option, remedy) = match self {
            Method::Secant if params.segments > 1 => {
                ("steps and segments", "lower steps or segments")
            }
            Method::Dig if params.eps.is_some() && bound > 8 * u64::from(params.steps) + 2 => {
                ("eps", "raise eps")
            }
            Method::Pom if params.min_steps > params.steps => ("min-steps", "lower min-steps"),
            _ => ("steps", "lower steps"),
        };
        let needed = if bound >= u64::MAX / 4 {
            "an unbounded number of".to_owned()
        } else {
            format!("up to {bound}")
        };
        Err(Error::invalid(
            option,
            format!(
                "{self} with these settings needs {needed} loop iterations per invocation; this \
                 device ends an invocation after {limit} (silently, with a wrong result): {remedy}"
            ),
        ))
    }

    /// Checks `params` for this method: their ranges ([`MethodParams::validate`]) and,
    /// for `pom`, `min_steps` (n_min, the head-on sample count) at most `steps`
    /// (n_max). What a command line and a scene file (each object's `[method]`) are
    /// checked with; the error names the parameter.
    pub fn check_params(self, params: &MethodParams) -> Result<()> {
        params.validate()?;
        if self == Method::Pom && params.min_steps > params.steps {
            return Err(Error::invalid(
                "min-steps",
                format!(
                    "{} is above steps {} (pom's head-on sample count n_min must not \
                     exceed n_max)",
                    params.min_steps, params.steps
                ),
            ));
        }
        Ok(())
    }

    /// What the method needs besides the G-buffer (the renderer builds only that).
    pub fn needs(self) -> Needs {
        match self {
            Method::Dig => Needs {
                pyramid: None,
                dig_corners: true,
                cone: None,
            },
            Method::DigGuarded => Needs {
                pyramid: Some(PyramidKind::Cell),
                dig_corners: true,
                cone: None,
            },
            Method::Pyramid => Needs {
                pyramid: Some(PyramidKind::Footprint),
                ..Needs::default()
            },
            Method::Exact => Needs {
                pyramid: Some(PyramidKind::Cell),
                ..Needs::default()
            },
            Method::Cone | Method::ConeExact => Needs {
                pyramid: Some(PyramidKind::Cell),
                dig_corners: false,
                cone: Some(ConeKind::Conservative),
            },
            Method::RelaxedCone => Needs {
                pyramid: Some(PyramidKind::Cell),
                dig_corners: false,
                cone: Some(ConeKind::Relaxed),
            },
            _ => Needs::default(),
        }
    }

    /// The parameters the method reads: the viewer shows these, the benchmark sweeps
    /// `steps` only for the methods that read it.
    pub fn reads(self) -> Reads {
        let none = Reads::default();
        match self {
            Method::Bump | Method::Exact | Method::ConeExact => none,
            Method::Linear => Reads {
                steps: true,
                ..none
            },
            Method::Relief | Method::Cone | Method::RelaxedCone => Reads {
                steps: true,
                refine_steps: true,
                ..none
            },
            Method::Pom => Reads {
                steps: true,
                min_steps: true,
                ..none
            },
            Method::Secant => Reads {
                steps: true,
                segments: true,
                ..none
            },
            Method::Dig | Method::DigGuarded => Reads {
                steps: true,
                refine_steps: true,
                block: true,
                ..none
            },
            Method::Pyramid => Reads {
                max_level: true,
                ..none
            },
        }
    }

    /// The default quality (`--steps`): the paper's 15 samples for `secant`, 64 for
    /// the marching methods (unused by `bump`, `pyramid` and `exact`).
    pub fn default_steps(self) -> u32 {
        match self {
            Method::Secant => 15,
            _ => 64,
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
                Error::invalid(
                    "method",
                    format!("unknown method '{s}' (known: {})", names.join(", ")),
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A method that does not read `steps` has a loop bound that does not depend on it,
    /// and one that reads `steps` (marches) has a bound that grows with it, except for
    /// the cone methods, whose march stops after a fixed budget.
    #[test]
    fn reads_agrees_with_loop_bound() {
        let with = |steps| MethodParams {
            steps,
            ..MethodParams::default()
        };
        for &m in Method::ALL {
            let (few, many) = (m.loop_bound(&with(4)), m.loop_bound(&with(400)));
            if !m.reads().steps {
                assert_eq!(few, many, "{m} does not read steps");
            } else if !matches!(m, Method::Cone | Method::RelaxedCone) {
                assert!(many > few, "{m} reads steps: {few:?} vs {many:?}");
            }
        }
    }

    #[test]
    fn names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().unwrap(), *m);
            // A method's own file, or a variant of another method's (relaxed-cone is
            // `cone`'s trace with RELAXED).
            let name = m.shader().name;
            let own = format!("trace/{}.comp", m.name().replace('-', "_"));
            assert!(
                name == own || (*m == Method::RelaxedCone && name == "trace/cone.comp[RELAXED]"),
                "{m}: {name}"
            );
        }
        let err = "nope".parse::<Method>().unwrap_err().to_string();
        assert!(err.contains("nope") && err.contains("relief"), "{err}");
    }

    #[test]
    fn default_lists_and_forward_paths() {
        let defaults = Method::defaults();
        assert_eq!(defaults.len(), Method::ALL.len() - 1);
        assert!(!defaults.contains(&Method::ConeExact));
        let forward: Vec<Method> = Method::ALL
            .iter()
            .copied()
            .filter(|m| m.forward_shader().is_some())
            .collect();
        assert_eq!(forward, [Method::Relief, Method::Pom]);
    }

    #[test]
    fn loop_limits_refuse_what_lavapipe_would_cut_short() {
        let p = |steps, segments, eps| MethodParams {
            steps,
            segments,
            eps,
            ..MethodParams::default()
        };
        // The secant case: 2000 x 64 samples, each pixel cut off at 65,535.
        let err = Method::Secant
            .check_loop_limit(&p(2000, 64, None), LOOP_LIMIT)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("lower steps or segments") && err.contains("128064"),
            "{err}"
        );
        assert!(
            Method::Secant
                .check_loop_limit(&p(1000, 64, None), LOOP_LIMIT)
                .is_ok()
        );
        let err = Method::Relief
            .check_loop_limit(&p(MAX_STEPS, 1, None), LOOP_LIMIT)
            .unwrap_err()
            .to_string();
        assert!(err.contains("lower steps"), "{err}");
        // DIG's step below the interval: unbounded without eps, 4/eps with it.
        let err = Method::Dig
            .check_loop_limit(&p(150, 1, Some(0.0)), LOOP_LIMIT)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("raise eps") && err.contains("unbounded"),
            "{err}"
        );
        assert!(
            Method::Dig
                .check_loop_limit(&p(150, 1, Some(1e-3)), LOOP_LIMIT)
                .is_ok()
        );
        assert!(
            Method::Dig
                .check_loop_limit(&p(8000, 1, None), LOOP_LIMIT)
                .is_ok()
        );
        assert!(
            Method::Dig
                .check_loop_limit(&p(8200, 1, None), LOOP_LIMIT)
                .is_err()
        );
        // Every default setting and the benchmark's largest run anywhere.
        for &m in Method::ALL {
            assert!(
                m.check_loop_limit(&MethodParams::for_method(m), LOOP_LIMIT)
                    .is_ok()
            );
            assert!(m.check_loop_limit(&p(1024, 1, None), LOOP_LIMIT).is_ok());
        }
        assert_eq!(Method::Exact.loop_bound(&p(MAX_STEPS, 1, None)), None);
    }
}
