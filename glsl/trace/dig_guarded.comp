#version 460
// dig-guarded (beyond the papers): DIG whose search is checked against the cell-max
// pyramid, so that no feature is stepped over. Plain DIG misses hits in two places:
//  * before its interval: the corners sample the surface only along the block's corner
//    rays, so a thin feature between them can rise above the interval's top along this
//    pixel's ray;
//  * inside it: a linear step at a grazing angle spans many texels, and a ridge between
//    two samples is skipped (relief mapping's failure too).
// The guard closes both with the conservative traversal of glsl/common/pyramid.glsl:
//  1. Before the interval, t in [0, 1 - h_top]: the traversal proves that no cell can
//     reach the ray (usually cheap: the ray is high above most nodes, which are skipped
//     at coarse levels), or returns the exact hit it finds there.
//  2. From the interval's top on, the traversal continues, started at the level whose
//     nodes are as wide as the interval's horizontal extent (it climbs when the ray
//     leaves them), and intersects the leaf cells exactly.
// Blocks whose corners are not on the pixel's surface run the traversal from the root.
//
// Every answer is the exact first intersection (up to f32, as `exact`); the interval
// only decides where the traversal restarts close to the surface. A variant that kept
// DIG's linear steps inside the interval and cleared each step with the pyramid nodes
// as wide as the step (intersecting exactly only the steps not cleared) was measured on
// issue 3's scenes: the same answers with about 1.9x the fetches, so the traversal
// replaces the steps. Measured (README): its fetches are `exact`'s plus the restart.
// dispmap-variant: ITERATIONS
#include "trace.glsl"
#include "pyramid.glsl"
#include "dig.glsl"

Hit exact_hit(Ray ray, float t, uint iterations) {
    return t < 0.0 ? miss(ray, iterations) : hit_at_t(ray, t, iterations);
}

// Blocks without a valid interval take the full traversal from the root; it is the same
// loop as the constrained pixels' second traversal (from t = 0 at the root level instead
// of from the interval's top at its level), so a SIMD group mixing both kinds runs it
// once, not a fallback traversal and then the constrained one.
Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    float h_bottom, h_top;
    bool constrained = dig_interval(pixel, h_bottom, h_top);
    float t_top = 1.0 - h_top;
    if (constrained && t_top > 0.0) {
        float t = pyramid_first_hit(ray, 0.0, t_top, iterations);
        if (t >= 0.0) {
            return hit_at_t(ray, t, iterations);
        }
    }
    int level = pyramid_levels() - 1;
    if (constrained) {
        vec2 origin, dir;
        texel_ray(ray, origin, dir);
        level = level_for_span(max(abs(dir.x), abs(dir.y)) * (h_top - h_bottom));
    } else {
        t_top = 0.0;
    }
    return exact_hit(ray, pyramid_first_hit_from(ray, t_top, 1.0, level, iterations), iterations);
}
