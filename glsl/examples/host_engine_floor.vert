#version 460
// examples/host_engine.rs: the host engine's floor, dispmap's tiled plane drawn with the
// provided include (no vertex buffer: GBufferParams::vertex_count() vertices), so its
// vertices, and with them the rays and hits, are bit-identical to `dispmap render`'s.
#include "host_engine.glsl"
#include "../include/dispmap_plane.glsl"

layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;
layout(location = 2) flat out vec4 v_normal;
layout(location = 3) flat out vec3 v_tangent;
layout(location = 4) flat out vec3 v_bitangent;

// The floor's surface id (the cube's faces are 2..7).
const float FLOOR_ID = 1.0;

void main() {
    dispmap_plane_vertex(gl_VertexIndex, pc.plane_cells, pc.world_rect, pc.uv_rect,
                         pc.camera_pos.xyz, v_eye_rel, v_uv);
    // The plane y = 0 with u along +x and v along +z.
    v_normal = vec4(0.0, 1.0, 0.0, FLOOR_ID);
    v_tangent = vec3(1.0, 0.0, 0.0);
    v_bitangent = vec3(0.0, 0.0, 1.0);
    gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
}
