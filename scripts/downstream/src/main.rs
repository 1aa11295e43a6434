//! A host outside dispmap's repository, depending on its lean core by path (no default
//! features: no file decoders; the height map is the host's texels): it must build with no
//! `.cargo/config.toml` while compiling its own G-buffer shaders with `shaderc` in its
//! `build.rs` (including `dispmap_gbuffer.glsl` and `dispmap_plane.glsl` from
//! DEP_DISPMAP_INCLUDE), then render one small frame with the validation layer on: its
//! own G-buffer draw, then dispmap's `DisplacementPass` recorded into its command buffer.
//! The pass runs with the corrected depth and the motion vectors on, over two frames of a
//! camera turning by 1.7 degrees: the host merges the depth into its own depth attachment
//! with `DepthResolvePass`, and the pass writes the displaced pixels' motion into the
//! host's `R16G16_SFLOAT` motion image (source `Camera`: the host's world is static; it
//! clears the image, having no sky pass of its own). Exits non-zero on any validation
//! message, any non-finite output, hits or corrected depths that differ from dispmap's
//! standalone `Renderer`'s (the host draws the same floor with the same include, so they
//! must be bit-identical), motion more than 0.01 px (plus the half float's rounding) from
//! the renderer's, or a merged depth attachment that differs from the corrected depth
//! (which holds the G-buffer's own depth where nothing is displaced).
//!
//! Built and run by `scripts/downstream-check.sh`.

use dispmap::abi::{GBufferParams, PixelRayParams};
use dispmap::ash::vk;
use dispmap::embed::{
    DEPTH_FORMAT, DepthCamera, DisplacementPass, FRAME_FORMAT, FrameInputs, FrameMotion,
    HIT_HEIGHT_FORMAT, HIT_UV_FORMAT, HitImages, MotionSettings, MotionSource, PassSettings,
    RAY_FORMAT, Timestamps,
};
use dispmap::gpu::commands::read_image;
use dispmap::gpu::pipeline::{RasterDesc, frame_area, raster_pipeline, set_frame_viewport};
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::{Image, OneShot};
use dispmap::heightfield::Texels;
use dispmap::passes::depth_resolve::DepthResolvePass;
use dispmap::passes::gbuffer::GBuffer;
use dispmap::passes::pixel_ray_buffer::PixelRayBuffer;
use dispmap::shaders::Shader;
use dispmap::{
    Context, ContextOptions, HeightField, Method, MethodParams, RenderSettings, Renderer, Scene,
};
use std::error::Error;
use std::sync::Arc;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

const SIDE: u32 = 64;
const METHOD: Method = Method::Relief;
/// The camera's turn between the two frames (degrees of azimuth).
const TURN_DEG: f32 = 1.7;
/// The host's motion image.
const MOTION_FORMAT: vk::Format = vk::Format::R16G16_SFLOAT;

/// The host's G-buffer shaders, compiled by its build script.
const GBUFFER_VERT: Shader = Shader {
    name: "downstream gbuffer.vert",
    spirv: include_bytes!(concat!(env!("OUT_DIR"), "/gbuffer.vert.spv")),
    // A raster stage: dispmap builds no descriptor layout from it (the host's own).
    bindings: &[],
};
const GBUFFER_FRAG: Shader = Shader {
    name: "downstream gbuffer.frag",
    spirv: include_bytes!(concat!(env!("OUT_DIR"), "/gbuffer.frag.spv")),
    bindings: &[],
};

/// The host: its G-buffer pipeline and images, its hit images, dispmap's pass, and a
/// command buffer with a fence. One frame slot.
struct Host {
    ctx: Arc<Context>,
    extent: vk::Extent2D,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    pipeline: vk::Pipeline,
    /// The floor's pixel rays (dispmap's buffer, written in the command buffer).
    rays: PixelRayBuffer,
    gbuffer: GBuffer,
    /// The hit uv and hit height images.
    hit: [Image; 2],
    motion: Image,
    pass: DisplacementPass,
    resolve: DepthResolvePass,
    shot: OneShot,
}

/// What one frame leaves: hits, corrected depth, merged depth attachment, motion.
struct Frame {
    hits: Vec<[f32; 4]>,
    corrected: Vec<f32>,
    merged: Vec<f32>,
    motion: Vec<[f32; 2]>,
}

/// Little-endian texels of `n` channels of 4 bytes.
fn f32s<const N: usize>(bytes: &[u8]) -> Vec<[f32; N]> {
    bytes
        .chunks_exact(4 * N)
        .map(|t| {
            std::array::from_fn(|i| f32::from_le_bytes(t[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

impl Host {
    fn new(ctx: Arc<Context>, field: &HeightField, scene: &Scene) -> Result<Host> {
        let extent = vk::Extent2D {
            width: SIDE,
            height: SIDE,
        };
        let dev = ctx.device();
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)
            .size(size_of::<GBufferParams>() as u32)];
        // Set 0, binding 0: the pixel rays of the frame (a push descriptor).
        let bindings = [vk::DescriptorSetLayoutBinding::default()
            .binding(0)
            .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
            .descriptor_count(1)
            .stage_flags(vk::ShaderStageFlags::FRAGMENT)];
        // SAFETY: a valid device and create info; dispmap's context enables
        // VK_KHR_push_descriptor.
        let set_layout = unsafe {
            dev.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default()
                    .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
                    .bindings(&bindings),
                None,
            )
        }?;
        let set_layouts = [set_layout];
        // SAFETY: a valid device and create info.
        let layout = unsafe {
            dev.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&ranges),
                None,
            )
        }?;
        let rays = PixelRayBuffer::new(&ctx, "downstream.pixel_rays")?;
        let pipeline = raster_pipeline(
            &ctx,
            &RasterDesc {
                vert: &GBUFFER_VERT,
                frag: &GBUFFER_FRAG,
                layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::GREATER,
                color_formats: &[RAY_FORMAT, FRAME_FORMAT],
                depth_format: DEPTH_FORMAT,
                name: "downstream.gbuffer",
            },
        )?;
        let gbuffer = GBuffer::new(&ctx, extent)?;
        let hit_image = |name: &str, format| {
            Image::new(
                &ctx,
                name,
                format,
                extent,
                1,
                vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
            )
        };
        let hit = [
            hit_image("downstream.hit.uv", HIT_UV_FORMAT)?,
            hit_image("downstream.hit.height", HIT_HEIGHT_FORMAT)?,
        ];
        let motion = Image::new(
            &ctx,
            "downstream.motion",
            MOTION_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        )?;
        let mut pass = DisplacementPass::new(
            ctx.clone(),
            field,
            PassSettings {
                method: METHOD,
                params: MethodParams::for_method(METHOD),
                depth_scale: scene.depth_scale,
                addressing: scene.addressing(),
                extent,
                frames_in_flight: 1,
            },
        )?;
        pass.set_depth_output(true)?;
        // The pass's own iteration counts, to compare every channel of the standalone
        // renderer's hits (which always have them).
        pass.set_iterations_output(true)?;
        pass.set_motion_output(Some(MotionSettings {
            format: MOTION_FORMAT,
            source: MotionSource::Camera,
            ..MotionSettings::default()
        }))?;
        let resolve = DepthResolvePass::new(&ctx)?;
        let shot = OneShot::new(&ctx, "downstream")?;
        Ok(Host {
            ctx,
            extent,
            layout,
            set_layout,
            pipeline,
            rays,
            gbuffer,
            hit,
            motion,
            pass,
            resolve,
            shot,
        })
    }

    /// Records one frame into `cmd`: the G-buffer draw (`params`: the floor and camera),
    /// the motion image cleared, the pass's entry barriers, the pass (with `camera` and
    /// the `previous` frame's), the corrected depth merged into the G-buffer's depth.
    ///
    /// # Safety
    /// `cmd` is this host's command buffer, recording; no earlier frame is in flight.
    unsafe fn record_frame(
        &mut self,
        cmd: vk::CommandBuffer,
        params: &GBufferParams,
        rays: &PixelRayParams,
        camera: DepthCamera,
        previous: DepthCamera,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let dev = ctx.device();
        let g = &self.gbuffer;
        // SAFETY: `cmd` is recording outside a render pass; the buffer lives as long as
        // the host.
        unsafe { self.rays.record_update(ctx, cmd, rays)? };
        // SAFETY: `cmd` is recording outside a render pass; nothing else uses the images
        // (no frame in flight), so their contents may be discarded.
        unsafe {
            sync::record(
                ctx,
                cmd,
                &gbuffer_barriers(
                    g,
                    (Access::UNDEFINED, Access::COLOR_ATTACHMENT_WRITE),
                    (Access::UNDEFINED, Access::DEPTH_ATTACHMENT_WRITE),
                ),
            )
        };
        let clear = |image: &Image, value: vk::ClearValue| {
            vk::RenderingAttachmentInfo::default()
                .image_view(image.view)
                .image_layout(if image.format == DEPTH_FORMAT {
                    vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL
                } else {
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL
                })
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(value)
        };
        let zero = vk::ClearValue {
            color: vk::ClearColorValue { float32: [0.0; 4] },
        };
        let colors = g.colors().map(|image| clear(image, zero));
        // Reverse-Z: cleared to 0, which the G-buffer contract reads as no geometry.
        let depth = clear(
            &g.depth,
            vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 0.0,
                    stencil: 0,
                },
            },
        );
        let rendering = vk::RenderingInfo::default()
            .render_area(frame_area(self.extent))
            .layer_count(1)
            .color_attachments(&colors)
            .depth_attachment(&depth);
        let ray_info = self.rays.info();
        let writes = [vk::WriteDescriptorSet::default()
            .dst_binding(0)
            .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
            .buffer_info(&ray_info)];
        // SAFETY: `cmd` is recording; the attachments are in the layouts the barriers
        // above made; the pipeline's layout takes these push constants (GBufferParams is
        // the shaders' block) and this push descriptor (set 0: the pixel rays' uniform
        // buffer, alive) and it draws from gl_VertexIndex alone.
        unsafe {
            dev.cmd_begin_rendering(cmd, &rendering);
            set_frame_viewport(ctx, cmd, self.extent);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            ctx.push_descriptor().cmd_push_descriptor_set(
                cmd,
                vk::PipelineBindPoint::GRAPHICS,
                self.layout,
                0,
                &writes,
            );
            dev.cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                0,
                bytemuck::bytes_of(params),
            );
            dev.cmd_draw(cmd, params.vertex_count(), 1, 0, 0);
            dev.cmd_end_rendering(cmd);
        }
        // The host's motion of its static world is the pass's job where it displaces;
        // the host has no sky pass, so the rest of the image is cleared.
        let clear_write = Access {
            stage: vk::PipelineStageFlags2::CLEAR,
            access: vk::AccessFlags2::TRANSFER_WRITE,
            layout: vk::ImageLayout::GENERAL,
        };
        // SAFETY: `cmd` is recording outside a render pass; no frame is in flight, so the
        // motion image may be discarded; it has TRANSFER_DST usage.
        unsafe {
            sync::transition(ctx, cmd, &self.motion, Access::UNDEFINED, clear_write);
            dev.cmd_clear_color_image(
                cmd,
                self.motion.raw,
                vk::ImageLayout::GENERAL,
                &vk::ClearColorValue { float32: [0.0; 4] },
                &[self.motion.range()],
            );
        }
        // The pass's entry (dispmap::embed's table): the G-buffer sampled by compute
        // shaders, the hit images discarded into GENERAL for their storage writes, the
        // motion image's clear visible to the pass's storage reads and writes.
        let mut barriers = gbuffer_barriers(
            g,
            (Access::COLOR_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
            (Access::DEPTH_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
        );
        for hit in &self.hit {
            barriers.push(sync::image_barrier(
                hit.raw,
                hit.range(),
                Access::UNDEFINED,
                Access::COMPUTE_STORAGE_WRITE,
            ));
        }
        barriers.push(sync::image_barrier(
            self.motion.raw,
            self.motion.range(),
            clear_write,
            Access::COMPUTE_STORAGE_READ_WRITE,
        ));
        // SAFETY: `cmd` is recording outside a render pass; the images are alive.
        unsafe { sync::record(ctx, cmd, &barriers) };
        let inputs = FrameInputs {
            frame_slot: 0,
            gbuffer: g.views(),
            hit: HitImages {
                uv: self.hit[0].host_view(),
                height: self.hit[1].host_view(),
            },
            shade: None,
            motion: Some(FrameMotion {
                image: self.motion.host_view(),
                previous,
            }),
        };
        // SAFETY: the images are in the entry layouts and accesses above; slot 0 has no
        // frame in flight; the host submits this command buffer to the context's queue.
        unsafe {
            self.pass
                .record_with_camera(cmd, &inputs, &camera, Timestamps::Off)
        }?;
        // The corrected depth into the host's depth attachment (dispmap::embed's
        // "Corrected depth"): the pass's image and the frame read by the resolve's
        // fragment shader, the G-buffer depth (read by the pass) as its attachment.
        let depth = self.pass.hit_depth(0).ok_or("the corrected depth is on")?;
        let fragment_sampled = Access {
            stage: vk::PipelineStageFlags2::FRAGMENT_SHADER,
            ..Access::COMPUTE_SAMPLED
        };
        let to_resolve = [
            sync::image_barrier(
                depth.raw,
                depth.range(),
                Access::COMPUTE_STORAGE_WRITE,
                fragment_sampled,
            ),
            sync::image_barrier(
                g.frame.raw,
                g.frame.range(),
                Access::COMPUTE_SAMPLED,
                fragment_sampled,
            ),
            sync::image_barrier(
                g.depth.raw,
                g.depth.range(),
                Access::COMPUTE_SAMPLED,
                Access::DEPTH_ATTACHMENT_WRITE,
            ),
        ];
        // SAFETY: `cmd` is recording outside a render pass; the barriers put the three
        // images in the states `DepthResolvePass::record` needs; all live until the frame
        // completes (`render` waits).
        unsafe {
            sync::record(ctx, cmd, &to_resolve);
            self.resolve.record(
                ctx,
                cmd,
                depth.view,
                g.frame.view,
                g.depth.view,
                self.extent,
            )?;
        }
        Ok(())
    }

    /// Renders one frame and reads back its hits, corrected and merged depth and motion.
    fn render(
        &mut self,
        params: &GBufferParams,
        rays: &PixelRayParams,
        camera: DepthCamera,
        previous: DepthCamera,
    ) -> Result<Frame> {
        let cmd = self.shot.begin(&self.ctx)?;
        // SAFETY: the host's command buffer, just begun; `submit_and_wait` waited for
        // the previous frame.
        unsafe { self.record_frame(cmd, params, rays, camera, previous) }?;
        self.shot.submit_and_wait(&self.ctx)?;
        let (ctx, shot) = (&self.ctx, &self.shot);
        // The pass leaves the hit images, its iteration counts and the motion in GENERAL
        // after its storage writes; the corrected depth was last sampled by the resolve;
        // the merged depth last written as the resolve's attachment.
        let [uv, height] = &self.hit;
        let iterations = self.pass.iterations(0).ok_or("the iteration counts are on")?;
        let read = |image| read_image(ctx, shot, image, Access::COMPUTE_STORAGE_WRITE);
        let hits = dispmap::passes::trace::join_hits(
            &read(uv)?,
            &read(height)?,
            Some(&read(iterations)?),
        );
        let depth = self.pass.hit_depth(0).ok_or("the corrected depth is on")?;
        let fragment_sampled = Access {
            stage: vk::PipelineStageFlags2::FRAGMENT_SHADER,
            ..Access::COMPUTE_SAMPLED
        };
        let corrected = f32s::<1>(&read_image(ctx, shot, depth, fragment_sampled)?);
        let merged = f32s::<1>(&read_image(
            ctx,
            shot,
            &self.gbuffer.depth,
            Access::DEPTH_ATTACHMENT_WRITE,
        )?);
        let halves = read_image(ctx, shot, &self.motion, Access::COMPUTE_STORAGE_WRITE)?;
        let motion = halves
            .chunks_exact(4)
            .map(|t| {
                std::array::from_fn(|i| half::f16::from_le_bytes([t[2 * i], t[2 * i + 1]]).to_f32())
            })
            .collect();
        Ok(Frame {
            hits,
            corrected: corrected.into_iter().map(|[d]| d).collect(),
            merged: merged.into_iter().map(|[d]| d).collect(),
            motion,
        })
    }

    /// Destroys the pass and the host's objects.
    fn destroy(mut self) {
        // SAFETY: `render` waited for every frame: the GPU is done with everything.
        unsafe {
            self.ctx.device().device_wait_idle().ok();
            self.pass.destroy();
            self.resolve.destroy(&self.ctx);
            self.ctx.device().destroy_pipeline(self.pipeline, None);
            self.ctx.device().destroy_pipeline_layout(self.layout, None);
            self.ctx
                .device()
                .destroy_descriptor_set_layout(self.set_layout, None);
            self.rays.destroy(&self.ctx);
            self.gbuffer.destroy(&self.ctx);
            for hit in &mut self.hit {
                hit.destroy(&self.ctx);
            }
            self.motion.destroy(&self.ctx);
            self.shot.destroy(&self.ctx);
        }
    }
}

fn main() -> Result<()> {
    // The host's own texels (16-bit heights, as an engine that loads its textures
    // itself hands them over): dispmap is built without its file decoders.
    let heights: Vec<u16> = (0..SIDE * SIDE)
        .map(|k| {
            let (u, v) = (
                (k % SIDE) as f32 / SIDE as f32,
                (k / SIDE) as f32 / SIDE as f32,
            );
            let tau = std::f32::consts::TAU;
            let h = 0.5 + 0.25 * (3.0 * tau * u).sin() * (2.0 * tau * v).cos();
            (h * 65535.0).round() as u16
        })
        .collect();
    let field = HeightField::from_texels(SIDE, SIDE, Texels::R16(heights), "downstream bumps")?;
    let scene = Scene::default();

    // A validated headless context (the device: DISPMAP_DEVICE, else the best one;
    // lavapipe on CI).
    let ctx = Arc::new(Context::headless(&ContextOptions {
        validation: Some(true),
        device: None,
    })?);
    if !ctx.has_messenger() {
        return Err("no debug messenger: validation messages would go unseen".into());
    }
    let device = ctx.info().name.clone();
    let messages = ctx.messages().clone();

    // Two frames: the camera turns between them (the second frame's motion is checked).
    let turned = Scene {
        camera: dispmap::scene::Camera {
            azimuth_deg: scene.camera.azimuth_deg + TURN_DEG,
            ..scene.camera
        },
        ..scene
    };
    let depth_camera = |s: &Scene| {
        let c = s.frame_camera(SIDE, SIDE);
        DepthCamera {
            view_proj: c.view_proj,
            eye: c.eye,
        }
    };
    let (first, second) = (depth_camera(&scene), depth_camera(&turned));
    let mut host = Host::new(ctx.clone(), &field, &scene)?;
    let (first_frame, second_frame) = (
        scene.frame_camera(SIDE, SIDE),
        turned.frame_camera(SIDE, SIDE),
    );
    let rendered = host
        .render(
            &scene.gbuffer_params(&first_frame),
            &first_frame.pixel_ray_params(),
            first,
            first,
        )
        .and_then(|_| {
            host.render(
                &turned.gbuffer_params(&second_frame),
                &second_frame.pixel_ray_params(),
                second,
                first,
            )
        });
    host.destroy();
    let frame = rendered?;

    // The standalone renderer of the same two frames: the reference.
    let (reference, ref_depth, ref_motion) = {
        let settings = RenderSettings {
            width: SIDE,
            height: SIDE,
            method: METHOD,
            params: MethodParams::for_method(METHOD),
            scene,
            shadows: Default::default(),
        };
        let mut renderer = Renderer::new(&ctx, &field, settings)?;
        renderer.set_depth_output(true)?;
        renderer.set_motion_output(true)?;
        renderer.render()?;
        renderer.set_scene(turned)?;
        renderer.render()?;
        (
            renderer.read_hits()?,
            renderer.read_depth()?.ok_or("the renderer's depth is on")?,
            renderer
                .read_motion()?
                .ok_or("the renderer's motion is on")?,
        )
    };
    // Destroy the device too: the validation layer reports leaked objects there.
    let ctx = Arc::into_inner(ctx).ok_or("something still holds the context")?;
    drop(ctx);

    let hits = &frame.hits;
    let non_finite = hits
        .iter()
        .flatten()
        .chain(&frame.corrected)
        .chain(&frame.merged)
        .chain(frame.motion.iter().flatten())
        .filter(|x| !x.is_finite())
        .count();
    let displaced: Vec<usize> = (0..hits.len()).filter(|&i| hits[i][2] >= 0.0).collect();
    let differ = hits
        .iter()
        .zip(&reference)
        .filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits))
        .count();
    let depth_differ = frame
        .corrected
        .iter()
        .zip(&ref_depth)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    // The corrected depth holds the G-buffer's own depth where nothing is displaced, so
    // the merged attachment must equal it everywhere.
    let merged_wrong = frame
        .merged
        .iter()
        .zip(&frame.corrected)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    let motion_error = displaced
        .iter()
        .map(|&i| {
            let (m, r) = (frame.motion[i], ref_motion[i]);
            let error = ((m[0] - r[0]).powi(2) + (m[1] - r[1]).powi(2)).sqrt();
            // The half float's rounding of the host's image.
            error - (r[0].abs() + r[1].abs()) / 1024.0
        })
        .fold(0.0f32, f32::max);
    let moved = displaced
        .iter()
        .filter(|&&i| ref_motion[i][0].abs() + ref_motion[i][1].abs() > 0.1)
        .count();
    println!(
        "downstream: {SIDE}x{SIDE} frames on {device} with the host's own G-buffer shaders \
         and depth and motion on: {} of {} pixels hit, {non_finite} non-finite, {differ} \
         hits and {depth_differ} corrected depths differ from the standalone renderer's, \
         {merged_wrong} merged depths differ from the corrected depth, motion within \
         {motion_error:.5} px (beyond the half float's rounding) of the renderer's ({moved} \
         pixels moved by more than 0.1 px); validation: {} errors, {} warnings",
        displaced.len(),
        hits.len(),
        messages.errors(),
        messages.warnings()
    );
    if hits.len() != (SIDE * SIDE) as usize || reference.len() != hits.len() {
        return Err(format!(
            "{} hit texels ({} from the renderer), expected {}",
            hits.len(),
            reference.len(),
            SIDE * SIDE
        )
        .into());
    }
    if non_finite > 0 {
        return Err(format!("{non_finite} output texels are not finite").into());
    }
    if displaced.is_empty() || moved == 0 {
        return Err("no pixel hit the surface, or nothing moved".into());
    }
    if differ > 0 || depth_differ > 0 {
        return Err(format!(
            "{differ} hits and {depth_differ} corrected depths differ from the standalone \
             renderer's"
        )
        .into());
    }
    if merged_wrong > 0 {
        return Err(format!("{merged_wrong} merged depths are not the corrected depth").into());
    }
    if motion_error > 0.01 {
        return Err(format!("motion {motion_error} px from the renderer's").into());
    }
    if messages.errors() > 0 || messages.warnings() > 0 {
        // dispmap logs each message through the `log` crate; this crate installs no
        // logger, so only the counts are known here.
        return Err(
            "validation reported errors or warnings: reproduce in the checkout \
                    with a logger (e.g. RUST_LOG=warn cargo test) to read them"
                .into(),
        );
    }
    Ok(())
}

/// One barrier per G-buffer image: the colour attachments from `color.0` to `color.1`, the
/// depth from `depth.0` to `depth.1` (this host's own barriers, with dispmap's helpers).
fn gbuffer_barriers(
    g: &GBuffer,
    color: (Access, Access),
    depth: (Access, Access),
) -> Vec<vk::ImageMemoryBarrier2<'static>> {
    let mut b: Vec<_> = g
        .colors()
        .iter()
        .map(|i| sync::image_barrier(i.raw, i.range(), color.0, color.1))
        .collect();
    b.push(sync::image_barrier(
        g.depth.raw,
        g.depth.range(),
        depth.0,
        depth.1,
    ));
    b
}
