// Height-field sampling. Requires `u_height` (sampler2D, linear filtering, the map's
// addressing) to be declared before inclusion.
#ifndef DISPMAP_HEIGHTFIELD_GLSL
#define DISPMAP_HEIGHTFIELD_GLSL

// The mip level height_at samples: 0 (the map itself) unless the trace pass sets it to
// the pixel's footprint level (level of detail on, glsl/common/trace.glsl), where the
// box-filtered mip chain (src/gpu/height_texture.rs) keeps the marchers from aliasing.
float g_height_lod = 0.0;

// Bilinear height in [0, 1] (1 = macro surface) at uv; texel centres at (i + 0.5) / W.
float height_at(vec2 uv) {
    return textureLod(u_height, uv, g_height_lod).r;
}

// Tangent-space normal (z out of the surface) of the displaced surface at uv.
// The surface is z = depth_scale * (H(u, v) - 1) in tile units; central differences one
// texel apart give dH/du and dH/dv.
vec3 height_normal(vec2 uv, vec2 map_size, float depth_scale) {
    vec2 texel = 1.0 / map_size;
    float hl = height_at(uv - vec2(texel.x, 0.0));
    float hr = height_at(uv + vec2(texel.x, 0.0));
    float hd = height_at(uv - vec2(0.0, texel.y));
    float hu = height_at(uv + vec2(0.0, texel.y));
    vec2 grad = vec2(hr - hl, hu - hd) / (2.0 * texel);
    return normalize(vec3(-depth_scale * grad, 1.0));
}

#endif
