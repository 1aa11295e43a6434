//! A context built from handles a host engine created itself (raw ash + gpu-allocator)
//! renders the same hits as the standalone context. The engine's instance has the
//! validation layer with synchronization validation and its own debug messenger: no
//! warning or error from instance creation to instance destruction.

mod common;

use ash::vk;
use common::{asset_map, finish, validated_context};
use dispmap::context::{Context, HostHandles, requirements};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::Scene;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::c_void;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Warning and error messages the engine's messenger saw.
static ENGINE_MESSAGES: AtomicU64 = AtomicU64::new(0);

unsafe extern "system" fn engine_messenger(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    if severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
            | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
    ) {
        ENGINE_MESSAGES.fetch_add(1, Ordering::SeqCst);
        // SAFETY: the layer passes valid callback data for the duration of the call.
        if let Some(message) =
            unsafe { data.as_ref() }.and_then(|d| unsafe { d.message_as_c_str() })
        {
            eprintln!("[engine validation] {}", message.to_string_lossy());
        }
    }
    vk::FALSE
}

fn settings() -> RenderSettings {
    RenderSettings {
        shadows: Default::default(),
        width: 96,
        height: 64,
        method: Method::Relief,
        params: MethodParams::default(),
        scene: Scene::default(),
    }
}

#[test]
fn host_handles_give_the_same_hits_as_standalone() {
    let rocks = asset_map("rocks_depth.jpg", Convention::Depth);

    let standalone = validated_context();
    let expected = {
        let mut r = Renderer::new(&standalone, &rocks, settings()).unwrap();
        r.render().unwrap();
        r.read_hits().unwrap()
    };
    let chosen = standalone.info().name.clone();
    finish(standalone);

    // The "engine": its own instance, device, queue and allocator.
    // SAFETY: test code; every handle below is created and destroyed in order.
    unsafe {
        let entry = ash::Entry::load().unwrap();
        let (instance, debug_utils, messenger) = engine_instance(&entry, requirements::API_VERSION);
        let physical_device = instance
            .enumerate_physical_devices()
            .unwrap()
            .into_iter()
            .find(|&pd| {
                instance
                    .get_physical_device_properties(pd)
                    .device_name_as_c_str()
                    .is_ok_and(|n| n.to_string_lossy() == chosen)
            })
            .unwrap();
        let family = instance
            .get_physical_device_queue_family_properties(physical_device)
            .iter()
            .position(|f| {
                f.queue_flags
                    .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
            })
            .unwrap() as u32;
        let exts: Vec<_> = requirements::DEVICE_EXTENSIONS
            .iter()
            .map(|e| e.as_ptr())
            .collect();
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true);
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&[1.0])];
        let device = instance
            .create_device(
                physical_device,
                &vk::DeviceCreateInfo::default()
                    .queue_create_infos(&queues)
                    .enabled_extension_names(&exts)
                    .push_next(&mut f13),
                None,
            )
            .unwrap();
        let queue = device.get_device_queue(family, 0);
        let allocator = Arc::new(Mutex::new(
            Allocator::new(&AllocatorCreateDesc {
                instance: instance.clone(),
                device: device.clone(),
                physical_device,
                debug_settings: Default::default(),
                buffer_device_address: false,
                allocation_sizes: Default::default(),
            })
            .unwrap(),
        ));
        // The engine's own pipeline cache: dispmap creates its pipelines with it.
        let cache = device
            .create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None)
            .unwrap();
        let ctx = Arc::new(
            Context::from_handles(
                HostHandles {
                    entry: entry.clone(),
                    instance: instance.clone(),
                    physical_device,
                    device: device.clone(),
                    queue_family_index: family,
                    queue,
                    allocator: allocator.clone(),
                },
                true,
            )
            .unwrap()
            .with_pipeline_cache(cache),
        );
        assert_eq!(ctx.pipeline_cache(), cache);
        let hits = {
            let mut r = Renderer::new(&ctx, &rocks, settings()).unwrap();
            r.render().unwrap();
            r.read_hits().unwrap()
        };
        drop(ctx);
        // Every pipeline was created with the host's cache (validation checks the handle;
        // lavapipe keeps its cache data at the 32-byte header: Mesa caches on disk, so
        // the cache's contents say nothing here).
        device.destroy_pipeline_cache(cache, None);
        let bits = |h: &[[f32; 4]]| h.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&hits), bits(&expected));

        // The host tears down what it owns; dispmap destroyed none of it.
        assert!(
            Arc::try_unwrap(allocator).is_ok(),
            "dispmap kept a reference to the host's allocator"
        );
        // The host's allocator, and dispmap's objects on the host's device, are all gone
        // when the device is destroyed (the object tracker would report them).
        device.destroy_device(None);
        debug_utils.destroy_debug_utils_messenger(messenger, None);
        instance.destroy_instance(None);
        drop(entry);
        assert_eq!(
            ENGINE_MESSAGES.load(Ordering::SeqCst),
            0,
            "the engine's validation reported warnings or errors"
        );
    }
}

/// The engine's instance at `api_version`, with the validation layer (synchronization
/// validation on) and its own messenger, also over instance creation.
///
/// # Safety
/// Test code: the caller destroys the messenger, then the instance.
unsafe fn engine_instance(
    entry: &ash::Entry,
    api_version: u32,
) -> (
    ash::Instance,
    ash::ext::debug_utils::Instance,
    vk::DebugUtilsMessengerEXT,
) {
    let app = vk::ApplicationInfo::default().api_version(api_version);
    let layers = [dispmap::context::VALIDATION_LAYER.as_ptr()];
    let extensions = [ash::ext::debug_utils::NAME.as_ptr()];
    let sync = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&sync);
    let messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(engine_messenger));
    let mut creation_messenger = messenger_info;
    // SAFETY: test code; valid create infos.
    unsafe {
        let instance = entry
            .create_instance(
                &vk::InstanceCreateInfo::default()
                    .application_info(&app)
                    .enabled_layer_names(&layers)
                    .enabled_extension_names(&extensions)
                    .push_next(&mut features)
                    .push_next(&mut creation_messenger),
                None,
            )
            .unwrap();
        let debug_utils = ash::ext::debug_utils::Instance::new(entry, &instance);
        let messenger = debug_utils
            .create_debug_utils_messenger(&messenger_info, None)
            .unwrap();
        (instance, debug_utils, messenger)
    }
}

/// A Vulkan 1.2 engine (its instance asks for 1.2; the device enables
/// `VK_KHR_synchronization2`, `VK_KHR_dynamic_rendering` and `VK_KHR_push_descriptor`, with
/// their features through the KHR structs) gets `Error::Unsupported` naming the 1.3 entry
/// points dispmap calls, never a panic inside ash at the first record.
#[test]
fn a_vulkan_1_2_device_is_refused_by_name() {
    // SAFETY: test code; every handle below is created and destroyed in order.
    unsafe {
        let entry = ash::Entry::load().unwrap();
        let (instance, debug_utils, messenger) = engine_instance(&entry, vk::API_VERSION_1_2);
        let physical_device = instance.enumerate_physical_devices().unwrap()[0];
        let family = instance
            .get_physical_device_queue_family_properties(physical_device)
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
            .unwrap() as u32;
        let exts = [
            ash::khr::synchronization2::NAME.as_ptr(),
            ash::khr::dynamic_rendering::NAME.as_ptr(),
            ash::khr::push_descriptor::NAME.as_ptr(),
        ];
        let mut sync2 =
            vk::PhysicalDeviceSynchronization2FeaturesKHR::default().synchronization2(true);
        let mut rendering =
            vk::PhysicalDeviceDynamicRenderingFeaturesKHR::default().dynamic_rendering(true);
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&[1.0])];
        let device = instance
            .create_device(
                physical_device,
                &vk::DeviceCreateInfo::default()
                    .queue_create_infos(&queues)
                    .enabled_extension_names(&exts)
                    .push_next(&mut sync2)
                    .push_next(&mut rendering),
                None,
            )
            .unwrap();
        let queue = device.get_device_queue(family, 0);
        let allocator = Arc::new(Mutex::new(
            Allocator::new(&AllocatorCreateDesc {
                instance: instance.clone(),
                device: device.clone(),
                physical_device,
                debug_settings: Default::default(),
                buffer_device_address: false,
                allocation_sizes: Default::default(),
            })
            .unwrap(),
        ));
        let result = Context::from_handles(
            HostHandles {
                entry: entry.clone(),
                instance: instance.clone(),
                physical_device,
                device: device.clone(),
                queue_family_index: family,
                queue,
                allocator: allocator.clone(),
            },
            true,
        );
        let message = match result {
            Err(dispmap::Error::Unsupported { what, .. }) => what,
            Err(e) => panic!("expected Unsupported, got {e}"),
            Ok(_) => panic!("a 1.2 device was accepted"),
        };
        assert!(message.contains("vkCmdPipelineBarrier2"), "{message}");
        eprintln!("refused: {message}");
        drop(allocator);
        device.destroy_device(None);
        debug_utils.destroy_debug_utils_messenger(messenger, None);
        instance.destroy_instance(None);
        assert_eq!(
            ENGINE_MESSAGES.load(Ordering::SeqCst),
            0,
            "the engine's validation reported warnings or errors"
        );
    }
}
