#version 460
// shade: lights the hit. The normal comes from the height field at the hit uv (central
// differences), the light is directional (Lambert + Blinn-Phong), the albedo is a stone
// colour darkened with depth (a cheap cavity term that makes the relief readable).
// Output: rgba8 (sRGB-encoded values in a UNORM storage image).
// SHADOWS variant (self-shadowing on): binding 7 holds the `shadow` pass's light
// visibility (1 = lit), which scales the direct light (diffuse and specular).
// dispmap-variant: SHADOWS
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The hit images: uv and height (< 0: no hit).
layout(set = 0, binding = 0, rg32f) uniform readonly image2D u_hit_uv;
layout(set = 0, binding = 2, r32f) uniform readonly image2D u_hit_height;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
layout(set = 0, binding = 3) uniform sampler2D u_height;
layout(set = 0, binding = 4, rgba8) uniform writeonly image2D u_color;
// Optional maps (src/material.rs): alpha 0 = the map is present; without one the height
// field is bound here and samples with alpha 1.
layout(set = 0, binding = 5) uniform sampler2D u_albedo;
layout(set = 0, binding = 6) uniform sampler2D u_normal_map;
#ifdef SHADOWS
layout(set = 0, binding = 7, r16f) uniform readonly image2D u_visibility;
#endif
// G-buffer depth (which pixels have geometry: glsl/common/tiles.glsl).
layout(set = 0, binding = 8) uniform sampler2D u_depth;

layout(push_constant) uniform ShadeParams {
    mat4 inv_view_proj;  // clip -> world
    vec4 camera_pos;     // xyz; w: the material this dispatch shades (an integer)
    vec4 light_dir;      // xyz: unit vector towards the light; w: intensity
    uvec2 frame_size;
    uvec2 map_size;
    float depth_scale;
    float ambient;
    float specular;
    float shininess;
} pc;

#include "heightfield.glsl"
#define DISPMAP_TILE_PASS
#include "tiles.glsl"

#include "sky.glsl"

// One workgroup per tile of the material's list; other pixels keep the host's colour.
void main() {
    ivec2 pixel;
    if (!material_pixel(uint(pc.camera_pos.w), pc.frame_size, pixel)) {
        return;
    }
    // View direction from the pixel alone (no depth needed).
    vec2 ndc = (vec2(pixel) + 0.5) / vec2(pc.frame_size) * 2.0 - 1.0;
    vec4 far_point = pc.inv_view_proj * vec4(ndc, 0.5, 1.0);
    vec3 V = normalize(far_point.xyz / far_point.w - pc.camera_pos.xyz);

    vec4 hit = vec4(imageLoad(u_hit_uv, pixel).xy, imageLoad(u_hit_height, pixel).x, 0.0);
    if (hit.z < 0.0) {
        // A ray that left the decal: the sky.
        imageStore(u_color, pixel, vec4(sky_color(V), 1.0));
        return;
    }
    DispmapFrame f = gbuffer_frame(pixel);
    vec3 N = f.normal;
    vec3 T = f.tangent;
    vec3 B = gbuffer_bitangent(f);
    vec3 n_ts = height_normal(hit.xy, vec2(pc.map_size), pc.depth_scale);
    vec4 normal_map = textureLod(u_normal_map, hit.xy, 0.0);
    if (normal_map.a < 0.5) {
        n_ts = normalize(normal_map.xyz * 2.0 - 1.0);
    }
    vec3 n = normalize(n_ts.x * T + n_ts.y * B + n_ts.z * N);

    vec3 L = pc.light_dir.xyz;
    vec3 H = normalize(L - V);
    float diffuse = max(dot(n, L), 0.0);
    float spec = diffuse > 0.0 ? pc.specular * pow(max(dot(n, H), 0.0), pc.shininess) : 0.0;
    vec4 albedo_map = textureLod(u_albedo, hit.xy, 0.0);
    vec3 base = albedo_map.a < 0.5 ? albedo_map.rgb : vec3(0.62, 0.55, 0.47);
    vec3 albedo = base * mix(0.35, 1.0, hit.z);
    float light = pc.light_dir.w;
#ifdef SHADOWS
    light *= imageLoad(u_visibility, pixel).r;
#endif
    vec3 color = albedo * (pc.ambient + light * diffuse) + vec3(spec * light);
    imageStore(u_color, pixel, vec4(srgb_encode(color), 1.0));
}
