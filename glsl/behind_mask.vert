#version 460
// behind_mask: one triangle covering the viewport at the depth the push constant gives
// (src/passes/behind_mask.rs): 1 (reverse-Z nearest) to block the pixels the behind layer
// leaves empty before its objects are drawn, 0 (the clear value) to restore them after.
layout(push_constant) uniform MaskParams {
    float depth;
} pc;

void main() {
    vec2 p = vec2(float((gl_VertexIndex << 1) & 2), float(gl_VertexIndex & 2));
    gl_Position = vec4(p * 2.0 - 1.0, pc.depth, 1.0);
}
