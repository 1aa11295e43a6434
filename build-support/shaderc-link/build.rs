//! Emits the glslang and SPIRV-Tools static libraries that a split
//! `libshaderc_combined.a` (Debian 12) leaves unresolved; see `src/lib.rs`.

use std::env;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Libraries that may resolve what shaderc's objects leave undefined, a library before
/// those it uses (glslang 11-13 split glslang into `MachineIndependent`,
/// `GenericCodeGen`, `OSDependent`, `OGLCompiler` and `HLSL`; later releases fold them,
/// and `SPIRV`, into `glslang`). Only those present are linked.
const SPLIT_LIBS: &[&str] = &[
    "SPIRV",
    "glslang",
    "MachineIndependent",
    "GenericCodeGen",
    "OGLCompiler",
    "OSDependent",
    "HLSL",
    "SPIRV-Tools-opt",
    "SPIRV-Tools",
];

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for var in [
        "SHADERC_LIB_DIR",
        "VULKAN_SDK",
        "PKG_CONFIG",
        "PKG_CONFIG_PATH",
        "PKG_CONFIG_LIBDIR",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    // Only Linux distributions ship the split layout.
    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target_os != "linux" {
        return;
    }
    let Some(dir) = search_dir() else { return };
    let Ok(dir) = dir.canonicalize() else { return };
    let combined = dir.join("libshaderc_combined.a");
    if combined.is_file() {
        println!("cargo:rerun-if-changed={}", combined.display());
    }
    if !is_split(&dir) {
        return;
    }
    println!("cargo:rustc-link-search=native={}", dir.display());
    for lib in SPLIT_LIBS {
        if dir.join(format!("lib{lib}.a")).is_file() {
            println!("cargo:rustc-link-lib=static={lib}");
        }
    }
}

/// The folder `shaderc-sys` 0.10 looks in for shaderc, in its order.
fn search_dir() -> Option<PathBuf> {
    if let Ok(dir) = env::var("SHADERC_LIB_DIR") {
        return Some(dir.into());
    }
    if let Ok(sdk) = env::var("VULKAN_SDK") {
        return Some(Path::new(&sdk).join("lib"));
    }
    if let Some(dir) = pkg_config_libdir() {
        return Some(dir);
    }
    let arch = match env::var("CARGO_CFG_TARGET_ARCH").ok()?.as_str() {
        "x86" => "i386".to_owned(),
        arch => arch.to_owned(),
    };
    let multiarch = PathBuf::from(format!("/usr/lib/{arch}-linux-gnu"));
    if multiarch.exists() {
        Some(multiarch)
    } else if arch == "x86_64" && Path::new("/usr/lib64").exists() {
        Some("/usr/lib64".into())
    } else {
        Some("/usr/lib".into())
    }
}

/// `pkg-config --variable=libdir shaderc`, when building for the host (`shaderc-sys`
/// asks pkg-config only then, as the `pkg-config` crate refuses cross builds by default).
fn pkg_config_libdir() -> Option<PathBuf> {
    if env::var("HOST").ok()? != env::var("TARGET").ok()? {
        return None;
    }
    let program = env::var("PKG_CONFIG").unwrap_or_else(|_| "pkg-config".to_owned());
    let output = Command::new(program)
        .args(["--variable=libdir", "shaderc"])
        .output()
        .ok()?;
    let dir = String::from_utf8(output.stdout).ok()?;
    let dir = dir.trim();
    (output.status.success() && !dir.is_empty()).then(|| dir.into())
}

/// Whether `dir` holds a shaderc-only `libshaderc_combined.a` with `libglslang.a` beside it.
fn is_split(dir: &Path) -> bool {
    let combined = dir.join("libshaderc_combined.a");
    if !combined.is_file() || !dir.join("libglslang.a").is_file() {
        return false;
    }
    // A complete archive defines glslang's `TShader::TShader(EShLanguage)`; its symbol table
    // (the first member of a GNU or BSD `ar` archive) lists every symbol the archive
    // defines. (Debian's split archive defines inline members of `glslang::TShader`'s nested
    // classes, never the constructor.) If the table cannot be read, trust the file layout.
    match symbol_table(&combined) {
        Some(table) => !contains(&table, b"_ZN7glslang7TShaderC1E"),
        None => true,
    }
}

/// The first member of an `ar` archive when it is a symbol table (`/`, `/SYM64/`,
/// `__.SYMDEF...`, or a BSD long name such as `#1/20` followed by `__.SYMDEF`).
fn symbol_table(archive: &Path) -> Option<Vec<u8>> {
    let mut file = File::open(archive).ok()?;
    let mut head = [0u8; 8 + 60];
    file.read_exact(&mut head).ok()?;
    if &head[..8] != b"!<arch>\n" || &head[66..68] != b"`\n" {
        return None;
    }
    let name = std::str::from_utf8(&head[8..24]).ok()?.trim_end();
    let size: u64 = std::str::from_utf8(&head[56..66])
        .ok()?
        .trim()
        .parse()
        .ok()?;
    let mut body = Vec::new();
    file.take(size).read_to_end(&mut body).ok()?;
    let is_table = name == "/"
        || name == "/SYM64/"
        || name.starts_with("__.SYMDEF")
        || (name.starts_with("#1/") && body.starts_with(b"__.SYMDEF"));
    is_table.then_some(body)
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}
