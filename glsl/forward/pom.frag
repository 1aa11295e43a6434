#version 460
// Forward parallax occlusion mapping: glsl/trace/pom.comp's march (its comments say what
// each step follows in Tatarchuk 2006) inside the G-buffer pass
// (glsl/forward/forward.glsl), with n_max and n_min from ForwardParams.
#include "forward.glsl"

uint pom_sample_count(Ray ray) {
    float n_max = float(max(u_march.steps, 1u));
    float n_min = float(clamp(u_march.min_steps, 1u, max(u_march.steps, 1u)));
    float tan_theta = pc.depth_scale > 0.0 ? length(ray.P) / pc.depth_scale : 0.0;
    float n_dot_v = inversesqrt(1.0 + min(tan_theta * tan_theta, 1e30));
    return uint(clamp(round(n_max + (n_min - n_max) * n_dot_v), n_min, n_max));
}

Hit trace_ray(Ray ray) {
    uint n = pom_sample_count(ray);
    float dh = 1.0 / float(n);
    uint iterations = 0u;
    float h_prev = 1.0;
    float above_prev = 0.0;
    for (uint i = 0u; i <= n; ++i) {
        float h = 1.0 - float(i) * dh;
        vec2 uv = ray_uv(ray, h);
        if (leaves_domain(uv)) {
            return miss(ray, iterations);
        }
        iterations += 1u;
        float surface = height_at(uv);
        if (surface >= h) {
            if (i == 0u) {
                return hit_at(ray, 1.0, iterations);
            }
            float below = surface - h;
            float w = above_prev / (above_prev + below);
            return hit_at(ray, mix(h_prev, h, w), iterations);
        }
        h_prev = h;
        above_prev = h - surface;
    }
    return hit_at(ray, 0.0, iterations);
}
