#version 460
// depth_resolve: merges the corrected depth (R32_SFLOAT, glsl/hit_depth.comp) into the
// bound D32_SFLOAT depth attachment: a pixel whose G-buffer frame names a material
// (glsl/common/tiles.glsl) gets its corrected depth, every other pixel (flat geometry, no
// geometry) keeps the attachment's depth (discarded fragment), so later geometry, fog or
// SSAO depth-test against the displaced surface and the host's own surfaces alike
// (src/passes/depth_resolve.rs).
layout(set = 0, binding = 0) uniform sampler2D u_hit_depth;
layout(set = 0, binding = 1) uniform usampler2D u_frame;

#include "tiles.glsl"

void main() {
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    if (gbuffer_material(pixel) == NOT_DISPLACED) {
        discard;
    }
    gl_FragDepth = texelFetch(u_hit_depth, pixel, 0).r;
}
