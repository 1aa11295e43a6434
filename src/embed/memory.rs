//! What a [`DisplacementPass`] holds: the bytes of device memory of each kind of resource
//! it owns and of each material ([`DisplacementPass::memory`]). The sizes are the
//! allocations' own (gpu-allocator's sizes of the pass's images and buffers), not
//! estimates; docs/embedding.md ("Memory") gives each resource's size formula.

use super::DisplacementPass;
use super::inputs::MaterialId;
use crate::gpu::owned::Destroy;

/// The device memory a [`DisplacementPass`] holds, in bytes, by kind of resource
/// ([`MemoryReport::total`] is their sum) and per material ([`MemoryReport::materials`]).
/// A host's own images (its G-buffer, hit images, a [`super::HostHeightMap`]) are the
/// host's and not counted.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryReport {
    /// dispmap's copies of the height maps (with their mip chains under level of
    /// detail); 0 for maps the host owns.
    pub height_textures: u64,
    /// The max and min pyramids of the maps.
    pub pyramids: u64,
    /// The cone maps (and, until their build, a relaxed cone map's scratch pyramids).
    pub cone_maps: u64,
    /// The map preparations the host asked for
    /// ([`DisplacementPass::set_map_preparation`]).
    pub map_preparations: u64,
    /// The materials' albedo and normal maps (an image shared by several materials once).
    pub material_maps: u64,
    /// Staging buffers of uploads the next record copies (height, albedo and normal maps).
    pub uploads: u64,
    /// The DIG corner grids: one per DIG material and frame slot.
    pub corner_grids: u64,
    /// The tile lists: one set per frame slot, sized by the frame alone
    /// ([`crate::passes::classify::TileLists::bytes_for`]).
    pub tile_lists: u64,
    /// The visibility images (self-shadowing on): one per frame slot.
    pub visibility: u64,
    /// The corrected-depth images (the output on): one per frame slot.
    pub hit_depth: u64,
    /// The iteration-count images (the output on): one per frame slot.
    pub iterations: u64,
    /// The curved meshes the `exact` walk follows
    /// ([`DisplacementPass::set_curved_meshes`]): their triangles, neighbours and start
    /// grid in one buffer.
    pub curved_meshes: u64,
    /// The mesh walk's lists of pixels (a material walks the curved meshes): one buffer
    /// per frame slot, 8 bytes a pixel (the triage's list and the walk's).
    pub walk_lists: u64,
    /// Replaced resources that frames in flight may still read, freed once every slot
    /// has been recorded again.
    pub retired: u64,
    /// Per live material, by index.
    pub materials: Vec<MaterialMemory>,
}

/// What one material brings ([`MemoryReport::materials`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialMemory {
    /// The material.
    pub id: MaterialId,
    /// Its height map with what is derived from it (texture, pyramids, cone maps and a
    /// pending upload), shared by `map_users` materials.
    pub map: u64,
    /// The live materials on that map (itself included).
    pub map_users: u32,
    /// Its DIG corner grids (every frame slot).
    pub corner_grids: u64,
    /// Its share of its albedo and normal maps (an image shared by `n` materials counts
    /// `1/n` for each) and of their pending uploads.
    pub material_maps: u64,
}

impl MemoryReport {
    /// Every byte the pass holds.
    pub fn total(&self) -> u64 {
        self.maps() + self.frame() + self.retired
    }

    /// What follows the content: height textures, pyramids, cone maps, map preparations,
    /// material maps, pending uploads and the curved meshes.
    pub fn maps(&self) -> u64 {
        self.height_textures
            + self.pyramids
            + self.cone_maps
            + self.map_preparations
            + self.material_maps
            + self.uploads
            + self.curved_meshes
    }

    /// What follows the frame's size: tile lists, corner grids, visibility, corrected
    /// depth, iteration counts and walk lists (every frame slot).
    pub fn frame(&self) -> u64 {
        self.tile_lists
            + self.corner_grids
            + self.visibility
            + self.hit_depth
            + self.iterations
            + self.walk_lists
    }
}

impl DisplacementPass {
    /// The device memory the pass holds now, by kind of resource and per material (see
    /// [`MemoryReport`]). Cheap (no Vulkan call); an empty report after
    /// [`DisplacementPass::destroy`].
    pub fn memory(&self) -> MemoryReport {
        let mut r = MemoryReport::default();
        for map in self.maps.iter().flatten() {
            r.height_textures += map.texture.bytes();
            r.pyramids += map.pyramids.bytes();
            r.cone_maps += map.cones.bytes();
            r.map_preparations += map.prepared.bytes();
            r.uploads += map.pending_fill.bytes();
        }
        for (i, m) in self.materials.iter().enumerate() {
            let Some(m) = m else { continue };
            r.material_maps += m.shading.bytes();
            r.uploads += m.pending_shading.bytes();
            let map = self.maps.get(m.map).and_then(Option::as_ref);
            r.materials.push(MaterialMemory {
                id: MaterialId {
                    index: i as u32,
                    generation: m.generation,
                },
                map: map.map_or(0, |e| e.bytes()),
                map_users: self
                    .materials
                    .iter()
                    .flatten()
                    .filter(|o| o.map == m.map)
                    .count() as u32,
                corner_grids: (self.slots.iter())
                    .filter_map(|s| s.corner_grid(i))
                    .map(Destroy::bytes)
                    .sum(),
                material_maps: m.shading.bytes() + m.pending_shading.bytes(),
            });
        }
        for s in &self.slots {
            r.tile_lists += s.tiles.bytes();
            r.visibility += s.visibility.bytes();
            r.hit_depth += s.hit_depth.bytes();
            r.corner_grids += s.corners.bytes();
            r.iterations += s.iterations.bytes();
            r.walk_lists += s.walk_list.bytes();
        }
        r.curved_meshes = self.walk.bytes();
        r.retired = self.retired.bytes();
        r
    }
}
