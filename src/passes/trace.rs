//! The `trace` pass: runs one method per pixel and writes the hit images.
//!
//! Bindings (set 0, push descriptors), by their GLSL names; `glsl/common/trace.glsl` (and
//! the includes of the methods that read more) give their numbers, which Rust takes from
//! the reflected SPIR-V:
//!
//! | binding | resource | layout on entry |
//! |---|---|---|
//! | `u_ray` | G-buffer `ray` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_depth` | G-buffer `depth` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_height` | height field (bilinear sampler) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_hit_uv` | hit uv image (`R32G32_SFLOAT` storage, written) | `GENERAL` |
//! | `u_hit_height` | hit height image (`R32_SFLOAT` storage, written) | `GENERAL` |
//! | `u_iterations` | iteration counts (`R32_UINT` storage, written; the `ITERATIONS` variant only) | `GENERAL` |
//! | `u_pyramid` | max-height pyramid (methods that need one; `texelFetch` per level) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_corners` | DIG corner grid (`dig`, `dig-guarded`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_curve` | G-buffer `curve` (`R16G16_SFLOAT`; the `CURVED` variant only, [`Method::curved_shader`]) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_walk` | the mesh walk buffer's texel view (`R32G32B32A32_UINT`, [`crate::mesh::walk::WalkMeshes`]; the walk's three steps, [`Method::walks_meshes`]) | host-written before the first submission that reads it |
//! | `u_walk_list` | the walk list ([`walk_list_bytes`]: reset; its first list appended to by the first trace, read and dispatched by the triage; its second appended to by the triage, read and dispatched by the walk) | |
//! | `u_frame` | G-buffer `frame` (the material; the surface id for the DIG corner test and the footprint level's neighbours) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_cone` | cone map (`cone`, `cone-exact`, `relaxed-cone`; `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_tiles` | the material's tile list ([`crate::passes::classify`]) | |
//!
//! A method's pipeline declares `u_pyramid`, `u_corners` and `u_cone` only when its
//! [`Needs`](crate::method::Needs) name them.
//! One dispatch traces one material: a workgroup per tile of its list, an invocation per
//! pixel of the material (others are left alone).
//!
//! A method that walks the pass's meshes ([`Method::walks_meshes`], traced curved, given
//! meshes) traces such a material in four dispatches instead of its curved trace (all
//! [`TracePass::record_walk`]): the first trace over the material's tiles
//! ([`WalkStep::First`]: the flat trace, which lists the pixels it cannot tell from the
//! meshes' convex flat regions are the walk's), the overlap step over those of them whose
//! path in their flat region only passes overlapping flat regions' shells, a cube's edges
//! ([`WalkStep::Overlap`]: those regions' relief along the path), the triage over the
//! others ([`WalkStep::Triage`]: keeps the pixels whose trace is the walk, resolves the
//! flat ones whose path meets only overlapping triangles' shells, lists the rest) and the
//! walk over those ([`WalkStep::Walk`]), the last three indirect dispatches of the lists'
//! own arguments. On a CPU driver, whose lanes run a shader's every instruction in
//! lockstep whether a lane takes its branch or not, each program then costs only the
//! pixels that need it.
//!
//! Each pixel's hit is its `(u, v)` in the hit uv image and its height in the hit height
//! image (`height < 0` means no hit); the pipeline built with iterations
//! ([`TracePass::new`]) also writes the pixel's iteration count (height-field or pyramid
//! fetches) into `u_iterations`.

use crate::abi::{TRACE_FLAG_AUTO_LEVEL, TRACE_FLAG_CURVED, TRACE_FLAG_LOD, TraceParams};
use crate::context::Context;
use crate::error::Error;
use crate::error::Result;
use crate::gpu::HeightTexture;
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::method::{MaxLevel, Method, MethodParams};
use crate::passes::classify::{MaterialTiles, TILES};
use crate::passes::cone::ConeMap;
use crate::passes::dig::CornerGrid;
use crate::passes::gbuffer::GBufferViews;
use crate::passes::pyramid::Pyramid;
use crate::scene::addressing_code;
use ash::vk;

/// One pixel's hit as the read-backs assemble it from the hit images: hit u, hit v
/// (the hit uv image), hit height (the hit height image), iteration count (the iteration
/// image, as `f32`). Height < 0 means no hit.
pub type HitTexel = [f32; 4];

/// Format of the hit uv image: the hit's `u`, `v`.
pub const HIT_UV_FORMAT: vk::Format = vk::Format::R32G32_SFLOAT;

/// Format of the hit height image: the hit's height in `[0, 1]`, `< 0` for no hit.
pub const HIT_HEIGHT_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// Format of the iteration counts (the pass's optional output): 32 bits, since a pixel's
/// count is bounded only by its method's parameters (a level-of-detail blend adds the
/// bump's to the trace's, and only lavapipe caps a loop at 65535).
pub const ITERATIONS_FORMAT: vk::Format = vk::Format::R32_UINT;

/// The hit images of one frame, by view (both of the frame's size, `GENERAL`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HitViews {
    /// The hit uv image ([`HIT_UV_FORMAT`]).
    pub uv: vk::ImageView,
    /// The hit height image ([`HIT_HEIGHT_FORMAT`]).
    pub height: vk::ImageView,
}

/// Splits `hits` (one texel per pixel) into the bytes of the hit uv and hit height images
/// (the iteration counts are dropped).
pub fn split_hits(hits: &[HitTexel]) -> (Vec<u8>, Vec<u8>) {
    let uv: Vec<[f32; 2]> = hits.iter().map(|t| [t[0], t[1]]).collect();
    let height: Vec<f32> = hits.iter().map(|t| t[2]).collect();
    (
        bytemuck::cast_slice(&uv).to_vec(),
        bytemuck::cast_slice(&height).to_vec(),
    )
}

/// Joins the bytes of the hit uv and hit height images and of the iteration counts
/// (`None`: counted as 0) into one texel per pixel.
pub fn join_hits(uv: &[u8], height: &[u8], iterations: Option<&[u8]>) -> Vec<HitTexel> {
    let uv: &[[f32; 2]] = bytemuck::cast_slice(uv);
    let height: &[f32] = bytemuck::cast_slice(height);
    let iterations: Option<&[u32]> = iterations.map(bytemuck::cast_slice);
    uv.iter()
        .zip(height)
        .enumerate()
        .map(|(i, (uv, h))| {
            let n = iterations.map_or(0, |it| it[i]);
            [uv[0], uv[1], *h, n as f32]
        })
        .collect()
}

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;
/// The bindings of `method`'s pipeline (its `needs`; `curved`: its curved variant), by GLSL name.
fn bindings(
    method: Method,
    iterations: bool,
    curved: bool,
) -> Vec<(&'static str, vk::DescriptorType)> {
    let needs = method.needs();
    let mut b = vec![
        ("u_ray", SAMPLED),
        ("u_depth", SAMPLED),
        ("u_height", SAMPLED),
        ("u_hit_uv", STORAGE),
        ("u_hit_height", STORAGE),
        ("u_frame", SAMPLED),
        TILES,
    ];
    if iterations {
        b.push(("u_iterations", STORAGE));
    }
    if curved {
        b.push(("u_curve", SAMPLED));
    }
    if needs.pyramid.is_some() {
        b.push(("u_pyramid", SAMPLED));
    }
    if needs.dig_corners {
        b.push(("u_corners", SAMPLED));
    }
    if needs.cone.is_some() {
        b.push(("u_cone", SAMPLED));
    }
    b
}

/// The bindings of the mesh walk's `step` for `method` (with the iteration output or
/// without):
/// * the first trace ([`Method::walk_first_shader`]): the flat trace's, the walk buffer and
///   the walk list (appended to);
/// * the triage ([`Method::walk_triage_shader`]) and the overlap step
///   ([`Method::walk_overlap_shader`]): the G-buffer, the height field and its pyramid,
///   the hit images (the first trace's hit heights read, the hits the step decides
///   written), the walk buffer and the walk list (its pixels read; the triage appends to
///   the walk's);
/// * the walk ([`Method::walk_shader`]): the flat trace's but the tile list (its pixels
///   come from the walk list), the curve image (the circle model of a pixel on no walked
///   triangle), the walk buffer and the walk list.
fn walk_bindings(
    method: Method,
    iterations: bool,
    step: WalkStep,
) -> Vec<(&'static str, vk::DescriptorType)> {
    let mut b = match step {
        WalkStep::First => bindings(method, iterations, false),
        WalkStep::Triage | WalkStep::Overlap => vec![
            ("u_ray", SAMPLED),
            ("u_depth", SAMPLED),
            ("u_height", SAMPLED),
            ("u_pyramid", SAMPLED),
            ("u_hit_uv", STORAGE),
            ("u_hit_height", STORAGE),
            ("u_frame", SAMPLED),
        ],
        WalkStep::Walk => {
            let mut b = bindings(method, iterations, true);
            b.retain(|&(name, _)| name != TILES.0);
            b
        }
    };
    b.push(("u_walk", vk::DescriptorType::UNIFORM_TEXEL_BUFFER));
    b.push(("u_walk_list", vk::DescriptorType::STORAGE_BUFFER));
    b
}

/// Bytes of the walk list's three headers (`WalkList` in `glsl/common/trace.glsl`): per
/// list, its dispatch's arguments and its count of pixels.
pub const WALK_LIST_HEADER: u64 = 48;

/// The walk list's headers before a walked material's first trace: per list, no
/// workgroup along x, one along y and z, no pixel.
pub const WALK_LIST_RESET: [u32; 12] = [0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 0];

/// Bytes of a walk list for a frame of `extent`: its headers, and two words a pixel (the
/// first trace's two lists, which share one: it lists a pixel in one of them at most, and
/// a material's pixels are at most the frame's; the triage's list).
pub fn walk_list_bytes(extent: vk::Extent2D) -> u64 {
    WALK_LIST_HEADER + 8 * u64::from(extent.width) * u64::from(extent.height)
}

/// The images the trace pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct TraceInputs<'a> {
    /// The G-buffer (ray, depth and frame are read).
    pub gbuffer: GBufferViews,
    /// The height field.
    pub height: &'a HeightTexture,
    /// The hit images (written; the frame's size).
    pub hit: HitViews,
    /// The iteration counts (written; the frame's size): given exactly when the pass was
    /// built with iterations.
    pub iterations: Option<vk::ImageView>,
    /// The frame's size.
    pub extent: vk::Extent2D,
    /// The pyramid, for methods that need one (built, `SHADER_READ_ONLY_OPTIMAL`).
    pub pyramid: Option<&'a Pyramid>,
    /// The DIG corner grid, for `dig` methods (written by this frame's corner pass,
    /// `SHADER_READ_ONLY_OPTIMAL`).
    pub corners: Option<&'a CornerGrid>,
    /// The cone map, for the cone methods (built, `SHADER_READ_ONLY_OPTIMAL`).
    pub cone: Option<&'a ConeMap>,
    /// The material and its tiles.
    pub tiles: MaterialTiles,
    /// Trace curved macro geometry with these pixel rays (`None`: every pixel's base
    /// surface is its tangent plane). Only methods with [`Method::traces_curved`] use it.
    pub curved: Option<TraceView>,
    /// The walk buffer's texel view ([`crate::mesh::walk::WalkMeshes::view`]) of the
    /// meshes the curved trace of a method with [`Method::walks_meshes`] follows; needed
    /// by the walk's dispatches, ignored elsewhere.
    pub walk: Option<vk::BufferView>,
    /// The walk list ([`walk_list_bytes`]): the triage appends the pixels the walk runs
    /// on, and the walk dispatches its arguments; needed by the walk's dispatches, ignored
    /// elsewhere.
    pub walk_list: Option<vk::Buffer>,
}

/// A frame's pixel rays for curved tracing (`glsl/common/curved.glsl`): the eye-relative
/// point of the near plane at the frame's centre and its steps per NDC unit, so that pixel
/// `(x, y)`'s view direction is `origin + ndc.x dx + ndc.y dy` with
/// `ndc = (pixel + 0.5) / frame * 2 - 1` (the unprojection `hit_depth` uses).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceView {
    /// The near-plane point at NDC (0, 0), eye-relative.
    pub origin: glam::Vec3,
    /// Its change per NDC unit along x.
    pub dx: glam::Vec3,
    /// Its change per NDC unit along y.
    pub dy: glam::Vec3,
    /// The eye's world position (the mesh walk's world-space triangles).
    pub eye: glam::Vec3,
}

impl TraceView {
    /// The pixel rays of a frame drawn with `view_proj` (world to clip, reverse-Z) from
    /// `eye`, composed and inverted in f64.
    pub fn new(view_proj: glam::Mat4, eye: glam::Vec3) -> Self {
        let eye_clip = view_proj.as_dmat4() * glam::DMat4::from_translation(eye.as_dvec3());
        let inv = eye_clip.inverse();
        // The near plane is NDC z = 1 (reverse-Z); its points are affine in NDC x, y.
        let at = |x: f64, y: f64| {
            let p = inv * glam::DVec4::new(x, y, 1.0, 1.0);
            p.truncate() / p.w
        };
        let origin = at(0.0, 0.0);
        TraceView {
            origin: origin.as_vec3(),
            dx: (at(1.0, 0.0) - origin).as_vec3(),
            dy: (at(0.0, 1.0) - origin).as_vec3(),
            eye,
        }
    }
}

/// The trace pass of one method.
pub struct TracePass {
    method: Method,
    curved: bool,
    iterations: bool,
    pipeline: FetchPipeline,
    /// The mesh walk's pipelines, one per [`WalkStep`] in its order, for a curved method
    /// with [`Method::walk_shader`] ([`TracePass::record_walk`]).
    walk: Option<Vec<FetchPipeline>>,
}

/// The mesh walk's four dispatches, in their order ([`TracePass::record_walk`]): they
/// replace the curved trace of a material whose meshes the pass walks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WalkStep {
    /// Over the material's tiles: the flat trace, and the pixels whose hit it cannot tell
    /// is the walk's listed.
    First,
    /// Over the pixels the first trace listed whose straight path in their flat region
    /// only passes overlapping flat regions' shells: those regions' relief along it.
    Overlap,
    /// Over the other pixels the first trace listed: keeps, resolves or lists each one.
    Triage,
    /// Over the pixels the triage listed: the walk itself.
    Walk,
}

impl WalkStep {
    /// The steps in their order.
    pub const ALL: [WalkStep; 4] = [
        WalkStep::First,
        WalkStep::Overlap,
        WalkStep::Triage,
        WalkStep::Walk,
    ];

    /// The step's shader for `method` (`None`: the method does not walk meshes).
    fn shader(self, method: Method, iterations: bool) -> Option<crate::shaders::Shader> {
        match self {
            WalkStep::First => method.walk_first_shader(iterations),
            WalkStep::Overlap => method.walk_overlap_shader(),
            WalkStep::Triage => method.walk_triage_shader(),
            WalkStep::Walk => method.walk_shader(iterations),
        }
    }

    /// The byte offset in the walk list of the dispatch arguments of the step's pixels
    /// (`None`: the first trace, over the material's tiles): the triage's are the first
    /// list's, the walk's the second's, the overlap step's the third's.
    fn list_args(self) -> Option<u64> {
        match self {
            WalkStep::First => None,
            WalkStep::Triage => Some(0),
            WalkStep::Walk => Some(16),
            WalkStep::Overlap => Some(32),
        }
    }

    /// Whether the step writes the pixels' iteration counts (the pipeline built with
    /// iterations): the first trace and the walk; the hits the triage and the overlap
    /// step decide keep the first trace's counts.
    fn writes_iterations(self) -> bool {
        matches!(self, WalkStep::First | WalkStep::Walk)
    }

    /// Whether the step reads the G-buffer's curve image: the walk (its circle model for
    /// a pixel on no walked triangle).
    fn reads_curve(self) -> bool {
        self == WalkStep::Walk
    }
}

impl TracePass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// The bindings of the shader of its mesh walk's `step` (`None`: no walk,
    /// [`TracePass::record_walk`]).
    pub fn walk_bindings(
        &self,
        step: WalkStep,
    ) -> Option<&'static [crate::shaders::ShaderBinding]> {
        self.walk
            .as_ref()
            .map(|w| w[step as usize].pipeline.bindings)
    }

    /// Builds the pipeline of `method`: with the curved path ([`TraceInputs::curved`],
    /// which reads the G-buffer's curve image) when `curved` is set and the method traces
    /// curved geometry ([`Method::curved_shader`]), else the flat variant, compiled
    /// without it. With `iterations` it is the shader's `ITERATIONS` variant, which also
    /// writes each pixel's iteration count ([`TraceInputs::iterations`]).
    pub fn new(ctx: &Context, method: Method, curved: bool, iterations: bool) -> Result<Self> {
        let curved = curved && method.traces_curved();
        let name = format!(
            "trace[{}{}{}]",
            method.name(),
            if curved { ",curved" } else { "" },
            if iterations { ",iterations" } else { "" }
        );
        let shader = match (method.curved_shader(iterations), curved, iterations) {
            (Some(s), true, _) => s,
            (_, _, true) => method.iterations_shader(),
            (_, _, false) => method.shader(),
        };
        let mut pipeline = FetchPipeline::specialized(
            ctx,
            &name,
            &shader,
            &bindings(method, iterations, curved),
            std::mem::size_of::<TraceParams>() as u32,
            &[],
        )?;
        let walk = if curved && method.walks_meshes() {
            match Self::walk_pipelines(ctx, &name, method, iterations) {
                Ok(p) => Some(p),
                Err(e) => {
                    // SAFETY: just made, never recorded.
                    unsafe { pipeline.destroy(ctx) };
                    return Err(e);
                }
            }
        } else {
            None
        };
        Ok(TracePass {
            method,
            curved,
            iterations,
            pipeline,
            walk,
        })
    }

    /// The pipelines of `method`'s mesh walk, one per [`WalkStep`] in its order.
    fn walk_pipelines(
        ctx: &Context,
        name: &str,
        method: Method,
        iterations: bool,
    ) -> Result<Vec<FetchPipeline>> {
        let size = std::mem::size_of::<TraceParams>() as u32;
        let mut made: Vec<FetchPipeline> = Vec::with_capacity(WalkStep::ALL.len());
        for step in WalkStep::ALL {
            let made_one = step
                .shader(method, iterations)
                .ok_or_else(|| Error::Internal(format!("{} has no {step:?} step", method.name())))
                .and_then(|shader| {
                    FetchPipeline::specialized(
                        ctx,
                        &format!("{name}.walk.{step:?}").to_lowercase(),
                        &shader,
                        &walk_bindings(method, iterations, step),
                        size,
                        &[],
                    )
                });
            match made_one {
                Ok(p) => made.push(p),
                Err(e) => {
                    // SAFETY: just made, never recorded.
                    unsafe { made.destroy(ctx) };
                    return Err(e);
                }
            }
        }
        Ok(made)
    }

    /// The method this pass runs.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The method and variant (curved, iterations): what a plan keys this pass by.
    pub fn key(&self) -> (Method, bool, bool) {
        (self.method, self.curved, self.iterations)
    }

    /// Whether this is the curved variant (it follows [`TraceInputs::curved`]; the flat
    /// one traces every pixel's tangent plane).
    pub fn curved(&self) -> bool {
        self.curved
    }

    /// Records the dispatch over the material's tiles. Fails (recording nothing) when a
    /// resource the method needs is missing from `inputs`.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `inputs`' views belong to that device and have the formats and usages of the
    ///   module's table; the hit images, the iteration image and the G-buffer are of
    ///   `inputs.extent`, the
    ///   corner grid (if any) was made for it.
    /// * When the command buffer executes, the images are in the layouts of the module's
    ///   table: the G-buffer, `height`, the pyramid, the corner grid and the cone map in
    ///   `SHADER_READ_ONLY_OPTIMAL`, their writes visible to compute-shader sampled
    ///   reads; the hit images (and iteration image) in `GENERAL`, earlier accesses ordered before
    ///   compute-shader storage writes (the caller's barriers); the tile list written by a
    ///   `classify` recorded before in the same command buffer.
    /// * The images behind `inputs` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: TraceInputs,
        params: &MethodParams,
        depth_scale: f32,
    ) -> Result<()> {
        // SAFETY: this function's contract, passed on.
        unsafe { self.record_on(None, ctx, cmd, inputs, params, depth_scale) }
    }

    /// Records one of the mesh walk's dispatches, which together replace
    /// [`TracePass::record`]'s curved trace (nothing when the pass has no walk,
    /// [`TracePass::walk_bindings`]), in their order, each after a barrier the caller
    /// records. Fails (recording nothing) when `inputs` lacks the walk buffer, the walk
    /// list or the view ([`TraceInputs::curved`]).
    ///
    /// * [`WalkStep::First`], over the material's tiles: the method's flat trace into the
    ///   hit images (and iteration counts), appending to the walk list's first list the
    ///   pixels where it cannot tell from the walk buffer's flat regions that the hit is
    ///   the walk's (to the third those whose path in their flat region only passes
    ///   overlapping flat regions' shells, to the second those whose path leaves their
    ///   region and those of surfaces without a flat triangle), and counting their
    ///   workgroups in the lists' headers; the caller reset the headers to
    ///   [`WALK_LIST_RESET`] before it.
    /// * [`WalkStep::Overlap`], an indirect dispatch of the third list's arguments over its
    ///   pixels: writes the hits in the overlapping regions' relief it finds before the
    ///   first trace's (`glsl/trace/exact.comp`'s `OVERLAP` variant), and appends to the
    ///   second list a pixel whose part of a region is a long ray in texel space.
    /// * [`WalkStep::Triage`], an indirect dispatch of the first list's arguments over its
    ///   pixels: keeps the first trace's hits (reading its hit heights) where they are the
    ///   walk's, writes those it resolves, and appends the other pixels to the second list.
    /// * [`WalkStep::Walk`], an indirect dispatch of the second list's arguments over its
    ///   pixels: rewrites their hits (`glsl/trace/exact.comp`'s `WALK` variant; the curved
    ///   trace's circle model for a pixel on no walked triangle).
    ///
    /// A level-of-detail blend ([`MethodParams::lod_threshold`]) keeps the curved trace
    /// ([`TracePass::record`]) and no walk.
    ///
    /// # Safety
    /// As [`TracePass::record`], and when the command buffer executes: the walk buffer
    /// holds [`crate::mesh::walk::walk_words`]' words, visible to compute-shader reads;
    /// for the first trace, the list's reset is visible to its storage reads and writes;
    /// for the overlap step, the triage and the walk, the steps before's writes (the list
    /// and the hits) are visible to indirect reads and compute-shader storage reads and
    /// writes.
    pub unsafe fn record_walk(
        &self,
        step: WalkStep,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: TraceInputs,
        params: &MethodParams,
        depth_scale: f32,
    ) -> Result<()> {
        if self.walk.is_none() {
            return Ok(());
        }
        // SAFETY: this function's contract, passed on.
        unsafe { self.record_on(Some(step), ctx, cmd, inputs, params, depth_scale) }
    }

    /// The dispatch `which`: the trace's (`None`) or the walk's first trace over the
    /// material's tiles, the triage's and the walk's over their lists.
    ///
    /// # Safety
    /// As [`TracePass::record`] or [`TracePass::record_walk`] (`which`).
    unsafe fn record_on(
        &self,
        which: Option<WalkStep>,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: TraceInputs,
        params: &MethodParams,
        depth_scale: f32,
    ) -> Result<()> {
        let pipeline = match (which, &self.walk) {
            (None, _) => &self.pipeline,
            (Some(step), Some(w)) => &w[step as usize],
            (_, None) => {
                return Err(Error::Internal(format!(
                    "trace[{}] has no mesh walk",
                    self.method.name()
                )));
            }
        };
        let walks = which.is_some();
        let TraceInputs {
            gbuffer,
            height,
            hit,
            iterations,
            extent,
            pyramid,
            corners,
            cone,
            tiles,
            curved,
            walk,
            walk_list,
        } = inputs;
        if iterations.is_some() != self.iterations {
            return Err(Error::invalid(
                "trace inputs",
                "the iteration image is given exactly to the pipeline built with iterations",
            ));
        }
        let needs = self.method.needs();
        let missing = |what: &str| {
            Error::invalid(
                "trace inputs",
                format!("method {} needs {what}", self.method.name()),
            )
        };
        let pyramid = match (needs.pyramid, pyramid) {
            (Some(kind), Some(p)) if p.kind == kind => Some(p),
            (Some(kind), _) => return Err(missing(&format!("a {kind:?} pyramid"))),
            (None, _) => None,
        };
        let corners = match (needs.dig_corners, corners) {
            (true, Some(c)) => Some(c),
            (true, None) => return Err(missing("the DIG corner grid")),
            (false, _) => None,
        };
        let cone = match (needs.cone.is_some(), cone) {
            (true, Some(c)) => Some(c),
            (true, None) => return Err(missing("the cone map")),
            (false, _) => None,
        };
        let fetch = |view: vk::ImageView| pipeline.fetch_view(view);
        let ray = fetch(gbuffer.ray.view);
        let depth = fetch(gbuffer.depth.view);
        let heights = [if params.lod_threshold.is_some() {
            height.descriptor_lod()
        } else {
            height.descriptor()
        }];
        let (hit_uv, hit_height) = (storage_view(hit.uv), storage_view(hit.height));
        let counts = iterations.map(storage_view);
        let pyramids = pyramid.map(|p| [p.descriptor()]);
        let grid = corners.map(|c| fetch(c.image.view));
        let frame = fetch(gbuffer.frame.view);
        // The curved trace and the walk (its circle model off the walked triangles) read
        // the curve image.
        let reads_curve = which.is_none_or(WalkStep::reads_curve);
        let curve = match (self.curved && reads_curve, gbuffer.curve) {
            (true, Some(c)) => Some(fetch(c.view)),
            (true, None) => {
                return Err(Error::invalid(
                    "gbuffer.curve",
                    format!(
                        "the curved trace of method {} reads the G-buffer's curve image, \
                         which the frame does not give",
                        self.method.name()
                    ),
                ));
            }
            (false, _) => None,
        };
        let pl = &pipeline.pipeline;
        let mut writes = vec![
            pl.image("u_ray", &ray)?,
            pl.image("u_depth", &depth)?,
            pl.image("u_height", &heights)?,
            pl.image("u_hit_height", &hit_height)?,
            pl.image("u_frame", &frame)?,
        ];
        writes.push(pl.image("u_hit_uv", &hit_uv)?);
        // The triage and the overlap step write no iteration counts (the hits they decide
        // keep the first trace's).
        if let Some(c) = counts
            .as_ref()
            .filter(|_| which.is_none_or(WalkStep::writes_iterations))
        {
            writes.push(pl.image("u_iterations", c)?);
        }
        if let Some(c) = &curve {
            writes.push(pl.image("u_curve", c)?);
        }
        let walk_view = match (walks, walk) {
            (true, Some(view)) => Some([view]),
            (true, None) => return Err(missing("the mesh walk buffer")),
            (false, _) => None,
        };
        if let Some(w) = &walk_view {
            writes.push(pl.texel_buffer("u_walk", w)?);
        }
        let list_info = match (walks, walk_list) {
            (true, Some(buffer)) => Some([vk::DescriptorBufferInfo {
                buffer,
                offset: 0,
                range: vk::WHOLE_SIZE,
            }]),
            (true, None) => return Err(missing("the walk list")),
            (false, _) => None,
        };
        if let Some(l) = &list_info {
            writes.push(pl.buffer("u_walk_list", l)?);
        }
        if let Some(p) = &pyramids {
            writes.push(pl.image("u_pyramid", p)?);
        }
        if let Some(g) = &grid {
            writes.push(pl.image("u_corners", g)?);
        }
        let cones = cone.map(|c| [c.descriptor()]);
        if let Some(c) = &cones {
            writes.push(pl.image("u_cone", c)?);
        }
        let (max_level, mut flags) = match params.max_level {
            MaxLevel::Fixed(l) => (l, 0),
            MaxLevel::Auto => (0, TRACE_FLAG_AUTO_LEVEL),
        };
        if params.lod_threshold.is_some() {
            flags |= TRACE_FLAG_LOD;
        }
        let curved = curved.filter(|_| self.curved);
        if curved.is_some() {
            flags |= TRACE_FLAG_CURVED;
        } else if walks {
            return Err(missing("the frame's view (the mesh walk's pixel rays)"));
        }
        // w: the eye's world position, x, y and z (the mesh walk).
        let view = |v: glam::Vec3, w: f32| v.extend(w).to_array();
        let push = TraceParams {
            frame_size: [extent.width, extent.height],
            map_size: height.size(),
            steps: params.steps,
            refine_steps: params.refine_steps,
            addressing: addressing_code(height.addressing),
            flags,
            min_steps: params.min_steps.min(params.steps),
            segments: params.segments,
            block: params.block,
            corner_size: corners.map_or([0, 0], CornerGrid::size),
            eps: params.dig_eps(),
            max_level,
            pyramid_levels: pyramid.map_or(0, Pyramid::shader_levels),
            depth_scale,
            lod_threshold: params.lod_threshold.unwrap_or(0.0),
            material: tiles.material,
            view_origin: curved.map_or([0.0; 4], |c| view(c.origin, c.eye.x)),
            view_dx: curved.map_or([0.0; 4], |c| view(c.dx, c.eye.y)),
            view_dy: curved.map_or([0.0; 4], |c| view(c.dy, c.eye.z)),
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match `bindings(needs)` (the pipeline's set 0: the pyramid and
        // grid are bound exactly when the method needs them, checked above) and name live
        // views in the layouts of the module's table; the push constants are the
        // `TraceParams` the layout was built with; the pipeline lives as long as this pass;
        // the list is the classification's (this function's contract).
        unsafe {
            match (which.and_then(WalkStep::list_args), walk_list) {
                // The walk list's own arguments (the step before's count of workgroups);
                // its pixels, not the tile list, say which pixel an invocation runs.
                (Some(args), Some(list)) => {
                    pipeline.pipeline.dispatch_indirect(
                        ctx,
                        cmd,
                        &writes,
                        bytemuck::bytes_of(&push),
                        list,
                        args,
                    );
                    Ok(())
                }
                _ => tiles.dispatch(
                    ctx,
                    cmd,
                    &pipeline.pipeline,
                    &writes,
                    bytemuck::bytes_of(&push),
                ),
            }
        }
    }
}

impl Destroy for TracePass {
    /// Destroys the pipeline and sampler.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
            self.walk.destroy(ctx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::pipeline::check_declared;

    /// What each method's trace pass binds is exactly what its shader declares (binding
    /// numbers and types reflected from the SPIR-V), for every method.
    #[test]
    fn declared_bindings_match_the_shaders() {
        for &m in Method::ALL {
            check_declared(&m.shader(), &bindings(m, false, false))
                .unwrap_or_else(|e| panic!("{}: {e}", m.name()));
            check_declared(&m.iterations_shader(), &bindings(m, true, false))
                .unwrap_or_else(|e| panic!("{} with iterations: {e}", m.name()));
            for iterations in [false, true] {
                if let Some(s) = m.curved_shader(iterations) {
                    check_declared(&s, &bindings(m, iterations, true)).unwrap_or_else(|e| {
                        panic!("{} curved, iterations {iterations}: {e}", m.name())
                    });
                }
                for step in WalkStep::ALL {
                    if let Some(s) = step.shader(m, iterations) {
                        check_declared(&s, &walk_bindings(m, iterations, step)).unwrap_or_else(
                            |e| panic!("{} walk {step:?}, iterations {iterations}: {e}", m.name()),
                        );
                    }
                }
            }
        }
    }

    /// A binding renamed, added or retyped in the GLSL is refused by name.
    #[test]
    fn a_binding_the_shader_lacks_is_refused() {
        let shader = Method::Relief.shader();
        let mut declared = bindings(Method::Relief, false, false);
        assert!(check_declared(&shader, &declared).is_ok());
        declared.push(("u_cone", SAMPLED));
        assert!(check_declared(&shader, &declared).is_err());
        let mut retyped = bindings(Method::Relief, false, false);
        retyped[0].1 = STORAGE;
        assert!(check_declared(&shader, &retyped).is_err());
    }
}
