//! The height field on the GPU: a sampled image at the map's precision and a linear
//! sampler with the map's addressing.
//!
//! Every method reads level 0 (`textureLod(.., 0)`, `texelFetch(.., 0)`) unless level of
//! detail is on, when the marchers sample at the pixel's footprint level
//! (`glsl/common/heightfield.glsl`). So the image has a mip chain (box-filtered by linear
//! 2:1 blits) only when it is created for level of detail (`chain`) and the format
//! supports linear blits: a third more memory is spent only where it is read. Without
//! blit support the image has one level and the level-of-detail sampling reads level 0.
//! Switching level of detail on or off later re-derives the texture on the GPU from the
//! old one's level 0 ([`HeightTexture::create_like`], [`HeightTexture::record_copy_from`]):
//! the height field's bytes are not kept on the host.
//!
//! Two views: [`HeightTexture::descriptor`] binds level 0 alone, what every pass reads
//! unless level of detail is on, and [`HeightTexture::descriptor_lod`] the whole chain.
//! A host engine's own image can be a height texture too ([`HeightTexture::from_host`]):
//! dispmap's views of it put the height channel in `r`, its mip chain is the host's, and
//! nothing is uploaded or filled (`crate::embed::HostHeightMap`).
//!
//! The single-level view is not only tidier: lavapipe compiles its samplers for the
//! view's level count, and through a view with a mip chain every filtered fetch took the
//! general path (measured at 640x360: `bump`'s trace 14.4 -> 5.8 ms, its shade 15.6 ->
//! 6.8 ms with level 0 alone).

use super::commands::{OneShot, record_copy_to_level0};
use super::sync::Access;
use super::track::{Handle, Tracker};
use super::{Buffer, Image};
use crate::context::Context;
use crate::error::{Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::heightfield::{Addressing, HeightField};
use ash::vk;

/// The uploaded height field.
pub struct HeightTexture {
    /// The image (`R8_UNORM`, `R16_UNORM` or `R32_SFLOAT`), in
    /// `SHADER_READ_ONLY_OPTIMAL` after upload; for a host's image
    /// ([`HeightTexture::from_host`]) the host's, borrowed, with dispmap's swizzled view.
    pub image: Image,
    /// Bilinear sampler with the addressing mode (repeat or clamp to edge).
    pub sampler: vk::Sampler,
    /// The addressing mode.
    pub addressing: Addressing,
    /// A view of level 0 alone (`None` when the image has one level: then `image.view`).
    base_view: Option<vk::ImageView>,
    /// A host engine's image ([`HeightTexture::from_host`]): `image` is borrowed (no
    /// memory of dispmap's), its views dispmap's; the format whose texels hold the
    /// sampled channel's values exactly (see [`HeightTexture::texel_format`]).
    host: Option<vk::Format>,
}

impl HeightTexture {
    /// Uploads `field` (and, with `chain`, builds its mip chain) and leaves it readable by
    /// compute shaders.
    pub fn upload(
        ctx: &Context,
        shot: &OneShot,
        field: &HeightField,
        addressing: Addressing,
        chain: bool,
    ) -> Result<Self> {
        let (mut texture, mut staging) = Self::create_for_upload(ctx, field, addressing, chain)?;
        let result = (|| {
            let cmd = shot.begin(ctx)?;
            // SAFETY: `cmd` was just begun by `shot.begin` (outside a render pass, on the
            // context's queue family) and is submitted and waited for below, before
            // `staging` is destroyed; `staging` came with `texture` from
            // `create_for_upload`, and the new texture has no earlier accesses.
            unsafe { texture.record_upload(ctx, cmd, &staging)? };
            shot.submit_and_wait(ctx)
        })();
        // SAFETY: the one-shot submission that used it was waited for (or never made).
        unsafe { staging.destroy(ctx) };
        if let Err(e) = result {
            // SAFETY: the one-shot submission that used it was waited for (or never made).
            unsafe { texture.destroy(ctx) };
            return Err(e);
        }
        Ok(texture)
    }

    /// Creates the image (with a mip chain when `chain`) and sampler without touching a
    /// queue, plus a filled staging buffer: the contents arrive when
    /// [`HeightTexture::record_upload`] is recorded and executed (the host-engine path,
    /// which never submits). The caller destroys the staging buffer once that copy has
    /// executed.
    pub fn create_for_upload(
        ctx: &Context,
        field: &HeightField,
        addressing: Addressing,
        chain: bool,
    ) -> Result<(Self, Buffer)> {
        let staging = crate::gpu::commands::staging_buffer(
            ctx,
            &format!("heightfield[{}].staging", field.label()),
            field.bytes(),
        )?;
        // SAFETY: no command has used the guarded value yet; it is kept before any frame records it.
        let staging = unsafe { crate::gpu::owned::Guard::new(ctx, staging) };
        let extent = vk::Extent2D {
            width: field.width(),
            height: field.height(),
        };
        let name = format!("heightfield[{}]", field.label());
        let texture = Self::create(ctx, &name, field.format(), extent, addressing, chain)?;
        Ok((texture, staging.keep()))
    }

    /// Creates an empty texture (contents undefined until a fill is recorded).
    fn create(
        ctx: &Context,
        name: &str,
        format: vk::Format,
        extent: vk::Extent2D,
        addressing: Addressing,
        chain: bool,
    ) -> Result<Self> {
        let levels = mip_levels(ctx, format, extent, chain);
        // TRANSFER_SRC: blit source of the chain and copy source of `record_copy_from`.
        let usage = vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_DST
            | vk::ImageUsageFlags::TRANSFER_SRC;
        let mut image = Image::new(ctx, name, format, extent, levels, usage)?;
        let base_view = if levels > 1 {
            match image.level_view(ctx, 0, &format!("{name}.level0")) {
                Ok(v) => Some(v),
                Err(e) => {
                    // SAFETY: built above and never used by a command.
                    unsafe { image.destroy(ctx) };
                    return Err(e);
                }
            }
        } else {
            None
        };
        match crate::gpu::pipeline::sampler(
            ctx,
            "heightfield.sampler",
            vk::Filter::LINEAR,
            address_mode(addressing),
        ) {
            Ok(sampler) => Ok(HeightTexture {
                image,
                sampler,
                addressing,
                base_view,
                host: None,
            }),
            Err(e) => {
                if let Some(v) = base_view {
                    // SAFETY: created above, never used.
                    unsafe { ctx.device().destroy_image_view(v, None) };
                }
                // SAFETY: built above and never used by a command.
                unsafe { image.destroy(ctx) };
                Err(e)
            }
        }
    }

    /// A host engine's sampled image as a height texture: views of it made by dispmap
    /// (every level, and level 0 alone) whose component mapping puts the image's
    /// `channel` in `r` (`g`, `b` zero, `a` one: what a one-channel map samples as), and a
    /// linear sampler with `addressing`. `texel_format`: a format whose texels hold every
    /// value the channel can sample as, exactly (`R8_UNORM` for an 8-bit unorm channel,
    /// `R16_UNORM` for a 16-bit one), or the image's format where there is none (the
    /// pyramid then keeps its `R32_SFLOAT` chain). Nothing is recorded: the host's image
    /// keeps its contents, layout and mip chain. [`Destroy::destroy`] destroys the views
    /// and the sampler, never the image.
    #[allow(clippy::too_many_arguments)]
    pub fn from_host(
        ctx: &Context,
        name: &str,
        raw: vk::Image,
        format: vk::Format,
        extent: vk::Extent2D,
        levels: u32,
        usage: vk::ImageUsageFlags,
        channel: vk::ComponentSwizzle,
        texel_format: vk::Format,
        addressing: Addressing,
    ) -> Result<Self> {
        let view = |level_count: u32, label: &str| -> Result<vk::ImageView> {
            let info = vk::ImageViewCreateInfo::default()
                .image(raw)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(format)
                .components(vk::ComponentMapping {
                    r: channel,
                    g: vk::ComponentSwizzle::ZERO,
                    b: vk::ComponentSwizzle::ZERO,
                    a: vk::ComponentSwizzle::ONE,
                })
                .subresource_range(vk::ImageSubresourceRange {
                    level_count,
                    ..crate::gpu::image::full_range(format, levels)
                });
            // SAFETY: the caller's image (alive, of `format` with `levels` levels and
            // SAMPLED usage: `from_host`'s callers check the host's description); the
            // view names levels it has, in its own format.
            let v =
                unsafe { ctx.device().create_image_view(&info, None) }.vk("vkCreateImageView")?;
            ctx.set_name(v, &format!("{name}.{label}"));
            Ok(v)
        };
        let all = view(levels, "view")?;
        let base_view = if levels > 1 {
            match view(1, "level0") {
                Ok(v) => Some(v),
                Err(e) => {
                    // SAFETY: created above, never used.
                    unsafe { ctx.device().destroy_image_view(all, None) };
                    return Err(e);
                }
            }
        } else {
            None
        };
        let image = Image::borrowed(raw, all, format, extent, levels, usage, name);
        let mut texture = HeightTexture {
            image,
            sampler: vk::Sampler::null(),
            addressing,
            base_view,
            host: Some(texel_format),
        };
        match crate::gpu::pipeline::sampler(
            ctx,
            "heightfield.sampler",
            vk::Filter::LINEAR,
            address_mode(addressing),
        ) {
            Ok(sampler) => {
                texture.sampler = sampler;
                Ok(texture)
            }
            Err(e) => {
                // SAFETY: the views were created above and never used.
                unsafe { texture.destroy(ctx) };
                Err(e)
            }
        }
    }

    /// Whether the image is a host engine's ([`HeightTexture::from_host`]).
    pub fn is_host(&self) -> bool {
        self.host.is_some()
    }

    /// The format whose texels hold the sampled values exactly: the image's own format,
    /// or for a host image the one [`HeightTexture::from_host`] was given (what decides
    /// the cell pyramid's storage format, `storage_format` in `passes::pyramid`).
    pub fn texel_format(&self) -> vk::Format {
        self.host.unwrap_or(self.image.format)
    }

    /// Whether the texture has the mip chain level of detail reads.
    pub fn has_chain(&self) -> bool {
        self.image.mip_levels > 1
    }

    /// Whether a texture for `chain` would differ from this one in its levels (false
    /// where the format has no linear blits: it keeps one level either way; always false
    /// for a host image, whose mip chain is the host's).
    pub fn differs_for(&self, ctx: &Context, chain: bool) -> bool {
        !self.is_host()
            && mip_levels(ctx, self.image.format, self.image.extent, chain) != self.image.mip_levels
    }

    /// An empty texture of the same map (size, format, addressing, name), with a mip chain
    /// when `chain`; [`HeightTexture::record_copy_from`] fills it from `self`.
    pub fn create_like(&self, ctx: &Context, chain: bool) -> Result<Self> {
        Self::create(
            ctx,
            self.image.name(),
            self.image.format,
            self.image.extent,
            self.addressing,
            chain,
        )
    }

    /// Records the fill of this texture from `source`, a texture of the same map in
    /// `SHADER_READ_ONLY_OPTIMAL` (frames in flight may still sample it): its level 0 is
    /// copied (bit for bit) and this texture's chain blitted from it as in
    /// [`HeightTexture::record_upload`]; `source` ends readable by compute shaders again.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `source` is a texture of the same size and format (e.g. `self` came from
    ///   `source.create_like`), distinct from `self`, whose level 0 is in
    ///   `SHADER_READ_ONLY_OPTIMAL` with its writes visible to compute-shader sampled
    ///   reads ([`Access::COMPUTE_SAMPLED`], as every fill leaves it) when the command
    ///   buffer executes.
    /// * `self`'s contents may be discarded: no earlier access of it is pending.
    /// * Both textures stay alive until the command buffer has executed.
    pub unsafe fn record_copy_from(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        source: &HeightTexture,
    ) -> Result<()> {
        // SAFETY: this function's # Safety contract is `record_fill`'s for an image
        // source.
        unsafe { self.record_fill(ctx, cmd, Level0::Image(&source.image)) }
    }

    /// Records the copy of `staging` (from [`HeightTexture::create_for_upload`]) into
    /// level 0 and the mip chain: every level discarded -> `TRANSFER_DST_OPTIMAL`, copy,
    /// then per level a linear 2:1 blit from the level above (the box average of the
    /// heights, for the level-of-detail sampling; level 0 stays the map, bit for bit),
    /// and every level -> `SHADER_READ_ONLY_OPTIMAL` visible to
    /// compute-shader sampled reads. All transfer work is in the `ALL_TRANSFER` stage.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `staging` is the buffer [`HeightTexture::create_for_upload`] returned with this
    ///   texture (level 0's texels, tightly packed).
    /// * The texture's contents may be discarded: no earlier access of it is pending.
    /// * The texture and `staging` stay alive until the command buffer has executed.
    pub unsafe fn record_upload(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        staging: &Buffer,
    ) -> Result<()> {
        // SAFETY: this function's # Safety contract is `record_fill`'s for a buffer
        // source.
        unsafe { self.record_fill(ctx, cmd, Level0::Buffer(staging)) }
    }

    /// Level 0 from `source`, then the chain (see [`HeightTexture::record_upload`]).
    ///
    /// # Safety
    /// As [`HeightTexture::record_upload`] for a buffer source, as
    /// [`HeightTexture::record_copy_from`] for an image source (level 0 of a texture of
    /// the same size and format, distinct from this one, sampled-readable).
    unsafe fn record_fill(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        source: Level0,
    ) -> Result<()> {
        let image = &self.image;
        // Each level is a resource of the fill's tracker, which places every barrier from
        // the declared accesses: every level enters discarded (this function's contract)
        // and is written once (level 0 by the copy, each other by its blit); an image
        // source's level 0 enters sampled-readable and returns there after the copy.
        let mut t = Tracker::new();
        for l in 0..image.mip_levels {
            t.enter(Handle::level(image, l), Access::UNDEFINED);
            t.declare(Handle::level(image, l), Access::TRANSFER_WRITE)?;
        }
        if let Level0::Image(src) = &source {
            t.enter(Handle::level(src, 0), Access::COMPUTE_SAMPLED);
            t.declare(Handle::level(src, 0), Access::TRANSFER_READ)?;
        }
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the images are alive, this one's contents may be discarded and the
        // source's level 0 is sampled-readable.
        unsafe { t.record(ctx, cmd)? };
        let aspect = image.range().aspect_mask;
        let layers = |l: u32| vk::ImageSubresourceLayers {
            aspect_mask: aspect,
            mip_level: l,
            base_array_layer: 0,
            layer_count: 1,
        };
        let extent = vk::Extent3D {
            width: image.extent.width,
            height: image.extent.height,
            depth: 1,
        };
        match source {
            // SAFETY: this function's # Safety contract: `staging` holds level 0 tightly
            // packed; level 0 is in `TRANSFER_DST_OPTIMAL` (the barriers above); the
            // image has `TRANSFER_DST` usage (`create`).
            Level0::Buffer(staging) => unsafe { record_copy_to_level0(ctx, cmd, staging, image) },
            Level0::Image(src) => {
                let region = vk::ImageCopy::default()
                    .src_subresource(layers(0))
                    .dst_subresource(layers(0))
                    .extent(extent);
                // SAFETY: this function's # Safety contract: `cmd` is recording outside a
                // render pass; both images are alive, of the same format and size, and
                // distinct; they are in the layouts named (barriers above).
                unsafe {
                    ctx.device().cmd_copy_image(
                        cmd,
                        src.raw,
                        vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                        image.raw,
                        vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                        &[region],
                    )
                };
                // The source back to sampled reads (frames in flight read it).
                t.declare(Handle::level(src, 0), Access::COMPUTE_SAMPLED)?;
            }
        }
        let corner = |l: u32| vk::Offset3D {
            x: (image.extent.width >> l).max(1) as i32,
            y: (image.extent.height >> l).max(1) as i32,
            z: 1,
        };
        for l in 1..image.mip_levels {
            t.declare(Handle::level(image, l - 1), Access::TRANSFER_READ)?;
            // SAFETY: this function's # Safety contract (`cmd` recording outside a render
            // pass, the images alive); the tracker knows every level's state.
            unsafe { t.record(ctx, cmd)? };
            let blit = vk::ImageBlit::default()
                .src_subresource(layers(l - 1))
                .src_offsets([vk::Offset3D::default(), corner(l - 1)])
                .dst_subresource(layers(l))
                .dst_offsets([vk::Offset3D::default(), corner(l)]);
            // SAFETY: as above; the levels are in the layouts named, the format supports
            // linear blits (checked by `mip_levels`).
            unsafe {
                ctx.device().cmd_blit_image(
                    cmd,
                    image.raw,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    image.raw,
                    vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                    &[blit],
                    vk::Filter::LINEAR,
                )
            };
        }
        for l in 0..image.mip_levels {
            t.declare(Handle::level(image, l), Access::COMPUTE_SAMPLED)?;
        }
        // SAFETY: as above.
        unsafe { t.record(ctx, cmd) }
    }

    /// Size in texels.
    pub fn size(&self) -> [u32; 2] {
        [self.image.extent.width, self.image.extent.height]
    }

    /// Descriptor info for a combined image sampler of level 0 alone (every pass, unless
    /// level of detail is on).
    pub fn descriptor(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: self.base_view.unwrap_or(self.image.view),
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }
    }

    /// Descriptor info for a combined image sampler of the whole mip chain (the trace pass
    /// with level of detail on).
    pub fn descriptor_lod(&self) -> vk::DescriptorImageInfo {
        vk::DescriptorImageInfo {
            image_view: self.image.view,
            ..self.descriptor()
        }
    }
}

impl Destroy for HeightTexture {
    /// Destroys image and sampler.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            if let Some(v) = self.base_view.take() {
                ctx.device().destroy_image_view(v, None);
            }
            if self.host.is_some() {
                // The host's image: only the view dispmap made goes.
                ctx.device().destroy_image_view(self.image.view, None);
                self.image.view = vk::ImageView::null();
            } else {
                self.image.destroy(ctx);
            }
            ctx.device().destroy_sampler(self.sampler, None);
            self.sampler = vk::Sampler::null();
        }
    }

    /// The image's memory (0 for a host's image: the host's memory).
    fn bytes(&self) -> u64 {
        self.image.bytes()
    }
}

/// Where level 0 comes from.
enum Level0<'a> {
    /// A staging buffer holding the map's texels, tightly packed.
    Buffer(&'a Buffer),
    /// Level 0 of another texture of the same map, sampled-readable.
    Image(&'a Image),
}

/// With `chain`, the full mip chain of `extent` when `format` supports linear blits
/// (sources and destinations, optimal tiling); else 1.
fn mip_levels(ctx: &Context, format: vk::Format, extent: vk::Extent2D, chain: bool) -> u32 {
    if !chain {
        return 1;
    }
    let needed = vk::FormatFeatureFlags::BLIT_SRC
        | vk::FormatFeatureFlags::BLIT_DST
        | vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR;
    if ctx.format_features(format).contains(needed) {
        32 - extent.width.max(extent.height).leading_zeros()
    } else {
        1
    }
}

fn address_mode(addressing: Addressing) -> vk::SamplerAddressMode {
    match addressing {
        Addressing::Repeat => vk::SamplerAddressMode::REPEAT,
        Addressing::Clamp => vk::SamplerAddressMode::CLAMP_TO_EDGE,
    }
}
