// Reading the host's G-buffer in dispmap's passes: the decoders of the frame target
// (glsl/include/dispmap_gbuffer.glsl packs it and documents every bit). A shader that
// includes this file declares `usampler2D u_frame` (the G-buffer's frame, R32G32_UINT)
// before it; readers go through these functions, never through the bits.
#ifndef DISPMAP_GBUFFER_GLSL
#define DISPMAP_GBUFFER_GLSL

#include "../include/dispmap_gbuffer.glsl"

// The material index of a pixel without displacement (src/abi.rs: NOT_DISPLACED).
#define NOT_DISPLACED 0xFFFFFFFFu
// Materials a pass may hold (src/abi.rs: MAX_MATERIALS; the frame's 11-bit field holds
// index + 1).
#define MAX_MATERIALS 1024u

// The frame's two words at `pixel`.
uvec2 gbuffer_frame_bits(ivec2 pixel) {
    return texelFetch(u_frame, pixel, 0).xy;
}

// The material of a frame (NOT_DISPLACED for 0 and for indices past the table).
uint gbuffer_frame_material(uvec2 bits) {
    uint m = dispmap_frame_material_plus_one(bits);
    return m == 0u || m > MAX_MATERIALS ? NOT_DISPLACED : m - 1u;
}

// The material written at `pixel` (NOT_DISPLACED: not displaced); the caller checks the
// depth for geometry.
uint gbuffer_material(ivec2 pixel) {
    return gbuffer_frame_material(gbuffer_frame_bits(pixel));
}

// The surface id at `pixel` (1..2048, a float as DIG's corner grid keeps it).
float gbuffer_surface(ivec2 pixel) {
    return float(dispmap_frame_surface_id(gbuffer_frame_bits(pixel)));
}

// The unit normal at `pixel`.
vec3 gbuffer_normal(ivec2 pixel) {
    return dispmap_frame_normal(gbuffer_frame_bits(pixel));
}

// The whole frame at `pixel`: N, T, handedness, material, surface id.
DispmapFrame gbuffer_frame(ivec2 pixel) {
    return dispmap_frame_unpack(gbuffer_frame_bits(pixel));
}

// The unit bitangent of a decoded frame (along +v).
vec3 gbuffer_bitangent(DispmapFrame f) {
    return f.handedness * cross(f.normal, f.tangent);
}

#endif
