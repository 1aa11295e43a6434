#version 460
// classify, step 1 of 4 (src/passes/classify.rs): counts the frame's 8x8 tiles per
// material. One workgroup per tile: each invocation reads its pixel's material (G-buffer
// depth and frame, glsl/common/gbuffer.glsl), the workgroup ORs them into a mask, and
// every material present adds one to its count and to the tile's. The tile's summary (no material, its one
// material, or several) is kept for the scatter (glsl/classify_scatter.comp), and a tile of
// several materials is appended to the list glsl/classify_mixed.comp runs over, after
// glsl/classify_offsets.comp placed each material's list in the slot's one tile buffer.
// Pixels of no live material (no geometry, flat geometry, an index past the table or of a
// removed material) get their hit texels here, since no trace writes them: uv (0, 0) and
// height NO_HIT_HEIGHT without geometry, NOT_DISPLACED_HEIGHT for flat geometry. With the
// DEPTH variant (corrected depth on) they also get their corrected depth: the G-buffer's
// own depth (0 without geometry), the depth of a surface that is not displaced; with the
// ITERATIONS variant (the iteration output on) an iteration count of 0.
// LISTED variants (a record over listed tiles only: the standalone renderer's behind
// layer, src/renderer/behind.rs): one workgroup per tile of u_listed (the behind layer's
// missed tiles, glsl/behind_cull.comp), an indirect dispatch; the caller gave every other
// tile's pixels their texels and the tile summaries TILE_EMPTY.
// dispmap-variant: DEPTH
// dispmap-variant: ITERATIONS
// dispmap-variant: DEPTH+ITERATIONS
// dispmap-variant: LISTED
// dispmap-variant: LISTED+DEPTH
// dispmap-variant: LISTED+ITERATIONS
// dispmap-variant: LISTED+DEPTH+ITERATIONS
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
#include "tiles.glsl"
layout(set = 0, binding = 2, rg32f) uniform writeonly image2D u_hit_uv;
layout(set = 0, binding = 6, r32f) uniform writeonly image2D u_hit_height;
// The slot's tile buffer (glsl/common/tiles.glsl): this step writes the tile summaries and
// the list of tiles of several materials.
layout(set = 0, binding = 3, std430) writeonly buffer Tiles {
    uint tiles[];
} u_tiles;
// The slot's arguments (glsl/common/tiles.glsl: ARGS_WORDS per table entry; the counts
// zeroed before the pass): this step reads the live flags and adds to the counts (the
// mixed tiles' too).
layout(set = 0, binding = 4, std430) buffer Args {
    uint args[];
} u_args;
#ifdef DEPTH
layout(set = 0, binding = 5, r32f) uniform writeonly image2D u_hit_depth;
#endif
#ifdef ITERATIONS
layout(set = 0, binding = 7, r32ui) uniform writeonly uimage2D u_iterations;
#endif
#ifdef LISTED
// The tiles to classify: a dispatch, the count, then the tiles packed x | y << 16.
layout(set = 0, binding = 8, std430) readonly buffer Listed {
    uvec4 header;
    uint tiles[];
} u_listed;
#endif

CLASSIFY_PARAMS

// Write the hit texels of pixels without displacement (off when the host's hits
// are shaded: DisplacementPass::record_shading).
#define CLASSIFY_FLAG_WRITE_HITS 1u

const uint MASK_WORDS = MAX_MATERIALS / 32u;
shared uint s_mask[MASK_WORDS];
shared uint s_n;
shared uint s_first;

void main() {
    uint lane = gl_LocalInvocationIndex;
#ifdef LISTED
    uint listed = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    if (listed >= u_listed.header.w) {
        return;
    }
    uint packed = u_listed.tiles[listed];
    uvec2 tile = uvec2(packed & 0xFFFFu, packed >> 16);
    ivec2 pixel = ivec2(tile * LOCAL_SIZE + gl_LocalInvocationID.xy);
    uint index = tile.y * ((pc.frame_size.x + LOCAL_SIZE - 1u) / LOCAL_SIZE) + tile.x;
#else
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    uint index = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uvec2 tile = gl_WorkGroupID.xy;
#endif
    if (lane < MASK_WORDS) {
        s_mask[lane] = 0u;
    }
    if (lane == 0u) {
        s_n = 0u;
    }
    barrier();
    if (all(lessThan(uvec2(pixel), pc.frame_size))) {
        float depth = texelFetch(u_depth, pixel, 0).r;
        uint m = depth > 0.0 ? gbuffer_material(pixel) : NOT_DISPLACED;
        if (m < pc.material_count && u_args.args[ARGS_WORDS * m + ARGS_LIVE] != 0u) {
            atomicOr(s_mask[m >> 5], 1u << (m & 31u));
        } else {
            if ((pc.flags & CLASSIFY_FLAG_WRITE_HITS) != 0u) {
                float h = depth > 0.0 ? NOT_DISPLACED_HEIGHT : NO_HIT_HEIGHT;
                imageStore(u_hit_uv, pixel, vec4(0.0));
                imageStore(u_hit_height, pixel, vec4(h));
            }
#ifdef ITERATIONS
            imageStore(u_iterations, pixel, uvec4(0u));
#endif
#ifdef DEPTH
            imageStore(u_hit_depth, pixel, vec4(max(depth, 0.0)));
#endif
        }
    }
    barrier();
    // Each material present adds one to its count and to the tile's (s_n; the first one
    // found names the tile's material in s_first).
    uint words = (pc.material_count + 31u) / 32u;
    if (lane < words) {
        uint bits = s_mask[lane];
        while (bits != 0u) {
            uint b = uint(findLSB(bits));
            bits &= bits - 1u;
            uint m = lane * 32u + b;
            atomicAdd(u_args.args[ARGS_WORDS * m + ARGS_COUNT], 1u);
            if (atomicAdd(s_n, 1u) == 0u) {
                s_first = m;
            }
        }
    }
    barrier();
    if (lane == 0u) {
        uint n = s_n;
        u_tiles.tiles[TILE_HEADER_WORDS + index] = n == 0u ? TILE_EMPTY : (n == 1u ? s_first : TILE_MIXED);
        if (n > 1u) {
            uint i = atomicAdd(u_args.args[ARGS_MIXED + ARGS_COUNT], 1u);
            u_tiles.tiles[TILE_HEADER_WORDS + pc.tile_count + i] = tile.x | (tile.y << 16);
        }
    }
}
