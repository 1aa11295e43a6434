#version 460
// The host's G-buffer fragment stage: the floor (y = 0, u along +x, v along +z) is
// material pc.eye.w - 1 of the pass, encoded with dispmap's G-buffer contract.
#include "frame.glsl"
#include "dispmap_gbuffer.glsl"

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_tangent;

void main() {
    DispmapSurface s = DispmapSurface(v_eye_rel, vec3(0.0), v_uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), 1.0, pc.depth_scale, pc.min_cos,
        pc.addressing);
    if (!dispmap_gbuffer_encode_material(s, uint(pc.eye.w) - 1u, out_ray, out_normal,
                                         out_tangent)) {
        discard;
    }
}
