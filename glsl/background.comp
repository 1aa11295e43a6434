#version 460
// background: the standalone renderer's own shading of what the displacement pass leaves
// alone (src/passes/background.rs), recorded before the pass: pixels without geometry get
// the sky (glsl/common/sky.glsl), pixels of flat geometry (G-buffer frame's material 0: not
// displaced) the Lambert and Blinn-Phong light of shade.comp on their G-buffer normal with
// a grey albedo. Displaced pixels are not written (the pass's `shade` writes them).
// BEHIND variant (the behind layer's G-buffer, glsl/include/dispmap_behind.glsl): pixels
// without geometry keep their colour (the first layer's), only flat geometry is lit, and
// only the tiles of the list of missed tiles (glsl/behind_cull.comp) are run: one
// workgroup per listed tile (an indirect dispatch), the layer has no geometry elsewhere.
// dispmap-variant: BEHIND
#include "frame.glsl"
#include "sky.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_depth;
layout(set = 0, binding = 1) uniform usampler2D u_frame;
#include "tiles.glsl"
layout(set = 0, binding = 3, rgba8) uniform writeonly image2D u_color;
#ifdef BEHIND
// The missed tiles (glsl/behind_cull.comp): a dispatch, the count, then the tiles.
layout(set = 0, binding = 4, std430) readonly buffer BehindTiles {
    uvec4 header;
    uint tiles[];
} u_behind_tiles;
#endif

layout(push_constant) uniform ShadeParams {
    mat4 inv_view_proj;  // clip -> world
    vec4 camera_pos;     // xyz
    vec4 light_dir;      // xyz: unit vector towards the light; w: intensity
    uvec2 frame_size;
    uvec2 map_size;
    float depth_scale;
    float ambient;
    float specular;
    float shininess;
} pc;

void main() {
#ifdef BEHIND
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    if (index >= u_behind_tiles.header.w) {
        return;
    }
    uint t = u_behind_tiles.tiles[index];
    ivec2 pixel = ivec2(t & 0xFFFFu, t >> 16) * LOCAL_SIZE + ivec2(gl_LocalInvocationID.xy);
#else
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
#endif
    if (any(greaterThanEqual(uvec2(pixel), pc.frame_size))) {
        return;
    }
    // The G-buffer first: the behind layer's is empty at nearly every pixel.
    bool geometry = texelFetch(u_depth, pixel, 0).r > 0.0;
#ifdef BEHIND
    if (!geometry) {
        return;
    }
#endif
    if (geometry && gbuffer_material(pixel) != NOT_DISPLACED) {
        return;
    }
    vec2 ndc = (vec2(pixel) + 0.5) / vec2(pc.frame_size) * 2.0 - 1.0;
    vec4 far_point = pc.inv_view_proj * vec4(ndc, 0.5, 1.0);
    vec3 V = normalize(far_point.xyz / far_point.w - pc.camera_pos.xyz);
    if (!geometry) {
        imageStore(u_color, pixel, vec4(sky_color(V), 1.0));
        return;
    }
    vec3 n = gbuffer_normal(pixel);
    vec3 L = pc.light_dir.xyz;
    vec3 H = normalize(L - V);
    float diffuse = max(dot(n, L), 0.0);
    float spec = diffuse > 0.0 ? pc.specular * pow(max(dot(n, H), 0.0), pc.shininess) : 0.0;
    vec3 albedo = vec3(0.55, 0.56, 0.58);
    float light = pc.light_dir.w;
    vec3 color = albedo * (pc.ambient + light * diffuse) + vec3(spec * light);
    imageStore(u_color, pixel, vec4(srgb_encode(color), 1.0));
}
