#version 460
// G-buffer pass for meshes (cube, sphere, torus, loaded meshes), vertex stage: reads the
// vertex buffer (src/mesh.rs Vertex), positions already in world space.
// CURVE variant: also passes the local uv scale on (the fragment stage's CURVE variant
// reads it).
// dispmap-variant: CURVE
#include "gbuffer_params.glsl"

layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_tangent;
layout(location = 3) in vec2 a_uv;
layout(location = 4) in float a_stretch;
layout(location = 5) in float a_surface;
#ifdef CURVE
layout(location = 6) in float a_scale;
#endif

layout(location = 0) out vec3 v_eye_rel; // position relative to the eye (precision, as gbuffer.vert)
layout(location = 1) out vec2 v_uv;
layout(location = 2) out vec3 v_normal;
layout(location = 3) out vec4 v_tangent;
layout(location = 4) out float v_stretch;
layout(location = 5) flat out float v_surface;
#ifdef CURVE
layout(location = 6) out float v_scale; // the local uv scale (the curve output's depth change)
#endif

void main() {
    v_eye_rel = a_position - pc.camera_pos.xyz;
    v_uv = a_uv;
    v_normal = a_normal;
    v_tangent = a_tangent;
    v_stretch = a_stretch;
    v_surface = a_surface;
#ifdef CURVE
    v_scale = a_scale;
#endif
    gl_Position = pc.view_proj * vec4(v_eye_rel, 1.0);
}
