#version 460
// G-buffer pass for meshes, fragment stage: re-orthonormalises the interpolated tangent
// frame (Gram-Schmidt), encodes the ray with the shared include, then corrects P for the
// uv stretch so depth_scale is in units of the local uv scale sqrt(s_u s_v) (src/mesh.rs
// documents the choice): P.x *= sqrt(s_v / s_u), P.y *= sqrt(s_u / s_v).
// BEHIND variant: the behind layer (glsl/include/dispmap_behind.glsl): a fragment is kept
// only at a pixel whose first-layer trace missed, behind the first layer's surface.
// CURVE variant: also writes the curve target (location 2, dispmap_gbuffer_curve), for a
// frame with materials traced curved; with CURVE_COMPUTED false (a draw whose material is
// not traced curved, where nothing reads it) it writes 0 there without computing it.
// dispmap-variant: BEHIND
// dispmap-variant: CURVE
// dispmap-variant: BEHIND+CURVE
#include "gbuffer_params.glsl"
#include "include/dispmap_gbuffer.glsl"
#ifdef BEHIND
#include "include/dispmap_behind.glsl"
// The first layer's G-buffer depth and hit height.
layout(set = 0, binding = 1) uniform sampler2D u_first_depth;
layout(set = 0, binding = 2, r32f) uniform readonly image2D u_first_hit_height;
#endif

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;
layout(location = 2) in vec3 v_normal;
layout(location = 3) in vec4 v_tangent;
layout(location = 4) in float v_stretch;
layout(location = 5) flat in float v_surface;
#ifdef CURVE
layout(location = 6) in float v_scale;
#endif

// A two-sided mesh (src/mesh.rs Mesh::two_sided, GBufferPass::new_mesh_two_sided): a
// fragment on the side the mesh's normals point away from is displaced as seen from that
// side (dispmap_surface_back_side) instead of discarded. The side is the triangle's own
// plane (from the derivatives of the eye-relative position, oriented by the interpolated
// normal), not the winding, so it holds for any index order.
layout(constant_id = 0) const bool TWO_SIDED = false;
// Whether the CURVE variant computes the curve output (src/passes/gbuffer.rs: the
// pipeline of the draws whose material is traced curved) or writes 0.
layout(constant_id = 1) const bool CURVE_COMPUTED = true;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;
#ifdef CURVE
layout(location = 2) out vec2 out_curve;
#endif

void main() {
#ifdef CURVE
    // Before any discard: derivatives need the whole quad.
    DispmapCurveInputs curve;
    if (CURVE_COMPUTED) {
        curve = dispmap_curve_inputs(v_uv, v_normal, v_scale);
    }
    out_curve = vec2(0.0);
#endif
#ifdef BEHIND
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    // A one-sided mesh's triangles that face away from the eye (its far side seen from
    // inside, glsl/include/dispmap_behind.glsl's dispmap_behind_faces_eye) never get here:
    // the rasteriser culls them (GBufferPass, Mesh::with_front_winding).
    if (!dispmap_behind_keep(imageLoad(u_first_hit_height, pixel).x,
                             texelFetch(u_first_depth, pixel, 0).r, gl_FragCoord.z)) {
        discard;
    }
#endif
    vec3 N = normalize(v_normal);
    vec3 T = v_tangent.xyz - N * dot(N, v_tangent.xyz);
    float tl = length(T);
    // A degenerate interpolated tangent (opposite tangents across a vertex): any T.
    T = tl > 1e-6 ? T / tl : normalize(abs(N.x) < 0.9 ? cross(N, vec3(1, 0, 0)) : cross(N, vec3(0, 1, 0)));
    float w = v_tangent.w < 0.0 ? -1.0 : 1.0;
    vec3 B = w * cross(N, T);
    DispmapSurface s = DispmapSurface(v_eye_rel, vec3(0.0), v_uv, N, T, B, v_surface,
        pc.depth_scale, pc.min_cos, pc.addressing);
    if (TWO_SIDED) {
        vec3 face = cross(dFdx(v_eye_rel), dFdy(v_eye_rel));
        face = dot(face, N) < 0.0 ? -face : face;
        if (dot(face, v_eye_rel) > 0.0) {
            s = dispmap_surface_back_side(s);
        }
    }
    // camera_pos.w: the drawn object's material index + 1, or 0 for an object that is
    // not displaced (src/abi.rs GBufferParams; 1 = material 0 for a single object).
    uint material_plus_one = uint(pc.camera_pos.w);
    if (!dispmap_gbuffer_encode_material(s, max(material_plus_one, 1u) - 1u, out_ray, out_frame)) {
        discard;
    }
    if (material_plus_one == 0u) {
        dispmap_gbuffer_encode_flat(s.normal, s.tangent, v_surface, out_ray, out_frame);
    }
    float stretch = clamp(v_stretch, 1.0 / 64.0, 64.0);
    out_ray.zw *= vec2(inversesqrt(stretch), sqrt(stretch));
#ifdef CURVE
    if (CURVE_COMPUTED && material_plus_one != 0u) {
        out_curve = dispmap_gbuffer_curve(s, curve, out_ray.zw);
    }
#endif
}
