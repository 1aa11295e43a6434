// The standalone renderer's background and the sRGB encoding of its colour image, shared
// by glsl/shade.comp (a displaced ray that leaves a decal shows the sky) and
// glsl/background.comp (pixels without geometry).
#ifndef DISPMAP_SKY_GLSL
#define DISPMAP_SKY_GLSL

vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

// The sky seen along the unit view direction V: a vertical gradient (sRGB-encoded).
vec3 sky_color(vec3 V) {
    float t = clamp(0.5 - 0.5 * V.y, 0.0, 1.0);
    return srgb_encode(mix(vec3(0.45, 0.6, 0.8), vec3(0.85, 0.9, 0.95), t));
}

#endif
