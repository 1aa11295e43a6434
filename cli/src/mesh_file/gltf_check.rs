//! The checks a glTF 2.0 primitive passes before its accessors are read: what the
//! specification allows for each attribute dispmap reads (types and component types, the
//! "Meshes" section's table), and that every accessor, buffer view and sparse block lies
//! inside its buffer with a usable stride ("Accessors", "Buffers and buffer views").
//! The `gltf` crate's readers assume all of this (a `TEXCOORD_0` of SHORT or a stride
//! smaller than the element reaches `unreachable!` or an assertion there); an error here
//! names the file, mesh, primitive and accessor instead.

use gltf::Semantic;
use gltf::accessor::{DataType, Dimensions};

/// Where an accessor is used, for messages: `mesh 0 ('Cube'), primitive 1, accessor 3
/// (TEXCOORD_0)`.
pub(super) struct Site<'a> {
    pub mesh: &'a gltf::Mesh<'a>,
    pub primitive: usize,
}

impl Site<'_> {
    fn name(&self, accessor: &gltf::Accessor, role: &str) -> String {
        let mesh = match self.mesh.name() {
            Some(n) => format!("mesh {} ('{n}')", self.mesh.index()),
            None => format!("mesh {}", self.mesh.index()),
        };
        format!(
            "{mesh}, primitive {}, accessor {} ({role})",
            self.primitive,
            accessor.index()
        )
    }
}

fn type_name(t: DataType) -> &'static str {
    match t {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

fn dims_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// Checks the primitive's accessors that dispmap reads (POSITION, NORMAL, TANGENT,
/// TEXCOORD_0, the indices) against the specification and the buffers' real lengths
/// (`buffers[i]`: buffer `i`'s bytes). `Err`: the message, naming the mesh, primitive and
/// accessor (the caller adds the file).
pub(super) fn check_primitive(
    site: &Site,
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
) -> Result<(), String> {
    use DataType::{F32, U8, U16, U32};
    let attributes: [(Semantic, &str, Dimensions, &[DataType], &str); 4] = [
        (
            Semantic::Positions,
            "POSITION",
            Dimensions::Vec3,
            &[F32],
            "VEC3 of FLOAT",
        ),
        (
            Semantic::Normals,
            "NORMAL",
            Dimensions::Vec3,
            &[F32],
            "VEC3 of FLOAT",
        ),
        (
            Semantic::Tangents,
            "TANGENT",
            Dimensions::Vec4,
            &[F32],
            "VEC4 of FLOAT",
        ),
        (
            Semantic::TexCoords(0),
            "TEXCOORD_0",
            Dimensions::Vec2,
            &[F32, U8, U16],
            "VEC2 of FLOAT, or of normalized UNSIGNED_BYTE or UNSIGNED_SHORT",
        ),
    ];
    let mut count = None;
    for (semantic, role, dims, types, allowed) in attributes {
        let Some(accessor) = primitive.get(&semantic) else {
            continue;
        };
        let name = site.name(&accessor, role);
        let (t, d) = (accessor.data_type(), accessor.dimensions());
        if d != dims || !types.contains(&t) {
            return Err(format!(
                "{name}: {} of {} is not allowed for {role} by the glTF 2.0 specification \
                 ({allowed})",
                dims_name(d),
                type_name(t)
            ));
        }
        if t != F32 && !accessor.normalized() {
            return Err(format!(
                "{name}: {role} of {} must be normalized (the glTF 2.0 specification)",
                type_name(t)
            ));
        }
        check_accessor(&name, &accessor, buffers, false)?;
        match count {
            None => count = Some((accessor.count(), role)),
            Some((n, first)) if n != accessor.count() => {
                return Err(format!(
                    "{name}: {} elements, but {first} has {n} (a primitive's attributes \
                     must have the same count)",
                    accessor.count()
                ));
            }
            Some(_) => {}
        }
    }
    if let Some(accessor) = primitive.indices() {
        let name = site.name(&accessor, "indices");
        let (t, d) = (accessor.data_type(), accessor.dimensions());
        if d != Dimensions::Scalar || !matches!(t, U8 | U16 | U32) || accessor.normalized() {
            return Err(format!(
                "{name}: {} of {}{} is not allowed for indices by the glTF 2.0 specification \
                 (SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not normalized)",
                dims_name(d),
                if accessor.normalized() {
                    "normalized "
                } else {
                    ""
                },
                type_name(t)
            ));
        }
        if accessor.view().is_none() {
            return Err(format!("{name}: indices need a bufferView"));
        }
        check_accessor(&name, &accessor, buffers, true)?;
        if accessor.count() % 3 != 0 {
            return Err(format!(
                "{name}: {} indices are not whole triangles (a multiple of 3)",
                accessor.count()
            ));
        }
    }
    Ok(())
}

/// The bytes of buffer view `view`, checked against its buffer's declared and real
/// length; `stride`: whether a byteStride is allowed on it.
fn view_bytes<'b>(
    name: &str,
    view: &gltf::buffer::View,
    buffers: &'b [gltf::buffer::Data],
    stride_allowed: bool,
) -> Result<&'b [u8], String> {
    let buffer = view.buffer();
    let declared = buffer.length() as u64;
    let (offset, length) = (view.offset() as u64, view.length() as u64);
    let end = offset + length;
    if end > declared {
        return Err(format!(
            "{name}: bufferView {} ends at byte {end}, past the {declared} bytes of buffer {}",
            view.index(),
            buffer.index()
        ));
    }
    let data = buffers
        .get(buffer.index())
        .map(|d| &d.0[..])
        .ok_or_else(|| format!("{name}: buffer {} was not read", buffer.index()))?;
    if !stride_allowed && view.stride().is_some() {
        return Err(format!(
            "{name}: bufferView {} has a byteStride, which the glTF 2.0 specification \
             forbids here",
            view.index()
        ));
    }
    data.get(offset as usize..end as usize).ok_or_else(|| {
        format!(
            "{name}: bufferView {} ends at byte {end}, past the {} bytes read for buffer {}",
            view.index(),
            data.len(),
            buffer.index()
        )
    })
}

/// Checks one accessor: a count of at least 1, an aligned offset, a stride of at least one
/// element (a multiple of the component size), every element inside its buffer view, and
/// a sparse block's indices (increasing, below the count) and values inside theirs.
/// `indices`: the accessor holds indices (its view may have no byteStride).
fn check_accessor(
    name: &str,
    accessor: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    indices: bool,
) -> Result<(), String> {
    let count = accessor.count() as u64;
    if count == 0 {
        return Err(format!(
            "{name}: count is 0 (the glTF 2.0 specification needs 1 or more)"
        ));
    }
    let component = accessor.data_type().size() as u64;
    let element = accessor.size() as u64;
    let offset = accessor.offset() as u64;
    if let Some(view) = accessor.view() {
        let bytes = view_bytes(name, &view, buffers, !indices)?;
        let stride = view.stride().map_or(element, |s| s as u64);
        if stride < element {
            return Err(format!(
                "{name}: bufferView {} has byteStride {stride}, smaller than the accessor's \
                 {element}-byte element",
                view.index()
            ));
        }
        if !stride.is_multiple_of(component)
            || !(offset + view.offset() as u64).is_multiple_of(component)
        {
            return Err(format!(
                "{name}: its offset or stride is not a multiple of its {component}-byte \
                 component (byteOffset {offset}, bufferView {} at {}, stride {stride})",
                view.index(),
                view.offset()
            ));
        }
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(offset + element))
            .unwrap_or(u64::MAX);
        if end > bytes.len() as u64 {
            return Err(format!(
                "{name}: {count} elements from byte {offset} with stride {stride} end at byte \
                 {end}, past the {} bytes of bufferView {}",
                bytes.len(),
                view.index()
            ));
        }
    } else if offset != 0 {
        return Err(format!("{name}: a byteOffset without a bufferView"));
    }
    let Some(sparse) = accessor.sparse() else {
        return Ok(());
    };
    let n = sparse.count() as u64;
    if n == 0 || n > count {
        return Err(format!(
            "{name}: a sparse count of {n} is outside 1..={count} (the accessor's count)"
        ));
    }
    let index = sparse.indices();
    let index_size = index.index_type().size() as u64;
    let bytes = view_bytes(name, &index.view(), buffers, false)?;
    let start = index.offset() as u64;
    if !start.is_multiple_of(index_size) || start + n * index_size > bytes.len() as u64 {
        return Err(format!(
            "{name}: its {n} sparse indices from byte {start} do not fit bufferView {} ({} \
             bytes) or are not aligned",
            index.view().index(),
            bytes.len()
        ));
    }
    let mut previous = None;
    for k in 0..n {
        let at = (start + k * index_size) as usize;
        let i = match index_size {
            1 => u64::from(bytes[at]),
            2 => u64::from(u16::from_le_bytes([bytes[at], bytes[at + 1]])),
            _ => u64::from(u32::from_le_bytes([
                bytes[at],
                bytes[at + 1],
                bytes[at + 2],
                bytes[at + 3],
            ])),
        };
        if i >= count || previous.is_some_and(|p| i <= p) {
            return Err(format!(
                "{name}: sparse index {i} (number {k}) is not increasing or not below the \
                 count {count}"
            ));
        }
        previous = Some(i);
    }
    let values = sparse.values();
    let bytes = view_bytes(name, &values.view(), buffers, false)?;
    let start = values.offset() as u64;
    if !start.is_multiple_of(component) || start + n * element > bytes.len() as u64 {
        return Err(format!(
            "{name}: its {n} sparse values from byte {start} do not fit bufferView {} ({} \
             bytes) or are not aligned",
            values.view().index(),
            bytes.len()
        ));
    }
    Ok(())
}
