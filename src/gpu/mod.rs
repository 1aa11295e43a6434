//! Thin, named wrappers over Vulkan objects: buffers, images, compute pipelines with push
//! descriptors, barriers and one-shot submissions for the standalone path.
//!
//! Every object gets a debug name at creation. Objects are destroyed explicitly with
//! [`owned::Destroy::destroy`] (an `unsafe fn`: the GPU must be done with them);
//! dropping one that still owns GPU memory logs a warning (a leak). Nothing here uses the
//! passes, the orchestrator, materials or meshes.

pub mod buffer;
pub mod commands;
pub mod height_texture;
pub mod image;
pub mod owned;
pub mod pipeline;
pub mod sync;
pub mod track;

pub use buffer::Buffer;
pub use commands::OneShot;
pub use height_texture::HeightTexture;
pub use image::{HostView, Image, ViewRef};
pub use pipeline::ComputePipeline;
