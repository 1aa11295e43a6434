// Exact texel access to the height field: texelFetch with the map's addressing done by
// hand, and the bilinear surface from 4 texels in f32 (the surface the CPU reference
// intersects; the hardware filter may quantise its weights: 8 bits on lavapipe, which
// moves a grazing hit by many texels). Requires `u_height` and a push-constant block
// `pc` with an `addressing` member to be declared before inclusion.
#ifndef DISPMAP_TEXELS_GLSL
#define DISPMAP_TEXELS_GLSL

// i mod n in [0, n) for any sign of i, without integer division (CPU drivers such as
// lavapipe run `%` and `/` on ints one lane at a time; GPUs expand them into long
// sequences). The float quotient is exact in its inputs for |i|, n < 2^24 (texel
// coordinates of any ray a f32 position can resolve) and correctly rounded, so its floor
// is off by at most one: one fix-up each way makes the result exactly `i mod n`.
int wrap_index(int i, int n) {
    int r = i - int(floor(float(i) / float(n))) * n;
    r += r < 0 ? n : 0;
    return r >= n ? r - n : r;
}

// Texel p of the map, wrapped (repeat) or clamped (clamp) into it.
float texel_height(ivec2 p) {
    ivec2 size = textureSize(u_height, 0);
    if (pc.addressing == ADDRESSING_REPEAT) {
        p = ivec2(wrap_index(p.x, size.x), wrap_index(p.y, size.y));
    } else {
        p = clamp(p, ivec2(0), size - 1);
    }
    return texelFetch(u_height, p, 0).r;
}

// The 4 texels at the corners of cell c (texels c, c + (1, 0), c + (0, 1), c + (1, 1)),
// wrapped or clamped as texel_height does, by one textureGather with the map's own
// sampler (whose addressing is the map's) instead of 4 fetches with the addressing by
// hand. The cell is first brought into the map (wrapped; or clamped to -1 .. size - 1,
// which clamps to the same texels), so the gather point, the corner the 4 texels share at
// (c + 1) / size, is within a texel of [0, 1]: half a texel from any other choice of
// texels, which rounding cannot cross. Components: x = (c.x, c.y + 1), y = (c.x + 1,
// c.y + 1), z = (c.x + 1, c.y), w = (c.x, c.y).
vec4 cell_texels(ivec2 c) {
    ivec2 size = textureSize(u_height, 0);
    if (pc.addressing == ADDRESSING_REPEAT) {
        c = ivec2(wrap_index(c.x, size.x), wrap_index(c.y, size.y));
    } else {
        c = clamp(c, ivec2(-1), size - 1);
    }
    return textureGather(u_height, vec2(c + 1) / vec2(size), 0);
}

// The bilinear height at uv (texel centres at (i + 0.5) / size), nested-lerp form.
float height_exact(vec2 uv) {
    vec2 x = uv * vec2(textureSize(u_height, 0)) - 0.5;
    vec2 cf = floor(x);
    vec2 f = x - cf;
    vec4 g = cell_texels(ivec2(cf));
    float h00 = g.w;
    float h10 = g.z;
    float h01 = g.x;
    float h11 = g.y;
    float top = h00 + (h10 - h00) * f.x;
    float bottom = h01 + (h11 - h01) * f.x;
    return top + (bottom - top) * f.y;
}

#endif
