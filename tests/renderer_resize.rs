//! `Renderer::resize` (the viewer's window resizes): a resized renderer renders exactly
//! what a new renderer of that size renders, with validation on; a refused size keeps
//! the old one. `Renderer::color_image` has the frame's size.

mod common;

use common::{asset_map, finish, validated_context};
use dispmap::heightfield::Convention;
use dispmap::method::{Method, MethodParams};
use dispmap::renderer::{RenderSettings, Renderer};
use dispmap::scene::{Camera, Scene};

fn settings(method: Method, width: u32, height: u32) -> RenderSettings {
    RenderSettings {
        shadows: Default::default(),
        width,
        height,
        method,
        params: MethodParams::with_steps(24),
        scene: Scene {
            camera: Camera {
                elevation_deg: 20.0,
                ..Camera::default()
            },
            ..Scene::default()
        },
    }
}

#[test]
fn a_resized_renderer_renders_what_a_new_one_of_that_size_renders() {
    let ctx = validated_context();
    let field = asset_map("rocks_depth.jpg", Convention::Depth);
    // dig: per-size corner grids; the depth output: a per-size image of the pass.
    for method in [Method::Relief, Method::Dig] {
        let mut resized = Renderer::new(&ctx, &field, settings(method, 128, 72)).unwrap();
        resized.set_depth_output(true).unwrap();
        resized.render().unwrap();
        resized.resize(96, 64).unwrap();
        assert_eq!(
            (resized.settings().width, resized.settings().height),
            (96, 64)
        );
        let e = resized.color_image().extent;
        assert_eq!((e.width, e.height), (96, 64));
        assert!(
            resized.read_depth().is_err(),
            "no frame of the new size has written the depth yet"
        );
        resized.render().unwrap();

        let mut fresh = Renderer::new(&ctx, &field, settings(method, 96, 64)).unwrap();
        fresh.set_depth_output(true).unwrap();
        fresh.render().unwrap();
        assert_eq!(
            resized.read_color().unwrap(),
            fresh.read_color().unwrap(),
            "{method}"
        );
        assert_eq!(
            bytemuck::cast_slice::<_, u8>(&resized.read_hits().unwrap()),
            bytemuck::cast_slice::<_, u8>(&fresh.read_hits().unwrap()),
            "{method}"
        );
        assert_eq!(resized.read_depth().unwrap(), fresh.read_depth().unwrap());

        // A refused size keeps the renderer as it was.
        let e = resized.resize(0, 64).unwrap_err();
        assert!(e.to_string().contains("size"), "{e}");
        assert_eq!(
            (resized.settings().width, resized.settings().height),
            (96, 64)
        );
        resized.render().unwrap();
        assert_eq!(resized.read_color().unwrap(), fresh.read_color().unwrap());
    }
    finish(ctx);
}

#[test]
fn extensions_the_loader_or_device_lacks_are_refused_by_name() {
    use dispmap::context::{Context, ContextOptions};
    let options = ContextOptions {
        validation: Some(true),
        device: None,
    };
    let e = Context::with_extensions(&options, &[c"VK_DISPMAP_no_such_instance_extension"], &[])
        .err()
        .expect("an unknown instance extension is refused");
    assert!(
        e.to_string()
            .contains("VK_DISPMAP_no_such_instance_extension"),
        "{e}"
    );
    let e = Context::with_extensions(&options, &[], &[c"VK_DISPMAP_no_such_device_extension"])
        .err()
        .expect("an unknown device extension is refused");
    assert!(
        e.to_string()
            .contains("VK_DISPMAP_no_such_device_extension"),
        "{e}"
    );
    // What every device has: the context is made, and passes the teardown check.
    let ctx = Context::with_extensions(&options, &[], &[ash::khr::push_descriptor::NAME]).unwrap();
    finish(std::sync::Arc::new(ctx));
}
