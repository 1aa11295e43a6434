//! The passes of a frame, one file each: `gbuffer` (graphics), `pyramid` (the min-reduce
//! chain), `dig` (the DIG corner pass), `trace` (the method), `shadow` (optional
//! self-shadowing) and `shade`; the `forward` pass (graphics: the G-buffer with relief
//! mapping or POM in its fragment shader, as engines do; the benchmark's yardstick); on
//! request `hit_depth` (the corrected depth of the displaced surface), `motion` (the
//! motion vectors of displaced pixels) and `depth_resolve` (graphics: that depth into a depth
//! attachment). Every pass only records into a command buffer it is given; the one
//! orchestrator, [`crate::embed::DisplacementPass`], declares each stage's accesses (its
//! shaders' reflected bindings) to its frame graph, whose [`crate::gpu::track::Tracker`]
//! places the barriers between the compute passes, and its host (an engine, or
//! [`crate::renderer::Renderer`]) the G-buffer's and the entry barriers.

pub mod background;
pub mod behind_mask;
pub(crate) mod behind_open;
pub(crate) mod behind_tiles;
pub mod camera_motion;
pub mod classify;
pub mod cone;
pub mod depth_resolve;
pub mod dig;
pub mod forward;
pub mod gbuffer;
pub mod height_range;
pub mod hit_depth;
pub mod hit_resolve;
pub mod motion;
pub mod pixel_ray_buffer;
pub mod prepare;
pub mod pyramid;
pub mod shade;
pub mod shadow;
pub mod trace;

/// Every map preparation ([`prepare::MapPreparation`]), in recording order (after the
/// uploads, pyramids and cone maps): the displacement pass's table keys its entries by
/// (map, index here) and builds those a host asked for.
pub static MAP_PREPARATIONS: &[&dyn prepare::Kind] =
    &[&prepare::KindOf::<height_range::HeightRange>::NEW];

/// The passes of a frame, in recording order; what timestamps and debug labels name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PassName {
    /// The G-buffer raster pass (the standalone renderer's; a host records its own).
    GBuffer,
    /// Copies of staged data: a new height map (and its mip chain) or material maps, or
    /// the height texture refilled when level of detail is switched. One-off.
    Upload,
    /// The min-reduce chain of the pyramid methods (and of hard shadows' cell pyramid).
    /// One-off: built once per height map.
    Pyramid,
    /// The cone map of the cone-stepping methods (built from the pyramid). One-off:
    /// built once per height map.
    Cone,
    /// A map's lowest and highest height ([`height_range`], a map preparation a host asks
    /// for). One-off: built once per height map.
    HeightRange,
    /// The classification of the frame's tiles by material (every frame).
    Classify,
    /// The DIG corner pass.
    DigCorners,
    /// The intersection method, writing the hit images.
    Trace,
    /// Self-shadowing: the light visibility of each hit.
    Shadow,
    /// Lighting of the hits into the colour image.
    Shade,
    /// The corrected depth of the displaced surface.
    HitDepth,
    /// The motion vectors of the displaced pixels.
    Motion,
    /// The standalone renderer's behind layer, in one figure: its G-buffer raster, the
    /// light of its flat geometry and the displacement pass recorded on it (a host
    /// times its own).
    Behind,
}

impl PassName {
    /// Every pass, in recording order.
    pub const ALL: [PassName; 13] = [
        PassName::GBuffer,
        PassName::Upload,
        PassName::Pyramid,
        PassName::Cone,
        PassName::HeightRange,
        PassName::Classify,
        PassName::DigCorners,
        PassName::Trace,
        PassName::Shadow,
        PassName::Shade,
        PassName::HitDepth,
        PassName::Motion,
        PassName::Behind,
    ];

    /// The name in reports, metrics files and debug labels (`gbuffer`, `upload`,
    /// `pyramid`, `cone`, `height_range`, `classify`, `dig_corners`, `trace`, `shadow`, `shade`, `hit_depth`,
    /// `motion`, `behind`).
    pub fn as_str(self) -> &'static str {
        match self {
            PassName::GBuffer => "gbuffer",
            PassName::Upload => "upload",
            PassName::Pyramid => "pyramid",
            PassName::Cone => "cone",
            PassName::HeightRange => "height_range",
            PassName::Classify => "classify",
            PassName::DigCorners => "dig_corners",
            PassName::Trace => "trace",
            PassName::Shadow => "shadow",
            PassName::Shade => "shade",
            PassName::HitDepth => "hit_depth",
            PassName::Motion => "motion",
            PassName::Behind => "behind",
        }
    }

    /// How many passes of [`PassName::ALL`] the displacement pass records (every one but
    /// the host's G-buffer pass and the renderer's behind layer): its timestamp queries are
    /// twice that.
    pub const fn recorded_by_pass() -> u32 {
        let mut n = 0;
        let mut i = 0;
        while i < PassName::ALL.len() {
            if !matches!(PassName::ALL[i], PassName::GBuffer | PassName::Behind) {
                n += 1;
            }
            i += 1;
        }
        n
    }

    /// Whether the pass runs once after a change (a new map or method) rather than
    /// every frame: such times are reported apart from the per-frame total.
    pub fn is_one_off(self) -> bool {
        matches!(
            self,
            PassName::Upload | PassName::Pyramid | PassName::Cone | PassName::HeightRange
        )
    }
}

impl std::fmt::Display for PassName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
