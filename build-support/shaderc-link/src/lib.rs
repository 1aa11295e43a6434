//! Link-only helper of dispmap's build script; it has no items.
//!
//! dispmap's `build.rs` compiles `glsl/` with the `shaderc` crate, built with its
//! `prefer-static-linking` feature, so `shaderc-sys` links `static=shaderc_combined`
//! whenever `libshaderc_combined.a` exists in the folder it searches.
//!
//! On most layouts that archive is complete: the Vulkan SDK's, and the one `shaderc`
//! builds from source, hold shaderc together with glslang and SPIRV-Tools. Debian 12 (and
//! distributions that package the same way) split them: `libshaderc_combined.a` holds
//! only shaderc's own objects, `libshaderc.so.1` leaves the glslang symbols undefined,
//! and glslang and SPIRV-Tools ship as separate static libraries (`glslang-dev`,
//! `spirv-tools`). Linking a build script against either shaderc library then fails
//! with `undefined reference: glslang::TShader::...`.
//!
//! This crate's build script looks in the folder that `shaderc-sys` searches
//! (`SHADERC_LIB_DIR`, else `$VULKAN_SDK/lib`, else pkg-config's `libdir` of `shaderc`,
//! else the distribution's library folder for the target, e.g.
//! `/usr/lib/x86_64-linux-gnu`). When it finds that split layout there (a
//! `libshaderc_combined.a` whose symbol table defines no glslang symbol, with
//! `libglslang.a` beside it), it emits `rustc-link-lib=static=...` for the glslang and
//! SPIRV-Tools libraries present there, in dependency order; on every other platform
//! or layout it emits nothing. Link directives of a library's build script reach every
//! binary that links that library, here dispmap's build script, so the fix travels
//! with the dependency graph: a crate outside this repository that depends on dispmap
//! by path builds too, with no `.cargo/config.toml`.
//!
//! dispmap's `build.rs` names this crate (`use dispmap_shaderc_link as _;`) so that it is
//! linked although nothing in it is used.
