//! A wgpu application that records dispmap's displacement pass into its frames.
//!
//! Everything but the pass is wgpu: the device ([`dispmap_wgpu::WgpuDevice`]: a wgpu
//! device over a Vulkan device with the pass's extensions), the textures, the G-buffer
//! render pipeline, the render passes, the copies and the submissions. The G-buffer
//! pipeline draws dispmap's tiled plane twice, the left half of the frame as material 0
//! (the rocks map, `--method`, exact by default) and the right half as material 1 (the
//! bricks map, `--second`, relief by default), each through a scissor rectangle, with
//! dispmap's own G-buffer shaders (`glsl/gbuffer.vert` and `gbuffer.frag`:
//! `dispmap_plane.glsl` for the plane's vertices and each pixel's own centre ray,
//! `dispmap_gbuffer.glsl` to encode the material given in `GBufferParams::camera_pos.w`),
//! whose SPIR-V dispmap's build script compiles (`dispmap::shaders`), handed to wgpu raw
//! (`create_shader_module_passthrough`, `Features::PASSTHROUGH_SHADERS`): its rays, depths
//! and hits are then dispmap's bit for bit (`tests/wgpu_host.rs`). wgpu's own compiler,
//! naga 30, does not read this SPIR-V (`OpLine` among the types, then `OpCopyLogical` in
//! `gbuffer.frag`), and a port to WGSL would lose the `precise` (no contraction)
//! double-float arithmetic of the pixel rays, which WGSL cannot express.
//!
//! Per frame (two in flight): encoder 1 clears the colour texture to the sky colour,
//! draws the G-buffer and ends with `transition_resources` into the states of the
//! contract; encoder 2 is `dispmap_wgpu::record` (the pass, and the corrected depth
//! merged into the G-buffer's depth texture); encoder 3 copies the hits, the depth, the
//! colour and the normals to buffers; one `queue.submit` for the three. The pass times
//! itself (`Timestamps::Owned`), read after the slot's submission completed.
//!
//! `cargo run -p dispmap-wgpu --example wgpu_host -- --out wgpu.png [--size 256x144]
//! [--frames 4] [--method exact] [--second relief] [--no-validation]`. Headless only
//! (no window).

use anyhow::{Context as _, Result, anyhow, bail, ensure};
use dispmap::embed::{DisplacementPass, MaterialSettings, PassName, PassSettings, Timestamps};
use dispmap::heightfield::{Convention, HeightField};
use dispmap::method::{Method, MethodParams};
use dispmap::scene::Scene;
use dispmap_wgpu::{DepthMerge, DeviceOptions, WgpuDevice, WgpuFrame, WgpuImage, WgpuShade};
use std::borrow::Cow;
use std::path::PathBuf;

const ROCKS: &[u8] = include_bytes!("../../assets/heightmaps/rocks_depth.jpg");
const BRICKS: &[u8] = include_bytes!("../../assets/heightmaps/bricks_depth.jpg");
const FRAMES_IN_FLIGHT: usize = 2;
/// The sky: the colour texture's clear (the pass writes only displaced pixels).
const SKY: wgpu::Color = wgpu::Color {
    r: 0.5,
    g: 0.52,
    b: 0.55,
    a: 1.0,
};

const USAGE: &str = "usage: cargo run -p dispmap-wgpu --example wgpu_host -- [--out wgpu.png] \
                     [--size 256x144] [--frames 4] [--method exact] [--second relief] \
                     [--no-validation]";

/// What to render.
#[derive(Clone, Debug)]
pub struct Options {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames to render (at least 2: both slots are used).
    pub frames: u32,
    /// Material 0's method (the rocks, left half).
    pub method: Method,
    /// Material 1's method (the bricks, right half).
    pub second: Method,
    /// Vulkan validation (core + synchronization) and wgpu's.
    pub validation: bool,
    /// Write the last frame's colour here (PNG).
    pub out: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            width: 256,
            height: 144,
            frames: 4,
            method: Method::Exact,
            second: Method::Relief,
            validation: true,
            out: None,
        }
    }
}

/// What the run produced (the last frame).
pub struct Output {
    /// Device name.
    pub device: String,
    /// The hits: `u`, `v`, height and 0 (no iteration counts asked for).
    pub hits: Vec<[f32; 4]>,
    /// The depth texture after the merge: the corrected depth at displaced pixels.
    pub depth: Vec<f32>,
    /// The colour (RGBA8).
    pub color: Vec<u8>,
    /// Per-pass milliseconds of every frame, in frame order.
    pub timings: Vec<Vec<(PassName, f64)>>,
    /// Vulkan validation warnings and errors and wgpu errors, instance to teardown.
    pub validation_messages: u64,
}

/// The first column of material 1 (the right half).
pub fn split(width: u32) -> u32 {
    width / 2
}

/// The scene (the standalone renderer's default tiled plane).
pub fn scene() -> Scene {
    Scene::default()
}

/// The rocks map (material 0).
pub fn rocks() -> Result<HeightField> {
    Ok(HeightField::decode(
        ROCKS,
        Convention::Depth,
        "rocks_depth.jpg",
    )?)
}

/// The bricks map (material 1).
pub fn bricks() -> Result<HeightField> {
    Ok(HeightField::decode(
        BRICKS,
        Convention::Depth,
        "bricks_depth.jpg",
    )?)
}

#[allow(dead_code)]
fn main() -> Result<()> {
    let _ = env_logger::try_init();
    let mut o = Options::default();
    let mut args = std::env::args().skip(1);
    let method = |v: String| -> Result<Method> {
        Method::ALL
            .iter()
            .find(|m| m.name() == v)
            .copied()
            .ok_or_else(|| anyhow!("unknown method {v}"))
    };
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
            "--method" => o.method = method(value()?)?,
            "--second" => o.second = method(value()?)?,
            "--no-validation" => o.validation = false,
            "--help" | "-h" => {
                println!("{USAGE}");
                return Ok(());
            }
            other => bail!("unknown argument {other}\n{USAGE}"),
        }
    }
    let out = run(&o)?;
    for (i, t) in out.timings.iter().enumerate() {
        println!("frame {i}: {t:?}");
    }
    println!(
        "{} + {} on {}: {} validation messages",
        o.method.name(),
        o.second.name(),
        out.device,
        out.validation_messages
    );
    ensure!(out.validation_messages == 0, "validation reported problems");
    Ok(())
}

/// One slot's textures and read-back buffers.
struct Slot {
    ray: Target,
    frame: Target,
    depth: Target,
    hit_uv: Target,
    hit_height: Target,
    color: Target,
    readback: Vec<Readback>,
}

struct Target {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
}

impl Target {
    /// A colour attachment cleared to transparent black.
    fn cleared(&self) -> Option<wgpu::RenderPassColorAttachment<'_>> {
        Some(wgpu::RenderPassColorAttachment {
            view: &self.view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                store: wgpu::StoreOp::Store,
            },
        })
    }

    fn image(&self) -> WgpuImage<'_> {
        WgpuImage {
            texture: &self.texture,
            view: &self.view,
        }
    }
}

/// Runs the application: creates everything, renders `o.frames` frames with two in
/// flight, reads back the last one, tears down and counts the validation messages.
pub fn run(o: &Options) -> Result<Output> {
    ensure!(o.frames >= 2, "--frames must be at least 2");
    let features = wgpu::Features::IMMEDIATES | wgpu::Features::PASSTHROUGH_SHADERS;
    let gpu = WgpuDevice::new(&DeviceOptions {
        validation: o.validation,
        features,
        limits: wgpu::Limits {
            max_immediate_size: std::mem::size_of::<dispmap::abi::GBufferParams>() as u32,
            ..wgpu::Limits::default()
        },
    })?;
    let messages = gpu.messages().clone();
    let device_name = gpu.name().to_string();
    let result = frames(&gpu, o);
    drop(gpu);
    let (hits, depth, color, timings) = result?;
    if let Some(path) = &o.out {
        image::save_buffer(path, &color, o.width, o.height, image::ColorType::Rgba8)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(Output {
        device: device_name,
        hits,
        depth,
        color,
        timings,
        validation_messages: messages.total(),
    })
}

type Frames = (Vec<[f32; 4]>, Vec<f32>, Vec<u8>, Vec<Vec<(PassName, f64)>>);

fn frames(gpu: &WgpuDevice, o: &Options) -> Result<Frames> {
    let device = &gpu.device;
    let scene = scene();
    let camera = scene.frame_camera(o.width, o.height);
    let g = scene.gbuffer_params(&camera);
    // wgpu-hal draws with a flipped viewport (negative height: WebGPU's y-up clip space).
    // naga's SPIR-V writer negates `gl_Position.y` to match; raw SPIR-V does not, so the
    // shaders get the view-projection with its y row negated: each clip y is then
    // exactly the negation of dispmap's, the viewport flips it back, and pixels, coverage
    // and interpolation are dispmap's bit for bit. The fragment shader uses only the z
    // and w rows (the pixel's depth).
    let mut params = g;
    for axis in [
        &mut params.view_proj.x_axis,
        &mut params.view_proj.y_axis,
        &mut params.view_proj.z_axis,
        &mut params.view_proj.w_axis,
    ] {
        axis.y = -axis.y;
    }
    let pipeline = gbuffer_pipeline(device)?;
    let rays = camera.pixel_ray_params();
    let ray_buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("pixel rays"),
        size: std::mem::size_of_val(&rays) as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    gpu.queue
        .write_buffer(&ray_buffer, 0, bytemuck::bytes_of(&rays));
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("pixel rays"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: ray_buffer.as_entire_binding(),
        }],
    });
    let slots: Vec<Slot> = (0..FRAMES_IN_FLIGHT).map(|s| slot(device, o, s)).collect();

    let ctx = gpu.context().clone();
    let (rocks, bricks) = (rocks()?, bricks()?);
    let extent = dispmap::ash::vk::Extent2D {
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
    let mut merge = None;
    let result = (|| {
        let second = pass.add_material(
            &bricks,
            MaterialSettings {
                method: o.second,
                params: MethodParams::for_method(o.second),
                depth_scale: scene.depth_scale,
                addressing: scene.addressing(),
            },
        )?;
        ensure!(second.index() == 1, "the second material is index 1");
        pass.set_depth_output(true)?;
        merge = Some(DepthMerge::new(&ctx)?);
        let light = {
            let (e, a) = (
                scene.light.elevation_deg.to_radians(),
                scene.light.azimuth_deg.to_radians(),
            );
            dispmap::glam::Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
        };
        let mut submitted: Vec<Option<wgpu::SubmissionIndex>> = vec![None; FRAMES_IN_FLIGHT];
        let mut timings = Vec::new();
        let split = split(o.width);
        for frame in 0..o.frames {
            let s = frame as usize % FRAMES_IN_FLIGHT;
            if let Some(index) = submitted[s].take() {
                dispmap_wgpu::wait_for(device, index)?;
                timings.push(pass.timings(s as u32)?);
            }
            let slot = &slots[s];
            // 1. The host's colour and G-buffer, then the hand-off states.
            let mut draw = device.create_command_encoder(&Default::default());
            draw.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("sky"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &slot.color.view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(SKY),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
            {
                let mut rp = draw.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("gbuffer"),
                    color_attachments: &[slot.ray.cleared(), slot.frame.cleared()],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &slot.depth.view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(0.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    ..Default::default()
                });
                rp.set_pipeline(&pipeline);
                rp.set_bind_group(0, &bind_group, &[]);
                for (material, x, w) in [(0u32, 0, split), (1, split, o.width - split)] {
                    if w == 0 {
                        continue;
                    }
                    // camera_pos.w: the material index + 1 (GBufferParams).
                    let p = dispmap::abi::GBufferParams {
                        camera_pos: camera.eye.extend(material as f32 + 1.0),
                        ..params
                    };
                    rp.set_immediates(0, bytemuck::bytes_of(&p));
                    rp.set_scissor_rect(x, 0, w, o.height);
                    rp.draw(0..g.vertex_count(), 0..1);
                }
            }
            let resource =
                [&slot.ray, &slot.frame, &slot.depth].map(|t| (t, wgpu::TextureUses::RESOURCE));
            let storage = [&slot.hit_uv, &slot.hit_height, &slot.color]
                .map(|t| (t, wgpu::TextureUses::STORAGE_READ_WRITE));
            draw.transition_resources(
                std::iter::empty(),
                resource
                    .into_iter()
                    .chain(storage)
                    .map(|(t, state)| wgpu::TextureTransition {
                        texture: &t.texture,
                        selector: None,
                        state,
                    }),
            );
            // 2. The displacement pass in an encoder of its own.
            let mut displace = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("dispmap"),
            });
            let wframe = WgpuFrame {
                frame_slot: s as u32,
                ray: slot.ray.image(),
                frame: slot.frame.image(),
                depth: slot.depth.image(),
                curve: None,
                hit_uv: slot.hit_uv.image(),
                hit_height: slot.hit_height.image(),
                shade: Some(WgpuShade {
                    color: slot.color.image(),
                    view_proj: camera.view_proj,
                    camera_pos: camera.eye,
                    light_dir: light,
                    light_intensity: scene.light.intensity,
                }),
            };
            // SAFETY: the pass is the device's; `displace` records nothing else and is
            // submitted below after `draw`, whose transition_resources put the textures
            // in the contract's states; the slot's previous submission was waited for.
            unsafe {
                dispmap_wgpu::record(
                    &mut displace,
                    &mut pass,
                    &wframe,
                    None,
                    merge.as_ref(),
                    Timestamps::Owned,
                )?;
            }
            // 3. Read-back of what the pass wrote.
            let mut copy = device.create_command_encoder(&Default::default());
            let sources = [
                (&slot.hit_uv, wgpu::TextureAspect::All),
                (&slot.hit_height, wgpu::TextureAspect::All),
                (&slot.depth, wgpu::TextureAspect::DepthOnly),
                (&slot.color, wgpu::TextureAspect::All),
            ];
            for ((t, aspect), (buffer, row, _)) in sources.into_iter().zip(&slot.readback) {
                copy.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo {
                        texture: &t.texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d::ZERO,
                        aspect,
                    },
                    wgpu::TexelCopyBufferInfo {
                        buffer,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(*row),
                            rows_per_image: None,
                        },
                    },
                    t.texture.size(),
                );
            }
            submitted[s] =
                Some(
                    gpu.queue
                        .submit([draw.finish(), displace.finish(), copy.finish()]),
                );
        }
        let last = (o.frames as usize - 1) % FRAMES_IN_FLIGHT;
        for k in 1..=FRAMES_IN_FLIGHT {
            let s = (last + k) % FRAMES_IN_FLIGHT;
            if let Some(index) = submitted[s].take() {
                dispmap_wgpu::wait_for(device, index)?;
                timings.push(pass.timings(s as u32)?);
            }
        }
        let rb = &slots[last].readback;
        let uv: Vec<f32> = read(device, &rb[0], o)?;
        let height: Vec<f32> = read(device, &rb[1], o)?;
        let depth: Vec<f32> = read(device, &rb[2], o)?;
        let color: Vec<u8> = read(device, &rb[3], o)?;
        // `u`, `v`, height; the application does not ask for the iteration counts (0).
        let hits = uv
            .chunks_exact(2)
            .zip(&height)
            .map(|(c, &h)| [c[0], c[1], h, 0.0])
            .collect();
        Ok((hits, depth, color, timings))
    })();
    let _ = device.poll(wgpu::PollType::wait_indefinitely());
    // SAFETY: the device is idle: nothing recorded with the pass or the merge is pending.
    unsafe {
        pass.destroy();
        if let Some(m) = merge.as_mut() {
            m.destroy();
        }
    }
    drop((pass, merge));
    drop(ctx);
    result
}

/// The texels of one read-back buffer (`buffer`, padded row bytes, bytes a pixel), rows
/// unpadded.
fn read<T: bytemuck::Pod>(device: &wgpu::Device, rb: &Readback, o: &Options) -> Result<Vec<T>> {
    let (buffer, row, pixel) = rb;
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| {
        if let Err(e) = r {
            log::error!("map: {e}");
        }
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow!("poll: {e}"))?;
    let data = slice
        .get_mapped_range()
        .map_err(|e| anyhow!("reading back: {e}"))?;
    let used = (o.width * pixel) as usize;
    let mut bytes = Vec::with_capacity(used * o.height as usize);
    for y in 0..o.height as usize {
        let start = y * *row as usize;
        bytes.extend_from_slice(&data[start..start + used]);
    }
    drop(data);
    buffer.unmap();
    Ok(bytemuck::pod_collect_to_vec(&bytes))
}

type Readback = (wgpu::Buffer, u32, u32);

fn slot(device: &wgpu::Device, o: &Options, s: usize) -> Slot {
    let size = wgpu::Extent3d {
        width: o.width,
        height: o.height,
        depth_or_array_layers: 1,
    };
    let target = |name: &str, format, usage| {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(&format!("{name}[{s}]")),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        Target { texture, view }
    };
    use wgpu::TextureFormat as F;
    use wgpu::TextureUsages as U;
    let attachment = U::RENDER_ATTACHMENT | U::TEXTURE_BINDING;
    let readback = |name: &str, bytes_per_pixel: u32| {
        let row = (o.width * bytes_per_pixel).div_ceil(256) * 256;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{name} readback[{s}]")),
            size: u64::from(row) * u64::from(o.height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        (buffer, row, bytes_per_pixel)
    };
    Slot {
        ray: target("ray", F::Rgba32Float, attachment),
        frame: target("frame", F::Rg32Uint, attachment),
        depth: target("depth", F::Depth32Float, attachment | U::COPY_SRC),
        hit_uv: target("hit.uv", F::Rg32Float, U::STORAGE_BINDING | U::COPY_SRC),
        hit_height: target("hit.height", F::R32Float, U::STORAGE_BINDING | U::COPY_SRC),
        color: target(
            "color",
            F::Rgba8Unorm,
            U::STORAGE_BINDING | U::RENDER_ATTACHMENT | U::COPY_SRC,
        ),
        readback: vec![
            readback("hit.uv", 8),
            readback("hit.height", 4),
            readback("depth", 4),
            readback("color", 4),
        ],
    }
}

/// The G-buffer pipeline: dispmap's plane with dispmap's own G-buffer shaders.
fn gbuffer_pipeline(device: &wgpu::Device) -> Result<wgpu::RenderPipeline> {
    let module = |shader: &dispmap::shaders::Shader| -> Result<wgpu::ShaderModule> {
        let words = shader.words()?;
        // SAFETY: SPIR-V compiled by shaderc for Vulkan 1.3 from the repository's GLSL;
        // its interface (set 0 binding 0 uniform, 128 bytes of push constants, three
        // colour outputs and the depth) matches the layout below.
        Ok(unsafe {
            device.create_shader_module_passthrough(wgpu::ShaderModuleDescriptorPassthrough {
                label: Some(shader.name),
                entry_points: Cow::Owned(vec![wgpu::PassthroughShaderEntryPoint {
                    name: Cow::Borrowed("main"),
                    workgroup_size: (0, 0, 0),
                }]),
                spirv: Some(Cow::Owned(words)),
                ..Default::default()
            })
        })
    };
    let vert = module(&dispmap::shaders::GBUFFER_VERT)?;
    let frag = module(&dispmap::shaders::GBUFFER_FRAG)?;
    let set = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("pixel rays"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("gbuffer"),
        bind_group_layouts: &[Some(&set)],
        immediate_size: std::mem::size_of::<dispmap::abi::GBufferParams>() as u32,
    });
    let target = |format| {
        Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })
    };
    Ok(
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("gbuffer"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &vert,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &frag,
                entry_point: Some("main"),
                compilation_options: Default::default(),
                targets: &[
                    target(wgpu::TextureFormat::Rgba32Float),
                    target(wgpu::TextureFormat::Rg32Uint),
                ],
            }),
            multiview_mask: None,
            cache: None,
        }),
    )
}
