#version 460
// classify, step 4 of 4 (src/passes/classify.rs): writes every tile of several materials
// into the list of each material it holds. An indirect dispatch of one workgroup per tile
// of the list glsl/classify.comp made: the tile's invocations read their pixels' materials
// again (the same reads as step 1, so each list gets exactly the entries step 1 counted),
// the workgroup ORs them into a mask, and each material present takes its list's next
// entry (glsl/classify_offsets.comp placed the lists).
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
#include "tiles.glsl"
// The slot's tile buffer: this step reads the list of mixed tiles and writes the entries.
layout(set = 0, binding = 2, std430) buffer Tiles {
    uint tiles[];
} u_tiles;
// The slot's arguments: this step reads the live flags and the list's length and advances
// the cursors.
layout(set = 0, binding = 3, std430) buffer Args {
    uint args[];
} u_args;

CLASSIFY_PARAMS

const uint MASK_WORDS = MAX_MATERIALS / 32u;
shared uint s_mask[MASK_WORDS];

void main() {
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    // Past the list (the last row of a list longer than MAX_TILE_ROW): uniform.
    if (index >= u_args.args[ARGS_MIXED + ARGS_COUNT]) {
        return;
    }
    uint tile = u_tiles.tiles[TILE_HEADER_WORDS + pc.tile_count + index];
    uint lane = gl_LocalInvocationIndex;
    if (lane < MASK_WORDS) {
        s_mask[lane] = 0u;
    }
    barrier();
    ivec2 pixel = ivec2(tile & 0xFFFFu, tile >> 16) * LOCAL_SIZE + ivec2(gl_LocalInvocationID.xy);
    if (all(lessThan(uvec2(pixel), pc.frame_size))) {
        float depth = texelFetch(u_depth, pixel, 0).r;
        uint m = depth > 0.0 ? gbuffer_material(pixel) : NOT_DISPLACED;
        if (m < pc.material_count && u_args.args[ARGS_WORDS * m + ARGS_LIVE] != 0u) {
            atomicOr(s_mask[m >> 5], 1u << (m & 31u));
        }
    }
    barrier();
    uint words = (pc.material_count + 31u) / 32u;
    if (lane < words) {
        uint bits = s_mask[lane];
        while (bits != 0u) {
            uint b = uint(findLSB(bits));
            bits &= bits - 1u;
            uint i = atomicAdd(u_args.args[ARGS_WORDS * (lane * 32u + b) + ARGS_CURSOR], 1u);
            u_tiles.tiles[i] = tile;
        }
    }
}
