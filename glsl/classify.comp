#version 460
// classify: sorts the frame's 8x8 tiles by material (src/passes/classify.rs). One
// workgroup per tile: each invocation reads its pixel's material (G-buffer depth and
// frame, glsl/common/tiles.glsl), the workgroup ORs them into a mask, and for every
// material present the tile is appended to that material's list, whose count is the
// workgroup count of the material's VkDispatchIndirectCommand (x = min(n, MAX_TILE_ROW),
// y = rows): every later per-material pass is one indirect dispatch over its list. Pixels of no live material (no geometry, flat
// geometry, an index past the table or of a removed material) get their hit buffer texel
// here, since no trace writes it: (0, 0, NO_HIT_HEIGHT, 0) without geometry,
// (0, 0, NOT_DISPLACED_HEIGHT, 0) for flat geometry. With the DEPTH variant (corrected
// depth on) they also get their corrected depth: the G-buffer's own depth (0 without
// geometry), the depth of a surface that is not displaced.
// dispmap-variant: DEPTH
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
#include "tiles.glsl"
layout(set = 0, binding = 2, rgba32f) uniform writeonly image2D u_hit;
// Every material's list, `tile_capacity` entries each (material m at m * tile_capacity).
layout(set = 0, binding = 3, std430) writeonly buffer Tiles {
    uint tiles[];
} u_tiles;
// Per material 4 words: a VkDispatchIndirectCommand (x, y, z), set to (0, 0, 1) before
// the pass, and w = 1 for a live material, 0 for a vacant table entry. Then a count per
// material (set to 0 before the pass): the length of its list.
layout(set = 0, binding = 4, std430) buffer Args {
    uint args[];
} u_args;
#ifdef DEPTH
layout(set = 0, binding = 5, r32f) uniform writeonly image2D u_hit_depth;
#endif

layout(push_constant) uniform ClassifyParams {
    uvec2 frame_size;    // pixels
    uint material_count; // table entries (live or vacant)
    uint tile_capacity;  // entries per material list
    uint flags;          // CLASSIFY_FLAG_*
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

// Write the hit buffer texels of pixels without displacement (off when the host's hits
// are shaded: DisplacementPass::record_shading).
#define CLASSIFY_FLAG_WRITE_HITS 1u

const uint MASK_WORDS = MAX_MATERIALS / 32u;
shared uint s_mask[MASK_WORDS];

void main() {
    uint lane = gl_LocalInvocationIndex;
    if (lane < MASK_WORDS) {
        s_mask[lane] = 0u;
    }
    barrier();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(uvec2(pixel), pc.frame_size))) {
        float depth = texelFetch(u_depth, pixel, 0).r;
        uint m = depth > 0.0 ? gbuffer_material(pixel) : NOT_DISPLACED;
        if (m < pc.material_count && u_args.args[4u * m + 3u] != 0u) {
            atomicOr(s_mask[m >> 5], 1u << (m & 31u));
        } else {
            if ((pc.flags & CLASSIFY_FLAG_WRITE_HITS) != 0u) {
                float h = depth > 0.0 ? NOT_DISPLACED_HEIGHT : NO_HIT_HEIGHT;
                imageStore(u_hit, pixel, vec4(0.0, 0.0, h, 0.0));
            }
#ifdef DEPTH
            imageStore(u_hit_depth, pixel, vec4(max(depth, 0.0)));
#endif
        }
    }
    barrier();
    uint words = (pc.material_count + 31u) / 32u;
    if (lane < words) {
        uint bits = s_mask[lane];
        uint tile = gl_WorkGroupID.x | (gl_WorkGroupID.y << 16);
        while (bits != 0u) {
            uint b = uint(findLSB(bits));
            bits &= bits - 1u;
            uint m = lane * 32u + b;
            uint i = atomicAdd(u_args.args[4u * pc.material_count + m], 1u);
            u_tiles.tiles[m * pc.tile_capacity + i] = tile;
            atomicMax(u_args.args[4u * m], min(i + 1u, MAX_TILE_ROW));
            atomicMax(u_args.args[4u * m + 1u], i / MAX_TILE_ROW + 1u);
        }
    }
}
