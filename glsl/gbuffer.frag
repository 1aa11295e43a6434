#version 460
// G-buffer pass, fragment stage: writes the tangent-space ray and the shading frame.
//   out_ray     rgba32f  (uv0.x, uv0.y, P.x, P.y): entry uv (reduced to [0,1) for repeat
//                        addressing, so rays keep full precision far from the origin) and
//                        the parallax vector P = depth_scale * V.xy / -V.z in UV units.
//   out_normal  rgba16f  world-space normal N (xyz), w = surface id (1: the one surface
//                        drawn; 0 = cleared, no geometry). See src/passes/gbuffer.rs.
//   out_tangent rgba16f  world-space tangent T = dP/du (xyz), w = handedness: B = w * cross(N, T).
// Back faces (viewer below the surface) are discarded: nothing to displace.
#include "gbuffer.glsl"

layout(location = 0) in vec3 v_world;
layout(location = 1) in vec2 v_uv;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_tangent;

// The id of the one surface this pass draws (DIG's same-surface test).
const float SURFACE_ID = 1.0;

void main() {
    // The quad lies on y = 0 with u along +x and v along +z.
    const vec3 N = vec3(0.0, 1.0, 0.0);
    const vec3 T = vec3(1.0, 0.0, 0.0);
    const vec3 B = vec3(0.0, 0.0, 1.0);
    vec3 V = normalize(v_world - pc.camera_pos.xyz);
    vec3 v_ts = vec3(dot(V, T), dot(V, B), dot(V, N));
    if (v_ts.z >= 0.0) {
        discard;
    }
    vec2 P = pc.depth_scale * v_ts.xy / max(-v_ts.z, pc.min_cos);
    vec2 uv0 = pc.addressing == ADDRESSING_REPEAT ? v_uv - floor(v_uv) : v_uv;
    out_ray = vec4(uv0, P);
    out_normal = vec4(N, SURFACE_ID);
    out_tangent = vec4(T, dot(cross(N, T), B) < 0.0 ? -1.0 : 1.0);
}
