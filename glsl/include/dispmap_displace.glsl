// The displaced surface point of a hit, for a host engine's shaders (its own motion
// vectors, decals, fog or reflections on the displaced surface) and for dispmap's own
// `hit_depth` and `motion` passes, so the corrected depth, the motion vectors and the
// host compute the same point from the same code.
//
// Inputs are what the pass and the G-buffer hold for a pixel (glsl/include/dispmap_gbuffer.glsl
// documents the G-buffer): the hit (uv.x, uv.y from the hit uv image, height in [0, 1] from the hit height image,
// height < 0 for no hit), the G-buffer's uv0 (ray.xy), N, T and the handedness of its
// frame (dispmap_frame_unpack in dispmap_gbuffer.glsl), the material's depth scale (tile units), and the entry point: the macro
// surface point under the pixel centre, which dispmap_entry_eye_rel unprojects from the
// G-buffer depth.
//
// Positions are offsets from the eye (world minus eye), and the matrices are eye-relative:
// eye_clip = view_proj * translation(eye) and its inverse (composed in f64 on the CPU:
// dispmap's HitDepthParams::new and MotionParams::new). A far pixel's small reverse-Z depth
// then never cancels large world coordinates. Add the eye for a world position.
//
//     p_hit = p_entry + T du + B dv - N (1 - h) depth_scale,   (du, dv) = hit.uv - uv0,
//
// with B = sign(handedness) * cross(N, T): uv and depth_scale are both in tile units and T,
// B are unit vectors, so one tile is one world unit along them. For a traced hit p_hit
// lies on the pixel's view ray (the G-buffer's tangent-space ray is the view ray).
#ifndef DISPMAP_INCLUDE_DISPLACE_GLSL
#define DISPMAP_INCLUDE_DISPLACE_GLSL

// The entry point (offset from the eye) of the pixel whose centre is `pixel_centre`
// (pixels, e.g. vec2(pixel) + 0.5) in a frame of `frame_size` pixels, at the G-buffer's
// reverse-Z `depth` (> 0), with inv_eye_clip = inverse(view_proj * translation(eye)).
vec3 dispmap_entry_eye_rel(mat4 inv_eye_clip, vec2 pixel_centre, vec2 frame_size, float depth) {
    vec2 ndc = pixel_centre / frame_size * 2.0 - 1.0;
    vec4 entry_h = inv_eye_clip * vec4(ndc, depth, 1.0);
    return entry_h.xyz / entry_h.w;
}

// The displaced point (offset from the eye) of `hit` seen through a pixel whose entry
// point is `entry_eye_rel` (see the top of this file for the formula and the inputs).
vec3 dispmap_displaced_eye_rel(vec3 entry_eye_rel, vec4 hit, vec2 uv0, vec3 N, vec3 T,
                               float handedness, float depth_scale) {
    vec3 B = (handedness < 0.0 ? -1.0 : 1.0) * cross(N, T);
    vec2 duv = hit.xy - uv0;
    return entry_eye_rel + T * duv.x + B * duv.y - N * ((1.0 - hit.z) * depth_scale);
}

// The clip-space position of an eye-relative point under eye_clip = view_proj *
// translation(eye) (the current frame's, or the previous frame's view-projection times
// translation(current eye) for where the point was drawn last frame).
vec4 dispmap_clip(mat4 eye_clip, vec3 p_eye_rel) {
    return eye_clip * vec4(p_eye_rel, 1.0);
}

#endif
