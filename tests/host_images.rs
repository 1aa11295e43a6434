//! The host images the pass reads and writes (the G-buffer, hit images, colour, motion)
//! are checked before anything is recorded: a wrong format, a smaller size or a missing
//! usage is refused with an error naming the image, and motion inputs must match the motion
//! output's state. Vulkan itself would not say: a storage image of the wrong format is
//! written without an error or a validation message (issue 23). After the refusals the
//! pass records a valid frame; validation on throughout.

mod common;

use ash::vk;
use common::{asset_map, finish, validated_context};
use dispmap::embed::{
    COLOR_FORMAT, DepthCamera, DisplacementPass, FrameInputs, FrameMotion, HIT_HEIGHT_FORMAT,
    HIT_UV_FORMAT, HitImages, HostView, MotionSettings, PassSettings, ShadeTarget, Timestamps,
};
use dispmap::error::Error;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::track::Tracker;
use dispmap::gpu::{Image, OneShot};
use dispmap::heightfield::{Addressing, Convention};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::gbuffer::{GBuffer, GBufferViews};
use glam::{Mat4, Vec3};

const EXTENT: vk::Extent2D = vk::Extent2D {
    width: 32,
    height: 16,
};

/// The name and message of an `InvalidInput` error.
fn refused(result: dispmap::Result<impl std::fmt::Debug>) -> (String, String) {
    match result {
        Err(Error::InvalidInput { name, message }) => (name, message),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn wrong_host_images_are_refused_by_name() {
    let ctx = validated_context();
    let c = &*ctx;
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    let storage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
    let image = |name: &str, format: vk::Format, extent: vk::Extent2D| {
        Image::new(c, name, format, extent, 1, storage).unwrap()
    };
    let mut gbuffer = GBuffer::new(c, EXTENT).unwrap();
    let mut hit_uv = image("hit.uv", HIT_UV_FORMAT, EXTENT);
    let mut hit_height = image("hit.height", HIT_HEIGHT_FORMAT, EXTENT);
    let mut half_hit = image("hit16", vk::Format::R16G16B16A16_SFLOAT, EXTENT);
    let mut small_hit = image(
        "small_hit",
        HIT_UV_FORMAT,
        vk::Extent2D {
            width: 16,
            height: 16,
        },
    );
    let mut motion32 = image("motion32", vk::Format::R32G32_SFLOAT, EXTENT);
    let mut shot = OneShot::new(c, "test").unwrap();
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &field,
        PassSettings {
            method: Method::Relief,
            params: MethodParams::for_method(Method::Relief),
            depth_scale: 0.1,
            addressing: Addressing::Repeat,
            extent: EXTENT,
            frames_in_flight: 1,
        },
    )
    .unwrap();
    let inputs = FrameInputs {
        frame_slot: 0,
        gbuffer: gbuffer.views(),
        hit: HitImages {
            uv: hit_uv.host_view(),
            height: hit_height.host_view(),
        },
        shade: None,
        motion: None,
    };
    let hit = inputs.hit;
    let camera = DepthCamera {
        view_proj: Mat4::IDENTITY,
        eye: Vec3::ZERO,
    };
    let cmd = shot.begin(c).unwrap();
    // SAFETY (every record below): `cmd` is recording outside a render pass on the
    // context's queue family and submitted below; each call is refused before it records
    // anything (the assertions), so no image is accessed.
    let mut record = |inputs: &FrameInputs| unsafe {
        pass.record_with_camera(cmd, inputs, &camera, Timestamps::Off)
    };

    let (name, message) = refused(record(&FrameInputs {
        hit: HitImages {
            uv: half_hit.host_view(),
            ..hit
        },
        ..inputs
    }));
    assert_eq!(name, "hit.uv");
    assert!(message.contains("R16G16B16A16_SFLOAT"), "{message}");
    // The two images swapped: each is refused by its own name.
    let (name, message) = refused(record(&FrameInputs {
        hit: HitImages {
            uv: hit.height,
            height: hit.uv,
        },
        ..inputs
    }));
    assert_eq!(name, "hit.uv");
    assert!(message.contains("R32_SFLOAT"), "{message}");
    let (name, message) = refused(record(&FrameInputs {
        hit: HitImages {
            height: hit.uv,
            ..hit
        },
        ..inputs
    }));
    assert_eq!(name, "hit.height");
    assert!(message.contains("R32G32_SFLOAT"), "{message}");
    let (name, message) = refused(record(&FrameInputs {
        hit: HitImages {
            uv: small_hit.host_view(),
            ..hit
        },
        ..inputs
    }));
    assert_eq!(name, "hit.uv");
    assert!(message.contains("16x16"), "{message}");
    let (name, message) = refused(record(&FrameInputs {
        hit: HitImages {
            height: HostView {
                usage: vk::ImageUsageFlags::SAMPLED,
                ..hit.height
            },
            ..hit
        },
        ..inputs
    }));
    assert_eq!(name, "hit.height");
    assert!(message.contains("STORAGE"), "{message}");
    // The G-buffer: a half-float ray image (uv0 would lose its bits) and a depth view
    // without SAMPLED usage.
    let views = gbuffer.views();
    let (name, message) = refused(record(&FrameInputs {
        gbuffer: GBufferViews {
            ray: HostView {
                format: vk::Format::R16G16B16A16_SFLOAT,
                ..views.ray
            },
            ..views
        },
        ..inputs
    }));
    assert_eq!(name, "gbuffer.ray");
    assert!(message.contains("R32G32B32A32_SFLOAT"), "{message}");
    let (name, message) = refused(record(&FrameInputs {
        gbuffer: GBufferViews {
            depth: HostView {
                usage: vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
                ..views.depth
            },
            ..views
        },
        ..inputs
    }));
    assert_eq!(name, "gbuffer.depth");
    assert!(message.contains("SAMPLED"), "{message}");
    let shaded = |color: HostView| FrameInputs {
        shade: Some(ShadeTarget {
            color,
            view_proj: Mat4::IDENTITY,
            camera_pos: Vec3::ZERO,
            light_dir: Vec3::Y,
            light_intensity: 1.0,
        }),
        ..inputs
    };
    // An HDR colour target where the pass writes sRGB-encoded RGBA8.
    let (name, message) = refused(record(&shaded(half_hit.host_view())));
    assert_eq!(name, "color");
    assert!(message.contains(&format!("{COLOR_FORMAT:?}")), "{message}");

    // A camera that would write NaN colour, depths or motion.
    let mut nan_camera = shaded(half_hit.host_view());
    if let Some(t) = &mut nan_camera.shade {
        t.view_proj = Mat4::from_cols_array(&[f32::NAN; 16]);
    }
    let (name, _) = refused(record(&nan_camera));
    assert_eq!(name, "camera");

    // Motion inputs follow the output's state and format.
    let with_motion = |image: HostView| FrameInputs {
        motion: Some(FrameMotion {
            image,
            previous: camera,
        }),
        ..inputs
    };
    let (name, _) = refused(record(&with_motion(motion32.host_view())));
    assert_eq!(name, "motion", "motion inputs while the output is off");
    pass.set_motion_output(Some(MotionSettings::default()))
        .unwrap();
    // SAFETY: as above.
    let mut record = |inputs: &FrameInputs| unsafe {
        pass.record_with_camera(cmd, inputs, &camera, Timestamps::Off)
    };
    let (name, _) = refused(record(&inputs));
    assert_eq!(name, "motion", "no motion inputs while the output is on");
    let (name, message) = refused(record(&with_motion(motion32.host_view())));
    assert_eq!(name, "motion");
    assert!(message.contains("R16G16_SFLOAT"), "{message}");
    let mut nan_previous = with_motion(motion32.host_view());
    if let Some(m) = &mut nan_previous.motion {
        m.previous.eye = Vec3::splat(f32::INFINITY);
    }
    let (name, _) = refused(record(&nan_previous));
    assert_eq!(name, "motion.previous");
    pass.set_motion_output(None).unwrap();

    // A material traced curved reads the G-buffer's curve image: a frame without it, or
    // with one of another format, is refused by its name.
    let material = pass.primary();
    pass.set_material_curved(material, true).unwrap();
    // SAFETY: as above.
    let mut record = |inputs: &FrameInputs| unsafe {
        pass.record_with_camera(cmd, inputs, &camera, Timestamps::Off)
    };
    let (name, message) = refused(record(&inputs));
    assert_eq!(name, "gbuffer.curve");
    assert!(message.contains("curved"), "{message}");
    let (name, message) = refused(record(&FrameInputs {
        gbuffer: GBufferViews {
            curve: Some(half_hit.host_view()),
            ..views
        },
        ..inputs
    }));
    assert_eq!(name, "gbuffer.curve");
    assert!(message.contains("R16G16_SFLOAT"), "{message}");
    pass.set_material_curved(material, false).unwrap();

    // The refusals changed nothing: a valid frame records and runs.
    // SAFETY: `cmd` is recording (above); the G-buffer is discarded into the sampled
    // layout and the hit images into GENERAL for storage writes (barriers below).
    unsafe {
        let mut t = Tracker::new();
        gbuffer.enter(&mut t, Access::UNDEFINED, Access::UNDEFINED);
        gbuffer
            .declare(&mut t, Access::COMPUTE_SAMPLED, Access::COMPUTE_SAMPLED)
            .unwrap();
        t.record(c, cmd).unwrap();
        for image in [&hit_uv, &hit_height] {
            sync::transition(
                c,
                cmd,
                image,
                Access::UNDEFINED,
                Access::COMPUTE_STORAGE_WRITE,
            );
        }
        pass.record(cmd, &inputs, Timestamps::Off).unwrap();
    }
    shot.submit_and_wait(c).unwrap();

    // SAFETY: the one submission completed.
    unsafe { pass.destroy() };
    for i in [
        &mut hit_uv,
        &mut hit_height,
        &mut half_hit,
        &mut small_hit,
        &mut motion32,
    ] {
        // SAFETY: the one submission completed.
        unsafe { i.destroy(c) };
    }
    // SAFETY: the one submission completed.
    unsafe {
        gbuffer.destroy(c);
        shot.destroy(c);
    }
    finish(ctx);
}
