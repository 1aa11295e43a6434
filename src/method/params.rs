//! The methods' parameters ([`MethodParams`]), their limits and their validation.

use super::Method;
use crate::error::{Error, Result};

/// Largest accepted step count: beyond it a frame takes minutes on lavapipe and the
/// linear step is far below the height map's own precision.
pub const MAX_STEPS: u32 = 1 << 16;

/// The steps a traversal may take per invocation (`TRAVERSAL_CAP` in
/// `glsl/common/frame.glsl`): the cone methods' march is cut there (no hit).
pub const TRAVERSAL_CAP: u64 = 16384;

/// The cone steps a cone method's ray takes before it hands over to the pyramid
/// traversal (`CONE_BUDGET` in `glsl/common/cone.glsl`).
pub const CONE_BUDGET: u64 = 4096;

/// Largest DIG block side in pixels.
pub const MAX_BLOCK: u32 = 64;

/// Largest `secant` segment count.
pub const MAX_SEGMENTS: u32 = 64;

/// Largest `--lod-threshold`: a footprint of 2^31 texels per pixel is beyond any map.
pub const MAX_LOD_THRESHOLD: f32 = 31.0;

/// The coarsest level the `pyramid` method may stop at (minification).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum MaxLevel {
    /// Always traverse down to this level (0 = full detail).
    Fixed(u32),
    /// From the pixel's texel footprint (log2 of the texels a pixel spans).
    Auto,
}

impl std::str::FromStr for MaxLevel {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        if s == "auto" {
            return Ok(MaxLevel::Auto);
        }
        s.parse::<u32>()
            .ok()
            .filter(|&l| l <= 31)
            .map(MaxLevel::Fixed)
            .ok_or_else(|| {
                Error::invalid(
                    "max-level",
                    format!("'{s}' is neither 'auto' nor a level in 0..=31"),
                )
            })
    }
}

/// Parameters of the methods; each method reads the ones it documents.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct MethodParams {
    /// The quality: linear steps over the full depth (`linear`, `relief`, `dig`'s corner
    /// pass and `iter`), `n_max` of `pom`, samples per segment of `secant`.
    pub steps: u32,
    /// `n_min` of `pom` (used as `min(min_steps, steps)`).
    pub min_steps: u32,
    /// Binary-search steps after the linear march (`relief`, `dig`: `I_B`).
    pub refine_steps: u32,
    /// `secant`: the ray is split into this many segments, each sampled `steps` times.
    pub segments: u32,
    /// `dig`: block size in pixels (x, y).
    pub block: [u32; 2],
    /// `dig`: `eps1 = eps2` widening of the corner interval; `None` = `1 / steps`.
    pub eps: Option<f32>,
    /// `pyramid`: the coarsest traversal level (minification).
    pub max_level: MaxLevel,
    /// Level of detail for every method (Tatarchuk 2006), `None` = off: a pixel whose
    /// footprint level `l = log2(texels per pixel)` (0 when magnified) reaches this
    /// threshold `L` takes the bump result without tracing; in `L - 1 < l < L` the traced
    /// hit is blended toward it (see `trace_lod` in `glsl/common/trace.glsl`). `L >= 1`
    /// leaves every magnified pixel untouched.
    #[cfg_attr(feature = "serde", serde(default))]
    pub lod_threshold: Option<f32>,
}

impl Default for MethodParams {
    fn default() -> Self {
        MethodParams {
            steps: 64,
            min_steps: 8,
            refine_steps: 5,
            segments: 1,
            block: [4, 4],
            eps: None,
            max_level: MaxLevel::Fixed(0),
            lod_threshold: None,
        }
    }
}

impl MethodParams {
    /// The defaults of `method` (its default step count).
    pub fn for_method(method: Method) -> Self {
        MethodParams {
            steps: method.default_steps(),
            ..Default::default()
        }
    }

    /// The given step count, other values default.
    pub fn with_steps(steps: u32) -> Self {
        MethodParams {
            steps,
            ..Default::default()
        }
    }

    /// DIG's interval widening: `eps` or `1 / steps`.
    pub fn dig_eps(&self) -> f32 {
        self.eps.unwrap_or(1.0 / self.steps.max(1) as f32)
    }

    /// Checks the ranges; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if self.steps == 0 || self.steps > MAX_STEPS {
            return Err(Error::invalid(
                "steps",
                format!("{} is outside 1..={MAX_STEPS}", self.steps),
            ));
        }
        if self.min_steps == 0 || self.min_steps > MAX_STEPS {
            return Err(Error::invalid(
                "min-steps",
                format!("{} is outside 1..={MAX_STEPS}", self.min_steps),
            ));
        }
        if self.refine_steps > 32 {
            return Err(Error::invalid(
                "refine-steps",
                format!(
                    "{} is outside 0..=32 (32 halvings exceed float precision)",
                    self.refine_steps
                ),
            ));
        }
        if self.segments == 0 || self.segments > MAX_SEGMENTS {
            return Err(Error::invalid(
                "segments",
                format!("{} is outside 1..={MAX_SEGMENTS}", self.segments),
            ));
        }
        if self.block.iter().any(|&b| b == 0 || b > MAX_BLOCK) {
            return Err(Error::invalid(
                "block",
                format!(
                    "{}x{} is outside 1..={MAX_BLOCK} per side",
                    self.block[0], self.block[1]
                ),
            ));
        }
        if let Some(eps) = self.eps
            && !(0.0..=1.0).contains(&eps)
        {
            return Err(Error::invalid(
                "eps",
                format!("{eps} is outside 0..=1 (a fraction of the full depth)"),
            ));
        }
        if let Some(l) = self.lod_threshold
            && !(0.0..=MAX_LOD_THRESHOLD).contains(&l)
        {
            return Err(Error::invalid(
                "lod-threshold",
                format!("{l} is outside 0..={MAX_LOD_THRESHOLD} (a mip level)"),
            ));
        }
        if let MaxLevel::Fixed(l) = self.max_level
            && l > 31
        {
            return Err(Error::invalid(
                "max-level",
                format!("{l} is outside 0..=31"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_are_checked() {
        let bad = [
            ("steps", MethodParams::with_steps(0)),
            (
                "min-steps",
                MethodParams {
                    min_steps: 0,
                    ..Default::default()
                },
            ),
            (
                "segments",
                MethodParams {
                    segments: 0,
                    ..Default::default()
                },
            ),
            (
                "block",
                MethodParams {
                    block: [4, 0],
                    ..Default::default()
                },
            ),
            (
                "eps",
                MethodParams {
                    eps: Some(f32::NAN),
                    ..Default::default()
                },
            ),
            (
                "lod-threshold",
                MethodParams {
                    lod_threshold: Some(f32::NAN),
                    ..Default::default()
                },
            ),
            (
                "lod-threshold",
                MethodParams {
                    lod_threshold: Some(-1.0),
                    ..Default::default()
                },
            ),
        ];
        for (name, params) in bad {
            let err = params.validate().unwrap_err().to_string();
            assert!(err.contains(name), "{name}: {err}");
        }
        assert!(MethodParams::default().validate().is_ok());
        assert_eq!("auto".parse::<MaxLevel>().unwrap(), MaxLevel::Auto);
        assert_eq!("3".parse::<MaxLevel>().unwrap(), MaxLevel::Fixed(3));
        assert!("-1".parse::<MaxLevel>().is_err());
    }
}
