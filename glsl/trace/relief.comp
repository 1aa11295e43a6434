#version 460
// relief: relief mapping (Policarpo, Oliveira & Comba 2005). The linear march of
// `linear`, then `refine_steps` bisection steps between the last sample above the
// surface and the first one below it; the hit is the midpoint of the final interval
// (relief_search in search.glsl, shared with DIG's unconstrained search and the forward
// path). On curved meshes (TRACE_FLAG_CURVED) the same march along the curved ray
// (curved_march in curved.glsl).
// dispmap-variant: ITERATIONS
// dispmap-variant: CURVED
// dispmap-variant: CURVED+ITERATIONS
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    if (CURVED_VARIANT && g_curve.k != 0.0) {
        return curved_march(ray, g_curve, pc.steps, pc.refine_steps, false);
    }
    uint iterations = 0u;
    return relief_search(ray, pc.steps, pc.refine_steps, iterations);
}
