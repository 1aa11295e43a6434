//! A small "host engine" that embeds dispmap's displacement pass in its own Vulkan frame.
//!
//! The engine is written against ash and gpu-allocator only: it creates its own instance
//! (with the Khronos validation layer, synchronization validation and a debug messenger
//! that counts warnings and errors), device, queue, allocator, command pool, fences,
//! G-buffer images, vertex buffer and graphics pipeline (its own shaders,
//! `glsl/examples/host_engine.{vert,frag}`, which write dispmap's G-buffer channels with
//! `glsl/include/dispmap_gbuffer.glsl`). dispmap is used for the pass
//! ([`dispmap::embed`]), for the scene's camera (so the rays equal those of the standalone
//! `dispmap render` for the comparison test) and for loading the height maps.
//!
//! The engine's SPIR-V comes from dispmap's `build.rs`, which compiles every shader under
//! `glsl/` into `$OUT_DIR` at build time; the example includes those files with
//! `include_bytes!` (shaderc is only a build dependency, so nothing compiles at run time).
//!
//! Geometry: the tiled floor (the standalone renderer's plane, same vertices and
//! triangle order, now from a vertex buffer) and a cube standing on it, each face its own
//! chart (surface ids 2..7, uv 0..1 per face, one tile per face).
//!
//! Frames: two in flight, each slot with its own G-buffer, hit buffer, colour image,
//! read-back buffers, command buffer and fence. Slot 0 times the pass into the engine's
//! own query pool, slot 1 into the pass's own pool. At frame 1 the engine swaps the
//! height map to bricks and at frame 3 back to the rocks map, so the pass re-uploads it
//! and rebuilds the pyramid while older frames are in flight.
//!
//! `cargo run --example host_engine -- --out host.png [--size 256x144] [--frames 6]
//! [--method exact] [--no-cube] [--no-validation]`

use anyhow::{Context as _, Result, anyhow, bail, ensure};
use ash::vk;
use dispmap::context::{Context, HostHandles};
use dispmap::embed::{self, DisplacementPass, FrameInputs, PassSettings, ShadeTarget, Timestamps};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::GBufferViews;
use dispmap::scene::Scene;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{
    Allocation, AllocationCreateDesc, AllocationScheme, Allocator, AllocatorCreateDesc,
};
use std::ffi::{CStr, c_void};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

const VERT_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/examples__host_engine.vert.spv"));
const FRAG_SPV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/examples__host_engine.frag.spv"));
const ROCKS: &[u8] = include_bytes!("../assets/heightmaps/rocks_depth.jpg");
const BRICKS: &[u8] = include_bytes!("../assets/heightmaps/bricks_depth.jpg");

const FRAMES_IN_FLIGHT: usize = 2;
const FLOOR_ID: f32 = 1.0;
/// Floats per vertex: position 3, uv 2, normal + surface id 4, tangent 3, bitangent 3.
const VERTEX_FLOATS: usize = 15;

/// What to render.
#[derive(Clone, Debug)]
pub struct Options {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames to render (at least 4: the height-map swaps happen in frames 1 and 3).
    pub frames: u32,
    /// The method.
    pub method: Method,
    /// Draw the cube next to the floor.
    pub cube: bool,
    /// Enable the validation layer (core + synchronization validation).
    pub validation: bool,
    /// Write the last frame's colour here.
    pub out: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            width: 256,
            height: 144,
            frames: 6,
            method: Method::Exact,
            cube: true,
            validation: true,
            out: None,
        }
    }
}

/// What the run produced.
pub struct Output {
    /// Device name.
    pub device: String,
    /// The last frame's hit buffer.
    pub hits: Vec<[f32; 4]>,
    /// The last frame's surface ids (G-buffer `normal.w`; 0: nothing drawn).
    pub surface_ids: Vec<f32>,
    /// The last frame's colour (RGBA8).
    pub color: Vec<u8>,
    /// Per-pass milliseconds of each completed frame, in frame order.
    pub timings: Vec<Vec<(&'static str, f64)>>,
    /// Validation warnings + errors over the whole run (instance creation to destruction).
    pub validation_messages: u64,
    /// Whether the validation layer was on.
    pub validated: bool,
    /// Allocations left in the engine's allocator after everything was destroyed.
    pub leaked_allocations: usize,
}

impl Output {
    /// Whether the floor was drawn at pixel `i` (not the cube, not the sky).
    pub fn is_floor(&self, i: usize) -> bool {
        self.surface_ids[i] == FLOOR_ID
    }
}

/// The scene the engine draws (the standalone renderer's default tiled plane).
pub fn scene() -> Scene {
    Scene::default()
}

/// The rocks map the final frames use.
pub fn rocks() -> Result<HeightField> {
    Ok(HeightField::decode(
        ROCKS,
        Convention::Depth,
        "rocks_depth.jpg",
    )?)
}

#[allow(dead_code)]
fn main() -> Result<()> {
    let _ = env_logger::try_init();
    let mut o = Options::default();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or_else(|| anyhow!("{a} needs a value"));
        match a.as_str() {
            "--out" => o.out = Some(value()?.into()),
            "--size" => {
                let v = value()?;
                let (w, h) = v.split_once('x').ok_or_else(|| anyhow!("--size WxH"))?;
                (o.width, o.height) = (w.parse()?, h.parse()?);
            }
            "--frames" => o.frames = value()?.parse()?,
            "--method" => {
                let v = value()?;
                o.method = *Method::ALL
                    .iter()
                    .find(|m| m.name() == v)
                    .ok_or_else(|| anyhow!("unknown method {v}"))?;
            }
            "--no-cube" => o.cube = false,
            "--no-validation" => o.validation = false,
            other => bail!("unknown argument {other} (see the example's docs)"),
        }
    }
    let out = run(&o)?;
    for (i, t) in out.timings.iter().enumerate() {
        println!("frame {i}: {t:?}");
    }
    println!(
        "{} on {}: {} validation messages, {} leaked allocations",
        o.method.name(),
        out.device,
        out.validation_messages,
        out.leaked_allocations
    );
    ensure!(out.validation_messages == 0, "validation reported problems");
    Ok(())
}

/// Counts validation warnings and errors.
#[derive(Default)]
struct Messages {
    count: AtomicU64,
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the duration of the call, with a
    // NUL-terminated message.
    let text = unsafe {
        data.as_ref()
            .filter(|d| !d.p_message.is_null())
            .map(|d| CStr::from_ptr(d.p_message).to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    if severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
            | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
    ) {
        // SAFETY: `user` points to the engine's `Messages`, alive until the instance
        // (and with it the messenger) is destroyed.
        if let Some(m) = unsafe { (user as *const Messages).as_ref() } {
            m.count.fetch_add(1, Ordering::SeqCst);
        }
        eprintln!("[host engine validation] {text}");
    }
    vk::FALSE
}

/// An image, its view and its memory.
struct EngineImage {
    image: vk::Image,
    view: vk::ImageView,
    allocation: Option<Allocation>,
    aspect: vk::ImageAspectFlags,
}

/// A buffer and its memory.
struct EngineBuffer {
    buffer: vk::Buffer,
    allocation: Option<Allocation>,
}

/// The per-slot resources.
struct Slot {
    ray: EngineImage,
    normal: EngineImage,
    tangent: EngineImage,
    depth: EngineImage,
    hit: EngineImage,
    color: EngineImage,
    hit_readback: EngineBuffer,
    normal_readback: EngineBuffer,
    color_readback: EngineBuffer,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    submitted: bool,
    /// Host-pool timestamps of the frame in flight (slot 0 only).
    host_scopes: Vec<embed::TimestampScope>,
}

/// Everything the engine created, destroyed in reverse order by [`Engine::destroy`].
struct Engine {
    entry: ash::Entry,
    instance: ash::Instance,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    physical_device: vk::PhysicalDevice,
    device: ash::Device,
    family: u32,
    queue: vk::Queue,
    allocator: Option<Arc<Mutex<Allocator>>>,
    debug_utils: Option<ash::ext::debug_utils::Device>,
    pool: vk::CommandPool,
    query_pool: vk::QueryPool,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    vertices: Option<EngineBuffer>,
    vertex_count: u32,
    slots: Vec<Slot>,
}

/// Runs the engine: creates everything, renders `o.frames` frames with two in flight,
/// reads back the last one, destroys everything and reports.
pub fn run(o: &Options) -> Result<Output> {
    ensure!(o.frames >= 4, "--frames must be at least 4");
    let messages = Box::new(Messages::default());
    // SAFETY: every Vulkan object below is created from the ones before it and destroyed
    // in reverse order (`Engine::destroy`), after the GPU is idle; the messenger's user
    // data (`messages`) outlives the instance.
    unsafe {
        let mut engine = Engine::create(o, &messages)?;
        let result = engine.render(o);
        let leaked = engine.destroy();
        let mut out = result?;
        out.leaked_allocations = leaked?;
        out.validation_messages = messages.count.load(Ordering::SeqCst);
        out.validated = o.validation;
        Ok(out)
    }
}

impl Engine {
    /// # Safety
    /// `messages` must outlive the engine's instance.
    unsafe fn create(o: &Options, messages: &Messages) -> Result<Engine> {
        // SAFETY: loading the system loader; the caller's contract covers the rest.
        unsafe {
            let entry = ash::Entry::load()?;
            let reqs = embed::requirements();
            let app = vk::ApplicationInfo::default()
                .application_name(c"host_engine")
                .api_version(reqs.api_version);
            let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
            let exts = [ash::ext::debug_utils::NAME.as_ptr()];
            let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
            let mut features =
                vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
            let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
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
                .user_data(messages as *const Messages as *mut c_void);
            let mut info = vk::InstanceCreateInfo::default()
                .application_info(&app)
                .enabled_extension_names(&exts)
                .push_next(&mut messenger_info);
            if o.validation {
                info = info.enabled_layer_names(&layers).push_next(&mut features);
            }
            let instance = entry
                .create_instance(&info, None)
                .context("vkCreateInstance (is vulkan-validationlayers installed?)")?;
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let handle = du.create_debug_utils_messenger(&messenger_info, None)?;
            let messenger = Some((du, handle));

            // The device: the best one that dispmap supports (discrete, integrated, CPU).
            let mut candidates = Vec::new();
            for pd in instance.enumerate_physical_devices()? {
                let props = instance.get_physical_device_properties(pd);
                let name = props
                    .device_name_as_c_str()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                if let Err(e) = embed::check_physical_device(&instance, pd) {
                    eprintln!("host engine: skipping {name}: {e}");
                    continue;
                }
                let family = instance
                    .get_physical_device_queue_family_properties(pd)
                    .iter()
                    .position(|f| {
                        f.queue_flags
                            .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
                            && f.timestamp_valid_bits > 0
                    });
                let rank = match props.device_type {
                    vk::PhysicalDeviceType::DISCRETE_GPU => 0,
                    vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
                    vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
                    vk::PhysicalDeviceType::CPU => 3,
                    _ => 4,
                };
                if let Some(f) = family {
                    candidates.push((rank, pd, f as u32));
                }
            }
            candidates.sort_by_key(|c| c.0);
            let Some(&(_, physical_device, family)) = candidates.first() else {
                instance.destroy_instance(None);
                bail!("no Vulkan device supports the displacement pass");
            };
            let dev_exts: Vec<_> = reqs.device_extensions.iter().map(|e| e.as_ptr()).collect();
            // The engine's own G-buffer pass uses dynamic rendering; the pass adds what it
            // needs (synchronization2).
            let mut f13 = reqs.enable_vulkan13(
                vk::PhysicalDeviceVulkan13Features::default().dynamic_rendering(true),
            );
            let queues = [vk::DeviceQueueCreateInfo::default()
                .queue_family_index(family)
                .queue_priorities(&[1.0])];
            let device_info = vk::DeviceCreateInfo::default()
                .queue_create_infos(&queues)
                .enabled_extension_names(&dev_exts)
                .push_next(&mut f13);
            embed::check_device_create_info(&device_info)?;
            let device = instance.create_device(physical_device, &device_info, None)?;
            let queue = device.get_device_queue(family, 0);
            let allocator = Allocator::new(&AllocatorCreateDesc {
                instance: instance.clone(),
                device: device.clone(),
                physical_device,
                debug_settings: Default::default(),
                buffer_device_address: false,
                allocation_sizes: Default::default(),
            })?;
            let debug_utils = Some(ash::ext::debug_utils::Device::new(&instance, &device));
            let mut engine = Engine {
                entry,
                instance,
                messenger,
                physical_device,
                device,
                family,
                queue,
                allocator: Some(Arc::new(Mutex::new(allocator))),
                debug_utils,
                pool: vk::CommandPool::null(),
                query_pool: vk::QueryPool::null(),
                layout: vk::PipelineLayout::null(),
                pipeline: vk::Pipeline::null(),
                vertices: None,
                vertex_count: 0,
                slots: Vec::new(),
            };
            if let Err(e) = engine.create_resources(o) {
                let _ = engine.destroy();
                return Err(e);
            }
            Ok(engine)
        }
    }

    fn name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_utils {
            let name = std::ffi::CString::new(name).unwrap_or_default();
            let info = vk::DebugUtilsObjectNameInfoEXT::default()
                .object_handle(handle)
                .object_name(&name);
            // SAFETY: the handle belongs to the engine's device.
            let _ = unsafe { du.set_debug_utils_object_name(&info) };
        }
    }

    fn allocator(&self) -> std::sync::MutexGuard<'_, Allocator> {
        self.allocator
            .as_ref()
            .expect("allocator alive")
            .lock()
            .expect("allocator lock")
    }

    /// # Safety
    /// The device is alive.
    unsafe fn image(
        &self,
        name: &str,
        format: vk::Format,
        extent: vk::Extent2D,
        usage: vk::ImageUsageFlags,
    ) -> Result<EngineImage> {
        let aspect = if format == embed::DEPTH_FORMAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        };
        // SAFETY: valid device and create infos; memory from the engine's allocator.
        unsafe {
            let image = self.device.create_image(
                &vk::ImageCreateInfo::default()
                    .image_type(vk::ImageType::TYPE_2D)
                    .format(format)
                    .extent(vk::Extent3D {
                        width: extent.width,
                        height: extent.height,
                        depth: 1,
                    })
                    .mip_levels(1)
                    .array_layers(1)
                    .samples(vk::SampleCountFlags::TYPE_1)
                    .tiling(vk::ImageTiling::OPTIMAL)
                    .usage(usage),
                None,
            )?;
            let requirements = self.device.get_image_memory_requirements(image);
            let allocation = self.allocator().allocate(&AllocationCreateDesc {
                name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })?;
            self.device
                .bind_image_memory(image, allocation.memory(), allocation.offset())?;
            let view = self.device.create_image_view(
                &vk::ImageViewCreateInfo::default()
                    .image(image)
                    .view_type(vk::ImageViewType::TYPE_2D)
                    .format(format)
                    .subresource_range(range(aspect)),
                None,
            )?;
            self.name(image, name);
            self.name(view, &format!("{name}.view"));
            Ok(EngineImage {
                image,
                view,
                allocation: Some(allocation),
                aspect,
            })
        }
    }

    /// # Safety
    /// The device is alive.
    unsafe fn buffer(
        &self,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<EngineBuffer> {
        // SAFETY: valid device and create info; memory from the engine's allocator.
        unsafe {
            let buffer = self.device.create_buffer(
                &vk::BufferCreateInfo::default().size(size).usage(usage),
                None,
            )?;
            let requirements = self.device.get_buffer_memory_requirements(buffer);
            let allocation = self.allocator().allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })?;
            self.device
                .bind_buffer_memory(buffer, allocation.memory(), allocation.offset())?;
            self.name(buffer, name);
            Ok(EngineBuffer {
                buffer,
                allocation: Some(allocation),
            })
        }
    }

    /// # Safety
    /// The device is alive; called once from `create`.
    unsafe fn create_resources(&mut self, o: &Options) -> Result<()> {
        // SAFETY: valid device and create infos throughout.
        unsafe {
            let dev = self.device.clone();
            self.pool = dev.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(self.family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )?;
            self.name(self.pool, "engine.command_pool");
            self.query_pool = dev.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(embed::MAX_QUERIES),
                None,
            )?;
            self.name(self.query_pool, "engine.timestamps");

            // Pipeline: the engine's own shaders, vertex buffer, dynamic rendering.
            let module = |bytes: &[u8], name: &str| -> Result<vk::ShaderModule> {
                let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes))?;
                let m = dev.create_shader_module(
                    &vk::ShaderModuleCreateInfo::default().code(&words),
                    None,
                )?;
                self.name(m, name);
                Ok(m)
            };
            let vert = module(VERT_SPV, "engine.gbuffer.vert")?;
            let frag = module(FRAG_SPV, "engine.gbuffer.frag")?;
            let ranges = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)
                .size(std::mem::size_of::<EngineParams>() as u32)];
            self.layout = dev.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges),
                None,
            )?;
            self.name(self.layout, "engine.gbuffer.layout");
            let stages = [
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(vk::ShaderStageFlags::VERTEX)
                    .module(vert)
                    .name(c"main"),
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(vk::ShaderStageFlags::FRAGMENT)
                    .module(frag)
                    .name(c"main"),
            ];
            let bindings = [vk::VertexInputBindingDescription::default()
                .binding(0)
                .stride((VERTEX_FLOATS * 4) as u32)
                .input_rate(vk::VertexInputRate::VERTEX)];
            let attribute = |location: u32, format: vk::Format, float_offset: u32| {
                vk::VertexInputAttributeDescription::default()
                    .location(location)
                    .binding(0)
                    .format(format)
                    .offset(float_offset * 4)
            };
            let attributes = [
                attribute(0, vk::Format::R32G32B32_SFLOAT, 0),
                attribute(1, vk::Format::R32G32_SFLOAT, 3),
                attribute(2, vk::Format::R32G32B32A32_SFLOAT, 5),
                attribute(3, vk::Format::R32G32B32_SFLOAT, 9),
                attribute(4, vk::Format::R32G32B32_SFLOAT, 12),
            ];
            let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
                .vertex_binding_descriptions(&bindings)
                .vertex_attribute_descriptions(&attributes);
            let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
                .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
            let viewport = vk::PipelineViewportStateCreateInfo::default()
                .viewport_count(1)
                .scissor_count(1);
            let raster = vk::PipelineRasterizationStateCreateInfo::default()
                .polygon_mode(vk::PolygonMode::FILL)
                .cull_mode(vk::CullModeFlags::NONE)
                .line_width(1.0);
            let multisample = vk::PipelineMultisampleStateCreateInfo::default()
                .rasterization_samples(vk::SampleCountFlags::TYPE_1);
            let depth = vk::PipelineDepthStencilStateCreateInfo::default()
                .depth_test_enable(true)
                .depth_write_enable(true)
                .depth_compare_op(vk::CompareOp::GREATER);
            let blend_attachments = [vk::PipelineColorBlendAttachmentState::default()
                .color_write_mask(vk::ColorComponentFlags::RGBA);
                3];
            let blend =
                vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
            let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
            let dynamic =
                vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
            let color_formats = [embed::RAY_FORMAT, embed::FRAME_FORMAT, embed::FRAME_FORMAT];
            let mut rendering = vk::PipelineRenderingCreateInfo::default()
                .color_attachment_formats(&color_formats)
                .depth_attachment_format(embed::DEPTH_FORMAT);
            let info = [vk::GraphicsPipelineCreateInfo::default()
                .stages(&stages)
                .vertex_input_state(&vertex_input)
                .input_assembly_state(&input_assembly)
                .viewport_state(&viewport)
                .rasterization_state(&raster)
                .multisample_state(&multisample)
                .depth_stencil_state(&depth)
                .color_blend_state(&blend)
                .dynamic_state(&dynamic)
                .layout(self.layout)
                .push_next(&mut rendering)];
            let pipelines = dev.create_graphics_pipelines(vk::PipelineCache::null(), &info, None);
            dev.destroy_shader_module(vert, None);
            dev.destroy_shader_module(frag, None);
            self.pipeline = pipelines.map_err(|(_, e)| e)?[0];
            self.name(self.pipeline, "engine.gbuffer.pipeline");

            // Geometry.
            let vertices = geometry(o);
            self.vertex_count = (vertices.len() / VERTEX_FLOATS) as u32;
            let bytes: &[u8] = bytemuck::cast_slice(&vertices);
            let mut vb = self.buffer(
                "engine.vertices",
                bytes.len() as u64,
                vk::BufferUsageFlags::VERTEX_BUFFER,
                MemoryLocation::CpuToGpu,
            )?;
            vb.allocation
                .as_mut()
                .and_then(|a| a.mapped_slice_mut())
                .ok_or_else(|| anyhow!("vertex buffer not mapped"))?[..bytes.len()]
                .copy_from_slice(bytes);
            self.vertices = Some(vb);

            // Per-slot resources.
            let extent = vk::Extent2D {
                width: o.width,
                height: o.height,
            };
            let cmds = dev.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(self.pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(FRAMES_IN_FLIGHT as u32),
            )?;
            let attachment = vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC;
            let storage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
            let pixels = (o.width * o.height) as u64;
            for (s, &cmd) in cmds.iter().enumerate() {
                let n = |what: &str| format!("engine.slot{s}.{what}");
                self.name(cmd, &n("cmd"));
                let fence = dev.create_fence(&vk::FenceCreateInfo::default(), None)?;
                self.name(fence, &n("fence"));
                let readback = |what: &str, bytes: u64| {
                    self.buffer(
                        &n(what),
                        bytes,
                        vk::BufferUsageFlags::TRANSFER_DST,
                        MemoryLocation::GpuToCpu,
                    )
                };
                let slot = Slot {
                    ray: self.image(&n("gbuffer.ray"), embed::RAY_FORMAT, extent, attachment)?,
                    normal: self.image(
                        &n("gbuffer.normal"),
                        embed::FRAME_FORMAT,
                        extent,
                        attachment,
                    )?,
                    tangent: self.image(
                        &n("gbuffer.tangent"),
                        embed::FRAME_FORMAT,
                        extent,
                        attachment,
                    )?,
                    depth: self.image(
                        &n("gbuffer.depth"),
                        embed::DEPTH_FORMAT,
                        extent,
                        vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                            | vk::ImageUsageFlags::SAMPLED,
                    )?,
                    hit: self.image(&n("hits"), embed::HIT_FORMAT, extent, storage)?,
                    color: self.image(&n("color"), embed::COLOR_FORMAT, extent, storage)?,
                    hit_readback: readback("hits.readback", pixels * 16)?,
                    normal_readback: readback("normal.readback", pixels * 8)?,
                    color_readback: readback("color.readback", pixels * 4)?,
                    cmd,
                    fence,
                    submitted: false,
                    host_scopes: Vec::new(),
                };
                self.slots.push(slot);
            }
            Ok(())
        }
    }

    /// # Safety
    /// Called once, after `create`.
    unsafe fn render(&mut self, o: &Options) -> Result<Output> {
        let allocator = self.allocator.clone().expect("allocator alive");
        // SAFETY: the handles are the engine's own, valid and created from one another;
        // they outlive the context (dropped below, before `destroy`).
        let ctx = Arc::new(unsafe {
            Context::from_handles(
                HostHandles {
                    entry: self.entry.clone(),
                    instance: self.instance.clone(),
                    physical_device: self.physical_device,
                    device: self.device.clone(),
                    queue_family_index: self.family,
                    queue: self.queue,
                    allocator,
                },
                true,
            )?
        });
        let device_name = ctx.info().name.clone();
        let rocks = rocks()?;
        let bricks = HeightField::decode(BRICKS, Convention::Depth, "bricks_depth.jpg")?;
        let scene = scene();
        let extent = vk::Extent2D {
            width: o.width,
            height: o.height,
        };
        let mut pass = DisplacementPass::new(
            ctx.clone(),
            &rocks,
            PassSettings {
                method: o.method,
                params: MethodParams::for_method(o.method),
                depth_scale: scene.depth_scale,
                addressing: scene.addressing(),
                extent,
                frames_in_flight: FRAMES_IN_FLIGHT as u32,
            },
        )?;
        // SAFETY: frames are recorded, submitted and waited for below; the pass is
        // destroyed after the device is idle, also on an error path.
        let result = unsafe { self.frames(o, &mut pass, &rocks, &bricks) };
        // SAFETY: the device is idle (waited for in `frames` or here on error).
        unsafe {
            let _ = self.device.device_wait_idle();
            pass.destroy();
        }
        drop(pass);
        ensure!(
            Arc::strong_count(&ctx) == 1,
            "the context is still shared after destroy"
        );
        drop(ctx);
        let (hits, surface_ids, color, timings) = result?;
        Ok(Output {
            device: device_name,
            hits,
            surface_ids,
            color,
            timings,
            validation_messages: 0,
            validated: o.validation,
            leaked_allocations: 0,
        })
    }

    /// The frame loop. Returns the last frame's hits, surface ids and colour, and the
    /// timings of every frame.
    ///
    /// # Safety
    /// `pass` was built on the engine's device.
    #[allow(clippy::type_complexity)]
    unsafe fn frames(
        &mut self,
        o: &Options,
        pass: &mut DisplacementPass,
        rocks: &HeightField,
        bricks: &HeightField,
    ) -> Result<(
        Vec<[f32; 4]>,
        Vec<f32>,
        Vec<u8>,
        Vec<Vec<(&'static str, f64)>>,
    )> {
        let scene = scene();
        let camera = scene.frame_camera(o.width, o.height);
        let g = scene.gbuffer_params(&camera);
        let params = EngineParams {
            view_proj: camera.view_proj.to_cols_array(),
            camera_pos: camera.eye.extend(1.0).to_array(),
            depth_scale: g.depth_scale,
            min_cos: g.min_cos,
            addressing: g.addressing,
            pad: 0,
        };
        let light = {
            let (e, a) = (
                scene.light.elevation_deg.to_radians(),
                scene.light.azimuth_deg.to_radians(),
            );
            glam::Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
        };
        let extent = vk::Extent2D {
            width: o.width,
            height: o.height,
        };
        let mut timings = Vec::new();
        let mut last_slot = 0;
        for frame in 0..o.frames {
            let s = frame as usize % FRAMES_IN_FLIGHT;
            last_slot = s;
            // SAFETY: the fence and buffers belong to the engine; the slot's previous
            // frame is waited for before its resources are reused (the slot contract).
            unsafe {
                let slot = &mut self.slots[s];
                if slot.submitted {
                    self.device.wait_for_fences(&[slot.fence], true, u64::MAX)?;
                    self.device.reset_fences(&[slot.fence])?;
                    slot.submitted = false;
                    timings.push(if s == 0 {
                        embed::read_timestamps(pass.context(), &slot.host_scopes)?
                    } else {
                        pass.timings(s as u32)?
                    });
                }
            }
            // Height-map changes while the previous frame is still in flight.
            if frame == 1 {
                pass.set_height_map(bricks)?;
            } else if frame == 3 {
                pass.set_height_map(rocks)?;
            }
            let slot = &self.slots[s];
            let cmd = slot.cmd;
            let dev = &self.device;
            // SAFETY: `cmd` is the slot's, not pending (waited above).
            unsafe {
                dev.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
                dev.begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )?;
            }
            // The engine's G-buffer pass.
            let discard_to = |img: &EngineImage, stage, access, layout| {
                barrier(
                    img,
                    (
                        vk::PipelineStageFlags2::COPY | vk::PipelineStageFlags2::COMPUTE_SHADER,
                        vk::AccessFlags2::NONE,
                        vk::ImageLayout::UNDEFINED,
                    ),
                    (stage, access, layout),
                )
            };
            let color_write = (
                vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags2::COLOR_ATTACHMENT_WRITE,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
            );
            let depth_write = (
                vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                    | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS,
                vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                    | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE,
                vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
            );
            let sampled = (
                vk::PipelineStageFlags2::COMPUTE_SHADER,
                vk::AccessFlags2::SHADER_SAMPLED_READ,
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            );
            let storage_write = (
                vk::PipelineStageFlags2::COMPUTE_SHADER,
                vk::AccessFlags2::SHADER_STORAGE_WRITE,
                vk::ImageLayout::GENERAL,
            );
            let colors = [&slot.ray, &slot.normal, &slot.tangent];
            let mut before: Vec<_> = colors
                .iter()
                .map(|i| discard_to(i, color_write.0, color_write.1, color_write.2))
                .collect();
            before.push(discard_to(
                &slot.depth,
                depth_write.0,
                depth_write.1,
                depth_write.2,
            ));
            let attachments: Vec<_> = colors
                .iter()
                .map(|i| {
                    vk::RenderingAttachmentInfo::default()
                        .image_view(i.view)
                        .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                        .load_op(vk::AttachmentLoadOp::CLEAR)
                        .store_op(vk::AttachmentStoreOp::STORE)
                        .clear_value(vk::ClearValue {
                            color: vk::ClearColorValue { float32: [0.0; 4] },
                        })
                })
                .collect();
            let depth_attachment = vk::RenderingAttachmentInfo::default()
                .image_view(slot.depth.view)
                .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(vk::ClearValue {
                    depth_stencil: vk::ClearDepthStencilValue {
                        depth: 0.0,
                        stencil: 0,
                    },
                });
            let area = vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent,
            };
            // SAFETY: `cmd` is recording; every image is the slot's and alive.
            unsafe {
                pipeline_barrier(dev, cmd, &before);
                dev.cmd_begin_rendering(
                    cmd,
                    &vk::RenderingInfo::default()
                        .render_area(area)
                        .layer_count(1)
                        .color_attachments(&attachments)
                        .depth_attachment(&depth_attachment),
                );
                dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
                dev.cmd_set_viewport(
                    cmd,
                    0,
                    &[vk::Viewport {
                        x: 0.0,
                        y: 0.0,
                        width: o.width as f32,
                        height: o.height as f32,
                        min_depth: 0.0,
                        max_depth: 1.0,
                    }],
                );
                dev.cmd_set_scissor(cmd, 0, &[area]);
                dev.cmd_push_constants(
                    cmd,
                    self.layout,
                    vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                    0,
                    bytemuck::bytes_of(&params),
                );
                let vb = self.vertices.as_ref().expect("vertex buffer").buffer;
                dev.cmd_bind_vertex_buffers(cmd, 0, &[vb], &[0]);
                dev.cmd_draw(cmd, self.vertex_count, 1, 0, 0);
                dev.cmd_end_rendering(cmd);
            }
            // Entry barriers of the displacement pass (its documented contract).
            let mut entry: Vec<_> = colors
                .iter()
                .map(|i| barrier(i, color_write, sampled))
                .collect();
            entry.push(barrier(&slot.depth, depth_write, sampled));
            entry.push(discard_to(
                &slot.hit,
                storage_write.0,
                storage_write.1,
                storage_write.2,
            ));
            entry.push(discard_to(
                &slot.color,
                storage_write.0,
                storage_write.1,
                storage_write.2,
            ));
            // SAFETY: as above.
            unsafe { pipeline_barrier(dev, cmd, &entry) };
            let timestamps = if s == 0 {
                Timestamps::Host {
                    pool: self.query_pool,
                    first_query: 0,
                }
            } else {
                Timestamps::Owned
            };
            let inputs = FrameInputs {
                frame_slot: s as u32,
                gbuffer: GBufferViews {
                    ray: slot.ray.view,
                    normal: slot.normal.view,
                    tangent: slot.tangent.view,
                    depth: slot.depth.view,
                    extent,
                },
                hit: slot.hit.view,
                shade: Some(ShadeTarget {
                    color: slot.color.view,
                    view_proj: camera.view_proj,
                    camera_pos: camera.eye,
                    light_dir: light,
                    light_intensity: scene.light.intensity,
                }),
            };
            // SAFETY: `cmd` is recording outside a render pass, for the context's queue
            // family; the views are the slot's, in the entry states set above; the slot's
            // previous frame completed; the host pool has MAX_QUERIES queries.
            let recorded = unsafe { pass.record(cmd, &inputs, timestamps)? };
            // Read-back copies of the hits, the surface ids and the colour.
            let copy_src = (
                vk::PipelineStageFlags2::COPY,
                vk::AccessFlags2::TRANSFER_READ,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            );
            let after = [
                barrier(
                    &slot.hit,
                    (
                        vk::PipelineStageFlags2::COMPUTE_SHADER,
                        vk::AccessFlags2::SHADER_STORAGE_WRITE
                            | vk::AccessFlags2::SHADER_STORAGE_READ,
                        vk::ImageLayout::GENERAL,
                    ),
                    copy_src,
                ),
                barrier(&slot.color, storage_write, copy_src),
                barrier(&slot.normal, sampled, copy_src),
            ];
            // SAFETY: `cmd` is recording; images and buffers are the slot's.
            unsafe {
                pipeline_barrier(dev, cmd, &after);
                for (img, buf) in [
                    (&slot.hit, &slot.hit_readback),
                    (&slot.color, &slot.color_readback),
                    (&slot.normal, &slot.normal_readback),
                ] {
                    let region = vk::BufferImageCopy::default()
                        .image_subresource(vk::ImageSubresourceLayers {
                            aspect_mask: img.aspect,
                            mip_level: 0,
                            base_array_layer: 0,
                            layer_count: 1,
                        })
                        .image_extent(vk::Extent3D {
                            width: o.width,
                            height: o.height,
                            depth: 1,
                        });
                    dev.cmd_copy_image_to_buffer(
                        cmd,
                        img.image,
                        vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                        buf.buffer,
                        &[region],
                    );
                }
                let to_host = [vk::MemoryBarrier2::default()
                    .src_stage_mask(vk::PipelineStageFlags2::COPY)
                    .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                    .dst_stage_mask(vk::PipelineStageFlags2::HOST)
                    .dst_access_mask(vk::AccessFlags2::HOST_READ)];
                dev.cmd_pipeline_barrier2(
                    cmd,
                    &vk::DependencyInfo::default().memory_barriers(&to_host),
                );
                dev.end_command_buffer(cmd)?;
                let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
                let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
                dev.queue_submit2(self.queue, &submit, slot.fence)?;
            }
            let slot = &mut self.slots[s];
            slot.submitted = true;
            slot.host_scopes = if s == 0 {
                recorded.timestamps
            } else {
                Vec::new()
            };
        }
        // Drain both slots (oldest first) and read the last frame back.
        for k in 1..=FRAMES_IN_FLIGHT {
            let s = (last_slot + k) % FRAMES_IN_FLIGHT;
            let slot = &mut self.slots[s];
            if slot.submitted {
                // SAFETY: the fence belongs to the engine and was submitted.
                unsafe {
                    self.device.wait_for_fences(&[slot.fence], true, u64::MAX)?;
                    self.device.reset_fences(&[slot.fence])?;
                    slot.submitted = false;
                    timings.push(if s == 0 {
                        embed::read_timestamps(pass.context(), &slot.host_scopes)?
                    } else {
                        pass.timings(s as u32)?
                    });
                }
            }
        }
        let slot = &self.slots[last_slot];
        let read = |b: &EngineBuffer| -> Result<Vec<u8>> {
            Ok(b.allocation
                .as_ref()
                .and_then(|a| a.mapped_slice())
                .ok_or_else(|| anyhow!("read-back buffer not mapped"))?
                .to_vec())
        };
        let pixels = (o.width * o.height) as usize;
        let hits: Vec<[f32; 4]> =
            bytemuck::cast_slice(&read(&slot.hit_readback)?[..pixels * 16]).to_vec();
        let normal = read(&slot.normal_readback)?;
        let surface_ids = normal[..pixels * 8]
            .chunks_exact(8)
            .map(|t| f16_to_f32(u16::from_le_bytes([t[6], t[7]])))
            .collect();
        let color = read(&slot.color_readback)?[..pixels * 4].to_vec();
        if let Some(path) = &o.out {
            image::save_buffer(
                path,
                &color,
                o.width,
                o.height,
                image::ExtendedColorType::Rgba8,
            )
            .with_context(|| format!("writing {}", path.display()))?;
        }
        Ok((hits, surface_ids, color, timings))
    }

    /// Destroys everything the engine created; returns the allocations the allocator
    /// still held once every engine resource was freed (the leak check).
    ///
    /// # Safety
    /// Every object of the engine is idle or was never used.
    unsafe fn destroy(&mut self) -> Result<usize> {
        // SAFETY: the caller's contract; each object is destroyed once, children first.
        unsafe {
            let dev = self.device.clone();
            let _ = dev.device_wait_idle();
            let free_image = |e: &mut Engine, mut img: EngineImage| {
                dev.destroy_image_view(img.view, None);
                dev.destroy_image(img.image, None);
                if let Some(a) = img.allocation.take() {
                    let _ = e.allocator().free(a);
                }
            };
            let free_buffer = |e: &mut Engine, mut buf: EngineBuffer| {
                dev.destroy_buffer(buf.buffer, None);
                if let Some(a) = buf.allocation.take() {
                    let _ = e.allocator().free(a);
                }
            };
            for slot in std::mem::take(&mut self.slots) {
                dev.destroy_fence(slot.fence, None);
                for img in [
                    slot.ray,
                    slot.normal,
                    slot.tangent,
                    slot.depth,
                    slot.hit,
                    slot.color,
                ] {
                    free_image(self, img);
                }
                for buf in [slot.hit_readback, slot.normal_readback, slot.color_readback] {
                    free_buffer(self, buf);
                }
            }
            if let Some(vb) = self.vertices.take() {
                free_buffer(self, vb);
            }
            dev.destroy_pipeline(self.pipeline, None);
            dev.destroy_pipeline_layout(self.layout, None);
            dev.destroy_query_pool(self.query_pool, None);
            dev.destroy_command_pool(self.pool, None);
            // The leak check: everything the pass and the engine allocated is freed.
            let leaked = self.allocator().generate_report().allocations.len();
            let allocator = self.allocator.take().expect("allocator alive");
            let allocator = Arc::try_unwrap(allocator)
                .map_err(|_| anyhow!("the allocator is still shared (dispmap kept a reference)"));
            drop(allocator);
            // The object tracker reports every object still alive here as an error.
            dev.destroy_device(None);
            if let Some((du, handle)) = self.messenger.take() {
                du.destroy_debug_utils_messenger(handle, None);
            }
            self.instance.destroy_instance(None);
            Ok(leaked)
        }
    }
}

/// Push constants of the engine's G-buffer shaders.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct EngineParams {
    view_proj: [f32; 16],
    camera_pos: [f32; 4],
    depth_scale: f32,
    min_cos: f32,
    addressing: u32,
    pad: u32,
}

type Side = (vk::PipelineStageFlags2, vk::AccessFlags2, vk::ImageLayout);

fn range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

fn barrier(img: &EngineImage, before: Side, after: Side) -> vk::ImageMemoryBarrier2<'static> {
    vk::ImageMemoryBarrier2::default()
        .image(img.image)
        .subresource_range(range(img.aspect))
        .src_stage_mask(before.0)
        .src_access_mask(before.1)
        .old_layout(before.2)
        .dst_stage_mask(after.0)
        .dst_access_mask(after.1)
        .new_layout(after.2)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
}

/// # Safety
/// `cmd` is recording and the images are alive.
unsafe fn pipeline_barrier(
    dev: &ash::Device,
    cmd: vk::CommandBuffer,
    b: &[vk::ImageMemoryBarrier2],
) {
    // SAFETY: the caller's contract.
    unsafe {
        dev.cmd_pipeline_barrier2(cmd, &vk::DependencyInfo::default().image_memory_barriers(b))
    };
}

fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let frac = (h & 0x3ff) as f32;
    sign * match exp {
        0 => frac * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    }
}

/// The floor (the standalone renderer's plane: same corners, same triangle order) and,
/// with `o.cube`, a cube standing on it.
fn geometry(o: &Options) -> Vec<f32> {
    let scene = scene();
    let camera = scene.frame_camera(o.width, o.height);
    let g = scene.gbuffer_params(&camera);
    let (w, uv) = (g.world_rect, g.uv_rect);
    let mut v = Vec::new();
    let corners = [(0, 0), (1, 0), (1, 1), (0, 0), (1, 1), (0, 1)];
    for (sx, sz) in corners {
        let pick = |a: f32, b: f32, s: i32| if s == 0 { a } else { b };
        v.extend_from_slice(&[
            pick(w.x, w.z, sx),
            0.0,
            pick(w.y, w.w, sz),
            pick(uv.x, uv.z, sx),
            pick(uv.y, uv.w, sz),
            0.0,
            1.0,
            0.0,
            FLOOR_ID,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ]);
    }
    if o.cube {
        let centre = glam::Vec3::new(0.06, 0.05, -0.06);
        let half = 0.05f32;
        let side = 2.0 * half;
        let faces = [
            (glam::Vec3::X, glam::Vec3::NEG_Z),
            (glam::Vec3::NEG_X, glam::Vec3::Z),
            (glam::Vec3::Y, glam::Vec3::X),
            (glam::Vec3::NEG_Y, glam::Vec3::X),
            (glam::Vec3::Z, glam::Vec3::X),
            (glam::Vec3::NEG_Z, glam::Vec3::NEG_X),
        ];
        for (i, (n, t)) in faces.into_iter().enumerate() {
            let b = n.cross(t);
            let id = 2.0 + i as f32;
            let corner = |su: f32, sv: f32| centre + half * n + half * (su * t + sv * b);
            for (su, sv) in [
                (-1.0, -1.0),
                (1.0, -1.0),
                (1.0, 1.0),
                (-1.0, -1.0),
                (1.0, 1.0),
                (-1.0, 1.0),
            ] {
                let p = corner(su, sv);
                // One tile per face: uv 0..1 along T and B.
                let (u, vv) = ((su + 1.0) * 0.5 * side / side, (sv + 1.0) * 0.5);
                v.extend_from_slice(&[
                    p.x, p.y, p.z, u, vv, n.x, n.y, n.z, id, t.x, t.y, t.z, b.x, b.y, b.z,
                ]);
            }
        }
    }
    v
}
