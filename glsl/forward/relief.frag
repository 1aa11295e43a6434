#version 460
// Forward relief mapping: glsl/trace/relief.comp's search inside the G-buffer pass
// (glsl/forward/forward.glsl).
#include "forward.glsl"

Hit trace_ray(Ray ray) {
    uint iterations = 0u;
    return relief_search(ray, u_march.steps, u_march.refine_steps, iterations);
}
