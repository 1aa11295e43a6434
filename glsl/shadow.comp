#version 460
// shadow: self-shadowing of the displaced surface after Tatarchuk 2006, section 3.2.
// Runs after `trace`; for each pixel's hit it casts a ray from the hit towards the
// directional light and writes the light's visibility (1 = lit, 0 = shadowed) into an
// r16f image that `shade` multiplies into the direct (diffuse + specular) light.
// Bindings and push constants mirror src/passes/shadow.rs and src/abi.rs (ShadowParams).
//
// The light ray in the height field's units. Heights h are in [0, 1] with 1 = the macro
// surface; the depth of height h below the macro surface is (1 - h) * depth_scale tiles,
// and one uv unit is one tile. With L_ts = (L.T, L.B, L.N) the unit light direction in
// the G-buffer's tangent frame (T along +u, B along +v, N the macro normal), a step along
// the light that climbs by dh heights rises dh * depth_scale tiles and therefore moves
// dh * depth_scale / L_ts.z tiles along L, i.e. by
//     climb * dh,   climb = depth_scale * L_ts.xy / L_ts.z      (uv per unit height)
// in uv. From the receiver (uv_hit, h0) the light ray is uv(h) = uv_hit + (h - h0) climb
// for h in [h0, 1]; above h = 1 nothing can occlude. L_ts.z is taken at least
// `min_cos` (as the view ray's MIN_COS), so climb stays finite for a light on the horizon.
// Where the macro surface faces away from the light (L_ts.z <= 0) the pixel is in shadow
// (visibility 0), as in the paper, which traces only where N.L > 0.
//
// The receiver is the surface point under the hit, (uv_hit, H(uv_hit)) with H the exact
// bilinear surface (Tatarchuk's reference height h0), not the hit's own height: an
// approximate hit (a march's, or the pyramid method's refinement) can lie under the
// surface by more than the bias, and its light ray would start inside the solid (acne).
// For the exact methods H(uv_hit) is the hit height to f32 rounding.
//
// Modes (SHADOW_MODE_*):
// * hard, PYRAMID variant (methods with a pyramid: exact, dig-guarded, pyramid): exact
//   "any hit" query with the cell-max pyramid traversal of pyramid.glsl. Reversed, the
//   light ray is a view ray entering the macro surface at uv_hit + (1 - h0) climb with
//   parallax -climb, its ray parameter t = 1 - h; the hit is occluded when that ray meets
//   the bilinear surface for t in [0, 1 - h0 - bias] (the light ray from h0 + bias
//   up to the macro surface; clamp addressing: only inside the decal). The CPU twin is
//   Reference::occluded (cli/src/reference.rs), in f64.
// * hard, marching methods: a linear march up the light ray with the method's step
//   (1/steps of the full depth), from Tatarchuk's reference height h0 = H(uv_hit) (the
//   surface under the hit: a march's hit may lie up to a step below it); occluded at the
//   first sample with H >= the ray's height. Like the view march it can step over
//   features thinner than its horizontal step |climb| / steps, so it only ever misses
//   shadows. Its samples are the exact bilinear surface (height_exact: 4 texelFetch),
//   not the hardware filter: the filter's 8-bit weights (lavapipe, and most GPUs) move
//   the surface by up to slope / 512 texel, which near the start of the ray shows as
//   shadow acne (measured on rocks, light 20 degrees, 1024 steps: 7% of the pixels
//   falsely shadowed with the filter, none with the exact surface; the exact surface
//   only near the receiver and the filter beyond still gave 0.35%, at no saving).
// * soft (every method): Tatarchuk's penumbra estimate. n = `samples` heights are read
//   at the fractions s_i = i / (n + 1) of the light ray from h0 = H(uv_hit) to the macro
//   surface (the paper's n = 8 samples, spaced as its 0.11 steps); each gives the
//   blocker's height above the ray, d_i = H(uv_i) - (h0 + r_i), r_i = s_i (1 - h0) the
//   ray's climb to the sample. The penumbra grows with the blocker-to-receiver distance
//   (the paper's Fig. 8), so each sample's occlusion is d_i / r_i (the blocker's rise
//   over the light ray relative to the ray's own climb: 1 = the horizon is twice as
//   steep as the light) and the visibility is 1 - clamp(max_i d_i / r_i, 0, 1). An
//   estimate, not a physical area-light integral: blockers below the ray cast nothing,
//   and features thinner than the sample spacing, or nearer the receiver than the first
//   sample, are missed (the paper's "lack of hard contact shadow"). Its samples are
//   hardware-filtered fetches, as in the paper: its first sample is far enough from the
//   receiver for the filter's 8-bit weights not to matter (measured on rocks: the mean
//   visibility moves by < 0.001 with exact-surface samples).
//
// dispmap-variant: PYRAMID
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0, rg32f) uniform readonly image2D u_hit_uv;
layout(set = 0, binding = 2, r32f) uniform readonly image2D u_hit_height;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
// The height field (linear filtering, the map's addressing).
layout(set = 0, binding = 3) uniform sampler2D u_height;
// binding 4: the cell-max pyramid, PYRAMID variant only (declared by pyramid.glsl).
layout(set = 0, binding = 5, r16f) uniform writeonly image2D u_visibility;
// G-buffer depth (which pixels have geometry: glsl/common/tiles.glsl).
layout(set = 0, binding = 6) uniform sampler2D u_depth;

layout(push_constant) uniform ShadowParams {
    vec4 light_dir;      // xyz: world-space unit vector towards the light
    uvec2 frame_size;    // pixels
    uvec2 map_size;      // texels
    float depth_scale;   // displacement depth in tile units
    float bias;          // the light ray starts this far (heights) above the hit
    float min_cos;       // lower bound of L_ts.z for the climb
    uint addressing;     // ADDRESSING_*
    uint mode;           // SHADOW_MODE_*
    uint steps;          // hard, marching: steps over the full depth (the method's)
    uint samples;        // soft: light samples
    uint pyramid_levels; // levels of the bound pyramid (PYRAMID variant); bit 16: level 0 not stored
    uint material;       // the material this dispatch shadows (its tiles: binding 15)
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

#define DISPMAP_TILE_PASS
#include "tiles.glsl"

#define SHADOW_MODE_HARD 1u
#define SHADOW_MODE_SOFT 2u

#include "march.glsl"
#include "texels.glsl"
#ifdef PYRAMID
#include "pyramid.glsl"
#endif

#ifdef PYRAMID
bool hard_occluded(vec2 uv, vec2 climb) {
    float rise = 1.0 - height_exact(uv);
    float t_stop = rise - pc.bias;
    if (!(t_stop >= 0.0)) {
        return false; // the hit is within `bias` of the macro surface
    }
    uint iterations = 0u;
    // Tile-local for repeat addressing (the hit's uv is unwrapped, up to |P| tiles from
    // the tile the view ray entered): the traversal keeps its precision near 0.
    vec2 start = uv + rise * climb;
    if (pc.addressing == ADDRESSING_REPEAT) {
        start -= floor(start);
    }
    Ray light = Ray(start, -climb);
    return pyramid_segment_hit(light, 0.0, t_stop, pyramid_levels() - 1, iterations) >= 0.0;
}
#else
bool hard_occluded(vec2 uv, vec2 climb) {
    float h0 = height_exact(uv);
    float dh = 1.0 / float(max(pc.steps, 1u));
    uint n = uint(max(floor((1.0 - h0) / dh), 0.0));
    for (uint k = 1u; k <= n; ++k) {
        float rise = float(k) * dh;
        vec2 uv_k = uv + rise * climb;
        if (leaves_domain(uv_k)) {
            return false; // clamp: the ray left the decal, nothing beyond it
        }
        if (height_exact(uv_k) >= h0 + rise) {
            return true;
        }
    }
    return false;
}
#endif

float soft_visibility(vec2 uv, vec2 climb) {
    float h0 = height_at(uv);
    float rise = 1.0 - h0;
    if (!(rise > 0.0)) {
        return 1.0;
    }
    uint n = max(pc.samples, 1u);
    float occlusion = 0.0;
    for (uint i = 1u; i <= n; ++i) {
        float r = rise * float(i) / float(n + 1u);
        vec2 uv_i = uv + r * climb;
        if (leaves_domain(uv_i)) {
            break;
        }
        occlusion = max(occlusion, (height_at(uv_i) - (h0 + r)) / r);
    }
    return 1.0 - clamp(occlusion, 0.0, 1.0);
}

// One workgroup per tile of the material's list; other pixels are left alone.
void main() {
    ivec2 pixel;
    if (!material_pixel(pc.material, pc.frame_size, pixel)) {
        return;
    }
    vec4 hit = vec4(imageLoad(u_hit_uv, pixel).xy, imageLoad(u_hit_height, pixel).x, 0.0);
    float visibility = 1.0; // no hit: nothing to shadow
    if (hit.z >= 0.0) {
        DispmapFrame f = gbuffer_frame(pixel);
        vec3 N = f.normal;
        vec3 T = f.tangent;
        vec3 B = gbuffer_bitangent(f);
        vec3 L = pc.light_dir.xyz;
        vec3 l_ts = vec3(dot(L, T), dot(L, B), dot(L, N));
        if (!(l_ts.z > 0.0)) {
            visibility = 0.0;
        } else {
            vec2 climb = pc.depth_scale * l_ts.xy / max(l_ts.z, pc.min_cos);
            if (pc.mode == SHADOW_MODE_SOFT) {
                visibility = soft_visibility(hit.xy, climb);
            } else {
                visibility = hard_occluded(hit.xy, climb) ? 0.0 : 1.0;
            }
        }
    }
    imageStore(u_visibility, pixel, vec4(visibility));
}
