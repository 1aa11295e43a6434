//! The run's driver ([`run`]): the progress weights, each map's sweep in turn, the
//! map-size sweep and the one-off builds.

use super::*;
use dispmap::context::Context;
use dispmap::error::{Error, Result};
use dispmap::heightfield::HeightField;
use dispmap::passes::PassName;
use dispmap::renderer::Renderer;
use std::sync::Arc;
use std::time::{Instant, SystemTime};

/// The sweep's progress, reported after each unit of work.
#[derive(Clone, Debug)]
pub struct Progress {
    /// Work done, in [`Progress::total`]'s units.
    pub done: u64,
    /// All the work: a timed frame at `N` steps weighs `N` (methods without steps
    /// [`NO_STEPS_WEIGHT`]), a reference frame [`REFERENCE_WEIGHT`]: roughly
    /// proportional to lavapipe's time.
    pub total: u64,
    /// What runs now, e.g. `rocks dig 100 (frame 3/8)`.
    pub stage: String,
}

/// Progress weight of one frame of a method without a step count.
pub const NO_STEPS_WEIGHT: u64 = 100;

/// Renderers of the material-table numbers ([`materials`]).
const MATERIALS_RENDERERS: u64 = 6;

/// Renderers of the cost of silhouettes ([`silhouettes`]); the materials scene's count
/// as several (five objects, three maps).
const SILHOUETTE_RENDERERS: u64 = 8;

/// Progress weight of one reference frame (CPU intersection).
pub const REFERENCE_WEIGHT: u64 = 150;

/// The one-off builds of a renderer's maps, GPU milliseconds.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Builds {
    pub(super) pyramid: Option<f64>,
    pub(super) cone: Option<f64>,
}

impl Builds {
    pub(super) fn of(renderer: &Renderer) -> Self {
        Builds {
            pyramid: renderer.build_ms(PassName::Pyramid),
            cone: renderer.build_ms(PassName::Cone),
        }
    }

    /// Each build's faster time.
    pub(super) fn min(self, other: Self) -> Self {
        let min = |a: Option<f64>, b: Option<f64>| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Builds {
            pyramid: min(self.pyramid, other.pyramid),
            cone: min(self.cone, other.cone),
        }
    }
}

/// The fastest of 3 single-threaded CPU builds of `field`'s pyramid of `kind`, ms.
pub(super) fn cpu_pyramid_ms(
    field: &HeightField,
    config: &BenchConfig,
    kind: dispmap::method::PyramidKind,
) -> f64 {
    let addressing = config.scene.addressing();
    min_of((0..3).map(|_| {
        let start = Instant::now();
        let levels = dispmap::passes::pyramid::cpu_build(field, addressing, kind);
        std::hint::black_box(levels);
        start.elapsed().as_secs_f64() * 1e3
    }))
}

/// The smallest of `values` (infinity when empty).
pub(super) fn min_of(values: impl Iterator<Item = f64>) -> f64 {
    values.fold(f64::INFINITY, f64::min)
}

fn run_weight(steps: Option<u32>, frames: u32) -> u64 {
    u64::from(frames) * steps.map_or(NO_STEPS_WEIGHT, u64::from)
}

/// [`run_weight`] of every frame of every pass.
fn frames_rendered(config: &BenchConfig) -> u32 {
    config.frames * config.repeat
}

/// The total progress weight of a sweep over `maps` maps (and the size sweep if
/// `size_sweep`).
fn total_weight(config: &BenchConfig, maps: usize, size_sweep: bool) -> u64 {
    let refs = config.error_frame_indices().len() as u64 * REFERENCE_WEIGHT;
    let per_map: u64 = config
        .methods
        .iter()
        .chain(&config.forward_methods())
        .flat_map(|&m| config.settings_of(m))
        .map(|s| run_weight(s, frames_rendered(config)))
        .sum::<u64>()
        + refs;
    let per_size: u64 = config
        .size_methods
        .iter()
        .map(|&m| {
            run_weight(
                has_steps(m).then_some(config.size_steps),
                frames_rendered(config),
            )
        })
        .sum::<u64>()
        + refs;
    per_map * maps as u64
        + if config.materials {
            MATERIALS_RENDERERS * run_weight(Some(64), frames_rendered(config))
        } else {
            0
        }
        + if config.silhouettes {
            SILHOUETTE_RENDERERS * run_weight(Some(64), frames_rendered(config))
        } else {
            0
        }
        + if size_sweep {
            per_size * config.sizes.len() as u64
        } else {
            0
        }
}

pub(super) struct Tracker<'p> {
    done: u64,
    total: u64,
    sink: &'p mut dyn FnMut(&Progress),
}

impl Tracker<'_> {
    pub(super) fn advance(&mut self, weight: u64, stage: String) {
        self.done = (self.done + weight).min(self.total);
        (self.sink)(&Progress {
            done: self.done,
            total: self.total,
            stage,
        });
    }
}

/// Runs the sweep: the methods sweep over `maps`, then (if `config.sizes` is not empty
/// and `size_source` is given) the map-size sweep on `size_source`. `progress` is called
/// after every frame. Validates `config` first.
pub fn run(
    ctx: &Arc<Context>,
    config: &BenchConfig,
    maps: &[MapSpec],
    size_source: Option<&MapSpec>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<BenchResults> {
    let mut config = config.clone();
    config.validate()?;
    if maps.is_empty() && (config.sizes.is_empty() || size_source.is_none()) {
        return Err(Error::invalid(
            "--maps",
            "no map to benchmark (give --maps or --heightmap)",
        ));
    }
    let mut names = std::collections::HashSet::new();
    for m in maps {
        if !names.insert(file_stem(&m.name)) {
            return Err(Error::invalid(
                "--maps",
                format!("two maps are named '{}'", m.name),
            ));
        }
    }
    let size_sweep = !config.sizes.is_empty() && size_source.is_some();
    let started = SystemTime::now();
    let clock = Instant::now();
    let mut tracker = Tracker {
        done: 0,
        total: total_weight(&config, maps.len(), size_sweep),
        sink: progress,
    };
    let mut rows = Vec::new();
    let mut pass_medians = Vec::new();
    let mut images = Vec::new();
    let heat_steps = config.heatmap_steps();
    let mut runs: Vec<RunSpec> = config
        .methods
        .iter()
        .flat_map(|&method| {
            config
                .settings_of(method)
                .into_iter()
                .map(move |steps| RunSpec {
                    method,
                    steps,
                    heat: steps.is_none_or(|s| s == heat_steps),
                    forward: false,
                })
        })
        .collect();
    // The forward runs, interleaved with the others in every frame (after them).
    for method in config.forward_methods() {
        for steps in config.settings_of(method) {
            runs.push(RunSpec {
                method,
                steps,
                heat: false,
                forward: true,
            });
        }
    }
    for map in maps {
        let sweep = MapSweep::new(ctx, &config, map, Sweep::Methods, &mut tracker)?;
        let (r, p, imgs) = sweep.run(&runs, &mut tracker)?;
        rows.extend(r);
        pass_medians.extend(p);
        images.extend(imgs);
    }
    let mut size_info = None;
    if let (true, Some(source)) = (size_sweep, size_source) {
        size_info = Some(map_info(&source.name, &source.field));
        for &side in &config.sizes {
            let label = format!("{}@{side}", source.name);
            let field = resample(&source.field, side, side, &label)?;
            let spec = MapSpec { name: label, field };
            let runs: Vec<RunSpec> = config
                .size_methods
                .iter()
                .map(|&method| RunSpec {
                    method,
                    steps: has_steps(method).then_some(config.size_steps),
                    heat: false,
                    forward: false,
                })
                .collect();
            let sweep = MapSweep::new(ctx, &config, &spec, Sweep::MapSize, &mut tracker)?;
            let (r, p, _) = sweep.run(&runs, &mut tracker)?;
            rows.extend(r);
            pass_medians.extend(p);
        }
    }
    let materials = if config.materials {
        let per_pass = MATERIALS_RENDERERS * run_weight(Some(64), frames_rendered(&config))
            / u64::from(config.repeat);
        Some(materials::run(
            ctx,
            config.frame,
            config.frames,
            config.repeat,
            &mut |r| tracker.advance(per_pass, format!("materials (pass {r}/{})", config.repeat)),
        )?)
    } else {
        None
    };
    let silhouettes = if config.silhouettes {
        let per_pass = SILHOUETTE_RENDERERS * run_weight(Some(64), frames_rendered(&config))
            / u64::from(config.repeat);
        Some(silhouettes::run(
            ctx,
            config.frame,
            config.frames,
            config.repeat,
            &mut |r| {
                tracker.advance(
                    per_pass,
                    format!("silhouettes (pass {r}/{})", config.repeat),
                )
            },
        )?)
    } else {
        None
    };
    let info = ctx.info();
    Ok(BenchResults {
        materials,
        silhouettes,
        maps: maps.iter().map(|m| map_info(&m.name, &m.field)).collect(),
        size_source: size_info,
        device: info.name.clone(),
        driver: info.driver.clone(),
        api_version: info.api_version.clone(),
        traversal_rules: ctx.traversal_rules(),
        config,
        rows,
        pass_medians,
        images,
        started,
        wall: clock.elapsed(),
    })
}

fn map_info(name: &str, field: &HeightField) -> MapInfo {
    MapInfo {
        name: name.to_owned(),
        label: field.label().to_owned(),
        width: field.width(),
        height: field.height(),
        format: format!("{:?}", field.format()),
        mean_height: field.mean(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_and_weights() {
        let c = BenchConfig {
            steps: vec![10, 20],
            frames: 2,
            ..BenchConfig::default()
        };
        assert_eq!(c.settings_of(Method::Bump), [None]);
        assert_eq!(c.settings_of(Method::Dig), [Some(10), Some(20)]);
        assert_eq!(run_weight(Some(10), 2), 20);
        assert_eq!(run_weight(None, 2), 2 * NO_STEPS_WEIGHT);
        assert!(c.frame_set().contains("error frames 0 1"));
        assert!(!c.frame_set().contains(','));
    }
}
