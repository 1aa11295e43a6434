//! The intersection methods and their parameters.
//!
//! Adding a method: write `glsl/trace/<name>.comp` (include `trace.glsl`, define
//! `Hit trace_ray(Ray ray)`), add a variant here with its name and shader, and, if it
//! needs a pre-pass (a pyramid, a corner grid), say so in [`Method::needs`] and add the
//! pass under `src/passes/`.

use crate::error::{Error, Result};
use crate::shaders::{self, Shader};

/// An intersection method (CLI `--method` names in [`Method::name`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// One fetch at the entry point: the cost floor (plain bump mapping).
    Bump,
    /// Fixed-step linear march with early exit (steep parallax mapping).
    Linear,
    /// Linear march then binary search (relief mapping).
    Relief,
}

/// Pre-passes and resources a method needs beyond the G-buffer and the height map.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    /// The max-height pyramid (min-reduce chain).
    pub pyramid: bool,
    /// The DIG corner grid.
    pub dig_corners: bool,
}

impl Method {
    /// Every method, in report order (cheapest first).
    pub const ALL: &'static [Method] = &[Method::Bump, Method::Linear, Method::Relief];

    /// CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Bump => "bump",
            Method::Linear => "linear",
            Method::Relief => "relief",
        }
    }

    /// The compute shader of the method's trace pass.
    pub fn shader(self) -> Shader {
        match self {
            Method::Bump => shaders::TRACE_BUMP_COMP,
            Method::Linear => shaders::TRACE_LINEAR_COMP,
            Method::Relief => shaders::TRACE_RELIEF_COMP,
        }
    }

    /// What the method needs besides the G-buffer.
    pub fn needs(self) -> Needs {
        Needs::default()
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Method::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
                Error::invalid(
                    "method",
                    format!("unknown method '{s}' (known: {})", names.join(", ")),
                )
            })
    }
}

/// Largest accepted step count: beyond it a frame takes minutes on lavapipe and the
/// linear step is far below the height map's own precision.
pub const MAX_STEPS: u32 = 1 << 16;

/// Parameters shared by the methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MethodParams {
    /// Linear steps over the full depth (the quality setting; ignored by `bump`).
    pub steps: u32,
    /// Binary-search steps after the linear march (`relief`).
    pub refine_steps: u32,
}

impl Default for MethodParams {
    fn default() -> Self {
        MethodParams {
            steps: 64,
            refine_steps: 5,
        }
    }
}

impl MethodParams {
    /// Checks the ranges; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if self.steps == 0 || self.steps > MAX_STEPS {
            return Err(Error::invalid(
                "steps",
                format!("{} is outside 1..={MAX_STEPS}", self.steps),
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
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>().unwrap(), *m);
            assert!(m.shader().name.ends_with(&format!("{}.comp", m.name())));
        }
        let err = "nope".parse::<Method>().unwrap_err().to_string();
        assert!(err.contains("nope") && err.contains("relief"), "{err}");
    }

    #[test]
    fn params_are_checked() {
        assert!(
            MethodParams {
                steps: 0,
                refine_steps: 5
            }
            .validate()
            .is_err()
        );
        assert!(MethodParams::default().validate().is_ok());
    }
}
