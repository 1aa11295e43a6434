//! What a run sweeps ([`BenchConfig`]): its validation, the frames and settings it
//! implies, and the parsing of the option lists.

use super::*;
use dispmap::error::{Error, Result};
use dispmap::method::{MAX_STEPS, Method};
use dispmap::renderer::MAX_FRAME_SIDE;
use dispmap::scene::Scene;

/// What to sweep. [`BenchConfig::default`] is the protocol's default run.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchConfig {
    /// Frame width and height in pixels (`--size`).
    pub frame: [u32; 2],
    /// Frames (camera azimuths) per run (`--frames`).
    pub frames: u32,
    /// Interleaved passes over the frames (`--repeat`): every run renders its `frames`
    /// frames `repeat` times; the times are the minimum over all of them, with the range
    /// of the per-pass minima as the spread.
    pub repeat: u32,
    /// Frames that get the reference and the error measures (`--error-frames`); `None`:
    /// all of them.
    pub error_frames: Option<u32>,
    /// Quality settings (`--steps`), ascending.
    pub steps: Vec<u32>,
    /// Methods (`--methods`), in [`Method::ALL`] order; by default
    /// [`Method::defaults`].
    pub methods: Vec<Method>,
    /// Map sides of the map-size sweep (`--sizes`), ascending; empty: no sweep.
    pub sizes: Vec<u32>,
    /// Methods of the map-size sweep.
    pub size_methods: Vec<Method>,
    /// The setting of the map-size sweep (`--size-steps`).
    pub size_steps: u32,
    /// The scene of frame 0 (the azimuth is set per frame).
    pub scene: Scene,
    /// Self-shadowing of every run (`--shadows`, default off): when on, the `shadow`
    /// pass is timed (`shadow_ms`) and counted in `total_ms`, not in `method_ms`.
    pub shadows: dispmap::passes::shadow::ShadowMode,
    /// The material-table numbers ([`materials`], `--materials`, default on): six small
    /// renderers over the same `K R` frames.
    pub materials: bool,
    /// The cost of silhouettes ([`silhouettes`], `--silhouettes`, default on): four
    /// renderers of the rocks sphere and materials scenes over the same `K R` frames.
    pub silhouettes: bool,
    /// The forward path (`--forward`, default on): every run of a method with one
    /// ([`Method::forward_shader`]: `relief`, `pom`) is also run forward (module docs).
    pub forward: bool,
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            frame: DEFAULT_FRAME,
            frames: DEFAULT_FRAMES,
            repeat: DEFAULT_REPEAT,
            error_frames: None,
            steps: DEFAULT_STEPS.to_vec(),
            methods: Method::defaults(),
            sizes: DEFAULT_SIZES.to_vec(),
            size_methods: SIZE_METHODS.to_vec(),
            size_steps: DEFAULT_SIZE_STEPS,
            scene: protocol_scene(),
            shadows: dispmap::passes::shadow::ShadowMode::Off,
            materials: true,
            silhouettes: true,
            forward: true,
        }
    }
}

impl BenchConfig {
    /// Checks every value and puts the lists in order (sorted, without duplicates); the
    /// error names the command-line option.
    pub fn validate(&mut self) -> Result<()> {
        let [w, h] = self.frame;
        if w == 0 || h == 0 || w > MAX_FRAME_SIDE || h > MAX_FRAME_SIDE {
            return Err(Error::invalid(
                "--size",
                format!("{w}x{h} is outside 1..={MAX_FRAME_SIDE} per side"),
            ));
        }
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return Err(Error::invalid(
                "--frames",
                format!("{} is outside 1..={MAX_FRAMES}", self.frames),
            ));
        }
        if self.repeat == 0 || self.repeat > MAX_REPEAT {
            return Err(Error::invalid(
                "--repeat",
                format!("{} is outside 1..={MAX_REPEAT}", self.repeat),
            ));
        }
        if let Some(n) = self.error_frames
            && (n == 0 || n > self.frames)
        {
            return Err(Error::invalid(
                "--error-frames",
                format!("{n} is outside 1..={} (--frames)", self.frames),
            ));
        }
        if self.steps.is_empty() {
            return Err(Error::invalid("--steps", "the list is empty"));
        }
        if let Some(bad) = self.steps.iter().find(|&&s| s == 0 || s > MAX_STEPS) {
            return Err(Error::invalid(
                "--steps",
                format!("{bad} is outside 1..={MAX_STEPS}"),
            ));
        }
        self.steps.sort_unstable();
        self.steps.dedup();
        if self.methods.is_empty() {
            return Err(Error::invalid("--methods", "the list is empty"));
        }
        self.methods = in_report_order(&self.methods);
        if let Some(bad) = self
            .sizes
            .iter()
            .find(|&&s| !(2..=MAX_MAP_SIDE).contains(&s))
        {
            return Err(Error::invalid(
                "--sizes",
                format!("{bad} is outside 2..={MAX_MAP_SIDE}"),
            ));
        }
        self.sizes.sort_unstable();
        self.sizes.dedup();
        self.size_methods = in_report_order(&self.size_methods);
        if self.size_steps == 0 || self.size_steps > MAX_STEPS {
            return Err(Error::invalid(
                "--size-steps",
                format!("{} is outside 1..={MAX_STEPS}", self.size_steps),
            ));
        }
        self.scene.validate()
    }

    /// The frames that get the reference (module docs), ascending.
    pub fn error_frame_indices(&self) -> Vec<u32> {
        error_frames(self.frames, self.error_frames.unwrap_or(self.frames))
    }

    /// The scene of frame `f`: the camera turned to azimuth `(f + 0.5) 360 / K`.
    pub fn frame_scene(&self, f: u32) -> Scene {
        let mut scene = self.scene;
        scene.camera.azimuth_deg = azimuth_deg(f, self.frames);
        scene
    }

    /// The frame set as one CSV-safe phrase (azimuths and error frames).
    pub fn frame_set(&self) -> String {
        let k = self.frames;
        let errors: Vec<String> = self
            .error_frame_indices()
            .iter()
            .map(|f| f.to_string())
            .collect();
        format!(
            "azimuth (f+0.5)*{}deg for f<{k}; error frames {}",
            trim_float(360.0 / f64::from(k)),
            errors.join(" ")
        )
    }

    /// The quality settings of `method`: every `--steps` value, or one run without a
    /// step count.
    pub fn settings_of(&self, method: Method) -> Vec<Option<u32>> {
        if has_steps(method) {
            self.steps.iter().copied().map(Some).collect()
        } else {
            vec![None]
        }
    }

    /// The forward runs (module docs): each `relief` and `pom` setting of the methods
    /// sweep, when [`BenchConfig::forward`] is on.
    pub fn forward_methods(&self) -> Vec<Method> {
        self.methods
            .iter()
            .copied()
            .filter(|m| self.forward && m.forward_shader().is_some())
            .collect()
    }

    /// The setting whose heat maps are written: the largest `--steps`.
    pub fn heatmap_steps(&self) -> u32 {
        self.steps
            .iter()
            .copied()
            .max()
            .unwrap_or(DEFAULT_SIZE_STEPS)
    }
}

/// The methods of `list`, once each, in [`Method::ALL`] order.
fn in_report_order(list: &[Method]) -> Vec<Method> {
    Method::ALL
        .iter()
        .copied()
        .filter(|m| list.contains(m))
        .collect()
}

/// Frames `floor(i k / n)` for `i < n` (`n` clamped to `1..=k`).
pub fn error_frames(k: u32, n: u32) -> Vec<u32> {
    let k = k.max(1);
    let n = n.clamp(1, k);
    (0..n)
        .map(|i| (u64::from(i) * u64::from(k) / u64::from(n)) as u32)
        .collect()
}

/// The camera azimuth of frame `f` of `k`, degrees: `(f + 0.5) 360 / k`.
pub fn azimuth_deg(f: u32, k: u32) -> f32 {
    ((f64::from(f) + 0.5) * 360.0 / f64::from(k.max(1))) as f32
}

pub(super) fn trim_float(x: f64) -> String {
    let s = format!("{x:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// Parses a comma-separated list; empty items are an error naming `option`.
fn parse_list<T>(
    option: &str,
    s: &str,
    parse: impl Fn(&str) -> std::result::Result<T, String>,
) -> Result<Vec<T>> {
    if s.trim().is_empty() {
        return Err(Error::invalid(option, "the list is empty"));
    }
    s.split(',')
        .map(|item| {
            let item = item.trim();
            if item.is_empty() {
                return Err(Error::invalid(option, format!("empty item in '{s}'")));
            }
            parse(item).map_err(|m| Error::invalid(option, m))
        })
        .collect()
}

/// Parses `--steps` (`75,100,125,150`): positive step counts up to [`MAX_STEPS`].
pub fn parse_steps(s: &str) -> Result<Vec<u32>> {
    parse_list("--steps", s, |item| match item.parse::<u32>() {
        Ok(n) if (1..=MAX_STEPS).contains(&n) => Ok(n),
        _ => Err(format!("'{item}' is not a step count in 1..={MAX_STEPS}")),
    })
}

/// Parses `--methods` (`relief,pom,dig`, `all`, or `default`: [`Method::defaults`]).
pub fn parse_methods(s: &str) -> Result<Vec<Method>> {
    match s.trim() {
        "all" => return Ok(Method::ALL.to_vec()),
        "default" => return Ok(Method::defaults()),
        _ => {}
    }
    parse_list("--methods", s, |item| {
        item.parse::<Method>().map_err(|e| match e {
            Error::InvalidInput { message, .. } => message,
            other => other.to_string(),
        })
    })
}

/// Parses `--sizes` (`256,512,1024,2048`, or `none`): map sides in 2..=[`MAX_MAP_SIDE`].
pub fn parse_sizes(s: &str) -> Result<Vec<u32>> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    parse_list("--sizes", s, |item| match item.parse::<u32>() {
        Ok(n) if (2..=MAX_MAP_SIDE).contains(&n) => Ok(n),
        _ => Err(format!("'{item}' is not a map side in 2..={MAX_MAP_SIDE}")),
    })
}

/// Parses `--maps` (`rocks,bricks,mountains`, or `none`): bundled map names.
pub fn parse_maps(s: &str) -> Result<Vec<String>> {
    if s.trim() == "none" {
        return Ok(Vec::new());
    }
    parse_list("--maps", s, |item| {
        if crate::bundled::NAMES.contains(&item) {
            Ok(item.to_owned())
        } else {
            Err(format!(
                "unknown bundled map '{item}' (known: {}; add a file with --heightmap)",
                crate::bundled::NAMES.join(", ")
            ))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_frames_are_spread_and_start_at_zero() {
        assert_eq!(error_frames(8, 8), (0..8).collect::<Vec<_>>());
        assert_eq!(error_frames(8, 2), [0, 4]);
        assert_eq!(error_frames(8, 3), [0, 2, 5]);
        assert_eq!(error_frames(1, 5), [0]);
        assert_eq!(error_frames(5, 0), [0]);
        assert_eq!(azimuth_deg(0, 8), 22.5);
        assert_eq!(azimuth_deg(7, 8), 337.5);
    }

    #[test]
    fn lists_parse_and_bad_items_name_the_option() {
        assert_eq!(parse_steps("75, 100,125,150").unwrap(), [75, 100, 125, 150]);
        assert_eq!(
            parse_methods("pom,dig").unwrap(),
            [Method::Pom, Method::Dig]
        );
        assert_eq!(parse_methods("all").unwrap(), Method::ALL);
        // The default lists leave cone-exact out; it stays available by name.
        assert_eq!(parse_methods("default").unwrap(), Method::defaults());
        assert!(!BenchConfig::default().methods.contains(&Method::ConeExact));
        assert!(!SIZE_METHODS.contains(&Method::ConeExact));
        assert_eq!(parse_methods("cone-exact").unwrap(), [Method::ConeExact]);
        assert_eq!(parse_sizes("256,2048").unwrap(), [256, 2048]);
        assert!(parse_sizes("none").unwrap().is_empty());
        assert_eq!(parse_maps("rocks").unwrap(), ["rocks"]);
        for (result, option, needle) in [
            (parse_steps("").map(|_| ()), "--steps", "empty"),
            (parse_steps("0").map(|_| ()), "--steps", "'0'"),
            (parse_steps("10,,20").map(|_| ()), "--steps", "empty"),
            (parse_steps("x").map(|_| ()), "--steps", "'x'"),
            (parse_methods("pom,magic").map(|_| ()), "--methods", "magic"),
            (parse_sizes("1").map(|_| ()), "--sizes", "'1'"),
            (parse_sizes("256,abc").map(|_| ()), "--sizes", "abc"),
            (parse_maps("moon").map(|_| ()), "--maps", "moon"),
        ] {
            let err = result.unwrap_err().to_string();
            assert!(err.contains(option) && err.contains(needle), "{err}");
        }
    }

    #[test]
    fn config_validation_names_options_and_orders_lists() {
        let mut c = BenchConfig {
            steps: vec![150, 75, 75],
            methods: vec![Method::Pom, Method::Bump, Method::Pom],
            sizes: vec![512, 256],
            ..BenchConfig::default()
        };
        c.validate().unwrap();
        assert_eq!(c.steps, [75, 150]);
        assert_eq!(c.methods, [Method::Bump, Method::Pom]);
        assert_eq!(c.sizes, [256, 512]);
        type Spoil = fn(&mut BenchConfig);
        let cases: [(&str, Spoil); 7] = [
            ("--steps", |c| c.steps.clear()),
            ("--steps", |c| c.steps = vec![0]),
            ("--methods", |c| c.methods.clear()),
            ("--frames", |c| c.frames = 0),
            ("--error-frames", |c| c.error_frames = Some(99)),
            ("--sizes", |c| c.sizes = vec![1]),
            ("--size", |c| c.frame = [0, 10]),
        ];
        for (option, spoil) in cases {
            let mut c = BenchConfig::default();
            spoil(&mut c);
            let err = c.validate().unwrap_err().to_string();
            assert!(err.contains(option), "{option}: {err}");
        }
    }
}
