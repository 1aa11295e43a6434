//! The `gbuffer` pass: rasterises the macro geometry into the attachments the later
//! passes read.
//!
//! | attachment | format | contents |
//! |---|---|---|
//! | `ray` | `R32G32B32A32_SFLOAT` | entry `uv0` (tile-local for repeat addressing) and parallax vector `P` |
//! | `frame` | `R32G32_UINT` | world normal `N` (octahedral, 2 x 14 bits), world tangent `T = dP/du` (its angle about `N`, 13 bits), handedness (`B = ±N x T`), material + 1 (11 bits; 0: not displaced), surface id (11 bits): [`frame`] packs and unpacks it, as `glsl/include/dispmap_gbuffer.glsl` does |
//! | `depth` | `D32_SFLOAT` | reverse-Z depth, cleared to 0: 0 means no geometry |
//! | `curve` | `R16G16_SFLOAT` | only for frames with materials traced curved: the normal curvature along the pixel's ray in units of the depth and the depth's change along it (`dispmap_gbuffer_curve` in `glsl/include/dispmap_gbuffer.glsl`), cleared to 0 |
//!
//! The surface id names a piece of geometry whose UVs are continuous (a chart). DIG
//! trusts a block's corner interval only when the block's corners and the pixel share
//! one id. The plane and the quad are one surface (id 1): the tiled plane's wrap of `uv0`
//! into `[0, 1)` is not a discontinuity, since the addressing repeats the map. Meshes
//! (`src/mesh.rs`) carry their ids per vertex: the cube's six faces are ids 1 to 6.
//!
//! On the plane and the quad the entry (`uv0`, the position `P` and the depth derive from)
//! is each pixel's own centre ray met with the surface in double-float arithmetic
//! (`dispmap_plane_pixel_ray` in `glsl/include/dispmap_plane.glsl`), from the frame's
//! [`PixelRayParams`] in a uniform buffer the plane pipeline owns (`PixelRayBlock`; the
//! push constants are full) and writes in each recording; the vertices only decide
//! coverage, and a fragment whose centre ray misses the surface is discarded. Meshes
//! interpolate their vertices' attributes.
//!
//! `record` expects every attachment in `COLOR_ATTACHMENT_OPTIMAL` /
//! `DEPTH_ATTACHMENT_OPTIMAL` (contents may be discarded: it clears them) and leaves them
//! there, written.

pub mod frame;

use crate::abi::{GBufferParams, PixelRayParams};
use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{RasterDesc, RasterSet, raster_pipeline_culled};
use crate::gpu::sync::Access;
use crate::gpu::track::{Handle, Tracker};
use crate::gpu::{HostView, Image};
use crate::passes::pixel_ray_buffer::PixelRayBuffer;
use crate::shaders;
use ash::vk;

/// One pixel's ray as read back from the G-buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Entry point (the macro surface, `h = 1`) in UV units.
    pub uv0: [f64; 2],
    /// Parallax vector: the UV offset after descending the full depth (to `h = 0`).
    pub parallax: [f64; 2],
}

/// Format of the `ray` attachment.
pub const RAY_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
/// Format of the `frame` attachment (normal, tangent, handedness, material, surface id).
pub const FRAME_FORMAT: vk::Format = vk::Format::R32G32_UINT;
/// Format of the depth attachment.
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;
/// Format of the optional `curve` attachment (the curved trace's input).
pub const CURVE_FORMAT: vk::Format = vk::Format::R16G16_SFLOAT;

/// The views of a G-buffer the compute passes read (dispmap's own [`GBuffer`] or a host
/// engine's images with the same formats and meaning, see the module docs), each with the
/// format, size and usage the pass checks ([`GBufferViews::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GBufferViews {
    /// `uv0.xy, P.xy` ([`RAY_FORMAT`]).
    pub ray: HostView,
    /// Normal, tangent, handedness, material and surface id ([`FRAME_FORMAT`]).
    pub frame: HostView,
    /// Reverse-Z depth, 0 = no geometry ([`DEPTH_FORMAT`], a depth-aspect view).
    pub depth: HostView,
    /// The curve of each pixel ([`CURVE_FORMAT`], `dispmap_gbuffer_curve`): required by
    /// the curved trace (a material traced curved,
    /// [`crate::embed::DisplacementPass::set_material_curved`]), read by nothing else;
    /// `None` for a frame without one.
    pub curve: Option<HostView>,
    /// Frame size in pixels (every image's size).
    pub extent: vk::Extent2D,
}

impl GBufferViews {
    /// Checks each image's format, `SAMPLED` usage and size against the contract and
    /// `extent` (the pass's frame size); the error names the image (`gbuffer.ray`, ...).
    pub fn check(&self, extent: vk::Extent2D) -> crate::error::Result<()> {
        let sampled = vk::ImageUsageFlags::SAMPLED;
        self.ray
            .check("gbuffer.ray", &[RAY_FORMAT], sampled, extent)?;
        self.frame
            .check("gbuffer.frame", &[FRAME_FORMAT], sampled, extent)?;
        if let Some(curve) = &self.curve {
            curve.check("gbuffer.curve", &[CURVE_FORMAT], sampled, extent)?;
        }
        self.depth
            .check("gbuffer.depth", &[DEPTH_FORMAT], sampled, extent)
    }
}

/// The G-buffer images of one frame size.
pub struct GBuffer {
    /// `uv0.xy, P.xy`.
    pub ray: Image,
    /// Normal, tangent, handedness, material and surface id ([`frame`]).
    pub frame: Image,
    /// Reverse-Z depth.
    pub depth: Image,
    /// The curve of each pixel, for a frame with curved tracing ([`GBuffer::new_curved`]).
    pub curve: Option<Image>,
}

impl GBuffer {
    /// Creates the three images for a `extent` frame.
    pub fn new(ctx: &Context, extent: vk::Extent2D) -> Result<Self> {
        Self::build(ctx, extent, false)
    }

    /// Creates the three images and the curve image (drawn by pipelines built with
    /// `curve`, [`GBufferPass::new_layer`]) for a `extent` frame.
    pub fn new_curved(ctx: &Context, extent: vk::Extent2D) -> Result<Self> {
        Self::build(ctx, extent, true)
    }

    fn build(ctx: &Context, extent: vk::Extent2D, curve: bool) -> Result<Self> {
        use crate::gpu::owned::Guard;
        let color = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_SRC;
        let image = |name: &str, format: vk::Format, usage: vk::ImageUsageFlags| {
            let image = Image::new(ctx, name, format, extent, 1, usage)?;
            // SAFETY: no command has used the image; it is kept below or destroyed here.
            Ok::<_, crate::error::Error>(unsafe { Guard::new(ctx, image) })
        };
        let ray = image("gbuffer.ray", RAY_FORMAT, color)?;
        let frame = image("gbuffer.frame", FRAME_FORMAT, color)?;
        let curve = if curve {
            Some(image("gbuffer.curve", CURVE_FORMAT, color)?)
        } else {
            None
        };
        let depth = image(
            "gbuffer.depth",
            DEPTH_FORMAT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        )?;
        Ok(GBuffer {
            ray: ray.keep(),
            frame: frame.keep(),
            depth: depth.keep(),
            curve: curve.map(Guard::keep),
        })
    }

    /// The views the compute passes bind.
    pub fn views(&self) -> GBufferViews {
        GBufferViews {
            ray: self.ray.host_view(),
            frame: self.frame.host_view(),
            depth: self.depth.host_view(),
            curve: self.curve.as_ref().map(Image::host_view),
            extent: self.ray.extent,
        }
    }

    /// The contract's colour attachments in location order (ray, frame; the curve image,
    /// when there is one, is the third: [`GBuffer::attachments`]).
    pub fn colors(&self) -> [&Image; 2] {
        [&self.ray, &self.frame]
    }

    /// Every colour attachment in location order: [`GBuffer::colors`], then the curve
    /// image when there is one.
    pub fn attachments(&self) -> Vec<&Image> {
        let mut c = self.colors().to_vec();
        c.extend(self.curve.as_ref());
        c
    }

    /// Its images enter `t`: the colour attachments in `color`, the depth in `depth`
    /// (e.g. discarded, or a host's state after its last frame).
    pub fn enter(&self, t: &mut Tracker<Handle>, color: Access, depth: Access) {
        for image in self.attachments() {
            t.enter(Handle::image(image), color);
        }
        t.enter(Handle::image(&self.depth), depth);
    }

    /// Declares the colour attachments accessed as `color` and the depth as `depth` (e.g.
    /// attachment writes for the G-buffer pass, compute sampled reads after it).
    pub fn declare(&self, t: &mut Tracker<Handle>, color: Access, depth: Access) -> Result<()> {
        for image in self.attachments() {
            t.declare(Handle::image(image), color)?;
        }
        t.declare(Handle::image(&self.depth), depth)
    }
}

impl Destroy for GBuffer {
    /// Destroys the images.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.ray.destroy(ctx);
            self.frame.destroy(ctx);
            self.depth.destroy(ctx);
            self.curve.destroy(ctx);
        }
    }
}

/// The GLSL name of the pixel rays' uniform block (`glsl/gbuffer.frag`,
/// `glsl/forward/forward.glsl`).
pub(crate) const PIXEL_RAYS: &str = "PixelRayBlock";

/// The GLSL names of the behind variant's reads of the first layer
/// (`glsl/gbuffer.frag`, `glsl/gbuffer_mesh.frag` with `BEHIND`).
const FIRST_DEPTH: &str = "u_first_depth";
const FIRST_HIT: &str = "u_first_hit_height";

/// The vertex and fragment shaders of the plane's pipeline (`mesh` false) or the
/// meshes', the fragment stage's `BEHIND` variant for the behind layer, its `CURVE`
/// variant for a G-buffer with the curve image.
fn layer_shaders(mesh: bool, behind: bool, curve: bool) -> (shaders::Shader, shaders::Shader) {
    use shaders::*;
    let frag = match (mesh, behind, curve) {
        (true, false, false) => GBUFFER_MESH_FRAG,
        (true, true, false) => GBUFFER_MESH_FRAG_BEHIND,
        (true, false, true) => GBUFFER_MESH_FRAG_CURVE,
        (true, true, true) => GBUFFER_MESH_FRAG_BEHIND_CURVE,
        (false, false, false) => GBUFFER_FRAG,
        (false, true, false) => GBUFFER_FRAG_BEHIND,
        (false, false, true) => GBUFFER_FRAG_CURVE,
        (false, true, true) => GBUFFER_FRAG_BEHIND_CURVE,
    };
    let vert = match (mesh, curve) {
        (true, false) => GBUFFER_MESH_VERT,
        (true, true) => GBUFFER_MESH_VERT_CURVE,
        (false, _) => GBUFFER_VERT,
    };
    (vert, frag)
}

/// Set 0 of the plane's pipeline (`mesh` false) or the meshes' as the shaders declare it:
/// the plane's pixel rays (a uniform buffer the pass owns and writes in each recording);
/// meshes interpolate and bind nothing; the behind variant (`behind`) also reads the
/// first layer's depth (sampled) and hit height image (a storage image).
pub(crate) fn raster_set(mesh: bool, behind: bool) -> Result<RasterSet> {
    let (vert, frag) = layer_shaders(mesh, behind, false);
    let mut declared = Vec::new();
    if !mesh {
        declared.push((PIXEL_RAYS, vk::DescriptorType::UNIFORM_BUFFER));
    }
    if behind {
        declared.push((FIRST_DEPTH, vk::DescriptorType::COMBINED_IMAGE_SAMPLER));
        declared.push((FIRST_HIT, vk::DescriptorType::STORAGE_IMAGE));
    }
    RasterSet::new(
        &[
            (&vert, vk::ShaderStageFlags::VERTEX),
            (&frag, vk::ShaderStageFlags::FRAGMENT),
        ],
        &declared,
    )
}

/// The graphics pipeline of the G-buffer pass (the plane's also its set layout and the
/// uniform buffer of the frame's pixel rays).
pub struct GBufferPass {
    pipeline: vk::Pipeline,
    /// A mesh pipeline drawing into a G-buffer with the curve image, built for a frame
    /// with draws that do not read it ([`GBufferPass::new_layer_with`]): the same pipeline
    /// writing 0 there without computing the curve (the fragment stage's `CURVE_COMPUTED`
    /// false), for the draws whose material is not traced curved ([`GBufferDraw::curve`]);
    /// null otherwise.
    zero_curve: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    /// Set 0 as the shaders declare it (the plane's pixel rays; empty for meshes).
    set: RasterSet,
    rays: Option<PixelRayBuffer>,
    mesh: bool,
    two_sided: bool,
    /// The behind layer's variant (`BEHIND` in `glsl/gbuffer*.frag`): set 0 also has the
    /// first layer's depth and hit height image.
    behind: bool,
    /// Draws into a G-buffer with the curve image ([`GBuffer::new_curved`]; the
    /// fragment stage's `CURVE` variant).
    curve: bool,
    /// The behind variant's nearest sampler of the first layer's depth (null otherwise).
    sampler: vk::Sampler,
}

impl GBufferPass {
    /// Builds the pipeline of the plane and the quad (dynamic rendering: no render pass
    /// object; no vertex buffer).
    pub fn new(ctx: &Context) -> Result<Self> {
        Self::new_layer(ctx, false, false, false, false)
    }

    /// Builds the pipeline of meshes (`glsl/gbuffer_mesh.*`): one vertex buffer of
    /// [`crate::mesh::Vertex`] and `u32` indices, drawn by [`GBufferPass::record_mesh`].
    pub fn new_mesh(ctx: &Context) -> Result<Self> {
        Self::new_layer(ctx, true, false, false, false)
    }

    /// As [`GBufferPass::new_mesh`] for two-sided meshes ([`crate::mesh::Mesh::two_sided`]):
    /// a fragment on the side the mesh's normals point away from is displaced as seen from
    /// that side (its normal reversed, `dispmap_surface_back_side` in
    /// `glsl/include/dispmap_gbuffer.glsl`) instead of discarded. The same shader with its
    /// `TWO_SIDED` specialization constant set; built only for a frame that draws such a
    /// mesh.
    pub fn new_mesh_two_sided(ctx: &Context) -> Result<Self> {
        Self::new_layer(ctx, true, true, false, false)
    }

    /// The behind layer's pipeline of the same kind as [`GBufferPass::new`] (`mesh`
    /// false), [`GBufferPass::new_mesh`] or [`GBufferPass::new_mesh_two_sided`]: the
    /// fragment stage's `BEHIND` variant keeps a fragment only at a pixel whose
    /// first-layer trace missed, behind the first layer's surface
    /// (`glsl/include/dispmap_behind.glsl`); drawn by [`record_draws_behind`].
    pub fn new_behind(ctx: &Context, mesh: bool, two_sided: bool) -> Result<Self> {
        Self::new_layer(ctx, mesh, two_sided, true, false)
    }

    /// Whether this is a behind layer's pipeline ([`GBufferPass::new_behind`]).
    pub fn is_behind(&self) -> bool {
        self.behind
    }

    /// Whether this is the mesh pipeline.
    pub fn is_mesh(&self) -> bool {
        self.mesh
    }

    /// Whether this is the two-sided mesh pipeline.
    pub fn is_two_sided(&self) -> bool {
        self.two_sided
    }

    /// The pipeline of any kind: the plane's or the meshes' (`mesh`), one-sided or
    /// two-sided (`two_sided`, meshes only), the first layer's or the behind layer's
    /// (`behind`), drawing into a G-buffer with the curve image or without (`curve`:
    /// [`GBuffer::new_curved`], the fragment stage's `CURVE` variant, which writes the
    /// curvature the curved trace reads).
    pub fn new_layer(
        ctx: &Context,
        mesh: bool,
        two_sided: bool,
        behind: bool,
        curve: bool,
    ) -> Result<Self> {
        Self::new_layer_with(ctx, mesh, two_sided, behind, curve, false)
    }

    /// [`GBufferPass::new_layer`]; a mesh pipeline with the curve image (`curve`) also
    /// builds, with `zero_curve`, its twin that writes 0 there without computing it, for
    /// the draws whose material is not traced curved ([`GBufferDraw::curve`]; without the
    /// twin such a draw computes the curve, which nothing reads).
    pub(crate) fn new_layer_with(
        ctx: &Context,
        mesh: bool,
        two_sided: bool,
        behind: bool,
        curve: bool,
        zero_curve: bool,
    ) -> Result<Self> {
        let two_sided = two_sided && mesh;
        let dev = ctx.device();
        let name = format!(
            "{}{}{}",
            match (mesh, two_sided) {
                (false, _) => "gbuffer",
                (true, false) => "gbuffer_mesh",
                (true, true) => "gbuffer_mesh_two_sided",
            },
            if behind { "_behind" } else { "" },
            if curve { "_curve" } else { "" }
        );
        let name = name.as_str();
        let (vert, frag) = layer_shaders(mesh, behind, curve);
        let set = raster_set(mesh, behind)?;
        // The mesh fragment stage's specialization constants' ids (read before anything
        // is built: an error leaves nothing to free).
        let mut ids = Vec::new();
        for name in ["TWO_SIDED", "CURVE_COMPUTED"] {
            ids.push(frag.spec_constant_id(name)?);
        }
        let has_set = !set.is_empty();
        let (set_layout, rays) = if !has_set {
            (vk::DescriptorSetLayout::null(), None)
        } else if mesh {
            (set.set_layout(ctx, &format!("{name}.set_layout"))?, None)
        } else {
            // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
            let rays = unsafe {
                crate::gpu::owned::Guard::new(
                    ctx,
                    PixelRayBuffer::new(ctx, &format!("{name}.pixel_rays"))?,
                )
            };
            let set_layout = set.set_layout(ctx, &format!("{name}.set_layout"))?;
            (set_layout, Some(rays.keep()))
        };
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)
            .size(std::mem::size_of::<GBufferParams>() as u32)];
        let set_layouts = [set_layout];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts[..usize::from(has_set)])
            .push_constant_ranges(&ranges);
        let mut owned = GBufferPass {
            pipeline: vk::Pipeline::null(),
            zero_curve: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layout,
            set,
            rays,
            mesh,
            two_sided,
            behind,
            curve,
            sampler: vk::Sampler::null(),
        };
        if behind {
            owned.sampler = match crate::gpu::pipeline::sampler(
                ctx,
                &format!("{name}.fetch_sampler"),
                vk::Filter::NEAREST,
                vk::SamplerAddressMode::CLAMP_TO_EDGE,
            ) {
                Ok(s) => s,
                Err(e) => {
                    // SAFETY: built above and never used by a command.
                    unsafe { owned.destroy(ctx) };
                    return Err(e);
                }
            };
        }
        // SAFETY: valid device and create info.
        owned.layout = match unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")
        {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { owned.destroy(ctx) };
                return Err(e);
            }
        };
        let layout = owned.layout;
        let bindings = [vk::VertexInputBindingDescription {
            binding: 0,
            stride: std::mem::size_of::<crate::mesh::Vertex>() as u32,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attributes = crate::mesh::vertex_attributes();
        // The uv scale (the last attribute) only for the CURVE variant, which reads it.
        let read = if curve {
            attributes.len()
        } else {
            attributes.len() - 1
        };
        let (vertex_bindings, vertex_attributes): (&[_], &[_]) = if mesh {
            (&bindings, &attributes[..read])
        } else {
            (&[], &[])
        };
        // The mesh fragment stage's TWO_SIDED and CURVE_COMPUTED (32-bit bools), by the
        // ids the SPIR-V gives them (a variant may leave one out).
        let bool_size = std::mem::size_of::<vk::Bool32>();
        let entries: Vec<_> = (0u32..)
            .zip(&ids)
            .filter_map(|(i, id)| {
                id.map(|constant_id| vk::SpecializationMapEntry {
                    constant_id,
                    offset: i * bool_size as u32,
                    size: bool_size,
                })
            })
            .collect();
        let build = |computed: bool, suffix: &str| {
            let values: Vec<u8> = [two_sided, computed]
                .iter()
                .flat_map(|&b| vk::Bool32::from(b).to_ne_bytes())
                .collect();
            let spec = vk::SpecializationInfo::default()
                .map_entries(&entries)
                .data(&values);
            raster_pipeline_culled(
                ctx,
                &RasterDesc {
                    vert: &vert,
                    frag: &frag,
                    layout,
                    vertex_bindings,
                    vertex_attributes,
                    depth_compare: vk::CompareOp::GREATER,
                    color_formats: &[RAY_FORMAT, FRAME_FORMAT, CURVE_FORMAT]
                        [..2 + usize::from(curve)],
                    depth_format: DEPTH_FORMAT,
                    name: &format!("{name}{suffix}.pipeline"),
                },
                mesh.then_some(&spec),
                // A one-sided mesh's faces turned away are discarded by the fragment shader
                // anyway: culled before they are shaded.
                mesh && !two_sided,
            )
        };
        owned.pipeline = match build(true, "") {
            Ok(p) => p,
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { owned.destroy(ctx) };
                return Err(e);
            }
        };
        if mesh && curve && zero_curve {
            owned.zero_curve = match build(false, "_zero_curve") {
                Ok(p) => p,
                Err(e) => {
                    // SAFETY: built above and never used by a command.
                    unsafe { owned.destroy(ctx) };
                    return Err(e);
                }
            };
        }
        ctx.set_name(layout, &format!("{name}.layout"));
        Ok(owned)
    }

    /// Records the pass: clears the G-buffer and draws the plane (a grid about the eye,
    /// [`GBufferParams::plane_cells`]) or the quad (two triangles), generated in the
    /// vertex shader ([`GBufferParams::vertex_count`] vertices, by `dispmap_plane_vertex`
    /// in `glsl/include/dispmap_plane.glsl`, which a host engine may use to draw the
    /// same plane). Needs the pipeline of
    /// [`GBufferPass::new`].
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance (the pass begins and ends its own dynamic rendering), for a
    ///   queue of the context's queue family.
    /// * When the command buffer executes, `target`'s colour images are in
    ///   `COLOR_ATTACHMENT_OPTIMAL` and its depth image in `DEPTH_ATTACHMENT_OPTIMAL`,
    ///   earlier accesses ordered before the attachment writes (the caller's barriers;
    ///   the contents are cleared).
    /// * `target` and this pass stay alive until the command buffer has executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        target: &GBuffer,
        params: &GBufferParams,
        rays: &PixelRayParams,
    ) -> Result<()> {
        debug_assert!(!self.mesh, "the mesh pipeline draws with record_mesh");
        // SAFETY: this function's # Safety contract is `record_draw`'s without a mesh.
        unsafe { self.record_draw(ctx, cmd, target, params, None, rays) }
    }

    /// Records the pass: clears the G-buffer and draws `mesh` (its buffers must stay
    /// alive until the command buffer has executed). Needs [`GBufferPass::new_mesh`].
    ///
    /// # Safety
    /// As [`GBufferPass::record`]; in addition `mesh`'s buffers stay alive until the
    /// command buffer has executed.
    pub unsafe fn record_mesh(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        target: &GBuffer,
        params: &GBufferParams,
        mesh: &crate::mesh::MeshBuffers,
    ) -> Result<()> {
        debug_assert!(self.mesh, "the plane pipeline draws with record");
        // SAFETY: this function's # Safety contract is `record_draw`'s with a mesh (which
        // reads no pixel rays).
        unsafe {
            self.record_draw(
                ctx,
                cmd,
                target,
                params,
                Some(mesh),
                &PixelRayParams::default(),
            )
        }
    }

    /// # Safety
    /// As [`GBufferPass::record`], and [`GBufferPass::record_mesh`] with a mesh.
    unsafe fn record_draw(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        target: &GBuffer,
        params: &GBufferParams,
        mesh: Option<&crate::mesh::MeshBuffers>,
        rays: &PixelRayParams,
    ) -> Result<()> {
        let draw = GBufferDraw {
            pass: self,
            params: *params,
            mesh,
            curve: true,
        };
        // SAFETY: this function's # Safety contract is `record_draws`'s for one draw.
        unsafe { record_draws(ctx, cmd, target, std::slice::from_ref(&draw), rays) }
    }
}

impl Destroy for GBufferPass {
    /// Destroys the pipeline, its layouts and the pixel-ray buffer. The GPU must be done
    /// with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            ctx.device().destroy_pipeline(self.pipeline, None);
            ctx.device().destroy_pipeline(self.zero_curve, None);
            self.zero_curve = vk::Pipeline::null();
            ctx.device().destroy_pipeline_layout(self.layout, None);
            ctx.device()
                .destroy_descriptor_set_layout(self.set_layout, None);
            ctx.device().destroy_sampler(self.sampler, None);
            self.sampler = vk::Sampler::null();
            self.pipeline = vk::Pipeline::null();
            self.layout = vk::PipelineLayout::null();
            self.set_layout = vk::DescriptorSetLayout::null();
            if let Some(mut rays) = self.rays.take() {
                rays.destroy(ctx);
            }
        }
    }
}

/// One object of [`record_draws`]: the pipeline (the plane's, [`GBufferPass::new`], with
/// no mesh; the meshes', [`GBufferPass::new_mesh`], with one), its push constants (each
/// object its own material in `camera_pos.w`, depth scale and addressing) and its mesh.
pub struct GBufferDraw<'a> {
    /// The pipeline.
    pub pass: &'a GBufferPass,
    /// The object's push constants.
    pub params: GBufferParams,
    /// The object's vertex and index buffers (mesh pipeline only).
    pub mesh: Option<&'a crate::mesh::MeshBuffers>,
    /// Whether its fragments compute the curve output (its material is traced curved).
    /// `false` writes 0 in a G-buffer's curve image without computing it, where nothing
    /// reads it (a mesh drawn into a G-buffer with the curve image: a flat object, a
    /// material traced as tangent planes); no effect without the curve image.
    pub curve: bool,
}

/// Records the G-buffer pass of several objects: clears the G-buffer once and draws every
/// object in order into it (one rendering instance; the depth test keeps the nearest).
/// `rays` are the frame's pixel rays ([`crate::scene::FrameCamera::pixel_ray_params`]),
/// which the plane's draws read: written into each plane pipeline's buffer in the
/// command buffer before the rendering begins.
///
/// # Safety
/// As [`GBufferPass::record`] for `target`; every draw's pass and mesh buffers stay alive
/// until the command buffer has executed, and a draw has a mesh exactly when its pass is
/// the mesh pipeline.
pub unsafe fn record_draws(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    target: &GBuffer,
    draws: &[GBufferDraw<'_>],
    rays: &PixelRayParams,
) -> Result<()> {
    // SAFETY: this function's # Safety contract.
    unsafe { record_layer(ctx, cmd, target, draws, rays, None, None, None) }
}

/// What the behind layer's draws read of the first layer: its G-buffer depth (sampled,
/// `SHADER_READ_ONLY_OPTIMAL`) and its hit height image (a storage image read, `GENERAL`).
#[derive(Clone, Copy, Debug)]
pub struct FirstLayer {
    /// The first layer's `D32_SFLOAT` depth view.
    pub depth: vk::ImageView,
    /// The first layer's hit height view (`R32_SFLOAT`).
    pub hit_height: vk::ImageView,
}

/// Records the behind layer ([`GBufferPass::new_behind`], `glsl/include/dispmap_behind.glsl`)
/// into `target`: as [`record_draws`], every draw's pass a behind pipeline, each fragment
/// kept only at a pixel whose first-layer trace missed and behind the first layer's
/// surface.
///
/// # Safety
/// As [`record_draws`]; in addition, when the command buffer executes, `first.depth` is
/// in `SHADER_READ_ONLY_OPTIMAL` and `first.hit_height` in `GENERAL`, their writes visible to
/// fragment-shader sampled and storage reads, and both stay alive until it has executed.
pub unsafe fn record_draws_behind(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    target: &GBuffer,
    draws: &[GBufferDraw<'_>],
    rays: &PixelRayParams,
    first: FirstLayer,
) -> Result<()> {
    // SAFETY: this function's # Safety contract.
    unsafe { record_layer(ctx, cmd, target, draws, rays, Some(first), None, None) }
}

/// As [`record_draws_behind`], the objects' raster kept to the pixels whose first-layer
/// trace missed by `mask` ([`crate::passes::behind_mask`]): the same G-buffer, the
/// objects' fragments elsewhere rejected by the depth test before fragment shading.
///
/// # Safety
/// As [`record_draws_behind`]; `mask` stays alive until the command buffer has executed.
pub unsafe fn record_draws_behind_masked(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    target: &GBuffer,
    draws: &[GBufferDraw<'_>],
    rays: &PixelRayParams,
    first: FirstLayer,
    mask: &crate::passes::behind_mask::BehindMaskPass,
) -> Result<()> {
    // SAFETY: this function's # Safety contract.
    unsafe { record_layer(ctx, cmd, target, draws, rays, Some(first), Some(mask), None) }
}

/// The indirect commands a culled behind layer draws with
/// ([`crate::passes::behind_tiles`]): per draw of the layer, in order, the range
/// `(first, count)` of its commands, command `c` at `offset + c * stride` of `buffer` (a
/// `VkDrawIndexedIndirectCommand` for a mesh, a `VkDrawIndirectCommand` for the plane).
#[derive(Clone, Copy, Debug)]
pub(crate) struct IndirectDraws<'a> {
    /// The buffer of the commands (`INDIRECT_BUFFER` usage).
    pub buffer: vk::Buffer,
    /// The offset of command 0.
    pub offset: u64,
    /// The bytes between commands.
    pub stride: u64,
    /// Per draw, its commands.
    pub ranges: &'a [(u32, u32)],
    /// The listed tiles opened first ([`crate::passes::behind_open`]): the layer's depth
    /// cleared to [`crate::passes::behind_mask::BLOCK_DEPTH`] and its colours left
    /// uncleared, the listed tiles then written with the clear values, so the objects
    /// draw only there. `None`: every attachment cleared.
    pub open: Option<(
        &'a crate::passes::behind_open::BehindOpenPass,
        crate::passes::behind_open::OpenTiles,
    )>,
}

/// As [`record_draws_behind`] (with `mask`, [`record_draws_behind_masked`]), each draw
/// recorded as its range of indirect commands in `indirect` (the same triangles in the
/// same order, split into pieces; a piece whose command has no vertices draws nothing).
/// With `indirect.open`, only its listed tiles are cleared and drawn: outside them the
/// depth is [`crate::passes::behind_mask::BLOCK_DEPTH`] and the colours undefined.
///
/// # Safety
/// As [`record_draws_behind`] (and `_masked`); the commands were written before and made
/// visible to indirect reads (the caller's barrier), their first index (or vertex) and
/// count inside each draw's own, and `indirect.buffer` stays alive until the command
/// buffer has executed; as [`crate::passes::behind_open::BehindOpenPass::record`] for
/// `indirect.open`.
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn record_draws_behind_culled(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    target: &GBuffer,
    draws: &[GBufferDraw<'_>],
    rays: &PixelRayParams,
    first: FirstLayer,
    mask: Option<&crate::passes::behind_mask::BehindMaskPass>,
    indirect: IndirectDraws<'_>,
) -> Result<()> {
    if indirect.ranges.len() != draws.len() {
        return Err(crate::error::Error::Internal(
            "one range of indirect commands per behind draw".into(),
        ));
    }
    // SAFETY: this function's # Safety contract.
    unsafe {
        record_layer(
            ctx,
            cmd,
            target,
            draws,
            rays,
            Some(first),
            mask,
            Some(indirect),
        )
    }
}

/// [`record_draws`] (`first` `None`), [`record_draws_behind`] or (with `mask`)
/// [`record_draws_behind_masked`]; with `indirect`, [`record_draws_behind_culled`].
///
/// # Safety
/// As those.
#[allow(clippy::too_many_arguments)]
unsafe fn record_layer(
    ctx: &Context,
    cmd: vk::CommandBuffer,
    target: &GBuffer,
    draws: &[GBufferDraw<'_>],
    rays: &PixelRayParams,
    first: Option<FirstLayer>,
    mask: Option<&crate::passes::behind_mask::BehindMaskPass>,
    indirect: Option<IndirectDraws<'_>>,
) -> Result<()> {
    use crate::passes::behind_mask::{BLOCK_DEPTH, CLEAR_DEPTH};
    let mask = match (mask, first) {
        (Some(m), Some(f)) => Some((m, f)),
        _ => None,
    };
    let extent = target.ray.extent;
    if let Some(d) = draws
        .iter()
        .find(|d| d.pass.curve != target.curve.is_some())
    {
        return Err(crate::error::Error::invalid(
            "G-buffer draws",
            format!(
                "a pipeline {} the curve image drawn into a G-buffer {} it",
                if d.pass.curve { "with" } else { "without" },
                if target.curve.is_some() {
                    "with"
                } else {
                    "without"
                }
            ),
        ));
    }
    // Each plane pipeline's pixel-ray buffer, once.
    let mut updated: Vec<*const GBufferPass> = Vec::new();
    for draw in draws {
        if let Some(buffer) = &draw.pass.rays
            && !updated.contains(&std::ptr::from_ref(draw.pass))
        {
            updated.push(std::ptr::from_ref(draw.pass));
            // SAFETY: this function's # Safety contract: `cmd` is recording outside a
            // render pass; the pass (and its buffer) outlives the command buffer.
            unsafe { buffer.record_update(ctx, cmd, rays)? };
        }
    }
    if let Some((m, _)) = mask
        && m.has_curve() != target.curve.is_some()
    {
        return Err(crate::error::Error::Internal(
            "the behind mask's pipeline and the G-buffer differ on the curve image".into(),
        ));
    }
    let open = indirect.and_then(|i| i.open);
    if let Some((pass, _)) = open
        && pass.has_curve() != target.curve.is_some()
    {
        return Err(crate::error::Error::Internal(
            "the listed tiles' pipeline and the G-buffer differ on the curve image".into(),
        ));
    }
    // Opened tiles: the colours are written there before anything reads them (and read
    // nowhere else), the depth blocks every other pixel. The curve image is never
    // cleared: every fragment drawn writes it, and it is read only at pixels of a
    // material traced curved, which a fragment drew.
    let color_attachments: Vec<_> = target
        .attachments()
        .iter()
        .enumerate()
        .map(|(i, image)| {
            let a = crate::gpu::pipeline::cleared_color_attachment(
                image.view,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                [0.0; 4],
            );
            if open.is_some() || i >= target.colors().len() {
                a.load_op(vk::AttachmentLoadOp::DONT_CARE)
            } else {
                a
            }
        })
        .collect();
    let mut depth_attachment = crate::gpu::pipeline::cleared_depth_attachment(target.depth.view);
    if open.is_some() {
        depth_attachment = depth_attachment.clear_value(vk::ClearValue {
            depth_stencil: vk::ClearDepthStencilValue {
                depth: crate::passes::behind_mask::BLOCK_DEPTH,
                stencil: 0,
            },
        });
    }
    let area = crate::gpu::pipeline::frame_area(extent);
    let rendering = vk::RenderingInfo::default()
        .render_area(area)
        .layer_count(1)
        .color_attachments(&color_attachments)
        .depth_attachment(&depth_attachment);
    // A plane pipeline's pixel rays, bound by the name its shaders give them.
    let infos: Vec<_> = draws
        .iter()
        .map(|d| d.pass.rays.as_ref().map(PixelRayBuffer::info))
        .collect();
    // The behind variant's reads of the first layer, by the names its shaders give them.
    let depth_infos: Vec<_> = draws
        .iter()
        .map(|d| {
            first.map(|f| {
                [vk::DescriptorImageInfo {
                    sampler: d.pass.sampler,
                    image_view: f.depth,
                    image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                }]
            })
        })
        .collect();
    let hit_info = first.map(|f| crate::gpu::pipeline::storage_view(f.hit_height));
    let writes = draws
        .iter()
        .zip(infos.iter().zip(&depth_infos))
        .map(|(d, (info, depth))| {
            let mut w = Vec::new();
            if let Some(i) = info {
                w.push(d.pass.set.buffer(PIXEL_RAYS, i)?);
            }
            if let (Some(depth), Some(hit)) = (depth, &hit_info) {
                w.push(d.pass.set.image(FIRST_DEPTH, depth)?);
                w.push(d.pass.set.image(FIRST_HIT, hit)?);
            }
            Ok(w)
        })
        .collect::<Result<Vec<_>>>()?;
    let dev = ctx.device();
    // SAFETY: this function's # Safety contract: `cmd` is recording; `extent` is the
    // size of attachments `Image::new` created (non-zero, within
    // `maxImageDimension2D`), which the viewport limits cover.
    unsafe { crate::gpu::pipeline::set_frame_viewport(ctx, cmd, extent) };
    // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
    // pass; the attachments are alive and in the layouts documented above (the
    // caller's barriers); a mesh's buffers are alive and match the mesh pipeline's
    // vertex input (`MeshBuffers` holds `Vertex`es and `u32` indices); a plane
    // pipeline's push descriptor is its set 0 (the pixel rays, a uniform buffer the pass
    // owns, written above; the binding the shaders' reflection gives).
    unsafe {
        dev.cmd_begin_rendering(cmd, &rendering);
        if let Some((pass, tiles)) = open {
            // The listed tiles back to the clear values: the objects draw there only.
            pass.record(ctx, cmd, tiles, extent)?;
        }
        if let Some((m, f)) = mask {
            // The pixels the layer leaves empty, blocked for the objects' depth test.
            m.record(ctx, cmd, f, BLOCK_DEPTH)?;
        }
        for (d, (draw, write)) in draws.iter().zip(&writes).enumerate() {
            debug_assert_eq!(draw.pass.mesh, draw.mesh.is_some(), "pipeline vs mesh");
            debug_assert_eq!(
                draw.pass.behind,
                first.is_some(),
                "behind pipeline vs layer"
            );

            let pipeline = if draw.curve || draw.pass.zero_curve == vk::Pipeline::null() {
                draw.pass.pipeline
            } else {
                draw.pass.zero_curve
            };
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, pipeline);
            if !write.is_empty() {
                ctx.push_descriptor().cmd_push_descriptor_set(
                    cmd,
                    vk::PipelineBindPoint::GRAPHICS,
                    draw.pass.layout,
                    0,
                    write,
                );
            }
            dev.cmd_push_constants(
                cmd,
                draw.pass.layout,
                vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                0,
                bytemuck::bytes_of(&draw.params),
            );
            if let Some(m) = draw.mesh {
                dev.cmd_bind_vertex_buffers(cmd, 0, &[m.vertices.raw], &[0]);
                dev.cmd_bind_index_buffer(cmd, m.indices.raw, 0, vk::IndexType::UINT32);
            }
            match (draw.mesh, &indirect) {
                (Some(m), None) => dev.cmd_draw_indexed(cmd, m.index_count, 1, 0, 0, 0),
                (None, None) => dev.cmd_draw(cmd, draw.params.vertex_count(), 1, 0, 0),
                (mesh, Some(i)) => {
                    // The draw's pieces: one multi-draw command where the device has
                    // `multiDrawIndirect` (the same draws in the same order), else one
                    // command each. A CPU driver pays per command: lavapipe spent about
                    // 1 ms on the materials scene's ~960 commands, most of them empty.
                    let (start, count) = i.ranges[d];
                    let (per, commands) = if ctx.multi_draw_indirect() {
                        (count, count.min(1))
                    } else {
                        (1, count)
                    };
                    for c in 0..commands {
                        let at = i.offset + u64::from(start + c) * i.stride;
                        if mesh.is_some() {
                            dev.cmd_draw_indexed_indirect(cmd, i.buffer, at, per, i.stride as u32);
                        } else {
                            dev.cmd_draw_indirect(cmd, i.buffer, at, per, i.stride as u32);
                        }
                    }
                }
            }
        }
        if let Some((m, f)) = mask {
            // Those pixels back to the clear values.
            m.record(ctx, cmd, f, CLEAR_DEPTH)?;
        }
        dev.cmd_end_rendering(cmd);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What each graphics pass binds (the G-buffer's plane and meshes, every method's
    /// forward pass, the depth resolve, the behind mask and listed tiles) is exactly what its shaders declare, numbers and
    /// types reflected from the SPIR-V, and every binding is bound by a name.
    #[test]
    fn graphics_passes_bind_what_their_shaders_declare() {
        let plane = raster_set(false, false).unwrap();
        assert!(!plane.is_empty());
        assert!(raster_set(true, false).unwrap().is_empty());
        for mesh in [false, true] {
            raster_set(mesh, true).unwrap_or_else(|e| panic!("behind, mesh {mesh}: {e}"));
        }
        let mut forward = 0;
        for m in crate::method::Method::ALL {
            if let Some(frag) = m.forward_shader() {
                crate::passes::forward::raster_set(&frag)
                    .unwrap_or_else(|e| panic!("{}: {e}", m.name()));
                forward += 1;
            }
        }
        assert!(forward >= 2, "relief and pom have forward paths");
        crate::passes::depth_resolve::raster_set().unwrap();
        for curve in [false, true] {
            crate::passes::behind_mask::raster_set(curve).unwrap();
        }
        for curve in [false, true] {
            crate::passes::behind_open::raster_set(curve).unwrap();
        }
    }

    /// A binding the shaders lack, or one they type differently, is refused.
    #[test]
    fn a_graphics_binding_the_shaders_lack_is_refused() {
        let stages = [
            (&shaders::GBUFFER_VERT, vk::ShaderStageFlags::VERTEX),
            (&shaders::GBUFFER_FRAG, vk::ShaderStageFlags::FRAGMENT),
        ];
        let ray = (PIXEL_RAYS, vk::DescriptorType::UNIFORM_BUFFER);
        assert!(RasterSet::new(&stages, &[ray]).is_ok());
        assert!(RasterSet::new(&stages, &[]).is_err());
        let extra = ("u_height", vk::DescriptorType::COMBINED_IMAGE_SAMPLER);
        assert!(RasterSet::new(&stages, &[ray, extra]).is_err());
        let retyped = (PIXEL_RAYS, vk::DescriptorType::STORAGE_BUFFER);
        assert!(RasterSet::new(&stages, &[retyped]).is_err());
        // Two stages giving one binding number different names.
        let clash = [
            (&shaders::GBUFFER_FRAG, vk::ShaderStageFlags::VERTEX),
            (&shaders::DEPTH_RESOLVE_FRAG, vk::ShaderStageFlags::FRAGMENT),
        ];
        assert!(RasterSet::new(&clash, &[]).is_err());
    }
}
