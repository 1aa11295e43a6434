//! The memory bound of a run: an estimate of the bytes a render needs from the map's and
//! the frame's size, made before anything large is allocated, and refused when it is
//! above the memory available (or `--max-memory`). See docs/guarantees.md.
//!
//! The estimate is the larger of the two peaks of a run: loading the map (the file's
//! bytes, the decoded image and the height field it becomes, all held at once) and
//! rendering (the height field, the GPU's copy of it with its pyramids, the frame's GPU
//! buffers and read-backs, and with `--metrics` the exact reference: its texels and max
//! pyramid, [`Reference::memory_bytes`], and its per-pixel rays and hits), and the
//! albedo and normal maps ([`MaterialMaps`]). The per-texel
//! and per-pixel coefficients are the peak resident memory measured on lavapipe (whose
//! "GPU" memory is the process's), rounded up (docs/guarantees.md has the
//! measurements).

use crate::reference::Reference;
use dispmap::error::{Error, Result};
use dispmap::heightfield::ImageHeader;
use dispmap::method::{ConeKind, Method, PyramidKind};
use dispmap::passes::pyramid::stored_texels;

/// Bytes of the process before any map or frame (Vulkan instance and device, lavapipe,
/// the binary): measured 90-100 MiB with a 2048x2048 map and a 64x64 frame, rounded up.
const BASE_BYTES: u64 = 128 << 20;
/// Bytes per texel of the GPU's copy of the map, per byte of a texel, plus one (the
/// height image, its staging buffer and the pyramids): measured 1.9 (8-bit) and 4.0
/// (16-bit) on 8192x8192 maps.
const GPU_BYTES_PER_TEXEL_BYTE: u64 = 2;
/// Bytes per frame pixel of the GPU's buffers and the colour read-back of any render:
/// measured 62-65 when the tile lists took a few kilobytes; they are counted apart now
/// ([`tile_list_bytes`]).
const FRAME_BYTES_PER_PIXEL: u64 = 72;

/// Bytes of the displacement pass's tile lists for a `frame` (the standalone renderer
/// has one frame slot): sized by the frame alone, whatever the number of materials
/// (`TileLists::bytes_for`: about 4.06 bytes a pixel).
pub fn tile_list_bytes(frame: [u32; 2]) -> u64 {
    dispmap::passes::classify::TileLists::bytes_for(ash::vk::Extent2D {
        width: frame[0],
        height: frame[1],
    })
}
/// Bytes per frame pixel `--heatmap` adds (hits and rays read back, the image): measured
/// 69.
const HEATMAP_BYTES_PER_PIXEL: u64 = 72;
/// Bytes per frame pixel `--depth-out` adds (the depth read back, the RGB f32 image):
/// measured 21.
const DEPTH_BYTES_PER_PIXEL: u64 = 32;
/// Bytes per frame pixel the reference adds (`--metrics`): its rays, hits, shaded colour
/// and the compared values: measured 105.
const REFERENCE_BYTES_PER_PIXEL: u64 = 120;

/// What a run keeps per pixel beyond the frame itself, and the one-off maps its methods
/// build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Extras {
    /// The exact reference (`--metrics`, the demo).
    pub reference: bool,
    /// `--heatmap` (or `--interval-map`: the same read-backs at most).
    pub heatmap: bool,
    /// `--depth-out`.
    pub depth: bool,
    /// The methods' pyramids and cone maps alive at the peak.
    pub maps: MethodMaps,
    /// A loaded mesh (`geometry = "mesh"`); all zero for none.
    pub mesh: MeshSize,
    /// The albedo and normal maps ([`MaterialMaps`]); all zero for none.
    pub images: MaterialMaps,
    /// Curved tracing (`--curved`): the curve images and the mesh walk; off for none.
    pub curved: Curved,
}

/// Bytes per triangle of the meshes the curved `exact` trace walks, at the peak of making
/// the walk buffer (its packed words, the buffer they are written into, the neighbour
/// and grid maps of the build): the peak resident memory with `--curved` less the peak
/// without, 64x64 frame, OBJ UV spheres: 496 on 423,200 triangles (467 MB against 257
/// MB), 441 on 845,000 (679 MB against 306 MB). Counted as 640: with the mesh's other
/// render-time bytes, which [`MESH_BYTES_PER_VERTEX`] and [`MESH_BYTES_PER_TRIANGLE`]
/// undercount at these sizes, the estimate is then 5% and 20% above those two peaks.
const WALK_BYTES_PER_TRIANGLE: u64 = 640;
/// Bytes per pixel of the G-buffer's curve image (`R16G16_SFLOAT`), in each of the two
/// layers (the first and the behind layer).
const CURVE_BYTES_PER_PIXEL: u64 = 8;
/// Frame slots a curved render may have (the first layer's and the behind layer's),
/// each with its walk list.
const WALK_LIST_SLOTS: u64 = 2;

/// What curved tracing adds to a run, for the estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Curved {
    /// Whether displaced meshes are traced curved (`--curved`): the G-buffers get their
    /// curve images.
    pub on: bool,
    /// Triangles of the meshes a material walks (its method [`Method::walks_meshes`] on a
    /// mesh, with `on`): the walk buffer, and a walk list per frame slot.
    pub walked_triangles: u64,
}

impl Curved {
    /// The triangles one object adds to [`Curved::walked_triangles`]: its mesh's (`loaded`
    /// for `geometry = "mesh"`, else the generated one's) when `curved` is on and its
    /// material's `method` walks meshes; none for the tiled plane and the quad.
    pub fn object_triangles(
        curved: bool,
        geometry: dispmap::scene::Geometry,
        method: Option<Method>,
        loaded: &MeshSize,
    ) -> u64 {
        if !curved || !method.is_some_and(Method::walks_meshes) {
            return 0;
        }
        match geometry {
            dispmap::scene::Geometry::Mesh => loaded.triangles,
            g => g
                .generated_mesh()
                .map_or(0, |m| (m.indices.len() / 3) as u64),
        }
    }

    /// Bytes while rendering `frame` pixels.
    pub fn render_bytes(&self, frame: [u32; 2]) -> u64 {
        if !self.on {
            return 0;
        }
        let pixels = u64::from(frame[0]) * u64::from(frame[1]);
        let walk = if self.walked_triangles > 0 {
            self.walked_triangles * WALK_BYTES_PER_TRIANGLE
                + WALK_LIST_SLOTS
                    * dispmap::passes::trace::walk_list_bytes(ash::vk::Extent2D {
                        width: frame[0],
                        height: frame[1],
                    })
        } else {
            0
        };
        pixels * CURVE_BYTES_PER_PIXEL + walk
    }
}

/// Bytes per texel of an albedo or normal map on the CPU while rendering: its RGBA8
/// texels (one copy per file, shared by every object that names it).
const RGBA_HELD_BYTES_PER_TEXEL: u64 = 4;
/// Bytes per texel of an albedo or normal map on the GPU, once per file however many
/// materials use it (they share one image: `MaterialTextures::create_sharing`): the
/// `R8G8B8A8` image, its staging buffer and the copy the staging buffer is filled from
/// (on lavapipe all are the process's memory). An 8000x8000 albedo measured 848 MB at
/// its peak with a 16x16 frame: about 12 bytes per texel over the process's base, its
/// held texels included.
const RGBA_GPU_BYTES_PER_TEXEL: u64 = 12;

/// The albedo and normal maps of a run, for the estimate: the texels held and the GPU
/// copies (each file once), and the largest load's transient bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MaterialMaps {
    /// Bytes of the decoded RGBA8 texels kept while rendering (each file once).
    pub held: u64,
    /// Bytes of the GPU images and their staging buffers (each file once: the
    /// materials naming it share its image).
    pub gpu: u64,
    /// The largest single load's bytes beyond what it keeps: the file and the decoded
    /// image before its RGBA8 conversion.
    pub load: u64,
}

impl MaterialMaps {
    /// Adds a map of `header`'s size: `first_use` when its file was not counted yet (its
    /// texels and its GPU image are held once, however many materials use it).
    pub fn add(&mut self, header: &ImageHeader, first_use: bool) {
        if first_use {
            let texels = u64::from(header.width) * u64::from(header.height);
            self.add_loaded([header.width, header.height]);
            self.load = self
                .load
                .max(header.file_bytes + texels * u64::from(header.decoded_bytes_per_pixel));
        }
    }

    /// Adds a map already loaded, of `size` texels (each distinct map once).
    pub fn add_loaded(&mut self, size: [u32; 2]) {
        let texels = u64::from(size[0]) * u64::from(size[1]);
        self.held += texels * RGBA_HELD_BYTES_PER_TEXEL;
        self.gpu += texels * RGBA_GPU_BYTES_PER_TEXEL;
    }

    /// The maps of loaded materials: each distinct map once (clones of one
    /// [`dispmap::material::RgbaMap`] share their texels, and the renderer shares the
    /// image of maps with the same texels).
    pub fn of_loaded<'a>(
        materials: impl IntoIterator<Item = &'a dispmap::material::MaterialImages>,
    ) -> Self {
        let mut out = MaterialMaps::default();
        let mut seen = Vec::new();
        for images in materials {
            for map in [&images.albedo, &images.normal_map].into_iter().flatten() {
                // Clones share their texels: one map, one address.
                let at = map.texels().as_ptr();
                if !seen.contains(&at) {
                    seen.push(at);
                    out.add_loaded([map.width(), map.height()]);
                }
            }
        }
        out
    }

    /// Bytes while rendering.
    pub fn render_bytes(&self) -> u64 {
        self.held + self.gpu
    }
}

/// Bytes a mesh holds while it is read and built, per byte of its files (the bytes read,
/// held while the parser runs), per vertex (the parser's attributes and index map, the
/// mesh's per-vertex sums for its tangent frame, the finished vertices) and per triangle
/// (the parser's, the mesh's and the upload's indices). Fitted to the peak resident
/// memory of OBJ and glTF meshes of 0.7-2 million triangles (docs/guarantees.md,
/// "Memory": measured 0.80 bytes per file byte, 131 per vertex, 91 per triangle), and
/// rounded up.
const MESH_LOAD_BYTES_PER_FILE_BYTE: u64 = 1;
/// See [`MESH_LOAD_BYTES_PER_FILE_BYTE`].
const MESH_LOAD_BYTES_PER_VERTEX: u64 = 170;
/// See [`MESH_LOAD_BYTES_PER_FILE_BYTE`].
const MESH_LOAD_BYTES_PER_TRIANGLE: u64 = 120;
/// Freed memory the C allocator keeps across the load's phases: blocks below glibc's
/// mmap threshold (at most 32 MiB) go back to its heap, not to the system, so a mesh of
/// up to a few hundred thousand vertices peaks at the sum of its phases (measured: up
/// to 570 bytes per vertex and 66 MB above the per-element terms); counted as 750 bytes
/// per vertex, at most 96 MiB.
const MESH_HEAP_BYTES_PER_VERTEX: u64 = 750;
/// See [`MESH_HEAP_BYTES_PER_VERTEX`].
const MESH_HEAP_MAX_BYTES: u64 = 96 << 20;
/// Bytes per vertex and per triangle of the renderer's copy of a mesh (the vertex and
/// the indices), which the curved `exact` trace walks once curved tracing is on.
const MESH_COPY_BYTES_PER_VERTEX: u64 = 56;
const MESH_COPY_BYTES_PER_TRIANGLE: u64 = 12;
/// Bytes per vertex of a loaded mesh while rendering (the mesh, the renderer's copy that
/// the curved `exact` trace walks once curved tracing is on, the GPU's vertex buffer and
/// its staging copy: 56 bytes each).
const MESH_BYTES_PER_VERTEX: u64 = 248;
/// Bytes per triangle of a loaded mesh while rendering (indices: the mesh's, the
/// renderer's copy, the GPU's and the staging copy).
const MESH_BYTES_PER_TRIANGLE: u64 = 60;

/// A mesh's size for the estimate: its files' bytes and its vertex and triangle counts
/// ([`crate::mesh_file::measure`], before it is loaded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshSize {
    /// The mesh file's bytes (with a glTF's buffer files).
    pub file_bytes: u64,
    /// Vertices.
    pub vertices: u64,
    /// Triangles.
    pub triangles: u64,
}

impl MeshSize {
    /// Bytes held while the mesh is read and built (with the renderer's copy that the
    /// curved `exact` trace walks, made while the parsed mesh is still held: 56 bytes a
    /// vertex and 12 a triangle).
    pub fn load_bytes(&self) -> u64 {
        self.file_bytes * MESH_LOAD_BYTES_PER_FILE_BYTE
            + self.vertices * (MESH_LOAD_BYTES_PER_VERTEX + MESH_COPY_BYTES_PER_VERTEX)
            + self.triangles * (MESH_LOAD_BYTES_PER_TRIANGLE + MESH_COPY_BYTES_PER_TRIANGLE)
            + (self.vertices * MESH_HEAP_BYTES_PER_VERTEX).min(MESH_HEAP_MAX_BYTES)
    }

    /// Bytes held while rendering it.
    pub fn render_bytes(&self) -> u64 {
        self.vertices * MESH_BYTES_PER_VERTEX + self.triangles * MESH_BYTES_PER_TRIANGLE
    }
}

/// The one-off per-map images of the methods of a run alive at once: cell pyramids
/// (padded to powers of two: every level in the map's own format for 8- and 16-bit maps,
/// levels 1 and up in `R32_SFLOAT` for float ones; counted at 2 bytes per node), footprint
/// pyramids (`pyramid`'s, every level in `R32_SFLOAT`), cone maps (`R32G32_SFLOAT`) and a
/// relaxed cone map's build scratch (four more full `R32_SFLOAT` pyramids). Measured on
/// an 8-bit 2048² map, 64x64 frame (peak resident memory over `relief`'s), when the cell
/// pyramid was a full `R32_SFLOAT` chain and its 8-bit copy: `exact` +36.8 MB (its pyramid
/// and copy: 28.0 MB computed), `cone` +87.9 MB (61.5 MB computed), `relaxed-cone`
/// +170.1 MB (151.1 MB computed); the rest is pipeline compiles and the blit's, within
/// the process allowance (`BASE_BYTES`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MethodMaps {
    /// Cell pyramids.
    pub pyramids: u32,
    /// Footprint pyramids.
    pub footprint_pyramids: u32,
    /// Cone maps.
    pub cone_maps: u32,
    /// Relaxed cone maps being built (their scratch).
    pub relaxed_builds: u32,
}

impl MethodMaps {
    /// What `method` builds; `shadows`: hard self-shadowing, which builds a cell pyramid
    /// of its own when the method has none.
    pub fn of(method: Method, shadows: bool) -> Self {
        let needs = method.needs();
        let cell = needs.pyramid == Some(PyramidKind::Cell);
        MethodMaps {
            pyramids: u32::from(cell || shadows),
            footprint_pyramids: u32::from(needs.pyramid == Some(PyramidKind::Footprint)),
            cone_maps: u32::from(needs.cone.is_some()),
            relaxed_builds: u32::from(needs.cone == Some(ConeKind::Relaxed)),
        }
    }

    /// The maps of `methods` alive together (the benchmark keeps one renderer per method).
    pub fn together(methods: &[Method]) -> Self {
        methods.iter().fold(MethodMaps::default(), |sum, &m| {
            let one = MethodMaps::of(m, false);
            MethodMaps {
                pyramids: sum.pyramids + one.pyramids,
                footprint_pyramids: sum.footprint_pyramids + one.footprint_pyramids,
                cone_maps: sum.cone_maps + one.cone_maps,
                relaxed_builds: sum.relaxed_builds + one.relaxed_builds,
            }
        })
    }

    /// Their bytes on a `size` map.
    pub fn bytes(&self, size: [u32; 2]) -> u64 {
        let (w, h) = (size[0].max(1), size[1].max(1));
        // A cell pyramid: every level at 1 or 2 bytes (8- and 16-bit maps) or levels 1 and
        // up at 4 (float maps, a third of the nodes): at most 2 bytes per node.
        let cell = 2 * stored_texels(0, [w, h]);
        let full = 4 * stored_texels(0, [w, h]);
        let cone = u64::from(w) * u64::from(h) * 8;
        u64::from(self.pyramids) * cell
            + u64::from(self.footprint_pyramids) * full
            + u64::from(4 * self.relaxed_builds) * full
            + u64::from(self.cone_maps) * cone
    }
}

/// A run's estimated peak memory, with its parts for the message.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The estimated peak in bytes.
    pub bytes: u64,
    /// What it is made of (name, bytes), for messages.
    pub parts: Vec<(&'static str, u64)>,
}

/// The map facts the estimate needs: from a file's header ([`dispmap::HeightField::probe`])
/// or a loaded map (no load peak then).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapSize {
    /// Texels per row and column.
    pub size: [u32; 2],
    /// Bytes per texel of the height field (1, 2 or 4).
    pub texel_bytes: u32,
    /// Bytes held while loading beyond the height field (file + decoded image); 0 for a
    /// map already loaded.
    pub load_bytes: u64,
}

impl MapSize {
    /// From a file's header: the load holds the file and the decoded image.
    pub fn from_header(h: &ImageHeader) -> Self {
        MapSize {
            size: [h.width, h.height],
            texel_bytes: h.texel_bytes,
            load_bytes: h.file_bytes
                + u64::from(h.width) * u64::from(h.height) * u64::from(h.decoded_bytes_per_pixel),
        }
    }

    /// A map already in memory.
    pub fn loaded(field: &dispmap::HeightField) -> Self {
        MapSize {
            size: [field.width(), field.height()],
            texel_bytes: match field.format() {
                ash::vk::Format::R8_UNORM => 1,
                ash::vk::Format::R16_UNORM => 2,
                _ => 4,
            },
            load_bytes: 0,
        }
    }
}

/// The estimate of rendering `frame` pixels on `map` with `extras`.
pub fn estimate(map: MapSize, frame: [u32; 2], extras: Extras) -> Estimate {
    let texels = u64::from(map.size[0]) * u64::from(map.size[1]);
    let pixels = u64::from(frame[0]) * u64::from(frame[1]);
    let field = texels * u64::from(map.texel_bytes);
    let gpu = texels * (GPU_BYTES_PER_TEXEL_BYTE * u64::from(map.texel_bytes) + 1);
    let method_maps = extras.maps.bytes(map.size);
    let per_pixel = FRAME_BYTES_PER_PIXEL
        + if extras.heatmap {
            HEATMAP_BYTES_PER_PIXEL
        } else {
            0
        }
        + if extras.depth {
            DEPTH_BYTES_PER_PIXEL
        } else {
            0
        };
    let frame_bytes = pixels * per_pixel + tile_list_bytes(frame);
    let (ref_map, ref_frame) = if extras.reference {
        (
            Reference::memory_bytes(map.size[0], map.size[1]),
            pixels * REFERENCE_BYTES_PER_PIXEL,
        )
    } else {
        (0, 0)
    };
    // The mesh is read after the map: the map's load and the mesh's are two peaks. The
    // albedo and normal maps are read after both, beside the field and the mesh.
    let mesh_load = extras.mesh.load_bytes();
    let mesh_render = extras.mesh.render_bytes();
    let images = extras.images.render_bytes();
    let image_load = field + mesh_render + extras.images.held + extras.images.load;
    let load_peak = (map.load_bytes.max(mesh_load) + field).max(image_load);
    let curved = extras.curved.render_bytes(frame);
    let render_peak = field
        + gpu
        + method_maps
        + frame_bytes
        + ref_map
        + ref_frame
        + mesh_render
        + images
        + curved;
    let mut parts = vec![("process", BASE_BYTES)];
    if load_peak > render_peak {
        if image_load > map.load_bytes.max(mesh_load) + field {
            parts.push(("albedo and normal maps, loading", image_load - field));
        } else if mesh_load > map.load_bytes {
            parts.push(("mesh file and parsing", mesh_load));
        } else {
            parts.push(("map file and decoding", map.load_bytes));
        }
        parts.push(("height field", field));
    } else {
        parts.push(("height field", field));
        if mesh_render > 0 {
            parts.push(("mesh", mesh_render));
        }
        parts.push(("GPU copy of the map", gpu));
        if images > 0 {
            parts.push(("albedo and normal maps", images));
        }
        if method_maps > 0 {
            parts.push(("pyramids and cone maps", method_maps));
        }
        parts.push(("frame", frame_bytes));
        if curved > 0 {
            parts.push(("curve images and mesh walk (--curved)", curved));
        }
        if extras.reference {
            parts.push(("reference texels and pyramid", ref_map));
            parts.push(("reference rays and hits", ref_frame));
        }
    }
    Estimate {
        bytes: BASE_BYTES + load_peak.max(render_peak),
        parts,
    }
}

/// One displaced material of a frame of several objects, for [`estimate_objects`]: its
/// map and what its method builds on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialMemory {
    /// Its height map.
    pub map: MapSize,
    /// Its pyramids and cone maps.
    pub maps: MethodMaps,
    /// Its DIG block size, when its method is a DIG (a corner grid per frame slot).
    pub dig_block: Option<[u32; 2]>,
}

/// Bytes of a DIG corner grid (`R32G32B32A32_SFLOAT` per block corner) of `frame`.
fn corner_grid_bytes(frame: [u32; 2], block: [u32; 2]) -> u64 {
    let corners = |side: u32, b: u32| u64::from(side.div_ceil(b.max(1)) + 1);
    corners(frame[0], block[0]) * corners(frame[1], block[1]) * 16
}

/// The estimate of rendering `frame` pixels of several objects: **one** set of frame
/// images, read-backs and reference rays and hits whatever the number of materials
/// (`extras`' per-pixel parts, counted once), and per material only what it brings: its
/// height field, the GPU's copy, its method's pyramids and cone maps, its DIG corner grid
/// and, with the reference, its reference texels and pyramid; and the objects' meshes
/// (`extras.mesh`, their sizes summed). Maps are loaded one after the other, so the load
/// peak is the largest map's on top of the fields before it (and the meshes').
pub fn estimate_objects(materials: &[MaterialMemory], frame: [u32; 2], extras: Extras) -> Estimate {
    let pixels = u64::from(frame[0]) * u64::from(frame[1]);
    let per_pixel = FRAME_BYTES_PER_PIXEL
        + if extras.heatmap {
            HEATMAP_BYTES_PER_PIXEL
        } else {
            0
        }
        + if extras.depth {
            DEPTH_BYTES_PER_PIXEL
        } else {
            0
        };
    let frame_bytes = pixels * per_pixel + tile_list_bytes(frame);
    let ref_frame = if extras.reference {
        pixels * REFERENCE_BYTES_PER_PIXEL
    } else {
        0
    };
    let (mut fields, mut gpu, mut method_maps, mut grids, mut ref_maps) = (0, 0, 0, 0, 0);
    let mut load_peak = 0u64;
    for m in materials {
        let texels = u64::from(m.map.size[0]) * u64::from(m.map.size[1]);
        let field = texels * u64::from(m.map.texel_bytes);
        load_peak = load_peak.max(fields + m.map.load_bytes + field);
        fields += field;
        gpu += texels * (GPU_BYTES_PER_TEXEL_BYTE * u64::from(m.map.texel_bytes) + 1);
        method_maps += m.maps.bytes(m.map.size);
        grids += m.dig_block.map_or(0, |b| corner_grid_bytes(frame, b));
        if extras.reference {
            ref_maps += Reference::memory_bytes(m.map.size[0], m.map.size[1]);
        }
    }
    // The meshes (`extras.mesh`: their sizes summed) are read beside the maps, the
    // albedo and normal maps after them.
    let load_peak = (load_peak + extras.mesh.load_bytes())
        .max(fields + extras.mesh.load_bytes() + extras.images.held + extras.images.load);
    let mesh_render = extras.mesh.render_bytes();
    let images = extras.images.render_bytes();
    let curved = extras.curved.render_bytes(frame);
    let render_peak = fields
        + gpu
        + method_maps
        + grids
        + frame_bytes
        + ref_maps
        + ref_frame
        + mesh_render
        + images
        + curved;
    let mut parts = vec![("process", BASE_BYTES)];
    parts.push(("height fields", fields));
    if mesh_render > 0 {
        parts.push(("meshes", mesh_render));
    }
    parts.push(("GPU copies of the maps", gpu));
    if images > 0 {
        parts.push(("albedo and normal maps", images));
    }
    if method_maps > 0 {
        parts.push(("pyramids and cone maps", method_maps));
    }
    if grids > 0 {
        parts.push(("DIG corner grids", grids));
    }
    parts.push(("frame", frame_bytes));
    if curved > 0 {
        parts.push(("curve images and mesh walk (--curved)", curved));
    }
    if extras.reference {
        parts.push(("reference texels and pyramids", ref_maps));
        parts.push(("reference rays and hits", ref_frame));
    }
    Estimate {
        bytes: BASE_BYTES + load_peak.max(render_peak),
        parts,
    }
}

/// Bytes as GiB or MiB with one decimal.
pub fn human(bytes: u64) -> String {
    if bytes >= 1 << 30 {
        format!("{:.1} GiB", bytes as f64 / f64::from(1u32 << 30))
    } else {
        format!("{:.1} MiB", bytes as f64 / f64::from(1u32 << 20))
    }
}

/// The memory this process may still take: `MemAvailable` of /proc/meminfo, lowered to
/// the cgroup's limit less its usage where one is set (cgroup v2); `None` where neither
/// can be read.
pub fn available() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find_map(|l| l.strip_prefix("MemAvailable:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
                .map(|kib| kib * 1024)
        });
    let read = |name: &str| {
        std::fs::read_to_string(format!("/sys/fs/cgroup/{name}"))
            .ok()
            .and_then(|t| t.trim().parse::<u64>().ok())
    };
    let cgroup = match (read("memory.max"), read("memory.current")) {
        (Some(max), Some(current)) => Some(max.saturating_sub(current)),
        _ => None,
    };
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Parses a memory size: bytes, or a number with `K`, `M`, `G` or `T` (powers of 1024;
/// an optional `iB`/`B` after it), e.g. `8G`, `512MiB`, `1.5G`.
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let lower = t.to_ascii_lowercase();
    let number = lower.trim_end_matches("ib").trim_end_matches('b');
    let (digits, shift) = match number.chars().last() {
        Some('k') => (&number[..number.len() - 1], 10),
        Some('m') => (&number[..number.len() - 1], 20),
        Some('g') => (&number[..number.len() - 1], 30),
        Some('t') => (&number[..number.len() - 1], 40),
        _ => (number, 0),
    };
    let value: f64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a memory size (e.g. 8G, 512M, 1073741824)"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes > u64::MAX as f64 {
        return Err(format!("'{s}' is not a positive memory size"));
    }
    Ok(bytes as u64)
}

/// Refuses `estimate` when it is above `max` (from `option`, e.g. `--max-memory`) or,
/// without one, above the memory available; the message gives the estimate, its parts
/// and the limit. `what` names the run (the map and frame).
pub fn check(estimate: &Estimate, max: Option<u64>, what: &str) -> Result<()> {
    let (limit, source) = match max {
        Some(m) => (m, "--max-memory".to_owned()),
        None => match available() {
            Some(a) => (
                a,
                "available memory (MemAvailable, cgroup limit)".to_owned(),
            ),
            None => return Ok(()),
        },
    };
    if estimate.bytes <= limit {
        return Ok(());
    }
    let parts: Vec<String> = estimate
        .parts
        .iter()
        .map(|(name, b)| format!("{name} {}", human(*b)))
        .collect();
    Err(Error::invalid(
        "memory",
        format!(
            "{what} needs about {} ({}), more than the {} of {source}; use a smaller map{} \
             or frame{}",
            human(estimate.bytes),
            parts.join(", "),
            human(limit),
            if estimate.parts.iter().any(|(n, _)| n.starts_with("mesh")) {
                ", mesh"
            } else {
                ""
            },
            if max.is_some() {
                " or raise --max-memory"
            } else {
                " or pass --max-memory to override"
            }
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dispmap::mesh::Mesh;

    #[test]
    fn materials_share_one_set_of_frame_images() {
        let map = MapSize {
            size: [1024, 1024],
            texel_bytes: 1,
            load_bytes: 0,
        };
        let one = MaterialMemory {
            map,
            maps: MethodMaps::of(Method::Exact, false),
            dig_block: None,
        };
        let frame = [640, 360];
        let extras = Extras {
            reference: true,
            ..Extras::default()
        };
        let single = estimate(
            map,
            frame,
            Extras {
                maps: one.maps,
                ..extras
            },
        );
        let a = estimate_objects(&[one], frame, extras);
        let b = estimate_objects(&[one, one, one], frame, extras);
        // One material: the single-object estimate.
        assert_eq!(a.bytes, single.bytes);
        // Two more materials add their maps only, not the frame, its tile lists (sized by
        // the frame alone) or the reference rays.
        let per_material = a.bytes
            - BASE_BYTES
            - tile_list_bytes(frame)
            - u64::from(frame[0])
                * u64::from(frame[1])
                * (FRAME_BYTES_PER_PIXEL + REFERENCE_BYTES_PER_PIXEL);
        assert_eq!(b.bytes - a.bytes, 2 * per_material);
        let dig = MaterialMemory {
            dig_block: Some([4, 4]),
            ..one
        };
        let c = estimate_objects(&[one, dig], frame, extras);
        assert_eq!(
            c.bytes - estimate_objects(&[one, one], frame, extras).bytes,
            161 * 91 * 16
        );
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_bytes("8G"), Ok(8 << 30));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5g"), Ok(3 << 29));
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert!(parse_bytes("-1G").is_err());
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("0").is_err());
    }

    #[test]
    fn estimate_grows_with_map_frame_and_reference_and_is_refused_above_the_limit() {
        let map = MapSize {
            size: [16384, 16384],
            texel_bytes: 1,
            load_bytes: 0,
        };
        let plain = Extras::default();
        let with_reference = Extras {
            reference: true,
            ..plain
        };
        let small = estimate(map, [256, 144], plain);
        let metrics = estimate(map, [256, 144], with_reference);
        let frame = estimate(map, [16384, 16384], plain);
        assert!(small.bytes < metrics.bytes && small.bytes < frame.bytes);
        // The reference's texels and pyramid in f32: 4 (1 + 4/3) bytes per texel.
        let r = Reference::memory_bytes(16384, 16384);
        assert!(r > 9 * (16384 * 16384) && r < 10 * (16384 * 16384), "{r}");
        let err = check(&frame, Some(1 << 30), "the 16384x16384 frame")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("16384x16384") && err.contains("GiB") && err.contains("--max-memory"),
            "{err}"
        );
        assert!(check(&small, Some(u64::MAX), "x").is_ok());
    }

    /// Curved tracing adds the two layers' curve images and, for a material that walks
    /// a mesh, its triangles' walk buffer and a walk list per frame slot; nothing for a
    /// method that does not walk or a geometry with nothing to walk.
    #[test]
    fn curved_tracing_adds_the_curve_images_and_the_mesh_walk() {
        use dispmap::scene::Geometry;
        let frame = [640, 360];
        let pixels = 640 * 360;
        let loaded = MeshSize {
            file_bytes: 1 << 20,
            vertices: 10_000,
            triangles: 20_000,
        };
        let walked = Curved::object_triangles(true, Geometry::Mesh, Some(Method::Exact), &loaded);
        assert_eq!(walked, 20_000);
        let sphere = Curved::object_triangles(true, Geometry::Sphere, Some(Method::Exact), &loaded);
        assert_eq!(sphere, (Mesh::sphere().indices.len() / 3) as u64);
        for (curved, geometry, method) in [
            (false, Geometry::Mesh, Some(Method::Exact)),
            (true, Geometry::Mesh, Some(Method::Relief)),
            (true, Geometry::Mesh, None),
            (true, Geometry::Quad, Some(Method::Exact)),
            (true, Geometry::TiledPlane, Some(Method::Exact)),
        ] {
            assert_eq!(
                Curved::object_triangles(curved, geometry, method, &loaded),
                0,
                "{curved} {geometry:?} {method:?}"
            );
        }
        let list = dispmap::passes::trace::walk_list_bytes(ash::vk::Extent2D {
            width: 640,
            height: 360,
        });
        let on = Curved {
            on: true,
            walked_triangles: walked,
        };
        assert_eq!(
            on.render_bytes(frame),
            8 * pixels + 20_000 * WALK_BYTES_PER_TRIANGLE + 2 * list
        );
        assert_eq!(
            Curved {
                on: true,
                walked_triangles: 0
            }
            .render_bytes(frame),
            8 * pixels
        );
        assert_eq!(Curved::default().render_bytes(frame), 0);
        let map = MapSize {
            size: [1024, 1024],
            texel_bytes: 1,
            load_bytes: 0,
        };
        let plain = Extras {
            mesh: loaded,
            ..Extras::default()
        };
        let base = estimate(map, frame, plain);
        let curved = estimate(
            map,
            frame,
            Extras {
                curved: on,
                ..plain
            },
        );
        assert_eq!(curved.bytes - base.bytes, on.render_bytes(frame));
        assert!(
            curved
                .parts
                .iter()
                .any(|(name, _)| name.contains("mesh walk")),
            "{:?}",
            curved.parts
        );
    }

    #[test]
    fn method_maps_follow_what_the_method_builds() {
        let size = [2048, 2048];
        let pyramid = MethodMaps::of(Method::Exact, false).bytes(size);
        // 2 bytes per node of the padded chain: 2 (4^12 - 1) / 3.
        assert_eq!(pyramid, 2 * ((1u64 << 24) - 1) / 3);
        assert_eq!(MethodMaps::of(Method::Relief, false).bytes(size), 0);
        assert_eq!(MethodMaps::of(Method::Relief, true).bytes(size), pyramid);
        assert_eq!(MethodMaps::of(Method::Exact, true).bytes(size), pyramid);
        let full = 4 * ((1u64 << 24) - 1) / 3;
        assert_eq!(MethodMaps::of(Method::Pyramid, false).bytes(size), full);
        assert_eq!(
            MethodMaps::of(Method::Pyramid, true).bytes(size),
            full + pyramid
        );
        let cone = MethodMaps::of(Method::Cone, false).bytes(size);
        assert_eq!(cone, pyramid + 8 * 2048 * 2048);
        let relaxed = MethodMaps::of(Method::RelaxedCone, false).bytes(size);
        assert_eq!(relaxed, cone + 4 * full);
        // A 1025-wide map pads its pyramid to 2048.
        // The padded chain: 2048 + 1024 + .. + 1 nodes.
        assert_eq!(
            MethodMaps::of(Method::Exact, false).bytes([1025, 1]),
            2 * 4095
        );
        assert_eq!(
            MethodMaps::together(&[Method::Exact, Method::ConeExact, Method::Pom]),
            MethodMaps {
                pyramids: 2,
                footprint_pyramids: 0,
                cone_maps: 1,
                relaxed_builds: 0
            }
        );
        let map = MapSize {
            size,
            texel_bytes: 1,
            load_bytes: 0,
        };
        let with = |maps| Extras {
            maps,
            ..Extras::default()
        };
        let plain = estimate(map, [64, 64], with(MethodMaps::default()));
        let r = estimate(
            map,
            [64, 64],
            with(MethodMaps::of(Method::RelaxedCone, false)),
        );
        assert_eq!(r.bytes - plain.bytes, relaxed);
        assert!(
            r.parts
                .iter()
                .any(|(name, _)| *name == "pyramids and cone maps")
        );
    }
}
