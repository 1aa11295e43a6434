#version 460
// The host's G-buffer vertex stage: dispmap's tiled floor from gl_VertexIndex.
#include "frame.glsl"
#include "dispmap_plane.glsl"

layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;

void main() {
    dispmap_plane_vertex(gl_VertexIndex, pc.plane_cells, pc.world_rect, pc.uv_rect, pc.eye.xyz,
                         v_eye_rel, v_uv);
    gl_Position = pc.view_proj_eye * vec4(v_eye_rel, 1.0);
}
