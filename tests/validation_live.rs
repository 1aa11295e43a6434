//! The checks every GPU test relies on can fail: the validated context's counter sees a
//! synchronization hazard (synchronization validation is on) and an object left alive at
//! the device's destruction (the object tracker), and `common::finish` turns either into
//! a failed test. Without this, "zero validation messages" could pass vacuously.

mod common;

use ash::vk;
use dispmap::gpu::owned::Destroy;
use dispmap::gpu::sync::{self, Access};
use dispmap::gpu::{Buffer, Image, OneShot};
use gpu_allocator::MemoryLocation;

/// Two copies into the same image with no barrier between them: a write-after-write
/// hazard only synchronization validation reports.
#[test]
fn a_missing_barrier_is_reported() {
    let ctx = common::validated_context();
    let extent = vk::Extent2D {
        width: 4,
        height: 4,
    };
    let mut image = Image::new(
        &ctx,
        "live.image",
        vk::Format::R8G8B8A8_UNORM,
        extent,
        1,
        vk::ImageUsageFlags::TRANSFER_DST | vk::ImageUsageFlags::STORAGE,
    )
    .unwrap();
    let mut staging = Buffer::new(
        &ctx,
        "live.staging",
        64,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::CpuToGpu,
    )
    .unwrap();
    let mut shot = OneShot::new(&ctx, "live").unwrap();
    let cmd = shot.begin(&ctx).unwrap();
    // SAFETY: `cmd` was just begun by `shot.begin` (outside a render pass, on the
    // context's queue family) and is submitted and waited for below, before the image is
    // destroyed; the new image has never been accessed and has `TRANSFER_DST` usage.
    unsafe { sync::transition(&ctx, cmd, &image, Access::UNDEFINED, Access::TRANSFER_WRITE) };
    let region = vk::BufferImageCopy::default()
        .image_subresource(vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        })
        .image_extent(vk::Extent3D {
            width: 4,
            height: 4,
            depth: 1,
        });
    for _ in 0..2 {
        // SAFETY: `cmd` is recording; buffer and image are alive and sized for the copy.
        unsafe {
            ctx.device().cmd_copy_buffer_to_image(
                cmd,
                staging.raw,
                image.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            )
        };
    }
    shot.submit_and_wait(&ctx).unwrap();
    let errors = ctx.messages().errors();
    // SAFETY: the one submission completed.
    unsafe {
        shot.destroy(&ctx);
        staging.destroy(&ctx);
        image.destroy(&ctx);
    }
    assert!(
        errors > 0,
        "synchronization validation did not report the write-after-write hazard"
    );
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| common::finish(ctx)));
    assert!(
        result.is_err(),
        "common::finish passed a frame with a hazard"
    );
}

/// A fence never destroyed: the object tracker reports it when the device is destroyed,
/// which `common::finish` checks after the destruction.
#[test]
fn a_leaked_object_is_reported_at_teardown() {
    let ctx = common::validated_context();
    // SAFETY: valid device; the fence is leaked on purpose.
    let fence = unsafe {
        ctx.device()
            .create_fence(&vk::FenceCreateInfo::default(), None)
    }
    .unwrap();
    ctx.set_name(fence, "live.leaked_fence");
    assert_eq!(
        ctx.messages().total(),
        0,
        "nothing reported before teardown"
    );
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| common::finish(ctx)));
    assert!(
        result.is_err(),
        "common::finish did not fail on an object alive at vkDestroyDevice"
    );
}
