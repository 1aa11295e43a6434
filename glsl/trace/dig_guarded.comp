#version 460
// dig-guarded (beyond the papers): DIG whose interval start is checked against the cell-
// max pyramid. The corners only sample the surface at the block's corner rays, so a thin
// feature between them can rise above the interval's top along this pixel's ray, and DIG
// would step past it. The guard runs the conservative pyramid traversal
// (glsl/common/pyramid.glsl) over the part of the ray *before* the interval,
// h in [h_top, 1]: if no cell there can reach the ray (the usual case, and cheap: the
// ray is high above most nodes) the DIG refinement inside the interval is safe to use;
// if the traversal finds a hit there, that hit is exact and is returned.
// Blocks whose corners are not on the pixel's surface use the full pyramid traversal.
// The refinement inside the interval samples the exact bilinear surface (4 texel
// fetches, see dig.glsl), the surface the guard and the reference intersect.
#include "trace.glsl"
#include "pyramid.glsl"
#define DIG_EXACT true
#include "dig.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    float h_bottom, h_top;
    if (!dig_interval(pixel, h_bottom, h_top)) {
        float t = pyramid_first_hit(ray, 0.0, 1.0, iterations);
        return t < 0.0 ? miss(ray, iterations) : hit_at(ray, 1.0 - t, iterations);
    }
    if (h_top < 1.0) {
        float t = pyramid_first_hit(ray, 0.0, 1.0 - h_top, iterations);
        if (t >= 0.0) {
            return hit_at(ray, 1.0 - t, iterations);
        }
    }
    return dig_constrained(ray, h_bottom, h_top, iterations);
}
