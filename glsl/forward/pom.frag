#version 460
// Forward parallax occlusion mapping: glsl/trace/pom.comp's march inside the G-buffer pass
// (glsl/forward/forward.glsl), with n_max and n_min from ForwardParams.
#include "forward.glsl"

Hit trace_ray(Ray ray) {
    return pom_search(ray, u_march.steps, u_march.min_steps, pc.depth_scale);
}
