//! The error overlay: the exact reference traced off the render thread, its measures
//! and the pixels it marks.

use super::headless::Headless;
use super::panel::SideError;
use super::state::ViewState;
use super::viewer::{FrameKey, Viewer};
use anyhow::{Context as _, Result, bail};
use dispmap::heightfield::Addressing;
use dispmap_cli::measure::Measure as _;
use dispmap_cli::metrics::{self, ARTIFACT_TEXELS, ErrorMetrics, HitTexel, MapGeometry};
use dispmap_cli::reference::{Hit, Ray, Reference};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, mpsc};

/// The error overlay: computed for a frame, shown while the frame's inputs stay.
pub(super) struct Overlay {
    /// The inputs it was computed for.
    pub(super) key: FrameKey,
    /// Per side: which pixels are artifacts (1), misses / non-finite (2) or sent to
    /// bump mapping by level of detail (3).
    pub(super) marks: Vec<Vec<u8>>,
    /// Per side: the measures.
    pub(super) results: Vec<SideError>,
}

/// A background reference job.
pub(super) struct ErrorJob {
    pub(super) key: FrameKey,
    pub(super) done: Arc<AtomicUsize>,
    pub(super) total: usize,
    pub(super) rx: mpsc::Receiver<Vec<Option<Hit>>>,
    pub(super) rays: Vec<Option<Ray>>,
    /// Per side: name, hits, map geometry.
    pub(super) sides: Vec<(String, Vec<HitTexel>, MapGeometry)>,
    /// The pixels level of detail sends (wholly or in part) to bump mapping (empty when
    /// it is off).
    pub(super) lod: Vec<bool>,
}

impl Viewer {
    /// Starts the exact reference of the current frame in a background thread.
    pub(super) fn start_error_job(&mut self, state: &ViewState) -> Result<()> {
        if self.job.is_some() {
            eprintln!("error overlay: already computing");
            return Ok(());
        }
        if !state.assets.objects.is_empty() {
            // One reference map here; `render --metrics` traces each material's own.
            eprintln!(
                "error overlay: not available for a scene of several objects (use render \
                 --metrics: one entry per material)"
            );
            return Ok(());
        }
        // The rays and hits of the last rendered frame (the current inputs); the
        // reference traces each pixel's own f64 centre ray on the plane and the quad
        // (`Renderer::reference_rays`), so entry errors show too.
        let rays = self.left.reference_rays()?.rays;
        let mut sides = vec![(
            self.left.settings().method.name().to_owned(),
            self.left.read_hits()?,
            self.left.map_geometry(),
        )];
        if let Some(r) = &self.right {
            sides.push((
                r.settings().method.name().to_owned(),
                r.read_hits()?,
                r.map_geometry(),
            ));
        }
        let settings = *self.left.settings();
        let lod = match settings.params.lod_threshold {
            Some(threshold) => {
                let (normals, _) = self.left.read_frames()?;
                let g = self.left.map_geometry();
                lod_pixels(
                    &rays,
                    &normals,
                    settings.width as usize,
                    [g.map_width, g.map_height],
                    settings.scene.addressing() == Addressing::Repeat,
                    threshold,
                )
            }
            None => Vec::new(),
        };
        let field = state.maps[state.map].1.clone();
        let addressing = settings.scene.addressing();
        let done = Arc::new(AtomicUsize::new(0));
        let (tx, rx) = mpsc::channel();
        let total = rays.len();
        let thread_rays = rays.clone();
        let thread_done = done.clone();
        std::thread::Builder::new()
            .name("dispmap-reference".into())
            .spawn(move || {
                let reference = Reference::new(&field, addressing);
                let mut hits = Vec::with_capacity(thread_rays.len());
                for chunk in thread_rays.chunks(4096) {
                    hits.extend(reference.trace(chunk));
                    thread_done.fetch_add(chunk.len(), Ordering::Relaxed);
                }
                // The viewer may have quit meanwhile: nothing to tell then.
                let _ = tx.send(hits);
            })
            .context("cannot start the reference thread")?;
        eprintln!("error overlay: computing the exact reference of {total} pixels...");
        self.job = Some(ErrorJob {
            key: self.frame_key(state),
            done,
            total,
            rx,
            rays,
            sides,
            lod,
        });
        Ok(())
    }

    /// Picks up a finished reference: the overlay when the frame is still the same.
    pub(super) fn poll_job(
        &mut self,
        key: &FrameKey,
        headless: Option<&mut Headless>,
    ) -> Result<()> {
        let Some(job) = &self.job else {
            return Ok(());
        };
        let hits = match job.rx.try_recv() {
            Ok(hits) => hits,
            Err(mpsc::TryRecvError::Empty) => return Ok(()),
            Err(mpsc::TryRecvError::Disconnected) => {
                self.job = None;
                bail!("the reference thread ended without a result");
            }
        };
        let job = self.job.take().context("the job vanished")?;
        if &job.key != key {
            eprintln!(
                "error overlay: the frame changed while the reference was computed; press C again"
            );
            if let Some(h) = headless {
                h.waiting_error = false;
            }
            return Ok(());
        }
        // Pixels level of detail sent to bump mapping are not compared: no ray.
        let compared: Vec<Option<Ray>> = job
            .rays
            .iter()
            .enumerate()
            .map(|(i, r)| r.filter(|_| !job.lod.get(i).copied().unwrap_or(false)))
            .collect();
        let covered = job.rays.iter().filter(|r| r.is_some()).count();
        let lod_count = job
            .rays
            .iter()
            .zip(&job.lod)
            .filter(|(r, l)| r.is_some() && **l)
            .count();
        let mut marks = Vec::new();
        let mut results = Vec::new();
        for (name, gpu, geometry) in &job.sides {
            let e = metrics::hit_errors(gpu, &hits, &compared, *geometry);
            print_error(name, &e, lod_count);
            let mut m = mark_pixels(gpu, &hits, &compared, *geometry);
            for ((mark, ray), lod) in m.iter_mut().zip(&job.rays).zip(&job.lod) {
                if ray.is_some() && *lod {
                    *mark = 3;
                }
            }
            marks.push(m);
            results.push(SideError {
                metrics: e,
                lod_pixels: lod_count,
                covered,
            });
        }
        self.overlay = Some(Overlay {
            key: job.key,
            marks,
            results,
        });
        if let Some(h) = headless {
            h.waiting_error = false;
        }
        Ok(())
    }
}

/// The pixels level of detail sends (wholly or in part) to bump mapping at
/// `threshold`: those whose footprint level exceeds `threshold - 1` (`trace_lod` in
/// glsl/common/trace.glsl blends from there). The level is the CPU twin of
/// `footprint_level` there: log2 of the larger uv step in texels to the right / lower
/// neighbour (left / upper at the last column / row) on the same surface (`normals`'
/// w), tile wraps removed under repeat addressing; pixels within 1e-3 of the boundary
/// count as sent (the GPU's f32 level may fall on either side), except a magnified
/// pixel (at most one texel: level exactly 0), which only a threshold below 1 sends.
pub(super) fn lod_pixels(
    rays: &[Option<Ray>],
    normals: &[[f32; 4]],
    width: usize,
    map: [u32; 2],
    repeat: bool,
    threshold: f32,
) -> Vec<bool> {
    let height = rays.len() / width.max(1);
    let from = f64::from(threshold) - 1.0 - 1e-3;
    (0..rays.len())
        .map(|i| {
            let Some(ray) = &rays[i] else {
                return false;
            };
            let (x, y) = (i % width, i / width);
            let mut texels: f64 = 0.0;
            for (q, inside) in [
                (
                    if x + 1 < width {
                        i + 1
                    } else {
                        i.wrapping_sub(1)
                    },
                    width > 1,
                ),
                (
                    if y + 1 < height {
                        i + width
                    } else {
                        i.wrapping_sub(width)
                    },
                    height > 1,
                ),
            ] {
                if !inside || normals.get(q).map(|n| n[3]) != normals.get(i).map(|n| n[3]) {
                    continue;
                }
                let Some(n) = rays.get(q).and_then(Option::as_ref) else {
                    continue;
                };
                let mut d = [n.uv0[0] - ray.uv0[0], n.uv0[1] - ray.uv0[1]];
                if repeat {
                    for c in &mut d {
                        *c -= c.round();
                    }
                }
                texels = texels.max((d[0] * f64::from(map[0])).hypot(d[1] * f64::from(map[1])));
            }
            if texels <= 1.0 {
                threshold < 1.0
            } else {
                texels.log2() > from
            }
        })
        .collect()
}

/// Per pixel: 0 fine (or no geometry), 1 an artifact (more than [`ARTIFACT_TEXELS`]
/// off), 2 a miss (exactly one of method and reference hits) or a non-finite hit: the
/// classes of [`metrics::hit_errors`].
pub(super) fn mark_pixels(
    gpu: &[HitTexel],
    reference: &[Option<Hit>],
    rays: &[Option<Ray>],
    geometry: MapGeometry,
) -> Vec<u8> {
    gpu.iter()
        .zip(reference)
        .zip(rays)
        .map(|((t, r), ray)| {
            if ray.is_none() {
                return 0;
            }
            if !t.iter().all(|c| c.is_finite()) {
                return 2;
            }
            match (t[2] >= 0.0, r) {
                (true, Some(hit)) => {
                    u8::from(metrics::hit_distance_texels(t, hit, geometry) > ARTIFACT_TEXELS)
                }
                (false, None) => 0,
                _ => 2,
            }
        })
        .collect()
}

pub(super) fn print_error(name: &str, e: &ErrorMetrics, lod: usize) {
    let lod = if lod > 0 {
        format!(", {lod} more sent to bump mapping by level of detail (magenta, not compared)")
    } else {
        String::new()
    };
    eprintln!(
        "error overlay: {name}: mean {:.3} texels, p99 {:.3}, max {:.3}, artifacts {:.3}% \
         (red: more than {ARTIFACT_TEXELS} texel off; cyan: misses), {} pixels, non-finite \
         {}{lod}",
        e.mean_texels,
        e.p99_texels,
        e.max_texels,
        100.0 * e.artifact_fraction,
        e.compared_pixels,
        e.nonfinite_pixels
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_of_detail_sends_minified_pixels_past_the_band() {
        // One row of four pixels over a 64-texel map: uv steps of 0.5, 3, 12 texels.
        let ray = |u: f64| {
            Some(Ray {
                uv0: [u, 0.0],
                parallax: [0.0, 0.0],
            })
        };
        let t = 1.0 / 64.0;
        let rays = [ray(0.0), ray(0.5 * t), ray(3.5 * t), ray(15.5 * t)];
        let normals = [[0.0, 1.0, 0.0, 0.0]; 4];
        let sent = |threshold| lod_pixels(&rays, &normals, 4, [64, 64], true, threshold);
        // Levels: 0 (magnified), 1.58, 3.58, 3.58 (the last pixel looks left); a pixel
        // is sent above threshold - 1.
        assert_eq!(sent(1.0), vec![false, true, true, true]);
        assert_eq!(sent(3.0), vec![false, false, true, true]);
        assert_eq!(sent(5.0), vec![false, false, false, false]);
        // Below 1 every pixel blends toward bump mapping.
        assert_eq!(sent(0.5), vec![true; 4]);
        // Another surface's neighbour is not a neighbour.
        let mut split = normals;
        split[2][3] = 1.0;
        let sent = lod_pixels(&rays, &split, 4, [64, 64], true, 3.0);
        assert_eq!(sent, vec![false, false, false, false]);
    }
}
