//! Measurement of a frame against the exact reference, in one place for `render`, `demo`,
//! `bench` and the tests: the reference frame ([`Measure::reference`]), the per-pass
//! timing accumulation over frames ([`Measure::render_frames`]) and the error metrics
//! with the method's hits and colour ([`Measure::measure`]). Implemented for the
//! standalone [`Renderer`]; the renderer itself only renders and reads back.

use crate::metrics::{self, ErrorMetrics, HitTexel, MapGeometry};
use crate::reference::{Hit, Ray, Reference};
use dispmap::error::Result;
use dispmap::passes::PassName;
use dispmap::passes::shadow::ShadowMode;
use dispmap::renderer::Renderer;

/// The reference for one frame: rays read from the G-buffer, exact hits, and those
/// hits shaded by the same `shade` pass.
pub struct FrameReference {
    /// Each pixel's ray (`None`: no geometry).
    pub rays: Vec<Option<Ray>>,
    /// The exact first intersections.
    pub hits: Vec<Option<Hit>>,
    /// The reference hits shaded (RGBA8).
    pub color: Vec<u8>,
}

/// The result of [`Measure::measure`].
pub struct Measurement {
    /// Median per-pass milliseconds and `total`.
    pub timings_ms: Vec<(String, f64)>,
    /// Error against the reference.
    pub error: ErrorMetrics,
    /// The hit buffer of the last frame.
    pub hits: Vec<HitTexel>,
    /// The colour image of the last frame.
    pub color: Vec<u8>,
}

/// The method's last frame against a reference: [`Measure::compare_last`].
pub struct Compared {
    /// Error against the reference.
    pub error: ErrorMetrics,
    /// The hit buffer.
    pub hits: Vec<HitTexel>,
    /// The colour image.
    pub color: Vec<u8>,
}

/// The name of the per-frame sum in [`Measure::render_frames`].
pub const TOTAL: &str = "total";

/// Measurement of a renderer's frames.
pub trait Measure {
    /// Renders `frames` frames and returns the median time of each pass and of their
    /// sum ([`TOTAL`], per frame: without the one-off passes), in pass order. The
    /// pyramid is listed with the time of its (one) build, whichever frame ran it; the
    /// upload is not listed.
    fn render_frames(&mut self, frames: u32) -> Result<Vec<(String, f64)>>;

    /// Renders the G-buffer (with the current method), computes the exact hits of its
    /// rays on the CPU and shades them. With hard shadows the reference is shaded with
    /// the exact visibility of those hits ([`Reference::occluded`], whatever the method's
    /// shadow query); with soft shadows the `shadow` pass's estimate (the same for every
    /// method) runs on them.
    fn reference(&mut self, reference: &Reference) -> Result<FrameReference>;

    /// Renders a frame with the current method and measures it against `reference`
    /// (which must come from the same scene). Returns the times, metrics, hits, colour.
    fn measure(&mut self, reference: &FrameReference, frames: u32) -> Result<Measurement>;

    /// The last rendered frame's hits and colour against `reference` (which must come
    /// from the same scene).
    fn compare_last(&self, reference: &FrameReference) -> Result<Compared>;

    /// Map size and depth scale for the metrics.
    fn map_geometry(&self) -> MapGeometry;
}

impl Measure for Renderer {
    fn render_frames(&mut self, frames: u32) -> Result<Vec<(String, f64)>> {
        let mut samples: Vec<(PassName, Vec<f64>)> = Vec::new();
        let mut totals = Vec::new();
        for _ in 0..frames.max(1) {
            let times = self.render()?;
            let per_frame: Vec<_> = times.into_iter().filter(|(n, _)| !n.is_one_off()).collect();
            totals.push(per_frame.iter().map(|(_, ms)| ms).sum());
            for (name, ms) in per_frame {
                match samples.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, v)) => v.push(ms),
                    None => samples.push((name, vec![ms])),
                }
            }
        }
        let mut out: Vec<(String, f64)> = Vec::new();
        for name in [PassName::Pyramid, PassName::Cone] {
            if let Some(ms) = self.build_ms(name) {
                out.push((name.to_string(), ms));
            }
        }
        out.extend(
            samples
                .into_iter()
                .map(|(n, v)| (n.to_string(), dispmap::timing::median(&v))),
        );
        out.push((TOTAL.into(), dispmap::timing::median(&totals)));
        Ok(out)
    }

    fn reference(&mut self, reference: &Reference) -> Result<FrameReference> {
        self.render()?;
        let rays = self.read_rays()?;
        let hits = reference.trace(&rays);
        let texels: Vec<HitTexel> = hits
            .iter()
            .map(|h| match h {
                Some(h) => [h.uv[0] as f32, h.uv[1] as f32, h.height as f32, 0.0],
                None => [0.0, 0.0, dispmap::abi::NO_HIT_HEIGHT, 0.0],
            })
            .collect();
        let color = if self.settings().shadows.mode == ShadowMode::Hard {
            // Hard shadows have an exact answer: the reference is shaded with it,
            // whichever method (and shadow query) this renderer runs.
            let (normal, tangent) = self.read_frames()?;
            let scene = self.settings().scene;
            let light = scene.light_direction();
            let visibility = crate::reference::reference_visibility(
                reference,
                &hits,
                &normal,
                &tangent,
                [light.x, light.y, light.z],
                scene.depth_scale,
            );
            self.shade_hits_with(&texels, Some(&visibility))?
        } else {
            // Off, or soft (the same estimate for every method): the pass itself.
            self.shade_hits(&texels)?
        };
        Ok(FrameReference { rays, hits, color })
    }

    fn measure(&mut self, reference: &FrameReference, frames: u32) -> Result<Measurement> {
        let timings_ms = self.render_frames(frames)?;
        let Compared { error, hits, color } = self.compare_last(reference)?;
        Ok(Measurement {
            timings_ms,
            error,
            hits,
            color,
        })
    }

    fn map_geometry(&self) -> MapGeometry {
        let [w, h] = self.pass().map_size();
        MapGeometry {
            map_width: w,
            map_height: h,
            depth_scale: self.settings().scene.depth_scale as f64,
        }
    }

    fn compare_last(&self, reference: &FrameReference) -> Result<Compared> {
        let hits = self.read_hits()?;
        let color = self.read_color()?;
        let mut error =
            metrics::hit_errors(&hits, &reference.hits, &reference.rays, self.map_geometry());
        error.psnr_db = metrics::psnr_rgba8(&color, &reference.color);
        Ok(Compared { error, hits, color })
    }
}
