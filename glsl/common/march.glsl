// The tangent-space ray and the fixed-step march shared by the trace methods and the DIG
// corner pass. Requires `u_height` (see heightfield.glsl) and a push-constant block `pc`
// with an `addressing` member to be declared before inclusion.
#ifndef DISPMAP_MARCH_GLSL
#define DISPMAP_MARCH_GLSL

#include "heightfield.glsl"

// The tangent-space ray: uv(h) = uv0 + (1 - h) * P, h from 1 (entry) down to 0.
struct Ray {
    vec2 uv0;
    vec2 P;
};

vec2 ray_uv(Ray ray, float h) {
    return ray.uv0 + (1.0 - h) * ray.P;
}

// True when a clamp-addressed ray has left the decal at uv (the silhouette).
bool leaves_domain(vec2 uv) {
    return pc.addressing == ADDRESSING_CLAMP && (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))));
}

// Fixed-step march from h = 1 down to h = 0 in `steps` equal steps, stopping at the
// first sample on or below the surface (H >= h). Returns the index of that sample
// (0 = the entry point) in `below`, or false when a clamp ray leaves the domain first.
// Every sample is one height fetch, counted in `iterations`.
bool linear_march(Ray ray, uint steps, out uint below, inout uint iterations) {
    float dh = 1.0 / float(steps);
    for (uint i = 0u; i <= steps; ++i) {
        float h = 1.0 - float(i) * dh;
        vec2 uv = ray_uv(ray, h);
        if (leaves_domain(uv)) {
            below = i;
            return false;
        }
        iterations += 1u;
        if (height_at(uv) >= h) {
            below = i;
            return true;
        }
    }
    // Unreachable: at h = 0 every height satisfies H >= 0.
    below = steps;
    return true;
}

#endif
