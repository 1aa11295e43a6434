#version 460
// exact (beyond the papers; in the spirit of maximum mipmaps, Tevs, Ihrke & Seidel 2008):
// the cell-max pyramid bounds every bilinear cell (level 0: the max of its 4 corner
// texels; above: the max of the children), so a skipped node can never hold a part of
// the surface the ray reaches; the leaf cell is intersected exactly (the quadratic of
// the bilinear patch along the ray, stable root, bisection when rounding defeats the
// closed form). See glsl/common/pyramid.glsl; it agrees with the CPU reference
// (cli/src/reference.rs) to f32 precision. The surface is the map's exact bilinear
// interpolation (texelFetch), not the hardware filter (8-bit weights on lavapipe).
#include "trace.glsl"
#include "pyramid.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    uint iterations = 0u;
    float t = pyramid_first_hit(ray, 0.0, 1.0, iterations);
    if (t < 0.0) {
        return miss(ray, iterations);
    }
    return hit_at_t(ray, t, iterations);
}
