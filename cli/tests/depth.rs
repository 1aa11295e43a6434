//! Corrected depth (`Renderer::set_depth_output`, `passes::hit_depth`,
//! `passes::depth_resolve`): the GPU depth of each hit matches the depth of the exact
//! reference hit computed on the CPU in f64, and a box standing in the displaced plane,
//! depth-tested against the resolved `D32_SFLOAT` attachment, is visible exactly where it
//! is nearer than the reference surface. Validation on throughout.

#[path = "../../tests/common/mod.rs"]
mod common;

use ash::vk;
use common::{asset_map, finish, validated_context};
use dispmap::context::Context;
use dispmap::gpu::commands::read_image;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::pipeline::{RasterDesc, raster_pipeline};
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Image, OneShot};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::passes::depth_resolve::{DEPTH_FORMAT, DepthResolvePass};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Geometry, Scene};
use dispmap::shaders;
use dispmap_cli::measure::Measure as _;
use dispmap_cli::metrics::{self, HitTexel};
use dispmap_cli::reference::{Hit, Reference};
use glam::{DMat4, DVec3, DVec4, Mat4, Vec4};

const WIDTH: u32 = 256;
const HEIGHT: u32 = 144;

/// Largest relative difference between the GPU's corrected depth (f32 unprojection of the
/// G-buffer depth, tangent-frame offset, projection) and the CPU's (f64, from the same
/// G-buffer depth and the reference hit). Measured: 6.2e-7 (tiled plane), 4.4e-7 (quad).
const DEPTH_REL_TOL: f64 = 2e-6;

/// Depths closer than this (relative) count as equal in the box test: the rasterised
/// depths of the box and of the G-buffer are f32 plane equations (the G-buffer's differs
/// from the analytic plane by up to 2.1e-6 near the box; 4.0e-3 in the pixel row next to
/// the horizon, where the rasteriser's 1/256-pixel vertex snapping meets a depth whose
/// relative gradient is about one per pixel: tests/gbuffer_plane.rs).
const EQUAL_DEPTH_REL: f64 = 1e-4;

/// A GPU hit "equals" the reference hit within this distance (texels).
const SAME_HIT_TEXELS: f64 = 1e-2;

fn settings(geometry: Geometry, elevation: f32) -> RenderSettings {
    RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        method: Method::Exact,
        params: MethodParams::for_method(Method::Exact),
        scene: Scene {
            geometry,
            camera: Camera {
                elevation_deg: elevation,
                ..Camera::default()
            },
            ..Scene::default()
        },
        shadows: Default::default(),
    }
}

/// The CPU side in f64: pixel rays, macro entry points and projected depths.
struct CpuCamera {
    eye: DVec3,
    view_proj: DMat4,
    inv_view_proj: DMat4,
}

impl CpuCamera {
    fn new(scene: &Scene) -> Self {
        let cam = scene.frame_camera(WIDTH, HEIGHT);
        let view_proj = cam.view_proj.as_dmat4();
        CpuCamera {
            eye: cam.eye.as_dvec3(),
            view_proj,
            inv_view_proj: view_proj.inverse(),
        }
    }

    /// The unit direction through the point (`x`, `y`) of the frame (pixels).
    fn direction(&self, x: f64, y: f64) -> DVec3 {
        let ndc_x = x / f64::from(WIDTH) * 2.0 - 1.0;
        let ndc_y = y / f64::from(HEIGHT) * 2.0 - 1.0;
        let p = self.inv_view_proj * DVec4::new(ndc_x, ndc_y, 0.5, 1.0);
        ((p.truncate() / p.w) - self.eye).normalize()
    }

    /// The reverse-Z depth of a world point.
    fn depth(&self, p: DVec3) -> f64 {
        let c = self.view_proj * p.extend(1.0);
        c.z / c.w
    }

    /// The macro entry point of pixel `i`: its centre's ray meets the plane y = 0.
    fn entry(&self, i: usize) -> DVec3 {
        let (x, y) = (
            (i % WIDTH as usize) as f64 + 0.5,
            (i / WIDTH as usize) as f64 + 0.5,
        );
        let d = self.direction(x, y);
        self.eye + d * (-self.eye.y / d.y)
    }

    /// The entry point of pixel `i` unprojected from the G-buffer's depth.
    fn unproject(&self, i: usize, depth: f32) -> DVec3 {
        let (x, y) = (
            (i % WIDTH as usize) as f64 + 0.5,
            (i / WIDTH as usize) as f64 + 0.5,
        );
        let ndc = DVec4::new(
            x / f64::from(WIDTH) * 2.0 - 1.0,
            y / f64::from(HEIGHT) * 2.0 - 1.0,
            f64::from(depth),
            1.0,
        );
        let p = self.inv_view_proj * ndc;
        p.truncate() / p.w
    }

    /// The depth of a hit of pixel `i` whose ray entered at `uv0`, at `entry` (the
    /// plane's frame: T = +x along u, B = +z along v, N = +y; one tile = one world unit).
    fn hit_depth(&self, entry: DVec3, uv0: [f64; 2], hit: &Hit, depth_scale: f64) -> f64 {
        let p = entry
            + DVec3::new(
                hit.uv[0] - uv0[0],
                -(1.0 - hit.height) * depth_scale,
                hit.uv[1] - uv0[1],
            );
        self.depth(p)
    }
}

#[test]
fn corrected_depth_matches_the_reference_hits() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    // The tiled plane with sky at the top (15 degrees down, fov 45) and the quad, whose
    // clamp-addressed rays can leave the decal (a miss: depth 0).
    for (geometry, elevation) in [(Geometry::TiledPlane, 15.0), (Geometry::Quad, 30.0)] {
        let s = settings(geometry, elevation);
        let reference = Reference::new(&field, s.scene.addressing());
        let mut renderer = Renderer::new(&ctx, &field, s).unwrap();
        assert!(renderer.read_depth().unwrap().is_none(), "off by default");
        renderer.set_depth_output(true).unwrap();
        let err = renderer.read_depth().unwrap_err().to_string();
        assert!(err.contains("no frame"), "{err}");
        assert!(renderer.hit_depth().is_none());
        let frame_ref = renderer.reference(&reference).unwrap();
        renderer.render().unwrap();
        let hits = renderer.read_hits().unwrap();
        let depth = renderer.read_depth().unwrap().expect("depth output is on");
        let macro_depth = renderer.read_macro_depth().unwrap();
        let cam = CpuCamera::new(&s.scene);
        let geo = renderer.map_geometry();
        let (mut compared, mut skipped, mut empty) = (0usize, 0usize, 0usize);
        let (mut max_rel, mut max_raster): (f64, f64) = (0.0, 0.0);
        for (i, ((gpu, ray), want)) in hits
            .iter()
            .zip(&frame_ref.rays)
            .zip(&frame_ref.hits)
            .enumerate()
        {
            assert!(depth[i].is_finite(), "{geometry:?} pixel {i}: {}", depth[i]);
            match (ray, want, gpu[2] >= 0.0) {
                (Some(ray), Some(want), true) => {
                    if metrics::hit_distance_texels(gpu, want, geo) > SAME_HIT_TEXELS {
                        skipped += 1;
                        continue;
                    }
                    // The entry the G-buffer gives (its f32 raster depth; on the plane
                    // it differs from the analytic entry by the rasteriser's precision,
                    // reported as `max_raster`).
                    let entry = cam.unproject(i, macro_depth[i]);
                    let analytic = cam.depth(cam.entry(i));
                    max_raster =
                        max_raster.max((f64::from(macro_depth[i]) - analytic).abs() / analytic);
                    let cpu = cam.hit_depth(entry, ray.uv0, want, geo.depth_scale);
                    let rel = (f64::from(depth[i]) - cpu).abs() / cpu;
                    max_rel = max_rel.max(rel);
                    assert!(
                        rel <= DEPTH_REL_TOL,
                        "{geometry:?} pixel {i}: GPU depth {} vs CPU {cpu} (rel {rel:e})",
                        depth[i]
                    );
                    // Displaced into the surface: never nearer than the macro entry.
                    assert!(cpu <= f64::from(macro_depth[i]) * (1.0 + 1e-9));
                    compared += 1;
                }
                (_, _, false) => {
                    assert_eq!(
                        depth[i], 0.0,
                        "{geometry:?} pixel {i}: no hit, depth {}",
                        depth[i]
                    );
                    empty += 1;
                }
                _ => skipped += 1,
            }
        }
        println!(
            "{geometry:?}: {compared} hits compared, max relative depth error {max_rel:.3e} \
             (G-buffer raster depth vs the analytic plane: {max_raster:.3e}); {empty} pixels \
             without a hit (depth 0); {skipped} skipped (GPU hit != reference)"
        );
        assert!(compared > 5000, "{geometry:?}: {compared}");
        assert!(
            empty > 0,
            "{geometry:?}: the frame should have pixels without a hit"
        );
        assert!(
            skipped * 1000 <= compared,
            "{geometry:?}: {skipped} skipped"
        );
        let times = renderer.render().unwrap();
        assert!(
            times.iter().any(|(n, _)| *n == PassName::HitDepth),
            "{times:?}"
        );
        renderer.set_depth_output(false).unwrap();
        assert!(renderer.read_depth().unwrap().is_none());
        let times = renderer.render().unwrap();
        assert!(
            !times.iter().any(|(n, _)| *n == PassName::HitDepth),
            "{times:?}"
        );
        drop(renderer);
    }
    finish(ctx);
}

/// Sampled by fragment shaders.
const FRAGMENT_SAMPLED: Access = Access {
    stage: vk::PipelineStageFlags2::FRAGMENT_SHADER,
    access: vk::AccessFlags2::SHADER_SAMPLED_READ,
    layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
};

/// `BoxParams` of glsl/tests/depth_box.vert.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct BoxParams {
    view_proj: Mat4,
    box_min: Vec4,
    box_max: Vec4,
}

const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;

/// A graphics pipeline drawing the box (white) with a reverse-Z depth test.
struct BoxPipeline {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
}

impl BoxPipeline {
    fn new(ctx: &Context) -> BoxPipeline {
        let dev = ctx.device();
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX)
            .size(std::mem::size_of::<BoxParams>() as u32)];
        let layout_info = vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges);
        // SAFETY: valid device and create info.
        let layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .expect("vkCreatePipelineLayout");
        ctx.set_name(layout, "test.box.layout");
        let pipeline = raster_pipeline(
            ctx,
            &RasterDesc {
                vert: &shaders::TESTS_DEPTH_BOX_VERT,
                frag: &shaders::TESTS_DEPTH_BOX_FRAG,
                layout,
                vertex_bindings: &[],
                vertex_attributes: &[],
                depth_compare: vk::CompareOp::GREATER,
                color_formats: &[COLOR_FORMAT],
                depth_format: DEPTH_FORMAT,
                name: "test.box.pipeline",
            },
        )
        .unwrap();
        BoxPipeline { pipeline, layout }
    }

    /// Draws the box into `color` with depth testing against `depth` (both kept).
    ///
    /// # Safety
    /// `cmd` is a command buffer of `ctx`'s device in the recording state, outside a render
    /// pass instance, for a queue of the context's queue family; when it executes `color`
    /// is in `COLOR_ATTACHMENT_OPTIMAL` and `depth` in `DEPTH_ATTACHMENT_OPTIMAL`, both of
    /// the same size, earlier writes ordered before the attachment accesses; both images
    /// and the pipeline stay alive until it has executed.
    unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        color: &Image,
        depth: &Image,
        params: &BoxParams,
    ) {
        let extent = color.extent;
        let color_attachments = [vk::RenderingAttachmentInfo::default()
            .image_view(color.view)
            .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue {
                color: vk::ClearColorValue { float32: [0.0; 4] },
            })];
        let depth_attachment = vk::RenderingAttachmentInfo::default()
            .image_view(depth.view)
            .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE);
        let area = dispmap::gpu::pipeline::frame_area(extent);
        let rendering = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1)
            .color_attachments(&color_attachments)
            .depth_attachment(&depth_attachment);
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording; `extent` is an
        // attachment's size, so it is non-zero and within the viewport limits.
        unsafe { dispmap::gpu::pipeline::set_frame_viewport(ctx, cmd, extent) };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the attachments are alive and in the layouts named above.
        unsafe {
            dev.cmd_begin_rendering(cmd, &rendering);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            dev.cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::VERTEX,
                0,
                bytemuck::bytes_of(params),
            );
            dev.cmd_draw(cmd, 36, 1, 0, 0);
            dev.cmd_end_rendering(cmd);
        }
    }

    fn destroy(&mut self, ctx: &Context) {
        // SAFETY: the GPU is done with them (the test waited for its submission).
        unsafe {
            ctx.device().destroy_pipeline(self.pipeline, None);
            ctx.device().destroy_pipeline_layout(self.layout, None);
        }
    }
}

/// Where the ray `eye + t d` enters the box, if it does (slab method).
fn box_entry(eye: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<f64> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        let (a0, a1) = ((lo[a] - eye[a]) / d[a], (hi[a] - eye[a]) / d[a]);
        t0 = t0.max(a0.min(a1));
        t1 = t1.min(a0.max(a1));
    }
    (t0 <= t1).then_some(t0)
}

#[test]
fn a_box_clips_at_the_displaced_height() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let s = settings(Geometry::TiledPlane, 30.0);
    let reference = Reference::new(&field, s.scene.addressing());
    let mut renderer = Renderer::new(&ctx, &field, s).unwrap();
    renderer.set_depth_output(true).unwrap();
    let frame_ref = renderer.reference(&reference).unwrap();
    renderer.render().unwrap();
    let hits: Vec<HitTexel> = renderer.read_hits().unwrap();
    let corrected = renderer.read_depth().unwrap().expect("depth output is on");
    let macro_depth = renderer.read_macro_depth().unwrap();

    // The box stands in the displaced layer (y in [-0.1, 0]): its lower half is buried
    // where the rocks rise above it, visible where they fall below it.
    let (lo, hi) = (DVec3::new(-0.15, -0.09, -0.1), DVec3::new(0.05, 0.04, 0.1));
    let cam_f32 = s.scene.frame_camera(WIDTH, HEIGHT);
    let params = BoxParams {
        view_proj: cam_f32.view_proj,
        box_min: lo.as_vec3().extend(1.0),
        box_max: hi.as_vec3().extend(1.0),
    };
    let extent = vk::Extent2D {
        width: WIDTH,
        height: HEIGHT,
    };
    let mut shot = OneShot::new(&ctx, "test.box").unwrap();
    let mut depth = Image::new(
        &ctx,
        "test.resolved_depth",
        DEPTH_FORMAT,
        extent,
        1,
        vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST,
    )
    .unwrap();
    let mut color = Image::new(
        &ctx,
        "test.box_color",
        COLOR_FORMAT,
        extent,
        1,
        vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC,
    )
    .unwrap();
    let mut resolve = DepthResolvePass::new(&ctx).unwrap();
    let mut boxes = BoxPipeline::new(&ctx);
    let source = renderer.hit_depth().expect("depth output is on");
    let frame = &renderer.gbuffer().frame;
    let cmd = shot.begin(&ctx).unwrap();
    // SAFETY: `cmd` was just begun by `shot.begin` (outside a render pass, on the context's
    // queue family) and is submitted and waited for below, while every image lives;
    // `source` is the renderer's corrected depth, in `GENERAL` written by `hit_depth` (the
    // state the renderer documents after `render`); `depth` and `color` are new, never
    // accessed, with attachment usage.
    unsafe {
        sync::record(
            &ctx,
            cmd,
            &[
                sync::image_barrier(
                    source.raw,
                    source.range(),
                    Access::COMPUTE_STORAGE_WRITE,
                    FRAGMENT_SAMPLED,
                ),
                sync::image_barrier(
                    depth.raw,
                    depth.range(),
                    Access::UNDEFINED,
                    Access::TRANSFER_WRITE,
                ),
                // The resolve reads which pixels are displaced from the G-buffer frame.
                sync::image_barrier(
                    frame.raw,
                    frame.range(),
                    Access::COMPUTE_SAMPLED,
                    FRAGMENT_SAMPLED,
                ),
                sync::image_barrier(
                    color.raw,
                    color.range(),
                    Access::UNDEFINED,
                    Access::COLOR_ATTACHMENT_WRITE,
                ),
            ],
        )
    };
    // The host's depth before the merge: cleared to 0 (the far plane), as the G-buffer's
    // is where nothing was drawn.
    // SAFETY: as above; `depth` is in TRANSFER_DST_OPTIMAL (the barrier above).
    unsafe {
        ctx.device().cmd_clear_depth_stencil_image(
            cmd,
            depth.raw,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &vk::ClearDepthStencilValue::default(),
            &[depth.range()],
        );
        sync::transition(
            &ctx,
            cmd,
            &depth,
            Access::TRANSFER_WRITE,
            Access::DEPTH_ATTACHMENT_WRITE,
        );
    }
    // SAFETY: as above; `source` and the frame are sampled-readable by fragment shaders
    // and `depth` in `DEPTH_ATTACHMENT_OPTIMAL` (the barriers above), all of `extent`.
    unsafe {
        resolve
            .record(&ctx, cmd, source.view, frame.view, depth.view, extent)
            .unwrap()
    };
    // SAFETY: as above; `depth` was written in `DEPTH_ATTACHMENT_OPTIMAL` by the resolve.
    unsafe {
        sync::transition(
            &ctx,
            cmd,
            &depth,
            Access::DEPTH_ATTACHMENT_WRITE,
            Access::DEPTH_ATTACHMENT_WRITE,
        )
    };
    // SAFETY: as above; `color` is in `COLOR_ATTACHMENT_OPTIMAL` (the first barriers) and
    // `depth` holds the resolved depth in `DEPTH_ATTACHMENT_OPTIMAL` (the barrier above).
    unsafe { boxes.record(&ctx, cmd, &color, &depth, &params) };
    // Back to the state the renderer documents for its corrected depth.
    // SAFETY: as above; `source` and the frame are in `SHADER_READ_ONLY_OPTIMAL` (the
    // first barriers).
    unsafe {
        sync::transition(
            &ctx,
            cmd,
            source,
            FRAGMENT_SAMPLED,
            Access::COMPUTE_STORAGE_WRITE,
        );
        sync::transition(&ctx, cmd, frame, FRAGMENT_SAMPLED, Access::COMPUTE_SAMPLED);
    }
    shot.submit_and_wait(&ctx).unwrap();
    let rgba = read_image(&ctx, &shot, &color, Access::COLOR_ATTACHMENT_WRITE).unwrap();
    // The resolve copied the corrected depth pixel for pixel (the box wrote only where
    // it passed the test, so compare outside the box's pixels).
    let resolved = read_image(&ctx, &shot, &depth, Access::DEPTH_ATTACHMENT_WRITE).unwrap();
    let resolved: &[f32] = bytemuck::cast_slice(&resolved);
    let unchanged = (0..resolved.len())
        .filter(|&i| rgba[4 * i] == 0)
        .inspect(|&i| {
            assert_eq!(
                resolved[i].to_bits(),
                corrected[i].to_bits(),
                "pixel {i}: resolved {} vs corrected {}",
                resolved[i],
                corrected[i]
            )
        })
        .count();
    assert!(unchanged > 30000, "{unchanged}");

    let cam = CpuCamera::new(&s.scene);
    let geo = renderer.map_geometry();
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let (mut checked, mut ambiguous, mut buried, mut revealed) = (0usize, 0usize, 0, 0);
    for i in 0..w * h {
        let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        // Coverage: the pixel centre's ray, and rays 0.01 pixel around it (the
        // rasteriser's sub-pixel snapping): a pixel on the box's outline is ambiguous.
        let entries: Vec<Option<f64>> = [
            (0.0, 0.0),
            (-0.01, -0.01),
            (0.01, -0.01),
            (-0.01, 0.01),
            (0.01, 0.01),
        ]
        .iter()
        .map(|(dx, dy)| box_entry(cam.eye, cam.direction(x + dx, y + dy), lo, hi))
        .collect();
        if entries.iter().any(Option::is_some) != entries.iter().all(Option::is_some) {
            ambiguous += 1;
            continue;
        }
        let visible = rgba[4 * i] == 255;
        let Some(t) = entries[0] else {
            assert!(!visible, "pixel {i}: box drawn where the box is not");
            checked += 1;
            continue;
        };
        let box_depth = cam.depth(cam.eye + cam.direction(x, y) * t);
        let surface_depth = match (&frame_ref.rays[i], &frame_ref.hits[i]) {
            (Some(ray), Some(hit)) => {
                if metrics::hit_distance_texels(&hits[i], hit, geo) > SAME_HIT_TEXELS {
                    // The exact method's f32 hit differs from the f64 reference here.
                    ambiguous += 1;
                    continue;
                }
                cam.hit_depth(
                    cam.unproject(i, macro_depth[i]),
                    ray.uv0,
                    hit,
                    geo.depth_scale,
                )
            }
            _ => 0.0,
        };
        if (box_depth - surface_depth).abs() <= EQUAL_DEPTH_REL * surface_depth {
            ambiguous += 1;
            continue;
        }
        let nearer = box_depth > surface_depth;
        assert_eq!(
            visible, nearer,
            "pixel {i}: box depth {box_depth}, displaced surface {surface_depth} (GPU {})",
            corrected[i]
        );
        checked += 1;
        if nearer && box_depth < f64::from(macro_depth[i]) {
            revealed += 1; // below the macro surface, above the displaced one
        }
        if !nearer {
            buried += 1;
        }
    }
    println!(
        "box: {checked} pixels checked, {ambiguous} ambiguous (outline or equal depth), \
         {revealed} visible below the macro surface, {buried} hidden by the displaced surface"
    );
    assert!(
        ambiguous * 50 <= checked,
        "{ambiguous} ambiguous of {checked}"
    );
    assert!(revealed > 200 && buried > 200, "{revealed} / {buried}");

    destroy_all(
        &ctx,
        &mut shot,
        &mut depth,
        &mut color,
        &mut resolve,
        &mut boxes,
    );
    drop(renderer);
    finish(ctx);
}

fn destroy_all(
    ctx: &Context,
    shot: &mut OneShot,
    depth: &mut Image,
    color: &mut Image,
    resolve: &mut DepthResolvePass,
    boxes: &mut BoxPipeline,
) {
    boxes.destroy(ctx);
    // SAFETY: the command buffer that recorded the resolve has completed (waited for).
    unsafe { resolve.destroy(ctx) };
    // SAFETY: the command buffers that used them completed (waited for).
    unsafe {
        color.destroy(ctx);
        depth.destroy(ctx);
        shot.destroy(ctx);
    }
}

fn dispmap_cli() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_dispmap"));
    c.env("DISPMAP_VALIDATION", "1");
    c
}

#[test]
fn cli_depth_out_writes_the_corrected_depth() {
    let dir = std::env::temp_dir().join(format!("dispmap-depth-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let map = common::repo_root().join("assets/heightmaps/rocks_depth.jpg");
    let run = |depth_out: &std::path::Path, extra: &[&str]| {
        dispmap_cli()
            .args(["render", "--heightmap"])
            .arg(&map)
            .args([
                "--convention",
                "depth",
                "--method",
                "exact",
                "--size",
                "64x36",
            ])
            .args(["--camera-elevation", "15", "--frames", "1", "--out"])
            .arg(dir.join("color.png"))
            .arg("--depth-out")
            .arg(depth_out)
            .args(extra)
            .output()
            .unwrap()
    };
    let (exr, png) = (dir.join("depth.exr"), dir.join("depth.png"));
    for path in [&exr, &png] {
        let out = run(path, &[]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(!stderr.contains("Validation"), "{stderr}");
    }

    // The same frame through the library.
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let mut s = settings(Geometry::TiledPlane, 15.0);
    (s.width, s.height) = (64, 36);
    let mut renderer = Renderer::new(&ctx, &field, s).unwrap();
    renderer.set_depth_output(true).unwrap();
    renderer.render().unwrap();
    let want = renderer.read_depth().unwrap().unwrap();
    drop(renderer);
    finish(ctx);

    let got = image::open(&exr).unwrap().to_rgb32f();
    assert_eq!((got.width(), got.height()), (64, 36));
    let red: Vec<f32> = got.pixels().map(|p| p.0[0]).collect();
    assert_eq!(red, want, "the EXR holds the renderer's corrected depth");
    assert!(want.contains(&0.0) && want.iter().any(|&d| d > 0.0));
    let grey = image::open(&png).unwrap().to_luma16();
    for (g, d) in grey.pixels().zip(&want) {
        assert_eq!(g.0[0], (d.clamp(0.0, 1.0) * 65535.0).round() as u16);
    }

    // Bad outputs are named and leave no file.
    let bad = dir.join("depth.tif");
    let out = run(&bad, &[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--depth-out"));
    assert!(!bad.exists());
    let missing = dir.join("no-such-folder").join("depth.exr");
    let out = run(&missing, &[]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--depth-out"));
    let json = dir.join("m.json");
    let json_arg = json.to_str().unwrap();
    let out = run(&exr, &["--lod-threshold", "1.5", "--metrics", json_arg]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(report["lod_threshold"], 1.5);
    let out = run(&exr, &["--lod-threshold", "-1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("lod-threshold"));
    std::fs::remove_dir_all(&dir).unwrap();
}
