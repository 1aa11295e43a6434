//! A wgpu device over a Vulkan device that has what the displacement pass needs, and the
//! dispmap context over the same device.

use crate::{Error, Result, Vulkan};
use dispmap::ash::{self, vk};
use dispmap::context::{Context, HostHandles};
use dispmap::embed;
use dispmap::gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{CStr, c_void};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// What [`WgpuDevice::new`] creates.
#[derive(Clone, Debug, Default)]
pub struct DeviceOptions {
    /// The Khronos validation layer with synchronization validation, every warning and
    /// error counted ([`WgpuDevice::messages`]), and wgpu's own validation
    /// (`InstanceFlags::VALIDATION`, uncaptured wgpu errors counted).
    pub validation: bool,
    /// wgpu features the application needs besides wgpu's defaults (e.g.
    /// `IMMEDIATES`); every one must be supported by the chosen adapter.
    pub features: wgpu::Features,
    /// wgpu limits the application needs (`wgpu::Limits::default()` when left default).
    pub limits: wgpu::Limits,
}

/// Validation messages counted since the instance was created: the Vulkan layers'
/// warnings and errors and wgpu's uncaptured errors.
#[derive(Debug, Default)]
pub struct Messages {
    warnings: AtomicU64,
    errors: AtomicU64,
    wgpu_errors: AtomicU64,
}

impl Messages {
    /// Vulkan validation warnings.
    pub fn warnings(&self) -> u64 {
        self.warnings.load(Ordering::SeqCst)
    }
    /// Vulkan validation errors.
    pub fn errors(&self) -> u64 {
        self.errors.load(Ordering::SeqCst)
    }
    /// wgpu validation errors (the device's uncaptured errors).
    pub fn wgpu_errors(&self) -> u64 {
        self.wgpu_errors.load(Ordering::SeqCst)
    }
    /// All of them.
    pub fn total(&self) -> u64 {
        self.warnings() + self.errors() + self.wgpu_errors()
    }
}

/// A wgpu device on Vulkan with the displacement pass's requirements enabled, and the
/// dispmap [`Context`] over the same `VkDevice`.
///
/// Teardown: destroy every `DisplacementPass` and [`crate::DepthMerge`] built on
/// [`WgpuDevice::context`] (after the device is idle: [`crate::wait_for`]) and drop
/// every other clone of the context before this value is dropped; dropping it drops the
/// context (dispmap's allocator) first, then the wgpu queue, device, adapter and
/// instance. The `VkInstance` (and the debug messenger) is destroyed when wgpu drops its
/// last object of it.
pub struct WgpuDevice {
    context: Option<Arc<Context>>,
    /// The queue.
    pub queue: wgpu::Queue,
    /// The device.
    pub device: wgpu::Device,
    /// The adapter (its `VkPhysicalDevice` passed dispmap's checks).
    pub adapter: wgpu::Adapter,
    /// The instance (Vulkan only).
    pub instance: wgpu::Instance,
    messages: Arc<Messages>,
    name: String,
}

impl WgpuDevice {
    /// Creates the instance, picks the best device that dispmap and wgpu support
    /// (discrete, integrated, virtual, CPU), opens it with wgpu's extensions and features
    /// for `options.features` plus the pass's (`VK_KHR_push_descriptor`,
    /// `synchronization2`, and `dynamicRendering` for [`crate::DepthMerge`]) and wraps it.
    pub fn new(options: &DeviceOptions) -> Result<Self> {
        let messages = Arc::new(Messages::default());
        // SAFETY: loading the system Vulkan loader runs its initialisation code; nothing
        // else in this function races it.
        let entry = unsafe { ash::Entry::load() }
            .map_err(|e| Error::NoDevice(format!("no Vulkan loader: {e}")))?;
        let flags = if options.validation {
            wgpu::InstanceFlags::VALIDATION | wgpu::InstanceFlags::DEBUG
        } else {
            wgpu::InstanceFlags::empty()
        };
        let api_version = embed::requirements().api_version;
        let mut extensions =
            wgpu::hal::vulkan::Instance::desired_extensions(&entry, api_version, flags)
                .map_err(|e| Error::Wgpu(format!("instance extensions: {e}")))?;
        if options.validation {
            // SAFETY: plain query on a loaded entry.
            let layers = unsafe { entry.enumerate_instance_layer_properties() }.map_err(|r| {
                Error::Vulkan {
                    call: "vkEnumerateInstanceLayerProperties",
                    result: r,
                }
            })?;
            if !layers
                .iter()
                .any(|l| l.layer_name_as_c_str().ok() == Some(VALIDATION_LAYER))
            {
                return Err(Error::NoDevice(
                    "validation requested but VK_LAYER_KHRONOS_validation is not installed".into(),
                ));
            }
            if !extensions.contains(&ash::ext::debug_utils::NAME) {
                extensions.push(ash::ext::debug_utils::NAME);
            }
        }
        let debug_utils = extensions.contains(&ash::ext::debug_utils::NAME);
        let instance = create_instance(&entry, options.validation, &extensions, &messages)?;
        let messenger = if debug_utils {
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            // SAFETY: the instance enabled VK_EXT_debug_utils; the user data is the
            // counter, kept alive by the drop callback below until the messenger is gone.
            match unsafe { du.create_debug_utils_messenger(&messenger_info(&messages), None) } {
                Ok(m) => Some((du, m)),
                Err(result) => {
                    // SAFETY: nothing was created from the instance.
                    unsafe { instance.destroy_instance(None) };
                    return Err(Error::Vulkan {
                        call: "vkCreateDebugUtilsMessengerEXT",
                        result,
                    });
                }
            }
        } else {
            None
        };
        let owned = instance.clone();
        let kept = messages.clone();
        // The loader stays loaded until the instance is gone (wgpu-hal drops its own
        // entry before it calls this).
        let loader = entry.clone();
        let drop_instance: wgpu::hal::DropCallback = Box::new(move || {
            // SAFETY: wgpu-hal calls this once, after every object of the instance is
            // gone; the messenger goes first, then the instance, then the counter.
            unsafe {
                if let Some((du, m)) = messenger {
                    du.destroy_debug_utils_messenger(m, None);
                }
                owned.destroy_instance(None);
            }
            drop(kept);
            drop(loader);
        });
        // SAFETY: `instance` was created from `entry` with `api_version`, `extensions`
        // (wgpu's desired ones) and `flags`; the drop callback destroys it.
        let hal_instance = unsafe {
            wgpu::hal::vulkan::Instance::from_raw(
                entry.clone(),
                instance.clone(),
                api_version,
                0,
                None,
                extensions,
                flags,
                wgpu::MemoryBudgetThresholds::default(),
                false,
                Some(drop_instance),
            )
        }
        .map_err(|e| Error::Wgpu(format!("wrapping the instance: {e}")))?;
        // SAFETY: a Vulkan hal instance for the Vulkan API.
        let wgpu_instance = unsafe { wgpu::Instance::from_hal::<Vulkan>(hal_instance) };
        let (adapter, physical_device, name) = pick_adapter(&wgpu_instance, &instance, options)?;
        let (device, queue) = open_device(&adapter, options)?;
        if options.validation {
            let counter = messages.clone();
            device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
                counter.wgpu_errors.fetch_add(1, Ordering::SeqCst);
                log::error!("[wgpu] {e}");
            }));
        }
        let context = {
            // SAFETY: a Vulkan device (opened through wgpu-hal's Vulkan adapter above).
            let hal = unsafe { device.as_hal::<Vulkan>() }
                .ok_or_else(|| Error::NotVulkan("the device".into()))?;
            let raw = hal.raw_device().clone();
            let allocator = Allocator::new(&AllocatorCreateDesc {
                instance: instance.clone(),
                device: raw.clone(),
                physical_device,
                debug_settings: Default::default(),
                buffer_device_address: false,
                allocation_sizes: Default::default(),
            })
            .map_err(|e| Error::Wgpu(format!("dispmap's allocator: {e}")))?;
            let handles = HostHandles {
                entry,
                instance,
                physical_device,
                device: raw,
                queue_family_index: hal.queue_family_index(),
                queue: hal.raw_queue(),
                allocator: Arc::new(Mutex::new(allocator)),
            };
            // SAFETY: the handles come from one another (wgpu-hal opened the device from
            // the physical device of this instance, the queue is its queue) and outlive
            // the context: `WgpuDevice` drops the context before the wgpu objects.
            Arc::new(unsafe { Context::from_handles(handles, debug_utils) }?)
        };
        Ok(WgpuDevice {
            context: Some(context),
            queue,
            device,
            adapter,
            instance: wgpu_instance,
            messages,
            name,
        })
    }

    /// The dispmap context over the wgpu device (for `DisplacementPass::new`).
    pub fn context(&self) -> &Arc<Context> {
        self.context.as_ref().expect("alive until drop")
    }

    /// The validation counter (it outlives the device: hold a clone to read the
    /// messages of the teardown too).
    pub fn messages(&self) -> &Arc<Messages> {
        &self.messages
    }

    /// The device's name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

impl Drop for WgpuDevice {
    fn drop(&mut self) {
        if let Some(ctx) = self.context.take() {
            if Arc::strong_count(&ctx) > 1 {
                log::error!(
                    "WgpuDevice dropped while its dispmap context is still held elsewhere \
                     (a DisplacementPass not destroyed?): the context then outlives the device"
                );
            }
            // The device is idle before dispmap's allocator frees its memory.
            let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
            drop(ctx);
        }
    }
}

fn create_instance(
    entry: &ash::Entry,
    validation: bool,
    extensions: &[&'static CStr],
    messages: &Arc<Messages>,
) -> Result<ash::Instance> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"dispmap-wgpu")
        .engine_name(c"wgpu")
        .api_version(embed::requirements().api_version);
    let layers = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        vec![]
    };
    let names: Vec<_> = extensions.iter().map(|e| e.as_ptr()).collect();
    let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    let mut messenger = messenger_info(messages);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&names);
    if extensions.contains(&ash::ext::debug_utils::NAME) {
        info = info.push_next(&mut messenger);
    }
    if validation {
        info = info.push_next(&mut features);
    }
    // SAFETY: every pointer in `info` outlives the call; the messenger's user data is the
    // counter, alive while the instance is.
    unsafe { entry.create_instance(&info, None) }.map_err(|result| Error::Vulkan {
        call: "vkCreateInstance",
        result,
    })
}

/// The best physical device that passes dispmap's checks and that wgpu exposes, with a
/// graphics + compute queue family 0 (the family wgpu-hal opens).
fn pick_adapter(
    wgpu_instance: &wgpu::Instance,
    instance: &ash::Instance,
    options: &DeviceOptions,
) -> Result<(wgpu::Adapter, vk::PhysicalDevice, String)> {
    // SAFETY: the instance was made from a Vulkan hal instance.
    let hal = unsafe { wgpu_instance.as_hal::<Vulkan>() }
        .ok_or_else(|| Error::NotVulkan("the instance".into()))?;
    // SAFETY: plain queries on the live instance.
    let devices =
        unsafe { instance.enumerate_physical_devices() }.map_err(|result| Error::Vulkan {
            call: "vkEnumeratePhysicalDevices",
            result,
        })?;
    let mut refused = Vec::new();
    let mut candidates = Vec::new();
    for pd in devices {
        // SAFETY: `pd` was enumerated from `instance`.
        let props = unsafe { instance.get_physical_device_properties(pd) };
        let name = props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // SAFETY: as above.
        if let Err(e) = unsafe { embed::check_physical_device(instance, pd) } {
            refused.push(format!("{name}: {e}"));
            continue;
        }
        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
        let family0 = families.first().is_some_and(|f| {
            f.queue_flags
                .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
                && f.timestamp_valid_bits > 0
        });
        if !family0 {
            refused.push(format!(
                "{name}: queue family 0 lacks graphics, compute or timestamps"
            ));
            continue;
        }
        let Some(exposed) = hal.expose_adapter(pd) else {
            refused.push(format!("{name}: wgpu does not expose it"));
            continue;
        };
        if !exposed.features.contains(options.features) {
            refused.push(format!(
                "{name}: lacks wgpu features {:?}",
                options.features - exposed.features
            ));
            continue;
        }
        let rank = match props.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 0,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 3,
            _ => 4,
        };
        candidates.push((rank, pd, name, exposed));
    }
    candidates.sort_by_key(|c| c.0);
    let Some((_, pd, name, exposed)) = candidates.into_iter().next() else {
        return Err(Error::NoDevice(refused.join("; ")));
    };
    // SAFETY: the exposed adapter comes from this instance's hal instance.
    let adapter = unsafe { wgpu_instance.create_adapter_from_hal::<Vulkan>(exposed) };
    Ok((adapter, pd, name))
}

/// Opens the device through wgpu-hal with the pass's extension and features added.
fn open_device(
    adapter: &wgpu::Adapter,
    options: &DeviceOptions,
) -> Result<(wgpu::Device, wgpu::Queue)> {
    let limits = options.limits.clone();
    let hints = wgpu::MemoryHints::Performance;
    let open = {
        // SAFETY: the adapter was created from a Vulkan hal adapter.
        let hal = unsafe { adapter.as_hal::<Vulkan>() }
            .ok_or_else(|| Error::NotVulkan("the adapter".into()))?;
        // The pass's needs, as their own (pre-1.3) structures: wgpu-hal chains others of
        // the 1.3 promoted features (image robustness) on their own too, so a
        // VkPhysicalDeviceVulkan13Features would be invalid next to them.
        let mut sync2 =
            vk::PhysicalDeviceSynchronization2Features::default().synchronization2(true);
        let mut dynamic =
            vk::PhysicalDeviceDynamicRenderingFeatures::default().dynamic_rendering(true);
        let (sync2, dynamic) = (&mut sync2, &mut dynamic);
        let callback: Box<wgpu::hal::vulkan::CreateDeviceCallback<'_>> = Box::new(move |args| {
            for ext in embed::requirements().device_extensions {
                if !args.extensions.contains(ext) {
                    args.extensions.push(ext);
                }
            }
            let info = std::mem::take(args.create_info);
            *args.create_info = info.push_next(sync2).push_next(dynamic);
        });
        // SAFETY: the callback only adds an extension the physical device has and
        // features it supports (both checked by `embed::check_physical_device` when the
        // adapter was picked); nothing is removed.
        unsafe { hal.open_with_callback(options.features, &limits, &hints, Some(callback)) }
            .map_err(|e| Error::Wgpu(format!("opening the device: {e}")))?
    };
    let desc = wgpu::DeviceDescriptor {
        label: Some("dispmap-wgpu"),
        required_features: options.features,
        required_limits: limits,
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: hints,
        trace: wgpu::Trace::Off,
    };
    // SAFETY: the hal device was opened from this adapter with `desc`'s features.
    unsafe { adapter.create_device_from_hal::<Vulkan>(open, &desc) }
        .map_err(|e| Error::Wgpu(format!("wrapping the device: {e}")))
}

fn messenger_info(messages: &Arc<Messages>) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(on_message))
        .user_data(Arc::as_ptr(messages) as *mut c_void)
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the duration of the call.
    let data = unsafe { data.as_ref() };
    let text = |p: *const std::ffi::c_char| {
        // SAFETY: a non-null message / id name is a NUL-terminated string owned by the
        // layer for the duration of the call.
        (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    };
    let message = data.and_then(|d| text(d.p_message)).unwrap_or_default();
    // The loader's notices (GENERAL, "Loader Message") are not findings.
    let loader_notice = kind == vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
        && data.and_then(|d| text(d.p_message_id_name)).as_deref() == Some("Loader Message");
    if loader_notice {
        log::info!("[vulkan notice] {message}");
        return vk::FALSE;
    }
    // SAFETY: `user` is `Arc::as_ptr` of the counter, alive until the messenger and the
    // instance are destroyed (the instance's drop callback holds a clone).
    let counter = unsafe { (user as *const Messages).as_ref() };
    if let Some(c) = counter {
        if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            c.errors.fetch_add(1, Ordering::SeqCst);
        } else {
            c.warnings.fetch_add(1, Ordering::SeqCst);
        }
    }
    log::error!("[vulkan {kind:?} {severity:?}] {message}");
    vk::FALSE
}
