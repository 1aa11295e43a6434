//! The library's error type. Vulkan failures keep their `vk::Result`.

use ash::vk;
use std::path::PathBuf;

/// Everything the library can fail with.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A Vulkan call failed; `call` names it.
    #[error("Vulkan call {call} failed: {result}")]
    Vulkan {
        /// The entry point that failed, e.g. `vkCreateDevice`.
        call: &'static str,
        /// The code it returned.
        result: vk::Result,
    },
    /// The Vulkan loader could not be opened (no `libvulkan.so.1`).
    #[error(
        "cannot load the Vulkan library: {0} (install libvulkan1 and a driver such as mesa-vulkan-drivers)"
    )]
    Loader(String),
    /// A loader call failed while the environment names the driver manifests
    /// (`VK_ICD_FILENAMES` / `VK_DRIVER_FILES`): the loader reports a manifest it cannot
    /// parse as a failed host allocation, so the variable is named.
    #[error(
        "Vulkan call {call} failed: {result} (with {variable}={value}: the Vulkan loader fails this way on a driver manifest it cannot parse; check that the file is valid JSON naming an installed driver)"
    )]
    DriverManifest {
        /// The entry point that failed.
        call: &'static str,
        /// The code it returned.
        result: vk::Result,
        /// `VK_ICD_FILENAMES` or `VK_DRIVER_FILES`.
        variable: &'static str,
        /// Its value.
        value: String,
    },
    /// No physical device matches the request or has what dispmap needs.
    #[error("no suitable Vulkan device: {0}")]
    NoDevice(String),
    /// The device lacks a feature, extension or limit.
    #[error("device {device} does not support {what}")]
    Unsupported {
        /// Device name.
        device: String,
        /// What is missing.
        what: String,
    },
    /// gpu-allocator failed.
    #[error("GPU memory allocation failed for {name}: {source}")]
    Allocation {
        /// Debug name of the resource.
        name: String,
        /// The allocator's error.
        source: gpu_allocator::AllocationError,
    },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// An image file could not be decoded or encoded.
    #[error("{path}: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Misuse: an object was used after its `destroy`.
    #[error("{0} used after destroy()")]
    Destroyed(&'static str),
    /// An internal invariant broke (e.g. a thread panicked while holding the allocator's
    /// lock); not caused by the input.
    #[error("internal error: {0}")]
    Internal(String),
    /// A parameter is out of range or inconsistent.
    #[error("invalid {name}: {message}")]
    InvalidInput {
        /// The option or field, e.g. `--steps`.
        name: String,
        /// Why it is rejected.
        message: String,
    },
}

/// Short form used across the crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Adds the failing call's name to a `vk::Result`.
pub(crate) trait VkContext<T> {
    /// Names the call that produced the error.
    fn vk(self, call: &'static str) -> Result<T>;
}

impl<T> VkContext<T> for std::result::Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T> {
        self.map_err(|result| Error::Vulkan { call, result })
    }
}

impl Error {
    /// Builds an [`Error::InvalidInput`].
    pub fn invalid(name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::InvalidInput {
            name: name.into(),
            message: message.into(),
        }
    }
}
