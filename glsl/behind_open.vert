#version 460
// behind_open: the missed tiles of the behind layer's list, each as two triangles covering
// its 8x8 pixels at depth 0 (src/passes/behind_open.rs; the list is
// glsl/behind_cull.comp's, packed x | y << 16), drawn as one instance per listed tile.
#include "frame.glsl"

// The list: a VkDispatchIndirectCommand, the count, then the tiles.
layout(set = 0, binding = 0, std430) readonly buffer List {
    uint dispatch_x;
    uint dispatch_y;
    uint dispatch_z;
    uint count;
    uint tiles[];
} u_list;

layout(push_constant) uniform OpenParams {
    // The frame's size in pixels.
    vec2 frame_size;
} pc;

void main() {
    uint t = u_list.tiles[gl_InstanceIndex];
    vec2 tile = vec2(float(t & 0xFFFFu), float(t >> 16));
    // Corners (0, 0), (1, 0), (0, 1), then (1, 1), (0, 1), (1, 0).
    uint v = uint(gl_VertexIndex);
    uint corner = v < 3u ? v : 6u - v;
    vec2 c = vec2(float(corner & 1u), float(corner >> 1));
    // Tile edges lie on whole pixels: every pixel centre is half a pixel from them.
    vec2 p = (tile + c) * float(LOCAL_SIZE) / pc.frame_size;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
