//! Wavefront OBJ files: every model of the file as one mesh (via `tobj`, from bytes read
//! through [`dispmap::input`]; a `mtllib` is read the same way), and the scan of
//! [`measure`](super::measure).

use super::{MAX_FILE_BYTES, MAX_MTL_BYTES, WHAT, check_counts};
use crate::memory::MeshSize;
use dispmap::error::{Error, Result};
use dispmap::mesh::Mesh;
use glam::Vec3;
use std::io::BufRead as _;
use std::path::Path;

/// The counts of an OBJ file from one pass over its lines: triangles exactly (a face of
/// `n` corners makes `n - 2`), vertices as the largest of its position, texture
/// coordinate and normal counts, at most one per face corner (the loader makes one
/// vertex per distinct corner: as many for a mesh whose corners share their indices).
pub(super) fn measure(path: &Path) -> Result<MeshSize> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let (file, file_bytes) = dispmap::input::open(path, MAX_FILE_BYTES, WHAT)?;
    let mut reader = std::io::BufReader::with_capacity(1 << 16, file);
    let (mut v, mut vt, mut vn, mut corners, mut triangles) = (0u64, 0u64, 0u64, 0u64, 0u64);
    let mut line = Vec::new();
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line).map_err(io)? == 0 {
            break;
        }
        let mut words = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(b"v") => v += 1,
            Some(b"vt") => vt += 1,
            Some(b"vn") => vn += 1,
            Some(b"f") => {
                let n = words.count() as u64;
                corners += n;
                triangles += n.saturating_sub(2);
            }
            _ => {}
        }
    }
    Ok(MeshSize {
        file_bytes,
        vertices: v.max(vt).max(vn).min(corners),
        triangles,
    })
}

/// Loads every model of a Wavefront OBJ file as one mesh (see the module docs of
/// [`super`]). Errors name the file. A `mtllib` that is not a regular file of at most
/// [`MAX_MTL_BYTES`] is refused by name; a missing one is ignored (materials are not
/// used).
pub fn load_obj(path: &Path) -> Result<Mesh> {
    let label = path.display().to_string();
    let bad = |message: String| Error::invalid(label.clone(), message);
    let bytes = dispmap::input::read(path, MAX_FILE_BYTES, WHAT)?;
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let dir = path.parent().unwrap_or(Path::new("."));
    let mtl_error = std::cell::RefCell::new(None);
    let loaded = tobj::load_obj_buf(&mut &bytes[..], &options, |mtl| {
        let mtl = dir.join(mtl);
        match dispmap::input::read(&mtl, MAX_MTL_BYTES, "a material library (mtllib)") {
            Ok(text) => tobj::load_mtl_buf(&mut &text[..]),
            Err(Error::Io { source, .. }) if source.kind() == std::io::ErrorKind::NotFound => {
                Err(tobj::LoadError::OpenFileFailed)
            }
            Err(e) => {
                mtl_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    });
    drop(bytes);
    if let Some(e) = mtl_error.into_inner() {
        return Err(bad(format!("its mtllib cannot be read: {e}")));
    }
    let (models, _materials) = loaded.map_err(|e| bad(format!("not a valid OBJ file: {e}")))?;
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Option<Vec3>> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    let vertices: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    let triangles: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    check_counts(&label, vertices as u64, triangles as u64)?;
    for model in &models {
        let m = &model.mesh;
        let count = m.positions.len() / 3;
        if count == 0 {
            continue;
        }
        if m.texcoords.len() / 2 != count {
            return Err(bad(format!(
                "model '{}' has no texture coordinates (vt), which displacement needs",
                model.name
            )));
        }
        let base = positions.len() as u32;
        let has_normals = m.normals.len() / 3 == count;
        for k in 0..count {
            positions.push(Vec3::from_slice(&m.positions[3 * k..3 * k + 3]));
            normals.push(has_normals.then(|| Vec3::from_slice(&m.normals[3 * k..3 * k + 3])));
            uvs.push([m.texcoords[2 * k], 1.0 - m.texcoords[2 * k + 1]]);
        }
        for &i in &m.indices {
            if i as usize >= count {
                return Err(bad(format!(
                    "model '{}': index {i} out of range",
                    model.name
                )));
            }
            indices.push(base + i);
        }
    }
    Mesh::from_triangles(&label, positions, normals, uvs, indices)
}
