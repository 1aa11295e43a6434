#version 460
// G-buffer pass, vertex stage: the macro plane y = 0, generated from gl_VertexIndex (no
// vertex buffer) by dispmap_plane_vertex, the function a host engine uses to draw the
// same plane (glsl/include/dispmap_plane.glsl documents the quad, plane_cells = 0, and the
// grid of 2n x 2n cells about the eye, plane_cells = n > 0).
#include "gbuffer.glsl"
#include "include/dispmap_plane.glsl"

// Position relative to the eye: interpolated near the eye at full precision wherever the
// eye is (world positions far from the origin would lose the view direction's bits).
layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;

void main() {
    dispmap_plane_vertex(gl_VertexIndex, pc.plane_cells, pc.world_rect, pc.uv_rect,
                         pc.camera_pos.xyz, v_eye_rel, v_uv);
    gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
}
