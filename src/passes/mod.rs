//! The passes of a frame, one file each: `gbuffer` (graphics), `pyramid` (the min-reduce
//! chain), `dig` (the DIG corner pass), `trace` (the method), `shadow` (optional
//! self-shadowing) and `shade`; on request `hit_depth` (the corrected depth of the
//! displaced surface) and `depth_resolve` (graphics: that depth into a depth
//! attachment). Every pass only
//! records into a command buffer it is given; the caller places the barriers between
//! passes (see [`crate::renderer`] for the order and
//! the layouts each pass expects).

pub mod depth_resolve;
pub mod dig;
pub mod gbuffer;
pub mod hit_depth;
pub mod pyramid;
pub mod shade;
pub mod shadow;
pub mod trace;

use crate::context::Context;
use crate::error::{Result, VkContext};
use ash::vk;

/// Creates a sampler named `name`.
pub(crate) fn sampler(
    ctx: &Context,
    name: &str,
    filter: vk::Filter,
    address: vk::SamplerAddressMode,
) -> Result<vk::Sampler> {
    let info = vk::SamplerCreateInfo::default()
        .mag_filter(filter)
        .min_filter(filter)
        .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
        .address_mode_u(address)
        .address_mode_v(address)
        .address_mode_w(address)
        .max_lod(vk::LOD_CLAMP_NONE);
    // SAFETY: valid device and create info.
    let sampler = unsafe { ctx.device().create_sampler(&info, None) }.vk("vkCreateSampler")?;
    ctx.set_name(sampler, name);
    Ok(sampler)
}
