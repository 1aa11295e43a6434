//! The host's own shader build, as an engine has one: compiles `shaders/gbuffer.vert` and
//! `shaders/gbuffer.frag` to SPIR-V with the `shaderc` crate into OUT_DIR for `main.rs`.
//! `#include "x.glsl"` resolves against `shaders/` first, then against dispmap's GLSL
//! include folder, which cargo hands this script as DEP_DISPMAP_INCLUDE (dispmap's
//! manifest says `links = "dispmap"`): no path into dispmap's checkout, wherever cargo
//! put it (path, git or registry dependency).

use std::error::Error;
use std::path::{Path, PathBuf};

fn main() -> Result<(), Box<dyn Error>> {
    let include = PathBuf::from(
        std::env::var("DEP_DISPMAP_INCLUDE")
            .map_err(|_| "DEP_DISPMAP_INCLUDE is not set: dispmap publishes its include folder")?,
    );
    let own = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?).join("shaders");
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    println!("cargo:rerun-if-changed=shaders");

    let compiler =
        shaderc::Compiler::new().map_err(|e| format!("shaderc: cannot create a compiler: {e}"))?;
    for (file, kind) in [
        ("gbuffer.vert", shaderc::ShaderKind::Vertex),
        ("gbuffer.frag", shaderc::ShaderKind::Fragment),
    ] {
        let path = own.join(file);
        let source = std::fs::read_to_string(&path)
            .map_err(|e| format!("reading {}: {e}", path.display()))?;
        let mut options = shaderc::CompileOptions::new().map_err(|e| format!("shaderc: {e}"))?;
        options.set_target_env(
            shaderc::TargetEnv::Vulkan,
            shaderc::EnvVersion::Vulkan1_3 as u32,
        );
        options.set_optimization_level(shaderc::OptimizationLevel::Performance);
        options.set_warnings_as_errors();
        let folders = [own.clone(), include.clone()];
        options.set_include_callback(move |requested, _kind, _from, _depth| {
            resolve(&folders, requested)
        });
        let artifact = compiler
            .compile_into_spirv(&source, kind, file, "main", Some(&options))
            .map_err(|e| format!("{file}: {e}"))?;
        std::fs::write(out.join(format!("{file}.spv")), artifact.as_binary_u8())?;
    }
    Ok(())
}

/// `requested` under the first of `folders` that has it.
fn resolve(folders: &[PathBuf], requested: &str) -> Result<shaderc::ResolvedInclude, String> {
    let found = folders
        .iter()
        .map(|dir| dir.join(requested))
        .find(|candidate| candidate.is_file())
        .ok_or_else(|| {
            format!("cannot find include \"{requested}\" in {folders:?} (DEP_DISPMAP_INCLUDE)")
        })?;
    println!("cargo:rerun-if-changed={}", found.display());
    let content =
        std::fs::read_to_string(&found).map_err(|e| format!("{}: {e}", found.display()))?;
    Ok(shaderc::ResolvedInclude {
        resolved_name: Path::new(&found).display().to_string(),
        content,
    })
}
