#version 460
// pyramid: the max-height pyramid (the papers' min-displacement pyramid; heights here, so
// the reduction is a max), up to three levels per dispatch. See src/passes/pyramid.rs.
//
// Level 0 (from the height map, texels.glsl's texel_height: wrapped or clamped):
//   PYRAMID_KIND_FOOTPRINT: texel (i, j) bounds the bilinear surface over the texel's own
//     footprint [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5] (texel-centre coordinates). On each
//     quarter of the footprint the surface is one bilinear patch whose maximum is at a
//     corner, so the bound is the max of 9 values: the texel, the 4 edge midpoints
//     (mean of 2 texels) and the 4 footprint corners (mean of 4 texels).
//   PYRAMID_KIND_CELL: cell (i, j) (between texel centres (i, j) and (i + 1, j + 1)) is
//     bounded by the max of its 4 corner texels: the bilinear patch's exact maximum.
//   PYRAMID_KIND_FALLS + q (q = neg_x + 2 neg_y; the relaxed cone map's input): cell
//     (i, j)'s corner maximum where its bilinear patch falls along quadrant q's direction
//     (x: +1, or -1 when neg_x; y likewise), i.e. an edge decreases along x or y in that
//     direction; 0 (no rise above any cell) where it does not.
// Level L > 0: node (i, j) = max of the children (2i + a, 2j + b), a, b in {0, 1}, that
//   exist in the level below (odd sizes: the last node covers one child column/row), so
//   node n of level L covers the cells [n 2^L, min((n + 1) 2^L, size)) of each axis.
//
// One dispatch writes level `level` and, when `next_size` / `next2_size` are not 0,
// levels `level + 1` and `level + 2`: each invocation computes the (up to) S x S nodes of
// `level` under one node of the dispatch's top level (S = 1, 2, 4), stores them, then
// the S/2 x S/2 nodes above them and their max. The block's nodes share their reads: at
// level 0 3x3 gathers (6x6 texels) for 4x4 nodes instead of 16 x 4 (cell) or 16 x 9
// (footprint) texels, above it one block of 8x8 nodes of the level below. A third of
// the dispatches and barriers, and fewer reads, for the same values (every max and mean
// in the same operation order; a node that does not exist is -1, below every height, so
// the maxima above it take the existing children only). The loops' bounds are run-time
// values (no unrolled 8x8 blocks for the compiler).
// `precise` keeps the means in the exact operation order the CPU build uses
// (src/passes/pyramid.rs: cpu_build), so the two agree bit for bit.
//
// An R32_SFLOAT cell pyramid does not store level 0 (pc.store_dst = 0 on the dispatch
// that starts there): the traversals test a level-0 cell's texels, read from the map
// itself, exactly (glsl/common/pyramid.glsl), the cone build takes its maximum from them.
//
// UNORM (the cell pyramid of a map whose texels are 8- or 16-bit unorm, in R8_UNORM or
// R16_UNORM; the default variant writes R32_SFLOAT chains): the maxima are texels as the
// shaders sample them, each the decoding of a code c of that format, and the node stores
// that code (nearest_code recovers it: the decoding is within an ulp of c / code_max),
// so the pyramid samples as the map's texels do, bit for bit. Levels above the first
// dispatch read the level below through a sampler (u_src; the height map on the level-0
// dispatch, which does not read it). The storage images have no format qualifier
// (written as the view's format: Vulkan 1.3's STORAGE_WRITE_WITHOUT_FORMAT format
// feature, checked by the pass).
// dispmap-variant: UNORM
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_height;
#ifdef UNORM
layout(set = 0, binding = 1) uniform sampler2D u_src;
#define SRC_LOAD(p) texelFetch(u_src, p, 0).r
layout(set = 0, binding = 2) uniform writeonly image2D u_dst;
layout(set = 0, binding = 3) uniform writeonly image2D u_next;
layout(set = 0, binding = 4) uniform writeonly image2D u_next2;
#else
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_src;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D u_dst;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D u_next;
layout(set = 0, binding = 4, r32f) uniform writeonly image2D u_next2;
#define SRC_LOAD(p) imageLoad(u_src, p).r
#endif

layout(push_constant) uniform PyramidParams {
    uvec2 src_size;   // logical size of the level below `level` (level 0: the map)
    uvec2 dst_size;   // logical size of `level`
    uvec2 next_size;  // logical size of `level + 1`, written too; (0, 0): not this dispatch
    uint level;       // the (first) level written
    uint kind;        // PYRAMID_KIND_*
    uint addressing;  // ADDRESSING_*
    uint code_max;    // UNORM: 255 or 65535 (the storage format's largest code); 0 otherwise
    uvec2 next2_size; // logical size of `level + 2`, written too; (0, 0): not this dispatch
    uint store_dst;   // 0: `level` is not stored (the cell pyramid's level 0), only those above
    uint pad[3];
} pc;

#include "texels.glsl"

#define PYRAMID_KIND_FOOTPRINT 0u
#define PYRAMID_KIND_CELL 1u
#define PYRAMID_KIND_FALLS 2u

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

// The code whose decoding f is (f within an ulp of c / s).
uint nearest_code(float f, float s) {
    return uint(clamp(round(f * s), 0.0, s));
}

// What imageStore writes for the bound m: m itself (R32_SFLOAT), or its code (UNORM) as
// (c + 1/4) / s, which a float -> unorm conversion (Vulkan: one of the two integers
// nearest to the value times s, i.e. c or c + 1; round to nearest, which every device
// does, gives c) stores as c.
vec4 encoded(float m) {
#ifdef UNORM
    float s = float(pc.code_max);
    return vec4((float(nearest_code(m, s)) + 0.25) / s);
#else
    return vec4(m);
#endif
}

void main() {
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    // Levels written by this dispatch: 1, 2 or 3; each invocation writes an S x S block
    // of `level` (S = 1, 2, 4), the S/2 x S/2 nodes above it and the one node above those.
    int count = pc.next2_size.x > 0u ? 3 : (pc.next_size.x > 0u ? 2 : 1);
    uvec2 grid = count == 3 ? pc.next2_size : (count == 2 ? pc.next_size : pc.dst_size);
    if (any(greaterThanEqual(uvec2(q), grid))) {
        return;
    }
    int span = 1 << (count - 1);
    ivec2 c0 = q * span;
    ivec2 dst_last = ivec2(pc.dst_size) - 1;
    // The block's reads, rows of 8: level 0: texels c0 - 1 .. c0 + 2 gathers - 2 (index
    // 0 ..); above: the level below's nodes 2 c0 .. 2 c0 + 2 span - 1 (clamped to its
    // last node).
    float r[64];
    if (pc.level == 0u) {
        // textureGather returns the 2x2 texels around a point with the sampler's
        // addressing (the map's own: repeat or clamp to edge), which is what
        // texel_height does by hand: gathers read the block of texels c0 - 1 .. that
        // fetches would, without the per-texel wrap arithmetic. The point (o + 1) / size
        // lies on the corner shared by texels o and o + 1, half a texel from any other
        // choice, so rounding cannot move it. Components: x = (i0, j1), y = (i1, j1),
        // z = (i1, j0), w = (i0, j0).
        vec2 inv = 1.0 / vec2(textureSize(u_height, 0));
        int gathers = max(2, span / 2 + 1);
        for (int b = 0; b < gathers; ++b) {
            for (int a = 0; a < gathers; ++a) {
                vec4 g = textureGather(u_height, vec2(c0 + ivec2(2 * a, 2 * b)) * inv, 0);
                int k = 2 * b * 8 + 2 * a;
                r[k] = g.w;
                r[k + 1] = g.z;
                r[k + 8] = g.x;
                r[k + 9] = g.y;
            }
        }
    } else {
        ivec2 src_last = ivec2(pc.src_size) - 1;
        for (int j = 0; j < 2 * span; ++j) {
            for (int i = 0; i < 2 * span; ++i) {
                r[j * 8 + i] = SRC_LOAD(min(2 * c0 + ivec2(i, j), src_last));
            }
        }
    }
    // The block's nodes of `level`, rows of 4; -1 (below every height) where a node
    // does not exist, so the maxima above take the existing children only.
    float nodes[16];
    for (int dy = 0; dy < span; ++dy) {
        for (int dx = 0; dx < span; ++dx) {
            ivec2 c = c0 + ivec2(dx, dy);
            float m = -1.0;
            if (all(lessThanEqual(c, dst_last))) {
                if (pc.level == 0u && pc.kind == PYRAMID_KIND_CELL) {
                    int k = (dy + 1) * 8 + dx + 1;
                    m = max(max(r[k], r[k + 1]), max(r[k + 8], r[k + 9]));
                } else if (pc.level == 0u && pc.kind >= PYRAMID_KIND_FALLS) {
                    int k = (dy + 1) * 8 + dx + 1;
                    float a00 = r[k], a10 = r[k + 1], a01 = r[k + 8], a11 = r[k + 9];
                    uint q = pc.kind - PYRAMID_KIND_FALLS;
                    bool falls_x = (q & 1u) != 0u ? (a10 > a00 || a11 > a01) : (a00 > a10 || a01 > a11);
                    bool falls_y = (q & 2u) != 0u ? (a01 > a00 || a11 > a10) : (a00 > a01 || a10 > a11);
                    m = falls_x || falls_y ? max(max(a00, a10), max(a01, a11)) : 0.0;
                } else if (pc.level == 0u) {
                    float t[9];
                    for (int j = 0; j < 3; ++j) {
                        for (int i = 0; i < 3; ++i) {
                            t[j * 3 + i] = r[(dy + j) * 8 + dx + i];
                        }
                    }
                    m = footprint_max(t);
                } else {
                    // Children 2c .. 2c + 1 (clamped): rows 2 dy, 2 dy + 1 of the block.
                    int k = 2 * dy * 8 + 2 * dx;
                    m = max(max(r[k], r[k + 1]), max(r[k + 8], r[k + 9]));
                }
                if (pc.store_dst != 0u) {
                    imageStore(u_dst, c, encoded(m));
                }
            }
            nodes[dy * 4 + dx] = m;
        }
    }
    if (count == 1) {
        return;
    }
    // Level + 1: the S/2 x S/2 nodes over the block.
    int half_span = span / 2;
    ivec2 next_last = ivec2(pc.next_size) - 1;
    float above[4];
    for (int ey = 0; ey < half_span; ++ey) {
        for (int ex = 0; ex < half_span; ++ex) {
            int k = 2 * ey * 4 + 2 * ex;
            float m = max(max(nodes[k], nodes[k + 1]), max(nodes[k + 4], nodes[k + 5]));
            ivec2 c = q * half_span + ivec2(ex, ey);
            if (all(lessThanEqual(c, next_last))) {
                imageStore(u_next, c, encoded(m));
            } else {
                m = -1.0;
            }
            above[ey * 2 + ex] = m;
        }
    }
    if (count == 3) {
        imageStore(u_next2, q, encoded(max(max(above[0], above[1]), max(above[2], above[3]))));
    }
}
