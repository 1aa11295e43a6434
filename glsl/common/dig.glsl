// Constrained ray refinement of Depth Interval Grids (Judnich & Ling, section 5), shared
// by `dig` and `dig-guarded`. Include after trace.glsl. The corner grid is written by
// the dig_corners pass (glsl/dig_corners.comp: x = ray height of the last sample above
// the surface, y = surface id).
#ifndef DISPMAP_DIG_GLSL
#define DISPMAP_DIG_GLSL

layout(set = 0, binding = 5) uniform sampler2D u_corners;

// The interval [h_bottom, h_top] of the pixel's block (equation 1 in heights: the
// corners' min - eps2 and max + eps1, clamped to [0, 1]). False when the block's corners
// are not all on the pixel's surface (no geometry at a corner, another surface, a
// silhouette of a clamp-addressed decal): then the interval means nothing.
// The block index is the float quotient (exact: (p + 0.5) / block is never within
// rounding of an integer for frame coordinates), not an integer division, and the 4
// corners (b, b + 1 on each axis; b + 1 <= the grid's last corner) come from two
// gathers, one per channel, instead of 4 fetches: a per-pixel cost that lavapipe pays
// one lane at a time for `/` and per fetch for texelFetch.
bool dig_interval(ivec2 pixel, out float h_bottom, out float h_top) {
    float surface = gbuffer_surface(pixel);
    vec2 b = floor((vec2(pixel) + 0.5) / vec2(pc.block));
    vec2 at = (b + 1.0) / vec2(pc.corner_size);
    vec4 heights = textureGather(u_corners, at, 0);
    vec4 ids = textureGather(u_corners, at, 1);
    bool same = surface > 0.0 && all(equal(ids, vec4(surface)));
    float lo = min(1.0, min(min(heights.x, heights.y), min(heights.z, heights.w)));
    float hi = max(0.0, max(max(heights.x, heights.y), max(heights.z, heights.w)));
    h_bottom = clamp(lo - pc.eps, 0.0, 1.0);
    h_top = clamp(hi + pc.eps, 0.0, 1.0);
    return same;
}

// The height step of the linear search inside [h_bottom, h_top]: a fixed horizontal step
// s = 1 / steps (in UV units, section 8.2), I_L = floor(|R_xy| / s) steps over the
// interval (equation 2), R_xy the interval's horizontal extent. Choices where the paper
// is silent:
//  * I_L is at least the interval's length in height steps of 1 / steps: the step is
//    never coarser than relief's at the same quality (the benchmark gives every method
//    the same step size; when |P| < 1 UV the fixed horizontal step would be coarser).
//  * I_L is at most 4 times that: near the horizon |P| >> 1 UV and a fixed UV step would
//    need thousands of samples per pixel.
float dig_step(Ray ray, float h_bottom, float h_top) {
    float iter = float(max(pc.steps, 1u));
    float len = h_top - h_bottom;
    float s = 1.0 / iter;
    float r_xy = len * length(ray.P);
    float relief = max(ceil(len * iter), 1.0);
    float i_l = clamp(floor(r_xy / s), relief, 4.0 * relief);
    return len > 0.0 ? len / i_l : 1.0 / iter;
}

// The search of a pixel: with a valid interval (`constrained`), a linear search from
// h_top down with the step of dig_step, then I_B = `refine_steps` bisections between the
// last two samples (hardware filter, as the paper); without one, relief's unconstrained
// search (relief_search in search.glsl: `steps` equal steps from the entry, bisection).
//  * If the interval's top sample is already on or below the surface, the hit lies
//    above the interval (the corners missed a feature): relief's search runs, from the
//    entry (the top sample stays counted).
//  * If no sample of the interval reaches the surface, the hit lies below it: the march
//    continues below the interval with the same step down to h = 0 (where every height
//    is on or above the ray, so the loop always ends).
// One loop and one bisection serve both searches: each lane picks its start, step and
// end before the loop (the top sample decides), so a SIMD group whose lanes mix the two
// runs one loop as long as its slowest lane, not a DIG loop and a relief loop one after
// the other (CPU drivers such as lavapipe run every branch any lane takes, for all
// lanes). The samples, counts and hits are exactly those of the two searches run apart:
// relief's lanes sample `1 - k / steps` unclamped, stop at k = steps and bisect from one
// step above, as relief_search does; DIG's lanes sample max(h_top - k dh, 0) and bisect
// from the previous sample.
Hit dig_search(Ray ray, bool constrained, float h_bottom, float h_top, inout uint iterations) {
    float steps = float(max(pc.steps, 1u));
    bool relief = !constrained;
    float start = 1.0;
    float dh = 1.0 / steps;
    float k = 0.0;
    float k_last = steps;
    float h_prev = 1.0;
    if (constrained) {
        vec2 uv = ray_uv(ray, h_top);
        if (leaves_domain(uv)) {
            return miss(ray, iterations);
        }
        iterations += 1u;
        if (height_at(uv) >= h_top || h_top <= 0.0) {
            if (h_top >= 1.0) {
                return hit_at(ray, 1.0, iterations);
            }
            relief = true;
        } else {
            start = h_top;
            dh = dig_step(ray, h_bottom, h_top);
            k = 1.0;
            // DIG's march ends at h = 0 (every sample there is on or below the surface).
            k_last = 3.0e38;
            h_prev = h_top;
        }
    }
    float h;
    for (;; k += 1.0) {
        float raw = start - k * dh;
        h = relief ? raw : max(raw, 0.0);
        vec2 uv = ray_uv(ray, h);
        if (leaves_domain(uv)) {
            return miss(ray, iterations);
        }
        iterations += 1u;
        if (height_at(uv) >= h || h <= 0.0 || k >= k_last) {
            break;
        }
        h_prev = h;
    }
    if (relief && k == 0.0) {
        return hit_at(ray, 1.0, iterations);
    }
    float h_above = relief ? h + dh : h_prev;
    return hit_at(ray, bisect(ray, h_above, h, pc.refine_steps, iterations), iterations);
}

#endif
