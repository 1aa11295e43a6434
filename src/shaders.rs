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
}

impl Shader {
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
