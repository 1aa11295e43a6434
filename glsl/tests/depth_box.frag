#version 460
// tests/depth.rs: the box is white.
layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(1.0);
}
