#version 460
// hit_depth: the corrected depth of the displaced surface. For each pixel with a hit, the
// hit's position is the entry point on the macro surface (unprojected from the G-buffer
// depth) moved along the tangent frame by the hit's offset from the entry
// (glsl/include/dispmap_displace.glsl, the code hosts and the `motion` pass use too), and
// its reverse-Z clip depth z / w is written to an R32_SFLOAT image. Positions are offsets
// from the eye (the matrices are view_proj * translation(eye) and its inverse,
// src/passes/hit_depth.rs), so a far pixel's small depth never cancels large world
// coordinates. For a traced hit p_hit lies on the pixel's view ray, so the depth is that
// of the displaced surface seen through the pixel. Pixels without a hit (no geometry, or a
// clamp-addressed ray that left the decal, which the shade pass draws as background) get
// 0, the cleared reverse-Z depth at infinity: nothing is there, so whatever lies behind
// must show.
// Bindings: src/passes/hit_depth.rs; push constants: src/abi.rs HitDepthParams.
#include "frame.glsl"
#include "include/dispmap_displace.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0, rg32f) uniform readonly image2D u_hit_uv;
layout(set = 0, binding = 4, r32f) uniform readonly image2D u_hit_height;
layout(set = 0, binding = 1) uniform sampler2D u_ray;
layout(set = 0, binding = 2) uniform sampler2D u_depth;
layout(set = 0, binding = 3) uniform usampler2D u_frame;
layout(set = 0, binding = 5, r32f) uniform writeonly image2D u_hit_depth;

layout(push_constant) uniform HitDepthParams {
    mat4 inv_eye_clip;  // clip -> world offset from the eye
    vec4 clip_z_row;    // row 2 of eye offset -> clip (the depth numerator)
    vec4 clip_w_row;    // row 3 of eye offset -> clip (the homogeneous w)
    uvec2 frame_size;   // pixels
    float depth_scale;  // displacement depth in tile units
    uint material;      // the material this dispatch resolves (its tiles: binding 15)
} pc;

#define DISPMAP_TILE_PASS
#include "tiles.glsl"

// One workgroup per tile of the material's list; `classify` wrote the other pixels (the
// G-buffer's own depth).
void main() {
    ivec2 pixel;
    if (!material_pixel(pc.material, pc.frame_size, pixel)) {
        return;
    }
    float depth = texelFetch(u_depth, pixel, 0).r;
    vec4 hit = vec4(imageLoad(u_hit_uv, pixel).xy, imageLoad(u_hit_height, pixel).x, 0.0);
    if (depth <= 0.0 || hit.z < 0.0) {
        imageStore(u_hit_depth, pixel, vec4(0.0));
        return;
    }
    vec3 entry = dispmap_entry_eye_rel(pc.inv_eye_clip, vec2(pixel) + 0.5, vec2(pc.frame_size),
                                       depth);
    vec2 uv0 = texelFetch(u_ray, pixel, 0).xy;
    DispmapFrame f = gbuffer_frame(pixel);
    vec3 p = dispmap_displaced_eye_rel(entry, hit, uv0, f.normal, f.tangent, f.handedness, pc.depth_scale);
    float z = dot(pc.clip_z_row, vec4(p, 1.0));
    float w = dot(pc.clip_w_row, vec4(p, 1.0));
    // w > 0 for every point beyond the entry along the view ray; keep the macro depth
    // for a degenerate frame rather than write a non-finite value.
    float corrected = w > 0.0 ? clamp(z / w, 0.0, 1.0) : depth;
    imageStore(u_hit_depth, pixel, vec4(corrected));
}
