//! dispmap: per-pixel displacement mapping with Vulkan compute shaders, measured speed
//! against error.
//!
//! A frame is a pass graph: `gbuffer` (raster) -> `trace` (the method, writing the hit
//! buffer) -> `shade`. Every pass records into a command buffer it is given and is
//! bracketed by GPU timestamps; [`reference`](mod@reference) computes the exact first intersection on
//! the CPU from the same rays, and [`metrics`] compares any method against it.
//!
//! Conventions (see `DESIGN.md` in the repository): heights in `[0, 1]` with 1 the
//! macro surface; texel centres at `(i + 0.5) / W`; the tangent-space ray
//! `uv(h) = uv0 + (1 - h) P`; the hit buffer holds `(u, v, height, iterations)`.

#![warn(missing_docs)]

pub mod abi;
pub mod bench;
pub mod bundled;
pub mod contact_sheet;
pub mod context;
pub mod embed;
pub mod error;
pub mod gpu;
pub mod heatmap;
pub mod heightfield;
pub mod material;
pub mod measure;
pub mod mesh;
pub mod method;
pub mod metrics;
pub mod output;
pub mod passes;
pub mod reference;
pub mod renderer;
pub mod scene;
pub mod scene_file;
pub mod shaders;
pub mod timing;

pub use context::{Context, ContextOptions};
pub use error::{Error, Result};
pub use heightfield::{Addressing, Convention, HeightField};
pub use method::{Method, MethodParams};
pub use renderer::{RenderSettings, Renderer};
pub use scene::{Camera, Geometry, Light, Scene};
