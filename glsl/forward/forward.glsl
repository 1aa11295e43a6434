// The forward path's fragment stage: relief mapping or POM evaluated inside the G-buffer
// pass, as engines do (Bevy, Godot, Unity, Unreal run the marcher in the fragment shader
// that writes their G-buffer). One invocation encodes the fragment exactly as
// glsl/gbuffer.frag does (the same include) and marches its ray at once: it writes the hit
// (the hit buffer's channels: hit u, hit v, hit height, iterations) where the deferred
// G-buffer writes the ray, and the normal and tangent the shading reads. A method file
// defines
//     Hit trace_ray(Ray ray);
// after including this file (glsl/forward/relief.frag, glsl/forward/pom.frag). Bindings
// and the parameter block: src/passes/forward.rs and src/abi.rs (ForwardParams).
//
// The marchers below are the compute trace's (glsl/common/trace.glsl: bisect,
// relief_search; glsl/trace/pom.comp) with the step counts read from ForwardParams
// instead of TraceParams, on the same shared march (glsl/common/march.glsl) and sampling
// (glsl/common/heightfield.glsl): tests/forward.rs checks that the hits agree bit for bit.
#ifndef DISPMAP_FORWARD_GLSL
#define DISPMAP_FORWARD_GLSL

#include "gbuffer.glsl"
#include "../include/dispmap_gbuffer.glsl"

// The height field (linear filtering, the map's addressing).
layout(set = 0, binding = 0) uniform sampler2D u_height;

// The method's step counts (a uniform buffer: the G-buffer's push constants already take
// the 128 bytes every device guarantees).
layout(set = 0, binding = 1, std140) uniform ForwardParams {
    uint steps;         // linear steps over the full depth (pom: n_max)
    uint refine_steps;  // relief: binary-search steps after the linear march
    uint min_steps;     // pom: n_min
    uint pad;
} u_march;

#include "march.glsl"

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;

layout(location = 0) out vec4 out_hit;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_tangent;

// The id of the one surface this pass draws (glsl/gbuffer.frag's).
const float SURFACE_ID = 1.0;

struct Hit {
    vec2 uv;
    float h;           // NO_HIT_HEIGHT for a miss
    uint iterations;   // height-field fetches spent
};

Hit hit_at(Ray ray, float h, uint iterations) {
    return Hit(ray_uv(ray, h), h, iterations);
}

Hit miss(Ray ray, uint iterations) {
    return Hit(ray.uv0, NO_HIT_HEIGHT, iterations);
}

// trace.glsl's bisect: `steps` halvings between a height above the surface and one on or
// below it; the midpoint of the final interval.
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

// trace.glsl's relief_search: the linear march, then the bisection.
Hit relief_search(Ray ray, inout uint iterations) {
    uint steps = max(u_march.steps, 1u);
    uint below;
    if (!linear_march(ray, steps, below, iterations)) {
        return miss(ray, iterations);
    }
    if (below == 0u) {
        return hit_at(ray, 1.0, iterations);
    }
    float dh = 1.0 / float(steps);
    float h_below = 1.0 - float(below) * dh;
    return hit_at(ray, bisect(ray, h_below + dh, h_below, u_march.refine_steps, iterations), iterations);
}

Hit trace_ray(Ray ray);

void main() {
    // glsl/gbuffer.frag's encoding: the quad lies on y = 0 with u along +x and v along +z.
    DispmapSurface s = DispmapSurface(v_eye_rel, vec3(0.0), v_uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), SURFACE_ID, pc.depth_scale, pc.min_cos,
        pc.addressing);
    uint material_plus_one = uint(pc.camera_pos.w);
    vec4 ray;
    if (!dispmap_gbuffer_encode_material(s, max(material_plus_one, 1u) - 1u, ray, out_normal,
                                         out_tangent)) {
        discard;
    }
    if (material_plus_one == 0u) {
        // Not displaced: what the classification pass writes for such a pixel.
        dispmap_gbuffer_encode_flat(s.normal, s.tangent, SURFACE_ID, ray, out_normal, out_tangent);
        out_hit = vec4(0.0, 0.0, NOT_DISPLACED_HEIGHT, 0.0);
        return;
    }
    Hit hit = trace_ray(Ray(ray.xy, ray.zw));
    out_hit = vec4(hit.uv, hit.h, float(hit.iterations));
}

#endif
