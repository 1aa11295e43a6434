#version 460
// tests/depth.rs: an axis-aligned box drawn from gl_VertexIndex (36 vertices, no vertex
// buffer), depth-tested against the resolved corrected depth.
layout(push_constant) uniform BoxParams {
    mat4 view_proj;
    vec4 box_min;  // xyz
    vec4 box_max;  // xyz
} pc;

const int FACES[36] = int[36](
    0, 2, 1, 1, 2, 3,  4, 5, 6, 5, 7, 6,  0, 1, 4, 1, 5, 4,
    2, 6, 3, 3, 6, 7,  0, 4, 2, 2, 4, 6,  1, 3, 5, 3, 7, 5);

void main() {
    int c = FACES[gl_VertexIndex];
    vec3 t = vec3(float(c & 1), float((c >> 1) & 1), float((c >> 2) & 1));
    vec3 p = mix(pc.box_min.xyz, pc.box_max.xyz, t);
    gl_Position = pc.view_proj * vec4(p, 1.0);
}
