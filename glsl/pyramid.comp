#version 460
// pyramid: the max-height pyramid (the papers' min-displacement pyramid; heights here, so
// the reduction is a max), two levels per dispatch. See src/passes/pyramid.rs.
//
// Level 0 (from the height map, texels.glsl's texel_height: wrapped or clamped):
//   PYRAMID_KIND_FOOTPRINT: texel (i, j) bounds the bilinear surface over the texel's own
//     footprint [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5] (texel-centre coordinates). On each
//     quarter of the footprint the surface is one bilinear patch whose maximum is at a
//     corner, so the bound is the max of 9 values: the texel, the 4 edge midpoints
//     (mean of 2 texels) and the 4 footprint corners (mean of 4 texels).
//   PYRAMID_KIND_CELL: cell (i, j) (between texel centres (i, j) and (i + 1, j + 1)) is
//     bounded by the max of its 4 corner texels: the bilinear patch's exact maximum.
// Level L > 0: node (i, j) = max of the children (2i + a, 2j + b), a, b in {0, 1}, that
//   exist in the level below (odd sizes: the last node covers one child column/row), so
//   node n of level L covers the cells [n 2^L, min((n + 1) 2^L, size)) of each axis.
//
// One dispatch writes level `level` and, when `next_size` is not 0, level `level + 1`:
// each invocation computes the (up to) 2x2 nodes of `level` under one node of
// `level + 1`, stores them and their max. The 2x2 nodes share their reads: at level 0
// one block of 3x3 texels (cell) or 4x4 (footprint) instead of 4 x 4 or 4 x 9, above it
// one block of 4x4 nodes of the level below. Half the dispatches and barriers, and
// fewer reads, for the same values (every max and mean in the same operation order).
// `precise` keeps the means in the exact operation order the CPU build uses
// (src/passes/pyramid.rs: cpu_build), so the two agree bit for bit.
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_height;
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_src;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D u_dst;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D u_next;

layout(push_constant) uniform PyramidParams {
    uvec2 src_size;   // logical size of the level below `level` (level 0: the map)
    uvec2 dst_size;   // logical size of `level`
    uvec2 next_size;  // logical size of `level + 1`, written too; (0, 0): not this dispatch
    uint level;       // the (first) level written
    uint kind;        // PYRAMID_KIND_*
    uint addressing;  // ADDRESSING_*
    uint pad[3];
} pc;

#include "texels.glsl"

#define PYRAMID_KIND_FOOTPRINT 0u
#define PYRAMID_KIND_CELL 1u

// The footprint bound from the 3x3 texels around a texel (t[4] the texel itself).
float footprint_max(float t[9]) {
    float m = t[4];
    // Edge midpoints: left, right, below, above.
    precise float el = (t[3] + t[4]) * 0.5;
    precise float er = (t[4] + t[5]) * 0.5;
    precise float eb = (t[1] + t[4]) * 0.5;
    precise float ea = (t[4] + t[7]) * 0.5;
    // Footprint corners: means of the 4 texels around them.
    precise float c00 = ((t[0] + t[1]) + (t[3] + t[4])) * 0.25;
    precise float c10 = ((t[1] + t[2]) + (t[4] + t[5])) * 0.25;
    precise float c01 = ((t[3] + t[4]) + (t[6] + t[7])) * 0.25;
    precise float c11 = ((t[4] + t[5]) + (t[7] + t[8])) * 0.25;
    m = max(m, max(max(el, er), max(eb, ea)));
    m = max(m, max(max(c00, c10), max(c01, c11)));
    return m;
}

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    bool pair = pc.next_size.x > 0u;
    if (any(greaterThanEqual(uvec2(q), pair ? pc.next_size : pc.dst_size))) {
        return;
    }
    int span = pair ? 2 : 1;
    ivec2 c0 = q * span;
    ivec2 dst_last = ivec2(pc.dst_size) - 1;
    // The block's reads: level 0: texels c0 - 1 .. c0 + 2 (index 0 .. 3); above: the
    // level below's nodes 2 c0 .. 2 c0 + 3 (clamped to its last node).
    float r[16];
    if (pc.level == 0u) {
        // textureGather returns the 2x2 texels around a point with the sampler's
        // addressing (the map's own: repeat or clamp to edge), which is what
        // texel_height does by hand: 4 gathers read the 4x4 block (texels c0 - 1 ..
        // c0 + 2) that 16 fetches would, without the per-texel wrap arithmetic. The
        // point (o + 1) / size lies on the corner shared by texels o and o + 1, half a
        // texel from any other choice, so rounding cannot move it. Components: x =
        // (i0, j1), y = (i1, j1), z = (i1, j0), w = (i0, j0).
        vec2 inv = 1.0 / vec2(textureSize(u_height, 0));
        for (int b = 0; b < 2; ++b) {
            for (int a = 0; a < 2; ++a) {
                vec4 g = textureGather(u_height, vec2(c0 + ivec2(2 * a, 2 * b)) * inv, 0);
                int k = 2 * b * 4 + 2 * a;
                r[k] = g.w;
                r[k + 1] = g.z;
                r[k + 4] = g.x;
                r[k + 5] = g.y;
            }
        }
    } else {
        ivec2 src_last = ivec2(pc.src_size) - 1;
        for (int j = 0; j < 4; ++j) {
            for (int i = 0; i < 4; ++i) {
                r[j * 4 + i] = imageLoad(u_src, min(2 * c0 + ivec2(i, j), src_last)).r;
            }
        }
    }
    float next;
    for (int dy = 0; dy < span; ++dy) {
        for (int dx = 0; dx < span; ++dx) {
            ivec2 c = c0 + ivec2(dx, dy);
            if (any(greaterThan(c, dst_last))) {
                continue;
            }
            float m;
            if (pc.level == 0u && pc.kind == PYRAMID_KIND_CELL) {
                int k = (dy + 1) * 4 + dx + 1;
                m = max(max(r[k], r[k + 1]), max(r[k + 4], r[k + 5]));
            } else if (pc.level == 0u) {
                float t[9];
                for (int j = 0; j < 3; ++j) {
                    for (int i = 0; i < 3; ++i) {
                        t[j * 3 + i] = r[(dy + j) * 4 + dx + i];
                    }
                }
                m = footprint_max(t);
            } else {
                // Children 2c .. 2c + 1 (clamped): rows 2 dy, 2 dy + 1 of the block.
                int k = 2 * dy * 4 + 2 * dx;
                m = max(max(r[k], r[k + 1]), max(r[k + 4], r[k + 5]));
            }
            imageStore(u_dst, c, vec4(m));
            next = (dx == 0 && dy == 0) ? m : max(next, m);
        }
    }
    if (pair) {
        imageStore(u_next, q, vec4(next));
    }
}
