//! The `trace` pass: runs one method per pixel and writes the hit buffer.
//!
//! Bindings (set 0, push descriptors), mirrored by `glsl/common/trace.glsl`:
//!
//! | binding | resource | layout on entry |
//! |---|---|---|
//! | 0 | G-buffer `ray` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 1 | G-buffer `depth` (sampled) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 2 | height field (bilinear sampler) | `SHADER_READ_ONLY_OPTIMAL` |
//! | 3 | hit buffer (`R32G32B32A32_SFLOAT` storage, written) | `GENERAL` |
//!
//! Each pixel's hit is `(u, v, height, iterations)`; `height < 0` means no hit.

use crate::abi::TraceParams;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::pipeline::image_write;
use crate::gpu::{ComputePipeline, HeightTexture, Image};
use crate::method::{Method, MethodParams};
use crate::passes::gbuffer::GBuffer;
use crate::scene::addressing_code;
use ash::vk;

/// Format of the hit buffer.
pub const HIT_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

const BINDINGS: [vk::DescriptorType; 4] = [
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
    vk::DescriptorType::STORAGE_IMAGE,
];

/// The images the trace pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct TraceInputs<'a> {
    /// The G-buffer (ray and depth are read).
    pub gbuffer: &'a GBuffer,
    /// The height field.
    pub height: &'a HeightTexture,
    /// The hit buffer (written).
    pub hit: &'a Image,
}

/// The trace pass of one method.
pub struct TracePass {
    method: Method,
    pipeline: ComputePipeline,
    fetch_sampler: vk::Sampler,
}

impl TracePass {
    /// Builds the pipeline of `method`.
    pub fn new(ctx: &Context, method: Method) -> Result<Self> {
        let name = format!("trace[{}]", method.name());
        let pipeline = ComputePipeline::new(
            ctx,
            &name,
            &method.shader(),
            &BINDINGS,
            std::mem::size_of::<TraceParams>() as u32,
        )?;
        let fetch_sampler = match crate::passes::sampler(
            ctx,
            &format!("{name}.fetch_sampler"),
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        ) {
            Ok(s) => s,
            Err(e) => {
                let mut p = pipeline;
                p.destroy(ctx);
                return Err(e);
            }
        };
        Ok(TracePass {
            method,
            pipeline,
            fetch_sampler,
        })
    }

    /// The method this pass runs.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Records the dispatch over the whole frame.
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: TraceInputs,
        params: &MethodParams,
    ) {
        let TraceInputs {
            gbuffer,
            height,
            hit,
        } = inputs;
        let fetch = |image: &Image| {
            [vk::DescriptorImageInfo {
                sampler: self.fetch_sampler,
                image_view: image.view,
                image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            }]
        };
        let ray = fetch(&gbuffer.ray);
        let depth = fetch(&gbuffer.depth);
        let heights = [height.descriptor()];
        let hits = [vk::DescriptorImageInfo {
            sampler: vk::Sampler::null(),
            image_view: hit.view,
            image_layout: vk::ImageLayout::GENERAL,
        }];
        let writes = [
            image_write(0, BINDINGS[0], &ray),
            image_write(1, BINDINGS[1], &depth),
            image_write(2, BINDINGS[2], &heights),
            image_write(3, BINDINGS[3], &hits),
        ];
        let extent = hit.extent;
        let push = TraceParams {
            frame_size: [extent.width, extent.height],
            map_size: height.size(),
            steps: params.steps,
            refine_steps: params.refine_steps,
            addressing: addressing_code(height.addressing),
            flags: 0,
        };
        self.pipeline.dispatch(
            ctx,
            cmd,
            &writes,
            bytemuck::bytes_of(&push),
            extent.width,
            extent.height,
        );
    }

    /// Destroys the pipeline and sampler.
    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
        // SAFETY: caller guarantees no pending use.
        unsafe { ctx.device().destroy_sampler(self.fetch_sampler, None) };
        self.fetch_sampler = vk::Sampler::null();
    }
}
