#version 460
// pom: parallax occlusion mapping (Tatarchuk 2006, "Dynamic parallax occlusion mapping
// with approximate soft shadows", section 5).
//   1. Sample count from the view angle: n = n_max + (n_min - n_max) * dot(N, V), with
//      the artist bounds n_max = `steps`, n_min = `min_steps` (clamped to n_max). Here
//      dot(N, V) = -V.z of the tangent-space view vector, recovered from the parallax
//      vector P = depth_scale * V.xy / -V.z as 1 / sqrt(1 + |P / depth_scale|^2), which
//      needs no extra G-buffer channel and is exact for the unclamped P.
//   2. A linear march in n equal height steps from the macro surface (h = 1) with early
//      exit at the first sample on or below the surface.
//   3. The hit is the intersection of the ray with the line through the last two height
//      samples (the paper's piecewise-linear approximation of the height profile).
// Not here: the soft shadows (shading) and the LOD blend to bump mapping (trace_lod in
// trace.glsl, shared by every method).
#include "trace.glsl"

uint pom_sample_count(Ray ray) {
    float n_max = float(max(pc.steps, 1u));
    float n_min = float(clamp(pc.min_steps, 1u, max(pc.steps, 1u)));
    // |P| / depth_scale = tan(theta); dot(N, V) = cos(theta). Guard depth_scale = 0
    // (a flat map: the view angle does not matter, take n_min).
    float tan_theta = pc.depth_scale > 0.0 ? length(ray.P) / pc.depth_scale : 0.0;
    float n_dot_v = inversesqrt(1.0 + min(tan_theta * tan_theta, 1e30));
    return uint(clamp(round(n_max + (n_min - n_max) * n_dot_v), n_min, n_max));
}

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint n = pom_sample_count(ray);
    float dh = 1.0 / float(n);
    uint iterations = 0u;
    float h_prev = 1.0;
    float above_prev = 0.0; // ray height - surface height at the previous sample (> 0)
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
            // Ray height minus surface height is linear between the two samples:
            // above_prev > 0 at h_prev, h - surface <= 0 at h. Its zero:
            float below = surface - h;
            float w = above_prev / (above_prev + below);
            return hit_at(ray, mix(h_prev, h, w), iterations);
        }
        h_prev = h;
        above_prev = h - surface;
    }
    // Unreachable: at h = 0 every height is on or above the ray.
    return hit_at(ray, 0.0, iterations);
}
