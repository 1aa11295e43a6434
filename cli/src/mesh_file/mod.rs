//! Mesh files: Wavefront OBJ (via `tobj`, [`obj`]) and glTF 2.0 (`.gltf` / `.glb`, via
//! `gltf`, [`gltf`]) loaded into a [`Mesh`] (conventions in [`dispmap::mesh`]: uv with `v`
//! down the image, normals computed where missing, tangents from the file or generated).
//!
//! Every file (the mesh, a glTF's `.bin` buffers, an OBJ's `mtllib`) is read through
//! [`dispmap::input`]: a regular file of bounded size, checked before it is read.
//! [`measure`] gives a mesh's size (file bytes, vertices, triangles) without building it,
//! so a run can bound its memory before the mesh is loaded; meshes above
//! [`MAX_TRIANGLES`] or [`MAX_VERTICES`] are refused there and by [`load`].

pub mod gltf;
mod gltf_check;
pub mod obj;

pub use self::gltf::load_gltf;
pub use self::obj::load_obj;
use crate::memory::MeshSize;
use dispmap::error::{Error, Result};
use dispmap::mesh::Mesh;
use std::path::Path;

/// The most triangles a loaded mesh may have (the G-buffer draws every one per frame).
pub const MAX_TRIANGLES: u64 = 16 << 20;
/// The most vertices a loaded mesh may have (three per triangle: a triangle soup).
pub const MAX_VERTICES: u64 = 3 * MAX_TRIANGLES;
/// The largest mesh file (OBJ, `.gltf`, `.glb`) or glTF buffer file read: 4 GiB.
pub const MAX_FILE_BYTES: u64 = 4 << 30;
/// The largest OBJ material library (`mtllib`) read: 16 MiB.
pub const MAX_MTL_BYTES: u64 = 16 << 20;

/// What errors call a mesh file.
const WHAT: &str = "a mesh file (.obj, .gltf or .glb)";

/// The format of a mesh file, by its extension.
fn kind(path: &Path) -> Result<Kind> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("obj") => Ok(Kind::Obj),
        Some("gltf" | "glb") => Ok(Kind::Gltf),
        _ => Err(Error::invalid(
            path.display().to_string(),
            "not a mesh file (.obj, .gltf or .glb)",
        )),
    }
}

enum Kind {
    Obj,
    Gltf,
}

/// Loads a mesh file by its extension: `.obj`, `.gltf` or `.glb`.
pub fn load(path: &Path) -> Result<Mesh> {
    // A folder is named as one whatever its name.
    dispmap::input::check(path, MAX_FILE_BYTES, WHAT)?;
    match kind(path)? {
        Kind::Obj => load_obj(path),
        Kind::Gltf => load_gltf(path),
    }
}

/// The size of a mesh file without building the mesh: its bytes (with a glTF's buffer
/// files) and its vertex and triangle counts (an OBJ's from a scan of its lines, the
/// vertex count an estimate there; a glTF's from its accessors). Memory stays at one
/// line of the file (an OBJ) or its JSON (a glTF). Errors name the file: not a regular
/// file, too large, more than [`MAX_TRIANGLES`] or [`MAX_VERTICES`].
pub fn measure(path: &Path) -> Result<MeshSize> {
    dispmap::input::check(path, MAX_FILE_BYTES, WHAT)?;
    let size = match kind(path)? {
        Kind::Obj => obj::measure(path)?,
        Kind::Gltf => gltf::measure(path)?,
    };
    check_counts(&path.display().to_string(), size.vertices, size.triangles)?;
    Ok(size)
}

/// Refuses more than [`MAX_TRIANGLES`] triangles or [`MAX_VERTICES`] vertices.
fn check_counts(label: &str, vertices: u64, triangles: u64) -> Result<()> {
    if triangles > MAX_TRIANGLES {
        return Err(Error::invalid(
            label,
            format!("has {triangles} triangles, more than the {MAX_TRIANGLES} a mesh may have"),
        ));
    }
    if vertices > MAX_VERTICES {
        return Err(Error::invalid(
            label,
            format!("has {vertices} vertices, more than the {MAX_VERTICES} a mesh may have"),
        ));
    }
    Ok(())
}
