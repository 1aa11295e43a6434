#version 460
// bump: the cost floor. One height fetch at the entry point; the hit is the surface point
// below uv0 (uv0, H(uv0)), i.e. no parallax at all, shaded with the normal at uv0 as in
// plain bump mapping. Also the far-LOD fallback of the methods that blend to it.
// dispmap-variant: ITERATIONS
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    return bump_hit(ray);
}
