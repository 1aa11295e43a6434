//! The Vulkan context: instance, physical device, device, one queue and the allocator.
//!
//! Two ways in, one code path:
//! * [`Context::headless`] creates everything itself (the CLI, tests and benchmarks): it
//!   loads the Vulkan library, creates an instance (with `VK_LAYER_KHRONOS_validation`
//!   and synchronization validation when `DISPMAP_VALIDATION=1`, and a debug messenger
//!   that counts and logs warning and error messages), picks a device, creates the
//!   device and a `gpu_allocator` allocator, then hands them to the same assembly step
//!   as the host path.
//! * [`Context::from_handles`] wraps a host engine's instance, physical device, device,
//!   queue and allocator. It never creates or destroys those handles.
//!
//! Device choice: `DISPMAP_DEVICE` (or the CLI's `--device`) selects by index in
//! enumeration order or by a case-insensitive substring of the name; otherwise a discrete
//! GPU is preferred, then integrated, virtual, and the CPU (lavapipe) last. Devices that
//! lack what dispmap needs (see [`requirements`]) are skipped with a logged reason.

use crate::error::{Error, Result, VkContext};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{CStr, CString, c_void};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

mod setup;

pub use setup::DEVICE_ENTRY_POINTS;
use setup::*;

/// The validation layer's name.
pub const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";
/// Environment variable that switches validation on (`1`, `true`, `on`, `yes`) or off
/// (`0`, `false`, `off`, `no`, empty); any other value is an error naming it.
pub const ENV_VALIDATION: &str = "DISPMAP_VALIDATION";
/// Environment variable that selects the device (index or name substring).
pub const ENV_DEVICE: &str = "DISPMAP_DEVICE";

/// What dispmap needs from a device, checked before it is used.
pub mod requirements {
    use ash::vk;
    use std::ffi::CStr;

    /// Minimum Vulkan API version (dynamic rendering and synchronization2 are core in 1.3).
    pub const API_VERSION: u32 = vk::API_VERSION_1_3;
    /// Device extensions: push descriptors let passes bind per recording, so a host can
    /// record frame N+1 while frame N runs without per-frame descriptor pools.
    pub const DEVICE_EXTENSIONS: &[&CStr] = &[ash::khr::push_descriptor::NAME];
    /// Formats and the features each needs (`format`, `optimal tiling features`).
    pub const FORMATS: &[(vk::Format, vk::FormatFeatureFlags)] = &[
        (
            vk::Format::R32G32B32A32_SFLOAT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::COLOR_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::STORAGE_IMAGE.as_raw()
                    | vk::FormatFeatureFlags::SAMPLED_IMAGE.as_raw(),
            ),
        ),
        // The hit uv image (a colour attachment of the forward path).
        (
            vk::Format::R32G32_SFLOAT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::COLOR_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::STORAGE_IMAGE.as_raw(),
            ),
        ),
        // The iteration counts (a colour attachment of the forward path).
        (
            vk::Format::R32_UINT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::COLOR_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::STORAGE_IMAGE.as_raw(),
            ),
        ),
        (
            vk::Format::R32G32_UINT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::COLOR_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::SAMPLED_IMAGE.as_raw(),
            ),
        ),
        (
            vk::Format::D32_SFLOAT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::SAMPLED_IMAGE.as_raw(),
            ),
        ),
        (
            vk::Format::R8G8B8A8_UNORM,
            vk::FormatFeatureFlags::STORAGE_IMAGE,
        ),
        (
            vk::Format::R8_UNORM,
            vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
        ),
        (
            vk::Format::R16_UNORM,
            vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
        ),
        // Height maps (filtered), the hit height image and the corrected depth.
        (
            vk::Format::R32_SFLOAT,
            vk::FormatFeatureFlags::from_raw(
                vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR.as_raw()
                    | vk::FormatFeatureFlags::COLOR_ATTACHMENT.as_raw()
                    | vk::FormatFeatureFlags::STORAGE_IMAGE.as_raw(),
            ),
        ),
    ];
}

/// How to build a standalone context.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Switch on the validation layer (with synchronization validation).
    /// `None` reads `DISPMAP_VALIDATION`.
    pub validation: Option<bool>,
    /// Device index or name substring. `None` reads `DISPMAP_DEVICE`, then picks the best.
    pub device: Option<String>,
}

/// Facts about the chosen device, for reports.
#[derive(Clone, Debug)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct DeviceInfo {
    /// `deviceName`.
    pub name: String,
    /// Device type, e.g. `CPU` or `DISCRETE_GPU`.
    pub device_type: String,
    /// Driver name and info, e.g. `llvmpipe: Mesa 22.3.6 (LLVM 15.0.6)`.
    pub driver: String,
    /// API version as `major.minor.patch`.
    pub api_version: String,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Valid bits of timestamps on the queue used.
    pub timestamp_valid_bits: u32,
    /// `maxImageDimension2D`.
    pub max_image_dimension_2d: u32,
    /// `maxTexelBufferElements` (the mesh walk's buffer is a texel buffer).
    pub max_texel_buffer_elements: u32,
    /// Queue family index used.
    pub queue_family_index: u32,
    /// Loop iterations the driver lets one shader invocation run, when it ends an
    /// invocation past a fixed count ([`LOOP_LIMIT`] on lavapipe); `None`
    /// when only a timeout bounds it.
    pub loop_limit: Option<u32>,
}

/// Loop iterations lavapipe (Mesa's llvmpipe) lets one shader invocation run, all of
/// its loops together; past them it ends the invocation silently
/// ([`DeviceInfo::loop_limit`]; the methods' bounds check against it).
pub const LOOP_LIMIT: u32 = 65_535;

/// Counts validation (debug messenger) messages of warning and error severity.
#[derive(Debug, Default)]
pub struct MessageCounter {
    warnings: AtomicU64,
    errors: AtomicU64,
}

impl MessageCounter {
    /// Warnings seen so far.
    pub fn warnings(&self) -> u64 {
        self.warnings.load(Ordering::SeqCst)
    }
    /// Errors seen so far.
    pub fn errors(&self) -> u64 {
        self.errors.load(Ordering::SeqCst)
    }
    /// Warnings plus errors.
    pub fn total(&self) -> u64 {
        self.warnings() + self.errors()
    }
}

/// Handles a host engine hands to [`Context::from_handles`].
pub struct HostHandles {
    /// A clone of the host's loader entry (`ash::Entry` is reference-counted; the host
    /// keeps its own clone alive until its instance is destroyed).
    pub entry: ash::Entry,
    /// The host's instance.
    pub instance: ash::Instance,
    /// The physical device behind `device`.
    pub physical_device: vk::PhysicalDevice,
    /// The host's device (created with the [`requirements`]).
    pub device: ash::Device,
    /// A queue family with graphics and compute.
    pub queue_family_index: u32,
    /// A queue of that family (used only by the standalone helpers, never on the host path).
    pub queue: vk::Queue,
    /// The host's allocator.
    pub allocator: Arc<Mutex<Allocator>>,
}

/// Device, queue and allocator, with the extension loaders dispmap uses.
pub struct Context {
    entry: ash::Entry,
    instance: ash::Instance,
    physical_device: vk::PhysicalDevice,
    device: ash::Device,
    queue_family_index: u32,
    queue: vk::Queue,
    allocator: Option<Arc<Mutex<Allocator>>>,
    push_descriptor: ash::khr::push_descriptor::Device,
    debug_utils: Option<ash::ext::debug_utils::Device>,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    messages: Arc<MessageCounter>,
    info: DeviceInfo,
    owns_handles: bool,
    /// The host's pipeline cache every pipeline is created with (null: none).
    pipeline_cache: vk::PipelineCache,
    /// Whether this context enabled the Khronos validation layer on its instance.
    validation: bool,
    /// [`Context::traversal_rules`].
    traversal_rules: bool,
    /// [`Context::multi_draw_indirect`].
    multi_draw_indirect: bool,
}

impl Context {
    /// Creates a standalone headless context (instance, device, queue, allocator).
    pub fn headless(options: &ContextOptions) -> Result<Self> {
        Self::with_extensions(options, &[], &[])
    }

    /// [`Context::headless`] with more instance and device extensions enabled, e.g. a
    /// window system's surface extensions and `VK_KHR_swapchain` for a viewer that
    /// presents the frames. An instance extension the loader lacks, or a device extension
    /// the chosen device lacks, is an error naming it; the device choice is the same as
    /// [`Context::headless`]'s.
    pub fn with_extensions(
        options: &ContextOptions,
        instance_extensions: &[&CStr],
        device_extensions: &[&CStr],
    ) -> Result<Self> {
        // SAFETY: loading the system Vulkan loader runs its initialisation code; it is the
        // documented way to get an entry and nothing else in this process races it.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| Error::Loader(e.to_string()))?;
        let validation = match options.validation {
            Some(v) => v,
            None => validation_from_env()?,
        };
        let messages = Arc::new(MessageCounter::default());
        let instance_exts = enumerate_instance_extensions(&entry)?;
        let has_debug_utils = instance_exts
            .iter()
            .any(|e| e == ash::ext::debug_utils::NAME);
        if validation && !validation_layer_present(&entry)? {
            let layer = VALIDATION_LAYER.to_string_lossy();
            // The loader hides a disabled layer as if it were not installed: say which.
            let disabled = std::env::var("VK_LOADER_LAYERS_DISABLE")
                .ok()
                .filter(|v| !v.is_empty());
            return Err(Error::NoDevice(match disabled {
                Some(v) => format!(
                    "{ENV_VALIDATION} is set but {layer} is not available: \
                     VK_LOADER_LAYERS_DISABLE={v} disables it (or it is not installed)"
                ),
                None => format!(
                    "{ENV_VALIDATION} is set but {layer} is not installed (apt-get install vulkan-validationlayers)"
                ),
            }));
        }
        let absent: Vec<String> = instance_extensions
            .iter()
            .filter(|want| !instance_exts.iter().any(|e| e.as_c_str() == **want))
            .map(|want| want.to_string_lossy().into_owned())
            .collect();
        if !absent.is_empty() {
            return Err(Error::NoDevice(format!(
                "the Vulkan loader lacks the instance extension(s) {}",
                absent.join(", ")
            )));
        }
        let instance = create_instance(
            &entry,
            validation,
            has_debug_utils,
            instance_extensions,
            &messages,
        )?;
        let messenger = if has_debug_utils {
            let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = messenger_info(&messages);
            // SAFETY: `instance` is valid and was created with VK_EXT_debug_utils; the
            // callback's user data points into `messages`, which the context keeps alive
            // until the messenger is destroyed in `Drop`.
            let handle = unsafe { loader.create_debug_utils_messenger(&info, None) }
                .vk("vkCreateDebugUtilsMessengerEXT")?;
            Some((loader, handle))
        } else {
            None
        };
        let result = Self::create_device(&instance, options, device_extensions);
        let (physical_device, device, queue_family_index, queue, multi_draw_indirect) = match result
        {
            Ok(v) => v,
            Err(e) => {
                // SAFETY: nothing else was created from this instance yet.
                unsafe {
                    if let Some((loader, handle)) = &messenger {
                        loader.destroy_debug_utils_messenger(*handle, None);
                    }
                    instance.destroy_instance(None);
                }
                return Err(e);
            }
        };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: {
                let mut settings = gpu_allocator::AllocatorDebugSettings::default();
                settings.log_leaks_on_shutdown = true;
                settings
            },
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|source| Error::Allocation {
            name: "allocator".into(),
            source,
        })?;
        let handles = HostHandles {
            entry,
            instance,
            physical_device,
            device,
            queue_family_index,
            queue,
            allocator: Arc::new(Mutex::new(allocator)),
        };
        // SAFETY: the handles were created above, from one another, and are owned by
        // the returned context (`owns_handles`), which destroys them in `Drop`.
        let mut ctx = unsafe { Self::assemble(handles, messages, messenger, has_debug_utils) }?;
        ctx.owns_handles = true;
        ctx.validation = validation;
        ctx.multi_draw_indirect = multi_draw_indirect;
        ctx.set_name(ctx.device.handle(), "dispmap.device");
        ctx.set_name(ctx.queue, "dispmap.queue");
        Ok(ctx)
    }

    /// Wraps a host engine's handles. dispmap never destroys them.
    ///
    /// Debug names are set only if the host's instance enabled `VK_EXT_debug_utils`
    /// (tell it with `debug_utils_enabled`).
    ///
    /// # Safety
    /// All handles must be valid, created from one another (`device` from
    /// `physical_device` of `instance`, `queue` from `device` in `queue_family_index`,
    /// `allocator` for `device`), and outlive the context and everything created from
    /// it. The device must have been created with everything [`Context::check_device`]
    /// asks for: it is checked here and a missing feature is an error.
    pub unsafe fn from_handles(handles: HostHandles, debug_utils_enabled: bool) -> Result<Self> {
        // SAFETY: forwarded from this function's contract.
        unsafe {
            Self::assemble(
                handles,
                Arc::new(MessageCounter::default()),
                None,
                debug_utils_enabled,
            )
        }
    }

    /// The shared assembly step of both constructors.
    ///
    /// # Safety
    /// As [`Context::from_handles`].
    unsafe fn assemble(
        handles: HostHandles,
        messages: Arc<MessageCounter>,
        messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
        debug_utils_enabled: bool,
    ) -> Result<Self> {
        let HostHandles {
            entry,
            instance,
            physical_device,
            device,
            queue_family_index,
            queue,
            allocator,
        } = handles;
        Self::check_device(&instance, physical_device).map_err(|missing| Error::Unsupported {
            device: device_name(&instance, physical_device),
            what: missing,
        })?;
        // SAFETY: `device` is a live device of `instance` (this function's contract).
        let missing = unsafe { missing_entry_points(&instance, &device) };
        if !missing.is_empty() {
            return Err(Error::Unsupported {
                device: device_name(&instance, physical_device),
                what: format!(
                    "device entry points {} (a Vulkan 1.3 device, created from an instance with apiVersion 1.3, with {} enabled)",
                    missing.join(", "),
                    ash::khr::push_descriptor::NAME.to_string_lossy()
                ),
            });
        }
        let info = device_info(&instance, physical_device, queue_family_index);
        let push_descriptor = ash::khr::push_descriptor::Device::new(&instance, &device);
        let debug_utils =
            debug_utils_enabled.then(|| ash::ext::debug_utils::Device::new(&instance, &device));
        Ok(Context {
            entry,
            instance,
            physical_device,
            device,
            queue_family_index,
            queue,
            allocator: Some(allocator),
            push_descriptor,
            debug_utils,
            messenger,
            messages,
            owns_handles: false,
            pipeline_cache: vk::PipelineCache::null(),
            validation: false,
            traversal_rules: info.device_type == format!("{:?}", vk::PhysicalDeviceType::CPU),
            multi_draw_indirect: false,
            info,
        })
    }

    /// Creates every later pipeline of this context (those of passes built from now on)
    /// with the host's `cache`, as engines do to ship warm pipeline caches; the host keeps
    /// it alive and destroys it after the context (dispmap never destroys it, and only
    /// reads and writes it inside `vkCreate*Pipelines`).
    ///
    /// # Safety
    /// `cache` is a pipeline cache of this context's device, alive as long as the
    /// context, and not used by another thread while dispmap creates pipelines
    /// (`VK_PIPELINE_CACHE_CREATE_EXTERNALLY_SYNCHRONIZED_BIT` caches included) unless it
    /// was created without that flag, which Vulkan makes thread-safe.
    pub unsafe fn with_pipeline_cache(mut self, cache: vk::PipelineCache) -> Self {
        self.pipeline_cache = cache;
        self
    }

    /// The pipeline cache pipelines are created with (null: none).
    pub fn pipeline_cache(&self) -> vk::PipelineCache {
        self.pipeline_cache
    }

    /// Builds every later pipeline of this context with the exact traversals' two step
    /// rules on or off ([`Context::traversal_rules`]): the same hits either way, only the
    /// step counts and the time change. For measuring and testing the other device
    /// kind's choice.
    pub fn with_traversal_rules(mut self, on: bool) -> Self {
        self.traversal_rules = on;
        self
    }

    /// Whether the cell-pyramid traversals (`exact`, `dig-guarded`, the cone methods'
    /// builds, hard shadows) cap their start level and climb only from the first child
    /// of a parent (`glsl/common/pyramid.glsl`, the `TRAVERSAL_RULES` specialization
    /// constant). They save steps, which pays on a CPU driver running 8 invocations in
    /// lockstep (lavapipe: 8-14% of `exact`'s time) and costs on a GPU's 32-wide
    /// warps (measured on an NVIDIA H200: `exact` 0.87-0.95x of its time without them);
    /// so they are on for `CPU` devices and off for the others (BENCHMARKS.md). The hits
    /// are the same either way.
    pub fn traversal_rules(&self) -> bool {
        self.traversal_rules
    }

    /// Whether the device was created with the `multiDrawIndirect` feature: dispmap's own
    /// context ([`Context::headless`]) enables it where the device has it; a host's
    /// ([`Context::from_handles`]) is taken to lack it. With it the behind layer draws
    /// each mesh's clusters with one indirect command instead of one per cluster.
    pub(crate) fn multi_draw_indirect(&self) -> bool {
        self.multi_draw_indirect
    }

    /// Checks a physical device against the [`requirements`]; the error lists what is missing.
    pub fn check_device(
        instance: &ash::Instance,
        physical_device: vk::PhysicalDevice,
    ) -> std::result::Result<(), String> {
        let mut missing = Vec::new();
        // SAFETY: `physical_device` was enumerated from `instance` (caller's contract).
        let props = unsafe { instance.get_physical_device_properties(physical_device) };
        if props.api_version < requirements::API_VERSION {
            missing.push(format!(
                "Vulkan 1.3 (has {})",
                version_string(props.api_version)
            ));
        }
        // SAFETY: as above.
        let exts = unsafe { instance.enumerate_device_extension_properties(physical_device) }
            .unwrap_or_default();
        for want in requirements::DEVICE_EXTENSIONS {
            if !exts
                .iter()
                .any(|e| e.extension_name_as_c_str().ok() == Some(*want))
            {
                missing.push(want.to_string_lossy().into_owned());
            }
        }
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13);
        // SAFETY: as above; the chain is valid for the duration of the call.
        unsafe { instance.get_physical_device_features2(physical_device, &mut f2) };
        if f13.dynamic_rendering == vk::FALSE {
            missing.push("dynamicRendering".into());
        }
        if f13.synchronization2 == vk::FALSE {
            missing.push("synchronization2".into());
        }
        if props.limits.timestamp_compute_and_graphics == vk::FALSE {
            missing.push("timestampComputeAndGraphics".into());
        }
        for (format, features) in requirements::FORMATS {
            // SAFETY: as above.
            let fp =
                unsafe { instance.get_physical_device_format_properties(physical_device, *format) };
            if !fp.optimal_tiling_features.contains(*features) {
                missing.push(format!("{format:?} with {features:?}"));
            }
        }
        if missing.is_empty() {
            Ok(())
        } else {
            Err(missing.join(", "))
        }
    }

    fn create_device(
        instance: &ash::Instance,
        options: &ContextOptions,
        extra_extensions: &[&CStr],
    ) -> Result<(vk::PhysicalDevice, ash::Device, u32, vk::Queue, bool)> {
        // SAFETY: `instance` is a valid instance.
        let devices =
            unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        if devices.is_empty() {
            return Err(Error::NoDevice(
                "the Vulkan loader reports no devices (install mesa-vulkan-drivers for lavapipe)"
                    .into(),
            ));
        }
        let selector = options
            .device
            .clone()
            .or_else(|| std::env::var(ENV_DEVICE).ok().filter(|s| !s.is_empty()));
        let physical_device = pick_device(instance, &devices, selector.as_deref())?;
        let queue_family_index = graphics_compute_family(instance, physical_device)
            .ok_or_else(|| Error::NoDevice("no queue family with graphics and compute".into()))?;
        let priorities = [1.0];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family_index)
            .queue_priorities(&priorities)];
        // SAFETY: `physical_device` was enumerated from `instance`.
        let available = unsafe { instance.enumerate_device_extension_properties(physical_device) }
            .vk("vkEnumerateDeviceExtensionProperties")?;
        let absent: Vec<String> = extra_extensions
            .iter()
            .filter(|want| {
                !available
                    .iter()
                    .any(|e| e.extension_name_as_c_str().ok() == Some(**want))
            })
            .map(|want| want.to_string_lossy().into_owned())
            .collect();
        if !absent.is_empty() {
            return Err(Error::Unsupported {
                device: device_name(instance, physical_device),
                what: absent.join(", "),
            });
        }
        let mut ext_names: Vec<&CStr> = requirements::DEVICE_EXTENSIONS.to_vec();
        for e in extra_extensions {
            if !ext_names.contains(e) {
                ext_names.push(e);
            }
        }
        let ext_names: Vec<_> = ext_names.iter().map(|e| e.as_ptr()).collect();
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true);
        // SAFETY: `physical_device` was enumerated from `instance`.
        let available = unsafe { instance.get_physical_device_features(physical_device) };
        // Optional: the behind layer's draws use it where the device has it.
        let multi_draw_indirect = available.multi_draw_indirect == vk::TRUE;
        let features =
            vk::PhysicalDeviceFeatures::default().multi_draw_indirect(multi_draw_indirect);
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_names)
            .enabled_features(&features)
            .push_next(&mut f13);
        // SAFETY: the physical device passed `check_device`, so the extensions and
        // features requested exist; all pointers in `info` outlive the call.
        let device =
            unsafe { instance.create_device(physical_device, &info, None) }.vk("vkCreateDevice")?;
        // SAFETY: the queue family and index 0 were requested at device creation.
        let queue = unsafe { device.get_device_queue(queue_family_index, 0) };
        Ok((
            physical_device,
            device,
            queue_family_index,
            queue,
            multi_draw_indirect,
        ))
    }

    /// The loader entry.
    pub fn entry(&self) -> &ash::Entry {
        &self.entry
    }
    /// The instance.
    pub fn instance(&self) -> &ash::Instance {
        &self.instance
    }
    /// The physical device.
    pub fn physical_device(&self) -> vk::PhysicalDevice {
        self.physical_device
    }
    /// The optimal-tiling features the device has for `format`.
    pub fn format_features(&self, format: vk::Format) -> vk::FormatFeatureFlags {
        // SAFETY: the physical device belongs to the context's instance, alive as long as
        // the context.
        unsafe {
            self.instance
                .get_physical_device_format_properties(self.physical_device, format)
        }
        .optimal_tiling_features
    }
    /// The logical device.
    pub fn device(&self) -> &ash::Device {
        &self.device
    }
    /// The queue family used for every pass.
    pub fn queue_family_index(&self) -> u32 {
        self.queue_family_index
    }
    /// The queue (standalone submissions only).
    pub fn queue(&self) -> vk::Queue {
        self.queue
    }
    /// The shared allocator.
    pub fn allocator(&self) -> &Arc<Mutex<Allocator>> {
        self.allocator
            .as_ref()
            .expect("the allocator exists until the context is dropped")
    }
    /// `VK_KHR_push_descriptor` functions.
    pub fn push_descriptor(&self) -> &ash::khr::push_descriptor::Device {
        &self.push_descriptor
    }
    /// Facts about the device.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }
    /// Validation messages counted so far (standalone contexts with a messenger).
    pub fn messages(&self) -> &Arc<MessageCounter> {
        &self.messages
    }
    /// Whether a debug messenger is installed (validation or debug utils available).
    pub fn has_messenger(&self) -> bool {
        self.messenger.is_some()
    }

    /// Whether this context enabled the Khronos validation layer on the instance it
    /// created (`ContextOptions::validation` or `DISPMAP_VALIDATION`); `false` for a
    /// host's handles ([`Context::from_handles`]), whose layers the host chose.
    pub fn validation_enabled(&self) -> bool {
        self.validation
    }

    /// Gives a Vulkan object a debug name (no-op without `VK_EXT_debug_utils`).
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(cname) = CString::new(name.replace('\0', " ")) else {
                return;
            };
            let info = vk::DebugUtilsObjectNameInfoEXT::default()
                .object_handle(handle)
                .object_name(&cname);
            // SAFETY: the handle belongs to this device and `info` outlives the call. A
            // failure only loses a debug name.
            if let Err(e) = unsafe { du.set_debug_utils_object_name(&info) } {
                log::debug!("cannot name {name}: {e}");
            }
        }
    }

    /// Opens a debug label region in `cmd` (shows up in captures and validation messages).
    ///
    /// # Safety
    /// `cmd` is a command buffer of this context's device in the recording state; the
    /// region is closed by [`Context::end_label`] later in the same command buffer (or one
    /// submitted after it to the same queue).
    pub unsafe fn begin_label(&self, cmd: vk::CommandBuffer, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(cname) = CString::new(name) else {
                return;
            };
            let label = vk::DebugUtilsLabelEXT::default().label_name(&cname);
            // SAFETY: this function's # Safety contract: `cmd` is a recording command
            // buffer of this device; `label` outlives the call.
            unsafe { du.cmd_begin_debug_utils_label(cmd, &label) };
        }
    }

    /// Closes the region opened by [`Context::begin_label`].
    ///
    /// # Safety
    /// `cmd` is a command buffer of this context's device in the recording state, and a
    /// region opened by [`Context::begin_label`] is open in it (or in one submitted
    /// earlier to the same queue).
    pub unsafe fn end_label(&self, cmd: vk::CommandBuffer) {
        if let Some(du) = &self.debug_utils {
            // SAFETY: this function's # Safety contract: `cmd` is recording and a region
            // opened by `begin_label` is open.
            unsafe { du.cmd_end_debug_utils_label(cmd) };
        }
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        if !self.owns_handles {
            return;
        }
        // SAFETY: the context created these handles and everything made from them must
        // have been destroyed by now (their `destroy` methods take `&Context`, so they
        // cannot outlive it in safe code). Waiting for idle makes GPU work finish first.
        unsafe {
            let _ = self.device.device_wait_idle();
        }
        if let Some(allocator) = self.allocator.take() {
            match Arc::try_unwrap(allocator) {
                Ok(mutex) => drop(mutex), // reports leaks through `log` on drop
                Err(_) => log::error!("allocator still shared at context drop: leaking it"),
            }
        }
        // SAFETY: as above; the allocator is gone, nothing else uses the device.
        unsafe {
            self.device.destroy_device(None);
            if let Some((loader, handle)) = self.messenger.take() {
                loader.destroy_debug_utils_messenger(handle, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Calls the messenger callback as a layer would.
    fn deliver(
        counter: &MessageCounter,
        severity: vk::DebugUtilsMessageSeverityFlagsEXT,
        kind: vk::DebugUtilsMessageTypeFlagsEXT,
        id_name: Option<&CStr>,
    ) {
        let text = c"a message";
        let mut data = vk::DebugUtilsMessengerCallbackDataEXT::default().message(text);
        if let Some(name) = id_name {
            data = data.message_id_name(name);
        }
        // SAFETY: the data and its string live across the call; `user` points at a live
        // MessageCounter, as the messenger's does.
        unsafe {
            debug_callback(
                severity,
                kind,
                &data,
                counter as *const MessageCounter as *mut c_void,
            )
        };
    }

    #[test]
    fn loader_notices_are_logged_and_findings_counted() {
        use vk::DebugUtilsMessageSeverityFlagsEXT as S;
        use vk::DebugUtilsMessageTypeFlagsEXT as T;
        let counter = MessageCounter::default();
        // The loader's notice that VK_INSTANCE_LAYERS inserted the validation layer.
        deliver(&counter, S::WARNING, T::GENERAL, Some(c"Loader Message"));
        deliver(&counter, S::ERROR, T::GENERAL, Some(c"Loader Message"));
        assert_eq!(counter.total(), 0);
        deliver(&counter, S::WARNING, T::VALIDATION, None);
        deliver(&counter, S::ERROR, T::VALIDATION, Some(c"VUID-x"));
        deliver(&counter, S::WARNING, T::PERFORMANCE, None);
        deliver(&counter, S::INFO, T::VALIDATION, None);
        deliver(&counter, S::INFO, T::GENERAL, None);
        assert_eq!((counter.errors(), counter.warnings()), (1, 2));
        // GENERAL findings of a layer (any other name, or none) count.
        deliver(&counter, S::WARNING, T::GENERAL, None);
        deliver(&counter, S::ERROR, T::GENERAL, Some(c"UNASSIGNED-x"));
        // The loader's name on a message that is not GENERAL alone counts too.
        deliver(
            &counter,
            S::ERROR,
            T::GENERAL | T::VALIDATION,
            Some(c"Loader Message"),
        );
        assert_eq!((counter.errors(), counter.warnings()), (3, 3));
    }

    #[test]
    fn the_validation_switch_refuses_what_it_does_not_know() {
        for on in ["1", "true", "ON", "yes", " on "] {
            assert_eq!(parse_switch(on), Some(true), "{on}");
        }
        for off in ["", "0", "false", "Off", "no"] {
            assert_eq!(parse_switch(off), Some(false), "{off}");
        }
        for bad in ["2", "enable", "y"] {
            assert_eq!(parse_switch(bad), None, "{bad}");
        }
    }
}
