//! `render --scene` of a scene with several objects (`[[object]]`,
//! `dispmap_cli::scene_objects`): one frame of every object into one G-buffer, each
//! displaced object a material of the pass, and with `--metrics` the whole frame's error
//! beside one entry per material (`materials`), each traced against its own map.

use crate::{ErrorSummary, Iterations, NO_PIXELS, RenderArgs, finish_with, timings_line};
use anyhow::{Context as _, Result, bail};
use clap::ArgMatches;
use clap::parser::ValueSource;
use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::HeightField;
use dispmap::passes::shadow::ShadowMode;
use dispmap::renderer::{ObjectAssets, RenderSettings, Renderer, SceneAssets};
use dispmap_cli::measure::{self, MaterialReference, Measure as _};
use dispmap_cli::metrics::MapGeometry;
use dispmap_cli::reference::Reference;
use dispmap_cli::scene_file::{MapSource, SceneFile};
use dispmap_cli::scene_objects::{self, MaterialSpec, ObjectSpec};
use dispmap_cli::{heatmap, memory, output};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

/// Flags that set what a scene of several objects sets per object.
const PER_OBJECT_FLAGS: [&str; 14] = [
    "method",
    "heightmap",
    "convention",
    "geometry",
    "depth_scale",
    "steps",
    "min_steps",
    "refine_steps",
    "segments",
    "block",
    "eps",
    "max_level",
    "lod_threshold",
    "interval_map",
];

/// The metrics JSON of a scene of several objects.
#[derive(Serialize)]
struct ObjectsMetrics<'a> {
    scene: String,
    objects: usize,
    width: u32,
    height: u32,
    frames: u32,
    camera_elevation: f32,
    shadows: &'a str,
    device: &'a str,
    driver: &'a str,
    timings_ms: BTreeMap<String, f64>,
    /// The whole frame: every displaced pixel, each in its own material's texels.
    error: ErrorSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    warning: Option<String>,
    nonfinite_pixels: u64,
    iterations: Iterations,
    /// One entry per displaced material (one per displaced object), in the scene's order.
    materials: Vec<MaterialMetrics>,
}

/// One material's share of the frame.
#[derive(Serialize)]
struct MaterialMetrics {
    /// Its index in the pass's table (what the G-buffer's `tangent.w` says).
    index: u32,
    /// The object (1-based, the scene file's order).
    object: usize,
    method: &'static str,
    steps: u32,
    heightmap: String,
    depth_scale: f32,
    /// Pixels of the frame that show it.
    pixels: u64,
    /// Its share of those pixels that are artifacts; `null` without pixels.
    artifact_fraction: Option<f64>,
    mean_texels: Option<f64>,
    p99_texels: Option<f64>,
    max_texels: Option<f64>,
    mean_iterations: Option<f64>,
}

impl MaterialMetrics {
    /// Its line on the console: the values of its JSON entry (no figure where the JSON
    /// has null).
    fn line(&self) -> String {
        let what = format!(
            "  material {} ({} on {}): {} pixels",
            self.index, self.method, self.heightmap, self.pixels
        );
        match self.artifact_fraction {
            Some(a) => format!("{what}, artifacts {:.3}%", 100.0 * a),
            None => format!("{what}: no pixel shows it, its metrics are null"),
        }
    }
}

/// `render`'s inputs of a scene of several objects (`render` and `view`): refuses the
/// flags the objects set themselves, applies the others to the scene's settings, checks
/// the memory bound before any map is read, loads the objects. Returns the first
/// displaced object's map and name (the renderer's primary material), the settings, the
/// assets with the objects, and the objects as resolved.
pub fn inputs(
    args: &RenderArgs,
    matches: &ArgMatches,
    file: &SceneFile,
    path: &Path,
) -> Result<(
    HeightField,
    String,
    RenderSettings,
    SceneAssets,
    Vec<ObjectSpec>,
)> {
    for id in PER_OBJECT_FLAGS {
        if matches.try_contains_id(id).unwrap_or(false)
            && matches.value_source(id) == Some(ValueSource::CommandLine)
        {
            bail!(
                "invalid --{}: {} lists objects, each with its own; set it per object in \
                 the scene file",
                id.replace('_', "-"),
                path.display()
            );
        }
    }
    let mut settings = file.settings(path)?;
    args.common
        .override_scene(&mut settings, file, None, matches);
    settings.validate()?;
    let specs = scene_objects::specs(file, path)?;
    // Every mesh's size, summed (each measured before it is loaded), and the triangles
    // curved tracing walks.
    let mut meshes = memory::MeshSize::default();
    let mut walked_triangles = 0;
    for o in &specs {
        let size = match &o.mesh {
            Some(m) => dispmap_cli::mesh_file::measure(m)?,
            None => memory::MeshSize::default(),
        };
        meshes.file_bytes += size.file_bytes;
        meshes.vertices += size.vertices;
        meshes.triangles += size.triangles;
        walked_triangles += memory::Curved::object_triangles(
            args.curved,
            o.geometry,
            o.material.as_ref().map(|m| m.settings.method),
            &size,
        );
    }
    // The albedo and normal maps (each file once, each material's GPU copy).
    let images = scene_objects::measure_images(
        specs
            .iter()
            .filter_map(|o| o.material.as_ref().map(|m| &m.maps)),
        path.parent().unwrap_or(Path::new(".")),
    )?;
    // The memory bound before any map is read (a file's header gives its size; a bundled
    // map is measured once loaded).
    let check = |sizes: &[memory::MapSize]| {
        let materials: Vec<_> = specs
            .iter()
            .filter_map(|o| o.material.as_ref())
            .zip(sizes)
            .map(|(m, &map)| memory::MaterialMemory {
                map,
                maps: memory::MethodMaps::of(
                    m.settings.method,
                    settings.shadows.mode == ShadowMode::Hard,
                ),
                dig_block: m
                    .settings
                    .method
                    .needs()
                    .dig_corners
                    .then_some(m.settings.params.block),
            })
            .collect();
        let frame = [settings.width, settings.height];
        let extras = memory::Extras {
            mesh: meshes,
            reference: args.metrics.is_some(),
            heatmap: args.heatmap.is_some(),
            depth: args.depth_out.is_some(),
            maps: memory::MethodMaps::default(),
            images,
            curved: memory::Curved {
                on: args.curved,
                walked_triangles,
            },
        };
        let what = format!(
            "rendering {}x{} with {} materials of {}{}",
            frame[0],
            frame[1],
            materials.len(),
            path.display(),
            if args.metrics.is_some() {
                " with the reference (--metrics)"
            } else {
                ""
            }
        );
        memory::check(
            &memory::estimate_objects(&materials, frame, extras),
            args.common.max_memory,
            &what,
        )
    };
    let mut headers = Vec::new();
    for m in specs.iter().filter_map(|o| o.material.as_ref()) {
        headers.push(match &m.source {
            MapSource::File { path, .. } => {
                memory::MapSize::from_header(&HeightField::probe(path)?)
            }
            // The bundled maps are at most 1025² 16-bit: counted exactly once loaded.
            MapSource::Bundled { .. } => memory::MapSize {
                size: [1025, 1025],
                texel_bytes: 2,
                load_bytes: 0,
            },
        });
    }
    check(&headers)?;
    let objects = scene_objects::load(&specs, path)?;
    let loaded: Vec<_> = objects
        .iter()
        .filter_map(|o| o.material.as_ref().map(|m| memory::MapSize::loaded(&m.0)))
        .collect();
    check(&loaded)?;
    let (field, label) = objects
        .iter()
        .zip(&specs)
        .find_map(|(o, s)| {
            Some((
                o.material.as_ref()?.0.clone(),
                s.material.as_ref()?.source.label(),
            ))
        })
        .context("no displaced object")?;
    let assets = SceneAssets {
        objects,
        ..SceneAssets::default()
    };
    let settings = assets.settings(settings);
    Ok((field, label, settings, assets, specs))
}

/// `render --scene FILE` where FILE has `[[object]]`s (`outputs` already checked).
pub fn render(
    options: &ContextOptions,
    args: &RenderArgs,
    matches: &ArgMatches,
    mut outputs: output::Outputs,
    file: &SceneFile,
    path: &Path,
) -> Result<()> {
    let (field, _, settings, assets, specs) = inputs(args, matches, file, path)?;
    let ctx = Arc::new(Context::headless(options)?);
    // Everything that uses the device, then `finish_with` checks validation whether it
    // succeeded or was refused.
    let result = (|| -> Result<()> {
        // Each object's loops against the device's budget, named by object and file.
        scene_objects::check_loop_limits(&specs, path, ctx.info().loop_limit)?;
        // Its refusals (the eye inside an object, an object's map too large) name the
        // scene file.
        let mut renderer = Renderer::with_assets(&ctx, &field, settings, &assets)
            .map_err(|e| dispmap_cli::scene_file::in_file(path, e))?;
        renderer.set_depth_output(args.depth_out.is_some())?;
        renderer.set_curved(args.curved)?;
        if args.no_behind {
            renderer.set_behind(false)?;
        }
        let materials = displaced(&renderer, &assets.objects, &specs);
        let references: Vec<Reference> = materials
            .iter()
            .map(|d| Reference::new(d.field, d.spec.settings.addressing))
            .collect();
        let material_refs: Vec<MaterialReference<'_>> = materials
            .iter()
            .zip(&references)
            .map(|(d, reference)| MaterialReference {
                index: d.index,
                reference,
                geometry: MapGeometry {
                    map_width: d.field.width(),
                    map_height: d.field.height(),
                    depth_scale: f64::from(d.spec.settings.depth_scale),
                },
            })
            .collect();
        let (timings, color, error, hits, rays) = if args.metrics.is_some() {
            let reference = measure::reference_objects(&mut renderer, &material_refs)?;
            let timings = renderer.render_frames(args.common.frames)?;
            let (compared, per_material) =
                measure::compare_objects(&renderer, &reference, &material_refs)?;
            (
                timings,
                compared.color,
                Some((compared.error, per_material)),
                compared.hits,
                reference.frame.rays,
            )
        } else {
            let timings = renderer.render_frames(args.common.frames)?;
            let (hits, rays) = if args.heatmap.is_some() {
                (renderer.read_hits()?, displaced_rays(&renderer)?)
            } else {
                (Vec::new(), Vec::new())
            };
            (timings, renderer.read_color()?, None, hits, rays)
        };
        let covered = heatmap::coverage(&hits, Some(&rays));
        let trace_iterations = heatmap::iteration_stats(&hits, &covered);
        let (width, height) = (renderer.settings().width, renderer.settings().height);
        if let Some(out) = &args.out {
            outputs.stage(out, output::png_bytes(out, width, height, &color)?)?;
        }
        if let Some(p) = &args.heatmap {
            let rgba = heatmap::iteration_heatmap(&hits, &covered, args.heatmap_max)?;
            outputs.stage(p, output::png_bytes(p, width, height, &rgba)?)?;
        }
        if let Some(p) = &args.depth_out {
            let Some(depth) = renderer.read_depth()? else {
                bail!("the renderer kept no corrected depth");
            };
            outputs.stage(p, output::depth_bytes(p, width, height, &depth)?)?;
        }
        let mut lines = vec![timings_line(&timings)];
        if let (Some(p), Some((error, per_material))) = (&args.metrics, &error) {
            let entries: Vec<MaterialMetrics> = materials
                .iter()
                .zip(per_material)
                .map(|(d, e)| {
                    let m = d.spec;
                    let some = |v: f64| (e.compared_pixels > 0).then_some(v);
                    MaterialMetrics {
                        index: d.index,
                        object: d.object,
                        method: m.settings.method.name(),
                        steps: m.settings.params.steps,
                        heightmap: m.source.label(),
                        depth_scale: m.settings.depth_scale,
                        pixels: e.compared_pixels,
                        artifact_fraction: some(e.artifact_fraction),
                        mean_texels: some(e.mean_texels),
                        p99_texels: some(e.p99_texels),
                        max_texels: some(e.max_texels),
                        mean_iterations: some(e.mean_iterations),
                    }
                })
                .collect();
            // The console says what the JSON says: the same values, null where it has
            // null.
            let summary = ErrorSummary::from(error);
            match summary.artifact_fraction {
                Some(a) => lines.push(format!(
                    "error: artifacts {:.3}% of {} displaced pixels, non-finite {}",
                    100.0 * a,
                    summary.compared_pixels,
                    error.nonfinite_pixels
                )),
                None => lines.push(format!(
                    "warning: {NO_PIXELS} (non-finite {})",
                    error.nonfinite_pixels
                )),
            }
            lines.extend(entries.iter().map(MaterialMetrics::line));
            let s = renderer.settings();
            let report = ObjectsMetrics {
                scene: path.display().to_string(),
                objects: specs.len(),
                width,
                height,
                frames: args.common.frames,
                camera_elevation: s.scene.camera.elevation_deg,
                shadows: s.shadows.mode.name(),
                device: &ctx.info().name,
                driver: &ctx.info().driver,
                timings_ms: timings.iter().cloned().collect(),
                error: summary,
                warning: (error.compared_pixels == 0).then(|| NO_PIXELS.to_owned()),
                nonfinite_pixels: error.nonfinite_pixels,
                iterations: trace_iterations.into(),
                materials: entries,
            };
            let json = serde_json::to_string_pretty(&report)?;
            outputs.stage(p, json.into_bytes())?;
        }
        crate::render_cmd::print_summary(args, &lines);
        Ok(())
    })();
    finish_with(ctx, result)?;
    outputs.commit()?;
    Ok(())
}

/// One displaced object: its material's index in the pass, the object's 1-based
/// number, its material and its map.
struct Displaced<'a> {
    index: u32,
    object: usize,
    spec: &'a MaterialSpec,
    field: &'a HeightField,
}

/// The displaced objects, in the scene's order.
fn displaced<'a>(
    renderer: &Renderer,
    objects: &'a [ObjectAssets],
    specs: &'a [ObjectSpec],
) -> Vec<Displaced<'a>> {
    renderer
        .object_materials()
        .into_iter()
        .zip(objects.iter().zip(specs))
        .enumerate()
        .filter_map(|(i, (id, (o, s)))| match (id, &s.material, &o.material) {
            (Some(id), Some(spec), Some((field, _, _))) => Some(Displaced {
                index: id.index(),
                object: i + 1,
                spec,
                field,
            }),
            _ => None,
        })
        .collect()
}

/// The rays of the displaced pixels (flat ones have none).
fn displaced_rays(renderer: &Renderer) -> Result<Vec<Option<dispmap::passes::gbuffer::Ray>>> {
    let materials = renderer.read_materials()?;
    Ok(renderer
        .read_rays()?
        .into_iter()
        .zip(materials)
        .map(|(r, m)| r.filter(|_| m.is_some()))
        .collect())
}
