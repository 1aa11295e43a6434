// The host's push constants for its G-buffer draw: the layout of dispmap's GBufferParams
// (src/abi.rs), so the host fills them with Scene::gbuffer_params.
#ifndef HOST_FRAME_GLSL
#define HOST_FRAME_GLSL

layout(push_constant) uniform HostGBufferParams {
    mat4 view_proj_eye; // eye-relative world (world - eye) -> clip (reverse-Z, Vulkan y down)
    vec4 eye;           // xyz: eye in world space; w: material index + 1
    vec4 world_rect;    // x0, z0, x1, z1 of the floor on y = 0
    vec4 uv_rect;       // u0, v0, u1, v1 at the rectangle's corners
    float depth_scale;  // displacement depth in tile units (the pass's)
    float min_cos;      // lower bound of -V.z
    uint addressing;    // DISPMAP_ADDRESSING_*
    uint plane_cells;   // the plane's grid (dispmap_plane.glsl)
} pc;

#endif
