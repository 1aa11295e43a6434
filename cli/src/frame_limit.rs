//! The largest frame a device can render: a frame's largest image (the G-buffer's ray
//! image, `R32G32B32A32_SFLOAT`, 16 bytes per pixel; the hit uv image, 8) and their
//! read-back buffers must each fit the device's `maxResourceSize` for that format and its
//! `maxMemoryAllocationSize`. [`check`] refuses a frame size above that before anything
//! is allocated, naming the limit (a 16384x16384 frame needs 4 GiB per image; lavapipe
//! takes 2 GiB).

use anyhow::{Result, bail};
use ash::vk;
use dispmap::context::Context;
use dispmap::passes::{gbuffer::RAY_FORMAT, trace::HIT_UV_FORMAT};

/// Bytes per pixel of the frame's largest image (the ray, RGBA f32).
pub const LARGEST_PIXEL_BYTES: u64 = 16;

/// The limit a frame runs into, for messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Limit {
    /// The most bytes one image or allocation may have.
    pub bytes: u64,
    /// Which device limit that is.
    pub name: &'static str,
}

impl Limit {
    /// The most pixels a frame may have.
    pub fn pixels(&self) -> u64 {
        self.bytes / LARGEST_PIXEL_BYTES
    }
}

/// The device's limit on one frame image: the smaller of `maxResourceSize` (for the ray
/// and hit uv images' formats, usage and tiling) and `maxMemoryAllocationSize`.
pub fn limit(ctx: &Context) -> Limit {
    let (instance, pd) = (ctx.instance(), ctx.physical_device());
    let mut limit = Limit {
        bytes: u64::MAX,
        name: "no limit",
    };
    let usages = [
        (
            RAY_FORMAT,
            vk::ImageUsageFlags::COLOR_ATTACHMENT
                | vk::ImageUsageFlags::SAMPLED
                | vk::ImageUsageFlags::TRANSFER_SRC,
        ),
        (
            HIT_UV_FORMAT,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        ),
    ];
    for (format, usage) in usages {
        // SAFETY: `pd` was enumerated from `instance`, which the context keeps alive; the
        // query only fills the returned struct.
        let props = unsafe {
            instance.get_physical_device_image_format_properties(
                pd,
                format,
                vk::ImageType::TYPE_2D,
                vk::ImageTiling::OPTIMAL,
                usage,
                vk::ImageCreateFlags::empty(),
            )
        };
        if let Ok(p) = props
            && p.max_resource_size < limit.bytes
        {
            limit = Limit {
                bytes: p.max_resource_size,
                name: "maxResourceSize (R32G32B32A32_SFLOAT images)",
            };
        }
    }
    let mut maintenance3 = vk::PhysicalDeviceMaintenance3Properties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut maintenance3);
    // SAFETY: as above; Vulkan 1.1 (which dispmap requires) has the query, and the chain
    // holds one struct that outlives the call.
    unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    let allocation = maintenance3.max_memory_allocation_size;
    if allocation > 0 && allocation < limit.bytes {
        limit = Limit {
            bytes: allocation,
            name: "maxMemoryAllocationSize",
        };
    }
    limit
}

/// Refuses a `width x height` frame whose largest images do not fit the device
/// ([`limit`]); `option` names where the size came from (`--size`).
pub fn check(ctx: &Context, width: u32, height: u32, option: &str) -> Result<()> {
    let limit = limit(ctx);
    let pixels = u64::from(width) * u64::from(height);
    if pixels > limit.pixels() {
        let side = (limit.pixels() as f64).sqrt().floor() as u64;
        bail!(
            "invalid {option}: a {width}x{height} frame needs {} bytes per image (the ray \
             image: {LARGEST_PIXEL_BYTES} bytes per pixel), more than device {}'s {} of {} \
             bytes: at most {} pixels (e.g. {side}x{side})",
            pixels * LARGEST_PIXEL_BYTES,
            ctx.info().name,
            limit.name,
            limit.bytes,
            limit.pixels()
        );
    }
    Ok(())
}
