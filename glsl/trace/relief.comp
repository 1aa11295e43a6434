#version 460
// relief: relief mapping (Policarpo, Oliveira & Comba 2005). The linear march of
// `linear`, then `refine_steps` bisection steps between the last sample above the
// surface and the first one below it; the hit is the midpoint of the final interval
// (relief_search in search.glsl, shared with DIG's unconstrained search and the forward
// path).
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    return relief_search(ray, pc.steps, pc.refine_steps, iterations);
}
