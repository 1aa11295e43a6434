// The trace pass: everything a method shares. A method file defines
//     Hit trace_ray(Ray ray, ivec2 pixel);
// after including this file; `main` below reads the G-buffer, calls it and writes the
// hit buffer. Bindings and push constants mirror src/passes/trace.rs and src/abi.rs.
// Methods that read more (the pyramid, the DIG corner grid) declare those bindings in
// their own includes (pyramid.glsl, dig.glsl).
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
    uint steps;         // linear steps over the full depth (the quality)
    uint refine_steps;  // binary-search steps after the linear march
    uint addressing;    // ADDRESSING_*
    uint flags;         // TRACE_FLAG_*
    uint min_steps;     // pom: n_min
    uint segments;      // secant: segments of the ray
    uvec2 block;        // dig: block size in pixels
    uvec2 corner_size;  // dig: corner-grid size
    float eps;          // dig: eps1 = eps2
    uint max_level;     // pyramid: coarsest traversal level
    uint pyramid_levels;// levels of the bound pyramid (0: none)
    float depth_scale;  // displacement depth in tile units
    uvec2 pad;
} pc;

// The pyramid method picks its coarsest level from the pixel's texel footprint.
#define TRACE_FLAG_AUTO_LEVEL 1u

#include "march.glsl"
#include "texels.glsl"

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

// Relief mapping: the linear march of `steps` equal height steps from the entry, then
// `refine_steps` bisections (hardware filter); `relief` and DIG's unconstrained search.
Hit relief_search(Ray ray, inout uint iterations) {
    uint steps = max(pc.steps, 1u);
    uint below;
    if (!linear_march(ray, steps, below, iterations)) {
        return miss(ray, iterations);
    }
    if (below == 0u) {
        return hit_at(ray, 1.0, iterations);
    }
    float dh = 1.0 / float(steps);
    float h_below = 1.0 - float(below) * dh;
    return hit_at(ray, bisect(ray, h_below + dh, h_below, pc.refine_steps, iterations), iterations);
}

Hit trace_ray(Ray ray, ivec2 pixel);

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
    Hit hit = trace_ray(Ray(g.xy, g.zw), pixel);
    imageStore(u_hit, pixel, vec4(hit.uv, hit.h, float(hit.iterations)));
}

#endif
