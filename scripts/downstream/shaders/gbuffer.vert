#version 460
// The host's G-buffer vertex stage: dispmap's tiled floor from gl_VertexIndex (its
// coverage; the fragment stage computes each pixel's entry from its centre ray).
#include "frame.glsl"
#include "dispmap_plane.glsl"

void main() {
    vec3 eye_rel;
    vec2 uv;
    dispmap_plane_vertex(gl_VertexIndex, pc.plane_cells, pc.world_rect, pc.uv_rect, pc.eye.xyz,
                         eye_rel, uv);
    gl_Position = pc.view_proj_eye * vec4(eye_rel, 1.0);
}
