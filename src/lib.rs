//! dispmap: per-pixel displacement mapping with Vulkan compute shaders, measured speed
//! against error.
//!
//! Given a height map and a G-buffer (each pixel's tangent-space view ray), dispmap finds
//! the first intersection of every ray with the height field by one of its methods
//! ([`Method`]: from bump mapping, steep parallax and relief mapping to DIG, the
//! max-height pyramid and an exact traversal), and shades, shadows and depth-corrects
//! the result. Everything runs as Vulkan compute passes that
//! record into a command buffer they are given.
//!
//! This is the core crate an engine depends on: the passes, their one orchestrator
//! [`embed::DisplacementPass`] (recorded into a host's command buffer) and the standalone
//! [`Renderer`], the first host of that pass (its own G-buffer, one-shot submission and
//! read-back). The exact CPU reference, the error metrics, the benchmark, scene files,
//! mesh loaders and the `dispmap` command-line tool live in the `dispmap-cli` crate of the
//! same repository (`cli/`), which an engine does not need.
//!
//! # Rendering a frame on its own
//!
//! [`Renderer`] creates its G-buffer, records the pass, submits and reads back:
//!
//! ```no_run
//! use dispmap::{Context, ContextOptions, Convention, HeightField, Method, MethodParams};
//! use dispmap::{RenderSettings, Renderer, Scene};
//! use std::{path::Path, sync::Arc};
//!
//! # fn main() -> dispmap::Result<()> {
//! let field = HeightField::load(Path::new("rocks_depth.jpg"), Convention::Depth)?;
//! let ctx = Arc::new(Context::headless(&ContextOptions::default())?);
//! let settings = RenderSettings {
//!     width: 320,
//!     height: 180,
//!     method: Method::Relief,
//!     params: MethodParams::default(),
//!     scene: Scene::default(), // the tiled plane, camera 30 degrees above it
//!     shadows: Default::default(),
//! };
//! let mut renderer = Renderer::new(&ctx, &field, settings)?;
//! let times = renderer.render()?; // per-pass GPU milliseconds
//! let rgba = renderer.read_color()?; // 320 x 180 RGBA8, sRGB
//! let hits = renderer.read_hits()?; // (u, v, height, iterations) per pixel
//! # let _ = (times, rgba, hits);
//! # Ok(())
//! # }
//! ```
//!
//! # Embedding the pass in an engine
//!
//! A host that owns its instance, device, queue and allocator enables what
//! [`embed::requirements`] lists, wraps its handles in a [`Context`], builds one
//! [`embed::DisplacementPass`] and records it each frame after its own G-buffer pass
//! (layouts, barriers and the frames-in-flight contract: the [`embed`] module docs;
//! `examples/host_engine.rs` is a complete engine):
//!
//! ```no_run
//! use ash::vk;
//! use dispmap::context::HostHandles;
//! use dispmap::embed::{self, DisplacementPass, FrameInputs, PassSettings, Timestamps};
//! use dispmap::passes::gbuffer::GBufferViews;
//! use dispmap::{Addressing, Context, HeightField, Method, MethodParams};
//! use std::sync::Arc;
//!
//! /// One frame of a host whose device was created with `embed::requirements()` enabled;
//! /// `cmd` is recording, the G-buffer and hit images are in the documented layouts.
//! fn frame(
//!     handles: HostHandles,
//!     field: &HeightField,
//!     cmd: vk::CommandBuffer,
//!     gbuffer: GBufferViews,
//!     [hit_uv, hit_height]: [vk::ImageView; 2],
//! ) -> dispmap::Result<()> {
//!     // The hit images as the pass checks them (format, size, usage: a wrong one is
//!     // refused).
//!     let view = |view, format| embed::HostView {
//!         view,
//!         format,
//!         extent: gbuffer.extent,
//!         usage: vk::ImageUsageFlags::STORAGE,
//!     };
//!     let hit = embed::HitImages {
//!         uv: view(hit_uv, embed::HIT_UV_FORMAT),
//!         height: view(hit_height, embed::HIT_HEIGHT_FORMAT),
//!     };
//!     // 1. The device has what the pass needs (an error naming what is missing).
//!     // SAFETY: the host's physical device was enumerated from its live instance.
//!     unsafe { embed::check_physical_device(&handles.instance, handles.physical_device)? };
//!     // 2. dispmap's view of the host's handles.
//!     // SAFETY: the handles are alive and the device has the requirements enabled.
//!     let ctx = Arc::new(unsafe { Context::from_handles(handles, false)? });
//!     // 3. Pipelines, the height texture (uploaded by the first record), per-slot state.
//!     let mut pass = DisplacementPass::new(ctx, field, PassSettings {
//!         method: Method::Relief,
//!         params: MethodParams::default(),
//!         depth_scale: 0.1,
//!         addressing: Addressing::Repeat,
//!         extent: gbuffer.extent,
//!         frames_in_flight: 2,
//!     })?;
//!     // 4. Each frame: record into the host's command buffer (the host submits it).
//!     let inputs = FrameInputs { frame_slot: 0, gbuffer, hit, shade: None, motion: None };
//!     // SAFETY: `cmd`, the views and the slot follow `record`'s documented contract.
//!     let recorded = unsafe { pass.record(cmd, &inputs, Timestamps::Owned)? };
//!     // ... the host's barriers, vkQueueSubmit2, its fence; then per-pass times:
//!     let times = pass.timings(0)?;
//!     # let _ = (recorded, times);
//!     // 5. After the device is idle.
//!     // SAFETY: no frame recorded with the pass is still executing.
//!     unsafe { pass.destroy() };
//!     Ok(())
//! }
//! ```
//!
//! A frame is a pass graph: `gbuffer` (raster) -> `[upload]` -> `[pyramid]` ->
//! `[dig_corners]` -> `trace` (the method, writing the hit images) -> `[shadow]` -> `shade`
//! -> `[hit_depth]` ([`passes::PassName`]). Every pass records into a command buffer it is
//! given and is bracketed by GPU timestamps.
//!
//! Conventions (`docs/design.md` in the repository): heights in `[0, 1]` with 1 the
//! macro surface; texel centres at `(i + 0.5) / W`; the tangent-space ray
//! `uv(h) = uv0 + (1 - h) P`; the hit images hold each hit's `(u, v)` and height, and
//! the pass's optional iteration output its iteration count.
//!
//! Features:
//!
//! * `decode` (on by default): height maps and material maps from PNG, JPEG and
//!   OpenEXR files or bytes (`HeightField::load`, `decode`, `probe`, `from_image`;
//!   `material::load_albedo`, `load_normal_map`), with the `image` crate and its
//!   decoders. An engine that loads its own textures turns it off (`default-features =
//!   false`: 20 packages instead of 48) and hands over texels:
//!   [`HeightField::from_texels`] (8-bit, 16-bit, float) and [`material::RgbaMap::new`].
//! * `serde` (off by default): `Serialize`/`Deserialize` for the settings types
//!   (methods, scenes, shadows, device info), as the command-line tool's files need.

#![warn(missing_docs)]

pub mod abi;
pub mod context;
pub mod embed;
pub mod error;
#[cfg(feature = "decode")]
mod exr_height;
pub mod gpu;
pub mod heightfield;
pub mod input;
pub mod material;
pub mod mesh;
pub mod method;
pub mod passes;
pub mod pixel_rays;
pub mod renderer;
pub mod scene;
pub mod shaders;
pub mod timing;

// The versions of the crates in dispmap's API (`HostHandles` takes ash handles and an
// `Arc<Mutex<gpu_allocator::vulkan::Allocator>>`, `ShadeTarget` a `glam::Mat4`): a host
// names them through these re-exports to use exactly dispmap's.
/// docs/embedding.md's code blocks, compiled by `cargo test --doc` (`no_run`: they need a
/// host's device and G-buffer). README.md's are compiled by dispmap-wgpu's doctests, whose
/// dependencies include both crates its blocks use.
#[cfg(doctest)]
#[doc = include_str!("../docs/embedding.md")]
pub struct EmbeddingDoctests;

pub use ash;
pub use glam;
pub use gpu_allocator;

pub use context::{Context, ContextOptions};
pub use error::{Error, Result};
pub use heightfield::{Addressing, Convention, HeightField};
pub use method::{Method, MethodParams};
pub use renderer::{RenderSettings, Renderer};
pub use scene::{Camera, Geometry, Light, Scene};
