// examples/host_engine.rs: push constants of the engine's G-buffer shaders (the engine's
// own `EngineParams`; the floor's fields are the values of dispmap's GBufferParams for
// the frame, so the floor is dispmap's plane).
#ifndef HOST_ENGINE_GLSL
#define HOST_ENGINE_GLSL

layout(push_constant) uniform EngineParams {
    mat4 view_proj;     // eye-relative world (world - camera_pos) -> clip (view_proj_eye)
    vec4 camera_pos;    // xyz: eye in world space; w: the draw's material (floor 0, cube 1)
    vec4 world_rect;    // the floor's rectangle (dispmap_plane_vertex)
    vec4 uv_rect;       // uv at its corners
    float depth_scale;
    float min_cos;
    uint addressing;
    uint plane_cells;   // the floor's grid: 2n x 2n cells about the eye
} pc;

#endif
