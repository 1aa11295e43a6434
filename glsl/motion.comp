#version 460
// motion: the screen motion of each displaced pixel, written into the host's motion image
// in place (src/passes/motion.rs documents the contract). For a pixel with a hit, p_hit
// is the displaced point seen through the pixel and p_entry the macro surface point under
// it (glsl/include/dispmap_displace.glsl, the code of hit_depth and of hosts), both as
// offsets from the current eye; prev_px(p) is a point's position in pixels under the
// previous frame's view-projection. The motion in pixels (previous minus current) is
//   source CAMERA:   prev_px(p_hit) - pixel centre            (a static world: exact)
//   source SURFACE:  prev_px(p_hit + t) - pixel centre,
// where t is the surface's own move since the previous frame: the host wrote the macro
// surface's motion m_entry at the pixel (its G-buffer pass); m_entry minus the camera's
// motion of the entry, prev_px(p_entry) - centre, is the surface's own screen motion, taken
// as a translation at constant previous view depth (exact for a static surface, where it
// is 0, and for a translation parallel to the image plane; the approximation
// src/passes/motion.rs measures for rotations and moves in depth). It is stored in the
// host's units and direction (flags). Pixels of other materials, without displacement or
// without a hit keep the image's value.
// Bindings: src/passes/motion.rs; push constants: src/abi.rs MotionParams.
// An R32G32_SFLOAT image with the WIDE variant, R16G16_SFLOAT without.
// dispmap-variant: WIDE
#include "frame.glsl"
#include "include/dispmap_displace.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0, rg32f) uniform readonly image2D u_hit_uv;
layout(set = 0, binding = 4, r32f) uniform readonly image2D u_hit_height;
layout(set = 0, binding = 1) uniform sampler2D u_ray;
layout(set = 0, binding = 2) uniform sampler2D u_depth;
layout(set = 0, binding = 3) uniform usampler2D u_frame;
#ifdef WIDE
layout(set = 0, binding = 5, rg32f) uniform image2D u_motion;
#else
layout(set = 0, binding = 5, rg16f) uniform image2D u_motion;
#endif

layout(push_constant) uniform MotionParams {
    mat4 inv_eye_clip;  // clip -> offset from the current eye (the current frame)
    vec4 prev_x_row;    // rows 0, 1 and 3 of previous view_proj * translation(current eye):
    vec4 prev_y_row;    // an offset from the current eye -> the previous frame's clip x,
    vec4 prev_w_row;    // y and w
    uvec2 frame_size;   // pixels
    float depth_scale;  // displacement depth in tile units
    uint material;      // bits 0-15: the material; 16-31: MOTION_* flags
} pc;

// Flags (src/passes/motion.rs: MotionParams::new).
#define MOTION_SURFACE 0x10000u  // add the host's macro motion (source SURFACE)
#define MOTION_UV 0x20000u       // units: pixels / frame size
#define MOTION_NDC 0x40000u      // units: 2 * pixels / frame size
#define MOTION_TO_CURRENT 0x80000u  // current minus previous (else previous minus current)

#define DISPMAP_TILE_PASS
#include "tiles.glsl"

// The previous frame's pixel position of an offset from the current eye; false behind
// the previous eye.
bool prev_pixel(vec3 p, out vec2 px) {
    vec4 q = vec4(p, 1.0);
    float w = dot(pc.prev_w_row, q);
    vec2 ndc = vec2(dot(pc.prev_x_row, q), dot(pc.prev_y_row, q)) / w;
    px = (ndc * 0.5 + 0.5) * vec2(pc.frame_size);
    return w > 0.0;
}

void main() {
    ivec2 pixel;
    if (!material_pixel(pc.material & 0xFFFFu, pc.frame_size, pixel)) {
        return;
    }
    float depth = texelFetch(u_depth, pixel, 0).r;
    vec4 hit = vec4(imageLoad(u_hit_uv, pixel).xy, imageLoad(u_hit_height, pixel).x, 0.0);
    if (depth <= 0.0 || hit.z < 0.0) {
        return;
    }
    vec2 centre = vec2(pixel) + 0.5;
    vec3 entry = dispmap_entry_eye_rel(pc.inv_eye_clip, centre, vec2(pc.frame_size), depth);
    vec2 uv0 = texelFetch(u_ray, pixel, 0).xy;
    DispmapFrame f = gbuffer_frame(pixel);
    vec3 p = dispmap_displaced_eye_rel(entry, hit, uv0, f.normal, f.tangent, f.handedness, pc.depth_scale);

    // Pixels -> the host's units and direction, and back.
    vec2 to_units = (pc.material & MOTION_UV) != 0u    ? 1.0 / vec2(pc.frame_size)
                    : (pc.material & MOTION_NDC) != 0u ? 2.0 / vec2(pc.frame_size)
                                                       : vec2(1.0);
    if ((pc.material & MOTION_TO_CURRENT) != 0u) {
        to_units = -to_units;
    }
    vec2 hit_prev;
    if (!prev_pixel(p, hit_prev)) {
        // Behind the previous eye: no previous position (the surface's motion, or 0).
        if ((pc.material & MOTION_SURFACE) == 0u) {
            imageStore(u_motion, pixel, vec4(0.0));
        }
        return;
    }
    vec2 motion = hit_prev - centre;
    if ((pc.material & MOTION_SURFACE) != 0u) {
        // The surface's own motion: the host's motion of the entry minus the camera's.
        vec2 entry_prev;
        if (!prev_pixel(entry, entry_prev)) {
            return;
        }
        vec2 own = imageLoad(u_motion, pixel).xy / to_units - (entry_prev - centre);
        // As a translation t of the surface at constant previous view depth (clip w):
        // rows x, y of the previous clip matrix move by own (in NDC) * w, row w by 0.
        mat3 rows = transpose(mat3(pc.prev_x_row.xyz, pc.prev_y_row.xyz, pc.prev_w_row.xyz));
        float w = dot(pc.prev_w_row, vec4(entry, 1.0));
        if (abs(determinant(rows)) > 0.0) {
            vec3 t = inverse(rows) * vec3(2.0 * own / vec2(pc.frame_size) * w, 0.0);
            // The displaced point moved with its surface.
            if (!prev_pixel(p + t, hit_prev)) {
                return;
            }
            motion = hit_prev - centre;
        }
    }
    imageStore(u_motion, pixel, vec4(motion * to_units, 0.0, 0.0));
}
