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

// The bilinear height at uv (texel centres at (i + 0.5) / size), nested-lerp form.
float height_exact(vec2 uv) {
    vec2 x = uv * vec2(textureSize(u_height, 0)) - 0.5;
    vec2 cf = floor(x);
    vec2 f = x - cf;
    ivec2 c = ivec2(cf);
    float h00 = texel_height(c);
    float h10 = texel_height(c + ivec2(1, 0));
    float h01 = texel_height(c + ivec2(0, 1));
    float h11 = texel_height(c + ivec2(1, 1));
    float top = h00 + (h10 - h00) * f.x;
    float bottom = h01 + (h11 - h01) * f.x;
    return top + (bottom - top) * f.y;
}

#endif
