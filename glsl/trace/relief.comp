#version 460
// relief: relief mapping (Policarpo, Oliveira & Comba 2005). The linear march of
// `linear`, then `refine_steps` bisection steps between the last sample above the
// surface and the first one below it; the hit is the midpoint of the final interval.
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint steps = max(pc.steps, 1u);
    uint iterations = 0u;
    uint below;
    if (!linear_march(ray, steps, below, iterations)) {
        return miss(ray, iterations);
    }
    if (below == 0u) {
        return hit_at(ray, 1.0, iterations);
    }
    float dh = 1.0 / float(steps);
    float h_below = 1.0 - float(below) * dh;
    float h = bisect(ray, h_below + dh, h_below, pc.refine_steps, iterations);
    return hit_at(ray, h, iterations);
}
