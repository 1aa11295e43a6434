// The forward path's fragment stage: relief mapping or POM evaluated inside the G-buffer
// pass, as engines do (Bevy, Godot, Unity, Unreal run the marcher in the fragment shader
// that writes their G-buffer). One invocation encodes the fragment exactly as
// glsl/gbuffer.frag does (the same include) and marches its ray at once: it writes the hit
// (the hit images: uv, height, and the iteration count) where the deferred G-buffer
// writes the ray, and the frame the shading reads. A method file
// defines
//     Hit trace_ray(Ray ray);
// after including this file (glsl/forward/relief.frag, glsl/forward/pom.frag). Bindings
// and the parameter block: src/passes/forward.rs and src/abi.rs (ForwardParams).
//
// The marchers are the compute trace's (glsl/common/search.glsl: relief_search,
// pom_search) with the step counts from ForwardParams instead of TraceParams, on the same
// march (glsl/common/march.glsl) and sampling (glsl/common/heightfield.glsl):
// tests/forward.rs checks that the hits agree bit for bit.
#ifndef DISPMAP_FORWARD_GLSL
#define DISPMAP_FORWARD_GLSL

#include "gbuffer_params.glsl"
#include "../include/dispmap_plane.glsl"
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

// The frame's pixel rays (glsl/gbuffer.frag's, src/abi.rs PixelRayParams).
layout(set = 0, binding = 2, std140) uniform PixelRayBlock {
    DispmapPixelRay u_pixel_ray;
};

#include "march.glsl"

layout(location = 0) out vec2 out_hit_uv;
layout(location = 1) out uvec2 out_frame;
layout(location = 2) out float out_hit_height;
layout(location = 3) out uint out_iterations;

// The id of the one surface this pass draws (glsl/gbuffer.frag's).
const float SURFACE_ID = 1.0;

#include "search.glsl"

Hit trace_ray(Ray ray);

void main() {
    // glsl/gbuffer.frag's entry (the pixel's own centre ray) and encoding: the quad lies on
    // y = 0 with u along +x and v along +z.
    vec3 eye_rel;
    vec2 uv;
    float t;
    if (!dispmap_plane_pixel_ray(u_pixel_ray, gl_FragCoord.xy, pc.world_rect, pc.uv_rect,
                                 pc.addressing == DISPMAP_ADDRESSING_REPEAT, eye_rel, uv, t)) {
        discard;
    }
    gl_FragDepth = dispmap_plane_pixel_depth(pc.view_proj, eye_rel);
    DispmapSurface s = DispmapSurface(eye_rel, vec3(0.0), uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), SURFACE_ID, pc.depth_scale, pc.min_cos,
        pc.addressing);
    uint material_plus_one = uint(pc.camera_pos.w);
    vec4 ray;
    if (!dispmap_gbuffer_encode_material(s, max(material_plus_one, 1u) - 1u, ray, out_frame)) {
        discard;
    }
    if (material_plus_one == 0u) {
        // Not displaced: what the classification pass writes for such a pixel.
        dispmap_gbuffer_encode_flat(s.normal, s.tangent, SURFACE_ID, ray, out_frame);
        out_hit_uv = vec2(0.0);
        out_hit_height = NOT_DISPLACED_HEIGHT;
        out_iterations = 0u;
        return;
    }
    Hit hit = trace_ray(Ray(ray.xy, ray.zw));
    out_hit_uv = hit.uv;
    out_hit_height = hit.h;
    out_iterations = hit.iterations;
}

#endif
