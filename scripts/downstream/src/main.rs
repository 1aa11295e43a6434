//! A host outside dispmap's repository, depending on its lean core by path (no default
//! features: no file decoders; the height map is the host's texels): it must build with no
//! `.cargo/config.toml` while compiling its own G-buffer shaders with `shaderc` in its
//! `build.rs` (including `dispmap_gbuffer.glsl` and `dispmap_plane.glsl` from
//! DEP_DISPMAP_INCLUDE), then render one small frame with the validation layer on: its
//! own G-buffer draw, then dispmap's `DisplacementPass` recorded into its command buffer.
//! Exits non-zero on any validation message, any non-finite hit texel, or hits that
//! differ from dispmap's standalone `Renderer`'s (the host draws the same floor with the
//! same include, so they must be bit-identical).
//!
//! Built and run by `scripts/downstream-check.sh`.

use dispmap::abi::GBufferParams;
use dispmap::ash::vk;
use dispmap::embed::{
    DEPTH_FORMAT, DisplacementPass, FRAME_FORMAT, FrameInputs, HIT_FORMAT, PassSettings,
    RAY_FORMAT, Timestamps,
};
use dispmap::gpu::commands::read_image;
use dispmap::gpu::pipeline::{RasterDesc, frame_area, raster_pipeline, set_frame_viewport};
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Image, OneShot};
use dispmap::heightfield::Texels;
use dispmap::passes::gbuffer::GBuffer;
use dispmap::shaders::Shader;
use dispmap::{
    Context, ContextOptions, HeightField, Method, MethodParams, RenderSettings, Renderer, Scene,
};
use std::error::Error;
use std::sync::Arc;

type Result<T> = std::result::Result<T, Box<dyn Error>>;

const SIDE: u32 = 64;
const METHOD: Method = Method::Relief;

/// The host's G-buffer shaders, compiled by its build script.
const GBUFFER_VERT: Shader = Shader {
    name: "downstream gbuffer.vert",
    spirv: include_bytes!(concat!(env!("OUT_DIR"), "/gbuffer.vert.spv")),
};
const GBUFFER_FRAG: Shader = Shader {
    name: "downstream gbuffer.frag",
    spirv: include_bytes!(concat!(env!("OUT_DIR"), "/gbuffer.frag.spv")),
};

/// The host: its G-buffer pipeline and images, its hit buffer, dispmap's pass, and a
/// command buffer with a fence. One frame slot.
struct Host {
    ctx: Arc<Context>,
    extent: vk::Extent2D,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    gbuffer: GBuffer,
    hit: Image,
    pass: DisplacementPass,
    shot: OneShot,
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
        // SAFETY: a valid device and create info.
        let layout = unsafe {
            dev.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges),
                None,
            )
        }?;
        let pipeline = raster_pipeline(
            &ctx,
            &RasterDesc {
                vert: &GBUFFER_VERT,
                frag: &GBUFFER_FRAG,
                layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::GREATER,
                color_formats: &[RAY_FORMAT, FRAME_FORMAT, FRAME_FORMAT],
                depth_format: DEPTH_FORMAT,
                name: "downstream.gbuffer",
            },
        )?;
        let gbuffer = GBuffer::new(&ctx, extent)?;
        let hit = Image::new(
            &ctx,
            "downstream.hit",
            HIT_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        let pass = DisplacementPass::new(
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
        let shot = OneShot::new(&ctx, "downstream")?;
        Ok(Host {
            ctx,
            extent,
            layout,
            pipeline,
            gbuffer,
            hit,
            pass,
            shot,
        })
    }

    /// Records one frame into `cmd`: the G-buffer draw (`params`: the floor and camera),
    /// the pass's entry barriers, the pass.
    ///
    /// # Safety
    /// `cmd` is this host's command buffer, recording; no earlier frame is in flight.
    unsafe fn record_frame(
        &mut self,
        cmd: vk::CommandBuffer,
        params: &GBufferParams,
    ) -> Result<()> {
        let ctx = &*self.ctx;
        let dev = ctx.device();
        let g = &self.gbuffer;
        // SAFETY: `cmd` is recording outside a render pass; nothing else uses the images
        // (no frame in flight), so their contents may be discarded.
        unsafe {
            sync::record(
                ctx,
                cmd,
                &g.barriers(
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
        // SAFETY: `cmd` is recording; the attachments are in the layouts the barriers
        // above made; the pipeline's layout takes these push constants (GBufferParams is
        // the shaders' block) and it draws from gl_VertexIndex alone.
        unsafe {
            dev.cmd_begin_rendering(cmd, &rendering);
            set_frame_viewport(ctx, cmd, self.extent);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
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
        // The pass's entry (dispmap::embed's table): the G-buffer sampled by compute
        // shaders, the hit buffer discarded into GENERAL for its storage writes.
        let mut barriers = g.barriers(
            (Access::COLOR_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
            (Access::DEPTH_ATTACHMENT_WRITE, Access::COMPUTE_SAMPLED),
        );
        barriers.push(sync::image_barrier(
            self.hit.raw,
            self.hit.range(),
            Access::UNDEFINED,
            Access::COMPUTE_STORAGE_WRITE,
        ));
        // SAFETY: `cmd` is recording outside a render pass; the images are alive.
        unsafe { sync::record(ctx, cmd, &barriers) };
        let inputs = FrameInputs {
            frame_slot: 0,
            gbuffer: g.views(),
            hit: self.hit.view,
            shade: None,
        };
        // SAFETY: the images are in the entry layouts and accesses above; slot 0 has no
        // frame in flight; the host submits this command buffer to the context's queue.
        unsafe { self.pass.record(cmd, &inputs, Timestamps::Off) }?;
        Ok(())
    }

    /// Renders one frame and reads its hit buffer back.
    fn render(&mut self, params: &GBufferParams) -> Result<Vec<[f32; 4]>> {
        let cmd = self.shot.begin(&self.ctx)?;
        // SAFETY: the host's command buffer, just begun; `submit_and_wait` waited for
        // the previous frame.
        unsafe { self.record_frame(cmd, params) }?;
        self.shot.submit_and_wait(&self.ctx)?;
        // The pass leaves the hit buffer in GENERAL after its storage writes.
        let bytes = read_image(
            &self.ctx,
            &self.shot,
            &self.hit,
            Access::COMPUTE_STORAGE_WRITE,
        )?;
        Ok(bytes
            .chunks_exact(16)
            .map(|t| {
                std::array::from_fn(|i| f32::from_le_bytes(t[4 * i..4 * i + 4].try_into().unwrap()))
            })
            .collect())
    }

    /// Destroys the pass and the host's objects.
    fn destroy(mut self) {
        // SAFETY: `render` waited for every frame: the GPU is done with everything.
        unsafe {
            self.ctx.device().device_wait_idle().ok();
            self.pass.destroy();
            self.ctx.device().destroy_pipeline(self.pipeline, None);
            self.ctx.device().destroy_pipeline_layout(self.layout, None);
        }
        self.gbuffer.destroy(&self.ctx);
        self.hit.destroy(&self.ctx);
        self.shot.destroy(&self.ctx);
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

    let camera = scene.frame_camera(SIDE, SIDE);
    let params = scene.gbuffer_params(&camera);
    let mut host = Host::new(ctx.clone(), &field, &scene)?;
    let rendered = host.render(&params);
    host.destroy();
    let hits = rendered?;

    // The standalone renderer of the same scene: the reference.
    let reference = {
        let settings = RenderSettings {
            width: SIDE,
            height: SIDE,
            method: METHOD,
            params: MethodParams::for_method(METHOD),
            scene,
            shadows: Default::default(),
        };
        let mut renderer = Renderer::new(&ctx, &field, settings)?;
        renderer.render()?;
        renderer.read_hits()?
    };
    // Destroy the device too: the validation layer reports leaked objects there.
    let ctx = Arc::into_inner(ctx).ok_or("something still holds the context")?;
    drop(ctx);

    let non_finite = hits
        .iter()
        .filter(|t| !t.iter().all(|x| x.is_finite()))
        .count();
    let hit = hits.iter().filter(|t| t[2] >= 0.0).count();
    let differ = hits
        .iter()
        .zip(&reference)
        .filter(|(a, b)| a.map(f32::to_bits) != b.map(f32::to_bits))
        .count();
    println!(
        "downstream: {SIDE}x{SIDE} frame on {device} with the host's own G-buffer shaders: \
         {hit} of {} pixels hit, {non_finite} non-finite, {differ} differ from the \
         standalone renderer's; validation: {} errors, {} warnings",
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
        return Err(format!("{non_finite} hit texels are not finite").into());
    }
    if hit == 0 {
        return Err("no pixel hit the surface".into());
    }
    if differ > 0 {
        return Err(format!("{differ} hit texels differ from the standalone renderer's").into());
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
