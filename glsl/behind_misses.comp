#version 460
// behind_misses: which 8x8 tiles of the frame hold a pixel the behind layer may cover
// (src/passes/behind_tiles.rs). After the first record, one indirect dispatch per live
// material over the first layer's tile list of that material (glsl/common/tiles.glsl):
// a workgroup per listed tile, an invocation per pixel; a pixel counts when its
// first-layer trace missed on geometry (dispmap_behind_missed,
// glsl/include/dispmap_behind.glsl). Only displaced pixels are traced, so only the
// materials' tiles can hold one, and each is counted by its own material's dispatch. Each
// missed pixel sets its tile's bit in its row's mask,
// raises the tile's nearest first-layer depth of its missed pixels to its own
// (reverse-Z: the largest): the behind layer keeps only fragments behind it there, and
// marks its material in the tile's mask of materials (a one-sided convex mesh's draw
// skips a tile whose misses are all its own: glsl/behind_cull.comp).
#define DISPMAP_TILES_NO_GBUFFER
#include "tiles.glsl"
#define DISPMAP_BEHIND_NO_DERIVATIVES
#include "include/dispmap_behind.glsl"
#include "include/dispmap_gbuffer.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The first layer's G-buffer depth and hit height, and its frame (the pixel's material).
layout(set = 0, binding = 0) uniform sampler2D u_first_depth;
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_first_hit_height;
layout(set = 0, binding = 4) uniform usampler2D u_first_frame;
// The first layer's tile lists (glsl/common/tiles.glsl).
layout(set = 0, binding = 2, std430) readonly buffer Tiles {
    uint tiles[];
} u_tiles;
// Per row of tiles, `mask_words` words: bit x of the row's mask = tile x holds a missed
// pixel; then per tile (row-major) the largest first-layer depth of its missed pixels, as
// float bits (zeroed before the pass; depths are positive, so their bits order as they do);
// then per tile the materials of its missed pixels (bit m for material m, bit 31 for every
// material from 31 on).
layout(set = 0, binding = 3, std430) buffer Masks {
    uint masks[];
} u_masks;

layout(push_constant) uniform MissParams {
    uvec2 frame_size;
    uint material;
    uint mask_words;
    uint rows;
    uint pad0;
    uint pad1;
} pc;

void main() {
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    if (index >= u_tiles.tiles[2u * pc.material + 1u]) {
        return;
    }
    uint t = u_tiles.tiles[u_tiles.tiles[2u * pc.material] + index];
    uvec2 tile = uvec2(t & 0xFFFFu, t >> 16);
    ivec2 pixel = ivec2(tile * LOCAL_SIZE + gl_LocalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(pixel), pc.frame_size))) {
        return;
    }
    // The hit height first: the depth only where the trace missed (few pixels).
    float height = imageLoad(u_first_hit_height, pixel).x;
    if (height != DISPMAP_MISS_HEIGHT) {
        return;
    }
    float depth = texelFetch(u_first_depth, pixel, 0).r;
    if (!dispmap_behind_missed(height, depth)) {
        return;
    }
    // Each missed pixel once, by its own material's dispatch (a tile of several materials
    // is in each one's list): its material's bit is then its own.
    if (dispmap_frame_material_plus_one(texelFetch(u_first_frame, pixel, 0).xy) != pc.material + 1u) {
        return;
    }
    // Only the (few) missed pixels write, straight to the buffer: no barrier or shared
    // memory in the workgroup (both commute, so the result is the same as one write per
    // tile).
    atomicOr(u_masks.masks[tile.y * pc.mask_words + (tile.x >> 5)], 1u << (tile.x & 31u));
    uint tiles_x = (pc.frame_size.x + LOCAL_SIZE - 1u) / LOCAL_SIZE;
    uint depths = pc.rows * pc.mask_words;
    uint at = tile.y * tiles_x + tile.x;
    atomicMax(u_masks.masks[depths + at], floatBitsToUint(depth));
    atomicOr(u_masks.masks[depths + pc.rows * tiles_x + at], 1u << min(pc.material, 31u));
}
