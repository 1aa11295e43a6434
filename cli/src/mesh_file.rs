//! Mesh files: Wavefront OBJ (via `tobj`) and glTF 2.0 (`.gltf` / `.glb`, via `gltf`)
//! loaded into a [`Mesh`] (conventions in [`dispmap::mesh`]: uv with `v` down the image,
//! normals computed where missing, tangents from the file or generated).

use dispmap::error::{Error, Result};
use dispmap::mesh::Mesh;
use glam::Vec3;
use std::path::Path;

/// Loads a mesh file by its extension: `.obj`, `.gltf` or `.glb`.
pub fn load(path: &Path) -> Result<Mesh> {
    if path.is_dir() {
        return Err(Error::invalid(
            path.display().to_string(),
            "is a folder, not a mesh file (.obj, .gltf or .glb)",
        ));
    }
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("obj") => load_obj(path),
        Some("gltf" | "glb") => load_gltf(path),
        _ => Err(Error::invalid(
            path.display().to_string(),
            "not a mesh file (.obj, .gltf or .glb)",
        )),
    }
}

/// The most triangles a loaded mesh may have (the G-buffer draws every one per frame).
pub const MAX_TRIANGLES: usize = 16 << 20;

/// Whether a buffer URI names a file at or below the glTF file's folder.
fn stays_in_folder(uri: &str) -> bool {
    let path = Path::new(uri);
    !uri.contains("://")
        && !path.is_absolute()
        && path.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        })
}

/// Loads the triangles of a glTF 2.0 file's default scene (every node, with its
/// world transform) as one mesh. Errors name the file.
pub fn load_gltf(path: &Path) -> Result<Mesh> {
    let label = path.display().to_string();
    let bad = |message: String| Error::invalid(label.clone(), message);
    let gltf = gltf::Gltf::open(path).map_err(|e| match e {
        gltf::Error::Io(source) => Error::Io {
            path: path.to_path_buf(),
            source,
        },
        other => bad(format!("not a valid glTF file: {other}")),
    })?;
    // Buffers are read from the file itself or from files beside it: a URI that leaves
    // the file's folder (absolute, `..`, a scheme other than data:) is refused by name.
    for buffer in gltf.document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
            && !stays_in_folder(uri)
        {
            return Err(bad(format!(
                "buffer {} points outside the file's folder ({uri}): only relative paths \
                 below it and data: URIs are read",
                buffer.index()
            )));
        }
    }
    let buffers = gltf::import_buffers(&gltf.document, path.parent(), gltf.blob.clone())
        .map_err(|e| bad(format!("cannot read its buffers: {e}")))?;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut tangents = Vec::new();
    let mut uvs = Vec::new();
    let mut indices = Vec::new();
    let mut stack: Vec<(gltf::Node, glam::Mat4)> = match gltf
        .document
        .default_scene()
        .or_else(|| gltf.document.scenes().next())
    {
        Some(scene) => scene.nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect(),
        None => return Err(bad("has no scene".into())),
    };
    // glTF nodes form trees (a node has at most one parent): a node reached twice is a
    // cycle or a shared subtree, which would repeat (or never end) the walk.
    let mut seen = vec![false; gltf.document.nodes().count()];
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(bad(format!(
                "node {} is reached twice (a cycle or a shared subtree: glTF nodes form trees)",
                node.index()
            )));
        }
        let world = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        stack.extend(node.children().map(|c| (c, world)));
        let Some(mesh) = node.mesh() else { continue };
        let normal_matrix = glam::Mat3::from_mat4(world).inverse().transpose();
        for primitive in mesh.primitives() {
            if primitive.mode() != gltf::mesh::Mode::Triangles {
                continue;
            }
            let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let Some(p) = reader.read_positions() else {
                continue;
            };
            let base = positions.len() as u32;
            positions.extend(p.map(|p| world.transform_point3(Vec3::from_array(p))));
            let count = positions.len() - base as usize;
            let uv: Vec<[f32; 2]> = reader
                .read_tex_coords(0)
                .map(|t| t.into_f32().collect())
                .unwrap_or_default();
            if uv.len() != count {
                return Err(bad(format!(
                    "mesh {} has no texture coordinates (TEXCOORD_0), which \
                     displacement needs",
                    mesh.index()
                )));
            }
            uvs.extend(uv);
            match reader.read_normals() {
                Some(n) => normals.extend(n.map(|n| Some(normal_matrix * Vec3::from_array(n)))),
                None => normals.extend(std::iter::repeat_n(None, count)),
            }
            match reader.read_tangents() {
                Some(t) => tangents.extend(t.map(|t| {
                    let xyz = glam::Mat3::from_mat4(world) * Vec3::new(t[0], t[1], t[2]);
                    Some(xyz.extend(t[3]))
                })),
                None => tangents.extend(std::iter::repeat_n(None, count)),
            }
            if normals.len() != positions.len() || tangents.len() != positions.len() {
                return Err(bad("a primitive's attribute counts differ".into()));
            }
            match reader.read_indices() {
                Some(i) => {
                    for i in i.into_u32() {
                        if i as usize >= count {
                            return Err(bad(format!("index {i} out of range")));
                        }
                        indices.push(base + i);
                    }
                }
                None => indices.extend(base..base + count as u32),
            }
        }
    }
    Mesh::from_parts(&label, positions, normals, tangents, uvs, indices)
}

/// Loads every model of a Wavefront OBJ file as one mesh (see the module docs).
/// Errors name the file.
pub fn load_obj(path: &Path) -> Result<Mesh> {
    let label = path.display().to_string();
    let bad = |message: String| Error::invalid(label.clone(), message);
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|e| match e {
        tobj::LoadError::OpenFileFailed | tobj::LoadError::ReadError => Error::Io {
            path: path.to_path_buf(),
            source: std::fs::File::open(path)
                .err()
                .unwrap_or_else(|| std::io::Error::other(e.to_string())),
        },
        other => bad(format!("not a valid OBJ file: {other}")),
    })?;
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Option<Vec3>> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
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
