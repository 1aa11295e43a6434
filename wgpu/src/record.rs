//! Recording the displacement pass into a wgpu command encoder, with the layout
//! hand-off between wgpu's usage states and the pass's layouts on both sides, and the
//! corrected depth merged into the wgpu depth texture.

use crate::images::{WgpuImage, host_view, raw_image};
use crate::{Error, Result, Vulkan};
use dispmap::ash::vk;
use dispmap::context::Context;
use dispmap::embed::{
    DepthCamera, DisplacementPass, FrameInputs, HitImages, RecordedFrame, ShadeTarget, Timestamps,
};
use dispmap::glam::{Mat4, Vec3};
use dispmap::gpu::owned::Destroy;
use dispmap::passes::depth_resolve::DepthResolvePass;
use dispmap::passes::gbuffer::GBufferViews;
use std::sync::Arc;

/// Shade the hits into the host's colour texture (the pass's `ShadeTarget`).
#[derive(Clone, Copy, Debug)]
pub struct WgpuShade<'a> {
    /// `Rgba8Unorm`, `STORAGE_BINDING`, the frame's size.
    pub color: WgpuImage<'a>,
    /// World to clip of the frame (reverse-Z).
    pub view_proj: Mat4,
    /// Eye position, world space.
    pub camera_pos: Vec3,
    /// Unit vector towards the light, world space.
    pub light_dir: Vec3,
    /// Light intensity.
    pub light_intensity: f32,
}

/// One frame's wgpu textures (the G-buffer contract of `dispmap::embed`, as wgpu
/// formats: `ray` `Rgba32Float`, `frame` `Rg32Uint`, `depth`
/// `Depth32Float`, each with `TEXTURE_BINDING`, and for a frame with a material traced
/// curved `curve` `Rg16Float`; `hit_uv` `Rg32Float` and `hit_height` `R32Float` with
/// `STORAGE_BINDING`).
#[derive(Clone, Copy, Debug)]
pub struct WgpuFrame<'a> {
    /// The frame-in-flight slot (`0..frames_in_flight`; the slot contract: the previous
    /// submission that recorded this slot has completed, see [`wait_for`]).
    pub frame_slot: u32,
    /// `uv0, P`.
    pub ray: WgpuImage<'a>,
    /// Normal, tangent, handedness, material and surface id (`dispmap_frame_pack`).
    pub frame: WgpuImage<'a>,
    /// Reverse-Z depth (0 = no geometry); with [`DepthMerge`] also `RENDER_ATTACHMENT`,
    /// and it receives the corrected depth of the displaced pixels.
    pub depth: WgpuImage<'a>,
    /// The curve of each pixel (`Rg16Float`, what `dispmap_gbuffer_curve` in
    /// `glsl/include/dispmap_gbuffer.glsl` computes; the host's G-buffer shader writes it
    /// as a third colour output): required while a material is traced curved
    /// (`DisplacementPass::set_material_curved`), `None` otherwise.
    pub curve: Option<WgpuImage<'a>>,
    /// The hit uv image the pass writes (each hit's `u`, `v`).
    pub hit_uv: WgpuImage<'a>,
    /// The hit height image the pass writes (each hit's height, -1 for none).
    pub hit_height: WgpuImage<'a>,
    /// Shade into a colour texture (`None`: the host shades from the hit images).
    pub shade: Option<WgpuShade<'a>>,
}

/// Writes the pass's corrected depth (`DisplacementPass::set_depth_output(true)`) into
/// the frame's wgpu depth texture at the displaced pixels, inside [`record`]
/// (dispmap's `DepthResolvePass`: a full-screen triangle with dynamic rendering, which
/// [`crate::WgpuDevice`] enables). Every other pixel keeps the G-buffer's depth.
pub struct DepthMerge {
    resolve: DepthResolvePass,
    ctx: Arc<Context>,
}

impl DepthMerge {
    /// Builds the pipeline on the pass's context.
    pub fn new(ctx: &Arc<Context>) -> Result<Self> {
        Ok(DepthMerge {
            resolve: DepthResolvePass::new(ctx)?,
            ctx: ctx.clone(),
        })
    }

    /// Destroys the pipeline.
    ///
    /// # Safety
    /// No submitted frame that recorded it is still executing (wait for the device).
    pub unsafe fn destroy(&mut self) {
        // SAFETY: this function's contract.
        unsafe { self.resolve.destroy(&self.ctx) };
    }
}

/// Records `pass` for `frame` into `encoder`, which must be an encoder used for nothing
/// else (wgpu 30 does not allow wgpu commands and raw commands in one encoder): the host
/// submits it after the encoder that drew the G-buffer and before the one that reads the
/// results, e.g. `queue.submit([gbuffer, dispmap, shading])`.
///
/// # The contract: wgpu usage states
///
/// wgpu tracks no state of what a raw encoder does, so the pass's encoder starts and ends
/// with every texture in the state wgpu believes it is in. Before (the host's G-buffer
/// encoder ends with `encoder.transition_resources(...)`):
///
/// | texture | wgpu state before and after | Vulkan layout (wgpu-hal) |
/// |---|---|---|
/// | `ray`, `frame` | `TextureUses::RESOURCE` | `SHADER_READ_ONLY_OPTIMAL` |
/// | `depth` | `TextureUses::RESOURCE` | `DEPTH_STENCIL_READ_ONLY_OPTIMAL` |
/// | `hit_uv`, `hit_height`, `shade.color` | `TextureUses::STORAGE_READ_WRITE` | `GENERAL` |
///
/// wgpu's own barrier into those states makes the G-buffer's writes visible to every
/// shader stage (`SHADER_READ` / `SHADER_WRITE` at vertex, fragment and compute), which
/// covers the pass's entry contract (the colour keeps the host's pixels where nothing is
/// displaced; the hit images are overwritten). Inside, this function moves `depth` from
/// `DEPTH_STENCIL_READ_ONLY_OPTIMAL` to `SHADER_READ_ONLY_OPTIMAL` for the pass (dispmap
/// samples it so), then, with `merge`, to `DEPTH_ATTACHMENT_OPTIMAL` for the merge, and
/// back to `DEPTH_STENCIL_READ_ONLY_OPTIMAL`, its writes made available to every later
/// command (`ALL_COMMANDS`). After: the same states as before, with the pass's writes of
/// `hit_uv`, `hit_height` and `color` (compute shader storage writes) and the merged depth: wgpu's next
/// barrier out of `STORAGE_READ_WRITE` or `RESOURCE` (e.g. a copy, a bind group) orders
/// them. The pass's own corrected-depth image is left in `SHADER_READ_ONLY_OPTIMAL`
/// (the next record of the slot discards it).
///
/// `camera`: the frame's camera for the corrected depth when `frame.shade` is `None`
/// (`DisplacementPass::record_with_camera`); ignored with a shade target.
///
/// Nothing is recorded when the textures are refused (errors name the texture's role):
/// an error leaves the encoder empty.
///
/// # Safety
/// * `pass` was built on the [`crate::WgpuDevice`]'s context whose device made `encoder`
///   and the textures; `encoder` has recorded nothing else and is submitted once, on that
///   device's queue, in the order the frames were recorded.
/// * The textures are in the states of the table when the encoder executes, stay alive
///   until it completed, and the slot contract holds (the previous submission that
///   recorded `frame.frame_slot` completed: [`wait_for`]).
/// * With [`Timestamps::Host`], the pool is a live timestamp pool of the device with the
///   pass's query range unused by the frame's other commands.
pub unsafe fn record(
    encoder: &mut wgpu::CommandEncoder,
    pass: &mut DisplacementPass,
    frame: &WgpuFrame<'_>,
    camera: Option<&DepthCamera>,
    merge: Option<&DepthMerge>,
    timestamps: Timestamps,
) -> Result<RecordedFrame> {
    let ray = host_view(frame.ray, "gbuffer.ray")?;
    let gbuffer = GBufferViews {
        ray,
        frame: host_view(frame.frame, "gbuffer.frame")?,
        depth: host_view(frame.depth, "gbuffer.depth")?,
        curve: frame
            .curve
            .map(|c| host_view(c, "gbuffer.curve"))
            .transpose()?,
        extent: ray.extent,
    };
    let hit = HitImages {
        uv: host_view(frame.hit_uv, "hit.uv")?,
        height: host_view(frame.hit_height, "hit.height")?,
    };
    let shade = match &frame.shade {
        Some(s) => Some(ShadeTarget {
            color: host_view(s.color, "color")?,
            view_proj: s.view_proj,
            camera_pos: s.camera_pos,
            light_dir: s.light_dir,
            light_intensity: s.light_intensity,
        }),
        None => None,
    };
    let inputs = FrameInputs {
        frame_slot: frame.frame_slot,
        gbuffer,
        hit,
        shade,
        motion: None,
    };
    if merge.is_some() {
        if !pass.depth_output() {
            return Err(Error::Texture {
                label: "gbuffer.depth".into(),
                what: "a depth merge needs the pass's corrected depth \
                       (DisplacementPass::set_depth_output(true))"
                    .into(),
            });
        }
        if !frame
            .depth
            .texture
            .usage()
            .contains(wgpu::TextureUsages::RENDER_ATTACHMENT)
        {
            return Err(Error::Texture {
                label: "gbuffer.depth".into(),
                what: "a depth merge writes it as an attachment: usage lacks RENDER_ATTACHMENT"
                    .into(),
            });
        }
    }
    let depth_image = raw_image(frame.depth.texture, "gbuffer.depth")?;
    // The corrected depth the merge reads (built by set_depth_output for every slot).
    let source = match merge {
        Some(_) => {
            let image = pass
                .hit_depth(frame.frame_slot)
                .ok_or_else(|| Error::Texture {
                    label: "gbuffer.depth".into(),
                    what: format!(
                        "the pass has no corrected depth for slot {}",
                        frame.frame_slot
                    ),
                })?;
            Some((image.raw, image.view))
        }
        None => None,
    };
    let ctx = pass.context()?.clone();
    let dev = ctx.device();
    // SAFETY: the closure records into the encoder's own open command buffer and does not
    // end it (as_hal_mut's contract); nothing else touches the encoder meanwhile.
    unsafe {
        encoder.as_hal_mut::<Vulkan, _, _>(|enc| {
            let enc = enc.ok_or_else(|| Error::NotVulkan("the command encoder".into()))?;
            let cmd = enc.raw_handle();
            let depth = |old, new, src: Side, dst: Side| {
                barrier(
                    dev,
                    cmd,
                    depth_image,
                    vk::ImageAspectFlags::DEPTH,
                    old,
                    new,
                    src,
                    dst,
                )
            };
            // wgpu's RESOURCE (depth: DEPTH_STENCIL_READ_ONLY_OPTIMAL) -> the pass's
            // sampled layout. wgpu's barrier into RESOURCE ended at the shader stages.
            depth(
                vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                (SHADER_STAGES, vk::AccessFlags2::NONE),
                (
                    vk::PipelineStageFlags2::COMPUTE_SHADER,
                    vk::AccessFlags2::SHADER_SAMPLED_READ,
                ),
            );
            let recorded = match (camera, frame.shade.is_some()) {
                (Some(c), false) => pass.record_with_camera(cmd, &inputs, c, timestamps),
                _ => pass.record(cmd, &inputs, timestamps),
            };
            let after_pass = (
                vk::PipelineStageFlags2::COMPUTE_SHADER,
                vk::AccessFlags2::NONE,
            );
            let back = (
                vk::PipelineStageFlags2::ALL_COMMANDS,
                vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE,
            );
            match (merge.zip(source), &recorded) {
                (Some((m, (source_image, source_view))), Ok(_)) => {
                    barrier(
                        dev,
                        cmd,
                        source_image,
                        vk::ImageAspectFlags::COLOR,
                        vk::ImageLayout::GENERAL,
                        vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                        (
                            vk::PipelineStageFlags2::COMPUTE_SHADER,
                            vk::AccessFlags2::SHADER_STORAGE_WRITE,
                        ),
                        (
                            vk::PipelineStageFlags2::FRAGMENT_SHADER,
                            vk::AccessFlags2::SHADER_SAMPLED_READ,
                        ),
                    );
                    let tests = vk::PipelineStageFlags2::EARLY_FRAGMENT_TESTS
                        | vk::PipelineStageFlags2::LATE_FRAGMENT_TESTS;
                    let depth_rw = vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_READ
                        | vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE;
                    depth(
                        vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                        vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
                        after_pass,
                        (tests, depth_rw),
                    );
                    m.resolve.record(
                        &ctx,
                        cmd,
                        source_view,
                        inputs.gbuffer.frame.view,
                        inputs.gbuffer.depth.view,
                        inputs.gbuffer.extent,
                    )?;
                    depth(
                        vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
                        vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
                        (tests, vk::AccessFlags2::DEPTH_STENCIL_ATTACHMENT_WRITE),
                        back,
                    );
                }
                _ => depth(
                    vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                    vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
                    after_pass,
                    back,
                ),
            }
            Ok(recorded?)
        })
    }
}

/// Waits until the submission `index` completed (the frame-slot contract before the slot
/// is recorded again, and before the pass's timestamps of that frame are read with
/// `DisplacementPass::timings` or `dispmap::embed::read_timestamps`).
pub fn wait_for(device: &wgpu::Device, index: wgpu::SubmissionIndex) -> Result<()> {
    device
        .poll(wgpu::PollType::Wait {
            submission_index: Some(index),
            timeout: None,
        })
        .map(|_| ())
        .map_err(|e| Error::Wgpu(format!("waiting for a submission: {e}")))
}

type Side = (vk::PipelineStageFlags2, vk::AccessFlags2);

/// The shader stages of wgpu-hal's barriers for `RESOURCE` and storage states.
const SHADER_STAGES: vk::PipelineStageFlags2 = vk::PipelineStageFlags2::from_raw(
    vk::PipelineStageFlags2::VERTEX_SHADER.as_raw()
        | vk::PipelineStageFlags2::FRAGMENT_SHADER.as_raw()
        | vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw(),
);

#[allow(clippy::too_many_arguments)]
/// # Safety
/// `cmd` is recording, outside a render pass; `image` belongs to its device.
unsafe fn barrier(
    dev: &dispmap::ash::Device,
    cmd: vk::CommandBuffer,
    image: vk::Image,
    aspect: vk::ImageAspectFlags,
    old: vk::ImageLayout,
    new: vk::ImageLayout,
    src: Side,
    dst: Side,
) {
    let b = [vk::ImageMemoryBarrier2::default()
        .image(image)
        .old_layout(old)
        .new_layout(new)
        .src_stage_mask(src.0)
        .src_access_mask(src.1)
        .dst_stage_mask(dst.0)
        .dst_access_mask(dst.1)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: aspect,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        })];
    // SAFETY: this function's contract; synchronization2 is enabled on the device.
    unsafe {
        dev.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&b),
        )
    };
}
