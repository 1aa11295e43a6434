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

#include "dispmap_double_float.glsl"

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


// ---------------------------------------------------------------------------------------
// The pixel's own ray (fragment stage). Interpolating eye_rel and uv across a cell gives
// each fragment the rasteriser's f32 interpolation, which near the horizon is tens of
// texels (worst measured: thousands) from where the pixel's centre ray meets the plane:
// there one pixel row spans hundreds of tiles. dispmap_plane_pixel_ray instead intersects
// the pixel's centre ray (gl_FragCoord.xy, centres at +0.5) with y = 0 in double-float
// arithmetic (dispmap_double_float.glsl) from the camera's f64 values, given as hi/lo f32
// pairs in a DispmapPixelRay (dispmap's `PixelRayParams`, src/abi.rs, from
// `FrameCamera::pixel_ray_params`; a host declares it in a uniform block, std140). The
// ray's angle below the horizon is a difference of two nearly equal terms near the
// horizon, which f32 cannot form (5 texels off at 2 degrees); the double-float keeps
// about 48 bits of it, and the uv is formed relative to the eye's tile so that it keeps
// sub-texel precision thousands of tiles away.
//
// The direction of pixel (px, py)'s centre ray (unnormalised) is
//     dir = forward + (px - W/2) step_x + (py - H/2) step_y
// with forward the unit view direction, step_x = right tan(fov_y / 2) aspect 2 / W and
// step_y = -up tan(fov_y / 2) 2 / H (row 0 is the top of the image): the direction
// through the pixel's centre of the projection the vertices are drawn with
// (docs/design.md, "Camera and frame").
struct DispmapPixelRay {
    vec4 eye_hi;     // xyz: the eye (world), rounded to f32; w: W / 2 (pixels)
    vec4 eye_lo;     // xyz: the eye minus eye_hi; w: H / 2 (pixels)
    vec4 dir_hi;     // xyz: forward (unit), rounded to f32; w: 0
    vec4 dir_lo;     // xyz: forward minus dir_hi; w: 0
    vec4 step_x_hi;  // xyz: the direction's change per pixel along x; w: 0
    vec4 step_x_lo;
    vec4 step_y_hi;  // xyz: the direction's change per pixel along y (downwards); w: 0
    vec4 step_y_lo;
};

// One component of the pixel's direction, a double-float: f + a sx + b sy.
vec2 dispmap_pixel_dir(float f_hi, float f_lo, float sx_hi, float sx_lo, float sy_hi,
                       float sy_lo, float a, float b) {
    vec2 d = dispmap_df_add(vec2(f_hi, f_lo), dispmap_df_mul_f(vec2(sx_hi, sx_lo), a));
    return dispmap_df_add(d, dispmap_df_mul_f(vec2(sy_hi, sy_lo), b));
}

// The entry of the pixel whose centre is frag_coord (gl_FragCoord.xy) on the plane
// y = 0 within world_rect, uv mapped by uv_rect (the inputs of dispmap_plane_vertex).
// Returns false when the centre ray does not meet the rectangle from above (it points
// at or above the horizon, the eye is not above the plane, or the entry lies outside
// world_rect): discard the fragment, as dispmap does. Else eye_rel is the entry minus
// the eye (its y is exactly -eye.y, its xz the ray's at that depth: use it as
// dispmap_gbuffer_encode's world_pos with camera_pos = vec3(0)) and uv the entry's uv,
// reduced to [0, 1) from its double-float value when `repeat` (the addressing repeats
// the map), so that it keeps sub-texel precision far from the eye; t is the ray
// parameter of the entry (entry = eye + t dir).
// Depth: the rasteriser's depth is interpolated like any attribute (near the horizon
// 1e-5 to 5e-4 of the depth off: tests/gbuffer_plane.rs); write the entry's own depth,
// gl_FragDepth = dispmap_plane_pixel_depth(view_proj_eye, eye_rel), so that the depth
// (the corrected depth, the depth resolve) agrees with uv0, as dispmap does.
bool dispmap_plane_pixel_ray(DispmapPixelRay r, vec2 frag_coord, vec4 world_rect,
                             vec4 uv_rect, bool repeat, out vec3 eye_rel, out vec2 uv,
                             out float t) {
    eye_rel = vec3(0.0);
    uv = vec2(0.0);
    t = 0.0;
    // Offsets from the frame's centre: exact (half-integers minus half-integers).
    precise float a = frag_coord.x - r.eye_hi.w;
    precise float b = frag_coord.y - r.eye_lo.w;
    vec2 dx = dispmap_pixel_dir(r.dir_hi.x, r.dir_lo.x, r.step_x_hi.x, r.step_x_lo.x,
                                r.step_y_hi.x, r.step_y_lo.x, a, b);
    vec2 dy = dispmap_pixel_dir(r.dir_hi.y, r.dir_lo.y, r.step_x_hi.y, r.step_x_lo.y,
                                r.step_y_hi.y, r.step_y_lo.y, a, b);
    vec2 dz = dispmap_pixel_dir(r.dir_hi.z, r.dir_lo.z, r.step_x_hi.z, r.step_x_lo.z,
                                r.step_y_hi.z, r.step_y_lo.z, a, b);
    vec2 eye_y = vec2(r.eye_hi.y, r.eye_lo.y);
    if (!(dy.x < 0.0) || !(eye_y.x > 0.0)) {
        return false;
    }
    vec2 tt = dispmap_df_div(eye_y, -dy);
    vec2 rx = dispmap_df_mul(dx, tt);
    vec2 rz = dispmap_df_mul(dz, tt);
    // The rectangle, relative to the eye (its edge needs no more than f32).
    vec2 lo = world_rect.xy - r.eye_hi.xz;
    vec2 hi = world_rect.zw - r.eye_hi.xz;
    if (!(rx.x >= lo.x && rx.x <= hi.x && rz.x >= lo.y && rz.x <= hi.y)) {
        return false;
    }
    t = tt.x;
    eye_rel = vec3(rx.x, -eye_y.x, rz.x);
    // uv = uv0 + (eye - world0 + rel) k per axis, in double-float.
    vec2 k = (uv_rect.zw - uv_rect.xy) / (world_rect.zw - world_rect.xy);
    vec2 rel[2] = vec2[](rx, rz);
    vec2 eye_hi = r.eye_hi.xz;
    vec2 eye_lo = r.eye_lo.xz;
    for (int i = 0; i < 2; ++i) {
        float e;
        float s = dispmap_two_sum(eye_hi[i], -world_rect[i], e);
        vec2 from_corner = dispmap_df_add(dispmap_df_add(vec2(s, e), vec2(eye_lo[i], 0.0)), rel[i]);
        vec2 u = dispmap_df_add(dispmap_df_mul_f(from_corner, k[i]), vec2(uv_rect[i], 0.0));
        if (repeat) {
            // hi - floor(hi) is exact; adding lo may step over an integer.
            precise float f = (u.x - floor(u.x)) + u.y;
            f = f < 0.0 ? f + 1.0 : f;
            uv[i] = f >= 1.0 ? f - 1.0 : f;
        } else {
            uv[i] = u.x;
        }
    }
    return true;
}

// The reverse-Z depth of the entry eye_rel (dispmap_plane_pixel_ray) through the
// eye-relative view-projection the vertices are drawn with (GBufferParams.view_proj).
float dispmap_plane_pixel_depth(mat4 view_proj_eye, vec3 eye_rel) {
    vec4 clip = view_proj_eye * vec4(eye_rel, 1.0);
    return clamp(clip.z / clip.w, 0.0, 1.0);
}

#endif
