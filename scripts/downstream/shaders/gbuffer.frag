#version 460
// The host's G-buffer fragment stage: the floor (y = 0, u along +x, v along +z) is
// material pc.eye.w - 1 of the pass, encoded with dispmap's G-buffer contract; its entry
// is the pixel's own centre ray (dispmap_plane_pixel_ray), from dispmap's PixelRayParams
// in a uniform buffer.
#include "frame.glsl"
#include "dispmap_plane.glsl"
#include "dispmap_gbuffer.glsl"

layout(set = 0, binding = 0, std140) uniform PixelRayBlock {
    DispmapPixelRay u_pixel_ray;
};

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;

void main() {
    vec3 eye_rel;
    vec2 uv;
    float t;
    if (!dispmap_plane_pixel_ray(u_pixel_ray, gl_FragCoord.xy, pc.world_rect, pc.uv_rect,
                                 pc.addressing == DISPMAP_ADDRESSING_REPEAT, eye_rel, uv, t)) {
        discard;
    }
    gl_FragDepth = dispmap_plane_pixel_depth(pc.view_proj_eye, eye_rel);
    DispmapSurface s = DispmapSurface(eye_rel, vec3(0.0), uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), 1.0, pc.depth_scale, pc.min_cos,
        pc.addressing);
    if (!dispmap_gbuffer_encode_material(s, uint(pc.eye.w) - 1u, out_ray, out_frame)) {
        discard;
    }
}
