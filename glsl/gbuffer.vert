#version 460
// G-buffer pass, vertex stage: the macro plane y = 0, generated from gl_VertexIndex (no
// vertex buffer). With plane_cells = 0 it is the two triangles of world_rect (the decal
// quad). With plane_cells = n > 0 it is world_rect as a grid of 2n x 2n cells (six
// vertices each) centred on the eye, its lines spaced geometrically: cells about the eye's
// height across under the eye, growing by a constant factor outwards to the rectangle's
// edge. Each cell then spans depths within a small ratio, so the rasteriser's f32 depth
// plane works at the precision of the depths it covers. (Two triangles 8192 tiles wide,
// clipped at the near plane, gave depths off by 1e-3 relative next to the eye on a
// close-up and up to 4e-3 at the horizon, and left pixels of the frame's last columns
// uncovered on some views: tests/gbuffer_plane.rs.) Grid vertices are computed from
// their integer grid coordinates only, so neighbouring cells share them bit for bit
// (watertight).
#include "gbuffer.glsl"

// Position relative to the eye: interpolated near the eye at full precision wherever the
// eye is (world positions far from the origin would lose the view direction's bits).
layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;

const vec2 CORNERS[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 0), vec2(1, 1), vec2(0, 1));

// Offset from the grid's centre of grid line k in [-n, n] along one axis: 0 at k = 0,
// exactly -to_lo / to_hi at k = -n / n, scale * (r^(|k|/n) - 1) in between, with
// r = extent / scale + 1 (the first cell is about scale across).
float grid_line(int k, int n, float to_lo, float to_hi, float scale) {
    if (k == 0) {
        return 0.0;
    }
    float extent = k < 0 ? to_lo : to_hi;
    float o = abs(k) == n ? extent
                          : scale * (pow(extent / scale + 1.0, float(abs(k)) / float(n)) - 1.0);
    return k < 0 ? -o : o;
}

void main() {
    int n = int(pc.plane_cells);
    vec2 corner = CORNERS[gl_VertexIndex % 6];
    if (n == 0) {
        vec2 xz = mix(pc.world_rect.xy, pc.world_rect.zw, corner);
        v_eye_rel = vec3(xz.x, 0.0, xz.y) - pc.camera_pos.xyz;
        v_uv = mix(pc.uv_rect.xy, pc.uv_rect.zw, corner);
        gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
        return;
    }
    int cell = gl_VertexIndex / 6;
    ivec2 k = ivec2(cell % (2 * n), cell / (2 * n)) + ivec2(corner) - n;
    vec2 lo = pc.world_rect.xy;
    vec2 hi = pc.world_rect.zw;
    // The grid's centre: the eye, clamped into the rectangle (then exactly the eye).
    vec2 centre = clamp(pc.camera_pos.xz, lo, hi);
    float scale = max(abs(pc.camera_pos.y), 1e-3);
    vec2 o = vec2(grid_line(k.x, n, centre.x - lo.x, hi.x - centre.x, scale),
                  grid_line(k.y, n, centre.y - lo.y, hi.y - centre.y, scale));
    // Everything from offsets, never from world coordinates: far from the origin a world
    // position has too few bits (1e-3 tiles at 1e4 tiles). The vertex relative to the eye
    // is the grid offset (plus the clamp's, 0 when the eye is over the rectangle), and the
    // transform is eye-relative (pc.view_proj), so both keep full precision near the eye.
    // `centre - mid` is exact: Scene lays the rectangle out about the eye's tile, so both
    // are close to each other (Sterbenz). Every attribute is a function of k alone, so
    // neighbouring cells share their vertices bit for bit (watertight).
    vec2 rel = (centre - pc.camera_pos.xz) + o;
    v_eye_rel = vec3(rel.x, -pc.camera_pos.y, rel.y);
    vec2 mid = 0.5 * (lo + hi);
    vec2 uv_per_world = (pc.uv_rect.zw - pc.uv_rect.xy) / (hi - lo);
    v_uv = 0.5 * (pc.uv_rect.xy + pc.uv_rect.zw) + ((centre - mid) + o) * uv_per_world;
    gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
}
