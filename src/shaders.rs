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

    /// The `constant_id` of the specialization constant the GLSL names `name`
    /// (`layout(constant_id = N) const ... name`), read from the SPIR-V's `OpName` and
    /// `SpecId` decoration: specialization ids, like binding numbers, exist only in the
    /// GLSL. `None` when the shader declares no such constant.
    pub fn spec_constant_id(&self, name: &str) -> Result<Option<u32>> {
        const OP_NAME: u32 = 5;
        const OP_DECORATE: u32 = 71;
        const DEC_SPEC_ID: u32 = 1;
        let words = self.words()?;
        let mut target = None;
        let mut ids = Vec::new();
        let mut i = 5;
        while i < words.len() {
            let count = (words[i] >> 16) as usize;
            let op = words[i] & 0xffff;
            let Some(a) = words.get(i + 1..i + count.max(1)) else {
                return Err(Error::invalid(
                    self.name,
                    "bad SPIR-V: truncated instruction",
                ));
            };
            match op {
                OP_NAME if a.len() >= 2 => {
                    let bytes: Vec<u8> = a[1..].iter().flat_map(|w| w.to_le_bytes()).collect();
                    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
                    if &bytes[..end] == name.as_bytes() {
                        target = Some(a[0]);
                    }
                }
                OP_DECORATE if a.len() >= 3 && a[1] == DEC_SPEC_ID => ids.push((a[0], a[2])),
                _ => {}
            }
            i += count.max(1);
        }
        Ok(target.and_then(|t| ids.iter().find(|&&(id, _)| id == t).map(|&(_, c)| c)))
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
