// Double-float arithmetic (a value as an unevaluated sum hi + lo of two f32s, about 48
// significant bits) for dispmap's pixel rays (dispmap_plane.glsl) and the `pyramid`
// traversal (glsl/common/pyramid.glsl). Host shaders get it with dispmap_plane.glsl.
//
// Exact products and sums (Dekker 1971, Knuth): the error of an f32 product or sum as a
// second f32, from correctly rounded adds and multiplies (Vulkan's precision for them),
// every step `precise` so that nothing is reassociated or contracted. Not fma: lavapipe
// does not fuse it (fma(a, b, -a * b) is 0 there), so an fma-based error term silently
// vanishes on a CPU driver. Division is not correctly rounded in Vulkan (2.5 ulp): the
// quotient below corrects its f32 estimates with exact remainders, so its result does
// not depend on the division's last bits beyond the double-float's own precision.
#ifndef DISPMAP_INCLUDE_DOUBLE_FLOAT_GLSL
#define DISPMAP_INCLUDE_DOUBLE_FLOAT_GLSL

// Veltkamp's split: x = hi + lo exactly, each half with at most 12 significant bits, so
// that a product of two halves is exact in f32.
vec2 dispmap_split_f32(float x) {
    precise float c = 4097.0 * x;
    precise float hi = c - (c - x);
    precise float lo = x - hi;
    return vec2(hi, lo);
}

// a b = p + e exactly; `bs` is dispmap_split_f32(b).
float dispmap_two_product(float a, float b, vec2 bs, out float e) {
    vec2 as_ = dispmap_split_f32(a);
    precise float p = a * b;
    precise float err = ((as_.x * bs.x - p) + as_.x * bs.y + as_.y * bs.x) + as_.y * bs.y;
    e = err;
    return p;
}

// a + b = s + e exactly.
float dispmap_two_sum(float a, float b, out float e) {
    precise float s = a + b;
    precise float bv = s - a;
    precise float err = (a - (s - bv)) + (b - bv);
    e = err;
    return s;
}

// a + b = (s, e) exactly, for |a| >= |b| (or a = 0).
vec2 dispmap_df_fast_two_sum(float a, float b) {
    precise float s = a + b;
    precise float e = b - (s - a);
    return vec2(s, e);
}

// a + b (double-floats).
vec2 dispmap_df_add(vec2 a, vec2 b) {
    float e;
    float s = dispmap_two_sum(a.x, b.x, e);
    precise float t = e + (a.y + b.y);
    return dispmap_df_fast_two_sum(s, t);
}

// a * b (a double-float times an f32).
vec2 dispmap_df_mul_f(vec2 a, float b) {
    float e;
    float p = dispmap_two_product(a.x, b, dispmap_split_f32(b), e);
    precise float t = e + a.y * b;
    return dispmap_df_fast_two_sum(p, t);
}

// a * b (double-floats).
vec2 dispmap_df_mul(vec2 a, vec2 b) {
    float e;
    float p = dispmap_two_product(a.x, b.x, dispmap_split_f32(b.x), e);
    precise float t = e + (a.x * b.y + a.y * b.x);
    return dispmap_df_fast_two_sum(p, t);
}

// a / b (double-floats, b.x != 0): two f32 quotient estimates, each corrected by the
// exact remainder.
vec2 dispmap_df_div(vec2 a, vec2 b) {
    precise float q1 = a.x / b.x;
    vec2 r = dispmap_df_add(a, -dispmap_df_mul_f(b, q1));
    precise float q2 = r.x / b.x;
    r = dispmap_df_add(r, -dispmap_df_mul_f(b, q2));
    precise float q3 = r.x / b.x;
    return dispmap_df_add(dispmap_df_fast_two_sum(q1, q2), vec2(q3, 0.0));
}

#endif
