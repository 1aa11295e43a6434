//! dispmap: per-pixel displacement mapping with Vulkan compute shaders, measured speed
//! against error.
//!
//! This is the core crate an engine depends on: the Vulkan compute passes, their one
//! orchestrator [`embed::DisplacementPass`] (recorded into a host's command buffer) and the
//! standalone [`Renderer`], the first host of that pass (its own G-buffer, one-shot
//! submission and read-back). The exact CPU reference, the error metrics, the benchmark,
//! scene files, mesh loaders and the `dispmap` command-line tool live in the `dispmap-cli`
//! crate of the same repository (`cli/`), which an engine does not need.
//!
//! A frame is a pass graph: `gbuffer` (raster) -> `[upload]` -> `[pyramid]` ->
//! `[dig_corners]` -> `trace` (the method, writing the hit buffer) -> `[shadow]` -> `shade`
//! -> `[hit_depth]` ([`passes::PassName`]). Every pass records into a command buffer it is
//! given and is bracketed by GPU timestamps.
//!
//! Conventions (`docs/design.md` in the repository): heights in `[0, 1]` with 1 the
//! macro surface; texel centres at `(i + 0.5) / W`; the tangent-space ray
//! `uv(h) = uv0 + (1 - h) P`; the hit buffer holds `(u, v, height, iterations)`.
//!
//! Feature `serde` (off by default): `Serialize`/`Deserialize` for the settings types
//! (methods, scenes, shadows, device info), as the command-line tool's files need.

#![warn(missing_docs)]

pub mod abi;
pub mod context;
pub mod embed;
pub mod error;
pub mod gpu;
pub mod heightfield;
pub mod material;
pub mod mesh;
pub mod method;
pub mod passes;
pub mod renderer;
pub mod scene;
pub mod shaders;
pub mod timing;

pub use context::{Context, ContextOptions};
pub use error::{Error, Result};
pub use heightfield::{Addressing, Convention, HeightField};
pub use method::{Method, MethodParams};
pub use renderer::{RenderSettings, Renderer};
pub use scene::{Camera, Geometry, Light, Scene};
