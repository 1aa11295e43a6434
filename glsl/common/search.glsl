// The hit record and the marchers' searches, shared by the compute trace
// (glsl/common/trace.glsl) and the forward path's fragment stage
// (glsl/forward/forward.glsl): each passes its own step counts (TraceParams or
// ForwardParams), so both run the same arithmetic on the same rays. Needs march.glsl
// (Ray, ray_uv, leaves_domain, linear_march) and height_at included before it.
#ifndef DISPMAP_SEARCH_GLSL
#define DISPMAP_SEARCH_GLSL

struct Hit {
    vec2 uv;
    float h;           // NO_HIT_HEIGHT for a miss
    uint iterations;   // height-field (or pyramid) fetches spent
};

Hit hit_at(Ray ray, float h, uint iterations) {
    return Hit(ray_uv(ray, h), h, iterations);
}

Hit miss(Ray ray, uint iterations) {
    return Hit(ray.uv0, NO_HIT_HEIGHT, iterations);
}

// Bisection between a height above the surface and one on or below it: `steps` halvings
// (one hardware-filtered fetch each); returns the midpoint of the final interval.
float bisect(Ray ray, float h_above, float h_below, uint steps, inout uint iterations) {
    for (uint i = 0u; i < steps; ++i) {
        float h_mid = 0.5 * (h_above + h_below);
        iterations += 1u;
        if (height_at(ray_uv(ray, h_mid)) >= h_mid) {
            h_below = h_mid;
        } else {
            h_above = h_mid;
        }
    }
    return 0.5 * (h_above + h_below);
}

// Relief mapping: the linear march of `linear_steps` equal height steps from the entry,
// then `refine_steps` bisections (hardware filter); `relief` and DIG's unconstrained search.
Hit relief_search(Ray ray, uint linear_steps, uint refine_steps, inout uint iterations) {
    uint steps = max(linear_steps, 1u);
    uint below;
    if (!linear_march(ray, steps, below, iterations)) {
        return miss(ray, iterations);
    }
    if (below == 0u) {
        return hit_at(ray, 1.0, iterations);
    }
    float dh = 1.0 / float(steps);
    float h_below = 1.0 - float(below) * dh;
    return hit_at(ray, bisect(ray, h_below + dh, h_below, refine_steps, iterations), iterations);
}

// Parallax occlusion mapping (Tatarchuk 2006, section 5; glsl/trace/pom.comp documents
// the steps). The sample count from the view angle: n = n_max + (n_min - n_max) *
// dot(N, V), with dot(N, V) = 1 / sqrt(1 + |P / depth_scale|^2) recovered from the
// parallax vector (depth_scale = 0, a flat map: n_min).
uint pom_sample_count(Ray ray, uint max_steps, uint min_steps, float depth_scale) {
    float n_max = float(max(max_steps, 1u));
    float n_min = float(clamp(min_steps, 1u, max(max_steps, 1u)));
    float tan_theta = depth_scale > 0.0 ? length(ray.P) / depth_scale : 0.0;
    float n_dot_v = inversesqrt(1.0 + min(tan_theta * tan_theta, 1e30));
    return uint(clamp(round(n_max + (n_min - n_max) * n_dot_v), n_min, n_max));
}

// POM's march: n equal height steps with early exit, the hit on the line through the
// last two samples.
Hit pom_search(Ray ray, uint max_steps, uint min_steps, float depth_scale) {
    uint n = pom_sample_count(ray, max_steps, min_steps, depth_scale);
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

#endif
