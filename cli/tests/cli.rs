//! The `dispmap` binary: the metrics JSON, validation, and clear errors on bad output
//! options (the table of bad inputs is tests/bad_input.rs).

use std::path::{Path, PathBuf};
use std::process::Command;

fn dispmap() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dispmap"));
    c.env("DISPMAP_VALIDATION", "1");
    c
}

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("assets/heightmaps")
        .join(name)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dispmap-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn render_writes_png_and_metrics_json() {
    let dir = scratch("render");
    let (png, json) = (dir.join("r.png"), dir.join("r.json"));
    let out = dispmap()
        .args(["render", "--heightmap"])
        .arg(asset("rocks_depth.jpg"))
        .args([
            "--convention",
            "depth",
            "--method",
            "relief",
            "--steps",
            "128",
        ])
        .args([
            "--size",
            "256x144",
            "--camera-elevation",
            "5",
            "--frames",
            "2",
        ])
        .arg("--out")
        .arg(&png)
        .arg("--metrics")
        .arg(&json)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        !stderr.contains("Validation"),
        "validation messages: {stderr}"
    );
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (256, 144));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["method"], "relief");
    assert_eq!(v["steps"], 128);
    assert_eq!(v["width"], 256);
    assert_eq!(v["height"], 144);
    assert!(v["device"].as_str().is_some_and(|d| !d.is_empty()));
    for pass in ["gbuffer", "trace", "shade", "total"] {
        let ms = v["timings_ms"][pass].as_f64().unwrap_or(-1.0);
        assert!(ms > 0.0, "timings_ms.{pass} = {ms}");
    }
    for key in [
        "mean_texels",
        "p99_texels",
        "max_texels",
        "artifact_fraction",
        "psnr_db",
    ] {
        assert!(
            v["error"][key].as_f64().is_some_and(f64::is_finite),
            "error.{key}"
        );
    }
    assert_eq!(v["nonfinite_pixels"], 0);
}

#[test]
fn info_names_the_device() {
    let out = dispmap().arg("info").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("timestamp period"), "{text}");
    assert!(text.contains("timestamp valid bits"), "{text}");
}

#[test]
fn device_is_chosen_by_name_and_index() {
    let by_index = dispmap().args(["--device", "0", "info"]).output().unwrap();
    assert!(by_index.status.success());
    let name = String::from_utf8_lossy(&by_index.stdout)
        .lines()
        .find_map(|l| l.strip_prefix("device:").map(|s| s.trim().to_owned()))
        .unwrap();
    let word = name.split_whitespace().next().unwrap().to_lowercase();
    let by_name = dispmap()
        .arg("info")
        .env("DISPMAP_DEVICE", &word)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&by_name.stdout).contains(&name));
    let missing = dispmap()
        .args(["--device", "no-such-gpu", "info"])
        .output()
        .unwrap();
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no-such-gpu"));
}

/// Each bad input fails with a message naming it, and leaves no output file.
/// `render` with the rocks map at a tiny size, the given extra arguments, PNG `out`.
fn render_small(method: &str, out: &Path, extra: &[&std::ffi::OsStr]) -> std::process::Output {
    dispmap()
        .args(["render", "--heightmap"])
        .arg(asset("rocks_depth.jpg"))
        .args(["--convention", "depth", "--method", method])
        .args(["--size", "64x48", "--frames", "1", "--steps", "32"])
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn dig_writes_heatmap_interval_map_and_corner_iterations() {
    let dir = scratch("dig-maps");
    let (png, heat, intervals, json) = (
        dir.join("d.png"),
        dir.join("h.png"),
        dir.join("i.png"),
        dir.join("m.json"),
    );
    let out = render_small(
        "dig",
        &png,
        &[
            "--heatmap".as_ref(),
            heat.as_ref(),
            "--interval-map".as_ref(),
            intervals.as_ref(),
            "--metrics".as_ref(),
            json.as_ref(),
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    for path in [&png, &heat, &intervals] {
        let img = image::open(path).unwrap();
        assert_eq!((img.width(), img.height()), (64, 48), "{}", path.display());
    }
    // The heat map uses more than one colour; the interval map is grey or red.
    let heat = image::open(&heat).unwrap().to_rgb8();
    let first = heat.get_pixel(0, 0);
    assert!(heat.pixels().any(|p| p != first), "flat heat map");
    let intervals = image::open(&intervals).unwrap().to_rgb8();
    assert!(
        intervals
            .pixels()
            .all(|p| p.0 == [255, 0, 0] || (p[0] == p[1] && p[1] == p[2]))
    );
    assert!(
        intervals.pixels().any(|p| p.0 != [255, 0, 0]),
        "no block has an interval"
    );
    let v = read_json(&json);
    let it = &v["iterations"];
    let (mean, p99, max) = (
        it["mean"].as_f64().unwrap(),
        it["p99"].as_f64().unwrap(),
        it["max"].as_f64().unwrap(),
    );
    assert!(mean > 0.0 && max >= p99 && p99 >= mean, "{it}");
    let cp = &v["corner_pass"];
    let corners = cp["corners"].as_u64().unwrap();
    assert_eq!(corners, (64 / 4 + 1) * (48 / 4 + 1));
    let total = cp["total"].as_f64().unwrap();
    assert!(total > 0.0, "{cp}");
    assert!((cp["mean"].as_f64().unwrap() - total / corners as f64).abs() < 1e-9);
    let with = cp["total_with_corners"].as_f64().unwrap();
    assert!(
        (with - total - it["total"].as_f64().unwrap()).abs() < 1e-6,
        "{v}"
    );
    let ms = v["timings_ms"]["dig_corners"].as_f64().unwrap_or(-1.0);
    assert!(ms > 0.0, "timings_ms.dig_corners = {ms}");
}

#[test]
fn interval_map_needs_a_dig_method() {
    let dir = scratch("interval-relief");
    let (png, intervals) = (dir.join("r.png"), dir.join("i.png"));
    let out = render_small(
        "relief",
        &png,
        &["--interval-map".as_ref(), intervals.as_ref()],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("--interval-map"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!png.exists() && !intervals.exists());
}

#[test]
fn exact_reports_the_pyramid_build_and_no_corner_pass() {
    let dir = scratch("exact");
    let (png, json) = (dir.join("e.png"), dir.join("e.json"));
    let out = render_small("exact", &png, &["--metrics".as_ref(), json.as_ref()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let v = read_json(&json);
    let ms = v["timings_ms"]["pyramid"].as_f64().unwrap_or(-1.0);
    assert!(ms > 0.0, "timings_ms.pyramid = {ms}");
    assert!(v.get("corner_pass").is_none(), "{v}");
    assert!(v["iterations"]["max"].as_f64().unwrap() > 0.0);
}

#[test]
fn unwritable_heatmap_is_named_and_nothing_is_written() {
    let dir = scratch("bad-heatmap");
    let png = dir.join("out.png");
    // A folder that does not exist (inside the scratch folder, so no run can have made it).
    let missing = dir.join("no-such-dir").join("h.png");
    let out = render_small("relief", &png, &["--heatmap".as_ref(), missing.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("--heatmap"), "{stderr}");
    assert!(stderr.contains("no-such-dir"), "{stderr}");
    assert!(!png.exists());
    let folder = dir.join("a-folder");
    std::fs::create_dir_all(&folder).unwrap();
    let out = render_small("relief", &png, &["--heatmap".as_ref(), folder.as_ref()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--heatmap"));
    assert!(!png.exists());
    let out = render_small(
        "relief",
        &png,
        &[
            "--heatmap".as_ref(),
            dir.join("h.png").as_os_str(),
            "--heatmap-max".as_ref(),
            "0".as_ref(),
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--heatmap-max"));
    assert!(!png.exists() && !dir.join("h.png").exists());
}

/// `dispmap render --method M` works for every method: a PNG, metrics with no
/// non-finite pixel, and the passes the method needs (and only those) in the timings.
#[test]
fn render_works_for_every_method() {
    let dir = scratch("every-method");
    for &method in dispmap::method::Method::ALL {
        let name = method.name();
        let (png, json) = (
            dir.join(format!("{name}.png")),
            dir.join(format!("{name}.json")),
        );
        let out = render_small(name, &png, &["--metrics".as_ref(), json.as_ref()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {stderr}");
        assert!(image::open(&png).is_ok(), "{name}: no PNG");
        let v = read_json(&json);
        assert_eq!(v["method"], name, "{v}");
        assert_eq!(v["nonfinite_pixels"], 0, "{name}: {v}");
        let needs = method.needs();
        let timings = &v["timings_ms"];
        assert_eq!(
            timings.get("pyramid").is_some(),
            needs.pyramid.is_some(),
            "{name}: {timings}"
        );
        assert_eq!(
            timings.get("dig_corners").is_some(),
            needs.dig_corners,
            "{name}: {timings}"
        );
    }
}

#[test]
fn demo_with_bad_options_prints_and_creates_nothing() {
    let dir = scratch("demo-bad-steps").join("out");
    let out = dispmap()
        .arg("demo")
        .arg("--steps=0")
        .arg("--out-dir")
        .arg(&dir)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("steps") && stderr.contains("0 is outside"),
        "{stderr}"
    );
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!dir.exists(), "{} was created", dir.display());
}

/// Validation enabled the common way (`VK_INSTANCE_LAYERS`, alone or beside
/// `DISPMAP_VALIDATION`): the loader's notices that it inserted the layer are logged, not
/// counted, so the commands succeed; a value of `DISPMAP_VALIDATION` that is neither on
/// nor off is refused by name instead of meaning "off".
#[test]
fn loader_notices_do_not_fail_commands_and_the_switch_is_checked() {
    let dir = scratch("loader");
    for dispmap_validation in [None, Some("1")] {
        let command = || {
            let mut c = Command::new(env!("CARGO_BIN_EXE_dispmap"));
            c.env("VK_INSTANCE_LAYERS", "VK_LAYER_KHRONOS_validation");
            c.env_remove("DISPMAP_VALIDATION");
            if let Some(v) = dispmap_validation {
                c.env("DISPMAP_VALIDATION", v);
            }
            c
        };
        let out = command().arg("info").output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{dispmap_validation:?}: {stderr}");
        let png = dir.join("r.png");
        let out = command()
            .args(["render", "--heightmap"])
            .arg(asset("rocks_depth.jpg"))
            .args([
                "--convention",
                "depth",
                "--size",
                "32x32",
                "--frames",
                "1",
                "--out",
            ])
            .arg(&png)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{dispmap_validation:?}: {stderr}");
    }
    for bad in ["2", "enable"] {
        let out = Command::new(env!("CARGO_BIN_EXE_dispmap"))
            .env("DISPMAP_VALIDATION", bad)
            .arg("info")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success(),
            "DISPMAP_VALIDATION={bad} was accepted"
        );
        assert!(
            stderr.contains("DISPMAP_VALIDATION") && stderr.contains(bad),
            "{stderr}"
        );
    }
}

/// `--out -` writes the PNG to standard output (the summary goes to standard error), and
/// `--metrics` alone needs no `--out`.
#[test]
fn out_to_stdout_and_metrics_without_an_image() {
    let dir = scratch("stdout");
    let base = |c: &mut Command| {
        c.args(["render", "--heightmap"])
            .arg(asset("rocks_depth.jpg"))
            .args(["--convention", "depth", "--size", "32x32", "--frames", "1"]);
    };
    let mut c = dispmap();
    base(&mut c);
    let out = c.args(["--out", "-"]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let png = image::load_from_memory(&out.stdout).expect("a PNG on standard output");
    assert_eq!((png.width(), png.height()), (32, 32));
    assert!(String::from_utf8_lossy(&out.stderr).contains("GPU time"));
    let json = dir.join("m.json");
    let mut c = dispmap();
    base(&mut c);
    let out = c.arg("--metrics").arg(&json).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read(&json).unwrap().starts_with(b"{"));
    let mut c = dispmap();
    base(&mut c);
    let out = c.output().unwrap();
    assert!(
        !out.status.success(),
        "neither --out nor --metrics was accepted"
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--out"), "{stderr}");
}

/// `render --samples 4`: the image is anti-aliased (each pixel the average of a 2x2
/// supersampled block: more distinct colours along the sphere's outline, the same
/// picture), while the metrics stay those of one ray per pixel centre, equal to the
/// `--samples 1` run's.
#[test]
fn supersampled_render_keeps_the_metrics() {
    let dir = scratch("samples");
    let run = |samples: &str| {
        let (png, json) = (
            dir.join(format!("s{samples}.png")),
            dir.join(format!("s{samples}.json")),
        );
        let out = dispmap()
            .args(["render", "--heightmap"])
            .arg(asset("rocks_depth.jpg"))
            .args(["--convention", "depth", "--geometry", "sphere", "--method"])
            .args(["exact", "--size", "96x54", "--samples", samples, "--out"])
            .arg(&png)
            .arg("--metrics")
            .arg(&json)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        (image::open(&png).unwrap().to_rgba8(), read_json(&json))
    };
    let (one, one_metrics) = run("1");
    let (four, four_metrics) = run("4");
    for key in ["error", "iterations", "coverage", "width", "height"] {
        assert_eq!(one_metrics[key], four_metrics[key], "{key}");
    }
    assert_eq!(one.dimensions(), four.dimensions());
    assert_ne!(one, four, "the supersampled image is the same");
    let diff: f64 = one
        .as_raw()
        .iter()
        .zip(four.as_raw())
        .map(|(a, b)| f64::from(a.abs_diff(*b)))
        .sum::<f64>()
        / one.as_raw().len() as f64;
    assert!(diff < 12.0, "not the same picture: mean difference {diff}");
    let distinct = |img: &image::RgbaImage| {
        img.pixels()
            .map(|p| p.0)
            .collect::<std::collections::HashSet<_>>()
            .len()
    };
    assert!(distinct(&four) > distinct(&one), "no intermediate colours");
    // Not a square number: refused, naming the option.
    let out = dispmap()
        .args(["render", "--heightmap"])
        .arg(asset("rocks_depth.jpg"))
        .args(["--convention", "depth", "--samples", "2", "--out"])
        .arg(dir.join("bad.png"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--samples"));
    assert!(!dir.join("bad.png").exists());
}

// ---------------------------------------------------------------------------------------
// Issue 37 (reliability, fourth round).
// ---------------------------------------------------------------------------------------

/// The console says what the metrics JSON says: a material no pixel shows (a small cube
/// inside a larger one) has null metrics in the JSON, and its console line gives no
/// artifact figure either (not "0 pixels, artifacts 0.000%").
#[test]
fn issue_37_console_and_json_agree_on_a_material_without_pixels() {
    let dir = scratch("issue37-hidden");
    let scene = dir.join("hidden.toml");
    std::fs::write(
        &scene,
        "size = [16, 16]\n\
         [[object]]\ngeometry = \"cube\"\n[object.heightmap]\n\
         [[object]]\ngeometry = \"cube\"\nscale = 0.01\n[object.heightmap]\nbundled = \"bricks\"\n",
    )
    .unwrap();
    let json = dir.join("m.json");
    let out = dispmap()
        .args(["render", "--frames", "1", "--scene"])
        .arg(&scene)
        .arg("--metrics")
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let hidden = &m["materials"][1];
    assert_eq!(hidden["pixels"], 0, "{m}");
    assert!(hidden["artifact_fraction"].is_null(), "{m}");
    let line = stdout
        .lines()
        .find(|l| l.contains("material") && l.contains("bricks"))
        .unwrap_or_else(|| panic!("no line of the hidden material in:\n{stdout}"));
    assert!(
        line.contains("0 pixels") && !line.contains('%') && line.contains("null"),
        "{line}"
    );
    // The visible material's line has the JSON's figure.
    let shown = &m["materials"][0];
    let fraction = shown["artifact_fraction"].as_f64().unwrap();
    let line = stdout
        .lines()
        .find(|l| l.contains("material") && l.contains("rocks"))
        .unwrap();
    assert!(
        line.contains(&format!("artifacts {:.3}%", 100.0 * fraction)),
        "{line} vs {shown}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Any finite azimuth turns the camera by its remainder modulo 360, reduced in f64 before
/// it is rounded: 3e9 + 30 degrees renders the very image of 150 degrees (the f32 angle
/// was 3e9, and its f32 sine disagreed with the pixel rays' f64 one).
#[test]
fn issue_37_large_azimuths_render_their_remainder() {
    let dir = scratch("issue37-azimuth");
    let render = |azimuth: &str, name: &str| {
        let png = dir.join(name);
        let out = dispmap()
            .args(["render", "--heightmap"])
            .arg(asset("rocks_depth.jpg"))
            .args([
                "--convention",
                "depth",
                "--method",
                "exact",
                "--size",
                "32x24",
                "--frames",
                "1",
                &format!("--camera-azimuth={azimuth}"),
                "--out",
            ])
            .arg(&png)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{azimuth}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        image::open(&png).unwrap().to_rgba8().into_raw()
    };
    let reduced = render("150", "a.png");
    // 3e9 = 8333333 * 360 + 120.
    assert!(render("3000000030", "b.png") == reduced, "3e9 + 30 degrees");
    assert!(
        render("-3000000030", "c.png") == render("-150", "d.png"),
        "-3e9 - 30 degrees"
    );
    std::fs::remove_dir_all(&dir).ok();
}
