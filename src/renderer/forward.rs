//! The renderer's forward frame: what engines do with relief mapping and POM, beside
//! dispmap's deferred frame, for the benchmark ([`crate::passes::forward`]).
//!
//! [`Renderer::render_forward`] records, in place of the G-buffer pass and the pass's
//! `classify -> trace -> shade`:
//!
//! 1. the G-buffer's `normal`, `tangent` and `depth`: discarded -> attachment layouts;
//!    the hit images and the forward path's iteration counts: discarded -> `GENERAL` for
//!    colour-attachment writes; the `ray`
//!    image: discarded -> `SHADER_READ_ONLY_OPTIMAL` (not written: the pass's views stay
//!    in their entry layouts); the forward height texture, on the first forward frame:
//!    visible to fragment-shader sampled reads;
//! 2. the `forward` pass in the renderer's `gbuffer` scope: the G-buffer and the hits
//!    from one fragment shader;
//! 3. the pass's entry barriers (the hit images: colour-attachment writes -> compute
//!    storage reads), the background, and [`DisplacementPass::record_shading`]:
//!    `classify -> [shadow] -> shade` on those hits, as the deferred frame shades its
//!    trace's.
//!
//! So a forward frame's times are `gbuffer` (the raster pass with the march), `classify`
//! and `shade`, a deferred frame's `gbuffer`, `classify`, `trace` and `shade`: the same
//! shading, the same attachments but the ray, which the forward frame does not need.
//!
//! [`DisplacementPass::record_shading`]: crate::embed::DisplacementPass::record_shading

use super::{DISCARD, GBUFFER_QUERIES, PassTimes, Renderer};
use crate::context::Context;
use crate::embed::Timestamps;
use crate::error::{Error, Result};
use crate::gpu::HeightTexture;
use crate::gpu::Image;
use crate::gpu::owned::Destroy;
use crate::gpu::sync::Access;
use crate::gpu::track::{Handle, Tracker};
use crate::heightfield::HeightField;
use crate::passes::PassName;
use crate::passes::forward::{ForwardPass, ForwardTargets};
use crate::passes::trace::ITERATIONS_FORMAT;
use crate::timing::ScopeWriter;
use ash::vk;

/// The forward path's own resources: the map's texture (an engine owns its textures;
/// the pass's are internal to it), one pipeline per method used so far and the iteration
/// counts of its frames (the pass's are written by its `trace`, which a forward frame
/// does not run).
pub(super) struct Forward {
    height: HeightTexture,
    passes: Vec<ForwardPass>,
    /// Whether a forward frame has made the texture visible to fragment shaders.
    height_visible: bool,
    /// The last forward frame's iteration counts (made by the first forward frame of
    /// each frame size).
    iterations: Option<Image>,
}

impl Forward {
    /// The last forward frame's iteration counts and their last access.
    pub(super) fn iterations(&self) -> Option<(&Image, Access)> {
        self.iterations.as_ref().map(|i| (i, HIT_ATTACHMENT_WRITE))
    }
}

impl Destroy for Forward {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.height.destroy(ctx);
            self.passes.destroy(ctx);
            self.iterations.destroy(ctx);
        }
    }
}

/// The hit images and iteration counts written as colour attachments in `GENERAL` (the
/// forward pass).
const HIT_ATTACHMENT_WRITE: Access = Access {
    layout: vk::ImageLayout::GENERAL,
    ..Access::COLOR_ATTACHMENT_WRITE
};

/// Sampled by fragment shaders (the forward pass's height texture).
const FRAGMENT_SAMPLED: Access = Access {
    stage: vk::PipelineStageFlags2::FRAGMENT_SHADER,
    ..Access::COMPUTE_SAMPLED
};

impl Renderer {
    /// Enables [`Renderer::render_forward`]: uploads `field`, which must be the map this
    /// renderer was built with (the forward pass samples its own copy, as an engine's
    /// G-buffer shader samples the engine's texture; the size and format are checked).
    /// Only for a renderer of the tiled plane or the quad (the G-buffer pass's own
    /// geometry), not of a mesh or of several objects. Calling it again replaces the
    /// copy.
    pub fn enable_forward(&mut self, field: &HeightField) -> Result<()> {
        if self.objects.is_some() || self.mesh.is_some() {
            return Err(Error::invalid(
                "forward",
                "the forward path draws the tiled plane or the quad, not a mesh or several \
                 objects",
            ));
        }
        let size = self.pass.map_size();
        if [field.width(), field.height()] != size {
            return Err(Error::invalid(
                field.label(),
                format!(
                    "{}x{} is not the renderer's map ({}x{}): the forward path needs the same \
                     map",
                    field.width(),
                    field.height(),
                    size[0],
                    size[1]
                ),
            ));
        }
        let ctx = &*self.ctx;
        let height = HeightTexture::upload(
            ctx,
            &self.shot,
            field,
            self.settings.scene.addressing(),
            false,
        )?;
        let mut old = self.forward.replace(Forward {
            height,
            passes: Vec::new(),
            height_visible: false,
            iterations: None,
        });
        // Every frame of this renderer was waited for: nothing reads the old copy.
        // SAFETY: every frame of this renderer was waited for (`render` submits and waits).
        unsafe { old.destroy(ctx) };
        Ok(())
    }

    /// Renders one forward frame (module docs: the method's march in the G-buffer pass,
    /// then the same shading as [`Renderer::render`]) and returns its per-pass GPU times.
    /// Needs [`Renderer::enable_forward`] and a method with a forward path (`relief`,
    /// `pom`: [`crate::method::Method::forward_shader`]); refused with level of detail
    /// (the forward pass samples level 0 only) and with the corrected-depth or the motion
    /// output on (the forward frame has neither stage). The hits are the deferred frame's
    /// ([`crate::passes::forward`]); [`Renderer::read_rays`] has no rays after it.
    pub fn render_forward(&mut self) -> Result<PassTimes> {
        let method = self.settings.method;
        let params = self.settings.params;
        if params.lod_threshold.is_some() {
            return Err(Error::invalid(
                "lod-threshold",
                "the forward path samples the map's level 0 only: turn level of detail off",
            ));
        }
        if self.pass.depth_output() {
            return Err(Error::invalid(
                "depth output",
                "the forward frame has no corrected depth: turn the output off",
            ));
        }
        if self.motion.is_some() {
            return Err(Error::invalid(
                "motion output",
                "the forward frame has no motion vectors: turn the output off",
            ));
        }
        let ctx = self.ctx.clone();
        let ctx = &*ctx;
        let (camera, target) = self.frame_target();
        let gbuffer_params = self.settings.scene.gbuffer_params(&camera);
        let forward = self.forward.as_mut().ok_or_else(|| {
            Error::invalid(
                "forward",
                "the forward path is not enabled (Renderer::enable_forward)",
            )
        })?;
        let index = match forward.passes.iter().position(|p| p.method() == method) {
            Some(i) => i,
            None => {
                forward.passes.push(ForwardPass::new(ctx, method, &params)?);
                forward.passes.len() - 1
            }
        };
        // Every earlier frame was waited for: nothing reads the parameter buffer.
        forward.passes[index].set_params(&params)?;
        let extent = self.settings.extent();
        if forward
            .iterations
            .as_ref()
            .is_none_or(|i| i.extent != extent)
        {
            let image = Image::new(
                ctx,
                "forward.iterations",
                ITERATIONS_FORMAT,
                extent,
                1,
                vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC,
            )?;
            // SAFETY: every frame of this renderer was waited for: nothing uses the old one.
            unsafe { forward.iterations.replace(image).destroy(ctx) };
        }
        let Some(iterations) = &forward.iterations else {
            return Err(Error::Internal("no forward iteration image".into()));
        };

        let cmd = self.shot.begin(ctx)?;
        let mut w = ScopeWriter::new(Some(self.timestamps.0), 0, GBUFFER_QUERIES);
        // SAFETY: `cmd` was just begun; the pool is alive with the range.
        unsafe { w.reset(ctx, cmd) };
        let g = &self.gbuffer;
        // The frame's images enter discarded (their previous frame was waited for), the
        // forward height texture sampled-readable by compute since its upload (fragment
        // shaders too after the first forward frame); the tracker places every barrier
        // from the accesses declared below.
        let mut t = Tracker::new();
        let [ray, frame, depth] = [&g.ray, &g.frame, &g.depth].map(Handle::image);
        let (hit_uv, hit_height) = (Handle::image(&self.hit.uv), Handle::image(&self.hit.height));
        let (counts, color) = (Handle::image(iterations), Handle::image(&self.color));
        for image in [ray, frame, depth, hit_uv, hit_height, counts, color] {
            t.enter(image, DISCARD);
        }
        let height = Handle::image(&forward.height.image);
        t.enter(
            height,
            if forward.height_visible {
                FRAGMENT_SAMPLED
            } else {
                Access::COMPUTE_SAMPLED
            },
        );
        t.declare(frame, Access::COLOR_ATTACHMENT_WRITE)?;
        t.declare(depth, Access::DEPTH_ATTACHMENT_WRITE)?;
        // Not written: the pass's views stay in their entry layouts.
        t.declare(ray, Access::COMPUTE_SAMPLED)?;
        for image in [hit_uv, hit_height, counts] {
            t.declare(image, HIT_ATTACHMENT_WRITE)?;
        }
        t.declare(height, FRAGMENT_SAMPLED)?;
        // SAFETY: `cmd` was begun by `shot.begin` above (outside a render pass, on the
        // context's queue family) and is submitted and waited for below, while the images
        // live; they entered as the tracker knows; the G-buffer and the hit images have
        // attachment usage (`GBuffer::new`, `frame_images`, the iteration image above).
        unsafe { t.record(ctx, cmd)? };
        let pass = &forward.passes[index];
        let targets = ForwardTargets {
            uv: &self.hit.uv,
            height: &self.hit.height,
            iterations,
        };
        let height_texture = &forward.height;
        // SAFETY: `cmd` is recording outside a render pass and `w.reset` was recorded
        // above (the scope's contract). In the body: the hit images and iteration counts are in `GENERAL`, the
        // frame in `COLOR_ATTACHMENT_OPTIMAL`, the depth in
        // `DEPTH_ATTACHMENT_OPTIMAL` and the height texture visible to fragment-shader
        // reads (the barriers above, or the first forward frame's); the parameter buffer
        // was written after every earlier frame completed; everything lives until the
        // submission below has completed.
        unsafe {
            w.scope(ctx, cmd, PassName::GBuffer, |cmd| {
                pass.record(
                    ctx,
                    cmd,
                    g,
                    targets,
                    height_texture,
                    (&gbuffer_params, &camera.pixel_ray_params()),
                )
            })?
        };
        // The pass's entry: the G-buffer sampled by compute, the hits read as storage,
        // the colour written (the background, then `shade`).
        t.declare(frame, Access::COMPUTE_SAMPLED)?;
        t.declare(depth, Access::COMPUTE_SAMPLED)?;
        t.declare(hit_uv, Access::COMPUTE_STORAGE_READ)?;
        t.declare(hit_height, Access::COMPUTE_STORAGE_READ)?;
        t.declare(color, Access::COMPUTE_STORAGE_WRITE)?;
        // SAFETY: `cmd` is recording outside a render pass (begun above, submitted
        // below); the images are alive and in the states the tracker knows (the
        // attachments written by the scope above).
        unsafe { t.record(ctx, cmd)? };
        // SAFETY: `cmd` is recording outside a render pass and submitted below; the
        // G-buffer is sampled-readable and the colour image in GENERAL for storage writes
        // (the barriers above).
        unsafe { self.record_background(cmd, &target, &mut t)? };
        let inputs = self.frame_inputs(Some(target));
        // SAFETY: `cmd` is recording outside a render pass on the context's queue and is
        // submitted below; the G-buffer views are in the entry states (the `ray` image
        // too, discarded: nothing reads it); the hits were written by the forward pass and
        // made visible to compute-shader storage reads (the barrier above); one slot,
        // whose previous frame was waited for; the pool has the queries after the
        // G-buffer's.
        let frame = unsafe {
            self.pass.record_shading(
                cmd,
                &inputs,
                None,
                Timestamps::Host {
                    pool: self.timestamps.0,
                    first_query: GBUFFER_QUERIES,
                },
            )?
        };
        self.shot.submit_and_wait(ctx)?;
        if let Some(f) = self.forward.as_mut() {
            f.height_visible = true;
        }
        self.rays_frame = None;
        self.forward_frame = true;
        self.frame_times(&w, &frame)
    }
}
