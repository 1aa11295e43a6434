//! The table's entries: what each height map (its texture and what is derived from
//! it, the map preparations included), each material and each frame slot holds, with
//! the key that identifies a map. `plan.rs` decides which entries exist.

use super::MaterialSettings;
use crate::context::Context;
use crate::error::Result;
use crate::gpu::owned::Destroy;
use crate::gpu::{Buffer, HeightTexture, Image};
use crate::heightfield::{Addressing, HeightField};
use crate::material::{MaterialStaging, MaterialTextures};
use crate::method::{ConeKind, PyramidKind};
use crate::passes::classify::TileLists;
use crate::passes::cone::ConeMap;
use crate::passes::dig::CornerGrid;
use crate::passes::prepare::Erased;
use crate::passes::pyramid::Pyramid;
use crate::timing::TimestampScope;
use ash::vk;
use std::hash::{Hash, Hasher};

/// A height texture's contents not yet recorded.
pub(super) enum Fill {
    /// A new map's staging buffer.
    Upload(Buffer),
    /// The texture it replaces (level of detail switched on or off: the mip chain added
    /// or dropped), whose level 0 is copied; frames in flight may still sample it.
    Copy(HeightTexture),
}

impl Destroy for Fill {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            match self {
                Fill::Upload(b) => b.destroy(ctx),
                Fill::Copy(h) => h.destroy(ctx),
            }
        }
    }

    fn bytes(&self) -> u64 {
        match self {
            Fill::Upload(b) => b.bytes(),
            Fill::Copy(h) => h.bytes(),
        }
    }
}

/// What identifies a height map: two materials with the same key share one texture and
/// everything derived from it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct MapKey {
    /// A 64-bit hash of the texels, or the host's image.
    hash: MapSource,
    size: [u32; 2],
    format: vk::Format,
    pub addressing: Addressing,
}

/// Where a map's texels are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MapSource {
    /// dispmap's upload of texels with this 64-bit hash.
    Texels(u64),
    /// A host engine's image as the host describes it, and the version of its contents
    /// (a new one each time the host says they changed: a new entry, new preparations).
    Host {
        map: super::HostHeightMap,
        version: u64,
    },
}

impl MapKey {
    pub fn of(field: &HeightField, addressing: Addressing) -> Self {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        field.bytes().hash(&mut h);
        MapKey {
            hash: MapSource::Texels(h.finish()),
            size: [field.width(), field.height()],
            format: field.format(),
            addressing,
        }
    }

    /// The key of a host image's map.
    pub fn host(
        source: MapSource,
        size: [u32; 2],
        format: vk::Format,
        addressing: Addressing,
    ) -> Self {
        MapKey {
            hash: source,
            size,
            format,
            addressing,
        }
    }

    /// The host image's source, `None` for dispmap's upload.
    pub fn host_source(&self) -> Option<MapSource> {
        matches!(self.hash, MapSource::Host { .. }).then_some(self.hash)
    }
}

/// A resource built by a record (`built`) or still to be.
pub(super) struct Built<T> {
    pub value: T,
    pub built: bool,
}

impl<T: Destroy> Destroy for Built<T> {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.value.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.value.bytes()
    }
}

/// One height map of the table and what is derived from it.
pub(super) struct MapEntry {
    pub key: MapKey,
    pub texture: HeightTexture,
    /// How `texture` is still to be filled (the next record); `None` once filled.
    pub pending_fill: Option<Fill>,
    pub pyramids: Vec<Built<Pyramid>>,
    pub cones: Vec<Built<ConeMap>>,
    /// Its entries of the table of map preparations.
    pub prepared: Vec<Prepared>,
}

/// An entry of the table of map preparations: its kind (an index of
/// [`crate::passes::prepare::KINDS`]) and its value, built by a record or still to be;
/// its key is (its map, `kind`).
pub(super) struct Prepared {
    pub kind: usize,
    pub value: Box<dyn Erased>,
    pub built: bool,
}

impl Destroy for Prepared {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe { self.value.destroy(ctx) }
    }

    fn bytes(&self) -> u64 {
        self.value.bytes()
    }
}

/// The pipelines of one kind of map preparation.
pub(super) struct PreparePass {
    pub kind: usize,
    pub pass: Box<dyn Erased>,
}

impl Destroy for PreparePass {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe { self.pass.destroy(ctx) }
    }
}

impl MapEntry {
    /// A new map's texture and its staged upload.
    pub fn new(ctx: &Context, field: &HeightField, key: MapKey, chain: bool) -> Result<Self> {
        let (texture, staging) =
            HeightTexture::create_for_upload(ctx, field, key.addressing, chain)?;
        Ok(MapEntry {
            key,
            texture,
            pending_fill: Some(Fill::Upload(staging)),
            pyramids: Vec::new(),
            cones: Vec::new(),
            prepared: Vec::new(),
        })
    }

    /// A host image's map: its texture (views of the host's image), nothing to fill.
    pub fn new_host(key: MapKey, texture: HeightTexture) -> Self {
        MapEntry {
            key,
            texture,
            pending_fill: None,
            pyramids: Vec::new(),
            cones: Vec::new(),
            prepared: Vec::new(),
        }
    }

    /// The built pyramid of `kind`.
    pub fn pyramid(&self, kind: PyramidKind) -> Option<&Pyramid> {
        self.pyramids
            .iter()
            .find(|p| p.built && p.value.kind == kind)
            .map(|p| &p.value)
    }

    /// The built cone map of `kind`.
    pub fn cone(&self, kind: ConeKind) -> Option<&ConeMap> {
        self.cones
            .iter()
            .find(|c| c.built && c.value.kind == kind)
            .map(|c| &c.value)
    }

    /// Whether the next record has work for it (a fill, a pyramid or cone build).
    pub fn pending(&self) -> bool {
        self.pending_fill.is_some()
            || self.pyramids.iter().any(|p| !p.built)
            || self.cones.iter().any(|c| !c.built)
            || self.prepared.iter().any(|p| !p.built)
    }
}

impl Destroy for MapEntry {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pending_fill.destroy(ctx);
            self.prepared.destroy(ctx);
            self.cones.destroy(ctx);
            self.pyramids.destroy(ctx);
            self.texture.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.pending_fill.bytes()
            + self.prepared.bytes()
            + self.cones.bytes()
            + self.pyramids.bytes()
            + self.texture.bytes()
    }
}

/// One displaced material of the table.
pub(super) struct MaterialEntry {
    pub generation: u32,
    pub settings: MaterialSettings,
    /// Its map in the pass's map table.
    pub map: usize,
    /// Albedo and normal map for `shade`.
    pub shading: Option<MaterialTextures>,
    /// Their staging buffers until a record copies them.
    pub pending_shading: Option<MaterialStaging>,
    /// Trace its pixels as curved macro geometry
    /// ([`super::DisplacementPass::set_material_curved`]).
    pub curved: bool,
}

impl Destroy for MaterialEntry {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.shading.destroy(ctx);
            self.pending_shading.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.shading.bytes() + self.pending_shading.bytes()
    }
}

/// What one frame in flight owns: a frame recorded in the slot uses these, and only
/// that slot's frames do.
pub(super) struct Slot {
    /// The material tile lists.
    pub tiles: TileLists,
    /// The light visibility (self-shadowing on).
    pub visibility: Option<Image>,
    /// The corrected depth (the corrected-depth output on).
    pub hit_depth: Option<Image>,
    /// The iteration counts (the iteration output on).
    pub iterations: Option<Image>,
    /// The mesh walk's list of pixels (a material walks the pass's meshes,
    /// [`crate::passes::trace::walk_list_bytes`]).
    pub walk_list: Option<crate::gpu::Buffer>,
    /// The DIG corner grid of each DIG material, by material index.
    pub corners: Vec<Option<CornerGrid>>,
    /// The owned-pool timestamp scopes the slot recorded last.
    pub scopes: Vec<TimestampScope>,
}

impl Destroy for Slot {
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.tiles.destroy(ctx);
            self.visibility.destroy(ctx);
            self.hit_depth.destroy(ctx);
            self.iterations.destroy(ctx);
            self.walk_list.destroy(ctx);
            self.corners.destroy(ctx);
        }
    }

    fn bytes(&self) -> u64 {
        self.tiles.bytes()
            + self.visibility.bytes()
            + self.hit_depth.bytes()
            + self.iterations.bytes()
            + self.walk_list.bytes()
            + self.corners.bytes()
    }
}

impl Slot {
    /// Material `material`'s corner grid in this slot (DIG materials only).
    pub fn corner_grid(&self, material: usize) -> Option<&CornerGrid> {
        self.corners.get(material)?.as_ref()
    }
}
