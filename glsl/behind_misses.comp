#version 460
// behind_misses: which 8x8 tiles of the frame hold a pixel the behind layer may cover
// (src/passes/behind_tiles.rs). After the first record, one indirect dispatch per live
// material over the first layer's tile list of that material (glsl/common/tiles.glsl):
// a workgroup per listed tile, an invocation per pixel; a pixel counts when its
// first-layer trace missed on geometry (dispmap_behind_missed,
// glsl/include/dispmap_behind.glsl). Only displaced pixels are traced, so only the
// materials' tiles can hold one. Each tile that does sets its bit in its row's mask and
// keeps the nearest first-layer depth of its missed pixels (reverse-Z: the largest): the
// behind layer keeps only fragments behind it there.
#define DISPMAP_TILES_NO_GBUFFER
#include "tiles.glsl"
#define DISPMAP_BEHIND_NO_DERIVATIVES
#include "include/dispmap_behind.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The first layer's G-buffer depth and hit height.
layout(set = 0, binding = 0) uniform sampler2D u_first_depth;
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_first_hit_height;
// The first layer's tile lists (glsl/common/tiles.glsl).
layout(set = 0, binding = 2, std430) readonly buffer Tiles {
    uint tiles[];
} u_tiles;
// Per row of tiles, `mask_words` words: bit x of the row's mask = tile x holds a missed
// pixel; then per tile (row-major) the largest first-layer depth of its missed pixels, as
// float bits (zeroed before the pass; depths are positive, so their bits order as they do).
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

shared uint s_missed;
shared uint s_depth;

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        s_missed = 0u;
        s_depth = 0u;
    }
    barrier();
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    bool listed = index < u_tiles.tiles[2u * pc.material + 1u];
    uvec2 tile = uvec2(0u);
    if (listed) {
        uint t = u_tiles.tiles[u_tiles.tiles[2u * pc.material] + index];
        tile = uvec2(t & 0xFFFFu, t >> 16);
        ivec2 pixel = ivec2(tile * LOCAL_SIZE + gl_LocalInvocationID.xy);
        // The hit height first: the depth only where the trace missed (few pixels).
        if (all(lessThan(uvec2(pixel), pc.frame_size))) {
            float height = imageLoad(u_first_hit_height, pixel).x;
            if (height == DISPMAP_MISS_HEIGHT) {
                float depth = texelFetch(u_first_depth, pixel, 0).r;
                if (dispmap_behind_missed(height, depth)) {
                    atomicOr(s_missed, 1u);
                    atomicMax(s_depth, floatBitsToUint(depth));
                }
            }
        }
    }
    barrier();
    if (listed && gl_LocalInvocationIndex == 0u && s_missed != 0u) {
        atomicOr(u_masks.masks[tile.y * pc.mask_words + (tile.x >> 5)], 1u << (tile.x & 31u));
        uint tiles_x = (pc.frame_size.x + LOCAL_SIZE - 1u) / LOCAL_SIZE;
        atomicMax(u_masks.masks[pc.rows * pc.mask_words + tile.y * tiles_x + tile.x], s_depth);
    }
}
