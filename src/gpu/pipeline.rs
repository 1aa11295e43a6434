//! Compute pipelines whose resources are bound with push descriptors.

use super::Image;
use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use crate::gpu::owned::Destroy;
use crate::shaders::{Shader, ShaderBinding};
use ash::vk;

/// A compute pipeline, its layout and its push-descriptor set layout.
pub struct ComputePipeline {
    /// The pipeline.
    pub pipeline: vk::Pipeline,
    /// Its layout (set 0: push descriptors; push constants for the compute stage).
    pub layout: vk::PipelineLayout,
    /// Set 0's layout.
    pub set_layout: vk::DescriptorSetLayout,
    /// Workgroup size in x and y (from the shader's `local_size`, fixed at 8x8).
    pub local_size: [u32; 2],
    /// The shader's bindings as its SPIR-V declares them ([`Shader::bindings`]): what a
    /// dispatch reads and writes, for the barrier tracker ([`crate::gpu::track`]).
    pub bindings: &'static [ShaderBinding],
}

/// Workgroup size every dispmap compute shader declares (`glsl/common/frame.glsl`).
pub const LOCAL_SIZE: [u32; 2] = [8, 8];

impl ComputePipeline {
    /// Builds a pipeline from `shader` whose set 0 is the shader's own bindings as its
    /// SPIR-V declares them ([`Shader::bindings`]: numbers, types, counts) and
    /// `push_constant_size` bytes of push constants. `declared` is what the pass binds,
    /// `(GLSL name, type)`: it must be exactly the shader's table ([`check_declared`]), so
    /// a binding added, removed or retyped in the GLSL is an error here, not a validation
    /// message at the first dispatch. Binding numbers exist only in the GLSL: the pass's
    /// descriptor writes name their bindings ([`ComputePipeline::image`],
    /// [`ComputePipeline::buffer`]).
    pub fn new(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        declared: &[(&str, vk::DescriptorType)],
        push_constant_size: u32,
    ) -> Result<Self> {
        Self::specialized(ctx, name, shader, declared, push_constant_size, &[])
    }

    /// As [`ComputePipeline::new`], with the shader's specialization constants
    /// `(GLSL name, value)` set (a variant compiled with a feature on or off, its dead
    /// branches removed by the driver); a name the shader does not declare is an error.
    /// Every compute pipeline also gets the context's `TRAVERSAL_RULES`
    /// ([`Context::traversal_rules`]) where its shader declares it.
    pub fn specialized(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        declared: &[(&str, vk::DescriptorType)],
        push_constant_size: u32,
        constants: &[(&str, u32)],
    ) -> Result<Self> {
        check_declared(shader, declared)?;
        let mut all = Vec::new();
        for &(name, value) in constants {
            let id = shader.spec_constant_id(name)?.ok_or_else(|| {
                Error::Internal(format!(
                    "{} has no specialization constant {name}",
                    shader.name
                ))
            })?;
            all.push((id, value));
        }
        if let Some(id) = shader.spec_constant_id("TRAVERSAL_RULES")? {
            all.push((id, vk::Bool32::from(ctx.traversal_rules())));
        }
        let dev = ctx.device();
        let binding_info: Vec<_> = shader
            .bindings
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.ty)
                    .descriptor_count(b.count)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default()
            .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
            .bindings(&binding_info);
        // SAFETY: valid device; VK_KHR_push_descriptor is enabled (requirements).
        let set_layout = unsafe { dev.create_descriptor_set_layout(&set_info, None) }
            .vk("vkCreateDescriptorSetLayout")?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .size(push_constant_size)];
        let set_layouts = [set_layout];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if push_constant_size > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        // SAFETY: valid device and set layout.
        let layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")?;
        let module = shader.module(ctx)?;
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        let entries: Vec<vk::SpecializationMapEntry> = (0u32..)
            .zip(&all)
            .map(|(i, &(constant_id, _))| vk::SpecializationMapEntry {
                constant_id,
                offset: 4 * i,
                size: 4,
            })
            .collect();
        let data: Vec<u32> = all.iter().map(|&(_, v)| v).collect();
        let spec = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(bytemuck::cast_slice(&data));
        stage = stage.specialization_info(&spec);
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];
        // SAFETY: module and layout are valid; the module was built by build.rs for
        // Vulkan 1.3 and matches the layout (checked by validation in tests).
        let result = unsafe { dev.create_compute_pipelines(ctx.pipeline_cache(), &info, None) };
        // SAFETY: the module is no longer needed once the pipeline exists.
        unsafe { dev.destroy_shader_module(module, None) };
        let pipeline = result.map_err(|(_, e)| e).vk("vkCreateComputePipelines")?[0];
        ctx.set_name(pipeline, name);
        ctx.set_name(layout, &format!("{name}.layout"));
        ctx.set_name(set_layout, &format!("{name}.set_layout"));
        Ok(ComputePipeline {
            pipeline,
            layout,
            set_layout,
            local_size: LOCAL_SIZE,
            bindings: shader.bindings,
        })
    }

    /// The shader's binding named `name` (its GLSL variable or block instance name).
    fn named(&self, name: &str) -> Result<&'static ShaderBinding> {
        self.bindings
            .iter()
            .find(|b| b.name == name)
            .ok_or_else(|| Error::Internal(format!("the shader has no binding named {name}")))
    }

    /// A descriptor write of the image binding named `name`: its number and type are the
    /// shader's (reflected).
    pub fn image<'a>(
        &self,
        name: &str,
        info: &'a [vk::DescriptorImageInfo],
    ) -> Result<vk::WriteDescriptorSet<'a>> {
        Ok(write_of(self.named(name)?).image_info(info))
    }

    /// A descriptor write of the buffer binding named `name`: its number and type are
    /// the shader's (reflected).
    pub fn buffer<'a>(
        &self,
        name: &str,
        info: &'a [vk::DescriptorBufferInfo],
    ) -> Result<vk::WriteDescriptorSet<'a>> {
        Ok(write_of(self.named(name)?).buffer_info(info))
    }

    /// A descriptor write of the texel buffer binding named `name` (its number and type
    /// the shader's, reflected).
    pub fn texel_buffer<'a>(
        &self,
        name: &str,
        views: &'a [vk::BufferView],
    ) -> Result<vk::WriteDescriptorSet<'a>> {
        Ok(write_of(self.named(name)?).texel_buffer_view(views))
    }

    /// Binds the pipeline, pushes `writes` as set 0 and `push` as push constants, and
    /// dispatches enough workgroups to cover `width x height` invocations.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device (the one this pipeline was built
    ///   on) in the recording state, outside a render pass instance, for a queue of the
    ///   context's queue family.
    /// * `writes` match set 0's layout (each binding declared, with its descriptor type)
    ///   and give every binding the shader uses; the views and samplers they name belong
    ///   to the device, stay alive until the command buffer has executed, and when it
    ///   executes the images are in the layouts the writes name, their earlier writes
    ///   made visible to the shader's accesses (the caller's barriers).
    /// * `push` is empty or exactly the pipeline's push-constant size.
    /// * The pipeline is not destroyed before the command buffer has executed.
    pub unsafe fn dispatch(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        writes: &[vk::WriteDescriptorSet],
        push: &[u8],
        width: u32,
        height: u32,
    ) {
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the set layout and name live resources in their layouts;
        // `push` fits the layout's push-constant range.
        unsafe {
            self.bind(ctx, cmd, writes, push);
            dev.cmd_dispatch(
                cmd,
                width.div_ceil(self.local_size[0]),
                height.div_ceil(self.local_size[1]),
                1,
            );
        }
    }

    /// Binds the pipeline, pushes `writes` as set 0 and `push` as push constants, and
    /// dispatches the workgroup count read from `args` at `offset` (a
    /// `VkDispatchIndirectCommand`) when the command buffer executes.
    ///
    /// # Safety
    /// As [`ComputePipeline::dispatch`]; `args` is a live buffer of the device with
    /// `INDIRECT_BUFFER` usage holding a `VkDispatchIndirectCommand` at `offset` (a
    /// multiple of 4), written before the dispatch and made visible to
    /// `DRAW_INDIRECT` `INDIRECT_COMMAND_READ` (the caller's barrier); each of its counts
    /// is within `maxComputeWorkGroupCount`.
    pub unsafe fn dispatch_indirect(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        writes: &[vk::WriteDescriptorSet],
        push: &[u8],
        args: vk::Buffer,
        offset: u64,
    ) {
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract, as in `dispatch`; `args` holds a
        // visible dispatch command at `offset`.
        unsafe {
            self.bind(ctx, cmd, writes, push);
            dev.cmd_dispatch_indirect(cmd, args, offset);
        }
    }

    /// Binds the pipeline, its set 0 (`writes`) and push constants (`push`).
    ///
    /// # Safety
    /// As [`ComputePipeline::dispatch`].
    unsafe fn bind(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        writes: &[vk::WriteDescriptorSet],
        push: &[u8],
    ) {
        let dev = ctx.device();
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the set layout and name live resources in their layouts;
        // `push` fits the layout's push-constant range.
        unsafe {
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            ctx.push_descriptor().cmd_push_descriptor_set(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.layout,
                0,
                writes,
            );
            if !push.is_empty() {
                dev.cmd_push_constants(cmd, self.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
            }
        }
    }
}

impl Destroy for ComputePipeline {
    /// Destroys pipeline and layouts and nulls their handles (a second call does
    /// nothing: Vulkan ignores null handles).
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            ctx.device().destroy_pipeline(self.pipeline, None);
            ctx.device().destroy_pipeline_layout(self.layout, None);
            ctx.device()
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
        self.pipeline = vk::Pipeline::null();
        self.layout = vk::PipelineLayout::null();
        self.set_layout = vk::DescriptorSetLayout::null();
    }
}

/// Checks what a pass binds (`declared`, `(GLSL name, type)` in any order) against the
/// bindings `shader`'s SPIR-V declares: the same names with the same types, every one in
/// set 0 and a single descriptor (push descriptors of one set); the error names the
/// shader and the difference. The numbers are the shader's alone.
pub fn check_declared(shader: &Shader, declared: &[(&str, vk::DescriptorType)]) -> Result<()> {
    check_bindings(shader.name, shader.bindings.iter(), declared)
}

/// [`check_declared`] for the bindings `bindings` of the shader (or shaders) `name`.
fn check_bindings<'a>(
    name: &str,
    bindings: impl Iterator<Item = &'a ShaderBinding> + Clone,
    declared: &[(&str, vk::DescriptorType)],
) -> Result<()> {
    let mut ours: Vec<(&str, vk::DescriptorType)> = declared.to_vec();
    ours.sort_by_key(|&(n, _)| n);
    let mut theirs: Vec<(&str, vk::DescriptorType)> =
        bindings.clone().map(|b| (b.name, b.ty)).collect();
    theirs.sort_by_key(|&(n, _)| n);
    if let Some(b) = bindings.clone().find(|b| b.set != 0 || b.count != 1) {
        return Err(Error::invalid(
            name,
            format!(
                "binding {} ({}) is in set {} with {} descriptors; passes push one set of \
                 single descriptors",
                b.binding, b.name, b.set, b.count
            ),
        ));
    }
    if ours != theirs {
        return Err(Error::invalid(
            name,
            format!("the pass binds {ours:?}, the shader declares {theirs:?}"),
        ));
    }
    Ok(())
}

/// Set 0 of a graphics pipeline, from its stages' reflected bindings ([`Shader::bindings`]):
/// each binding once, visible to the stages that declare it, bound by its GLSL name (the
/// numbers exist only in the GLSL).
#[derive(Debug)]
pub struct RasterSet {
    name: String,
    bindings: Vec<(&'static ShaderBinding, vk::ShaderStageFlags)>,
}

impl RasterSet {
    /// The joined bindings of `stages` (each shader with its stage); `declared` is what
    /// the pass binds, `(GLSL name, type)`, and must be exactly that table (as
    /// [`check_declared`]); a binding number two stages give different names or types is
    /// an error.
    pub fn new(
        stages: &[(&Shader, vk::ShaderStageFlags)],
        declared: &[(&str, vk::DescriptorType)],
    ) -> Result<Self> {
        let name = stages
            .iter()
            .map(|(s, _)| s.name)
            .collect::<Vec<_>>()
            .join(" + ");
        let mut bindings: Vec<(&'static ShaderBinding, vk::ShaderStageFlags)> = Vec::new();
        for &(shader, stage) in stages {
            for b in shader.bindings {
                match bindings
                    .iter_mut()
                    .find(|(o, _)| o.binding == b.binding && o.set == b.set)
                {
                    Some((o, flags)) if o.name == b.name && o.ty == b.ty => *flags |= stage,
                    Some((o, _)) => {
                        return Err(Error::invalid(
                            name,
                            format!(
                                "binding {} is {} ({:?}) in one stage and {} ({:?}) in another",
                                b.binding, o.name, o.ty, b.name, b.ty
                            ),
                        ));
                    }
                    None => bindings.push((b, stage)),
                }
            }
        }
        check_bindings(&name, bindings.iter().map(|(b, _)| *b), declared)?;
        Ok(RasterSet { name, bindings })
    }

    /// Whether the stages bind nothing (the pipeline layout then has no set).
    pub fn is_empty(&self) -> bool {
        self.bindings.is_empty()
    }

    /// Creates set 0's push-descriptor layout, named `name`.
    pub fn set_layout(&self, ctx: &Context, name: &str) -> Result<vk::DescriptorSetLayout> {
        let info: Vec<_> = self
            .bindings
            .iter()
            .map(|(b, stages)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.ty)
                    .descriptor_count(b.count)
                    .stage_flags(*stages)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default()
            .flags(vk::DescriptorSetLayoutCreateFlags::PUSH_DESCRIPTOR_KHR)
            .bindings(&info);
        // SAFETY: valid device; VK_KHR_push_descriptor is enabled (requirements).
        let layout = unsafe { ctx.device().create_descriptor_set_layout(&set_info, None) }
            .vk("vkCreateDescriptorSetLayout")?;
        ctx.set_name(layout, name);
        Ok(layout)
    }

    fn named(&self, name: &str) -> Result<&'static ShaderBinding> {
        self.bindings
            .iter()
            .find(|(b, _)| b.name == name)
            .map(|(b, _)| *b)
            .ok_or_else(|| Error::Internal(format!("{} has no binding named {name}", self.name)))
    }

    /// A descriptor write of the image binding named `name` (its number and type the
    /// shaders').
    pub fn image<'a>(
        &self,
        name: &str,
        info: &'a [vk::DescriptorImageInfo],
    ) -> Result<vk::WriteDescriptorSet<'a>> {
        Ok(write_of(self.named(name)?).image_info(info))
    }

    /// A descriptor write of the buffer binding named `name` (its number and type the
    /// shaders').
    pub fn buffer<'a>(
        &self,
        name: &str,
        info: &'a [vk::DescriptorBufferInfo],
    ) -> Result<vk::WriteDescriptorSet<'a>> {
        Ok(write_of(self.named(name)?).buffer_info(info))
    }
}

/// A descriptor write of the reflected binding `b` (its number and type), for
/// [`ComputePipeline`] and [`RasterSet`] to add the descriptors to.
fn write_of<'a>(b: &ShaderBinding) -> vk::WriteDescriptorSet<'a> {
    vk::WriteDescriptorSet::default()
        .dst_binding(b.binding)
        .descriptor_type(b.ty)
}

/// A descriptor write for binding `binding` of an image (sampled or storage).
pub fn image_write(
    binding: u32,
    ty: vk::DescriptorType,
    info: &[vk::DescriptorImageInfo],
) -> vk::WriteDescriptorSet<'_> {
    vk::WriteDescriptorSet::default()
        .dst_binding(binding)
        .descriptor_type(ty)
        .image_info(info)
}

/// A compute pipeline and the nearest-filtering sampler its `texelFetch` reads of
/// sampled images (G-buffer, corner grid) are bound with.
pub struct FetchPipeline {
    /// The pipeline.
    pub pipeline: ComputePipeline,
    sampler: vk::Sampler,
}

impl FetchPipeline {
    /// [`ComputePipeline::new`] plus a sampler named `<name>.fetch_sampler`.
    pub fn new(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        bindings: &[(&str, vk::DescriptorType)],
        push_constant_size: u32,
    ) -> Result<Self> {
        Self::specialized(ctx, name, shader, bindings, push_constant_size, &[])
    }

    /// As [`FetchPipeline::new`], with specialization constants
    /// ([`ComputePipeline::specialized`]).
    pub fn specialized(
        ctx: &Context,
        name: &str,
        shader: &Shader,
        bindings: &[(&str, vk::DescriptorType)],
        push_constant_size: u32,
        constants: &[(&str, u32)],
    ) -> Result<Self> {
        let mut pipeline = ComputePipeline::specialized(
            ctx,
            name,
            shader,
            bindings,
            push_constant_size,
            constants,
        )?;
        match sampler(
            ctx,
            &format!("{name}.fetch_sampler"),
            vk::Filter::NEAREST,
            vk::SamplerAddressMode::CLAMP_TO_EDGE,
        ) {
            Ok(sampler) => Ok(FetchPipeline { pipeline, sampler }),
            Err(e) => {
                // SAFETY: built above and never used by a command.
                unsafe { pipeline.destroy(ctx) };
                Err(e)
            }
        }
    }

    /// Descriptor info of `image` read with `texelFetch` (`SHADER_READ_ONLY_OPTIMAL`).
    pub fn fetch(&self, image: &Image) -> [vk::DescriptorImageInfo; 1] {
        self.fetch_view(image.view)
    }

    /// Descriptor info of any image view read with `texelFetch`
    /// (`SHADER_READ_ONLY_OPTIMAL`), e.g. a host's G-buffer.
    pub fn fetch_view(&self, view: vk::ImageView) -> [vk::DescriptorImageInfo; 1] {
        [vk::DescriptorImageInfo {
            sampler: self.sampler,
            image_view: view,
            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        }]
    }
}

impl Destroy for FetchPipeline {
    /// Destroys the pipeline and the sampler. The GPU must be done with them.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
            ctx.device().destroy_sampler(self.sampler, None);
            self.sampler = vk::Sampler::null();
        }
    }
}

/// A descriptor write for binding `binding` of a storage buffer range.
pub fn buffer_write(binding: u32, info: &[vk::DescriptorBufferInfo]) -> vk::WriteDescriptorSet<'_> {
    vk::WriteDescriptorSet::default()
        .dst_binding(binding)
        .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
        .buffer_info(info)
}

/// Descriptor info of `image` as a storage image (`GENERAL`).
pub fn storage(image: &Image) -> [vk::DescriptorImageInfo; 1] {
    storage_view(image.view)
}

/// Descriptor info of any image view as a storage image (`GENERAL`).
pub fn storage_view(view: vk::ImageView) -> [vk::DescriptorImageInfo; 1] {
    [vk::DescriptorImageInfo {
        sampler: vk::Sampler::null(),
        image_view: view,
        image_layout: vk::ImageLayout::GENERAL,
    }]
}

/// What differs between dispmap's raster pipelines (dynamic rendering, triangle lists,
/// one viewport and scissor set at record time, no blending; no culling unless built by
/// [`raster_pipeline_culled`]).
pub struct RasterDesc<'a> {
    /// Vertex stage.
    pub vert: &'a Shader,
    /// Fragment stage.
    pub frag: &'a Shader,
    /// The pipeline layout (owned by the caller).
    pub layout: vk::PipelineLayout,
    /// Vertex buffer bindings and attributes (empty: vertices generated in the shader).
    pub vertex_bindings: &'a [vk::VertexInputBindingDescription],
    /// Vertex attributes.
    pub vertex_attributes: &'a [vk::VertexInputAttributeDescription],
    /// Depth test (depth writes are on).
    pub depth_compare: vk::CompareOp,
    /// Colour attachment formats (all written, no blending).
    pub color_formats: &'a [vk::Format],
    /// Depth attachment format.
    pub depth_format: vk::Format,
    /// Debug name of the pipeline.
    pub name: &'a str,
}

/// Builds a graphics pipeline for dynamic rendering from `desc` (the shader modules live
/// only during the call).
pub fn raster_pipeline(ctx: &Context, desc: &RasterDesc) -> Result<vk::Pipeline> {
    raster_pipeline_specialized(ctx, desc, None)
}

/// As [`raster_pipeline`], with the fragment stage's specialization constants (for
/// example `TWO_SIDED` of `glsl/gbuffer_mesh.frag`).
pub fn raster_pipeline_specialized(
    ctx: &Context,
    desc: &RasterDesc,
    frag_specialization: Option<&vk::SpecializationInfo>,
) -> Result<vk::Pipeline> {
    raster_pipeline_culled(ctx, desc, frag_specialization, false)
}

/// As [`raster_pipeline_specialized`]; with `cull_back_faces` the rasteriser culls the
/// triangles whose winding faces away from the eye: front faces wind counter-clockwise in
/// the framebuffer, as dispmap's meshes seen from where their normals point
/// ([`crate::mesh::Mesh::with_front_winding`]).
pub fn raster_pipeline_culled(
    ctx: &Context,
    desc: &RasterDesc,
    frag_specialization: Option<&vk::SpecializationInfo>,
    cull_back_faces: bool,
) -> Result<vk::Pipeline> {
    let dev = ctx.device();
    let vert = desc.vert.module(ctx)?;
    let frag = match desc.frag.module(ctx) {
        Ok(m) => m,
        Err(e) => {
            // SAFETY: the module is unused.
            unsafe { dev.destroy_shader_module(vert, None) };
            return Err(e);
        }
    };
    let stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(vert)
            .name(c"main"),
        match frag_specialization {
            Some(spec) => vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(frag)
                .name(c"main")
                .specialization_info(spec),
            None => vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(frag)
                .name(c"main"),
        },
    ];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
        .vertex_binding_descriptions(desc.vertex_bindings)
        .vertex_attribute_descriptions(desc.vertex_attributes);
    let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default()
        .viewport_count(1)
        .scissor_count(1);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(if cull_back_faces {
            vk::CullModeFlags::BACK
        } else {
            vk::CullModeFlags::NONE
        })
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let depth = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(true)
        .depth_compare_op(desc.depth_compare);
    let blend_attachments: Vec<_> = desc
        .color_formats
        .iter()
        .map(|_| {
            vk::PipelineColorBlendAttachmentState::default()
                .color_write_mask(vk::ColorComponentFlags::RGBA)
        })
        .collect();
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
    let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let mut rendering = vk::PipelineRenderingCreateInfo::default()
        .color_attachment_formats(desc.color_formats)
        .depth_attachment_format(desc.depth_format);
    let info = [vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&input_assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth)
        .color_blend_state(&blend)
        .dynamic_state(&dynamic)
        .layout(desc.layout)
        .push_next(&mut rendering)];
    // SAFETY: every referenced state lives until the call returns; dynamic rendering is
    // enabled on the device (requirements).
    let result = unsafe { dev.create_graphics_pipelines(ctx.pipeline_cache(), &info, None) };
    // SAFETY: the modules are not needed after pipeline creation.
    unsafe {
        dev.destroy_shader_module(vert, None);
        dev.destroy_shader_module(frag, None);
    }
    let pipeline = result.map_err(|(_, e)| e).vk("vkCreateGraphicsPipelines")?[0];
    ctx.set_name(pipeline, desc.name);
    Ok(pipeline)
}

/// The render area covering all of `extent`.
pub fn frame_area(extent: vk::Extent2D) -> vk::Rect2D {
    vk::Rect2D {
        offset: vk::Offset2D::default(),
        extent,
    }
}

/// A colour attachment cleared to `clear` and stored, in `layout`.
pub fn cleared_color_attachment(
    view: vk::ImageView,
    layout: vk::ImageLayout,
    clear: [f32; 4],
) -> vk::RenderingAttachmentInfo<'static> {
    vk::RenderingAttachmentInfo::default()
        .image_view(view)
        .image_layout(layout)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)
        .clear_value(vk::ClearValue {
            color: vk::ClearColorValue { float32: clear },
        })
}

/// The G-buffer's reverse-Z depth attachment, cleared to 0 (no geometry) and stored.
pub fn cleared_depth_attachment(view: vk::ImageView) -> vk::RenderingAttachmentInfo<'static> {
    vk::RenderingAttachmentInfo::default()
        .image_view(view)
        .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)
        .clear_value(vk::ClearValue {
            depth_stencil: vk::ClearDepthStencilValue {
                depth: 0.0,
                stencil: 0,
            },
        })
}

/// Records the dynamic viewport (depth 0..1) and scissor covering all of `extent`: the
/// state every raster pipeline of [`raster_pipeline`] leaves dynamic.
///
/// # Safety
/// `cmd` is a command buffer of `ctx`'s device in the recording state (inside or outside
/// a render pass instance), for a queue of the context's queue family; `extent` is
/// non-zero and within the device's viewport limits (`maxViewportDimensions`).
pub unsafe fn set_frame_viewport(ctx: &Context, cmd: vk::CommandBuffer, extent: vk::Extent2D) {
    let viewport = vk::Viewport {
        x: 0.0,
        y: 0.0,
        width: extent.width as f32,
        height: extent.height as f32,
        min_depth: 0.0,
        max_depth: 1.0,
    };
    // SAFETY: this function's # Safety contract: `cmd` is recording and `extent` is a
    // valid viewport size; viewport and scissor are plain values.
    unsafe {
        ctx.device().cmd_set_viewport(cmd, 0, &[viewport]);
        ctx.device().cmd_set_scissor(cmd, 0, &[frame_area(extent)]);
    }
}

/// Creates a sampler named `name` (no mipmap filtering, every level reachable).
pub fn sampler(
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
