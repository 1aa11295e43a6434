#version 460
// behind_mask: the behind layer's mask of the pixels it may cover
// (src/passes/behind_mask.rs, glsl/include/dispmap_behind.glsl). A pixel whose first-layer
// trace missed is discarded (left to the layer's objects); every other pixel is written
// with the attachments' clear values (zero ray and frame) at the triangle's depth, so
// that drawn at depth 1 before the objects it fails their GREATER depth test early (no
// fragment shading there), and drawn at depth 0 after them it is cleared again. The
// CURVE variant (a G-buffer with the curve image) writes it too, as zero.
// dispmap-variant: CURVE
#include "include/dispmap_behind.glsl"
// The first layer's G-buffer depth and hit height.
layout(set = 0, binding = 0) uniform sampler2D u_first_depth;
layout(set = 0, binding = 1, r32f) uniform readonly image2D u_first_hit_height;

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;
#ifdef CURVE
layout(location = 2) out vec2 out_curve;
#endif

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    if (dispmap_behind_missed(imageLoad(u_first_hit_height, pixel).x,
                              texelFetch(u_first_depth, pixel, 0).r)) {
        discard;
    }
    out_ray = vec4(0.0);
    out_frame = uvec2(0u);
#ifdef CURVE
    out_curve = vec2(0.0);
#endif
}
