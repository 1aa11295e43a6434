#version 460
// examples/host_engine.rs: the host engine's own G-buffer fragment shader, writing
// dispmap's channels with the provided include. The draw's material is camera_pos.w (the
// floor 0, the cube 1); the cube's top face is flat geometry (not displaced). The floor's
// entry is the pixel's own centre ray (dispmap_plane_pixel_ray, with dispmap's
// PixelRayParams in a uniform buffer), exactly as dispmap's own G-buffer computes it; the
// cube's is the rasteriser's interpolation.
// BEHIND variant: the engine's behind layer (glsl/include/dispmap_behind.glsl): a fragment
// is kept only at a pixel whose first-layer trace missed, behind the first layer's surface.
// dispmap-variant: BEHIND
#include "../include/dispmap_plane.glsl"
#include "../include/dispmap_gbuffer.glsl"
#include "host_engine.glsl"

layout(set = 0, binding = 0, std140) uniform PixelRayBlock {
    DispmapPixelRay u_pixel_ray;
};

#ifdef BEHIND
#include "../include/dispmap_behind.glsl"
// The first layer's G-buffer depth and hit height (the same frame slot's).
layout(set = 0, binding = 1) uniform sampler2D u_first_depth;
layout(set = 0, binding = 2, r32f) uniform readonly image2D u_first_hit_height;

// Discards the fragment unless it belongs to the behind layer; `depth` is the one it writes.
void keep_behind_only(float depth) {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    if (!dispmap_behind_keep(imageLoad(u_first_hit_height, pixel).x,
                             texelFetch(u_first_depth, pixel, 0).r, depth)) {
        discard;
    }
}
#endif

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;
layout(location = 2) flat in vec4 v_normal;     // w: surface id
layout(location = 3) flat in vec3 v_tangent;
layout(location = 4) flat in vec3 v_bitangent;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;

// The floor's surface id (host_engine_floor.vert).
const float FLOOR_ID = 1.0;

void main() {
    // The cube keeps the rasteriser's depth; the floor writes its entry's (below).
    gl_FragDepth = gl_FragCoord.z;
    uint material = uint(pc.camera_pos.w);
    if (material != 0u && v_normal.y > 0.5) {
#ifdef BEHIND
        keep_behind_only(gl_FragDepth);
#endif
        dispmap_gbuffer_encode_flat(v_normal.xyz, v_tangent, v_normal.w, out_ray, out_frame);
        return;
    }
    vec3 eye_rel = v_eye_rel;
    vec2 uv = v_uv;
    if (v_normal.w == FLOOR_ID) {
        float t;
        if (!dispmap_plane_pixel_ray(u_pixel_ray, gl_FragCoord.xy, pc.world_rect, pc.uv_rect,
                                     pc.addressing == DISPMAP_ADDRESSING_REPEAT, eye_rel, uv, t)) {
            discard;
        }
        gl_FragDepth = dispmap_plane_pixel_depth(pc.view_proj, eye_rel);
    }
#ifdef BEHIND
    keep_behind_only(gl_FragDepth);
#endif
    DispmapSurface s = DispmapSurface(eye_rel, vec3(0.0), uv, v_normal.xyz,
        v_tangent, v_bitangent, v_normal.w, pc.depth_scale, pc.min_cos, pc.addressing);
    if (!dispmap_gbuffer_encode_material(s, material, out_ray, out_frame)) {
        discard;
    }
}
