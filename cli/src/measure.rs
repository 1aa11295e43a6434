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

/// The reference for one frame: its rays (each pixel's own f64 centre ray on the tiled
/// plane and the quad, else the G-buffer's: [`Renderer::reference_rays`]), exact hits,
/// and those hits shaded by the same `shade` pass.
pub struct FrameReference {
    /// Each pixel's ray (`None`: no geometry).
    pub rays: Vec<Option<Ray>>,
    /// Pixels the G-buffer drew whose f64 centre ray misses the surface: not compared
    /// (reported by `render --metrics`).
    pub drawn_only: usize,
    /// Pixels whose f64 centre ray meets the surface but that the G-buffer left empty:
    /// compared (a method has no ray there: an artifact where the reference hits).
    pub ray_only: usize,
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
        let traced = self.reference_rays()?;
        let (drawn_only, ray_only) = (traced.drawn_only.len(), traced.ray_only.len());
        let rays = traced.rays;
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
        Ok(FrameReference {
            rays,
            drawn_only,
            ray_only,
            hits,
            color,
        })
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

/// One displaced material of a frame of several objects: its index in the G-buffer
/// (`tangent.w`), its exact reference and its map geometry.
pub struct MaterialReference<'a> {
    /// [`dispmap::embed::MaterialId::index`].
    pub index: u32,
    /// The exact reference of its height map and addressing.
    pub reference: &'a Reference,
    /// Its map size and depth scale.
    pub geometry: MapGeometry,
}

/// The reference of a frame of several objects and which material each pixel shows.
pub struct ObjectsReference {
    /// Rays, exact hits and the shaded reference (rays `None` on flat pixels).
    pub frame: FrameReference,
    /// Each pixel's position in the materials list (`None`: no geometry or flat).
    pub pixel_material: Vec<Option<usize>>,
}

/// [`Measure::reference`] for a renderer of several objects
/// ([`Renderer::with_objects`]): each pixel's ray is traced in its own material's map
/// (grouped by the G-buffer's `tangent.w`); flat pixels have no ray. With hard shadows
/// each material's hits are shaded with their exact visibility in their own map.
pub fn reference_objects(
    renderer: &mut Renderer,
    materials: &[MaterialReference<'_>],
) -> Result<ObjectsReference> {
    use rayon::prelude::*;
    renderer.render()?;
    let by_index = |index: u32| materials.iter().position(|m| m.index == index);
    let pixel_material: Vec<Option<usize>> = renderer
        .read_materials()?
        .into_iter()
        .map(|m| m.and_then(by_index))
        .collect();
    let rays: Vec<Option<Ray>> = renderer
        .read_rays()?
        .into_iter()
        .zip(&pixel_material)
        .map(|(ray, m)| ray.filter(|_| m.is_some()))
        .collect();
    let hits: Vec<Option<Hit>> = rays
        .par_iter()
        .zip(pixel_material.par_iter())
        .map(|(ray, m)| match (ray, m) {
            (Some(ray), Some(m)) => materials[*m].reference.intersect(ray),
            _ => None,
        })
        .collect();
    let texels: Vec<HitTexel> = hits
        .iter()
        .map(|h| match h {
            Some(h) => [h.uv[0] as f32, h.uv[1] as f32, h.height as f32, 0.0],
            None => [0.0, 0.0, dispmap::abi::NO_HIT_HEIGHT, 0.0],
        })
        .collect();
    let color = if renderer.settings().shadows.mode == ShadowMode::Hard {
        let (normal, tangent) = renderer.read_frames()?;
        let light = renderer.settings().scene.light_direction();
        let mut visibility = vec![1.0f32; hits.len()];
        for (k, m) in materials.iter().enumerate() {
            let mine: Vec<Option<Hit>> = hits
                .iter()
                .zip(&pixel_material)
                .map(|(h, p)| h.filter(|_| *p == Some(k)))
                .collect();
            let v = crate::reference::reference_visibility(
                m.reference,
                &mine,
                &normal,
                &tangent,
                [light.x, light.y, light.z],
                m.geometry.depth_scale as f32,
            );
            for ((out, v), p) in visibility.iter_mut().zip(v).zip(&pixel_material) {
                if *p == Some(k) {
                    *out = v;
                }
            }
        }
        renderer.shade_hits_with(&texels, Some(&visibility))?
    } else {
        renderer.shade_hits(&texels)?
    };
    Ok(ObjectsReference {
        frame: FrameReference {
            rays,
            drawn_only: 0,
            ray_only: 0,
            hits,
            color,
        },
        pixel_material,
    })
}

/// The last frame of a renderer of several objects against `reference`: the whole
/// frame's error (each pixel in its own material's texels) and one [`ErrorMetrics`] per
/// material of `materials`, in its order (PSNR only for the whole frame).
pub fn compare_objects(
    renderer: &Renderer,
    reference: &ObjectsReference,
    materials: &[MaterialReference<'_>],
) -> Result<(Compared, Vec<ErrorMetrics>)> {
    let hits = renderer.read_hits()?;
    let color = renderer.read_color()?;
    let frame = &reference.frame;
    let pixel = &reference.pixel_material;
    // Pixels without a material have no ray: their geometry is never asked for.
    let geometry = |i: usize| materials[pixel[i].unwrap_or(0)].geometry;
    let mut error = metrics::hit_errors_with(&hits, &frame.hits, &frame.rays, geometry);
    error.psnr_db = metrics::psnr_rgba8(&color, &frame.color);
    let per_material = (0..materials.len())
        .map(|k| {
            let rays: Vec<Option<Ray>> = frame
                .rays
                .iter()
                .zip(pixel)
                .map(|(r, p)| r.filter(|_| *p == Some(k)))
                .collect();
            metrics::hit_errors(&hits, &frame.hits, &rays, materials[k].geometry)
        })
        .collect();
    Ok((Compared { error, hits, color }, per_material))
}
