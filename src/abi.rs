//! `#[repr(C)]` mirrors of the structs shared with GLSL (push-constant blocks).
//!
//! Each struct's layout is tested against the compiled SPIR-V itself: the tests read the
//! `Offset` decorations of the block with the same name in the shader and compare them
//! with `offset_of!`, and the struct size with the block's end. No GPU needed.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec4};

/// `ADDRESSING_REPEAT` in `glsl/common/frame.glsl`.
pub const ADDRESSING_REPEAT: u32 = 0;
/// `ADDRESSING_CLAMP` in `glsl/common/frame.glsl`.
pub const ADDRESSING_CLAMP: u32 = 1;
/// `NO_HIT_HEIGHT` in `glsl/common/frame.glsl`: the hit height of a miss.
pub const NO_HIT_HEIGHT: f32 = -1.0;
/// `NOT_DISPLACED_HEIGHT` in `glsl/common/frame.glsl`: the hit height of a pixel of flat
/// geometry (G-buffer frame's material 0), written by the classification pass.
pub const NOT_DISPLACED_HEIGHT: f32 = -2.0;
/// `MAX_MATERIALS` in `glsl/common/tiles.glsl`: the materials a pass may hold (the
/// G-buffer frame's 11-bit material field holds `index + 1`).
pub const MAX_MATERIALS: u32 = 1024;

/// `TraceParams` in `glsl/common/trace.glsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TraceParams {
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Height-map size in texels.
    pub map_size: [u32; 2],
    /// Linear steps over the full depth.
    pub steps: u32,
    /// Binary-search steps after the linear march.
    pub refine_steps: u32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
    /// `TRACE_FLAG_*`.
    pub flags: u32,
    /// `pom`: `n_min`.
    pub min_steps: u32,
    /// `secant`: segments.
    pub segments: u32,
    /// `dig`: block size in pixels.
    pub block: [u32; 2],
    /// `dig`: corner-grid size (`ceil(frame / block) + 1`).
    pub corner_size: [u32; 2],
    /// `dig`: `eps1 = eps2`.
    pub eps: f32,
    /// `pyramid`: the coarsest traversal level (with `TRACE_FLAG_AUTO_LEVEL`: a bias).
    pub max_level: u32,
    /// Levels of the bound pyramid (0 without one; `Pyramid::shader_levels`: bit 16 set
    /// where level 0 is not stored).
    pub pyramid_levels: u32,
    /// Displacement depth in tile units (`pom`: `N . V` from the parallax vector).
    pub depth_scale: f32,
    /// With `TRACE_FLAG_LOD`: the footprint mip level from which a pixel takes the bump
    /// result without tracing (a one-level band below it blends toward bump).
    pub lod_threshold: f32,
    /// The material this dispatch traces (the index in the pass's table).
    pub material: u32,
    /// With `TRACE_FLAG_CURVED`: the pixel rays ([`crate::passes::trace::TraceView`]):
    /// the near-plane point at the frame's centre, eye-relative (w: 0).
    pub view_origin: [f32; 4],
    /// Its step per NDC unit along x (w: 0).
    pub view_dx: [f32; 4],
    /// Its step per NDC unit along y (w: 0).
    pub view_dy: [f32; 4],
}

/// `TRACE_FLAG_AUTO_LEVEL` in `glsl/common/trace.glsl`: the pyramid method derives its
/// coarsest level from each pixel's texel footprint.
pub const TRACE_FLAG_AUTO_LEVEL: u32 = 1;

/// `TRACE_FLAG_LOD` in `glsl/common/trace.glsl`: the level-of-detail blend to bump
/// mapping at `TraceParams::lod_threshold` (Tatarchuk 2006), for every method.
pub const TRACE_FLAG_LOD: u32 = 2;

/// `TRACE_FLAG_CURVED` in `glsl/common/trace.glsl`: curved macro geometry
/// (`glsl/common/curved.glsl`), for the methods that honour it
/// ([`crate::method::Method::traces_curved`]).
pub const TRACE_FLAG_CURVED: u32 = 4;

/// `ForwardParams` in `glsl/forward/forward.glsl`: the forward pass's step counts (a
/// uniform buffer, [`crate::passes::forward`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ForwardParams {
    /// Linear steps over the full depth (`pom`: `n_max`).
    pub steps: u32,
    /// `relief`: binary-search steps after the linear march.
    pub refine_steps: u32,
    /// `pom`: `n_min`.
    pub min_steps: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

/// `PyramidParams` in `glsl/pyramid.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PyramidParams {
    /// Logical size of the level below `level` (level 0: the map).
    pub src_size: [u32; 2],
    /// Logical size of level `level`.
    pub dst_size: [u32; 2],
    /// Logical size of level `level + 1`, written by the same dispatch; `[0, 0]` when the
    /// dispatch writes `level` alone.
    pub next_size: [u32; 2],
    /// The (first) level written.
    pub level: u32,
    /// `PYRAMID_KIND_*`.
    pub kind: u32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
    /// The `UNORM` variant's largest code (255 or 65535: `R8_UNORM` or `R16_UNORM`
    /// storage, codes of the map's own texels); 0 for the `R32_SFLOAT` chains.
    pub code_max: u32,
    /// Logical size of level `level + 2`, written by the same dispatch; `[0, 0]` when
    /// the dispatch writes fewer levels.
    pub next2_size: [u32; 2],
    /// 0 when level `level` is computed but not stored (the cell pyramid's level 0: the
    /// traversals read a cell's texels instead); 1 otherwise.
    pub store_dst: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

/// `ConeParams` in `glsl/cone.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ConeParams {
    /// The map's size in texels (= cells).
    pub map_size: [u32; 2],
    /// Levels of the cell pyramid (`Pyramid::shader_levels`: bit 16 set where level 0 is
    /// not stored).
    pub levels: u32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
}

/// `CornerParams` in `glsl/dig_corners.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CornerParams {
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Corner-grid size.
    pub corner_size: [u32; 2],
    /// Block size in pixels.
    pub block: [u32; 2],
    /// Linear steps over the full depth.
    pub steps: u32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
    /// The material whose grid this is.
    pub material: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

/// `ClassifyParams` in `glsl/classify.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ClassifyParams {
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Table entries (live or vacant).
    pub material_count: u32,
    /// The tile buffer's first entry word (after its header and tile summaries).
    pub entries_base: u32,
    /// `CLASSIFY_FLAG_*`.
    pub flags: u32,
    /// The frame's 8x8 tiles.
    pub tile_count: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

/// `GBufferParams` in `glsl/common/gbuffer.glsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GBufferParams {
    /// Eye-relative world to clip (reverse-Z, Vulkan y down): `view_proj *
    /// translation(eye)`, built without the translation ([`crate::scene::FrameCamera`]).
    /// The vertex stages transform positions relative to the eye, so a camera far from
    /// the origin keeps full precision near the eye.
    pub view_proj: Mat4,
    /// Eye position (xyz); `w`: the drawn object's material index + 1, or 0 for an
    /// object that is not displaced (an integer in f32: the block is at the 128 bytes
    /// every device allows). [`crate::scene::Scene::gbuffer_params`] gives 1 (material 0).
    pub camera_pos: Vec4,
    /// x0, z0, x1, z1 of the quad (or of the plane's grid) on the y = 0 plane.
    pub world_rect: Vec4,
    /// u0, v0, u1, v1 at the rectangle's corners.
    pub uv_rect: Vec4,
    /// Displacement depth in tile units.
    pub depth_scale: f32,
    /// Lower bound of `-V.z` (keeps the parallax vector finite at grazing angles).
    pub min_cos: f32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
    /// 0: `world_rect` is drawn as one quad (two triangles). `n > 0`: it is drawn as a
    /// grid of `2n x 2n` cells centred on the eye (clamped into the rectangle), growing
    /// geometrically from about the eye's height across to the rectangle's edge (see
    /// `glsl/gbuffer.vert`); [`GBufferParams::vertex_count`] gives the draw's size.
    pub plane_cells: u32,
}

impl GBufferParams {
    /// Vertices of the non-mesh draw: 6 per quad or grid cell.
    pub fn vertex_count(&self) -> u32 {
        let side = 2 * self.plane_cells;
        6 * side.max(1) * side.max(1)
    }
}

/// `DispmapPixelRay` in `glsl/include/dispmap_plane.glsl`: each pixel's centre ray of the
/// frame as f32 pairs `hi + lo` of the camera's f64 values, for the G-buffer's
/// `dispmap_plane_pixel_ray` (a uniform buffer, std140: [`GBufferParams`] already takes
/// the 128 bytes of push constants every device guarantees). Formed by
/// [`crate::pixel_rays::PixelRays::params`]; the direction of the ray through pixel
/// centre `(px, py)` is `dir + (px - W/2) step_x + (py - H/2) step_y`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct PixelRayParams {
    /// The eye (xyz, rounded to f32); `w`: `W / 2`.
    pub eye_hi: [f32; 4],
    /// The eye minus `eye_hi` (xyz); `w`: `H / 2`.
    pub eye_lo: [f32; 4],
    /// The unit view direction (xyz).
    pub dir_hi: [f32; 4],
    /// Its rounding error.
    pub dir_lo: [f32; 4],
    /// The direction's change per pixel along x (xyz).
    pub step_x_hi: [f32; 4],
    /// Its rounding error.
    pub step_x_lo: [f32; 4],
    /// The direction's change per pixel along y, downwards (xyz).
    pub step_y_hi: [f32; 4],
    /// Its rounding error.
    pub step_y_lo: [f32; 4],
}

/// `ShadeParams` in `glsl/shade.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadeParams {
    /// Clip to world.
    pub inv_view_proj: Mat4,
    /// Eye position (xyz); `w`: the material this dispatch shades (an integer in f32:
    /// the block is at the 128 bytes every device allows).
    pub camera_pos: Vec4,
    /// Unit vector towards the light (xyz) and intensity (w).
    pub light_dir: Vec4,
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Height-map size in texels.
    pub map_size: [u32; 2],
    /// Displacement depth in tile units.
    pub depth_scale: f32,
    /// Ambient term.
    pub ambient: f32,
    /// Specular strength.
    pub specular: f32,
    /// Blinn-Phong exponent.
    pub shininess: f32,
}

impl ShadeParams {
    /// The shading of a frame seen through `view_proj` from `eye`, lit by a directional
    /// light towards `light_dir` (unit, world space) of `light_intensity`; the material
    /// constants (ambient 0.18, specular 0.25, shininess 48) are dispmap's one stone
    /// material. The one place these values are formed.
    pub fn new(
        view_proj: Mat4,
        eye: glam::Vec3,
        light_dir: glam::Vec3,
        light_intensity: f32,
        frame_size: [u32; 2],
        map_size: [u32; 2],
        depth_scale: f32,
    ) -> Self {
        ShadeParams {
            inv_view_proj: view_proj.inverse(),
            camera_pos: eye.extend(1.0),
            light_dir: light_dir.extend(light_intensity),
            frame_size,
            map_size,
            depth_scale,
            ambient: 0.18,
            specular: 0.25,
            shininess: 48.0,
        }
    }
}

/// `HitDepthParams` in `glsl/hit_depth.comp` (built by `HitDepthParams::new` in
/// `src/passes/hit_depth.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct HitDepthParams {
    /// Clip to eye-relative world (`inverse(view_proj * translation(eye))`): unprojects
    /// the G-buffer depth to the entry point's offset from the eye.
    pub inv_eye_clip: Mat4,
    /// Row 2 of `view_proj * translation(eye)`: the clip-space `z` of an eye offset.
    pub clip_z_row: Vec4,
    /// Row 3 of `view_proj * translation(eye)`: the clip-space `w` of an eye offset.
    pub clip_w_row: Vec4,
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Displacement depth in tile units.
    pub depth_scale: f32,
    /// The material this dispatch resolves.
    pub material: u32,
}

/// `MotionParams` in `glsl/motion.comp` (built by `MotionParams::new` in
/// `src/passes/motion.rs`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MotionParams {
    /// Clip to eye-relative world of the current frame (`inverse(view_proj *
    /// translation(eye))`): unprojects the G-buffer depth to the entry point.
    pub inv_eye_clip: Mat4,
    /// Row 0 of `previous view_proj * translation(eye)`: the previous frame's clip `x` of
    /// an offset from the current eye.
    pub prev_x_row: Vec4,
    /// Row 1 of the same matrix (clip `y`).
    pub prev_y_row: Vec4,
    /// Row 3 of the same matrix (clip `w`).
    pub prev_w_row: Vec4,
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Displacement depth in tile units.
    pub depth_scale: f32,
    /// Bits 0-15: the material this dispatch resolves; bits 16-31: the motion flags.
    pub material: u32,
}

/// `ShadowParams` in `glsl/shadow.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ShadowParams {
    /// World-space unit vector towards the light (xyz); w unused.
    pub light_dir: Vec4,
    /// Frame size in pixels.
    pub frame_size: [u32; 2],
    /// Height-map size in texels.
    pub map_size: [u32; 2],
    /// Displacement depth in tile units.
    pub depth_scale: f32,
    /// The light ray starts this far (heights) above the hit.
    pub bias: f32,
    /// Lower bound of the light's tangent-space `z` when forming its climb.
    pub min_cos: f32,
    /// `ADDRESSING_*`.
    pub addressing: u32,
    /// `SHADOW_MODE_*`.
    pub mode: u32,
    /// Hard shadows of the marching methods: steps over the full depth.
    pub steps: u32,
    /// Soft shadows: light samples.
    pub samples: u32,
    /// Levels of the bound pyramid (0 without one; `Pyramid::shader_levels`: bit 16 set
    /// where level 0 is not stored).
    pub pyramid_levels: u32,
    /// The material this dispatch shadows.
    pub material: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

/// `SHADOW_MODE_HARD` in `glsl/shadow.comp`.
pub const SHADOW_MODE_HARD: u32 = 1;
/// `SHADOW_MODE_SOFT` in `glsl/shadow.comp`.
pub const SHADOW_MODE_SOFT: u32 = 2;

#[cfg(test)]
pub(crate) mod spirv_layout {
    //! Minimal SPIR-V reader: member offsets of a named block.
    use std::collections::HashMap;

    const OP_NAME: u32 = 5;
    const OP_MEMBER_NAME: u32 = 6;
    const OP_MEMBER_DECORATE: u32 = 72;
    const DECORATION_OFFSET: u32 = 35;

    fn string(words: &[u32]) -> String {
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
        String::from_utf8_lossy(&bytes[..end]).into_owned()
    }

    /// `(member name, offset)` of the struct type named `block`, in member order.
    pub fn block_offsets(words: &[u32], block: &str) -> Vec<(String, u32)> {
        let mut type_id = None;
        let mut names: HashMap<u32, String> = HashMap::new();
        let mut offsets: HashMap<u32, u32> = HashMap::new();
        let mut member_names: Vec<(u32, u32, String)> = Vec::new();
        let mut member_offsets: Vec<(u32, u32, u32)> = Vec::new();
        let mut i = 5; // header
        while i < words.len() {
            let op = words[i] & 0xffff;
            let count = (words[i] >> 16) as usize;
            let operands = &words[i + 1..i + count.max(1)];
            match op {
                OP_NAME => {
                    names.insert(operands[0], string(&operands[1..]));
                }
                OP_MEMBER_NAME => {
                    member_names.push((operands[0], operands[1], string(&operands[2..])));
                }
                OP_MEMBER_DECORATE if operands[2] == DECORATION_OFFSET => {
                    member_offsets.push((operands[0], operands[1], operands[3]));
                }
                _ => {}
            }
            i += count.max(1);
        }
        // A struct used both in a block and as a function's value has two types of that
        // name: the block's carries the Offset decorations.
        for (id, name) in &names {
            if name == block
                && (type_id.is_none() || member_offsets.iter().any(|(t, _, _)| t == id))
            {
                type_id = Some(*id);
            }
        }
        let id = type_id.unwrap_or_else(|| panic!("block {block} not in the SPIR-V"));
        for (t, m, off) in member_offsets {
            if t == id {
                offsets.insert(m, off);
            }
        }
        let mut members: Vec<_> = member_names
            .into_iter()
            .filter(|(t, _, _)| *t == id)
            .map(|(_, m, n)| (m, n))
            .collect();
        members.sort();
        members
            .into_iter()
            .map(|(m, n)| {
                let off = *offsets.get(&m).expect("member without Offset");
                (n, off)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::spirv_layout::block_offsets;
    use super::*;
    use crate::shaders;
    use std::mem::{offset_of, size_of};

    /// Checks Rust offsets against the shader's, member by member, and the total size.
    fn check(shader: &shaders::Shader, block: &str, rust: &[(&str, usize)], size: usize) {
        let words = shader.words().unwrap();
        let glsl = block_offsets(&words, block);
        let glsl_names: Vec<&str> = glsl.iter().map(|(n, _)| n.as_str()).collect();
        let rust_names: Vec<&str> = rust.iter().map(|(n, _)| *n).collect();
        assert_eq!(glsl_names, rust_names, "{block}: member names/order differ");
        for ((name, off), (_, rust_off)) in glsl.iter().zip(rust) {
            assert_eq!(*off as usize, *rust_off, "{block}.{name} offset");
        }
        assert_eq!(
            size % 16,
            0,
            "{block}: push-constant size should be 16-byte aligned"
        );
        assert!(
            size <= 128,
            "{block}: over the guaranteed push-constant size"
        );
    }

    #[test]
    fn trace_params_layout() {
        check(
            &shaders::TRACE_RELIEF_COMP,
            "TraceParams",
            &[
                ("frame_size", offset_of!(TraceParams, frame_size)),
                ("map_size", offset_of!(TraceParams, map_size)),
                ("steps", offset_of!(TraceParams, steps)),
                ("refine_steps", offset_of!(TraceParams, refine_steps)),
                ("addressing", offset_of!(TraceParams, addressing)),
                ("flags", offset_of!(TraceParams, flags)),
                ("min_steps", offset_of!(TraceParams, min_steps)),
                ("segments", offset_of!(TraceParams, segments)),
                ("block", offset_of!(TraceParams, block)),
                ("corner_size", offset_of!(TraceParams, corner_size)),
                ("eps", offset_of!(TraceParams, eps)),
                ("max_level", offset_of!(TraceParams, max_level)),
                ("pyramid_levels", offset_of!(TraceParams, pyramid_levels)),
                ("depth_scale", offset_of!(TraceParams, depth_scale)),
                ("lod_threshold", offset_of!(TraceParams, lod_threshold)),
                ("material", offset_of!(TraceParams, material)),
                ("view_origin", offset_of!(TraceParams, view_origin)),
                ("view_dx", offset_of!(TraceParams, view_dx)),
                ("view_dy", offset_of!(TraceParams, view_dy)),
            ],
            size_of::<TraceParams>(),
        );
        assert_eq!(size_of::<TraceParams>(), 128);
    }

    #[test]
    fn forward_params_layout() {
        for shader in [&shaders::FORWARD_RELIEF_FRAG, &shaders::FORWARD_POM_FRAG] {
            check(
                shader,
                "ForwardParams",
                &[
                    ("steps", offset_of!(ForwardParams, steps)),
                    ("refine_steps", offset_of!(ForwardParams, refine_steps)),
                    ("min_steps", offset_of!(ForwardParams, min_steps)),
                    ("pad", offset_of!(ForwardParams, pad)),
                ],
                size_of::<ForwardParams>(),
            );
            // The fragment stage reads the G-buffer's push constants as its vertex stage
            // does.
            assert_eq!(
                block_offsets(&shader.words().unwrap(), "GBufferParams"),
                block_offsets(&shaders::GBUFFER_VERT.words().unwrap(), "GBufferParams"),
                "{}",
                shader.name
            );
        }
    }

    #[test]
    fn pyramid_params_layout() {
        for shader in [&shaders::PYRAMID_COMP, &shaders::PYRAMID_COMP_UNORM] {
            check(
                shader,
                "PyramidParams",
                &[
                    ("src_size", offset_of!(PyramidParams, src_size)),
                    ("dst_size", offset_of!(PyramidParams, dst_size)),
                    ("next_size", offset_of!(PyramidParams, next_size)),
                    ("level", offset_of!(PyramidParams, level)),
                    ("kind", offset_of!(PyramidParams, kind)),
                    ("addressing", offset_of!(PyramidParams, addressing)),
                    ("code_max", offset_of!(PyramidParams, code_max)),
                    ("next2_size", offset_of!(PyramidParams, next2_size)),
                    ("store_dst", offset_of!(PyramidParams, store_dst)),
                    ("pad", offset_of!(PyramidParams, pad)),
                ],
                size_of::<PyramidParams>(),
            );
        }
    }

    #[test]
    fn cone_params_layout() {
        check(
            &shaders::CONE_COMP,
            "ConeParams",
            &[
                ("map_size", offset_of!(ConeParams, map_size)),
                ("levels", offset_of!(ConeParams, levels)),
                ("addressing", offset_of!(ConeParams, addressing)),
            ],
            size_of::<ConeParams>(),
        );
    }

    #[test]
    fn corner_params_layout() {
        check(
            &shaders::DIG_CORNERS_COMP,
            "CornerParams",
            &[
                ("frame_size", offset_of!(CornerParams, frame_size)),
                ("corner_size", offset_of!(CornerParams, corner_size)),
                ("block", offset_of!(CornerParams, block)),
                ("steps", offset_of!(CornerParams, steps)),
                ("addressing", offset_of!(CornerParams, addressing)),
                ("material", offset_of!(CornerParams, material)),
                ("pad0", offset_of!(CornerParams, pad)),
                ("pad1", offset_of!(CornerParams, pad) + 4),
                ("pad2", offset_of!(CornerParams, pad) + 8),
            ],
            size_of::<CornerParams>(),
        );
    }

    #[test]
    fn gbuffer_params_layout() {
        check(
            &shaders::GBUFFER_VERT,
            "GBufferParams",
            &[
                ("view_proj", offset_of!(GBufferParams, view_proj)),
                ("camera_pos", offset_of!(GBufferParams, camera_pos)),
                ("world_rect", offset_of!(GBufferParams, world_rect)),
                ("uv_rect", offset_of!(GBufferParams, uv_rect)),
                ("depth_scale", offset_of!(GBufferParams, depth_scale)),
                ("min_cos", offset_of!(GBufferParams, min_cos)),
                ("addressing", offset_of!(GBufferParams, addressing)),
                ("plane_cells", offset_of!(GBufferParams, plane_cells)),
            ],
            size_of::<GBufferParams>(),
        );
        assert_eq!(size_of::<GBufferParams>(), 128);
    }

    #[test]
    fn pixel_ray_params_layout() {
        for shader in [&shaders::GBUFFER_FRAG, &shaders::FORWARD_RELIEF_FRAG] {
            check(
                shader,
                "DispmapPixelRay",
                &[
                    ("eye_hi", offset_of!(PixelRayParams, eye_hi)),
                    ("eye_lo", offset_of!(PixelRayParams, eye_lo)),
                    ("dir_hi", offset_of!(PixelRayParams, dir_hi)),
                    ("dir_lo", offset_of!(PixelRayParams, dir_lo)),
                    ("step_x_hi", offset_of!(PixelRayParams, step_x_hi)),
                    ("step_x_lo", offset_of!(PixelRayParams, step_x_lo)),
                    ("step_y_hi", offset_of!(PixelRayParams, step_y_hi)),
                    ("step_y_lo", offset_of!(PixelRayParams, step_y_lo)),
                ],
                size_of::<PixelRayParams>(),
            );
        }
        assert_eq!(size_of::<PixelRayParams>(), 128);
    }

    #[test]
    fn shade_params_layout() {
        check(
            &shaders::SHADE_COMP,
            "ShadeParams",
            &[
                ("inv_view_proj", offset_of!(ShadeParams, inv_view_proj)),
                ("camera_pos", offset_of!(ShadeParams, camera_pos)),
                ("light_dir", offset_of!(ShadeParams, light_dir)),
                ("frame_size", offset_of!(ShadeParams, frame_size)),
                ("map_size", offset_of!(ShadeParams, map_size)),
                ("depth_scale", offset_of!(ShadeParams, depth_scale)),
                ("ambient", offset_of!(ShadeParams, ambient)),
                ("specular", offset_of!(ShadeParams, specular)),
                ("shininess", offset_of!(ShadeParams, shininess)),
            ],
            size_of::<ShadeParams>(),
        );
        assert_eq!(size_of::<ShadeParams>(), 128);
    }

    #[test]
    fn hit_depth_params_layout() {
        check(
            &shaders::HIT_DEPTH_COMP,
            "HitDepthParams",
            &[
                ("inv_eye_clip", offset_of!(HitDepthParams, inv_eye_clip)),
                ("clip_z_row", offset_of!(HitDepthParams, clip_z_row)),
                ("clip_w_row", offset_of!(HitDepthParams, clip_w_row)),
                ("frame_size", offset_of!(HitDepthParams, frame_size)),
                ("depth_scale", offset_of!(HitDepthParams, depth_scale)),
                ("material", offset_of!(HitDepthParams, material)),
            ],
            size_of::<HitDepthParams>(),
        );
        assert_eq!(size_of::<HitDepthParams>(), 112);
    }

    #[test]
    fn motion_params_layout() {
        for shader in [&shaders::MOTION_COMP, &shaders::MOTION_COMP_WIDE] {
            check(
                shader,
                "MotionParams",
                &[
                    ("inv_eye_clip", offset_of!(MotionParams, inv_eye_clip)),
                    ("prev_x_row", offset_of!(MotionParams, prev_x_row)),
                    ("prev_y_row", offset_of!(MotionParams, prev_y_row)),
                    ("prev_w_row", offset_of!(MotionParams, prev_w_row)),
                    ("frame_size", offset_of!(MotionParams, frame_size)),
                    ("depth_scale", offset_of!(MotionParams, depth_scale)),
                    ("material", offset_of!(MotionParams, material)),
                ],
                size_of::<MotionParams>(),
            );
        }
        assert_eq!(size_of::<MotionParams>(), 128);
    }

    #[test]
    fn shadow_params_layout() {
        for shader in [&shaders::SHADOW_COMP, &shaders::SHADOW_COMP_PYRAMID] {
            check(
                shader,
                "ShadowParams",
                &[
                    ("light_dir", offset_of!(ShadowParams, light_dir)),
                    ("frame_size", offset_of!(ShadowParams, frame_size)),
                    ("map_size", offset_of!(ShadowParams, map_size)),
                    ("depth_scale", offset_of!(ShadowParams, depth_scale)),
                    ("bias", offset_of!(ShadowParams, bias)),
                    ("min_cos", offset_of!(ShadowParams, min_cos)),
                    ("addressing", offset_of!(ShadowParams, addressing)),
                    ("mode", offset_of!(ShadowParams, mode)),
                    ("steps", offset_of!(ShadowParams, steps)),
                    ("samples", offset_of!(ShadowParams, samples)),
                    ("pyramid_levels", offset_of!(ShadowParams, pyramid_levels)),
                    ("material", offset_of!(ShadowParams, material)),
                    ("pad0", offset_of!(ShadowParams, pad)),
                    ("pad1", offset_of!(ShadowParams, pad) + 4),
                    ("pad2", offset_of!(ShadowParams, pad) + 8),
                ],
                size_of::<ShadowParams>(),
            );
        }
        assert_eq!(size_of::<ShadowParams>(), 80);
    }

    #[test]
    fn classify_params_layout() {
        for shader in [
            &shaders::CLASSIFY_COMP,
            &shaders::CLASSIFY_COMP_DEPTH,
            &shaders::CLASSIFY_OFFSETS_COMP,
            &shaders::CLASSIFY_SCATTER_COMP,
            &shaders::CLASSIFY_MIXED_COMP,
        ] {
            check(
                shader,
                "ClassifyParams",
                &[
                    ("frame_size", offset_of!(ClassifyParams, frame_size)),
                    ("material_count", offset_of!(ClassifyParams, material_count)),
                    ("entries_base", offset_of!(ClassifyParams, entries_base)),
                    ("flags", offset_of!(ClassifyParams, flags)),
                    ("tile_count", offset_of!(ClassifyParams, tile_count)),
                    ("pad0", offset_of!(ClassifyParams, pad)),
                    ("pad1", offset_of!(ClassifyParams, pad) + 4),
                ],
                size_of::<ClassifyParams>(),
            );
        }
    }

    #[test]
    fn shadowed_shade_shares_the_block() {
        let plain = block_offsets(&shaders::SHADE_COMP.words().unwrap(), "ShadeParams");
        let shadowed = block_offsets(&shaders::SHADE_COMP_SHADOWS.words().unwrap(), "ShadeParams");
        assert_eq!(plain, shadowed);
    }

    #[test]
    fn every_trace_method_shares_the_block() {
        for s in shaders::ALL.iter().filter(|s| s.name.starts_with("trace/")) {
            let words = s.words().unwrap();
            let offs = block_offsets(&words, "TraceParams");
            assert_eq!(offs.len(), 19, "{}", s.name);
        }
    }
}
