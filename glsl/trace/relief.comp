#version 460
// relief: relief mapping (Policarpo, Oliveira & Comba 2005). The linear march of
// `linear`, then `refine_steps` bisection steps between the last sample above the
// surface and the first one below it; the hit is the midpoint of the final interval.
#include "trace.glsl"

Hit trace_ray(Ray ray) {
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
    float h_above = h_below + dh;
    for (uint i = 0u; i < pc.refine_steps; ++i) {
        float h_mid = 0.5 * (h_above + h_below);
        iterations += 1u;
        if (height_at(ray_uv(ray, h_mid)) >= h_mid) {
            h_below = h_mid;
        } else {
            h_above = h_mid;
        }
    }
    return hit_at(ray, 0.5 * (h_above + h_below), iterations);
}
