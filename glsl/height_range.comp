#version 460
// height_range: the lowest and highest texel of a height map's level 0, as the passes
// read it (texelFetch: a host map's channel as the GPU decodes it). See
// src/passes/height_range.rs.
//
// Each invocation reduces a BLOCK x BLOCK block of texels, the workgroup its 8x8 blocks
// in shared memory, and one invocation per workgroup merges the workgroup's result into
// u_range with atomicMin / atomicMax on order-preserving keys of the float bits (`key`:
// for every pair of non-NaN floats a < b iff key(a) < key(b), -0 just below +0), so the
// result is exact and independent of the order the workgroups run in. u_range enters
// as (0xffffffff, 0): every key is at most the first and at least the second.
#include "frame.glsl"

#define BLOCK 4

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_height;
layout(set = 0, binding = 1, std430) buffer HeightRange {
    uint lo_key;
    uint hi_key;
} u_range;

shared float s_lo[LOCAL_SIZE * LOCAL_SIZE];
shared float s_hi[LOCAL_SIZE * LOCAL_SIZE];

uint key(float h) {
    uint bits = floatBitsToUint(h);
    return (bits & 0x80000000u) != 0u ? ~bits : bits | 0x80000000u;
}

void main() {
    ivec2 size = textureSize(u_height, 0);
    ivec2 origin = ivec2(gl_GlobalInvocationID.xy) * BLOCK;
    float lo = uintBitsToFloat(0x7f800000u);  // +inf
    float hi = -lo;
    for (int j = 0; j < BLOCK; j++) {
        for (int i = 0; i < BLOCK; i++) {
            ivec2 p = origin + ivec2(i, j);
            if (all(lessThan(p, size))) {
                float h = texelFetch(u_height, p, 0).r;
                lo = min(lo, h);
                hi = max(hi, h);
            }
        }
    }
    uint me = gl_LocalInvocationIndex;
    s_lo[me] = lo;
    s_hi[me] = hi;
    barrier();
    for (uint half_n = LOCAL_SIZE * LOCAL_SIZE / 2; half_n > 0u; half_n /= 2u) {
        if (me < half_n) {
            s_lo[me] = min(s_lo[me], s_lo[me + half_n]);
            s_hi[me] = max(s_hi[me], s_hi[me + half_n]);
        }
        barrier();
    }
    // Every workgroup read at least one texel (the dispatch covers the map's blocks only;
    // the outside invocations of a partial one keep +-inf, which min / max ignore).
    if (me == 0u) {
        atomicMin(u_range.lo_key, key(s_lo[0]));
        atomicMax(u_range.hi_key, key(s_hi[0]));
    }
}
