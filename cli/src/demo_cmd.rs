//! `dispmap demo` (and `dispmap` alone): every default method on the bundled rocks map,
//! its images and contact sheet, and a table of times and errors.

use crate::args::{DemoArgs, validate_settings};
use crate::finish_with;
use anyhow::{Context as _, Result, bail};
use dispmap::context::{Context, ContextOptions};
use dispmap::method::Method;
use dispmap::renderer::Renderer;
use dispmap_cli::measure::Measure as _;
use dispmap_cli::reference::Reference;
use dispmap_cli::{bundled, memory, output};
use std::sync::Arc;

pub(crate) fn demo(options: &ContextOptions, args: &DemoArgs) -> Result<()> {
    args.common.check()?;
    // The default methods ([`Method::in_defaults`]: cone-exact is available by name only).
    let methods = Method::defaults();
    // Every method's settings are checked before anything is printed or created.
    for &method in &methods {
        validate_settings(&args.common.settings(method))?;
    }
    let field = bundled::rocks()?;
    let first = args.common.settings(methods[0]);
    memory::check(
        &memory::estimate(
            memory::MapSize::loaded(&field),
            [first.width, first.height],
            memory::Extras {
                reference: true,
                // One method at a time, the previous one's maps retired: at most all.
                maps: memory::MethodMaps::together(&methods),
                ..memory::Extras::default()
            },
        ),
        args.common.max_memory,
        &format!(
            "rendering {}x{} on the bundled rocks map with the reference",
            first.width, first.height
        ),
    )?;
    // The folder is checked now, created and filled at the end, all files together.
    // Each of its files too: a read-only contact_sheet.png is refused now, not after
    // every method ran.
    let mut names: Vec<String> = methods
        .iter()
        .map(|m| format!("{}.png", m.name()))
        .collect();
    names.extend(["reference.png".to_owned(), "contact_sheet.png".to_owned()]);
    output::check_folder_files(&args.out_dir, &names).context("invalid --out-dir")?;
    let mut outputs = output::Outputs::new();
    let ctx = Arc::new(Context::headless(options)?);
    // Everything that uses the device, then `finish_with` checks validation whether it
    // succeeded or was refused.
    let result = (|| -> Result<()> {
        dispmap_cli::frame_limit::check(&ctx, first.width, first.height, "--size")?;
        println!(
            "dispmap: {} on {} ({}), {}x{}, camera elevation {} deg, steps {}, median of {} frames",
            field.label(),
            ctx.info().name,
            ctx.info().driver,
            args.common.size.0,
            args.common.size.1,
            args.common.camera_elevation,
            args.common
                .steps
                .map_or("per method (secant 15, others 64)".into(), |s| s
                    .to_string()),
            args.common.frames
        );
        {
            let first = args.common.settings(methods[0]);
            let mut renderer = Renderer::new(&ctx, &field, first)?;
            let reference = Reference::new(&field, first.scene.addressing());
            let frame_ref = renderer.reference(&reference)?;
            let path = args.out_dir.join("reference.png");
            let png = output::png_bytes(&path, first.width, first.height, &frame_ref.color)?;
            outputs.stage_in(&args.out_dir, "reference.png", png)?;
            let mut tiles = vec![dispmap_cli::contact_sheet::Tile {
                label: "reference (CPU, exact)".into(),
                rgba: frame_ref.color.clone(),
            }];
            // The method column as wide as the longest name.
            let w = methods.iter().map(|m| m.name().len()).max().unwrap_or(6);
            println!(
                "\n{:<w$} {:>10} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10} {:>10} {:>9}",
                "method",
                "gbuffer",
                "trace ms",
                "shade ms",
                "total ms",
                "iters",
                "mean tx",
                "p99 tx",
                "artifact%",
                "PSNR dB"
            );
            for &method in &methods {
                let settings = args.common.settings(method);
                renderer.set_method(method, settings.params)?;
                let m = renderer.measure(&frame_ref, args.common.frames)?;
                let t = |name: &str| {
                    m.timings_ms
                        .iter()
                        .find(|(n, _)| n == name)
                        .map(|(_, ms)| *ms)
                        .unwrap_or(0.0)
                };
                let e = &m.error;
                println!(
                    "{:<w$} {:>10.3} {:>10.3} {:>10.3} {:>10.3} {:>8.1} {:>10.3} {:>10.3} {:>10.3} {:>9.2}",
                    method.name(),
                    t("gbuffer"),
                    t("trace"),
                    t("shade"),
                    t("total"),
                    e.mean_iterations,
                    e.mean_texels,
                    e.p99_texels,
                    100.0 * e.artifact_fraction,
                    e.psnr_db
                );
                if e.nonfinite_pixels > 0 {
                    bail!("{method}: {} non-finite hit texels", e.nonfinite_pixels);
                }
                let name = format!("{}.png", method.name());
                let png = output::png_bytes(
                    &args.out_dir.join(&name),
                    settings.width,
                    settings.height,
                    &m.color,
                )?;
                outputs.stage_in(&args.out_dir, &name, png)?;
                tiles.push(dispmap_cli::contact_sheet::Tile {
                    label: format!(
                        "{}  {:.2}% artifacts",
                        method.name(),
                        100.0 * e.artifact_fraction
                    ),
                    rgba: m.color,
                });
            }
            let sheet = dispmap_cli::contact_sheet::compose(&tiles, first.width, first.height, 5)?;
            let png = output::png_bytes(
                &args.out_dir.join("contact_sheet.png"),
                sheet.width,
                sheet.height,
                &sheet.rgba,
            )?;
            outputs.stage_in(&args.out_dir, "contact_sheet.png", png)?;
            println!(
                "\nimages: {} (reference.png is the exact reference, shaded; contact_sheet.png \
             shows every method beside it)",
                args.out_dir.display()
            );
        }
        Ok(())
    })();
    finish_with(ctx, result)?;
    outputs.commit()?;
    Ok(())
}
