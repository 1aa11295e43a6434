#version 460
// dig: Depth Interval Grids (Judnich & Ling). The dig_corners pass has stored, per block
// corner, the ray height just above its hit (section 4); here each pixel takes its
// block's interval from the 4 surrounding corners widened by eps (equation 1) and
// refines inside it: a linear search with a fixed horizontal step, I_L = floor(|R_xy|/s)
// (equation 2), then I_B bisections (section 5). Blocks whose corners are not all on the
// pixel's surface use the unconstrained search. Details: glsl/common/dig.glsl.
// dispmap-variant: ITERATIONS
#include "trace.glsl"
#include "dig.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    float h_bottom, h_top;
    bool constrained = dig_interval(pixel, h_bottom, h_top);
    return dig_search(ray, constrained, h_bottom, h_top, iterations);
}
