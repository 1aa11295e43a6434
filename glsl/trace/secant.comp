#version 460
// secant: displacement mapping with ray casting (Yerex & Jagersand 2004).
// The ray between the macro surface (h = 1) and the maximum depth (h = 0) is sampled at
// N = `steps` evenly spaced points (default 15), including both ends. The paper's
// hardware had a budget of texture *indirections*, so every sample is taken (none of
// their positions depends on an earlier fetch: no early exit); the interval between the
// first sample on or below the surface, j, and its neighbour j - 1 holds the hit, and the
// surface there is approximated by the secant line through d_{j-1} and d_j: the hit is
// that line's intersection with the ray.
// Multi-pass variant (`segments` = K > 1): the paper's passes each process one portion
// of the ray, nearest first; pass k samples [1 - k/K, 1 - (k+1)/K] with N points, and
// the first pass with a crossing gives the hit (later passes would be depth-tested away,
// so they are not run). N = 1 is taken as N = 2 (a segment needs both its ends).
// dispmap-variant: ITERATIONS
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint n = max(pc.steps, 2u);
    uint k_count = max(pc.segments, 1u);
    float seg_len = 1.0 / float(k_count);
    uint iterations = 0u;
    for (uint k = 0u; k < k_count; ++k) {
        float h_start = 1.0 - float(k) * seg_len;
        float dh = seg_len / float(n - 1u);
        // First crossing in this segment: j and the differences at j - 1 and j.
        int j = -1;
        float above_prev = 0.0, below_j = 0.0;
        float above = 0.0;
        bool left = false;
        for (uint i = 0u; i < n; ++i) {
            float h = h_start - float(i) * dh;
            vec2 uv = ray_uv(ray, h);
            if (leaves_domain(uv)) {
                left = true;
                break;
            }
            iterations += 1u;
            float d = height_at(uv) - h; // >= 0: on or below the surface
            if (j < 0) {
                if (d >= 0.0) {
                    j = int(i);
                    below_j = d;
                    above_prev = above;
                } else {
                    above = -d;
                }
            }
        }
        if (j == 0) {
            // The segment starts on the surface: the crossing is at its start (the
            // previous segment's last sample was above, so it lies within rounding).
            return hit_at(ray, h_start, iterations);
        }
        if (j > 0) {
            float h_j = h_start - float(j) * dh;
            float w = above_prev / (above_prev + below_j);
            return hit_at(ray, mix(h_j + dh, h_j, w), iterations);
        }
        if (left) {
            return miss(ray, iterations);
        }
    }
    // Unreachable: the last segment ends at h = 0, where every height is on or above
    // the ray.
    return hit_at(ray, 0.0, iterations);
}
