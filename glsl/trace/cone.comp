#version 460
// cone: robust cone step mapping (Dummer 2006; the conservative minimum step and the
// bilinear-correct cone map of Ban, Valasek, Balint & Vad 2024): cone steps
// (glsl/common/cone.glsl) until the ray is at or below its cell's maximum; there the
// bilinear height is sampled every 1 / steps of the depth up to the cell's exit; the
// first sample on or below the surface ends the march and `refine_steps` bisections
// between it and the last point above refine the hit. Thin features inside a cell's band
// can be stepped over (the error the marchers have); the cones themselves never skip.
//
// RELAXED (`relaxed-cone`, relaxed cone stepping after Policarpo & Oliveira 2007, over
// the relaxed cone map of glsl/cone.comp): a cone step may end inside the surface, having
// crossed it once; the height at the step's end tells, and the bisection then runs over
// the whole step.
// dispmap-variant: RELAXED
// dispmap-variant: ITERATIONS
// dispmap-variant: RELAXED+ITERATIONS
#include "trace.glsl"
#include "pyramid.glsl"
#ifdef RELAXED
#define CONE_RELAXED 1
#endif
#include "cone.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    ConeRay r;
    if (!cone_start(ray, r)) {
        return miss(ray, iterations);
    }
    float dt = 1.0 / float(max(pc.steps, 1u));
    float t = r.t_start, t_above = r.t_start;
    float step = 0.0;
    float cap = CONE_BUDGET;
    bool below = false;
    while (step < cap) {
        float t_exit;
        vec2 exit;
        if (!cone_advance(r, t, t_exit, exit, t_above, step, cap, iterations)) {
            break;
        }
        // The band: samples from t to the cell's exit.
        for (; step < cap; step += 1.0) {
            iterations += 1u;
            if (cone_height(r, t) >= 1.0 - t) {
                below = true;
                break;
            }
            if (t >= t_exit) {
                break;
            }
            t_above = t;
            t = min(t + dt, t_exit);
        }
        if (below || t_exit >= r.t_end) {
            break;
        }
        cone_move(r, exit, t_exit, t_exit);
        t = t_exit;
        step += 1.0;
    }
    if (!below) {
        // Out of cone steps before the ray's end: the exact pyramid traversal from the
        // point reached (above the surface), as cone-exact does.
        if (step >= cap && t < r.t_end) {
            float th = pyramid_first_hit_from(ray, t, 1.0, pyramid_levels() - 1, iterations);
            return th < 0.0 ? miss(ray, iterations) : hit_at(ray, 1.0 - th, iterations);
        }
        if (t >= 1.0) {
            return hit_at(ray, 0.0, iterations);
        }
        return miss(ray, iterations);
    }
    // Bisection between t_above (above the surface) and t (on or below it).
    float lo = t_above, hi = t;
    for (uint i = 0u; i < pc.refine_steps; ++i) {
        float mid = 0.5 * (lo + hi);
        iterations += 1u;
        if (cone_height(r, mid) >= 1.0 - mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    return hit_at(ray, 1.0 - 0.5 * (lo + hi), iterations);
}
