#version 460
// classify, step 3 of 3 (src/passes/classify.rs): writes every tile into the list of each
// material it holds, at the place glsl/classify_offsets.comp gave the list. One workgroup
// per tile: a tile without material does nothing, a tile of one material (its summary,
// glsl/classify.comp) takes one entry of that list; only a tile of several materials reads
// its pixels' materials again (the same reads as step 1, so each list gets exactly the
// entries step 1 counted). The order of a list's entries is the order the workgroups ran
// in; every pass re-checks its pixel's material, so the order changes no result.
#include "frame.glsl"
#include "tiles.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1) uniform sampler2D u_tangent;
// The slot's tile buffer: this step reads the summaries and writes the entries.
layout(set = 0, binding = 2, std430) buffer Tiles {
    uint tiles[];
} u_tiles;
// The slot's arguments: this step reads the live flags and advances the cursors.
layout(set = 0, binding = 3, std430) buffer Args {
    uint args[];
} u_args;

layout(push_constant) uniform ClassifyParams {
    uvec2 frame_size;    // pixels
    uint material_count; // table entries (live or vacant)
    uint entries_base;   // the tile buffer's first entry word
    uint flags;          // unused here
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

const uint MASK_WORDS = MAX_MATERIALS / 32u;
shared uint s_mask[MASK_WORDS];

void main() {
    uint lane = gl_LocalInvocationIndex;
    uint index = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint summary = u_tiles.tiles[TILE_HEADER_WORDS + index];
    uint tile = gl_WorkGroupID.x | (gl_WorkGroupID.y << 16);
    // The summary is the workgroup's: these returns are uniform.
    if (summary == TILE_EMPTY) {
        return;
    }
    if (summary != TILE_MIXED) {
        if (lane == 0u) {
            uint i = atomicAdd(u_args.args[ARGS_WORDS * summary + ARGS_CURSOR], 1u);
            u_tiles.tiles[i] = tile;
        }
        return;
    }
    if (lane < MASK_WORDS) {
        s_mask[lane] = 0u;
    }
    barrier();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(uvec2(pixel), pc.frame_size))) {
        float depth = texelFetch(u_depth, pixel, 0).r;
        uint m = depth > 0.0 ? decode_material(texelFetch(u_tangent, pixel, 0).w) : NOT_DISPLACED;
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
