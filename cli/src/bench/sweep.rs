//! One map's sweep: the runs interleaved frame by frame, their times and measures
//! accumulated, one [`RunRow`] each.

use super::*;
use crate::heatmap;
use crate::measure::{Compared, FrameReference, Measure as _};
use crate::metrics::{self, ErrorMetrics};
use crate::reference::Reference;
use dispmap::context::Context;
use dispmap::error::Result;
use dispmap::heightfield::HeightField;
use dispmap::method::Method;
use dispmap::passes::PassName;
use dispmap::renderer::{RenderSettings, Renderer};
use std::sync::Arc;

/// One (method, setting) of a map's sweep.
#[derive(Clone, Copy, Debug)]
pub(super) struct RunSpec {
    pub(super) method: Method,
    pub(super) steps: Option<u32>,
    /// Write the heat map (and DIG's interval map) of frame 0.
    pub(super) heat: bool,
    /// The forward path ([`Sweep::Forward`]).
    pub(super) forward: bool,
}

/// What a run has measured so far.
#[derive(Default)]
struct RunAccumulator {
    /// Every frame's time of each pass, over all passes of the repeat.
    passes: Vec<(PassName, Vec<f64>)>,
    /// Every frame's method time (`dig_corners + trace`), with its repeat pass.
    method_ms: Vec<(u32, f64)>,
    /// Every frame's total (without the one-off passes), with its repeat pass.
    total_ms: Vec<(u32, f64)>,
    errors: Vec<ErrorMetrics>,
    /// Forward runs: hit texels differing from the deferred run's, per error frame.
    forward_differing: Vec<u64>,
    corner_iterations: Vec<f64>,
    lockstep: Vec<[f64; 3]>,
}

impl RunAccumulator {
    /// Adds a frame's times; `forward`: the method runs in the G-buffer pass.
    fn add_times(&mut self, times: &[(PassName, f64)], pass: u32, forward: bool) {
        let mut frame_method = 0.0;
        let mut frame_total = 0.0;
        for &(name, ms) in times {
            if name.is_one_off() {
                continue;
            }
            frame_total += ms;
            let method_pass = if forward {
                name == PassName::GBuffer
            } else {
                name == PassName::Trace || name == PassName::DigCorners
            };
            if method_pass {
                frame_method += ms;
            }
            match self.passes.iter_mut().find(|(n, _)| *n == name) {
                Some((_, v)) => v.push(ms),
                None => self.passes.push((name, vec![ms])),
            }
        }
        self.method_ms.push((pass, frame_method));
        self.total_ms.push((pass, frame_total));
    }

    /// The robust time of a pass: its minimum over every frame of every pass.
    fn min_of(&self, name: PassName) -> Option<f64> {
        self.passes
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| min_of(v.iter().copied()))
    }

    /// The method time's minimum over all frames, its median, and the lowest and the
    /// highest per-pass minimum (the spread of the robust statistic over the repeat).
    fn method_stats(&self) -> (f64, f64, f64, f64) {
        let all: Vec<f64> = self.method_ms.iter().map(|&(_, ms)| ms).collect();
        let passes = self
            .method_ms
            .iter()
            .map(|&(p, _)| p)
            .max()
            .map_or(0, |p| p + 1);
        let per_pass: Vec<f64> = (0..passes)
            .map(|p| min_of(self.method_ms.iter().filter(|m| m.0 == p).map(|m| m.1)))
            .collect();
        (
            min_of(all.iter().copied()),
            dispmap::timing::median(&all),
            min_of(per_pass.iter().copied()),
            per_pass.iter().copied().fold(0.0, f64::max),
        )
    }

    /// The per-pass medians of the method time and of the per-frame total.
    fn pass_medians(&self) -> PassMedians {
        let per_pass = |values: &[(u32, f64)]| -> Vec<f64> {
            let passes = values.iter().map(|&(p, _)| p).max().map_or(0, |p| p + 1);
            (0..passes)
                .map(|p| {
                    let v: Vec<f64> = values.iter().filter(|m| m.0 == p).map(|m| m.1).collect();
                    dispmap::timing::median(&v)
                })
                .collect()
        };
        PassMedians {
            method: per_pass(&self.method_ms),
            total: per_pass(&self.total_ms),
        }
    }

    fn mean(&self, get: fn(&ErrorMetrics) -> f64) -> f64 {
        mean_of(self.errors.iter().map(get))
    }
}

/// One map's references and one renderer per method. The runs are interleaved frame by
/// frame (frame 0 of every run, then frame 1, ...), so a load that comes and goes on
/// the machine spreads over every method's frames instead of skewing the methods that
/// happened to run at that time; the per-pass medians then discard the slow frames.
pub(super) struct MapSweep<'a> {
    ctx: &'a Arc<Context>,
    config: &'a BenchConfig,
    name: String,
    field: &'a HeightField,
    sweep: Sweep,
    /// (frame index, reference), ascending.
    references: Vec<(u32, FrameReference)>,
}

impl<'a> MapSweep<'a> {
    /// Computes the references of the error frames (with a `bump` renderer).
    pub(super) fn new(
        ctx: &'a Arc<Context>,
        config: &'a BenchConfig,
        map: &'a MapSpec,
        sweep: Sweep,
        tracker: &mut Tracker<'_>,
    ) -> Result<Self> {
        let mut renderer = Renderer::new(ctx, &map.field, Self::settings(config, Method::Bump))?;
        let reference = Reference::new(&map.field, renderer.settings().scene.addressing());
        let mut references = Vec::new();
        for f in config.error_frame_indices() {
            renderer.set_scene(config.frame_scene(f))?;
            references.push((f, renderer.reference(&reference)?));
            tracker.advance(
                REFERENCE_WEIGHT,
                format!("{} reference (frame {})", map.name, f + 1),
            );
        }
        Ok(MapSweep {
            ctx,
            config,
            name: map.name.clone(),
            field: &map.field,
            sweep,
            references,
        })
    }

    fn settings(config: &BenchConfig, method: Method) -> RenderSettings {
        RenderSettings {
            width: config.frame[0],
            height: config.frame[1],
            method,
            params: protocol_params(None),
            scene: config.frame_scene(0),
            shadows: dispmap::passes::shadow::ShadowSettings {
                mode: config.shadows,
                ..Default::default()
            },
        }
    }

    /// Times every run over the frames (interleaved, see the type's docs) and measures
    /// their errors; returns one row per run, in order, their per-pass medians, and the
    /// heat and interval maps. A forward run uses the renderer of its method.
    pub(super) fn run(
        &self,
        runs: &[RunSpec],
        tracker: &mut Tracker<'_>,
    ) -> Result<(Vec<RunRow>, Vec<PassMedians>, Vec<NamedImage>)> {
        let config = self.config;
        // One renderer per method; each gets one untimed warm-up frame (first use of its
        // pipelines; it builds the pyramid, whose time is kept).
        let mut renderers: Vec<(Method, Renderer, Builds)> = Vec::new();
        for run in runs {
            if renderers.iter().any(|(m, _, _)| *m == run.method) {
                continue;
            }
            let mut settings = Self::settings(config, run.method);
            settings.params = protocol_params(run.steps);
            let mut renderer = Renderer::new(self.ctx, self.field, settings)?;
            renderer.render()?;
            if runs.iter().any(|r| r.forward && r.method == run.method) {
                renderer.enable_forward(self.field)?;
                // The forward pipeline's first use, untimed like the deferred one's.
                renderer.render_forward()?;
            }
            let mut builds = Builds::of(&renderer);
            // The builds run once per renderer: `repeat` renderers give `repeat` builds,
            // of which the fastest is kept (the same statistic as every other time).
            if builds.pyramid.is_some() || builds.cone.is_some() {
                for _ in 1..config.repeat {
                    let mut again = Renderer::new(self.ctx, self.field, settings)?;
                    again.render()?;
                    builds = builds.min(Builds::of(&again));
                }
            }
            renderers.push((run.method, renderer, builds));
        }
        let mut acc: Vec<RunAccumulator> = runs.iter().map(|_| RunAccumulator::default()).collect();
        let mut images = Vec::new();
        // The deferred hits of the current error frame, for the forward runs' comparison.
        let mut deferred_hits: std::collections::HashMap<
            (Method, Option<u32>),
            Vec<metrics::HitTexel>,
        > = std::collections::HashMap::new();
        let mut next_ref = 0;
        for (pass, f) in (0..config.repeat).flat_map(|p| (0..config.frames).map(move |f| (p, f))) {
            // The references are measured in the first pass only.
            let reference = match self.references.get(next_ref) {
                Some((rf, r)) if *rf == f && pass == 0 => {
                    next_ref += 1;
                    Some(r)
                }
                _ => None,
            };
            for (run, acc) in runs.iter().zip(acc.iter_mut()) {
                let (_, renderer, _) = renderers
                    .iter_mut()
                    .find(|(m, _, _)| *m == run.method)
                    .expect("a renderer per method was made above");
                renderer.set_method(run.method, protocol_params(run.steps))?;
                renderer.set_scene(config.frame_scene(f))?;
                let times = if run.forward {
                    renderer.render_forward()?
                } else {
                    renderer.render()?
                };
                acc.add_times(&times, pass, run.forward);
                if let Some(reference) = reference {
                    let img = self.measure(renderer, run, f, reference, acc, &mut deferred_hits)?;
                    images.extend(img);
                }
                tracker.advance(
                    run.steps.map_or(NO_STEPS_WEIGHT, u64::from),
                    format!(
                        "{} {}{} {} (frame {}/{}, pass {}/{})",
                        self.name,
                        run.method,
                        if run.forward { " forward" } else { "" },
                        run.steps.map_or("-".to_owned(), |s| s.to_string()),
                        f + 1,
                        config.frames,
                        pass + 1,
                        config.repeat
                    ),
                );
            }
        }
        let rows = runs
            .iter()
            .zip(&acc)
            .map(|(run, acc)| {
                let builds = renderers
                    .iter()
                    .find(|(m, _, _)| *m == run.method)
                    .map_or_else(Builds::default, |r| r.2);
                self.row(run, acc, builds)
            })
            .collect();
        let medians = acc.iter().map(RunAccumulator::pass_medians).collect();
        Ok((rows, medians, images))
    }

    /// Measures the last frame of `renderer` against `reference` into `acc`; returns the
    /// heat and interval maps when the run wants them and `f` is frame 0. A deferred
    /// run's hits are kept in `deferred` when a forward run of its method and setting
    /// follows; a forward run's are compared with them.
    fn measure(
        &self,
        renderer: &Renderer,
        run: &RunSpec,
        f: u32,
        reference: &FrameReference,
        acc: &mut RunAccumulator,
        deferred: &mut std::collections::HashMap<(Method, Option<u32>), Vec<metrics::HitTexel>>,
    ) -> Result<Vec<NamedImage>> {
        let frame = self.config.frame;
        let Compared {
            error: e,
            hits,
            color: _,
        } = renderer.compare_last(reference)?;
        let key = (run.method, run.steps);
        if run.forward {
            let bits = |t: &metrics::HitTexel| t.map(f32::to_bits);
            let differing = match deferred.get(&key) {
                Some(d) if d.len() == hits.len() => hits
                    .iter()
                    .zip(d)
                    .filter(|(a, b)| bits(a) != bits(b))
                    .count(),
                _ => hits.len(),
            };
            acc.forward_differing.push(differing as u64);
        } else if self.config.forward_methods().contains(&run.method) {
            deferred.insert(key, hits.clone());
        }
        let covered = heatmap::coverage(&hits, Some(&reference.rays));
        acc.lockstep.push([
            lockstep_iterations(&hits, &covered, frame[0], [8, 1]),
            lockstep_iterations(&hits, &covered, frame[0], [8, 4]),
            lockstep_iterations(&hits, &covered, frame[0], [4, 2]),
        ]);
        let corners = if run.method.needs().dig_corners {
            renderer.read_corners()?
        } else {
            None
        };
        if let Some((_, c)) = &corners {
            let stats = heatmap::corner_stats(c);
            acc.corner_iterations.push(if e.compared_pixels == 0 {
                0.0
            } else {
                stats.total / e.compared_pixels as f64
            });
        }
        acc.errors.push(e);
        if run.heat && f == 0 {
            self.images(renderer, run.method, &hits, &reference.rays, corners)
        } else {
            Ok(Vec::new())
        }
    }

    fn row(&self, run: &RunSpec, acc: &RunAccumulator, builds: Builds) -> RunRow {
        let config = self.config;
        let (method_ms, method_median_ms, method_lo_ms, method_hi_ms) = acc.method_stats();
        let medians = acc.pass_medians();
        let range = |v: &[f64]| {
            (
                min_of(v.iter().copied()),
                v.iter().copied().fold(0.0, f64::max),
            )
        };
        let (method_median_lo_ms, method_median_hi_ms) = range(&medians.method);
        let (total_median_lo_ms, total_median_hi_ms) = range(&medians.total);
        let totals: Vec<f64> = acc.total_ms.iter().map(|&(_, ms)| ms).collect();
        RunRow {
            sweep: if run.forward {
                Sweep::Forward
            } else {
                self.sweep
            },
            map: self.name.clone(),
            map_width: self.field.width(),
            map_height: self.field.height(),
            method: run.method.name().to_owned(),
            steps: run.steps,
            frame_width: config.frame[0],
            frame_height: config.frame[1],
            frames: config.frames,
            repeat: config.repeat,
            error_frames: acc.errors.len() as u32,
            frame_set: config.frame_set(),
            gbuffer_ms: acc.min_of(PassName::GBuffer).unwrap_or(0.0),
            pyramid_build_ms: run.method.needs().pyramid.and(builds.pyramid),
            cpu_pyramid_build_ms: match (self.sweep, run.method.needs().pyramid) {
                (Sweep::MapSize, Some(kind)) => Some(cpu_pyramid_ms(self.field, config, kind)),
                _ => None,
            },
            cone_build_ms: if run.method.needs().cone.is_some() {
                builds.cone
            } else {
                None
            },
            dig_corners_ms: acc.min_of(PassName::DigCorners),
            trace_ms: acc.min_of(PassName::Trace).unwrap_or(0.0),
            shade_ms: acc.min_of(PassName::Shade).unwrap_or(0.0),
            shadow_ms: acc.min_of(PassName::Shadow),
            method_ms,
            method_median_ms,
            method_lo_ms,
            method_hi_ms,
            total_ms: min_of(totals.iter().copied()),
            total_median_ms: dispmap::timing::median(&totals),
            method_median_lo_ms,
            method_median_hi_ms,
            total_median_lo_ms,
            total_median_hi_ms,
            iterations_mean: acc.mean(|e| e.mean_iterations),
            iterations_p99: acc.mean(|e| e.p99_iterations),
            iterations_simd8: mean_of(acc.lockstep.iter().map(|l| l[0])),
            iterations_warp32: mean_of(acc.lockstep.iter().map(|l| l[1])),
            iterations_quads8: mean_of(acc.lockstep.iter().map(|l| l[2])),
            corner_iterations: (!acc.corner_iterations.is_empty())
                .then(|| mean_of(acc.corner_iterations.iter().copied())),
            mean_texels: acc.mean(|e| e.mean_texels),
            p99_texels: acc.mean(|e| e.p99_texels),
            max_texels: acc.errors.iter().map(|e| e.max_texels).fold(0.0, f64::max),
            artifact_fraction: acc.mean(|e| e.artifact_fraction),
            psnr_db: acc.mean(|e| e.psnr_db),
            nonfinite_pixels: acc.errors.iter().map(|e| e.nonfinite_pixels).sum(),
            forward_differing_pixels: run.forward.then(|| acc.forward_differing.iter().sum()),
        }
    }

    /// The heat map of `hits` (fixed scale: the largest setting plus the binary search)
    /// and, for `dig`, the interval map of the same frame.
    fn images(
        &self,
        renderer: &Renderer,
        method: Method,
        hits: &[metrics::HitTexel],
        rays: &[Option<crate::reference::Ray>],
        corners: Option<([u32; 2], Vec<dispmap::passes::dig::Corner>)>,
    ) -> Result<Vec<NamedImage>> {
        let config = self.config;
        let [w, h] = config.frame;
        let stem = file_stem(&self.name);
        let scale = (config.heatmap_steps() + REFINE_STEPS) as f32;
        let covered = heatmap::coverage(hits, Some(rays));
        let heat = heatmap::iteration_heatmap(hits, &covered, Some(scale))?;
        let mut out = vec![NamedImage {
            file_name: format!("heatmap_{stem}_{}.png", method.name()),
            caption: format!(
                "{} on {}: trace iterations per pixel, frame 0 (0 to {scale}, saturating; \
                 the colour bar under it)",
                method.name(),
                self.name
            ),
            width: w,
            height: h + super::plot::HEAT_BAR_HEIGHT,
            rgba: super::plot::with_heat_bar(&heat, w, h, scale)?,
        }];
        if method == Method::Dig
            && let Some((grid, corners)) = corners
        {
            let params = renderer.settings().params;
            let intervals = heatmap::block_intervals(grid, &corners, params.dig_eps())?;
            out.push(NamedImage {
                file_name: format!("intervals_{stem}.png"),
                caption: format!(
                    "dig on {}: depth interval length per block, frame 0 (darker = longer; \
                     red = no interval)",
                    self.name
                ),
                width: w,
                height: h,
                rgba: heatmap::interval_map(
                    &intervals,
                    heatmap::block_count(grid),
                    params.block,
                    [w, h],
                )?,
            });
        }
        Ok(out)
    }
}

/// The mean of `values` (0 for none).
fn mean_of(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// The lockstep cost of a hit buffer: pixels are grouped in aligned `group[0] x
/// group[1]` tiles of a frame `width` pixels wide (row by row), and each tile with a
/// covered pixel costs the largest iteration count among its covered pixels (a SIMD
/// group runs until its slowest lane is done). Returns the mean cost per such tile (0
/// if none). Non-finite counts are skipped.
pub fn lockstep_iterations(
    hits: &[metrics::HitTexel],
    covered: &[bool],
    width: u32,
    group: [u32; 2],
) -> f64 {
    let w = width.max(1) as usize;
    let [gx, gy] = group.map(|g| g.max(1) as usize);
    let tiles_x = w.div_ceil(gx);
    let mut max: std::collections::HashMap<usize, f32> = std::collections::HashMap::new();
    for (i, (t, &c)) in hits.iter().zip(covered).enumerate() {
        if !c || !t[3].is_finite() {
            continue;
        }
        let (x, y) = (i % w, i / w);
        let tile = (y / gy) * tiles_x + x / gx;
        let m = max.entry(tile).or_insert(0.0);
        *m = m.max(t[3]);
    }
    mean_of(max.values().map(|&m| f64::from(m)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lockstep_cost_is_the_group_maximum() {
        let t = |n: f32| [0.0, 0.0, 0.5, n];
        // A 4x2 frame: groups of 2x1 -> (1, 5), (2, 2), (7, -), (3, 4 uncovered).
        let hits = [
            t(1.0),
            t(5.0),
            t(2.0),
            t(2.0),
            t(7.0),
            t(0.0),
            t(3.0),
            t(9.0),
        ];
        let covered = [true, true, true, true, true, false, true, false];
        let cost = lockstep_iterations(&hits, &covered, 4, [2, 1]);
        assert_eq!(cost, (5.0 + 2.0 + 7.0 + 3.0) / 4.0);
        // One 4x2 group: the largest covered count.
        assert_eq!(lockstep_iterations(&hits, &covered, 4, [4, 2]), 7.0);
        assert_eq!(lockstep_iterations(&hits, &[false; 8], 4, [2, 1]), 0.0);
    }
}
