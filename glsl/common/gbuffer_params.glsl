// Push constants of the G-buffer pass (src/abi.rs: GBufferParams).
#ifndef DISPMAP_GBUFFER_PARAMS_GLSL
#define DISPMAP_GBUFFER_PARAMS_GLSL

#include "frame.glsl"

layout(push_constant) uniform GBufferParams {
    mat4 view_proj;     // eye-relative world (world - camera_pos) -> clip (reverse-Z, Vulkan y down)
    vec4 camera_pos;    // xyz: eye in world space; w: material index + 1 (0: not displaced)
    vec4 world_rect;    // x0, z0, x1, z1 of the quad (or the plane's grid) on y = 0
    vec4 uv_rect;       // u0, v0, u1, v1 at the rectangle's corners
    float depth_scale;  // displacement depth in tile (UV) units
    float min_cos;      // lower bound of -V.z: keeps P finite at grazing angles
    uint addressing;    // ADDRESSING_*
    uint plane_cells;   // 0: world_rect is one quad; n > 0: a 2n x 2n grid about the eye
} pc;

#endif
