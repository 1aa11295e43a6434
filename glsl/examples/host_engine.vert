#version 460
// examples/host_engine.rs: the host engine's own G-buffer vertex shader for its meshes
// (the cube: vertex buffers, one tangent frame and surface id per face, passed flat so
// they reach the fragment shader unchanged). The floor has its own vertex shader,
// host_engine_floor.vert.
#include "host_engine.glsl"

layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec2 in_uv;
layout(location = 2) in vec4 in_normal;     // xyz: unit normal; w: surface id
layout(location = 3) in vec3 in_tangent;    // unit +u direction
layout(location = 4) in vec3 in_bitangent;  // unit +v direction

// Eye-relative position (precise near the eye wherever the eye is; see
// glsl/include/dispmap_gbuffer.glsl), transformed by the eye-relative view-projection.
layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out vec4 v_normal;
layout(location = 3) flat out vec3 v_tangent;
layout(location = 4) flat out vec3 v_bitangent;

void main() {
    v_eye_rel = in_pos - pc.camera_pos.xyz;
    v_uv = in_uv;
    v_normal = in_normal;
    v_tangent = in_tangent;
    v_bitangent = in_bitangent;
    gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
}
