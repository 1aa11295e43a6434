//! Setting up a standalone context: the validation switches from the environment, the
//! instance and its debug messenger, picking the device and queue family, and what the
//! device reports ([`DeviceInfo`]) and must provide ([`DEVICE_ENTRY_POINTS`]).

use super::*;

pub(super) fn validation_from_env() -> Result<bool> {
    match std::env::var(ENV_VALIDATION) {
        Err(std::env::VarError::NotPresent) => Ok(false),
        Err(e) => Err(Error::invalid(ENV_VALIDATION, e.to_string())),
        Ok(v) => parse_switch(&v).ok_or_else(|| {
            Error::invalid(
                ENV_VALIDATION,
                format!("'{v}' is neither on (1, true, on, yes) nor off (0, false, off, no)"),
            )
        }),
    }
}

/// An on/off environment value; `None` when it is neither.
pub(super) fn parse_switch(value: &str) -> Option<bool> {
    match value.trim().to_ascii_lowercase().as_str() {
        "1" | "true" | "on" | "yes" => Some(true),
        "" | "0" | "false" | "off" | "no" => Some(false),
        _ => None,
    }
}

/// A loader-level call's error: names a driver manifest variable of the environment when
/// the loader failed with `ERROR_OUT_OF_HOST_MEMORY` (how it reports a manifest it
/// cannot parse).
pub(super) fn loader_error(call: &'static str, result: vk::Result) -> Error {
    if result == vk::Result::ERROR_OUT_OF_HOST_MEMORY {
        for variable in ["VK_DRIVER_FILES", "VK_ICD_FILENAMES"] {
            if let Ok(value) = std::env::var(variable)
                && !value.is_empty()
            {
                return Error::DriverManifest {
                    call,
                    result,
                    variable,
                    value,
                };
            }
        }
    }
    Error::Vulkan { call, result }
}

pub(super) fn enumerate_instance_extensions(entry: &ash::Entry) -> Result<Vec<CString>> {
    // SAFETY: plain query on a loaded entry.
    let props = unsafe { entry.enumerate_instance_extension_properties(None) }
        .map_err(|r| loader_error("vkEnumerateInstanceExtensionProperties", r))?;
    Ok(props
        .iter()
        .filter_map(|p| p.extension_name_as_c_str().ok().map(CStr::to_owned))
        .collect())
}

pub(super) fn validation_layer_present(entry: &ash::Entry) -> Result<bool> {
    // SAFETY: plain query on a loaded entry.
    let layers = unsafe { entry.enumerate_instance_layer_properties() }
        .map_err(|r| loader_error("vkEnumerateInstanceLayerProperties", r))?;
    Ok(layers
        .iter()
        .any(|l| l.layer_name_as_c_str().ok() == Some(VALIDATION_LAYER)))
}

pub(super) fn create_instance(
    entry: &ash::Entry,
    validation: bool,
    debug_utils: bool,
    extra_extensions: &[&CStr],
    messages: &Arc<MessageCounter>,
) -> Result<ash::Instance> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"dispmap")
        .application_version(1)
        .engine_name(c"dispmap")
        .api_version(requirements::API_VERSION);
    let layers = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        vec![]
    };
    let mut exts = Vec::new();
    if debug_utils {
        exts.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    for e in extra_extensions {
        if !(debug_utils && *e == ash::ext::debug_utils::NAME) {
            exts.push(e.as_ptr());
        }
    }
    let enables = [
        vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
        vk::ValidationFeatureEnableEXT::BEST_PRACTICES,
    ];
    let enables = if best_practices_from_env() {
        &enables[..]
    } else {
        &enables[..1]
    };
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(enables);
    // Messages during instance creation/destruction go to the same counter.
    let mut messenger = messenger_info(messages);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&exts);
    if debug_utils {
        info = info.push_next(&mut messenger);
    }
    if validation {
        info = info.push_next(&mut features);
    }
    // SAFETY: every pointer in `info` outlives the call; the messenger's user data points
    // into `messages`, kept alive by the context.
    unsafe { entry.create_instance(&info, None) }.map_err(|r| loader_error("vkCreateInstance", r))
}

pub(super) fn best_practices_from_env() -> bool {
    std::env::var("DISPMAP_VALIDATION_BEST_PRACTICES").is_ok_and(|v| v == "1")
}

pub(super) fn messenger_info(
    messages: &Arc<MessageCounter>,
) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                | vk::DebugUtilsMessageSeverityFlagsEXT::INFO,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(Arc::as_ptr(messages) as *mut c_void)
}

pub(super) unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes a valid callback-data pointer for the duration of the call.
    let data = unsafe { data.as_ref() };
    let text = |p: *const std::ffi::c_char| {
        // SAFETY: a non-null `p_message` / `p_message_id_name` is a NUL-terminated string
        // owned by the layer for the duration of the call.
        (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    };
    let message = data.and_then(|d| text(d.p_message)).unwrap_or_default();
    // Every message of warning or error severity counts, GENERAL ones included (a layer
    // may report a finding as GENERAL), except the loader's own notices: GENERAL alone,
    // named "Loader Message" (e.g. "inserted layer" when VK_INSTANCE_LAYERS enables
    // validation): logged only.
    let loader_notice = kind == vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
        && data.and_then(|d| text(d.p_message_id_name)).as_deref() == Some("Loader Message");
    if loader_notice {
        if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            log::warn!("[vulkan notice, not counted] {message}");
        } else {
            log::info!("[vulkan notice] {message}");
        }
        return vk::FALSE;
    }
    // SAFETY: `user` is `Arc::as_ptr` of the context's MessageCounter, alive while the
    // messenger exists (destroyed before the counter is dropped).
    let counter = unsafe { (user as *const MessageCounter).as_ref() };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        if let Some(c) = counter {
            c.errors.fetch_add(1, Ordering::SeqCst);
        }
        log::error!("[vulkan {kind:?}] {message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        if let Some(c) = counter {
            c.warnings.fetch_add(1, Ordering::SeqCst);
        }
        log::warn!("[vulkan {kind:?}] {message}");
    } else {
        log::debug!("[vulkan {kind:?}] {message}");
    }
    vk::FALSE
}

pub(super) fn device_name(instance: &ash::Instance, pd: vk::PhysicalDevice) -> String {
    // SAFETY: `pd` was enumerated from `instance`.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    props
        .device_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|_| "<unnamed>".into())
}

pub(super) fn pick_device(
    instance: &ash::Instance,
    devices: &[vk::PhysicalDevice],
    selector: Option<&str>,
) -> Result<vk::PhysicalDevice> {
    let names: Vec<String> = devices.iter().map(|&d| device_name(instance, d)).collect();
    let listing = names
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{i}: {n}"))
        .collect::<Vec<_>>()
        .join("; ");
    if let Some(sel) = selector {
        if sel.trim().is_empty() {
            return Err(Error::NoDevice(format!(
                "the device selector (--device) is empty: an empty name \
                 would match every device; give an index or a part of a name (devices: \
                 {listing})"
            )));
        }
        let chosen = match sel.parse::<usize>() {
            Ok(i) => devices.get(i).copied().ok_or_else(|| {
                Error::NoDevice(format!(
                    "device index {i} out of range (devices: {listing})"
                ))
            })?,
            Err(_) => {
                let lower = sel.to_lowercase();
                let i = names
                    .iter()
                    .position(|n| n.to_lowercase().contains(&lower))
                    .ok_or_else(|| {
                        Error::NoDevice(format!(
                            "no device name contains '{sel}' (devices: {listing})"
                        ))
                    })?;
                devices[i]
            }
        };
        Context::check_device(instance, chosen).map_err(|missing| Error::Unsupported {
            device: device_name(instance, chosen),
            what: missing,
        })?;
        return Ok(chosen);
    }
    let rank = |t: vk::PhysicalDeviceType| match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    };
    let mut reasons = Vec::new();
    let mut best: Option<(u32, vk::PhysicalDevice)> = None;
    for (&d, name) in devices.iter().zip(&names) {
        if let Err(missing) = Context::check_device(instance, d) {
            log::info!("skipping device {name}: lacks {missing}");
            reasons.push(format!("{name}: lacks {missing}"));
            continue;
        }
        if graphics_compute_family(instance, d).is_none() {
            reasons.push(format!("{name}: no graphics+compute queue"));
            continue;
        }
        // SAFETY: `d` was enumerated from `instance`.
        let t = unsafe { instance.get_physical_device_properties(d) }.device_type;
        if best.is_none_or(|(r, _)| rank(t) < r) {
            best = Some((rank(t), d));
        }
    }
    best.map(|(_, d)| d)
        .ok_or_else(|| Error::NoDevice(reasons.join("; ")))
}

pub(super) fn graphics_compute_family(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> Option<u32> {
    // SAFETY: `pd` was enumerated from `instance`.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    families
        .iter()
        .position(|f| {
            f.queue_flags
                .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
                && f.timestamp_valid_bits > 0
        })
        .map(|i| i as u32)
}

pub(super) fn device_info(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    family: u32,
) -> DeviceInfo {
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
    // SAFETY: `pd` was enumerated from `instance`; the chain outlives the call.
    unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    let props = props2.properties;
    // SAFETY: as above.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let cstr = |r: std::result::Result<&CStr, _>| {
        r.map(|s: &CStr| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    DeviceInfo {
        name: cstr(props.device_name_as_c_str()),
        device_type: format!("{:?}", props.device_type),
        driver: format!(
            "{}: {}",
            cstr(driver.driver_name_as_c_str()),
            cstr(driver.driver_info_as_c_str())
        ),
        api_version: version_string(props.api_version),
        timestamp_period_ns: props.limits.timestamp_period,
        timestamp_valid_bits: families
            .get(family as usize)
            .map(|f| f.timestamp_valid_bits)
            .unwrap_or(0),
        max_image_dimension_2d: props.limits.max_image_dimension2_d,
        max_texel_buffer_elements: props.limits.max_texel_buffer_elements,
        queue_family_index: family,
        loop_limit: (driver.driver_id == vk::DriverId::MESA_LLVMPIPE).then_some(LOOP_LIMIT),
    }
}

pub(super) fn version_string(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

/// The device-level commands dispmap records or calls, by their Vulkan names: the 1.3 core
/// ones are absent from a device of a 1.2 instance even when the device supports 1.3 (or
/// has `VK_KHR_synchronization2` / `VK_KHR_dynamic_rendering`, whose `KHR` aliases dispmap
/// does not load), and ash would panic on the first call.
pub const DEVICE_ENTRY_POINTS: &[&CStr] = &[
    c"vkCmdPipelineBarrier2",
    c"vkCmdWriteTimestamp2",
    c"vkCmdBeginRendering",
    c"vkCmdEndRendering",
    c"vkQueueSubmit2",
    c"vkCmdPushDescriptorSetKHR",
    c"vkCmdDispatchIndirect",
    c"vkCmdUpdateBuffer",
];

/// The [`DEVICE_ENTRY_POINTS`] `device` does not provide.
///
/// # Safety
/// `device` is a live device created from `instance`.
pub(super) unsafe fn missing_entry_points(
    instance: &ash::Instance,
    device: &ash::Device,
) -> Vec<String> {
    DEVICE_ENTRY_POINTS
        .iter()
        .filter(|name| {
            // SAFETY: this function's contract; the name is NUL-terminated.
            unsafe { instance.get_device_proc_addr(device.handle(), name.as_ptr()) }.is_none()
        })
        .map(|name| name.to_string_lossy().into_owned())
        .collect()
}
