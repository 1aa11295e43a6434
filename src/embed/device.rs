//! What the displacement pass needs from the host's device: [`requirements`] before
//! `vkCreateDevice`, and the checks that turn a missing feature, extension or limit into
//! an [`Error::Unsupported`] naming it.

use crate::abi::ShadeParams;
use crate::context::{Context, requirements as context_requirements};
use crate::error::{Error, Result};
use crate::passes::PassName;
use ash::vk;
use std::ffi::CStr;

/// Timestamp queries one [`DisplacementPass::record`](super::DisplacementPass::record) writes at most: a begin/end pair
/// for each pass of [`PassName::ALL`] it records (every one but the host's `gbuffer`:
/// `upload`, `pyramid`, `cone`, `classify`, `dig_corners`, `trace`, `shadow`, `shade`,
/// `hit_depth` and `motion`).
pub const MAX_QUERIES: u32 = 2 * PassName::recorded_by_pass();

/// Largest `frames_in_flight` a pass accepts.
pub const MAX_FRAMES_IN_FLIGHT: u32 = 16;

/// The push-constant bytes the largest pass uses (`shade`: [`ShadeParams`]).
pub const PUSH_CONSTANT_BYTES: u32 = std::mem::size_of::<ShadeParams>() as u32;

/// Descriptors the largest pass pushes, reflected from the compute shaders' SPIR-V by
/// `build.rs` (today the self-shadowed `shade` variant: 10). Every Vulkan device with
/// `VK_KHR_push_descriptor` has at least 32.
pub const PUSH_DESCRIPTORS: u32 = crate::shaders::MAX_PASS_DESCRIPTORS;

/// What the pass needs from the host's device (see [`requirements`]).
#[derive(Clone, Debug)]
pub struct Requirements {
    /// Minimum `VkPhysicalDeviceProperties::apiVersion`.
    pub api_version: u32,
    /// Device extensions to enable.
    pub device_extensions: &'static [&'static CStr],
    /// `VkPhysicalDeviceVulkan13Features` members to enable (by their Vulkan names).
    pub vulkan13_features: &'static [&'static str],
    /// Minimum `maxPushConstantsSize`, bytes.
    pub max_push_constants_size: u32,
    /// Minimum `VkPhysicalDevicePushDescriptorPropertiesKHR::maxPushDescriptors`.
    pub max_push_descriptors: u32,
    /// `timestampComputeAndGraphics` must be true (the pass's timestamps).
    pub timestamp_compute_and_graphics: bool,
    /// Formats and the optimal-tiling features each needs.
    pub formats: &'static [(vk::Format, vk::FormatFeatureFlags)],
}

impl Requirements {
    /// Sets the required members of a `VkPhysicalDeviceVulkan13Features` the host chains
    /// into its `VkDeviceCreateInfo` (keeping what the host enabled itself, e.g. its own
    /// `dynamicRendering`).
    pub fn enable_vulkan13<'a>(
        &self,
        features: vk::PhysicalDeviceVulkan13Features<'a>,
    ) -> vk::PhysicalDeviceVulkan13Features<'a> {
        features.synchronization2(true)
    }
}

/// The device features, extensions and limits the displacement pass needs.
///
/// Only what the pass records needs to be *enabled*: `VK_KHR_push_descriptor` (every
/// pass pushes its descriptors) and `synchronization2` (every barrier and timestamp).
/// `dynamicRendering` is not listed: only dispmap's own G-buffer pass (the standalone
/// [`crate::renderer::Renderer`]) uses it, and the host enables it only if its own
/// rendering does.
///
/// What is *checked on the physical device* ([`check_physical_device`], and
/// [`Context::from_handles`] again) stays the standalone set of
/// [`Context::check_device`], which also asks for `dynamicRendering` *support* and the
/// attachment features of the G-buffer formats: both checks then accept the same
/// devices. This excludes no Vulkan 1.3 device that could run the pass with a
/// rasterised G-buffer: `dynamicRendering` support is mandatory in Vulkan 1.3, and the
/// host renders its G-buffer into those formats as attachments itself.
///
/// One method-specific need is checked when it arises instead: the cone methods' cone
/// map is an `R32G32_SFLOAT` storage image (not mandatory in Vulkan), so creating a pass
/// or switching to a cone method on a device without that format's storage support fails
/// with [`crate::error::Error::Unsupported`] naming it.
pub fn requirements() -> Requirements {
    Requirements {
        api_version: context_requirements::API_VERSION,
        device_extensions: context_requirements::DEVICE_EXTENSIONS,
        vulkan13_features: &["synchronization2"],
        max_push_constants_size: PUSH_CONSTANT_BYTES,
        max_push_descriptors: PUSH_DESCRIPTORS,
        timestamp_compute_and_graphics: true,
        formats: context_requirements::FORMATS,
    }
}

/// Checks that a physical device *supports* everything in [`requirements`]; the error
/// ([`Error::Unsupported`]) lists every missing item by its Vulkan name.
///
/// # Safety
/// `physical_device` must have been enumerated from `instance`, which must be alive.
pub unsafe fn check_physical_device(
    instance: &ash::Instance,
    physical_device: vk::PhysicalDevice,
) -> Result<()> {
    let mut missing = Vec::new();
    if let Err(m) = Context::check_device(instance, physical_device) {
        missing.push(m);
    }
    let wanted = requirements();
    let mut push = vk::PhysicalDevicePushDescriptorPropertiesKHR::default();
    let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut push);
    // SAFETY: the caller guarantees the handles; the chain outlives the call.
    unsafe { instance.get_physical_device_properties2(physical_device, &mut props) };
    let limits = props.properties.limits;
    let name = props
        .properties
        .device_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    if limits.max_push_constants_size < wanted.max_push_constants_size {
        missing.push(format!(
            "maxPushConstantsSize >= {} (has {})",
            wanted.max_push_constants_size, limits.max_push_constants_size
        ));
    }
    if push.max_push_descriptors < wanted.max_push_descriptors {
        missing.push(format!(
            "maxPushDescriptors >= {} (has {})",
            wanted.max_push_descriptors, push.max_push_descriptors
        ));
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(Error::Unsupported {
            device: name,
            what: missing.join(", "),
        })
    }
}

/// Checks that the host's `VkDeviceCreateInfo` *enables* what the pass needs: the
/// extensions of [`requirements`] and `synchronization2` (in a chained
/// `VkPhysicalDeviceVulkan13Features` or `VkPhysicalDeviceSynchronization2Features`;
/// `dynamicRendering` is not needed by the pass). Call it with the same create info
/// before (or after) `vkCreateDevice`: a device created without them would only show
/// validation errors later. The error lists every missing item.
///
/// # Safety
/// `info` must be a valid `VkDeviceCreateInfo`: its extension-name array and `pNext`
/// chain must point to live, correctly typed Vulkan structures.
pub unsafe fn check_device_create_info(info: &vk::DeviceCreateInfo) -> Result<()> {
    let mut missing = Vec::new();
    let names: Vec<&CStr> = (0..info.enabled_extension_count as usize)
        .map(|i| {
            // SAFETY: the caller guarantees `pp_enabled_extension_names` holds
            // `enabled_extension_count` NUL-terminated strings.
            unsafe { CStr::from_ptr(*info.pp_enabled_extension_names.add(i)) }
        })
        .collect();
    for want in requirements().device_extensions {
        if !names.contains(want) {
            missing.push(want.to_string_lossy().into_owned());
        }
    }
    let mut sync2 = false;
    let mut next = info.p_next as *const vk::BaseInStructure<'_>;
    while !next.is_null() {
        // SAFETY: every structure of a valid pNext chain starts with sType and pNext.
        let base = unsafe { &*next };
        match base.s_type {
            vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_3_FEATURES => {
                // SAFETY: the sType says which structure this is.
                let f = unsafe { &*(next as *const vk::PhysicalDeviceVulkan13Features<'_>) };
                sync2 |= f.synchronization2 == vk::TRUE;
            }
            vk::StructureType::PHYSICAL_DEVICE_SYNCHRONIZATION_2_FEATURES => {
                // SAFETY: as above.
                let f =
                    unsafe { &*(next as *const vk::PhysicalDeviceSynchronization2Features<'_>) };
                sync2 |= f.synchronization2 == vk::TRUE;
            }
            _ => {}
        }
        next = base.p_next;
    }
    if !sync2 {
        missing.push("synchronization2 (not enabled)".into());
    }
    if missing.is_empty() {
        Ok(())
    } else {
        Err(Error::Unsupported {
            device: "the host's VkDeviceCreateInfo".into(),
            what: missing.join(", "),
        })
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn create_info_without_the_extension_or_features_is_a_clear_error() {
        let info = vk::DeviceCreateInfo::default();
        // SAFETY: a default create info has no extensions and no chain.
        let err = unsafe { check_device_create_info(&info) }
            .unwrap_err()
            .to_string();
        assert!(err.contains("VK_KHR_push_descriptor"), "{err}");
        assert!(err.contains("synchronization2"), "{err}");

        let exts = [ash::khr::push_descriptor::NAME.as_ptr()];
        let mut f13 = requirements().enable_vulkan13(vk::PhysicalDeviceVulkan13Features::default());
        let info = vk::DeviceCreateInfo::default()
            .enabled_extension_names(&exts)
            .push_next(&mut f13);
        // SAFETY: the names and the chain live on this stack frame.
        unsafe { check_device_create_info(&info) }.unwrap();
        assert_eq!(
            f13.dynamic_rendering,
            vk::FALSE,
            "the pass needs no dynamicRendering"
        );
        assert_eq!(requirements().vulkan13_features, ["synchronization2"]);

        // synchronization2 through its own (pre-1.3 extension) structure counts too.
        let mut sync2 =
            vk::PhysicalDeviceSynchronization2Features::default().synchronization2(true);
        let info = vk::DeviceCreateInfo::default()
            .enabled_extension_names(&exts)
            .push_next(&mut sync2);
        // SAFETY: as above.
        unsafe { check_device_create_info(&info) }.unwrap();
    }

    #[test]
    fn requirements_cover_the_largest_pass() {
        let r = requirements();
        assert_eq!(r.max_push_constants_size, 128);
        assert!(
            r.device_extensions
                .contains(&ash::khr::push_descriptor::NAME)
        );
        assert!(
            r.formats
                .iter()
                .any(|(f, _)| *f == crate::passes::trace::HIT_UV_FORMAT)
        );
        // The iteration variants of `exact`'s mesh walk (its first trace and the walk)
        // push the most descriptors (11, reflected; the self-shadowed shade 10).
        for shader in [
            crate::shaders::TRACE_EXACT_COMP_CURVED_WALK_ITERATIONS,
            crate::shaders::TRACE_EXACT_COMP_WALK_FIRST_ITERATIONS,
        ] {
            assert_eq!(r.max_push_descriptors, shader.bindings.len() as u32);
        }
        assert_eq!(crate::shaders::SHADE_COMP_SHADOWS.bindings.len(), 10);
        assert_eq!(r.max_push_descriptors, 11);
        let largest = [
            std::mem::size_of::<crate::abi::ShadowParams>(),
            std::mem::size_of::<crate::abi::HitDepthParams>(),
            std::mem::size_of::<crate::abi::MotionParams>(),
            std::mem::size_of::<crate::abi::TraceParams>(),
        ];
        assert!(
            largest
                .iter()
                .all(|&b| b as u32 <= r.max_push_constants_size)
        );
    }

    /// `PUSH_DESCRIPTORS` is the largest compute pass's count of descriptors, and the
    /// timestamp queries cover every pass the displacement pass records.
    #[test]
    fn device_requirements_from_the_shaders() {
        let passes = crate::shaders::ALL.iter().filter(|s| {
            (s.name.ends_with(".comp") || s.name.contains(".comp["))
                && !s.name.starts_with("examples/")
                && !s.name.starts_with("tests/")
        });
        let largest = passes.map(|s| s.bindings.len() as u32).max();
        assert_eq!(largest, Some(super::PUSH_DESCRIPTORS));
        assert_eq!(
            super::PUSH_DESCRIPTORS,
            crate::shaders::TRACE_EXACT_COMP_CURVED_WALK_ITERATIONS
                .bindings
                .len() as u32
        );
        assert_eq!(
            super::MAX_QUERIES as usize,
            2 * (crate::passes::PassName::ALL.len() - 2)
        );
    }
}
