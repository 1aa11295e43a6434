//! `dispmap view` under Xvfb: a scripted run (a method switch, a resize, a camera path)
//! on the machine's Vulkan device with validation on, whose last presented frame must
//! equal `dispmap render`'s frame of the same camera and method bit for bit (`--no-ui`);
//! the split view with the error overlay, with and without the on-screen panel; zoom on
//! an object; the overlay with level of detail on. Skipped, with a message saying why,
//! where no X server can be started (no `Xvfb`: Debian's `xvfb` package, which
//! scripts/setup-debian.sh installs); a failure instead where `DISPMAP_NO_SKIP=1` (CI).

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "support/skip.rs"]
mod skip;
#[path = "support/xvfb.rs"]
mod xvfb;
use xvfb::start_xvfb;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dispmap-view-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn rocks() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/heightmaps/rocks_depth.jpg")
}

fn dispmap() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dispmap"));
    c.env("DISPMAP_VALIDATION", "1");
    c
}

/// Runs `cmd`, fails on an error exit or a validation message, returns standard error.
fn run_checked(cmd: &mut Command, what: &str) -> String {
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{what} failed:\n{stderr}");
    assert!(
        !stderr.contains("Validation") && !stderr.contains("[vulkan"),
        "{what}: validation messages:\n{stderr}"
    );
    stderr
}

#[test]
fn scripted_viewer_presents_the_render_frame_bit_for_bit() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            skip::skip(
                "scripted_viewer_presents_the_render_frame_bit_for_bit",
                &why,
            );
            return;
        }
    };
    let dir = scratch("scripted");
    let (path, script, shot, reference) = (
        dir.join("camera.txt"),
        dir.join("script.txt"),
        dir.join("view.png"),
        dir.join("render.png"),
    );
    // The camera moves every frame and ends at a grazing 12 degrees.
    std::fs::write(
        &path,
        "# elevation azimuth [height]\n30 0\n25 10 0.3\n20 20\n15 30\n12 40\n",
    )
    .unwrap();
    // relief first, pom from frame 1, a smaller window from frame 2, then secant.
    std::fs::write(&script, "1 method pom\n2 resize 112x72\n3 method secant\n").unwrap();
    let stderr = run_checked(
        dispmap()
            .env("DISPLAY", &xvfb.display)
            .env_remove("WAYLAND_DISPLAY")
            .args([
                "view", "--method", "relief", "--size", "128x80", "--frames", "6", "--no-ui",
            ])
            .arg("--camera-path")
            .arg(&path)
            .arg("--script")
            .arg(&script)
            .arg("--screenshot")
            .arg(&shot),
        "dispmap view",
    );
    assert!(stderr.contains("screenshot:"), "{stderr}");
    run_checked(
        dispmap()
            .args(["render", "--heightmap"])
            .arg(rocks())
            .args([
                "--convention",
                "depth",
                "--method",
                "secant",
                "--size",
                "112x72",
            ])
            .args([
                "--camera-elevation",
                "12",
                "--camera-azimuth",
                "40",
                "--camera-height",
                "0.3",
                "--frames",
                "1",
            ])
            .arg("--out")
            .arg(&reference),
        "dispmap render",
    );
    let view = image::open(&shot).unwrap().to_rgba8();
    let render = image::open(&reference).unwrap().to_rgba8();
    assert_eq!(
        view.dimensions(),
        (112, 72),
        "the resize did not reach the frame"
    );
    assert_eq!(render.dimensions(), view.dimensions());
    // The displaced region: pixels not of the sky colour (the top-left pixel is sky at
    // this camera); it must be most of the frame for the comparison to mean anything.
    let sky = *render.get_pixel(0, 0);
    let displaced = render.pixels().filter(|p| **p != sky).count();
    assert!(
        displaced > (112 * 72) / 2,
        "only {displaced} displaced pixels"
    );
    let differing: Vec<_> = view
        .enumerate_pixels()
        .filter(|(x, y, p)| *p != render.get_pixel(*x, *y))
        .map(|(x, y, _)| (x, y))
        .collect();
    assert!(
        differing.is_empty(),
        "{} of {} pixels differ from `dispmap render`, first {:?}",
        differing.len(),
        112 * 72,
        &differing[..differing.len().min(5)]
    );
}

/// The error percentage the viewer printed for `method`.
fn printed_artifacts(stderr: &str, method: &str) -> f64 {
    let line = stderr
        .lines()
        .find(|l| l.starts_with(&format!("error overlay: {method}:")))
        .unwrap_or_else(|| panic!("no error line for {method}:\n{stderr}"));
    let after = line.split("artifacts ").nth(1).unwrap();
    after.split('%').next().unwrap().parse().unwrap()
}

/// Runs `dispmap view` under `xvfb` with `args`; returns standard error.
fn view(xvfb: &xvfb::Xvfb, args: &[&str], script: &Path, shot: &Path) -> String {
    run_checked(
        dispmap()
            .env("DISPLAY", &xvfb.display)
            .env_remove("WAYLAND_DISPLAY")
            .arg("view")
            .args(args)
            .arg("--script")
            .arg(script)
            .arg("--screenshot")
            .arg(shot),
        "dispmap view",
    )
}

#[test]
fn split_view_with_error_overlay_shows_both_methods_and_the_reference_artifacts() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            skip::skip(
                "split_view_with_error_overlay_shows_both_methods_and_the_reference_artifacts",
                &why,
            );
            return;
        }
    };
    let dir = scratch("split");
    let (script, shot, panel_shot) = (
        dir.join("script.txt"),
        dir.join("view.png"),
        dir.join("panel.png"),
    );
    std::fs::write(&script, "0 split dig-guarded\n0 divider 0.5\n1 error\n").unwrap();
    // Large enough for the panel to leave part of the frame uncovered.
    let (w, h) = (640u32, 270u32);
    let common = [
        "--steps",
        "16",
        "--camera-elevation",
        "8",
        "--size",
        "640x270",
    ];
    let view_args: Vec<&str> = ["--method", "relief", "--frames", "3"]
        .into_iter()
        .chain(common)
        .collect();
    let no_ui: Vec<&str> = view_args.iter().copied().chain(["--no-ui"]).collect();
    let stderr = view(&xvfb, &no_ui, &script, &shot);
    // The summary counts the frames asked for (the overlay's wait renders more).
    assert!(stderr.contains("frames: 3"), "{stderr}");
    let render = |method: &str| {
        let (png, json) = (
            dir.join(format!("{method}.png")),
            dir.join(format!("{method}.json")),
        );
        run_checked(
            dispmap()
                .args(["render", "--heightmap"])
                .arg(rocks())
                .args(["--convention", "depth", "--method", method, "--frames", "1"])
                .args(common)
                .arg("--out")
                .arg(&png)
                .arg("--metrics")
                .arg(&json),
            "dispmap render",
        );
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let artifacts = v["error"]["artifact_fraction"].as_f64().unwrap();
        (image::open(&png).unwrap().to_rgba8(), artifacts)
    };
    let (relief, relief_artifacts) = render("relief");
    let (dig, dig_artifacts) = render("dig-guarded");
    // The overlay's measures are the metrics of `render --metrics` for the same frame.
    for (method, want) in [("relief", relief_artifacts), ("dig-guarded", dig_artifacts)] {
        let printed = printed_artifacts(&stderr, method);
        assert!(
            (printed - 100.0 * want).abs() < 0.0006,
            "{method}: the viewer printed {printed}%, render --metrics {}%",
            100.0 * want
        );
    }
    assert!(
        relief_artifacts > 0.0,
        "relief at 16 steps and 8 degrees has artifacts"
    );
    let view_img = image::open(&shot).unwrap().to_rgba8();
    assert_eq!(view_img.dimensions(), (w, h));
    let divider = w / 2;
    let (mut marked_left, mut marked_right) = (0, 0);
    for (x, y, p) in view_img.enumerate_pixels() {
        let mark = p.0 == [255, 0, 0, 255] || p.0 == [0, 255, 255, 255];
        if x < divider {
            if mark {
                marked_left += 1;
            } else {
                assert_eq!(p, relief.get_pixel(x, y), "left side at ({x}, {y})");
            }
        } else if x < divider + 2 {
            assert_eq!(p.0, [255, 255, 255, 255], "divider at ({x}, {y})");
        } else if mark {
            marked_right += 1;
        } else {
            assert_eq!(p, dig.get_pixel(x, y), "right side at ({x}, {y})");
        }
    }
    assert!(marked_left > 0, "no artifact marked on relief's side");
    if dig_artifacts == 0.0 {
        assert_eq!(
            marked_right, 0,
            "marks on dig-guarded's side without artifacts"
        );
    }

    // The same run with the panel: in split view it docks in a column at the right
    // edge (at most 40% of the window), the sides share the columns left of it, and
    // side A, above the labels' band, is relief's frame at that width (or a mark).
    let stderr = view(&xvfb, &view_args, &script, &panel_shot);
    assert!(stderr.contains("panel: median ms per frame"), "{stderr}");
    let docked = stderr
        .lines()
        .find_map(|l| l.strip_prefix("panel: docked at the right edge, "))
        .unwrap_or_else(|| panic!("the panel did not dock:\n{stderr}"));
    let px: u32 = docked.split(' ').next().unwrap().parse().unwrap();
    assert_eq!(px, w * 2 / 5, "{docked}");
    let sides = w - px;
    let narrow = dir.join("relief-narrow.png");
    run_checked(
        dispmap()
            .args(["render", "--heightmap"])
            .arg(rocks())
            .args([
                "--convention",
                "depth",
                "--method",
                "relief",
                "--frames",
                "1",
            ])
            .args(["--steps", "16", "--camera-elevation", "8", "--size"])
            .arg(format!("{sides}x{h}"))
            .arg("--out")
            .arg(&narrow),
        "dispmap render",
    );
    let narrow = image::open(&narrow).unwrap().to_rgba8();
    let panel = image::open(&panel_shot).unwrap().to_rgba8();
    assert_eq!(panel.dimensions(), (w, h));
    let divider = (0.5 * sides as f32).round() as u32;
    let mut marked = 0;
    for y in 0..h - 36 {
        for x in 0..divider {
            let p = panel.get_pixel(x, y);
            if p.0 == [255, 0, 0, 255] || p.0 == [0, 255, 255, 255] {
                marked += 1;
            } else {
                assert_eq!(
                    p,
                    narrow.get_pixel(x, y),
                    "side A under the panel at ({x}, {y})"
                );
            }
        }
    }
    assert!(
        marked > 0,
        "no artifact marked on relief's side with the panel"
    );
    // The panel's column is drawn (text, widgets, its background).
    let drawn = (sides..w)
        .flat_map(|x| (0..h).map(move |y| (x, y)))
        .filter(|&(x, y)| panel.get_pixel(x, y).0 != [255, 255, 255, 255])
        .count() as u32;
    assert!(
        drawn * 2 > px * h,
        "only {drawn} of {} panel pixels drawn",
        px * h
    );
}

#[test]
fn zoom_moves_the_eye_on_an_object() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            skip::skip("zoom_moves_the_eye_on_an_object", &why);
            return;
        }
    };
    let dir = scratch("zoom");
    let args = [
        "--geometry",
        "sphere",
        "--method",
        "relief",
        "--steps",
        "16",
        "--size",
        "96x64",
        "--frames",
        "2",
        "--no-ui",
    ];
    let shot = |name: &str, script: &str| {
        let (file, png) = (
            dir.join(format!("{name}.txt")),
            dir.join(format!("{name}.png")),
        );
        std::fs::write(&file, script).unwrap();
        view(&xvfb, &args, &file, &png);
        image::open(&png).unwrap().to_rgba8()
    };
    // The heat map paints pixels without geometry black.
    let still = shot("still", "0 heatmap on\n");
    let closer = shot("closer", "0 heatmap on\n1 zoom 3\n");
    let farther = shot("farther", "0 heatmap on\n1 zoom -3\n");
    // The sphere fills more of the frame from closer: fewer background pixels.
    let background =
        |img: &image::RgbaImage| img.pixels().filter(|p| p.0 == [0, 0, 0, 255]).count();
    let (b_still, b_closer, b_farther) = (
        background(&still),
        background(&closer),
        background(&farther),
    );
    assert!(
        b_closer < b_still && b_still < b_farther,
        "background pixels: closer {b_closer}, start {b_still}, farther {b_farther}"
    );
}

#[test]
fn error_overlay_with_level_of_detail_counts_bump_pixels_apart() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            skip::skip(
                "error_overlay_with_level_of_detail_counts_bump_pixels_apart",
                &why,
            );
            return;
        }
    };
    let dir = scratch("lod");
    let (script, shot) = (dir.join("script.txt"), dir.join("view.png"));
    // Bricks close up: level of detail at 2 sends the farther half of the plane to bump
    // mapping and leaves the nearer half to the methods.
    std::fs::write(&script, "0 map bricks\n0 lod 2\n1 error\n").unwrap();
    let (w, h) = (256u32, 144u32);
    let stderr = view(
        &xvfb,
        &[
            "--method",
            "exact",
            "--split",
            "relief",
            "--depth-scale",
            "0.2",
            "--camera-height",
            "0.05",
            "--size",
            "256x144",
            "--frames",
            "3",
            "--no-ui",
        ],
        &script,
        &shot,
    );
    let line = |method: &str| {
        stderr
            .lines()
            .find(|l| l.starts_with(&format!("error overlay: {method}:")))
            .unwrap_or_else(|| panic!("no overlay line for {method}: {stderr}"))
            .to_owned()
    };
    // The count before `what` in a line's `, `-separated parts.
    let count = |line: &str, what: &str| -> usize {
        line.split(", ")
            .find(|p| p.contains(what))
            .and_then(|p| p.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no '{what}' count: {line}"))
    };
    let exact = line("exact");
    let sent = count(&exact, "more sent to bump mapping");
    let compared = count(&exact, "pixels");
    assert!(
        sent > 1000 && compared > 1000,
        "level of detail should split the frame: {exact}"
    );
    // exact is exact where level of detail leaves the pixel to it; relief, on the same
    // pixels, is not.
    assert_eq!(printed_artifacts(&stderr, "exact"), 0.0, "{exact}");
    assert!(printed_artifacts(&stderr, "relief") > 0.0, "{stderr}");
    // The pixels sent to bump mapping have their own colour; no artifact is marked on
    // exact's side (left of the divider).
    let img = image::open(&shot).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (w, h));
    let magenta = img.pixels().filter(|p| p.0 == [255, 0, 255, 255]).count();
    assert!(magenta > 500, "only {magenta} magenta pixels");
    let red_left = img
        .enumerate_pixels()
        .filter(|(x, _, p)| *x < w / 2 && p.0 == [255, 0, 0, 255])
        .count();
    assert_eq!(red_left, 0, "artifact pixels on exact's side");
}

#[test]
fn view_help_gives_the_viewers_defaults() {
    let out = Command::new(env!("CARGO_BIN_EXE_dispmap"))
        .args(["view", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(help.contains("[default: 960x540]"), "{help}");
    assert!(!help.contains("256x144"), "{help}");
    assert!(!help.contains("[default: 3]"), "{help}");
    assert!(help.contains("--no-ui"), "{help}");
}

/// A scene file without `size` opens at the documented default (960x540), as the bundled
/// map does; the split heat map shares one scale (the panel would show the same top on
/// both sides: checked through the pixels, one colour for one count).
#[test]
fn a_scene_without_a_size_opens_at_the_default_size() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            eprintln!("SKIPPED a_scene_without_a_size_opens_at_the_default_size: {why}");
            return;
        }
    };
    let dir = scratch("scene-size");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/rocks_sphere.toml");
    let script = dir.join("script.txt");
    std::fs::write(&script, "0 heatmap on\n").unwrap();
    let shot = dir.join("shot.png");
    let scene = scene.to_string_lossy().into_owned();
    view(
        &xvfb,
        &[
            "--scene", &scene, "--steps", "8", "--frames", "2", "--no-ui",
        ],
        &script,
        &shot,
    );
    let png = image::open(&shot).unwrap();
    assert_eq!((png.width(), png.height()), (960, 540));
}

/// A scene of several objects: the viewer names every object's material (method, map,
/// depth) on the console, as its panel lists them, not only the first one's map.
#[test]
fn a_scene_of_several_objects_lists_every_material() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            eprintln!("SKIPPED a_scene_of_several_objects_lists_every_material: {why}");
            return;
        }
    };
    let dir = scratch("materials");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/materials.toml");
    let script = dir.join("script.txt");
    std::fs::write(&script, "").unwrap();
    let scene = scene.to_string_lossy().into_owned();
    let stderr = view(
        &xvfb,
        &["--scene", &scene, "--size", "96x54", "--frames", "1"],
        &script,
        &dir.join("shot.png"),
    );
    assert!(stderr.contains("a scene of 5 objects"), "{stderr}");
    for line in [
        "1. quad: relief on rocks_depth.jpg (bundled), depth 0.03",
        "2. cube: exact on bricks_depth.jpg (bundled), depth 0.08",
        "3. sphere: secant on mountains_height16.png (bundled), depth 0.05",
        "4. torus: flat",
    ] {
        assert!(stderr.contains(line), "no '{line}' in {stderr}");
    }
}

/// Issue 37: the split view side by side on a window 1 pixel wide (then 2 and 3) is
/// validation-clean: the right half never lands on a column the left half wrote (both
/// halves blitted into column 0 were a write-after-write hazard).
#[test]
fn side_by_side_on_a_one_pixel_window_is_validation_clean() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            eprintln!("SKIPPED side_by_side_on_a_one_pixel_window_is_validation_clean: {why}");
            return;
        }
    };
    let dir = scratch("one-pixel");
    let script = dir.join("script.txt");
    std::fs::write(
        &script,
        "0 split pom\n0 compare side-by-side\n1 resize 2x16\n2 resize 3x16\n",
    )
    .unwrap();
    let shot = dir.join("shot.png");
    run_checked(
        dispmap()
            .env("DISPLAY", &xvfb.display)
            .env_remove("WAYLAND_DISPLAY")
            .args([
                "view", "--size", "1x16", "--frames", "3", "--no-ui", "--script",
            ])
            .arg(&script)
            .arg("--screenshot")
            .arg(&shot),
        "view side by side at 1, 2 and 3 pixels wide",
    );
    assert_eq!(image::image_dimensions(&shot).unwrap(), (3, 16));
    std::fs::remove_dir_all(&dir).ok();
}

/// The split view of a scene of several objects at the documented 960x540 with the
/// panel: the panel docks in a column at the right edge, so that no panel pixel lies
/// over side A (its columns, above the band of the side labels, equal `render`'s frame
/// of the same scene at the width the sides share, bit for bit), and it lists the three
/// materials with their method, map and depth. Two of them are changed first through
/// the panel's controls (the cube's method, the sphere's map and depth): the panel lists
/// the changes and side A is `render`'s frame of the scene file changed the same way.
#[test]
fn split_view_panel_hides_no_side_and_lists_every_material() {
    let xvfb = match start_xvfb() {
        Ok(x) => x,
        Err(why) => {
            skip::skip(
                "split_view_panel_hides_no_side_and_lists_every_material",
                &why,
            );
            return;
        }
    };
    let dir = scratch("materials-split");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/materials.toml");
    let scene = scene.to_string_lossy().into_owned();
    let (script, shot, reference) = (
        dir.join("script.txt"),
        dir.join("view.png"),
        dir.join("render.png"),
    );
    std::fs::write(
        &script,
        "0 split pom\n0 divider 0.5\n0 object-method 2:relief\n0 object-map 3:rocks\n\
         0 object-depth 3:0.1\n",
    )
    .unwrap();
    // The same changes in the scene file.
    let text = std::fs::read_to_string(&scene).unwrap();
    let edited = text
        .replace("name = \"exact\"", "name = \"relief\"")
        .replace(
            "bundled = \"mountains\"\ndepth_scale = 0.05",
            "bundled = \"rocks\"\ndepth_scale = 0.1",
        );
    assert_ne!(edited, text);
    let edited_scene = dir.join("edited.toml");
    std::fs::write(&edited_scene, edited).unwrap();
    let (w, h) = (960u32, 540u32);
    let stderr = view(
        &xvfb,
        &["--scene", &scene, "--size", "960x540", "--frames", "2"],
        &script,
        &shot,
    );
    // The panel's own list: every material with its method, map and depth.
    let listed: Vec<&str> = stderr
        .lines()
        .skip_while(|l| !l.starts_with("panel: ") || !l.contains("objects listed"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .collect();
    let materials: Vec<&&str> = listed.iter().filter(|l| l.contains(" on ")).collect();
    assert_eq!(materials.len(), 3, "the panel listed {listed:?}\n{stderr}");
    for line in [
        "1. quad: relief on rocks_depth.jpg (bundled), depth 0.03",
        "2. cube: relief on bricks_depth.jpg (bundled), depth 0.08",
        "3. sphere: secant on rocks, depth 0.1",
    ] {
        assert!(
            listed.iter().any(|l| l.trim() == line),
            "no '{line}' in {listed:?}"
        );
    }
    // Where the sides end and the docked panel begins.
    let docked = stderr
        .lines()
        .find(|l| l.starts_with("panel: docked at the right edge, "))
        .unwrap_or_else(|| panic!("the panel did not dock:\n{stderr}"));
    let px: u32 = docked
        .trim_start_matches("panel: docked at the right edge, ")
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(px > 0 && px <= w * 2 / 5, "{docked}");
    let sides = w - px;
    let divider = (0.5 * sides as f32).round() as u32;
    run_checked(
        dispmap()
            .args(["render", "--frames", "1", "--scene"])
            .arg(&edited_scene)
            .arg("--size")
            .arg(format!("{sides}x{h}"))
            .arg("--out")
            .arg(&reference),
        "dispmap render",
    );
    let view_img = image::open(&shot).unwrap().to_rgba8();
    let render = image::open(&reference).unwrap().to_rgba8();
    assert_eq!(view_img.dimensions(), (w, h));
    // Side A (left of the divider), above the labels' band: the frame alone.
    let mut covered = 0;
    for y in 0..h - 36 {
        for x in 0..divider {
            covered += u32::from(view_img.get_pixel(x, y) != render.get_pixel(x, y));
        }
    }
    assert_eq!(
        covered,
        0,
        "{covered} pixels of side A ({divider}x{}) differ from render's frame",
        h - 36
    );
    // The panel is drawn in its column: most of it is not the frame's background.
    let drawn = (sides..w)
        .flat_map(|x| (0..h).map(move |y| (x, y)))
        .filter(|&(x, y)| view_img.get_pixel(x, y).0 != [255, 255, 255, 255])
        .count() as u32;
    assert!(
        drawn * 2 > px * h,
        "only {drawn} of {} pixels of the panel's column are drawn",
        px * h
    );
    std::fs::remove_dir_all(&dir).ok();
}
