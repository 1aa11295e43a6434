// The trace pass: everything a method shares. A method file defines
//     Hit trace_ray(Ray ray);
// after including this file; `main` below reads the G-buffer, calls it and writes the
// hit buffer. Bindings and push constants mirror src/passes/trace.rs and src/abi.rs.
#ifndef DISPMAP_TRACE_GLSL
#define DISPMAP_TRACE_GLSL

#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// G-buffer: rgba32f (uv0.x, uv0.y, P.x, P.y); depth (reverse-Z: 0 = no geometry).
layout(set = 0, binding = 0) uniform sampler2D u_ray;
layout(set = 0, binding = 1) uniform sampler2D u_depth;
// The height field (linear filtering, the map's addressing).
layout(set = 0, binding = 2) uniform sampler2D u_height;
// The hit buffer.
layout(set = 0, binding = 3, rgba32f) uniform writeonly image2D u_hit;

layout(push_constant) uniform TraceParams {
    uvec2 frame_size;   // pixels
    uvec2 map_size;     // texels
    uint steps;         // linear steps over the full depth
    uint refine_steps;  // binary-search steps after the linear march
    uint addressing;    // ADDRESSING_*
    uint flags;         // reserved, 0
} pc;

#include "heightfield.glsl"

// The tangent-space ray: uv(h) = uv0 + (1 - h) * P, h from 1 (entry) down to 0.
struct Ray {
    vec2 uv0;
    vec2 P;
};

struct Hit {
    vec2 uv;
    float h;           // NO_HIT_HEIGHT for a miss
    uint iterations;   // height-field fetches spent
};

vec2 ray_uv(Ray ray, float h) {
    return ray.uv0 + (1.0 - h) * ray.P;
}

// True when a clamp-addressed ray has left the decal at uv (the silhouette).
bool leaves_domain(vec2 uv) {
    return pc.addressing == ADDRESSING_CLAMP && (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))));
}

Hit hit_at(Ray ray, float h, uint iterations) {
    return Hit(ray_uv(ray, h), h, iterations);
}

Hit miss(Ray ray, uint iterations) {
    return Hit(ray.uv0, NO_HIT_HEIGHT, iterations);
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

Hit trace_ray(Ray ray);

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(pixel), pc.frame_size))) {
        return;
    }
    if (texelFetch(u_depth, pixel, 0).r <= 0.0) {
        imageStore(u_hit, pixel, vec4(0.0, 0.0, NO_HIT_HEIGHT, 0.0));
        return;
    }
    vec4 g = texelFetch(u_ray, pixel, 0);
    Hit hit = trace_ray(Ray(g.xy, g.zw));
    imageStore(u_hit, pixel, vec4(hit.uv, hit.h, float(hit.iterations)));
}

#endif
