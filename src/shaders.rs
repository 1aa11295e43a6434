//! SPIR-V compiled from `glsl/` by `build.rs` (one constant per shader file).

use crate::context::Context;
use crate::error::{Error, Result, VkContext};
use ash::vk;

/// One compiled shader.
#[derive(Clone, Copy, Debug)]
pub struct Shader {
    /// Path under `glsl/`, e.g. `trace/relief.comp`.
    pub name: &'static str,
    /// SPIR-V bytes (little-endian words).
    pub spirv: &'static [u8],
    /// Its descriptor bindings as the SPIR-V declares them (those its entry point uses),
    /// by set and binding: where binding numbers and types come from.
    pub bindings: &'static [ShaderBinding],
}

/// One descriptor binding of a shader, reflected from its SPIR-V by `build.rs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderBinding {
    /// Descriptor set.
    pub set: u32,
    /// Binding number.
    pub binding: u32,
    /// Descriptor type.
    pub ty: vk::DescriptorType,
    /// Array size (1 for a single descriptor; 0 for a runtime-sized array).
    pub count: u32,
    /// The variable's name in the GLSL.
    pub name: &'static str,
    /// Whether the shader may read it (not `writeonly`).
    pub reads: bool,
    /// Whether the shader may write it (a storage image or buffer not `readonly`).
    pub writes: bool,
}

impl Shader {
    /// The binding numbered `binding` in set 0, if the shader uses it.
    pub fn binding(&self, binding: u32) -> Option<&ShaderBinding> {
        self.bindings
            .iter()
            .find(|b| b.set == 0 && b.binding == binding)
    }

    /// The SPIR-V as words.
    pub fn words(&self) -> Result<Vec<u32>> {
        ash::util::read_spv(&mut std::io::Cursor::new(self.spirv))
            .map_err(|e| Error::invalid(self.name, format!("bad SPIR-V: {e}")))
    }

    /// Creates a shader module named after the file.
    pub fn module(&self, ctx: &Context) -> Result<vk::ShaderModule> {
        let words = self.words()?;
        let info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: the words are SPIR-V produced by shaderc for Vulkan 1.3.
        let module =
            unsafe { ctx.device().create_shader_module(&info, None) }.vk("vkCreateShaderModule")?;
        ctx.set_name(module, self.name);
        Ok(module)
    }
}

include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
