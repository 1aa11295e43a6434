//! The `shadow` pass: self-shadowing of the displaced surface after Tatarchuk 2006,
//! section 3.2. It runs after `trace`, casts a ray from each pixel's hit towards the
//! directional light and writes the light's visibility (`R16_SFLOAT`, 1 = lit, 0 =
//! shadowed); the shadowed `shade` pass ([`ShadePass::shadowed`](crate::passes::shade::ShadePass::shadowed))
//! multiplies it into the direct (diffuse and specular) light, not the ambient term.
//!
//! `glsl/shadow.comp` documents the light ray in the height field's units: from the hit
//! `(uv, h)` it is `uv(h') = uv + (h' - h) C` for `h'` in `[h, 1]`, with the climb
//! `C = depth_scale * L_ts.xy / max(L_ts.z, min_cos)` (uv per unit height; one uv unit is
//! one tile, the depth of height `h` is `(1 - h) depth_scale` tiles) and
//! `L_ts = (L.T, L.B, L.N)` from the G-buffer frame's normal and tangent. Where the macro
//! surface faces away from the light (`L_ts.z <= 0`) the pixel is in shadow (0).
//!
//! # Modes ([`ShadowMode`])
//!
//! * `off` (the default): the pass, its image and the shadowed shade variant are not
//!   built at all.
//! * `hard`: 0 or 1. What answers "does the surface cross the light ray" follows the
//!   method's family ([`ShadowTrace::for_method`]):
//!   - `exact`, `dig-guarded`, `pyramid`: the **exact** traversal of the cell-max pyramid
//!     (`glsl/common/pyramid.glsl`, `pyramid_segment_hit`) on the light ray reversed into
//!     a view ray; the pixel is occluded when the bilinear surface reaches the light ray
//!     anywhere from `H(uv_hit) + SHADOW_BIAS` up to the macro surface (clamp addressing:
//!     inside the decal). The receiver is the surface point under the hit (`H` the exact
//!     bilinear surface), so an approximate hit a little under the surface (`pyramid`'s)
//!     does not shadow itself. This is `dispmap_cli::reference::Reference::occluded`
//!     in `f32`. `exact` and `dig-guarded` share their method's cell pyramid; the
//!     `pyramid` method's own pyramid bounds texel footprints, so the stage builds a cell
//!     pyramid of its own (once, timed with the method's as `pyramid`).
//!   - every other method (`linear`, `relief`, `pom`, `secant`, `dig`, `bump`): a linear
//!     march up the light ray with the method's step (`--steps`, `1/steps` of the full
//!     depth per sample), starting from Tatarchuk's reference height `H(uv_hit)` (a
//!     march's hit can lie up to a step under the surface). It samples the exact bilinear
//!     surface (4 `texelFetch` per sample) rather than the hardware filter, whose 8-bit
//!     weights cause shadow acne near the receiver; so it only ever misses shadows (thin
//!     occluders between samples), fewer with more steps.
//! * `soft`: Tatarchuk's penumbra estimate for every method: `samples` heights along the
//!   light ray (default [`DEFAULT_SHADOW_SAMPLES`] = the paper's 8), each sample's blocker
//!   height above the ray divided by the ray's climb to it (the blocker-to-receiver
//!   ratio), visibility `1 - clamp(max, 0, 1)`. An approximation (see the shader).
//!
//! # Bindings
//!
//! Set 0, push descriptors, mirrored by `glsl/shadow.comp` (push constants:
//! [`ShadowParams`]):
//!
//! | binding (GLSL name; the shader numbers it) | resource | layout on entry |
//! |---|---|---|
//! | `u_hit_uv`, `u_hit_height` | hit images (storage, read) | `GENERAL` |
//! | `u_frame` | G-buffer `frame` (sampled, `texelFetch`) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_height` | height field (bilinear sampler) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_pyramid` | cell-max pyramid (hard shadows of the pyramid methods only) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_visibility` | visibility (`R16_SFLOAT` storage, written) | `GENERAL` |
//! | `u_depth` | G-buffer `depth` (sampled: which pixels have geometry) | `SHADER_READ_ONLY_OPTIMAL` |
//! | `u_tiles` | the material's tile list ([`crate::passes::classify`]) | |
//!
//! One dispatch shadows one material: a workgroup per tile of its list, an invocation per
//! pixel of the material.
//!
//! # Cost
//!
//! One more full-screen dispatch: soft is `samples` filtered fetches per pixel; hard with
//! a march is up to `(1 - h) * steps` samples of 4 texel fetches (early exit at the first
//! occluder); the
//! exact traversal costs about what the `exact` view ray costs for a ray of the light's
//! slope (grazing lights cross more cells).

use crate::abi::{SHADOW_MODE_HARD, SHADOW_MODE_SOFT, ShadeParams, ShadowParams};
use crate::context::Context;
use crate::error::{Error, Result};
use crate::gpu::owned::Destroy;
use crate::gpu::pipeline::{FetchPipeline, storage_view};
use crate::gpu::{HeightTexture, ViewRef};
use crate::heightfield::Addressing;
use crate::method::{Method, PyramidKind};
use crate::passes::classify::{MaterialTiles, TILES};
use crate::passes::gbuffer::GBufferViews;
use crate::passes::pyramid::Pyramid;
use crate::passes::trace::HitViews;
use crate::scene::addressing_code;
use crate::shaders;
use ash::vk;

/// Self-shadowing: the light ray starts this far (in heights, the depth being 1) above
/// the receiver, so the receiver's own surface does not shadow it where it faces the
/// light (see `dispmap_cli::reference::Reference::occluded`; the GPU `shadow` pass uses the same value).
pub const SHADOW_BIAS: f64 = 1.0 / 4096.0;

/// Self-shadowing: lower bound of the light's `L_ts.z` when the light ray's climb
/// `depth_scale * L.xy / L.z` is formed (the view ray's `MIN_COS` in `scene`), so the
/// climb stays finite for a light on the horizon.
pub const SHADOW_MIN_COS: f64 = 1e-4;

/// Format of the visibility image.
pub const VISIBILITY_FORMAT: vk::Format = vk::Format::R16_SFLOAT;

/// Default light samples of soft shadows: the paper's `n = 8` (its Fig. 7).
pub const DEFAULT_SHADOW_SAMPLES: u32 = 8;

/// Largest accepted `--shadow-samples`.
pub const MAX_SHADOW_SAMPLES: u32 = 1024;

/// Self-shadowing mode (CLI `--shadows`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum ShadowMode {
    /// No self-shadowing: no pass, no image.
    #[default]
    Off,
    /// First occluder along the light ray: visibility 0 or 1.
    Hard,
    /// Tatarchuk's penumbra estimate: visibility in `[0, 1]`.
    Soft,
}

impl ShadowMode {
    /// Every mode.
    pub const ALL: &'static [ShadowMode] = &[ShadowMode::Off, ShadowMode::Hard, ShadowMode::Soft];

    /// CLI name.
    pub fn name(self) -> &'static str {
        match self {
            ShadowMode::Off => "off",
            ShadowMode::Hard => "hard",
            ShadowMode::Soft => "soft",
        }
    }
}

impl std::fmt::Display for ShadowMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ShadowMode {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        ShadowMode::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                Error::invalid("shadows", format!("'{s}' is not one of: off, hard, soft"))
            })
    }
}

/// Self-shadowing settings (part of [`RenderSettings`](crate::renderer::RenderSettings)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ShadowSettings {
    /// The mode (`--shadows`).
    pub mode: ShadowMode,
    /// Light samples of soft shadows (`--shadow-samples`).
    pub samples: u32,
}

impl Default for ShadowSettings {
    fn default() -> Self {
        ShadowSettings {
            mode: ShadowMode::Off,
            samples: DEFAULT_SHADOW_SAMPLES,
        }
    }
}

impl ShadowSettings {
    /// Whether the `shadow` pass runs.
    pub fn is_on(&self) -> bool {
        self.mode != ShadowMode::Off
    }

    /// Checks the values; the error names the option.
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 || self.samples > MAX_SHADOW_SAMPLES {
            return Err(Error::invalid(
                "shadow-samples",
                format!("{} is outside 1..={MAX_SHADOW_SAMPLES}", self.samples),
            ));
        }
        Ok(())
    }
}

/// How the pass answers its query (the shader variant).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShadowTrace {
    /// Exact "any hit" traversal of the cell-max pyramid (`glsl/shadow.comp`'s
    /// `PYRAMID` variant): hard shadows of `exact`, `dig-guarded`, `pyramid` and the
    /// cone methods (whose cone map is built from the same cell pyramid).
    Pyramid,
    /// Samples of the hardware-filtered height field: the linear march of the marching
    /// methods' hard shadows and the soft estimate of every method.
    Sampled,
}

impl ShadowTrace {
    /// The query `mode` uses with `method`.
    pub fn for_method(mode: ShadowMode, method: Method) -> Self {
        match (mode, method.needs().pyramid) {
            (ShadowMode::Hard, Some(_)) => ShadowTrace::Pyramid,
            _ => ShadowTrace::Sampled,
        }
    }
}

/// The images the shadow pass reads and writes (layouts in the module docs).
#[derive(Clone, Copy)]
pub struct ShadowInputs<'a> {
    /// The hit images (read).
    pub hit: HitViews,
    /// The G-buffer (its frame is read).
    pub gbuffer: GBufferViews,
    /// The height field.
    pub height: &'a HeightTexture,
    /// A built cell-max pyramid ([`ShadowTrace::Pyramid`] only).
    pub pyramid: Option<&'a Pyramid>,
    /// The visibility output (written; the frame's size).
    pub visibility: ViewRef,
    /// The material and its tiles.
    pub tiles: MaterialTiles,
}

const SAMPLED: vk::DescriptorType = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_IMAGE;

/// The shadow pass of one [`ShadowTrace`].
pub struct ShadowPass {
    trace: ShadowTrace,
    pipeline: FetchPipeline,
}

impl ShadowPass {
    /// The bindings its shader declares (reflected): what a dispatch reads and writes.
    pub fn bindings(&self) -> &'static [crate::shaders::ShaderBinding] {
        self.pipeline.pipeline.bindings
    }

    /// Builds the pipeline of `trace`.
    pub fn new(ctx: &Context, trace: ShadowTrace) -> Result<Self> {
        // What it binds, by GLSL name (`glsl/shadow.comp` numbers them).
        let mut bindings = vec![
            ("u_hit_uv", STORAGE),
            ("u_hit_height", STORAGE),
            ("u_frame", SAMPLED),
            ("u_height", SAMPLED),
            ("u_visibility", STORAGE),
            ("u_depth", SAMPLED),
            TILES,
        ];
        let (name, shader) = match trace {
            ShadowTrace::Pyramid => {
                bindings.push(("u_pyramid", SAMPLED));
                ("shadow[pyramid]", &shaders::SHADOW_COMP_PYRAMID)
            }
            ShadowTrace::Sampled => ("shadow", &shaders::SHADOW_COMP),
        };
        let pipeline = FetchPipeline::new(
            ctx,
            name,
            shader,
            &bindings,
            std::mem::size_of::<ShadowParams>() as u32,
        )?;
        Ok(ShadowPass { trace, pipeline })
    }

    /// The query this pass runs.
    pub fn trace(&self) -> ShadowTrace {
        self.trace
    }

    /// The push constants of a frame: the light and frame from the frame's `shade`
    /// constants, the march's `steps` (the method's), the map's `addressing`.
    pub fn params(
        settings: &ShadowSettings,
        steps: u32,
        shade: &ShadeParams,
        addressing: Addressing,
    ) -> ShadowParams {
        ShadowParams {
            light_dir: shade.light_dir.truncate().extend(0.0),
            frame_size: shade.frame_size,
            map_size: shade.map_size,
            depth_scale: shade.depth_scale,
            bias: SHADOW_BIAS as f32,
            min_cos: SHADOW_MIN_COS as f32,
            addressing: addressing_code(addressing),
            mode: match settings.mode {
                ShadowMode::Soft => SHADOW_MODE_SOFT,
                _ => SHADOW_MODE_HARD,
            },
            steps: steps.max(1),
            samples: settings.samples.max(1),
            pyramid_levels: 0,
            material: 0,
            pad: [0; 3],
        }
    }

    /// Records the dispatch over the material's tiles. Fails (recording nothing) when the
    /// pyramid query gets no cell pyramid.
    ///
    /// # Safety
    /// * `cmd` is a command buffer of `ctx`'s device in the recording state, outside a
    ///   render pass instance, for a queue of the context's queue family.
    /// * `inputs`' views belong to that device and have the formats and usages of the
    ///   module's table; the hit images and the G-buffer are of `inputs.visibility`'s
    ///   size.
    /// * When the command buffer executes, the images are in the layouts of the module's
    ///   table: the hit images in `GENERAL`, their writes visible to compute-shader storage
    ///   reads; the G-buffer, `height` and the pyramid in `SHADER_READ_ONLY_OPTIMAL`,
    ///   their writes visible to compute-shader sampled reads; the visibility in
    ///   `GENERAL`, earlier accesses ordered before compute-shader storage writes (the
    ///   caller's barriers); the tile list written by a `classify` recorded before in the
    ///   same command buffer.
    /// * The images behind `inputs` and this pass stay alive until the command buffer has
    ///   executed.
    pub unsafe fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        inputs: ShadowInputs,
        params: &ShadowParams,
    ) -> Result<()> {
        let ShadowInputs {
            hit,
            gbuffer,
            height,
            pyramid,
            visibility,
            tiles,
        } = inputs;
        let pyramid = match (self.trace, pyramid) {
            (ShadowTrace::Pyramid, Some(p)) if p.kind == PyramidKind::Cell => Some(p),
            (ShadowTrace::Pyramid, _) => {
                return Err(Error::invalid(
                    "shadow inputs",
                    "hard shadows of the pyramid methods need a built cell pyramid",
                ));
            }
            (ShadowTrace::Sampled, _) => None,
        };
        let (hit_uv, hit_height) = (storage_view(hit.uv), storage_view(hit.height));
        let frame = self.pipeline.fetch_view(gbuffer.frame.view);
        let heights = [height.descriptor()];
        let pyramids = pyramid.map(|p| [p.descriptor()]);
        let out = storage_view(visibility.view);
        let depth = self.pipeline.fetch_view(gbuffer.depth.view);
        let pl = &self.pipeline.pipeline;
        let mut writes = vec![
            pl.image("u_hit_uv", &hit_uv)?,
            pl.image("u_hit_height", &hit_height)?,
            pl.image("u_frame", &frame)?,
            pl.image("u_height", &heights)?,
        ];
        if let Some(p) = &pyramids {
            writes.push(pl.image("u_pyramid", p)?);
        }
        writes.push(pl.image("u_visibility", &out)?);
        writes.push(pl.image("u_depth", &depth)?);
        let push = ShadowParams {
            pyramid_levels: pyramid.map_or(0, Pyramid::shader_levels),
            material: tiles.material,
            ..*params
        };
        // SAFETY: this function's # Safety contract: `cmd` is recording outside a render
        // pass; the writes match the pipeline's set 0 (the pyramid is bound exactly for
        // `ShadowTrace::Pyramid`, checked above) and name live views in the layouts of the
        // module's table; the push constants are the `ShadowParams` the layout was built
        // with; the pipeline lives as long as this pass; the list is the classification's
        // (this function's contract).
        unsafe {
            tiles.dispatch(
                ctx,
                cmd,
                &self.pipeline.pipeline,
                &writes,
                bytemuck::bytes_of(&push),
            )
        }
    }
}

impl Destroy for ShadowPass {
    /// Destroys the pipeline and sampler.
    unsafe fn destroy(&mut self, ctx: &Context) {
        // SAFETY: Destroy's contract (nothing pending uses these objects), passed on.
        unsafe {
            self.pipeline.destroy(ctx);
        }
    }
}

/// The visibility image's bytes of `values` (IEEE halves, rounded to nearest even).
pub fn encode_visibility(values: &[f32]) -> Vec<u8> {
    values
        .iter()
        .flat_map(|&v| half::f16::from_f32(v).to_bits().to_le_bytes())
        .collect()
}

/// `f32` of an IEEE half (the visibility image's texels).
pub fn f16_to_f32(bits: u16) -> f32 {
    half::f16::from_bits(bits).to_f32()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse_and_bad_values_name_the_option() {
        for &m in ShadowMode::ALL {
            assert_eq!(m.name().parse::<ShadowMode>().unwrap(), m);
        }
        let err = "on".parse::<ShadowMode>().unwrap_err().to_string();
        assert!(err.contains("shadows") && err.contains("'on'"), "{err}");
        let bad = ShadowSettings {
            mode: ShadowMode::Soft,
            samples: 0,
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("shadow-samples"), "{err}");
        assert!(ShadowSettings::default().validate().is_ok());
        assert!(!ShadowSettings::default().is_on());
    }

    #[test]
    fn the_query_follows_the_method_family() {
        use ShadowTrace::*;
        for &m in Method::ALL {
            let pyramid = matches!(
                m,
                Method::Exact
                    | Method::DigGuarded
                    | Method::Pyramid
                    | Method::Cone
                    | Method::ConeExact
                    | Method::RelaxedCone
            );
            let hard = ShadowTrace::for_method(ShadowMode::Hard, m);
            assert_eq!(hard, if pyramid { Pyramid } else { Sampled }, "{m}");
            assert_eq!(ShadowTrace::for_method(ShadowMode::Soft, m), Sampled, "{m}");
        }
    }

    #[test]
    fn visibility_as_halves() {
        assert_eq!(encode_visibility(&[1.0, 0.0]), vec![0x00, 0x3c, 0, 0]);
    }

    #[test]
    fn halves_decode() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0x0000), 0.0);
        assert_eq!(f16_to_f32(0x3800), 0.5);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x3bff), 1.0 - 1.0 / 2048.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert!(f16_to_f32(0x7e00).is_nan());
        assert_eq!(f16_to_f32(0x7c00), f32::INFINITY);
    }
}
