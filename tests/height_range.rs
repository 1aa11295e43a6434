//! The `height_range` map preparation: asked for through the displacement pass's table,
//! built once per map in its own scope by the host's preparation, its GPU range equal to
//! the minimum and maximum of the map's texels computed on the CPU (exactly for an
//! `R32_SFLOAT` map of odd size, its extremes in the last partial block; to the unorm
//! decoding's ulp for an `R8_UNORM` map shared by two materials), counted in the memory report and retired when no longer asked for.

mod common;

use common::{finish, validated_context};
use dispmap::embed::{DisplacementPass, MaterialSettings, PassSettings, Timestamps};
use dispmap::gpu::OneShot;
use dispmap::gpu::owned::Destroy;
use dispmap::heightfield::{Addressing, HeightField, Texels};
use dispmap::method::{Method, MethodParams};
use dispmap::passes::PassName;
use dispmap::passes::height_range::HeightRange;

/// `[min, max]` of the field's texels as decoded on the CPU.
fn cpu_range(field: &HeightField) -> [f32; 2] {
    let mut r = [f32::INFINITY, f32::NEG_INFINITY];
    for j in 0..field.height() {
        for i in 0..field.width() {
            let h = field.texel(i, j);
            r = [r[0].min(h), r[1].max(h)];
        }
    }
    r
}

/// A deterministic pseudo-random value in `[0, 1)`.
fn noise(i: u32) -> f32 {
    let x = i.wrapping_mul(2_654_435_761).rotate_left(13) ^ 0x9e37_79b9;
    (x >> 8) as f32 / (1u32 << 24) as f32
}

#[test]
fn the_gpu_height_range_is_the_texels_min_and_max() {
    let ctx = validated_context();
    let shot = OneShot::new(&ctx, "test.shot").unwrap();
    // 37 x 23: a partial 4x4 block and a partial workgroup on both axes; the extremes in
    // the last column and row, inside that partial block.
    let (w, h) = (37, 23);
    let mut values: Vec<f32> = (0..w * h).map(|i| 0.2 + 0.6 * noise(i)).collect();
    values[(5 * w + 36) as usize] = 0.062_5;
    values[(22 * w + 35) as usize] = 0.968_75;
    let r32 = HeightField::from_heights(w, h, values, "r32").unwrap();
    let r8 = HeightField::from_texels(
        64,
        50,
        Texels::R8(
            (0..64 * 50)
                .map(|i| 20 + (noise(i) * 200.0) as u8)
                .collect(),
        ),
        "r8",
    )
    .unwrap();
    let settings = |method| MaterialSettings {
        method,
        params: MethodParams::for_method(method),
        depth_scale: 0.1,
        addressing: Addressing::Repeat,
    };
    let mut pass = DisplacementPass::new(
        ctx.clone(),
        &r32,
        PassSettings {
            method: Method::Relief,
            params: MethodParams::for_method(Method::Relief),
            depth_scale: 0.1,
            addressing: Addressing::Repeat,
            extent: ash::vk::Extent2D {
                width: 16,
                height: 16,
            },
            frames_in_flight: 1,
        },
    )
    .unwrap();
    let first = pass.primary();
    let second = pass.add_material(&r8, settings(Method::Exact)).unwrap();
    let third = pass.add_material(&r8, settings(Method::Relief)).unwrap();
    assert!(pass.map_preparation::<HeightRange>(first).is_none());

    // Not asked for: the preparation records the uploads and exact's pyramid, no range.
    let cmd = shot.begin(&ctx).unwrap();
    // SAFETY: `cmd` was begun above and is submitted and waited for below.
    let prepared = unsafe { pass.record_preparation(cmd, Timestamps::Off) }.unwrap();
    shot.submit_and_wait(&ctx).unwrap();
    assert!(!prepared.passes.contains(&PassName::HeightRange));
    assert_eq!(pass.memory().map_preparations, 0);

    pass.set_map_preparation::<HeightRange>(true).unwrap();
    assert!(pass.preparation_pending());
    let cmd = shot.begin(&ctx).unwrap();
    // SAFETY: as above.
    let prepared = unsafe { pass.record_preparation(cmd, Timestamps::Off) }.unwrap();
    shot.submit_and_wait(&ctx).unwrap();
    assert_eq!(prepared.passes, [PassName::HeightRange]);
    assert!(!pass.preparation_pending(), "built once per map");
    // Two maps (the r8 one shared by two materials): one 8-byte buffer each, at least.
    assert!(pass.memory().map_preparations >= 16);
    for (id, field) in [(first, &r32), (second, &r8), (third, &r8)] {
        let range = pass.map_preparation::<HeightRange>(id).expect("built");
        // SAFETY: the preparation that built it was waited for.
        let gpu = unsafe { range.read() }.unwrap();
        let cpu = cpu_range(field);
        if field.label() == "r32" {
            // Floats: the GPU reads the texels as they are, and the reduction is exact.
            assert_eq!(gpu, cpu, "r32: GPU {gpu:?}, CPU {cpu:?}");
        } else {
            // Unorm texels: the same texels, each decoded to within an ulp of c / 255
            // (lavapipe's conversion differs from the CPU's division by one ulp).
            for (g, c) in gpu.iter().zip(cpu) {
                assert!(
                    (g - c).abs() <= c * f32::EPSILON,
                    "r8: GPU {gpu:?}, CPU {cpu:?}"
                );
            }
        }
    }
    assert_eq!(cpu_range(&r32), [0.062_5, 0.968_75]);
    assert_eq!(
        HeightRange::depths([0.25, 0.75], 0.1),
        [0.25 * 0.1, 0.75 * 0.1]
    );

    pass.set_map_preparation::<HeightRange>(false).unwrap();
    assert!(pass.map_preparation::<HeightRange>(first).is_none());
    assert!(!pass.preparation_pending());
    // SAFETY: every submission was waited for.
    unsafe {
        pass.destroy();
        let mut shot = shot;
        shot.destroy(&ctx);
    }
    drop(pass);
    finish(ctx);
}
