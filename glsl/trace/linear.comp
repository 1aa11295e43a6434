#version 460
// linear: steep parallax mapping (McGuire & McGuire 2005). `steps` equal steps in
// height from the entry point, early exit at the first sample on or below the surface;
// the hit is that sample (no refinement), so the error is up to one step.
// dispmap-variant: ITERATIONS
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    uint below;
    if (!linear_march(ray, max(pc.steps, 1u), below, iterations)) {
        return miss(ray, iterations);
    }
    return hit_at(ray, 1.0 - float(below) / float(max(pc.steps, 1u)), iterations);
}
