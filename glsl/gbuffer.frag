#version 460
// G-buffer pass, fragment stage: writes the tangent-space ray and the shading frame with
// the same include a host engine uses (glsl/include/dispmap_gbuffer.glsl documents every
// channel). The entry is the pixel's own centre ray met with the plane
// (dispmap_plane_pixel_ray, glsl/include/dispmap_plane.glsl), not the rasteriser's
// interpolation: fragments whose centre ray misses the plane or the quad are discarded,
// as are back faces (viewer below the surface: nothing to displace).
// BEHIND variant: the behind layer (glsl/include/dispmap_behind.glsl): a fragment is kept
// only at a pixel whose first-layer trace missed, behind the first layer's surface.
// CURVE variant: also writes the curve target (location 2) as 0, the plane's curvature,
// for a frame whose meshes write theirs.
// dispmap-variant: BEHIND
// dispmap-variant: CURVE
// dispmap-variant: BEHIND+CURVE
#include "gbuffer_params.glsl"
#include "include/dispmap_plane.glsl"
#include "include/dispmap_gbuffer.glsl"
#ifdef BEHIND
#include "include/dispmap_behind.glsl"
// The first layer's G-buffer depth and hit height.
layout(set = 0, binding = 1) uniform sampler2D u_first_depth;
layout(set = 0, binding = 2, r32f) uniform readonly image2D u_first_hit_height;
#endif

// The frame's pixel rays (src/abi.rs PixelRayParams; a uniform buffer: the push
// constants already take the 128 bytes every device guarantees).
layout(set = 0, binding = 0, std140) uniform PixelRayBlock {
    DispmapPixelRay u_pixel_ray;
};

layout(location = 0) out vec4 out_ray;
layout(location = 1) out uvec2 out_frame;
#ifdef CURVE
layout(location = 2) out vec2 out_curve;
#endif

// The id of the one surface this pass draws (DIG's same-surface test).
const float SURFACE_ID = 1.0;

void main() {
#ifdef CURVE
    out_curve = vec2(0.0);
#endif
#ifdef BEHIND
    // The layer's pixels first: everywhere else the fragment is discarded before the
    // pixel ray's double-float arithmetic (the depth this shader writes rules out the
    // early depth test that keeps the meshes' fragments to the behind mask).
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    float first_hit_height = imageLoad(u_first_hit_height, pixel).x;
    float first_depth = texelFetch(u_first_depth, pixel, 0).r;
    if (!dispmap_behind_missed(first_hit_height, first_depth)) {
        discard;
    }
#endif
    vec3 eye_rel;
    vec2 uv;
    float t;
    if (!dispmap_plane_pixel_ray(u_pixel_ray, gl_FragCoord.xy, pc.world_rect, pc.uv_rect,
                                 pc.addressing == DISPMAP_ADDRESSING_REPEAT, eye_rel, uv, t)) {
        discard;
    }
    // The entry's own depth, not the rasteriser's interpolation (dispmap_plane.glsl).
    gl_FragDepth = dispmap_plane_pixel_depth(pc.view_proj, eye_rel);
#ifdef BEHIND
    if (!dispmap_behind_keep(first_hit_height, first_depth, gl_FragDepth)) {
        discard;
    }
#endif
    // The quad lies on y = 0 with u along +x and v along +z.
    DispmapSurface s = DispmapSurface(eye_rel, vec3(0.0), uv, vec3(0.0, 1.0, 0.0),
        vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), SURFACE_ID, pc.depth_scale, pc.min_cos,
        pc.addressing);
    // camera_pos.w: the drawn object's material index + 1, or 0 for an object that is
    // not displaced (src/abi.rs GBufferParams; 1 = material 0 for a single object).
    uint material_plus_one = uint(pc.camera_pos.w);
    if (!dispmap_gbuffer_encode_material(s, max(material_plus_one, 1u) - 1u, out_ray, out_frame)) {
        discard;
    }
    if (material_plus_one == 0u) {
        dispmap_gbuffer_encode_flat(s.normal, s.tangent, SURFACE_ID, out_ray, out_frame);
    }
}
