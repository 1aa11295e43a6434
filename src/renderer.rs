//! The standalone renderer: owns the images and passes of one frame size and runs
//! `gbuffer -> [pyramid] -> [dig_corners] -> trace -> [shadow] -> shade` on the context's queue,
//! each pass between timestamps. It builds only what the method needs ([`Method::needs`]):
//! the pyramid (and its pass) only for the pyramid methods, the corner grid only for DIG.
//! The pyramid is built in the first frame after the method asks for it (the height map
//! does not change during a renderer's life) and reported as the `pyramid` pass of that
//! frame only.
//!
//! Barriers and layouts per frame (the contract each pass documents):
//!
//! 1. G-buffer images: discarded (`UNDEFINED`, after last frame's compute reads) ->
//!    attachment layouts; `gbuffer` clears and writes them.
//! 2. G-buffer -> `SHADER_READ_ONLY_OPTIMAL` for compute. When it is (re)built, the
//!    pyramid pass takes its image from discarded to `SHADER_READ_ONLY_OPTIMAL` itself.
//!    DIG: corner grid discarded -> `GENERAL`, `dig_corners` writes it, then ->
//!    `SHADER_READ_ONLY_OPTIMAL`. Hit buffer: discarded -> `GENERAL` for storage writes;
//!    `trace` writes the hits.
//! 3. Self-shadowing on ([`ShadowSettings`]): hit buffer storage write -> storage read,
//!    visibility discarded -> `GENERAL` storage write; `shadow` writes it, then storage
//!    write -> storage read. (The stage's own cell pyramid, `pyramid` method only, is
//!    built with the method's in the `pyramid` scope.)
//! 4. Hit buffer: storage write -> storage read (`GENERAL`); colour: discarded ->
//!    `GENERAL`; `shade` writes the colour.
//! 5. With [`Renderer::set_depth_output`] on: the corrected depth, discarded ->
//!    `GENERAL`; `hit_depth` writes it from the hit buffer (still `GENERAL`, storage read)
//!    and the G-buffer.
//!
//! After a frame the hit buffer is in `GENERAL` (last access: storage read), the colour
//! and the corrected depth in `GENERAL` (last access: storage write) and the G-buffer in
//! `SHADER_READ_ONLY_OPTIMAL`; the read-back helpers use exactly those states.

use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::commands::{read_image, upload_image};
use crate::gpu::sync::{self, Access};
use crate::gpu::{HeightTexture, Image, OneShot};
use crate::heightfield::HeightField;
use crate::method::{Method, MethodParams, Needs};
use crate::metrics::{self, ErrorMetrics, HitTexel, MapGeometry};
use crate::passes::dig::{Corner, CornerGrid, DigCornerPass};
use crate::passes::gbuffer::{GBuffer, GBufferPass};
use crate::passes::hit_depth::{HIT_DEPTH_FORMAT, HitDepthInputs, HitDepthPass};
use crate::passes::pyramid::{Pyramid, PyramidPass};
use crate::passes::shade::{COLOR_FORMAT, ShadeInputs, ShadePass};
use crate::passes::shadow::{ShadowInputs, ShadowMode, ShadowPass, ShadowSettings, ShadowStage};
use crate::passes::trace::{HIT_FORMAT, TraceInputs, TracePass};
use crate::reference::{Hit, Ray, Reference};
use crate::scene::Scene;
use crate::timing::GpuTimer;
// Scenes (issue 6): meshes and material maps.
use crate::material::{MaterialImages, MaterialTextures};
use crate::mesh::{Mesh, MeshBuffers};
use ash::vk;

/// Largest frame side the CLI accepts (a sanity bound; the device's limit applies too).
pub const MAX_FRAME_SIDE: u32 = 16384;

/// What to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// The intersection method.
    pub method: Method,
    /// Its parameters.
    pub params: MethodParams,
    /// Camera, light, geometry, depth scale.
    pub scene: Scene,
    /// Self-shadowing (default: off).
    pub shadows: ShadowSettings,
}

impl RenderSettings {
    /// Checks every value; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0
            || self.height == 0
            || self.width > MAX_FRAME_SIDE
            || self.height > MAX_FRAME_SIDE
        {
            return Err(Error::invalid(
                "size",
                format!(
                    "{}x{} is outside 1..={MAX_FRAME_SIDE} per side",
                    self.width, self.height
                ),
            ));
        }
        self.params.validate()?;
        self.shadows.validate()?;
        self.scene.validate()
    }
}

/// Per-pass GPU milliseconds of one frame, in pass order.
pub type PassTimes = Vec<(&'static str, f64)>;

/// Discarded contents, after compute reads or copies of an earlier frame.
const DISCARD: Access = Access {
    stage: vk::PipelineStageFlags2::from_raw(
        vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw() | vk::PipelineStageFlags2::COPY.as_raw(),
    ),
    access: vk::AccessFlags2::NONE,
    layout: vk::ImageLayout::UNDEFINED,
};

/// The reference for one frame: rays read from the G-buffer, exact hits, and those
/// hits shaded by the same `shade` pass.
pub struct FrameReference {
    /// Each pixel's ray (`None`: no geometry).
    pub rays: Vec<Option<Ray>>,
    /// The exact first intersections.
    pub hits: Vec<Option<Hit>>,
    /// The reference hits shaded (RGBA8).
    pub color: Vec<u8>,
}

/// Images, passes and a command buffer for one frame size.
pub struct Renderer<'a> {
    ctx: &'a Context,
    settings: RenderSettings,
    shot: OneShot,
    timer: GpuTimer,
    height: HeightTexture,
    gbuffer: GBuffer,
    hit: Image,
    color: Image,
    gbuffer_pass: GBufferPass,
    trace: TracePass,
    shade: ShadePass,
    /// What the method needs, built by [`Renderer::prepare`].
    extras: Extras,
    /// Self-shadowing (`None` when off), built by [`Renderer::prepare`].
    shadow: Option<ShadowStage>,
    /// The corrected-depth pass and image ([`Renderer::set_depth_output`]).
    depth: Option<DepthOutput>,
    /// The macro geometry's vertex and index buffers (meshes only).
    mesh: Option<MeshBuffers>,
    /// Albedo and normal maps (only when the scene has one).
    material: Option<MaterialTextures>,
}

/// What a scene brings besides the height field and the settings: a loaded mesh (for
/// [`crate::scene::Geometry::Mesh`]) and the material maps. The generated cube, sphere
/// and torus need no mesh here.
#[derive(Clone, Debug, Default)]
pub struct SceneAssets {
    /// The loaded mesh.
    pub mesh: Option<Mesh>,
    /// Albedo and normal map.
    pub material: MaterialImages,
}

/// The corrected depth of the displaced surface: its pass and `R32_SFLOAT` image.
struct DepthOutput {
    pass: HitDepthPass,
    image: Image,
    /// Whether a frame has written the image (before that it has no contents or layout).
    written: bool,
}

impl DepthOutput {
    fn destroy(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.image.destroy(ctx);
    }
}

/// The resources and passes only some methods need.
#[derive(Default)]
struct Extras {
    pyramid_pass: Option<PyramidPass>,
    pyramid: Option<Pyramid>,
    pyramid_built: bool,
    /// GPU milliseconds of the last pyramid build.
    pyramid_ms: Option<f64>,
    corner_pass: Option<DigCornerPass>,
    corners: Option<CornerGrid>,
}

impl Extras {
    fn destroy(&mut self, ctx: &Context) {
        if let Some(p) = &mut self.pyramid_pass {
            p.destroy(ctx);
        }
        if let Some(p) = &mut self.pyramid {
            p.destroy(ctx);
        }
        if let Some(p) = &mut self.corner_pass {
            p.destroy(ctx);
        }
        if let Some(c) = &mut self.corners {
            c.destroy(ctx);
        }
        *self = Extras::default();
    }
}

impl<'a> Renderer<'a> {
    /// Uploads `field` and builds what `settings` needs (no loaded mesh, no material
    /// maps: see [`Renderer::with_assets`]).
    pub fn new(ctx: &'a Context, field: &HeightField, settings: RenderSettings) -> Result<Self> {
        Self::with_assets(ctx, field, settings, &SceneAssets::default())
    }

    /// [`Renderer::new`] with a scene's mesh and material maps. Builds only what the
    /// scene uses: vertex buffers only for mesh geometry, textures only for given maps.
    pub fn with_assets(
        ctx: &'a Context,
        field: &HeightField,
        settings: RenderSettings,
        assets: &SceneAssets,
    ) -> Result<Self> {
        settings.validate()?;
        let geometry = settings.scene.geometry;
        let mesh = match (geometry.generated_mesh(), &assets.mesh) {
            (Some(generated), _) => Some(std::borrow::Cow::Owned(generated)),
            (None, Some(loaded)) if geometry == crate::scene::Geometry::Mesh => {
                Some(std::borrow::Cow::Borrowed(loaded))
            }
            (None, None) if geometry == crate::scene::Geometry::Mesh => {
                return Err(Error::invalid(
                    "geometry",
                    "'mesh' needs a loaded mesh (a scene file's `mesh` key)",
                ));
            }
            _ => None,
        };
        let max = ctx.info().max_image_dimension_2d;
        if field.width() > max || field.height() > max {
            return Err(Error::invalid(
                field.label(),
                format!(
                    "{}x{} exceeds the device's maxImageDimension2D ({max})",
                    field.width(),
                    field.height()
                ),
            ));
        }
        let extent = vk::Extent2D {
            width: settings.width,
            height: settings.height,
        };
        // Build in order; if a step fails, `parts` destroys what exists when dropped.
        let mut parts = Parts {
            ctx,
            shot: None,
            timer: None,
            height: None,
            gbuffer: None,
            hit: None,
            color: None,
            gbuffer_pass: None,
            trace: None,
            shade: None,
            mesh: None,
            material: None,
        };
        let shot = parts.shot.insert(OneShot::new(ctx, "renderer")?);
        parts.height = Some(HeightTexture::upload(
            ctx,
            shot,
            field,
            settings.scene.addressing(),
            settings.params.lod_threshold.is_some(),
        )?);
        parts.timer = Some(GpuTimer::new(ctx, "renderer.timestamps", 8)?);
        parts.gbuffer = Some(GBuffer::new(ctx, extent)?);
        parts.hit = Some(Image::new(
            ctx,
            "hits",
            HIT_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        )?);
        parts.color = Some(Image::new(
            ctx,
            "color",
            COLOR_FORMAT,
            extent,
            1,
            vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
        )?);
        parts.gbuffer_pass = Some(if mesh.is_some() {
            GBufferPass::new_mesh(ctx)?
        } else {
            GBufferPass::new(ctx)?
        });
        if let Some(mesh) = &mesh {
            let shot = parts.shot.as_ref().expect("built first");
            parts.mesh = Some(MeshBuffers::upload(ctx, shot, mesh)?);
        }
        parts.material = MaterialTextures::upload(
            ctx,
            parts.shot.as_ref().expect("built first"),
            &assets.material,
            settings.scene.addressing(),
        )?;
        parts.trace = Some(TracePass::new(ctx, settings.method)?);
        parts.shade = Some(ShadePass::new(ctx)?);
        let built = "every part was built above";
        let mut renderer = Renderer {
            ctx,
            settings,
            shot: parts.shot.take().expect(built),
            timer: parts.timer.take().expect(built),
            height: parts.height.take().expect(built),
            gbuffer: parts.gbuffer.take().expect(built),
            hit: parts.hit.take().expect(built),
            color: parts.color.take().expect(built),
            gbuffer_pass: parts.gbuffer_pass.take().expect(built),
            trace: parts.trace.take().expect(built),
            shade: parts.shade.take().expect(built),
            extras: Extras::default(),
            depth: None,
            shadow: None,
            mesh: parts.mesh.take(),
            material: parts.material.take(),
        };
        // On failure the renderer's Drop destroys everything built so far.
        renderer.prepare()?;
        Ok(renderer)
    }

    /// Builds what the current method needs and drops what it does not.
    fn prepare(&mut self) -> Result<()> {
        let ctx = self.ctx;
        let Needs {
            pyramid,
            dig_corners,
        } = self.settings.method.needs();
        // The height map's mip chain exists only while level of detail reads it.
        let chain = self.settings.params.lod_threshold.is_some();
        if self.height.differs_for(ctx, chain) {
            let mut new = self.height.create_like(ctx, chain)?;
            let filled = (|| {
                let cmd = self.shot.begin(ctx)?;
                new.record_copy_from(ctx, cmd, &self.height);
                self.shot.submit_and_wait(ctx)
            })();
            if let Err(e) = filled {
                new.destroy(ctx);
                return Err(e);
            }
            // The queue is idle (`submit_and_wait`): no frame reads the old texture.
            std::mem::replace(&mut self.height, new).destroy(ctx);
        }
        let frame = self.frame_size();
        let block = self.settings.params.block;
        let map_size = self.height.size();
        let addressing = self.height.addressing;
        let x = &mut self.extras;
        match pyramid {
            Some(kind) => {
                if x.pyramid_pass.is_none() {
                    x.pyramid_pass = Some(PyramidPass::new(ctx)?);
                }
                if x.pyramid.as_ref().is_none_or(|p| p.kind != kind) {
                    if let Some(mut old) = x.pyramid.take() {
                        old.destroy(ctx);
                    }
                    x.pyramid_built = false;
                    x.pyramid_ms = None;
                    x.pyramid = Some(Pyramid::new(ctx, map_size, kind, addressing)?);
                }
            }
            None => {
                if let Some(mut p) = x.pyramid_pass.take() {
                    p.destroy(ctx);
                }
                if let Some(mut p) = x.pyramid.take() {
                    p.destroy(ctx);
                }
                x.pyramid_built = false;
            }
        }
        if dig_corners {
            if x.corner_pass.is_none() {
                x.corner_pass = Some(DigCornerPass::new(ctx)?);
            }
            if x.corners.as_ref().is_none_or(|c| c.block != block) {
                if let Some(mut old) = x.corners.take() {
                    old.destroy(ctx);
                }
                x.corners = Some(CornerGrid::new(ctx, frame, block)?);
            }
        } else {
            if let Some(mut p) = x.corner_pass.take() {
                p.destroy(ctx);
            }
            if let Some(mut c) = x.corners.take() {
                c.destroy(ctx);
            }
        }
        self.prepare_shadows()
    }

    /// Builds or drops the self-shadowing stage and picks the matching shade pass.
    fn prepare_shadows(&mut self) -> Result<()> {
        let ctx = self.ctx;
        let shadows = self.settings.shadows;
        if self.shade.is_shadowed() != shadows.is_on() {
            let new = if shadows.is_on() {
                ShadePass::shadowed(ctx)?
            } else {
                ShadePass::new(ctx)?
            };
            let mut old = std::mem::replace(&mut self.shade, new);
            old.destroy(ctx);
        }
        let extent = vk::Extent2D {
            width: self.settings.width,
            height: self.settings.height,
        };
        ShadowStage::sync(
            ctx,
            &mut self.shadow,
            &shadows,
            self.settings.method,
            extent,
            self.height.size(),
            self.height.addressing,
        )
    }

    /// Switches self-shadowing (builds or drops the `shadow` pass and its image).
    pub fn set_shadows(&mut self, shadows: ShadowSettings) -> Result<()> {
        shadows.validate()?;
        self.settings.shadows = shadows;
        self.prepare()
    }

    /// The last frame's light visibility (1 = lit), row by row; `None` when
    /// self-shadowing is off.
    pub fn read_visibility(&self) -> Result<Option<Vec<f32>>> {
        let Some(stage) = &self.shadow else {
            return Ok(None);
        };
        let bytes = read_image(
            self.ctx,
            &self.shot,
            &stage.visibility,
            Access::COMPUTE_STORAGE_READ,
        )?;
        Ok(Some(
            bytes
                .chunks_exact(2)
                .map(|b| crate::passes::shadow::f16_to_f32(u16::from_le_bytes([b[0], b[1]])))
                .collect(),
        ))
    }

    /// The settings in use.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Switches the method (and its parameters); the G-buffer and map stay.
    pub fn set_method(&mut self, method: Method, params: MethodParams) -> Result<()> {
        params.validate()?;
        if method != self.trace.method() {
            let new = TracePass::new(self.ctx, method)?;
            let mut old = std::mem::replace(&mut self.trace, new);
            old.destroy(self.ctx);
        }
        self.settings.method = method;
        self.settings.params = params;
        self.prepare()
    }

    /// Changes camera, light or depth scale (the geometry and addressing must stay).
    pub fn set_scene(&mut self, scene: Scene) -> Result<()> {
        scene.validate()?;
        if scene.geometry != self.settings.scene.geometry {
            return Err(Error::invalid(
                "geometry",
                "changing the geometry needs a new renderer",
            ));
        }
        if scene.addressing() != self.height.addressing {
            return Err(Error::invalid(
                "geometry",
                "changing the addressing needs a new renderer",
            ));
        }
        self.settings.scene = scene;
        Ok(())
    }

    fn frame_size(&self) -> [u32; 2] {
        [self.settings.width, self.settings.height]
    }

    /// Renders one frame and returns its per-pass GPU times.
    pub fn render(&mut self) -> Result<PassTimes> {
        let ctx = self.ctx;
        let scene = self.settings.scene;
        let camera = scene.frame_camera(self.settings.width, self.settings.height);
        let gbuffer_params = scene.gbuffer_params(&camera);
        let shade_params = scene.shade_params(&camera, self.frame_size(), self.height.size());
        let cmd = self.shot.begin(ctx)?;
        self.timer.reset(ctx, cmd);

        let colors = self.gbuffer.colors();
        let mut to_attachments: Vec<_> = colors
            .iter()
            .map(|i| sync::image_barrier(i.raw, i.range(), DISCARD, Access::COLOR_ATTACHMENT_WRITE))
            .collect();
        to_attachments.push(sync::image_barrier(
            self.gbuffer.depth.raw,
            self.gbuffer.depth.range(),
            DISCARD,
            Access::DEPTH_ATTACHMENT_WRITE,
        ));
        sync::record(ctx, cmd, &to_attachments);
        ctx.begin_label(cmd, "gbuffer");
        self.timer.begin(ctx, cmd, "gbuffer")?;
        match &self.mesh {
            Some(mesh) => {
                self.gbuffer_pass
                    .record_mesh(ctx, cmd, &self.gbuffer, &gbuffer_params, mesh)
            }
            None => self
                .gbuffer_pass
                .record(ctx, cmd, &self.gbuffer, &gbuffer_params),
        }
        self.timer.end(ctx, cmd);
        ctx.end_label(cmd);

        let mut to_trace: Vec<_> = colors
            .iter()
            .map(|i| {
                sync::image_barrier(
                    i.raw,
                    i.range(),
                    Access::COLOR_ATTACHMENT_WRITE,
                    Access::COMPUTE_SAMPLED,
                )
            })
            .collect();
        to_trace.push(sync::image_barrier(
            self.gbuffer.depth.raw,
            self.gbuffer.depth.range(),
            Access::DEPTH_ATTACHMENT_WRITE,
            Access::COMPUTE_SAMPLED,
        ));
        to_trace.push(sync::image_barrier(
            self.hit.raw,
            self.hit.range(),
            DISCARD,
            Access::COMPUTE_STORAGE_WRITE,
        ));
        if let Some(corners) = &self.extras.corners {
            to_trace.push(sync::image_barrier(
                corners.image.raw,
                corners.image.range(),
                DISCARD,
                Access::COMPUTE_STORAGE_WRITE,
            ));
        }
        sync::record(ctx, cmd, &to_trace);

        let method_pyramid = match (
            &self.extras.pyramid_pass,
            &self.extras.pyramid,
            self.extras.pyramid_built,
        ) {
            (Some(pass), Some(pyramid), false) => Some((pass, pyramid)),
            _ => None,
        };
        let shadow_pyramid = self.shadow.as_ref().and_then(ShadowStage::unbuilt_pyramid);
        if method_pyramid.is_some() || shadow_pyramid.is_some() {
            ctx.begin_label(cmd, "pyramid");
            self.timer.begin(ctx, cmd, "pyramid")?;
            for (pass, pyramid) in method_pyramid.into_iter().chain(shadow_pyramid) {
                pass.record(ctx, cmd, &self.height, pyramid);
            }
            self.timer.end(ctx, cmd);
            ctx.end_label(cmd);
        }
        if let (Some(pass), Some(corners)) = (&self.extras.corner_pass, &self.extras.corners) {
            ctx.begin_label(cmd, "dig_corners");
            self.timer.begin(ctx, cmd, "dig_corners")?;
            pass.record(
                ctx,
                cmd,
                self.gbuffer.views(),
                &self.height,
                corners,
                self.settings.params.steps,
            );
            self.timer.end(ctx, cmd);
            ctx.end_label(cmd);
            sync::record(
                ctx,
                cmd,
                &[sync::image_barrier(
                    corners.image.raw,
                    corners.image.range(),
                    Access::COMPUTE_STORAGE_WRITE,
                    Access::COMPUTE_SAMPLED,
                )],
            );
        }

        ctx.begin_label(cmd, "trace");
        self.timer.begin(ctx, cmd, "trace")?;
        self.trace.record(
            ctx,
            cmd,
            TraceInputs {
                gbuffer: self.gbuffer.views(),
                height: &self.height,
                hit: self.hit.view_ref(),
                pyramid: self.extras.pyramid.as_ref(),
                corners: self.extras.corners.as_ref(),
            },
            &self.settings.params,
            scene.depth_scale,
        )?;
        self.timer.end(ctx, cmd);
        ctx.end_label(cmd);

        self.record_shade(cmd, &shade_params, Access::COMPUTE_STORAGE_WRITE, true)?;
        self.record_hit_depth(cmd, &camera)?;
        self.shot.submit_and_wait(ctx)?;
        if let Some(stage) = &mut self.shadow {
            stage.mark_built();
        }
        let times = self.timer.read(ctx)?;
        if self.extras.pyramid.is_some() && !self.extras.pyramid_built {
            self.extras.pyramid_built = true;
            self.extras.pyramid_ms = times.iter().find(|(n, _)| *n == "pyramid").map(|t| t.1);
        }
        Ok(times)
    }

    /// The last frame's DIG corner grid (`None` unless the method is a DIG): the grid size
    /// in corners and the corners row by row.
    pub fn read_corners(&self) -> Result<Option<([u32; 2], Vec<Corner>)>> {
        match &self.extras.corners {
            Some(c) => Ok(Some((
                c.size(),
                c.read(self.ctx, &self.shot, Access::COMPUTE_SAMPLED)?,
            ))),
            None => Ok(None),
        }
    }

    /// The pyramid's levels (logical sizes, row by row); `None` unless the method uses
    /// one and a frame has built it.
    pub fn read_pyramid(&self) -> Result<Option<Vec<Vec<f32>>>> {
        match (&self.extras.pyramid, self.extras.pyramid_built) {
            (Some(p), true) => Ok(Some(p.read_levels(self.ctx, &self.shot)?)),
            _ => Ok(None),
        }
    }

    /// Turns the corrected-depth output on (builds the `hit_depth` pass and its
    /// `R32_SFLOAT` image; every later [`Renderer::render`] runs it after `shade`) or off
    /// (destroys them).
    pub fn set_depth_output(&mut self, on: bool) -> Result<()> {
        match (on, self.depth.take()) {
            (true, Some(d)) => self.depth = Some(d),
            (true, None) => {
                let ctx = self.ctx;
                let mut pass = HitDepthPass::new(ctx)?;
                let extent = vk::Extent2D {
                    width: self.settings.width,
                    height: self.settings.height,
                };
                let image = Image::new(
                    ctx,
                    "hit_depth",
                    HIT_DEPTH_FORMAT,
                    extent,
                    1,
                    vk::ImageUsageFlags::STORAGE
                        | vk::ImageUsageFlags::SAMPLED
                        | vk::ImageUsageFlags::TRANSFER_SRC,
                );
                match image {
                    Ok(image) => {
                        self.depth = Some(DepthOutput {
                            pass,
                            image,
                            written: false,
                        })
                    }
                    Err(e) => {
                        pass.destroy(ctx);
                        return Err(e);
                    }
                }
            }
            (false, Some(mut d)) => {
                // SAFETY: every submission was waited for (render waits for its frame).
                unsafe {
                    let _ = self.ctx.device().device_wait_idle();
                }
                d.destroy(self.ctx);
            }
            (false, None) => {}
        }
        Ok(())
    }

    /// The corrected-depth image (`R32_SFLOAT`, reverse-Z clip depth of each pixel's hit,
    /// 0 without one; see [`crate::passes::hit_depth`]) once a frame has been rendered
    /// with the output on. It is in `GENERAL`, last written by a compute-shader storage
    /// write; a caller that reads it in its own submission (e.g.
    /// [`crate::passes::depth_resolve`]) places the barrier from that state and returns
    /// it there.
    pub fn hit_depth(&self) -> Option<&Image> {
        self.depth.as_ref().filter(|d| d.written).map(|d| &d.image)
    }

    /// The corrected depth of the last [`Renderer::render`]'s hits, row by row (`None`
    /// when the output is off; an error when no frame has been rendered since it was
    /// turned on). [`Renderer::shade_hits`] does not update it.
    pub fn read_depth(&self) -> Result<Option<Vec<f32>>> {
        match &self.depth {
            Some(d) if !d.written => Err(Error::invalid(
                "depth output",
                "no frame has been rendered since the depth output was turned on",
            )),
            Some(d) => {
                let bytes = read_image(
                    self.ctx,
                    &self.shot,
                    &d.image,
                    Access::COMPUTE_STORAGE_WRITE,
                )?;
                Ok(Some(bytemuck::cast_slice::<u8, f32>(&bytes).to_vec()))
            }
            None => Ok(None),
        }
    }

    fn record_hit_depth(
        &mut self,
        cmd: vk::CommandBuffer,
        camera: &crate::scene::FrameCamera,
    ) -> Result<()> {
        if let Some(d) = &mut self.depth {
            d.written = true;
        }
        let Some(depth) = &self.depth else {
            return Ok(());
        };
        let ctx = self.ctx;
        sync::record(
            ctx,
            cmd,
            &[sync::image_barrier(
                depth.image.raw,
                depth.image.range(),
                DISCARD,
                Access::COMPUTE_STORAGE_WRITE,
            )],
        );
        let params = crate::abi::HitDepthParams::new(
            camera.view_proj,
            camera.eye,
            self.frame_size(),
            self.settings.scene.depth_scale,
        );
        ctx.begin_label(cmd, "hit_depth");
        self.timer.begin(ctx, cmd, "hit_depth")?;
        depth.pass.record(
            ctx,
            cmd,
            HitDepthInputs {
                hit: self.hit.view,
                gbuffer: self.gbuffer.views(),
                hit_depth: depth.image.view_ref(),
            },
            &params,
        );
        self.timer.end(ctx, cmd);
        ctx.end_label(cmd);
        Ok(())
    }

    fn record_shade(
        &mut self,
        cmd: vk::CommandBuffer,
        params: &crate::abi::ShadeParams,
        hit_before: Access,
        run_shadow: bool,
    ) -> Result<()> {
        let ctx = self.ctx;
        let mut to_shade = vec![
            sync::image_barrier(
                self.hit.raw,
                self.hit.range(),
                hit_before,
                Access::COMPUTE_STORAGE_READ,
            ),
            sync::image_barrier(
                self.color.raw,
                self.color.range(),
                DISCARD,
                Access::COMPUTE_STORAGE_WRITE,
            ),
        ];
        if let (Some(stage), true) = (&self.shadow, run_shadow) {
            // The shadow pass reads the hits first; shade then needs only the colour's
            // and the visibility's barriers.
            let image = &stage.visibility;
            let hit_to_read = to_shade.remove(0);
            sync::record(
                ctx,
                cmd,
                &[
                    hit_to_read,
                    sync::image_barrier(
                        image.raw,
                        image.range(),
                        DISCARD,
                        Access::COMPUTE_STORAGE_WRITE,
                    ),
                ],
            );
            let shadow_params = ShadowPass::params(
                &self.settings.shadows,
                self.settings.params.steps,
                params,
                self.height.addressing,
            );
            ctx.begin_label(cmd, "shadow");
            self.timer.begin(ctx, cmd, "shadow")?;
            let recorded = stage.pass.record(
                ctx,
                cmd,
                ShadowInputs {
                    hit: self.hit.view,
                    gbuffer: self.gbuffer.views(),
                    height: &self.height,
                    pyramid: stage.pyramid(self.extras.pyramid.as_ref()),
                    visibility: image.view_ref(),
                },
                &shadow_params,
            );
            self.timer.end(ctx, cmd);
            ctx.end_label(cmd);
            recorded?;
            to_shade.push(sync::image_barrier(
                image.raw,
                image.range(),
                Access::COMPUTE_STORAGE_WRITE,
                Access::COMPUTE_STORAGE_READ,
            ));
        }
        sync::record(ctx, cmd, &to_shade);
        ctx.begin_label(cmd, "shade");
        self.timer.begin(ctx, cmd, "shade")?;
        self.shade.record_with_material(
            ctx,
            cmd,
            ShadeInputs {
                hit: self.hit.view,
                gbuffer: self.gbuffer.views(),
                height: &self.height,
                color: self.color.view_ref(),
                visibility: self.shadow.as_ref().map(|s| s.visibility.view),
            },
            self.material.as_ref(),
            params,
        )?;
        self.timer.end(ctx, cmd);
        ctx.end_label(cmd);
        Ok(())
    }

    /// Renders `frames` frames and returns the median time of each pass and of their
    /// sum (`total`, per frame: without the one-off pyramid build), in pass order. The
    /// pyramid is listed with the time of its (one) build, whichever frame ran it.
    pub fn render_frames(&mut self, frames: u32) -> Result<Vec<(String, f64)>> {
        let mut samples: Vec<(&'static str, Vec<f64>)> = Vec::new();
        let mut totals = Vec::new();
        for _ in 0..frames.max(1) {
            let times = self.render()?;
            totals.push(
                times
                    .iter()
                    .filter(|(n, _)| *n != "pyramid")
                    .map(|(_, ms)| ms)
                    .sum(),
            );
            for (name, ms) in times.into_iter().filter(|(n, _)| *n != "pyramid") {
                match samples.iter_mut().find(|(n, _)| *n == name) {
                    Some((_, v)) => v.push(ms),
                    None => samples.push((name, vec![ms])),
                }
            }
        }
        let mut out: Vec<(String, f64)> = Vec::new();
        if let (Some(ms), Some(_)) = (self.extras.pyramid_ms, &self.extras.pyramid) {
            out.push(("pyramid".into(), ms));
        }
        out.extend(
            samples
                .into_iter()
                .map(|(n, v)| (n.to_string(), crate::timing::median(&v))),
        );
        out.push(("total".into(), crate::timing::median(&totals)));
        Ok(out)
    }

    /// Each pixel's ray from the last frame's G-buffer (`None` where there is no geometry).
    pub fn read_rays(&self) -> Result<Vec<Option<Ray>>> {
        let ray = read_image(
            self.ctx,
            &self.shot,
            &self.gbuffer.ray,
            Access::COMPUTE_SAMPLED,
        )?;
        let depth = read_image(
            self.ctx,
            &self.shot,
            &self.gbuffer.depth,
            Access::COMPUTE_SAMPLED,
        )?;
        let ray: &[[f32; 4]] = bytemuck::cast_slice(&ray);
        let depth: &[f32] = bytemuck::cast_slice(&depth);
        Ok(ray
            .iter()
            .zip(depth)
            .map(|(r, &d)| {
                (d > 0.0).then(|| Ray {
                    uv0: [r[0] as f64, r[1] as f64],
                    parallax: [r[2] as f64, r[3] as f64],
                })
            })
            .collect())
    }

    /// The last frame's G-buffer depth (reverse-Z depth of the macro surface, 0 where
    /// there is no geometry), row by row.
    pub fn read_macro_depth(&self) -> Result<Vec<f32>> {
        let depth = read_image(
            self.ctx,
            &self.shot,
            &self.gbuffer.depth,
            Access::COMPUTE_SAMPLED,
        )?;
        Ok(bytemuck::cast_slice::<u8, f32>(&depth).to_vec())
    }

    /// The last frame's hit buffer.
    pub fn read_hits(&self) -> Result<Vec<HitTexel>> {
        let bytes = read_image(
            self.ctx,
            &self.shot,
            &self.hit,
            Access::COMPUTE_STORAGE_READ,
        )?;
        Ok(bytemuck::cast_slice::<u8, HitTexel>(&bytes).to_vec())
    }

    /// The last frame's colour image (RGBA8, sRGB-encoded).
    pub fn read_color(&self) -> Result<Vec<u8>> {
        read_image(
            self.ctx,
            &self.shot,
            &self.color,
            Access::COMPUTE_STORAGE_WRITE,
        )
    }

    /// Shades `hits` (one texel per pixel) with the current G-buffer and returns the
    /// colour. Overwrites the hit buffer. With self-shadowing on, the `shadow` pass runs
    /// on `hits` first.
    pub fn shade_hits(&mut self, hits: &[HitTexel]) -> Result<Vec<u8>> {
        self.shade_hits_with(hits, None)
    }

    /// [`Renderer::shade_hits`] with the light visibility given (one value per pixel;
    /// self-shadowing must be on) instead of computed by the `shadow` pass.
    pub fn shade_hits_with(
        &mut self,
        hits: &[HitTexel],
        visibility: Option<&[f32]>,
    ) -> Result<Vec<u8>> {
        let ctx = self.ctx;
        if let Some(values) = visibility {
            let stage = self.shadow.as_ref().ok_or_else(|| {
                Error::invalid("visibility", "self-shadowing is off: nothing to shade with")
            })?;
            upload_image(
                ctx,
                &self.shot,
                &stage.visibility,
                &crate::passes::shadow::encode_visibility(values),
                Access::COMPUTE_STORAGE_READ,
            )?;
        }
        upload_image(
            ctx,
            &self.shot,
            &self.hit,
            bytemuck::cast_slice(hits),
            Access::COMPUTE_STORAGE_READ,
        )?;
        let scene = self.settings.scene;
        let camera = scene.frame_camera(self.settings.width, self.settings.height);
        let params = scene.shade_params(&camera, self.frame_size(), self.height.size());
        let cmd = self.shot.begin(ctx)?;
        self.timer.reset(ctx, cmd);
        self.record_shade(
            cmd,
            &params,
            Access::COMPUTE_STORAGE_READ,
            visibility.is_none(),
        )?;
        self.shot.submit_and_wait(ctx)?;
        self.read_color()
    }

    /// Renders the G-buffer (with the current method), computes the exact hits of its
    /// rays on the CPU and shades them. With hard shadows the reference is shaded with
    /// the exact visibility of those hits ([`Reference::occluded`], whatever the method's
    /// shadow query); with soft shadows the `shadow` pass's estimate (the same for every
    /// method) runs on them.
    pub fn reference(&mut self, reference: &Reference) -> Result<FrameReference> {
        self.render()?;
        let rays = self.read_rays()?;
        let hits = reference.trace(&rays);
        let texels: Vec<HitTexel> = hits
            .iter()
            .map(|h| match h {
                Some(h) => [h.uv[0] as f32, h.uv[1] as f32, h.height as f32, 0.0],
                None => [0.0, 0.0, crate::abi::NO_HIT_HEIGHT, 0.0],
            })
            .collect();
        let color = if self.settings.shadows.mode == ShadowMode::Hard {
            // Hard shadows have an exact answer: the reference is shaded with it,
            // whichever method (and shadow query) this renderer runs.
            let visibility = self.reference_visibility(reference, &hits)?;
            self.shade_hits_with(&texels, Some(&visibility))?
        } else {
            // Off, or soft (the same estimate for every method): the pass itself.
            self.shade_hits(&texels)?
        };
        Ok(FrameReference { rays, hits, color })
    }

    /// The exact hard-shadow visibility of `hits` under the current light
    /// ([`crate::passes::shadow::reference_visibility`]).
    fn reference_visibility(
        &self,
        reference: &Reference,
        hits: &[Option<Hit>],
    ) -> Result<Vec<f32>> {
        let read = |image: &Image| -> Result<Vec<[f32; 4]>> {
            let bytes = read_image(self.ctx, &self.shot, image, Access::COMPUTE_SAMPLED)?;
            Ok(crate::passes::shadow::decode_rgba16f(&bytes))
        };
        let normal = read(&self.gbuffer.normal)?;
        let tangent = read(&self.gbuffer.tangent)?;
        let scene = self.settings.scene;
        let camera = scene.frame_camera(self.settings.width, self.settings.height);
        let light = scene
            .shade_params(&camera, self.frame_size(), self.height.size())
            .light_dir;
        Ok(crate::passes::shadow::reference_visibility(
            reference,
            hits,
            &normal,
            &tangent,
            [light.x, light.y, light.z],
            scene.depth_scale,
        ))
    }

    /// Renders a frame with the current method and measures it against `reference`
    /// (which must come from the same scene). Returns the times, metrics, hits, colour.
    pub fn measure(&mut self, reference: &FrameReference, frames: u32) -> Result<Measurement> {
        let timings = self.render_frames(frames)?;
        let hits = self.read_hits()?;
        let color = self.read_color()?;
        let mut error =
            metrics::hit_errors(&hits, &reference.hits, &reference.rays, self.map_geometry());
        error.psnr_db = metrics::psnr_rgba8(&color, &reference.color);
        Ok(Measurement {
            timings_ms: timings,
            error,
            hits,
            color,
        })
    }

    /// Map size and depth scale for the metrics.
    pub fn map_geometry(&self) -> MapGeometry {
        let [w, h] = self.height.size();
        MapGeometry {
            map_width: w,
            map_height: h,
            depth_scale: self.settings.scene.depth_scale as f64,
        }
    }
}

/// The result of [`Renderer::measure`].
pub struct Measurement {
    /// Median per-pass milliseconds and `total`.
    pub timings_ms: Vec<(String, f64)>,
    /// Error against the reference.
    pub error: ErrorMetrics,
    /// The hit buffer of the last frame.
    pub hits: Vec<HitTexel>,
    /// The colour image of the last frame.
    pub color: Vec<u8>,
}

impl Drop for Renderer<'_> {
    fn drop(&mut self) {
        let ctx = self.ctx;
        // SAFETY: every submission was waited for; idle makes sure of it on error paths.
        unsafe {
            let _ = ctx.device().device_wait_idle();
        }
        if let Some(stage) = &mut self.shadow {
            stage.destroy(ctx);
        }
        self.extras.destroy(ctx);
        if let Some(d) = &mut self.depth {
            d.destroy(ctx);
        }
        if let Some(m) = &mut self.mesh {
            m.destroy(ctx);
        }
        if let Some(m) = &mut self.material {
            m.destroy(ctx);
        }
        self.shade.destroy(ctx);
        self.trace.destroy(ctx);
        self.gbuffer_pass.destroy(ctx);
        self.color.destroy(ctx);
        self.hit.destroy(ctx);
        self.gbuffer.destroy(ctx);
        self.height.destroy(ctx);
        self.timer.destroy(ctx);
        self.shot.destroy(ctx);
    }
}

/// The renderer's parts while it is being built; destroys the built ones if a later
/// step fails.
struct Parts<'a> {
    ctx: &'a Context,
    shot: Option<OneShot>,
    timer: Option<GpuTimer>,
    height: Option<HeightTexture>,
    gbuffer: Option<GBuffer>,
    hit: Option<Image>,
    color: Option<Image>,
    gbuffer_pass: Option<GBufferPass>,
    trace: Option<TracePass>,
    shade: Option<ShadePass>,
    mesh: Option<MeshBuffers>,
    material: Option<MaterialTextures>,
}

impl Drop for Parts<'_> {
    fn drop(&mut self) {
        let ctx = self.ctx;
        if let Some(m) = &mut self.mesh {
            m.destroy(ctx);
        }
        if let Some(m) = &mut self.material {
            m.destroy(ctx);
        }
        if let Some(p) = &mut self.shade {
            p.destroy(ctx);
        }
        if let Some(p) = &mut self.trace {
            p.destroy(ctx);
        }
        if let Some(p) = &mut self.gbuffer_pass {
            p.destroy(ctx);
        }
        if let Some(i) = &mut self.color {
            i.destroy(ctx);
        }
        if let Some(i) = &mut self.hit {
            i.destroy(ctx);
        }
        if let Some(g) = &mut self.gbuffer {
            g.destroy(ctx);
        }
        if let Some(h) = &mut self.height {
            h.destroy(ctx);
        }
        if let Some(t) = &mut self.timer {
            t.destroy(ctx);
        }
        if let Some(s) = &mut self.shot {
            s.destroy(ctx);
        }
    }
}
