#version 460
// G-buffer pass, vertex stage: two triangles of an axis-aligned quad on the y = 0 plane
// (the tiled plane or the single decal), generated from gl_VertexIndex: no vertex buffer.
#include "gbuffer.glsl"

// Position relative to the eye: interpolated near the eye at full precision wherever the
// eye is (world positions far from the origin would lose the view direction's bits).
layout(location = 0) out vec3 v_eye_rel;
layout(location = 1) out vec2 v_uv;

const vec2 CORNERS[6] = vec2[](vec2(0, 0), vec2(1, 0), vec2(1, 1), vec2(0, 0), vec2(1, 1), vec2(0, 1));

void main() {
    vec2 s = CORNERS[gl_VertexIndex];
    vec2 xz = mix(pc.world_rect.xy, pc.world_rect.zw, s);
    vec3 world = vec3(xz.x, 0.0, xz.y);
    v_eye_rel = world - pc.camera_pos.xyz;
    v_uv = mix(pc.uv_rect.xy, pc.uv_rect.zw, s);
    gl_Position = pc.view_proj * vec4(world, 1.0);
}
