#version 460
// behind_cull: the behind layer's work from the missed tiles' masks
// (src/passes/behind_tiles.rs, after glsl/behind_misses.comp), in two steps:
// step 0: one invocation per row of tiles appends the row's missed tiles to the list
//   (packed x | y << 16, in no particular order) and counts them; one invocation per draw
//   of the layer writes its indirect draw command: the draw's own (indexed or not) where
//   its screen rectangle in tiles (projected on the CPU from the geometry's bounds,
//   conservatively) meets a missed tile whose nearest missed first-layer depth lies in
//   front of the draw's farthest point (else none of its fragments is behind a missed
//   pixel's surface) and which holds a missed pixel of a material not among the draw's
//   own (a one-sided convex mesh's: nothing of it lies behind its own surface), else the
//   same with no vertices;
// step 1: one invocation writes the list's dispatch: one workgroup per listed tile, in
//   rows of MAX_TILE_ROW (glsl/common/tiles.glsl), and after the draws' commands the
//   listed tiles' VkDrawIndirectCommand (6 vertices, an instance per listed tile:
//   glsl/behind_open.vert).
#define DISPMAP_TILES_NO_GBUFFER
#include "tiles.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The missed tiles' masks, then their depths, then their materials
// (glsl/behind_misses.comp).
layout(set = 0, binding = 0, std430) readonly buffer Masks {
    uint masks[];
} u_masks;
// The list: a VkDispatchIndirectCommand, the count, then the tiles.
layout(set = 0, binding = 1, std430) buffer List {
    uint dispatch_x;
    uint dispatch_y;
    uint dispatch_z;
    uint count;
    uint tiles[];
} u_list;
// Per draw: its rectangle in tiles (x0, y0, x1, y1, inclusive; x0 > x1: off the frame),
// its vertex or index count, first index or vertex, the reverse-Z depth of its farthest
// point, lowered conservatively (float bits), and the materials whose misses it cannot
// show (src/passes/behind_tiles.rs DrawSource::own).
layout(set = 0, binding = 2, std430) readonly buffer Sources {
    uvec4 sources[];
} u_sources;
// Per piece a VkDrawIndexedIndirectCommand (5 words; a VkDrawIndirectCommand in the first
// 4 for a piece that is not indexed: the count in word 0, the first index or vertex in
// word 2 either way), then the listed tiles' VkDrawIndirectCommand (4 words).
layout(set = 0, binding = 3, std430) writeonly buffer Draws {
    uint draws[];
} u_draws;

layout(push_constant) uniform CullParams {
    uint step;
    uint rows;
    uint mask_words;
    uint draw_count;
    uint tiles_x;
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

// Whether a tile of columns [x0, x1] of row y is missed with its nearest missed depth in
// front of `depth` (reverse-Z: larger) and a missed pixel of a material not in `own`.
bool row_meets(uint y, uint x0, uint x1, float depth, uint own) {
    for (uint w = x0 >> 5; w <= (x1 >> 5); ++w) {
        uint bits = u_masks.masks[y * pc.mask_words + w];
        uint lo = max(x0, w * 32u) - w * 32u;
        uint hi = min(x1, w * 32u + 31u) - w * 32u;
        bits &= (hi == 31u ? 0xFFFFFFFFu : ((1u << (hi + 1u)) - 1u)) & ~((1u << lo) - 1u);
        while (bits != 0u) {
            uint b = uint(findLSB(bits));
            bits &= bits - 1u;
            uint tile = y * pc.tiles_x + w * 32u + b;
            uint depths = pc.rows * pc.mask_words;
            if (uintBitsToFloat(u_masks.masks[depths + tile]) > depth
                && (u_masks.masks[depths + pc.rows * pc.tiles_x + tile] & ~own) != 0u) {
                return true;
            }
        }
    }
    return false;
}

void main() {
    uint i = gl_WorkGroupID.x * (LOCAL_SIZE * LOCAL_SIZE) + gl_LocalInvocationIndex;
    if (pc.step == 1u) {
        if (i == 0u) {
            uint n = u_list.count;
            u_list.dispatch_x = min(n, MAX_TILE_ROW);
            u_list.dispatch_y = (n + MAX_TILE_ROW - 1u) / MAX_TILE_ROW;
            u_list.dispatch_z = 1u;
            uint base = 5u * pc.draw_count;
            u_draws.draws[base] = 6u;
            u_draws.draws[base + 1u] = n;
            u_draws.draws[base + 2u] = 0u;
            u_draws.draws[base + 3u] = 0u;
        }
        return;
    }
    if (i < pc.rows) {
        for (uint w = 0u; w < pc.mask_words; ++w) {
            uint bits = u_masks.masks[i * pc.mask_words + w];
            if (bits == 0u) {
                continue;
            }
            uint at = atomicAdd(u_list.count, uint(bitCount(bits)));
            while (bits != 0u) {
                uint b = uint(findLSB(bits));
                bits &= bits - 1u;
                u_list.tiles[at++] = (w * 32u + b) | (i << 16);
            }
        }
    }
    if (i < pc.draw_count) {
        uvec4 rect = u_sources.sources[2u * i];
        uvec4 source = u_sources.sources[2u * i + 1u];
        bool meets = false;
        if (rect.x <= rect.z) {
            for (uint y = rect.y; y <= rect.w && !meets; ++y) {
                meets = row_meets(y, rect.x, rect.z, uintBitsToFloat(source.z), source.w);
            }
        }
        uint count = meets ? source.x : 0u;
        uint base = 5u * i;
        u_draws.draws[base] = count;
        u_draws.draws[base + 1u] = 1u;
        u_draws.draws[base + 2u] = source.y;
        u_draws.draws[base + 3u] = 0u;
        u_draws.draws[base + 4u] = 0u;
    }
}
