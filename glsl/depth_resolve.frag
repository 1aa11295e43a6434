#version 460
// depth_resolve: copies the corrected depth (R32_SFLOAT, glsl/hit_depth.comp) into the
// bound D32_SFLOAT depth attachment, pixel for pixel, so later geometry, fog or SSAO
// depth-test against the displaced surface (src/passes/depth_resolve.rs).
layout(set = 0, binding = 0) uniform sampler2D u_hit_depth;

void main() {
    gl_FragDepth = texelFetch(u_hit_depth, ivec2(gl_FragCoord.xy), 0).r;
}
