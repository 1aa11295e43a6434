#version 460
// examples/host_engine.rs: the host engine's own G-buffer fragment shader, writing
// dispmap's channels with the provided include. The draw's material is camera_pos.w (the
// floor 0, the cube 1); the cube's top face is flat geometry (not displaced).
#include "../include/dispmap_gbuffer.glsl"
#include "host_engine.glsl"

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;
layout(location = 2) flat in vec4 v_normal;     // w: surface id
layout(location = 3) flat in vec3 v_tangent;
layout(location = 4) flat in vec3 v_bitangent;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_tangent;

void main() {
    uint material = uint(pc.camera_pos.w);
    if (material != 0u && v_normal.y > 0.5) {
        dispmap_gbuffer_encode_flat(v_normal.xyz, v_tangent, v_normal.w, out_ray, out_normal, out_tangent);
        return;
    }
    DispmapSurface s = DispmapSurface(v_eye_rel, vec3(0.0), v_uv, v_normal.xyz,
        v_tangent, v_bitangent, v_normal.w, pc.depth_scale, pc.min_cos, pc.addressing);
    if (!dispmap_gbuffer_encode_material(s, material, out_ray, out_normal, out_tangent)) {
        discard;
    }
}
