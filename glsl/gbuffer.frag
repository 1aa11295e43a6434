#version 460
// G-buffer pass, fragment stage: writes the tangent-space ray and the shading frame with
// the same include a host engine uses (glsl/include/dispmap_gbuffer.glsl documents every
// channel). Back faces (viewer below the surface) are discarded: nothing to displace.
#include "gbuffer.glsl"
#include "include/dispmap_gbuffer.glsl"

layout(location = 0) in vec3 v_eye_rel;
layout(location = 1) in vec2 v_uv;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_tangent;

// The id of the one surface this pass draws (DIG's same-surface test).
const float SURFACE_ID = 1.0;

void main() {
    // The quad lies on y = 0 with u along +x and v along +z.
    DispmapSurface s = DispmapSurface(v_eye_rel, vec3(0.0), v_uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), SURFACE_ID, pc.depth_scale, pc.min_cos,
        pc.addressing);
    // camera_pos.w: the drawn object's material index + 1, or 0 for an object that is
    // not displaced (src/abi.rs GBufferParams; 1 = material 0 for a single object).
    uint material_plus_one = uint(pc.camera_pos.w);
    if (!dispmap_gbuffer_encode_material(s, max(material_plus_one, 1u) - 1u, out_ray, out_normal,
                                         out_tangent)) {
        discard;
    }
    if (material_plus_one == 0u) {
        dispmap_gbuffer_encode_flat(s.normal, s.tangent, SURFACE_ID, out_ray, out_normal, out_tangent);
    }
}
