#version 460
// G-buffer pass, vertex stage: the macro plane y = 0, generated from gl_VertexIndex (no
// vertex buffer) by dispmap_plane_vertex, the function a host engine uses to draw the
// same plane (glsl/include/dispmap_plane.glsl documents the quad, plane_cells = 0, and the
// grid of 2n x 2n cells about the eye, plane_cells = n > 0).
#include "gbuffer_params.glsl"
#include "include/dispmap_plane.glsl"

// The vertices only decide which pixels the plane covers: the fragment stage computes
// each pixel's entry and uv from its own centre ray (dispmap_plane_pixel_ray), so nothing
// is interpolated. Positions are relative to the eye, transformed by the eye-relative
// view-projection (full precision near the eye wherever the eye is).
//
// The rectangle is rasterised at twice its size about its centre: the raster only decides
// which pixels get a fragment, and each fragment's own f64 ray decides whether it meets the
// rectangle (gbuffer.frag discards the others). Drawn at its own size, its far edge near
// the horizon, in f32 and snapped to the rasteriser's sub-pixel grid, left out 1 to 3
// pixels of a row whose rays meet the rectangle (tests/camera_depth.rs).
void main() {
    vec3 eye_rel;
    vec2 uv;
    vec2 mid = 0.5 * (pc.world_rect.xy + pc.world_rect.zw);
    vec2 half_size = 0.5 * (pc.world_rect.zw - pc.world_rect.xy);
    vec4 raster_rect = vec4(mid - 2.0 * half_size, mid + 2.0 * half_size);
    dispmap_plane_vertex(gl_VertexIndex, pc.plane_cells, raster_rect, pc.uv_rect,
                         pc.camera_pos.xyz, eye_rel, uv);
    gl_Position = pc.view_proj * vec4(eye_rel, 1.0);
}
