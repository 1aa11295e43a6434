//! The wgpu example (`examples/wgpu_host.rs`: a wgpu device, G-buffer pipeline, render
//! passes and submissions, dispmap's pass recorded with `dispmap_wgpu::record` and its
//! corrected depth merged into the wgpu depth texture, two materials, two frames in
//! flight) runs headless under Vulkan core + synchronization validation and wgpu's own
//! validation with zero messages, and its hits and merged depth are bit-identical to the
//! standalone renderer's for the same camera, map and method: the left half of the frame
//! (material 0, rocks) against the renderer with the rocks map and material 0's method,
//! the right half (material 1, bricks) against the renderer with the bricks map and
//! material 1's method.

#[path = "../examples/wgpu_host.rs"]
#[allow(dead_code)]
mod wgpu_host;

use dispmap::context::{Context, ContextOptions};
use dispmap::heightfield::HeightField;
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use wgpu_host::{Options, run, split};

const W: u32 = 128;
const H: u32 = 72;

/// The standalone renderer's hits and corrected depth (validated, zero messages).
fn standalone(map: &HeightField, method: Method) -> (Vec<[f32; 4]>, Vec<f32>) {
    let ctx = std::sync::Arc::new(
        Context::headless(&ContextOptions {
            validation: Some(true),
            device: None,
        })
        .expect("a validated Vulkan context (run ./scripts/setup-debian.sh)"),
    );
    let out = {
        let mut r = Renderer::new(
            &ctx,
            map,
            RenderSettings {
                shadows: Default::default(),
                width: W,
                height: H,
                method,
                params: MethodParams::for_method(method),
                scene: wgpu_host::scene(),
            },
        )
        .unwrap();
        r.set_depth_output(true).unwrap();
        r.render().unwrap();
        (r.read_hits().unwrap(), r.read_depth().unwrap().unwrap())
    };
    let messages = ctx.messages().clone();
    drop(ctx);
    assert_eq!(messages.total(), 0, "standalone validation messages");
    out
}

fn app(method: Method, second: Method, out: Option<std::path::PathBuf>) -> wgpu_host::Output {
    let _ = env_logger::builder().is_test(true).try_init();
    let out = run(&Options {
        width: W,
        height: H,
        frames: 4,
        method,
        second,
        validation: true,
        out,
    })
    .unwrap();
    assert_eq!(
        out.validation_messages, 0,
        "Vulkan or wgpu validation messages (see the log)"
    );
    // Every frame was timed by the pass, after its submission completed.
    assert_eq!(out.timings.len(), 4);
    for t in &out.timings {
        let names: Vec<_> = t.iter().map(|(n, _)| n.as_str()).collect();
        for pass in ["classify", "trace", "shade", "hit_depth"] {
            assert!(names.contains(&pass), "{names:?}");
        }
        assert!(
            t.iter().all(|(_, ms)| ms.is_finite() && *ms >= 0.0),
            "{t:?}"
        );
    }
    out
}

/// Pixels whose hit (`u`, `v`, height: the application does not ask for the iteration
/// counts, which the standalone renderer has) or depth differs in bits from the
/// standalone frames (left half against `left`, right half against `right`), and the
/// displaced pixels.
fn differing(
    out: &wgpu_host::Output,
    left: &(Vec<[f32; 4]>, Vec<f32>),
    right: &(Vec<[f32; 4]>, Vec<f32>),
) -> (usize, usize, usize) {
    let (mut hits, mut depths, mut displaced) = (0, 0, 0);
    let n = (W * H) as usize;
    assert_eq!((out.hits.len(), out.depth.len()), (n, n));
    for i in 0..n {
        let want = if (i as u32 % W) < split(W) {
            left
        } else {
            right
        };
        let (got_hit, got_depth) = (out.hits[i], out.depth[i]);
        let bits = |h: [f32; 4]| [h[0], h[1], h[2]].map(f32::to_bits);
        if bits(got_hit) != bits(want.0[i]) {
            hits += 1;
        }
        if got_depth.to_bits() != want.1[i].to_bits() {
            depths += 1;
        }
        assert!(
            got_hit.iter().all(|v| v.is_finite()) && got_depth.is_finite(),
            "pixel {i}"
        );
        if got_hit[2] >= 0.0 {
            displaced += 1;
        }
    }
    (hits, depths, displaced)
}

#[test]
fn wgpu_app_matches_the_standalone_renderer_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("dispmap-wgpu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("wgpu.png");
    let out = app(Method::Exact, Method::Relief, Some(png.clone()));
    let left = standalone(&wgpu_host::rocks().unwrap(), Method::Exact);
    let right = standalone(&wgpu_host::bricks().unwrap(), Method::Relief);
    let (hits, depths, displaced) = differing(&out, &left, &right);
    assert_eq!(
        (hits, depths),
        (0, 0),
        "pixels differing from the standalone renderer"
    );
    let n = (W * H) as usize;
    assert!(
        displaced > n / 2,
        "displaced pixels with a hit: {displaced} of {n}"
    );
    // The merge wrote the corrected depth: it differs from the flat plane's somewhere.
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (W, H));
    std::fs::remove_dir_all(&dir).ok();
}

/// A texture the pass cannot use is refused before anything is recorded, the error
/// naming it; a mismatch only the pass's own check sees (a hit texture without storage
/// usage) names the image's role; no validation message either way.
#[test]
fn unusable_textures_are_refused_by_name() {
    use dispmap_wgpu::{DeviceOptions, WgpuDevice, WgpuImage, host_view};
    let _ = env_logger::builder().is_test(true).try_init();
    let gpu = WgpuDevice::new(&DeviceOptions {
        validation: true,
        ..Default::default()
    })
    .unwrap();
    let messages = gpu.messages().clone();
    let texture = |format, usage| {
        let t = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: None,
            size: wgpu::Extent3d {
                width: 8,
                height: 8,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        });
        let v = t.create_view(&Default::default());
        (t, v)
    };
    let (t, v) = texture(
        wgpu::TextureFormat::Bgra8Unorm,
        wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let err = host_view(
        WgpuImage {
            texture: &t,
            view: &v,
        },
        "sky lut",
    )
    .unwrap_err();
    assert!(
        err.to_string()
            .contains("texture sky lut: format Bgra8Unorm"),
        "{err}"
    );
    let (t, v) = texture(
        wgpu::TextureFormat::Rg32Float,
        wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let hit = host_view(
        WgpuImage {
            texture: &t,
            view: &v,
        },
        "hit.uv",
    )
    .unwrap();
    assert_eq!(hit.usage, dispmap::ash::vk::ImageUsageFlags::SAMPLED);
    assert_eq!(hit.format, dispmap::embed::HIT_UV_FORMAT);
    let err = hit
        .check(
            "hit.uv",
            &[dispmap::embed::HIT_UV_FORMAT],
            dispmap::ash::vk::ImageUsageFlags::STORAGE,
            hit.extent,
        )
        .unwrap_err();
    assert!(err.to_string().contains("hit.uv"), "{err}");
    drop((t, v));
    drop(gpu);
    assert_eq!(messages.total(), 0, "validation messages");
}
