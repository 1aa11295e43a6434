//! dispmap's displacement pass in a [wgpu](https://wgpu.rs) application on Vulkan.
//!
//! wgpu does not enable what the pass needs (`VK_KHR_push_descriptor`,
//! `synchronization2`, `dynamicRendering` for the depth merge) and keeps its Vulkan
//! objects to itself. This crate bridges the two through wgpu's `as_hal` API:
//!
//! 1. [`WgpuDevice::new`] creates the Vulkan instance (optionally with the Khronos
//!    validation layer, synchronization validation and a message counter), picks a device
//!    that dispmap supports, opens it through wgpu-hal with dispmap's extensions and
//!    features added to wgpu's own, wraps it as a `wgpu::Device` / `wgpu::Queue`, and
//!    builds a [`dispmap::context::Context`] over the same device with its own
//!    `gpu-allocator` allocator (wgpu keeps its allocator private: the device has two).
//! 2. [`host_view`] turns a `wgpu::Texture` and its view into the pass's
//!    [`dispmap::embed::HostView`]: the format and usage translated to Vulkan and checked,
//!    errors naming the texture.
//! 3. [`record`] records [`dispmap::embed::DisplacementPass`] into a wgpu command encoder
//!    of its own (wgpu 30 refuses a mix of raw and wgpu commands in one encoder), with the
//!    layout hand-off on both sides ([`record`] documents the wgpu usage states before and
//!    after: the contract), and with [`DepthMerge`] writes the corrected depth into the
//!    wgpu depth texture the G-buffer used.
//! 4. After the submission completes ([`wait_for`] with its `SubmissionIndex`), the pass's
//!    own timestamps are read with [`dispmap::embed::DisplacementPass::timings`].
//!
//! Versions: wgpu 30.0 (whose wgpu-hal uses ash 0.38 and gpu-allocator 0.28, the versions
//! dispmap's API names). The crate re-exports [`wgpu`] and [`dispmap`] so the host uses
//! exactly these.

mod device;
mod images;
mod record;

pub use device::{DeviceOptions, Messages, WgpuDevice};
pub use images::{WgpuImage, host_view, vk_format, vk_usage};
pub use record::{DepthMerge, WgpuFrame, WgpuShade, record, wait_for};

pub use dispmap;

/// README.md's code blocks (the core pass in a Vulkan host, and in wgpu), compiled by
/// `cargo test --doc` here, where both crates they use are dependencies (`no_run`: they
/// need a host's device and G-buffer).
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct ReadmeDoctests;
pub use wgpu;

/// The Vulkan API of wgpu-hal.
pub type Vulkan = wgpu::hal::api::Vulkan;

/// What can go wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// From dispmap (a missing device feature, a refused input, a Vulkan call).
    #[error(transparent)]
    Dispmap(#[from] dispmap::error::Error),
    /// A wgpu object that is not backed by Vulkan (another backend), named.
    #[error("{0} is not a Vulkan object (wgpu must run on its Vulkan backend)")]
    NotVulkan(String),
    /// A texture that cannot be one of the pass's images: its label and why.
    #[error("texture {label}: {what}")]
    Texture {
        /// The texture's label (or the role it was given for, e.g. `hit.uv`).
        label: String,
        /// What is wrong with it.
        what: String,
    },
    /// A Vulkan call failed.
    #[error("{call} failed: {result}")]
    Vulkan {
        /// The call.
        call: &'static str,
        /// Its result.
        result: dispmap::ash::vk::Result,
    },
    /// wgpu refused something (device creation, a poll).
    #[error("wgpu: {0}")]
    Wgpu(String),
    /// No Vulkan device supports both wgpu and the displacement pass.
    #[error("no Vulkan device supports the displacement pass: {0}")]
    NoDevice(String),
}

/// The crate's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;
