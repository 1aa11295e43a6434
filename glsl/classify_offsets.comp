#version 460
// classify, step 2 of 4 (src/passes/classify.rs): places each material's tile list in
// the slot's one tile buffer. One workgroup: an exclusive prefix sum of the counts of step
// 1 (glsl/classify.comp) gives each table entry's first entry word; it writes the list's
// place and length into the tile buffer's header (what the per-material passes read,
// glsl/common/tiles.glsl), the scatter's cursor (glsl/classify_scatter.comp,
// glsl/classify_mixed.comp) and the workgroup count of the entry's
// VkDispatchIndirectCommand (x = min(n, MAX_TILE_ROW), y = rows; an empty list keeps
// (0, 0, 1): no workgroup); and the one of the list of tiles of several materials. The counts of a frame sum to at
// most tiles * LOCAL_SIZE^2 (a tile holds at most that many materials): the lists fit the
// buffer. Each invocation handles MAX_MATERIALS / LOCAL_SIZE^2 consecutive entries (16
// loop iterations; the prefix over the invocations below is at most 63).
#include "frame.glsl"
#define DISPMAP_TILES_NO_GBUFFER
#include "tiles.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The slot's tile buffer: this step writes the header.
layout(set = 0, binding = 0, std430) writeonly buffer Tiles {
    uint tiles[];
} u_tiles;
// The slot's arguments: this step reads the counts and writes the dispatch arguments and
// the cursors.
layout(set = 0, binding = 1, std430) buffer Args {
    uint args[];
} u_args;

CLASSIFY_PARAMS

const uint LANES = uint(LOCAL_SIZE * LOCAL_SIZE);
const uint PER_LANE = MAX_MATERIALS / LANES;
shared uint s_sum[LANES];

void main() {
    uint lane = gl_LocalInvocationIndex;
    uint first = lane * PER_LANE;
    uint sum = 0u;
    for (uint k = 0u; k < PER_LANE; k++) {
        uint m = first + k;
        if (m < pc.material_count) {
            sum += u_args.args[ARGS_WORDS * m + ARGS_COUNT];
        }
    }
    s_sum[lane] = sum;
    barrier();
    uint at = pc.entries_base;
    for (uint k = 0u; k < lane; k++) {
        at += s_sum[k];
    }
    for (uint k = 0u; k < PER_LANE; k++) {
        uint m = first + k;
        if (m < pc.material_count) {
            uint n = u_args.args[ARGS_WORDS * m + ARGS_COUNT];
            u_tiles.tiles[2u * m] = at;
            u_tiles.tiles[2u * m + 1u] = n;
            u_args.args[ARGS_WORDS * m + ARGS_CURSOR] = at;
            if (n > 0u) {
                u_args.args[ARGS_WORDS * m] = min(n, MAX_TILE_ROW);
                u_args.args[ARGS_WORDS * m + 1u] = (n - 1u) / MAX_TILE_ROW + 1u;
            }
            at += n;
        }
    }
    if (lane == 0u) {
        uint n = u_args.args[ARGS_MIXED + ARGS_COUNT];
        if (n > 0u) {
            u_args.args[ARGS_MIXED] = min(n, MAX_TILE_ROW);
            u_args.args[ARGS_MIXED + 1u] = (n - 1u) / MAX_TILE_ROW + 1u;
        }
    }
}
