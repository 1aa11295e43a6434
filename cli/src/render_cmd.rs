//! `dispmap render` of a single surface: its inputs (flags or a scene file, the memory
//! checked before the map is read), the frames, and every output written together.

use crate::args::{RenderArgs, validate_settings};
use crate::metrics_report::{CornerPass, CoverageReport, MetricsReport, NO_PIXELS};
use crate::{finish_with, render_objects};
use anyhow::{Context as _, Result, bail};
use clap::ArgMatches;
use clap::parser::ValueSource;
use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::HeightField;
use dispmap::method::Method;
use dispmap::passes::shadow::ShadowMode;
use dispmap::renderer::{RenderSettings, Renderer, SceneAssets};
use dispmap::scene::Geometry;
use dispmap_cli::heatmap;
use dispmap_cli::measure::Measure as _;
use dispmap_cli::reference::Reference;
use dispmap_cli::{memory, output};
use std::path::Path;
use std::sync::Arc;

/// The largest depth scale at which `exact`, `dig-guarded` and `cone-exact` are measured
/// to agree with the reference as the accuracy tests require (at most 0.04% of pixels
/// more than a texel off on the mountains map at 1-60 degrees, docs/guarantees.md); above
/// it a warning is printed.
pub(crate) const EXACT_DEPTH_SCALE: f32 = 10.0;

/// The height map, settings and scene assets of `render`: from --scene (its values,
/// overridden by the flags given) or from the flags alone. What the command line
/// overrides is not loaded (--heightmap: the scene's map; --geometry: its mesh); the
/// run's memory is estimated and checked before the map is read (a file's header gives
/// its size).
pub(crate) fn render_inputs(
    args: &RenderArgs,
    matches: &ArgMatches,
) -> Result<(HeightField, String, RenderSettings, SceneAssets)> {
    use dispmap_cli::scene_file::{MapSource, SceneFile};
    let method_given = matches.value_source("method") == Some(ValueSource::CommandLine);
    let given_map = match (&args.heightmap, args.convention) {
        (Some(path), Some(convention)) => Some(MapSource::File {
            path: path.clone(),
            convention,
        }),
        _ => None,
    };
    let (settings, source, scene) = match &args.scene {
        None => {
            let Some(source) = given_map else {
                bail!("--heightmap and --convention are needed without --scene");
            };
            let settings = args.common.settings(args.method);
            validate_settings(&settings)?;
            (settings, source, None)
        }
        Some(scene_path) => {
            let file = SceneFile::read(scene_path)?;
            if file.has_objects() {
                let (field, label, settings, assets, _) =
                    render_objects::inputs(args, matches, &file, scene_path)?;
                return Ok((field, label, settings, assets));
            }
            let mut settings = file.settings(scene_path)?;
            args.common.override_scene(
                &mut settings,
                &file,
                method_given.then_some(args.method),
                matches,
            );
            validate_settings(&settings)?;
            let source = given_map.unwrap_or_else(|| file.heightmap_source(scene_path));
            (settings, source, Some((file, scene_path)))
        }
    };
    // The map's header, then a scene's mesh (not loaded when --geometry overrides it):
    // both measured before either is read, counted in the estimate.
    let header = match &source {
        MapSource::File { path, .. } => Some(HeightField::probe(path)?),
        MapSource::Bundled { .. } => None,
    };
    let mesh_path = match &scene {
        Some((file, path)) if settings.scene.geometry == Geometry::Mesh => file
            .mesh
            .as_ref()
            .map(|m| path.parent().unwrap_or(Path::new(".")).join(m)),
        _ => None,
    };
    let mesh = match &mesh_path {
        Some(m) => dispmap_cli::mesh_file::measure(m)?,
        None => memory::MeshSize::default(),
    };
    // The scene's albedo and normal maps, from their headers.
    let images = match &scene {
        Some((file, path)) => dispmap_cli::scene_objects::measure_images(
            [&file.material],
            path.parent().unwrap_or(Path::new(".")),
        )?,
        None => memory::MaterialMaps::default(),
    };
    let scene_path = scene.as_ref().map(|(_, path)| path.to_path_buf());
    let check_memory = |map: memory::MapSize, mesh: memory::MeshSize| {
        let frame = [settings.width, settings.height];
        let what = format!(
            "rendering {}x{} on the {}x{} map {}{}{}",
            frame[0],
            frame[1],
            map.size[0],
            map.size[1],
            source.label(),
            match &mesh_path {
                Some(m) => format!(
                    " with the mesh {} ({} vertices, {} triangles)",
                    m.display(),
                    mesh.vertices,
                    mesh.triangles
                ),
                None => String::new(),
            },
            if args.metrics.is_some() {
                " with the reference (--metrics)"
            } else {
                ""
            }
        );
        let what = match &scene_path {
            Some(path) if images != memory::MaterialMaps::default() => format!(
                "{what} with the albedo and normal maps of {}",
                path.display()
            ),
            _ => what,
        };
        let extras = memory::Extras {
            reference: args.metrics.is_some(),
            heatmap: args.heatmap.is_some() || args.interval_map.is_some(),
            depth: args.depth_out.is_some(),
            maps: memory::MethodMaps::of(
                settings.method,
                settings.shadows.mode == ShadowMode::Hard,
            ),
            mesh,
            images,
            curved: memory::Curved {
                on: args.curved,
                walked_triangles: memory::Curved::object_triangles(
                    args.curved,
                    settings.scene.geometry,
                    Some(settings.method),
                    &mesh,
                ),
            },
        };
        let estimate = memory::estimate(map, frame, extras);
        memory::check(&estimate, args.common.max_memory, &what)
    };
    if let Some(header) = &header {
        check_memory(memory::MapSize::from_header(header), mesh)?;
    }
    let field = source.load()?;
    if let Some(part) = field.part() {
        eprintln!(
            "note: {} has several parts: the height is read from {part} (the first part \
             with a Y channel, else with R, G and B, else with R; docs/scenes.md)",
            source.label()
        );
    }
    if let MapSource::Bundled { .. } = &source {
        check_memory(memory::MapSize::loaded(&field), mesh)?;
    }
    let assets = match scene {
        Some((file, path)) => file.assets(path, settings.scene.geometry == Geometry::Mesh)?,
        None => SceneAssets::default(),
    };
    // The mesh as parsed (an OBJ's vertex count was an estimate): its memory while
    // rendering, before anything is uploaded.
    if let Some(m) = &assets.mesh {
        let parsed = memory::MeshSize {
            file_bytes: 0,
            vertices: m.vertices.len() as u64,
            triangles: m.indices.len() as u64 / 3,
        };
        check_memory(memory::MapSize::loaded(&field), parsed)?;
    }
    Ok((field, source.label(), settings, assets))
}

pub(crate) fn render(
    options: &ContextOptions,
    args: &RenderArgs,
    matches: &ArgMatches,
) -> Result<()> {
    args.common.check()?;
    // Every output is checked before any work (before the inputs are read), its bytes
    // kept until all are made, and all are written together at the end (nothing is
    // written if any fails).
    let mut outputs = output::Outputs::new();
    let checks = [
        ("--out", args.out.as_ref(), output::Format::Png),
        ("--metrics", args.metrics.as_ref(), output::Format::Json),
        ("--heatmap", args.heatmap.as_ref(), output::Format::Png),
        (
            "--interval-map",
            args.interval_map.as_ref(),
            output::Format::Png,
        ),
        (
            "--depth-out",
            args.depth_out.as_ref(),
            output::Format::Depth,
        ),
    ];
    for (option, path, format) in checks {
        if let Some(path) = path {
            outputs
                .check(option, path, format)
                .with_context(|| format!("invalid {option}"))?;
        }
    }
    // Checked before any work, for every kind of scene.
    if let Some(max) = args.heatmap_max
        && !(max.is_finite() && max > 0.0)
    {
        bail!("invalid --heatmap-max: {max} is not a positive finite number");
    }
    if let Some(path) = &args.scene {
        let file = dispmap_cli::scene_file::SceneFile::read(path)?;
        if file.has_objects() {
            if args.samples > 1 {
                bail!(
                    "invalid --samples {}: a scene of several objects ({}) renders one \
                     sample per pixel",
                    args.samples,
                    path.display()
                );
            }
            return render_objects::render(options, args, matches, outputs, &file, path);
        }
    }
    let (field, heightmap_label, settings, assets) = render_inputs(args, matches)?;
    if matches!(
        settings.method,
        Method::Exact | Method::DigGuarded | Method::ConeExact | Method::Pyramid
    ) && settings.scene.depth_scale > EXACT_DEPTH_SCALE
    {
        eprintln!(
            "warning: --depth-scale {} is above {EXACT_DEPTH_SCALE}: {}'s agreement with the \
             exact reference is not guaranteed there (rays near the horizon whose hits lie \
             thousands of tiles away, beyond the f32 hit buffer's texel precision, or that \
             reach the traversal's step cap; measured on the mountains map, 1-60 degrees: \
             up to 0.55% of pixels more than a texel off at 30, 0.13% at 100, 0.97% at \
             300, 3.7% at 1000; docs/guarantees.md)",
            settings.scene.depth_scale, settings.method
        );
    }
    let dig = settings.method.needs().dig_corners;
    if args.interval_map.is_some() && !dig {
        bail!(
            "invalid --interval-map: method {} has no depth interval grid (only dig and \
             dig-guarded have one)",
            settings.method
        );
    }
    let ctx = Arc::new(Context::headless(options)?);
    // Everything that uses the device, then `finish_with` checks validation whether it
    // succeeded or was refused.
    let result = (|| -> Result<()> {
        dispmap_cli::frame_limit::check(&ctx, settings.width, settings.height, "--size")?;
        let mut renderer = Renderer::with_assets(&ctx, &field, settings, &assets)?;
        renderer.set_depth_output(args.depth_out.is_some())?;
        renderer.set_curved(args.curved)?;
        // A curved mesh can show itself behind a miss (a torus's far side behind the
        // carved top of its near tube): the behind layer draws it.
        if args.curved
            && !args.no_behind
            && !matches!(
                settings.scene.geometry,
                dispmap::scene::Geometry::TiledPlane | dispmap::scene::Geometry::Quad
            )
        {
            renderer.set_behind(true)?;
        }
        let mut coverage = None;
        let (timings, color, error, hits, rays) = if args.metrics.is_some() {
            let reference = Reference::new(&field, settings.scene.addressing());
            let frame_ref = renderer.reference(&reference)?;
            coverage = Some(CoverageReport {
                centre_rays: renderer.reference_rays()?.analytic,
                drawn_without_ray: frame_ref.drawn_only,
                ray_without_draw: frame_ref.ray_only,
            });
            let m = renderer.measure(&frame_ref, args.common.frames)?;
            (m.timings_ms, m.color, Some(m.error), m.hits, frame_ref.rays)
        } else {
            let timings = renderer.render_frames(args.common.frames)?;
            let (hits, rays) = if args.heatmap.is_some() {
                (renderer.read_hits()?, renderer.read_rays()?)
            } else {
                (Vec::new(), Vec::new())
            };
            (timings, renderer.read_color()?, None, hits, rays)
        };
        let silhouette = match (&args.metrics, mesh_of(&settings, &assets)) {
            (Some(_), Some(mesh)) => {
                let behind = renderer.read_behind_hits()?;
                Some(silhouette_agreement(
                    &mesh,
                    &field,
                    &settings,
                    &hits,
                    behind.as_deref(),
                ))
            }
            _ => None,
        };
        let covered = heatmap::coverage(&hits, Some(&rays));
        let trace_iterations = heatmap::iteration_stats(&hits, &covered);
        let corners = if dig && (args.metrics.is_some() || args.interval_map.is_some()) {
            renderer.read_corners()?
        } else {
            None
        };
        if let Some(out) = &args.out {
            let color = if args.samples > 1 {
                supersampled(&ctx, &field, settings, &assets, args)?
            } else {
                color
            };
            let png = output::png_bytes(out, settings.width, settings.height, &color)?;
            outputs.stage(out, png)?;
        }
        if let Some(path) = &args.heatmap {
            let rgba = heatmap::iteration_heatmap(&hits, &covered, args.heatmap_max)?;
            let png = output::png_bytes(path, settings.width, settings.height, &rgba)?;
            outputs.stage(path, png)?;
        }
        if let Some(path) = &args.depth_out {
            let depth = renderer
                .read_depth()?
                .context("the renderer kept no corrected depth")?;
            let bytes = output::depth_bytes(path, settings.width, settings.height, &depth)?;
            outputs.stage(path, bytes)?;
        }
        if let Some(path) = &args.interval_map {
            let (grid, corners) = corners
                .as_ref()
                .context("the renderer kept no DIG corner grid")?;
            let intervals = heatmap::block_intervals(*grid, corners, settings.params.dig_eps())?;
            let rgba = heatmap::interval_map(
                &intervals,
                heatmap::block_count(*grid),
                settings.params.block,
                [settings.width, settings.height],
            )?;
            let png = output::png_bytes(path, settings.width, settings.height, &rgba)?;
            outputs.stage(path, png)?;
        }
        if let Some(c) = coverage
            .as_ref()
            .filter(|c| c.drawn_without_ray + c.ray_without_draw > 0)
        {
            eprintln!(
                "note: coverage: {} pixels drawn whose centre ray misses the surface (not \
                 compared), {} centre-ray hits not drawn (compared)",
                c.drawn_without_ray, c.ray_without_draw
            );
        }
        if let (Some(path), Some(error), Some(coverage)) = (&args.metrics, error, coverage) {
            let report = MetricsReport {
                method: settings.method.name(),
                steps: settings.params.steps,
                refine_steps: settings.params.refine_steps,
                lod_threshold: settings.params.lod_threshold,
                width: settings.width,
                height: settings.height,
                frames: args.common.frames,
                heightmap: heightmap_label.clone(),
                depth_scale: settings.scene.depth_scale,
                camera_elevation: settings.scene.camera.elevation_deg,
                shadows: settings.shadows.mode.name(),
                device: &ctx.info().name,
                driver: &ctx.info().driver,
                timings_ms: timings.iter().cloned().collect(),
                error: (&error).into(),
                warning: (error.compared_pixels == 0).then(|| NO_PIXELS.to_owned()),
                nonfinite_pixels: error.nonfinite_pixels,
                coverage,
                iterations: trace_iterations.into(),
                corner_pass: corners
                    .as_ref()
                    .map(|(_, c)| CornerPass::new(heatmap::corner_stats(c), &trace_iterations)),
                silhouette: silhouette.map(Into::into),
            };
            let json = serde_json::to_string_pretty(&report)?;
            outputs.stage(path, json.into_bytes())?;
        }
        let summary = timings_line(&timings);
        let mut lines = vec![summary];
        if let Some(e) = error.as_ref().filter(|e| e.compared_pixels == 0) {
            eprintln!("warning: {NO_PIXELS} (non-finite {})", e.nonfinite_pixels);
        } else if let Some(e) = error {
            lines.push(format!(
                "error: mean {:.3} texels, p99 {:.3}, max {:.3}, artifacts {:.3}%, PSNR {:.2} dB, non-finite {}",
                e.mean_texels,
                e.p99_texels,
                e.max_texels,
                100.0 * e.artifact_fraction,
                e.psnr_db,
                e.nonfinite_pixels
            ));
        }
        if let Some(s) = silhouette {
            lines.push(format!(
                "silhouette: {:.2}% of {} pixels near an outline hit or miss as the tessellated \
                 mesh does",
                100.0 * s.share(),
                s.band
            ));
        }
        print_summary(args, &lines);
        Ok(())
    })();
    // Validation clean, then every output at once.
    finish_with(ctx, result)?;
    outputs.commit()?;
    Ok(())
}

/// The one mesh of a scene of one geometry: generated (cube, sphere, torus) or loaded.
fn mesh_of(settings: &RenderSettings, assets: &SceneAssets) -> Option<dispmap::mesh::Mesh> {
    assets
        .mesh
        .clone()
        .or_else(|| settings.scene.geometry.generated_mesh())
}

/// The frame's hit or miss near the outlines against the displaced mesh tessellated and
/// traced along each pixel's f64 centre ray (`dispmap_cli::silhouette`). A pixel hits when
/// its first layer's trace (`hits`) or, where that missed, the behind layer's (`behind`,
/// the next surface along the view ray) meets the surface.
fn silhouette_agreement(
    mesh: &dispmap::mesh::Mesh,
    field: &HeightField,
    settings: &RenderSettings,
    hits: &[dispmap_cli::metrics::HitTexel],
    behind: Option<&[dispmap_cli::metrics::HitTexel]>,
) -> dispmap_cli::silhouette::OutlineAgreement {
    use dispmap_cli::silhouette::{DisplacedMesh, outline_agreement};
    let camera = settings.scene.frame_camera(settings.width, settings.height);
    let surface = DisplacedMesh::new(
        mesh,
        dispmap::glam::DMat4::IDENTITY,
        field,
        settings.scene.addressing(),
        f64::from(settings.scene.depth_scale),
    );
    let (w, h) = (settings.width, settings.height);
    let rays: Vec<_> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| (camera.rays.eye, camera.rays.direction(x, y)))
        .collect();
    let reference: Vec<bool> = surface
        .first_hits(&rays)
        .iter()
        .map(Option::is_some)
        .collect();
    let frame: Vec<bool> = hits
        .iter()
        .enumerate()
        .map(|(i, t)| t[2] >= 0.0 || behind.is_some_and(|b| b[i][2] >= 0.0))
        .collect();
    outline_agreement(&reference, &frame, w as usize, h as usize)
}

/// Prints `render`'s console summary: with `--out -` (or `--metrics -`) standard output
/// carries the file, so the summary goes to standard error instead.
pub(crate) fn print_summary(args: &RenderArgs, lines: &[String]) {
    let to_stdout = [&args.out, &args.metrics]
        .iter()
        .any(|p| p.as_deref() == Some(Path::new("-")));
    for line in lines {
        if to_stdout {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    }
}

/// The per-pass times as one line.
pub(crate) fn timings_line(timings: &[(String, f64)]) -> String {
    let parts: Vec<String> = timings
        .iter()
        .map(|(name, ms)| format!("{name} {ms:.3} ms"))
        .collect();
    format!("GPU time (median): {}", parts.join(", "))
}

/// The `--out` image with `args.samples` samples per pixel: the frame rendered by a
/// second renderer at `k = sqrt(samples)` times the size in each direction (each sample
/// its own pixel-centre ray), and each `k x k` block averaged in linear light. Its
/// memory is checked like the frame's before it is allocated.
fn supersampled(
    ctx: &Arc<Context>,
    field: &HeightField,
    settings: RenderSettings,
    assets: &SceneAssets,
    args: &RenderArgs,
) -> Result<Vec<u8>> {
    let k = args.samples.isqrt();
    let mut big = settings;
    (big.width, big.height) = (settings.width * k, settings.height * k);
    dispmap_cli::frame_limit::check(ctx, big.width, big.height, "--samples")?;
    let extras = memory::Extras {
        maps: memory::MethodMaps::of(settings.method, settings.shadows.mode == ShadowMode::Hard),
        ..memory::Extras::default()
    };
    let estimate = memory::estimate(
        memory::MapSize::loaded(field),
        [big.width, big.height],
        extras,
    );
    memory::check(
        &estimate,
        args.common.max_memory,
        &format!(
            "rendering {}x{} for --samples {}",
            big.width, big.height, args.samples
        ),
    )?;
    let mut renderer = Renderer::with_assets(ctx, field, big, assets)?;
    renderer.render_frames(1)?;
    let rgba = renderer.read_color()?;
    Ok(output::downsample_srgb(
        &rgba,
        [big.width as usize, big.height as usize],
        k as usize,
    ))
}
