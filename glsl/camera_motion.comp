#version 460
// camera_motion: the standalone renderer's motion vectors of its static world (as an
// engine's camera-motion pass writes its velocity buffer from depth), recorded before the
// displacement pass, whose `motion` stage then corrects the displaced pixels
// (src/passes/camera_motion.rs). Every pixel gets prev_px(x) - centre in pixels: x is the
// macro surface point under the pixel centre (unprojected from the G-buffer depth, as
// glsl/include/dispmap_displace.glsl does) or, without geometry, the view direction at
// infinity (depth 0 of the reverse-Z infinite projection unprojects to a point with
// w = 0, which the previous camera projects as a direction), projected by the previous
// frame's camera. Homogeneous throughout, so both cases are one formula.
// Push constants: src/abi.rs MotionParams (depth_scale and material unused).
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1, rg32f) uniform writeonly image2D u_motion;

layout(push_constant) uniform MotionParams {
    mat4 inv_eye_clip;
    vec4 prev_x_row;
    vec4 prev_y_row;
    vec4 prev_w_row;
    uvec2 frame_size;
    float depth_scale;
    uint material;
} pc;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(pixel), pc.frame_size))) {
        return;
    }
    vec2 centre = vec2(pixel) + 0.5;
    vec2 ndc = centre / vec2(pc.frame_size) * 2.0 - 1.0;
    float depth = max(texelFetch(u_depth, pixel, 0).r, 0.0);
    vec4 x = pc.inv_eye_clip * vec4(ndc, depth, 1.0);
    float w = dot(pc.prev_w_row, x);
    vec2 motion = vec2(0.0);
    if (w > 0.0) {
        vec2 prev_ndc = vec2(dot(pc.prev_x_row, x), dot(pc.prev_y_row, x)) / w;
        motion = (prev_ndc * 0.5 + 0.5) * vec2(pc.frame_size) - centre;
    }
    imageStore(u_motion, pixel, vec4(motion, 0.0, 0.0));
}
