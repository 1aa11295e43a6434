#version 460
// cone-exact (beyond the papers): robust cone stepping (glsl/common/cone.glsl) over the
// conservative cone map of the bilinear surface until the ray is at or below the maximum
// of the cell it is in, then the exact ray/bilinear-patch solve of `exact`
// (glsl/common/pyramid.glsl: cell_hit) over the rest of the cell; on a miss the march
// goes on from the cell's exit. The cones never reach the surface, so no crossing is
// skipped: the same accuracy as `exact`, with fewer steps over open space.
// dispmap-variant: ITERATIONS
#include "trace.glsl"
#include "pyramid.glsl"
#define CONE_PRECISE
#include "cone.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    ConeRay r;
    if (!cone_start(ray, r)) {
        return miss(ray, iterations);
    }
    float t = r.t_start, t_above = r.t_start;
    float step = 0.0;
    // Each step leaves a cell or reaches its band, and each band test leaves the cell.
    float cap = CONE_BUDGET;
    while (step < cap) {
        float t_exit;
        vec2 exit;
        if (!cone_advance(r, t, t_exit, exit, t_above, step, cap, iterations)) {
            break;
        }
        float th = cell_hit(r.cell, cell_texels(r.cell), r.origin, r.dir, t, r.t_lo, r.t_end, g_long_ray);
        if (th >= 0.0) {
            return hit_at_t(ray, th, iterations);
        }
        if (t_exit >= r.t_end) {
            t = r.t_end;
            break;
        }
        cone_move(r, exit, t_exit, t_exit);
        t = t_exit;
        step += 1.0;
    }
    // Out of cone steps before the ray's end: the exact pyramid traversal from the point
    // reached (above the surface; no crossing before it).
    if (step >= cap && t < r.t_end) {
        float th = pyramid_first_hit_from(ray, t, 1.0, pyramid_levels() - 1, iterations);
        return th < 0.0 ? miss(ray, iterations) : hit_at_t(ray, th, iterations);
    }
    // The ray's end: at t = 1 (h = 0 <= H) it always hits; a clamp-addressed ray that
    // leaves the decal has no hit.
    if (t >= 1.0) {
        return hit_at(ray, 0.0, iterations);
    }
    return miss(ray, iterations);
}
