#version 460
// pyramid: one level of the max-height pyramid per dispatch (the papers' min-displacement
// pyramid; heights here, so the reduction is a max). See src/passes/pyramid.rs.
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
// `precise` keeps the means in the exact operation order the CPU build uses
// (src/passes/pyramid.rs: cpu_build), so the two agree bit for bit.
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_height;
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_src;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D u_dst;

layout(push_constant) uniform PyramidParams {
    uvec2 src_size;   // logical size of the level below (level 0: the map)
    uvec2 dst_size;   // logical size of the level written
    uint level;       // the level written
    uint kind;        // PYRAMID_KIND_*
    uint addressing;  // ADDRESSING_*
    uint pad;
} pc;

#include "texels.glsl"

#define PYRAMID_KIND_FOOTPRINT 0u
#define PYRAMID_KIND_CELL 1u

float level0(ivec2 p) {
    if (pc.kind == PYRAMID_KIND_CELL) {
        return max(max(texel_height(p), texel_height(p + ivec2(1, 0))), max(texel_height(p + ivec2(0, 1)), texel_height(p + ivec2(1, 1))));
    }
    float t[9];
    for (int j = 0; j < 3; ++j) {
        for (int i = 0; i < 3; ++i) {
            t[j * 3 + i] = texel_height(p + ivec2(i - 1, j - 1));
        }
    }
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
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(p), pc.dst_size))) {
        return;
    }
    float m;
    if (pc.level == 0u) {
        m = level0(p);
    } else {
        ivec2 last = ivec2(pc.src_size) - 1;
        ivec2 c = 2 * p;
        m = max(max(imageLoad(u_src, c).r, imageLoad(u_src, min(c + ivec2(1, 0), last)).r),
                max(imageLoad(u_src, min(c + ivec2(0, 1), last)).r, imageLoad(u_src, min(c + ivec2(1, 1), last)).r));
    }
    imageStore(u_dst, p, vec4(m));
}
