//! glTF 2.0 files (`.gltf`, `.glb`): the triangles of the default scene as one mesh. The
//! file and its buffer files are read through [`dispmap::input`] (a buffer's URI must stay
//! in the file's folder, or be a `data:` URI), and every accessor read is first checked
//! against the specification (`gltf_check.rs`).

use super::gltf_check::{Site, check_primitive};
use super::{MAX_FILE_BYTES, WHAT, check_counts};
use crate::memory::MeshSize;
use dispmap::error::{Error, Result};
use dispmap::mesh::Mesh;
use glam::Vec3;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// What errors call a glTF buffer file.
const BUFFER_WHAT: &str = "a glTF buffer file";

/// A buffer URI as a path below the glTF file's folder (percent-decoded), or why not.
fn buffer_path(uri: &str) -> std::result::Result<PathBuf, &'static str> {
    // A scheme (`file:`, `http:`) before any '/': a URI, not a relative path.
    if uri
        .split('/')
        .next()
        .is_some_and(|first| first.contains(':'))
    {
        return Err("only relative paths below it and data: URIs are read");
    }
    let raw = uri.as_bytes();
    let mut bytes = Vec::with_capacity(raw.len());
    let mut i = 0;
    while i < raw.len() {
        if raw[i] == b'%' {
            let hex = raw
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or("a '%' not followed by two hex digits")?;
            bytes.push(hex);
            i += 3;
        } else {
            bytes.push(raw[i]);
            i += 1;
        }
    }
    if bytes.contains(&0) {
        return Err("a NUL byte in the path");
    }
    let path = PathBuf::from(<std::ffi::OsStr as std::os::unix::ffi::OsStrExt>::from_bytes(&bytes));
    let below = !path.is_absolute()
        && path.components().all(|c| {
            matches!(
                c,
                std::path::Component::Normal(_) | std::path::Component::CurDir
            )
        });
    if below {
        Ok(path)
    } else {
        Err("only relative paths below it and data: URIs are read")
    }
}

/// Parses a glTF document (JSON, or a GLB's JSON with its binary chunk).
fn parse(bytes: &[u8], label: &str) -> Result<gltf::Gltf> {
    gltf::Gltf::from_slice(bytes)
        .map_err(|e| Error::invalid(label, format!("not a valid glTF file: {e}")))
}

/// The buffer file of buffer `buffer` (a relative URI), checked to stay in the folder.
fn buffer_file(path: &Path, buffer: &gltf::Buffer, uri: &str) -> Result<PathBuf> {
    let dir = path.parent().unwrap_or(Path::new("."));
    buffer_path(uri).map(|p| dir.join(p)).map_err(|why| {
        Error::invalid(
            path.display().to_string(),
            format!(
                "buffer {} points outside the file's folder ({uri}): {why}",
                buffer.index()
            ),
        )
    })
}

/// Reads every buffer of the document: the GLB's binary chunk, `data:` URIs, files beside
/// the glTF file (bounded regular files). Each must hold at least its byteLength.
fn read_buffers(
    path: &Path,
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>> {
    let label = path.display().to_string();
    let bad = |message: String| Error::invalid(label.clone(), message);
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let mut data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                bad(format!(
                    "buffer {} refers to a binary chunk the file does not have",
                    buffer.index()
                ))
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                gltf::buffer::Data::from_source(buffer.source(), None)
                    .map_err(|e| {
                        bad(format!(
                            "buffer {}: cannot decode its data: URI: {e}",
                            buffer.index()
                        ))
                    })?
                    .0
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = buffer_file(path, &buffer, uri)?;
                dispmap::input::read(&file, MAX_FILE_BYTES, BUFFER_WHAT)?
            }
        };
        if data.len() < buffer.length() {
            return Err(bad(format!(
                "buffer {} has {} bytes, fewer than its byteLength {}",
                buffer.index(),
                data.len(),
                buffer.length()
            )));
        }
        while data.len() % 4 != 0 {
            data.push(0);
        }
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
}

/// The meshes of the default scene (or the first) with their world transforms, in a
/// walk of its node trees; a node reached twice (a cycle or a shared subtree) is an
/// error.
fn scene_meshes<'a>(
    document: &'a gltf::Document,
    label: &str,
) -> Result<Vec<(gltf::Mesh<'a>, glam::Mat4)>> {
    let bad = |message: String| Error::invalid(label, message);
    let mut stack: Vec<(gltf::Node, glam::Mat4)> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect(),
        None => return Err(bad("has no scene".into())),
    };
    // glTF nodes form trees (a node has at most one parent): a node reached twice is a
    // cycle or a shared subtree, which would repeat (or never end) the walk.
    let mut seen = vec![false; document.nodes().count()];
    let mut meshes = Vec::new();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(bad(format!(
                "node {} is reached twice (a cycle or a shared subtree: glTF nodes form trees)",
                node.index()
            )));
        }
        let world = parent * glam::Mat4::from_cols_array_2d(&node.transform().matrix());
        stack.extend(node.children().map(|c| (c, world)));
        if let Some(mesh) = node.mesh() {
            meshes.push((mesh, world));
        }
    }
    Ok(meshes)
}

/// The triangle primitives read (mode TRIANGLES with a POSITION attribute).
fn triangle_primitives<'a>(mesh: &gltf::Mesh<'a>) -> impl Iterator<Item = gltf::Primitive<'a>> {
    mesh.primitives().filter(|p| {
        p.mode() == gltf::mesh::Mode::Triangles && p.get(&gltf::Semantic::Positions).is_some()
    })
}

/// The JSON of a `.glb` (its first chunk) or the whole of a `.gltf`, read from `path`
/// without its binary chunk; with the file's size.
fn json_of(path: &Path) -> Result<(Vec<u8>, u64)> {
    let io = |source| Error::Io {
        path: path.to_owned(),
        source,
    };
    let (mut file, len) = dispmap::input::open(path, MAX_FILE_BYTES, WHAT)?;
    let mut header = [0u8; 20];
    let n = file.read(&mut header).map_err(io)?;
    let json = if n >= 4 && &header[..4] == b"glTF" {
        file.read_exact(&mut header[n..]).map_err(io)?;
        let chunk = u64::from(u32::from_le_bytes([
            header[12], header[13], header[14], header[15],
        ]));
        if chunk > len {
            return Err(Error::invalid(
                path.display().to_string(),
                format!("its JSON chunk claims {chunk} bytes, more than the file's {len}"),
            ));
        }
        let mut json = header.to_vec();
        file.take(chunk).read_to_end(&mut json).map_err(io)?;
        // A GLB header claiming only this chunk, so the parser does not look for more.
        let total = (json.len() as u32).to_le_bytes();
        json[8..12].copy_from_slice(&total);
        json
    } else {
        let mut json = header[..n].to_vec();
        file.take(len.saturating_sub(n as u64))
            .read_to_end(&mut json)
            .map_err(io)?;
        json
    };
    Ok((json, len))
}

/// The size of a glTF file (see [`super::measure`]): the file's bytes with its buffer
/// files' and the decoded `data:` URIs', and the vertices and triangles of the default
/// scene's triangle primitives, from the accessors' counts.
pub(super) fn measure(path: &Path) -> Result<MeshSize> {
    let label = path.display().to_string();
    let (json, len) = json_of(path)?;
    let gltf = parse(&json, &label)?;
    let mut file_bytes = len;
    for buffer in gltf.document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            file_bytes += if uri.starts_with("data:") {
                uri.len() as u64 * 3 / 4
            } else {
                dispmap::input::check(
                    &buffer_file(path, &buffer, uri)?,
                    MAX_FILE_BYTES,
                    BUFFER_WHAT,
                )?
            };
        }
    }
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for (mesh, _) in scene_meshes(&gltf.document, &label)? {
        for primitive in triangle_primitives(&mesh) {
            let count = primitive
                .get(&gltf::Semantic::Positions)
                .map_or(0, |a| a.count() as u64);
            vertices += count;
            triangles += primitive.indices().map_or(count, |a| a.count() as u64) / 3;
        }
    }
    Ok(MeshSize {
        file_bytes,
        vertices,
        triangles,
    })
}

/// Loads the triangles of a glTF 2.0 file's default scene (every node, with its world
/// transform) as one mesh. Errors name the file; an accessor the specification does not
/// allow (or that leaves its buffer) is named with its mesh and primitive.
pub fn load_gltf(path: &Path) -> Result<Mesh> {
    let label = path.display().to_string();
    let bad = |message: String| Error::invalid(label.clone(), message);
    let bytes = dispmap::input::read(path, MAX_FILE_BYTES, WHAT)?;
    let gltf = parse(&bytes, &label)?;
    drop(bytes);
    // Buffers are read from the file itself or from files beside it: a URI that leaves
    // the file's folder (absolute, `..`, a scheme other than data:) is refused by name,
    // before any is read.
    for buffer in gltf.document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
        {
            buffer_file(path, &buffer, uri)?;
        }
    }
    let meshes = scene_meshes(&gltf.document, &label)?;
    let (mut vertices, mut triangles) = (0u64, 0u64);
    for (mesh, _) in &meshes {
        for primitive in triangle_primitives(mesh) {
            let count = primitive
                .get(&gltf::Semantic::Positions)
                .map_or(0, |a| a.count() as u64);
            vertices += count;
            triangles += primitive.indices().map_or(count, |a| a.count() as u64) / 3;
        }
    }
    check_counts(&label, vertices, triangles)?;
    let buffers = read_buffers(path, &gltf.document, gltf.blob.clone())?;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut tangents = Vec::new();
    let mut uvs = Vec::new();
    let mut indices = Vec::new();
    // glTF's material `doubleSided`: the mesh is drawn two-sided when any of its
    // triangle primitives' materials is (dispmap draws one mesh with one pipeline).
    let mut double_sided = false;
    for (mesh, world) in &meshes {
        let world = *world;
        let normal_matrix = glam::Mat3::from_mat4(world).inverse().transpose();
        for (k, primitive) in mesh.primitives().enumerate() {
            if primitive.mode() != gltf::mesh::Mode::Triangles
                || primitive.get(&gltf::Semantic::Positions).is_none()
            {
                continue;
            }
            double_sided |= primitive.material().double_sided();
            let site = Site { mesh, primitive: k };
            check_primitive(&site, &primitive, &buffers).map_err(bad)?;
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
                            return Err(bad(format!(
                                "mesh {}, primitive {k}: index {i} out of range (the \
                                 primitive has {count} vertices)",
                                mesh.index()
                            )));
                        }
                        indices.push(base + i);
                    }
                }
                None => indices.extend(base..base + count as u32),
            }
        }
    }
    let mut mesh = Mesh::from_parts(&label, positions, normals, tangents, uvs, indices)?;
    mesh.two_sided = double_sided;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffer_uris_stay_in_the_folder_after_decoding() {
        assert_eq!(buffer_path("a.bin"), Ok(PathBuf::from("a.bin")));
        assert_eq!(
            buffer_path("sub/a%20b.bin"),
            Ok(PathBuf::from("sub/a b.bin"))
        );
        for bad in [
            "../a.bin",
            "%2E%2E/a.bin",
            "/etc/passwd",
            "%2Fetc/passwd",
            "file:a.bin",
            "http://x/a.bin",
            "a%zz.bin",
            "a%00.bin",
        ] {
            assert!(buffer_path(bad).is_err(), "{bad}");
        }
    }
}
