//! The host's build script: finds dispmap's GLSL include folder through cargo's `links`
//! metadata (DEP_DISPMAP_INCLUDE, set because dispmap's manifest says `links =
//! "dispmap"`), as a host's own shader build would, with no path into dispmap's checkout.
//! It copies the G-buffer contract into OUT_DIR for `main.rs` to check.

use std::path::PathBuf;

fn main() {
    let include = std::env::var("DEP_DISPMAP_INCLUDE")
        .expect("DEP_DISPMAP_INCLUDE: dispmap's build script publishes its include folder");
    let gbuffer = PathBuf::from(&include).join("dispmap_gbuffer.glsl");
    println!("cargo:rerun-if-changed={}", gbuffer.display());
    let text = std::fs::read_to_string(&gbuffer)
        .unwrap_or_else(|e| panic!("reading {}: {e}", gbuffer.display()));
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR"));
    std::fs::write(out.join("dispmap_gbuffer.glsl"), text).expect("writing OUT_DIR");
}
