// dispmap's tiled plane for a host engine's vertex shader (and dispmap's own
// glsl/gbuffer.vert, so there is one source of truth). A host that draws dispmap's plane
// with this function and the same inputs gets bit-identical vertices, hence the same
// rays and hits as `dispmap render` (tests/host_engine.rs).
//
// The plane is y = 0 and needs no vertex buffer: draw `GBufferParams::vertex_count()`
// vertices (6 per cell, a triangle list, no culling needed) and pass gl_VertexIndex.
//   cells = 0:      world_rect as two triangles (the decal quad).
//   cells = n > 0:  world_rect as a grid of 2n x 2n cells centred on the eye (clamped into
//                   the rectangle), its lines spaced geometrically: cells about the eye's
//                   height across under the eye, growing by a constant factor outwards to
//                   the rectangle's edge, so each cell spans depths within a small ratio
//                   and the rasteriser's f32 depth plane keeps the precision of the depths
//                   it covers (two triangles 8192 tiles wide gave depths 1e-3 off next to
//                   the eye and left pixels uncovered: tests/gbuffer_plane.rs).
// Inputs are those of dispmap's GBufferParams (src/abi.rs; `Scene::gbuffer_params`):
// world_rect = (x0, z0, x1, z1), uv_rect = (u0, v0, u1, v1) at those corners, cells =
// plane_cells, eye = camera_pos.xyz. For the grid the rectangle must be laid out about
// the eye (dispmap centres it on the eye's tile), so that the eye minus the rectangle's
// middle is exact.
// Outputs: eye_rel, the vertex minus the eye (interpolate it as the fragment's
// eye-relative position for dispmap_gbuffer_encode, with camera_pos = vec3(0)), and uv.
// Transform eye_rel with the eye-relative view-projection (`FrameCamera::view_proj_eye`,
// dispmap's GBufferParams.view_proj): gl_Position = view_proj_eye * vec4(eye_rel, 1.0).
// Everything is computed from offsets relative to the eye, never from world coordinates,
// so a camera far from the origin keeps full precision near the eye; every attribute of
// a grid vertex is a function of its integer grid coordinates only, so neighbouring cells
// share their vertices bit for bit (watertight).
#ifndef DISPMAP_INCLUDE_PLANE_GLSL
#define DISPMAP_INCLUDE_PLANE_GLSL

const vec2 DISPMAP_PLANE_CORNERS[6] =
    vec2[](vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 0), vec2(1, 1), vec2(0, 1));

// Offset from the grid's centre of grid line k in [-n, n] along one axis: 0 at k = 0,
// exactly -to_lo / to_hi at k = -n / n, scale * (r^(|k|/n) - 1) in between, with
// r = extent / scale + 1 (the first cell is about scale across).
float dispmap_plane_grid_line(int k, int n, float to_lo, float to_hi, float scale) {
    if (k == 0) {
        return 0.0;
    }
    float extent = k < 0 ? to_lo : to_hi;
    float o = abs(k) == n ? extent
                          : scale * (pow(extent / scale + 1.0, float(abs(k)) / float(n)) - 1.0);
    return k < 0 ? -o : o;
}

// Vertex `vertex_index` of the plane (see above).
void dispmap_plane_vertex(int vertex_index, uint cells, vec4 world_rect, vec4 uv_rect,
                          vec3 eye, out vec3 eye_rel, out vec2 uv) {
    int n = int(cells);
    vec2 corner = DISPMAP_PLANE_CORNERS[vertex_index % 6];
    if (n == 0) {
        vec2 xz = mix(world_rect.xy, world_rect.zw, corner);
        eye_rel = vec3(xz.x, 0.0, xz.y) - eye;
        uv = mix(uv_rect.xy, uv_rect.zw, corner);
        return;
    }
    int cell = vertex_index / 6;
    ivec2 k = ivec2(cell % (2 * n), cell / (2 * n)) + ivec2(corner) - n;
    vec2 lo = world_rect.xy;
    vec2 hi = world_rect.zw;
    // The grid's centre: the eye, clamped into the rectangle (then exactly the eye).
    vec2 centre = clamp(eye.xz, lo, hi);
    float scale = max(abs(eye.y), 1e-3);
    vec2 o = vec2(dispmap_plane_grid_line(k.x, n, centre.x - lo.x, hi.x - centre.x, scale),
                  dispmap_plane_grid_line(k.y, n, centre.y - lo.y, hi.y - centre.y, scale));
    // Everything from offsets, never from world coordinates: far from the origin a world
    // position has too few bits (1e-3 tiles at 1e4 tiles). The vertex relative to the eye
    // is the grid offset (plus the clamp's, 0 when the eye is over the rectangle), and the
    // transform is eye-relative, so both keep full precision near the eye. `centre - mid`
    // is exact when the rectangle is laid out about the eye (both are then close to each
    // other: Sterbenz).
    vec2 rel = (centre - eye.xz) + o;
    eye_rel = vec3(rel.x, -eye.y, rel.y);
    vec2 mid = 0.5 * (lo + hi);
    vec2 uv_per_world = (uv_rect.zw - uv_rect.xy) / (hi - lo);
    uv = 0.5 * (uv_rect.xy + uv_rect.zw) + ((centre - mid) + o) * uv_per_world;
}

#endif
