//! The headless viewer's inputs: the camera path (`--camera-path FILE|orbit`) and the
//! event script (`--script FILE`), both plain text.
//!
//! Camera path file: one frame per line, `ELEVATION_DEG AZIMUTH_DEG [HEIGHT]`
//! (whitespace-separated; `#` starts a comment); frame `i` uses line `i`, the last line
//! holds for later frames; a line without a height keeps the previous one.
//!
//! Script file: `FRAME ACTION [ARGUMENT]` per line, applied before frame `FRAME`
//! (0-based) renders, in file order:
//!
//! | action | argument | effect |
//! | --- | --- | --- |
//! | `method` | a method name | the (left) method |
//! | `split` | a method name, or `off` | the right side of the split view |
//! | `divider` | a fraction in `[0, 1]` | the split view's divider position |
//! | `compare` | `wipe`, `ab`, `side-by-side` | how the split view shows the two methods |
//! | `flip` | | A/B mode, showing the other method |
//! | `zoom` | a number of wheel lines | the eye moves toward (positive) or away from the target |
//! | `panel` | `on`, `off` | the on-screen panel |
//! | `help` | `on`, `off` | the help overlay of the keys |
//! | `resize` | `WIDTHxHEIGHT` | asks the window system for that size; later frames wait until it has it |
//! | `steps` | N | the step count of every method shown |
//! | `depth-scale` | a number | the displacement depth |
//! | `shadows` | `off`, `hard`, `soft` | self-shadowing |
//! | `lod` | `off` or L | the level-of-detail threshold |
//! | `map` | `rocks`, `bricks`, `mountains` | a bundled map |
//! | `heatmap` | `on`, `off` | the iteration heat map view |
//! | `error` | | computes the error overlay; later frames wait until it is shown |
//! | `screenshot` | a PNG path | writes that frame as presented |
//! | `object-method` | `N:METHOD` | a scene of several objects: object `N`'s (1-based) method |
//! | `object-depth` | `N:DEPTH` | object `N`'s depth scale |
//! | `object-map` | `N:MAP` | object `N`'s height map: a bundled map, or `own` for its file |

use super::Compare;
use anyhow::{Context as _, Result, bail};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::shadow::ShadowMode;
use dispmap::scene::Scene;
use std::path::{Path, PathBuf};

/// The largest camera path or script file read (16 MiB).
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// One camera of a path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// Elevation in degrees.
    pub elevation: f32,
    /// Azimuth in degrees.
    pub azimuth: f32,
    /// Eye height, when the line gives one.
    pub height: Option<f32>,
}

/// `--camera-path`.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraPath {
    /// One full turn about the vertical axis over the frames, from the start azimuth.
    Orbit,
    /// The file's cameras.
    Points(Vec<PathPoint>),
}

impl CameraPath {
    /// Parses `orbit` or reads the file; every camera is checked as `render` checks
    /// one (`scene`: the run's, whose camera each line changes; [`Scene::validate`]),
    /// the error naming the file and line. Azimuths are read in f64 and reduced modulo
    /// 360 before they are rounded ([`dispmap::scene::reduce_degrees`]).
    pub fn parse(arg: &str, scene: &Scene) -> Result<Self> {
        if arg == "orbit" {
            return Ok(CameraPath::Orbit);
        }
        let path = Path::new(arg);
        let text = dispmap::input::read_to_string(path, MAX_FILE_BYTES, "a camera path")
            .with_context(|| format!("invalid --camera-path: cannot read {}", path.display()))?;
        let mut points = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |what: &str| {
                anyhow::anyhow!(
                    "invalid --camera-path: {}:{}: {what} (want ELEVATION AZIMUTH [HEIGHT])",
                    path.display(),
                    n + 1
                )
            };
            let values: Vec<f64> = line
                .split_whitespace()
                .map(|v| {
                    v.parse::<f64>()
                        .map_err(|_| bad(&format!("'{v}' is not a number")))
                })
                .collect::<Result<_>>()?;
            if !(2..=3).contains(&values.len()) {
                return Err(bad(&format!("{} values", values.len())));
            }
            if values.iter().any(|v| !v.is_finite()) {
                return Err(bad("a value is not finite"));
            }
            if !(0.5..=90.0).contains(&values[0]) {
                return Err(bad(&format!(
                    "elevation {} is outside [0.5, 90]",
                    values[0]
                )));
            }
            if let Some(&h) = values.get(2)
                && h <= 0.0
            {
                return Err(bad(&format!("height {h} is not positive")));
            }
            let point = PathPoint {
                elevation: values[0] as f32,
                azimuth: dispmap::scene::reduce_degrees(values[1]),
                height: values.get(2).map(|&h| h as f32),
            };
            // The camera this line gives, checked by `render`'s code (the height's
            // range and the near plane among them), before any window opens.
            let height = point
                .height
                .or_else(|| points.iter().rev().find_map(|p: &PathPoint| p.height))
                .unwrap_or(scene.camera.height);
            Scene {
                camera: dispmap::scene::Camera {
                    elevation_deg: point.elevation,
                    azimuth_deg: point.azimuth,
                    height,
                    ..scene.camera
                },
                ..*scene
            }
            .validate()
            .map_err(|e| bad(&e.to_string()))?;
            points.push(point);
        }
        if points.is_empty() {
            bail!("invalid --camera-path: {} has no camera", path.display());
        }
        Ok(CameraPath::Points(points))
    }
}

/// One scripted change.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// The (left) method.
    Method(Method),
    /// The split view's right method, or off.
    Split(Option<Method>),
    /// The divider as a fraction of the width.
    Divider(f32),
    /// How the split view shows the two methods.
    Compare(Compare),
    /// A/B mode, showing the other method.
    Flip,
    /// Wheel lines of zoom.
    Zoom(f32),
    /// The panel on or off.
    Panel(bool),
    /// The help overlay on or off.
    Help(bool),
    /// A window size.
    Resize(u32, u32),
    /// Steps of every method shown.
    Steps(u32),
    /// Displacement depth.
    DepthScale(f32),
    /// Self-shadowing.
    Shadows(ShadowMode),
    /// Level-of-detail threshold.
    Lod(Option<f32>),
    /// A bundled map by name.
    Map(String),
    /// The heat map view.
    Heatmap(bool),
    /// The error overlay.
    Error,
    /// A screenshot of the frame.
    Screenshot(PathBuf),
    /// Object `.0`'s (0-based) material: a change of its method, depth or map.
    Object(usize, ObjectChange),
}

/// A change of one object's material (a scene of several objects).
#[derive(Clone, Debug, PartialEq)]
pub enum ObjectChange {
    /// Its method.
    Method(Method),
    /// Its depth scale.
    Depth(f32),
    /// Its height map: a bundled map by name, or `None` for its own file.
    Map(Option<String>),
}

/// What a script is checked against when it is read ([`Script::read`]).
#[derive(Clone, Debug)]
pub struct Run {
    /// `--frames`: the frames 0 to `frames - 1` run; an action at a later frame would
    /// never run.
    pub frames: u32,
    /// The scene lists objects: the error overlay is not available.
    pub objects: bool,
    /// Per object of a scene of several objects, whether it has a height map (a
    /// material the `object-*` actions change).
    pub displaced: Vec<bool>,
}

/// A script: actions by frame, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Script {
    /// `(frame, action)`.
    pub events: Vec<(u32, Action)>,
    /// The line of each event in its file (1-based), for messages.
    pub lines: Vec<usize>,
}

impl Script {
    /// Reads and checks a script file (module docs) completely, against `run` too: no
    /// action after the last frame, no error overlay where the scene has none, one
    /// screenshot a frame, each to its own file. Errors name the file and line.
    pub fn read(path: &Path, run: &Run) -> Result<Self> {
        let text = dispmap::input::read_to_string(path, MAX_FILE_BYTES, "a script")
            .with_context(|| format!("invalid --script: cannot read {}", path.display()))?;
        Self::parse_for(&text, &path.display().to_string(), Some(run))
    }

    /// Parses a script's text, without a run to check it against; `name` labels errors.
    #[cfg(test)]
    pub fn parse(text: &str, name: &str) -> Result<Self> {
        Self::parse_for(text, name, None)
    }

    /// Parses a script's text, checked against `run` when given; `name` labels errors.
    pub fn parse_for(text: &str, name: &str, run: Option<&Run>) -> Result<Self> {
        let (mut events, mut lines) = (Vec::new(), Vec::new());
        // The line of each frame's screenshot, and of each screenshot's file.
        let mut shot_frames = std::collections::HashMap::new();
        let mut shot_files = std::collections::HashMap::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let bad = |what: String| anyhow::anyhow!("invalid --script: {name}:{}: {what}", n + 1);
            let mut parts = line.split_whitespace();
            let frame = parts.next().unwrap_or("");
            let frame: u32 = frame
                .parse()
                .map_err(|_| bad(format!("'{frame}' is not a frame number")))?;
            let action = parts.next().ok_or_else(|| bad("no action".into()))?;
            let arg = parts.next();
            if parts.next().is_some() {
                return Err(bad("more than one argument".into()));
            }
            let need = |what: &str| arg.ok_or_else(|| bad(format!("`{action}` needs {what}")));
            let number = |what: &str| -> Result<f32> {
                let v = need(what)?;
                v.parse::<f32>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("'{v}' is not a finite number")))
            };
            let switch = |v: &str| match v {
                "on" => Ok(true),
                "off" => Ok(false),
                _ => Err(bad(format!("'{v}' is neither on nor off"))),
            };
            let method = |v: &str| {
                v.parse::<Method>()
                    .map_err(|e| bad(format!("unknown method '{v}': {e}")))
            };
            let action = match action {
                "method" => Action::Method(method(need("a method")?)?),
                "split" => match need("a method or off")? {
                    "off" => Action::Split(None),
                    v => Action::Split(Some(method(v)?)),
                },
                "divider" => {
                    let f = number("a fraction")?;
                    if !(0.0..=1.0).contains(&f) {
                        return Err(bad(format!("divider {f} is outside [0, 1]")));
                    }
                    Action::Divider(f)
                }
                "compare" => match need("wipe, ab or side-by-side")? {
                    "wipe" => Action::Compare(Compare::Wipe),
                    "ab" => Action::Compare(Compare::Flip),
                    "side-by-side" => Action::Compare(Compare::SideBySide),
                    v => {
                        return Err(bad(format!("'{v}' is not wipe, ab or side-by-side")));
                    }
                },
                "flip" => Action::Flip,
                "zoom" => {
                    let lines = number("wheel lines")?;
                    if lines.abs() > 100.0 {
                        return Err(bad(format!("zoom {lines} is outside [-100, 100]")));
                    }
                    Action::Zoom(lines)
                }
                "panel" => Action::Panel(switch(need("on or off")?)?),
                "help" => Action::Help(switch(need("on or off")?)?),
                "resize" => {
                    let v = need("WIDTHxHEIGHT")?;
                    let (w, h) = crate::parse_size(v).map_err(bad)?;
                    if w > 8192 || h > 8192 {
                        return Err(bad(format!("{w}x{h} is larger than 8192 per side")));
                    }
                    Action::Resize(w, h)
                }
                "steps" => {
                    let v = need("a step count")?;
                    let s: u32 = v
                        .parse()
                        .ok()
                        .filter(|s| *s > 0)
                        .ok_or_else(|| bad(format!("'{v}' is not a positive integer")))?;
                    // The ranges `render` checks, here at parse time (before any frame).
                    MethodParams::with_steps(s)
                        .validate()
                        .map_err(|e| bad(e.to_string()))?;
                    Action::Steps(s)
                }
                "depth-scale" => {
                    let d = number("a depth")?;
                    Scene {
                        depth_scale: d,
                        ..Scene::default()
                    }
                    .validate()
                    .map_err(|e| bad(e.to_string()))?;
                    Action::DepthScale(d)
                }
                "shadows" => {
                    let v = need("off, hard or soft")?;
                    Action::Shadows(
                        v.parse::<ShadowMode>()
                            .map_err(|e| bad(format!("'{v}': {e}")))?,
                    )
                }
                "lod" => match need("off or a threshold")? {
                    "off" => Action::Lod(None),
                    _ => {
                        let l = number("a threshold")?;
                        MethodParams {
                            lod_threshold: Some(l),
                            ..MethodParams::default()
                        }
                        .validate()
                        .map_err(|e| bad(e.to_string()))?;
                        Action::Lod(Some(l))
                    }
                },
                "map" => {
                    let v = need("a bundled map")?;
                    if !crate::bundled::NAMES.contains(&v) {
                        return Err(bad(format!(
                            "unknown bundled map '{v}' (known: {})",
                            crate::bundled::NAMES.join(", ")
                        )));
                    }
                    Action::Map(v.to_owned())
                }
                "heatmap" => Action::Heatmap(switch(need("on or off")?)?),
                "error" => Action::Error,
                "screenshot" => {
                    let path = PathBuf::from(need("a PNG path")?);
                    crate::output::check_format(&path, crate::output::Format::Png)
                        .map_err(|e| bad(e.to_string()))?;
                    Action::Screenshot(path)
                }
                "object-method" | "object-depth" | "object-map" => {
                    let v = need("OBJECT:VALUE")?;
                    let (n, value) = v
                        .split_once(':')
                        .ok_or_else(|| bad(format!("'{v}' is not OBJECT:VALUE")))?;
                    let n: usize =
                        n.parse().ok().filter(|n| *n > 0).ok_or_else(|| {
                            bad(format!("'{n}' is not an object number (1, 2, ...)"))
                        })?;
                    let change = match action {
                        "object-method" => ObjectChange::Method(method(value)?),
                        "object-depth" => {
                            let d = value
                                .parse::<f32>()
                                .ok()
                                .filter(|x| x.is_finite())
                                .ok_or_else(|| bad(format!("'{value}' is not a finite number")))?;
                            Scene {
                                depth_scale: d,
                                ..Scene::default()
                            }
                            .validate()
                            .map_err(|e| bad(e.to_string()))?;
                            ObjectChange::Depth(d)
                        }
                        _ if value == "own" => ObjectChange::Map(None),
                        _ => {
                            if !crate::bundled::NAMES.contains(&value) {
                                return Err(bad(format!(
                                    "unknown bundled map '{value}' (known: {}, or own)",
                                    crate::bundled::NAMES.join(", ")
                                )));
                            }
                            ObjectChange::Map(Some(value.to_owned()))
                        }
                    };
                    Action::Object(n - 1, change)
                }
                other => return Err(bad(format!("unknown action '{other}'"))),
            };
            match (&action, arg) {
                (Action::Error, Some(_)) => return Err(bad("`error` takes no argument".into())),
                (Action::Flip, Some(_)) => return Err(bad("`flip` takes no argument".into())),
                _ => {}
            }
            if let Some(run) = run {
                if frame >= run.frames {
                    return Err(bad(format!(
                        "frame {frame} is past the last frame: --frames {} runs frames 0 to \
                         {}, so `{}` would never run",
                        run.frames,
                        run.frames.saturating_sub(1),
                        line.split_whitespace().nth(1).unwrap_or("")
                    )));
                }
                if let Action::Object(i, _) = &action {
                    match run.displaced.get(*i) {
                        Some(true) => {}
                        Some(false) => {
                            return Err(bad(format!(
                                "object {} has no height map: it has no material to change",
                                i + 1
                            )));
                        }
                        None => {
                            return Err(bad(format!(
                                "object {}: the scene has {} objects",
                                i + 1,
                                run.displaced.len()
                            )));
                        }
                    }
                }
                if action == Action::Error && run.objects {
                    return Err(bad(
                        "the error overlay is not available for a scene of several objects \
                         (`render --metrics` measures each material)"
                            .into(),
                    ));
                }
            }
            if let Action::Screenshot(path) = &action {
                if let Some(first) = shot_frames.insert(frame, n + 1) {
                    return Err(bad(format!(
                        "a second screenshot at frame {frame} (line {first} takes one): one \
                         screenshot a frame"
                    )));
                }
                if let Some(first) = shot_files.insert(path.clone(), n + 1) {
                    return Err(bad(format!(
                        "{} is also the screenshot of line {first}: each screenshot needs its \
                         own file",
                        path.display()
                    )));
                }
            }
            events.push((frame, action));
            lines.push(n + 1);
        }
        Ok(Script { events, lines })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_script_parses_and_bad_lines_name_their_line() {
        let s = Script::parse(
            "# comment\n0 method pom\n2 resize 96x64 # smaller\n3 split dig\n4 error\n\
             5 compare side-by-side\n5 flip\n6 zoom -2.5\n6 panel off\n\
             7 object-method 2:exact\n7 object-depth 1:0.25\n7 object-map 3:own\n\
             7 object-map 3:bricks\n",
            "t",
        )
        .unwrap();
        assert_eq!(
            s.events,
            vec![
                (0, Action::Method(Method::Pom)),
                (2, Action::Resize(96, 64)),
                (3, Action::Split(Some(Method::Dig))),
                (4, Action::Error),
                (5, Action::Compare(Compare::SideBySide)),
                (5, Action::Flip),
                (6, Action::Zoom(-2.5)),
                (6, Action::Panel(false)),
                (7, Action::Object(1, ObjectChange::Method(Method::Exact))),
                (7, Action::Object(0, ObjectChange::Depth(0.25))),
                (7, Action::Object(2, ObjectChange::Map(None))),
                (
                    7,
                    Action::Object(2, ObjectChange::Map(Some("bricks".into())))
                ),
            ]
        );
        for (text, want) in [
            ("x method pom", "t:1"),
            ("\n1 method nope", "t:2"),
            ("1 resize 0x4", "t:1"),
            ("1 divider 2", "t:1"),
            ("1 fly", "unknown action"),
            ("1 object-method 2", "OBJECT:VALUE"),
            ("1 object-method 0:pom", "object number"),
            ("1 object-depth 1:-1", "t:1"),
            ("1 object-map 1:nope", "unknown bundled map"),
            ("1 steps", "needs"),
            ("1 error now", "no argument"),
            ("1 compare swipe", "t:1"),
            ("1 zoom 1e9", "outside"),
            ("1 panel maybe", "neither on nor off"),
        ] {
            let e = Script::parse(text, "t").unwrap_err().to_string();
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn object_changes_are_checked_against_the_scenes_objects() {
        let run = Run {
            frames: 2,
            objects: true,
            displaced: vec![true, false],
        };
        let ok = Script::parse_for("1 object-method 1:pom\n", "t", Some(&run)).unwrap();
        assert_eq!(ok.events.len(), 1);
        for (text, want) in [
            ("0 object-depth 2:0.1", "object 2 has no height map"),
            ("0 object-map 3:rocks", "the scene has 2 objects"),
        ] {
            let e = Script::parse_for(text, "t", Some(&run))
                .unwrap_err()
                .to_string();
            assert!(e.contains(want) && e.contains("t:1"), "{text}: {e}");
        }
    }
}
