#version 460
// pom: parallax occlusion mapping (Tatarchuk 2006, "Dynamic parallax occlusion mapping
// with approximate soft shadows", section 5).
//   1. Sample count from the view angle: n = n_max + (n_min - n_max) * dot(N, V), with
//      the artist bounds n_max = `steps`, n_min = `min_steps` (clamped to n_max). Here
//      dot(N, V) = -V.z of the tangent-space view vector, recovered from the parallax
//      vector P = depth_scale * V.xy / -V.z as 1 / sqrt(1 + |P / depth_scale|^2), which
//      needs no extra G-buffer channel and is exact for the unclamped P.
//   2. A linear march in n equal height steps from the macro surface (h = 1) with early
//      exit at the first sample on or below the surface.
//   3. The hit is the intersection of the ray with the line through the last two height
//      samples (the paper's piecewise-linear approximation of the height profile).
// Not here: the soft shadows (shading) and the LOD blend to bump mapping (trace_lod in
// trace.glsl, shared by every method).
// The march: pom_search in search.glsl (shared with the forward path); on curved meshes
// (TRACE_FLAG_CURVED) curved_march (curved.glsl) with the same sample count per unit t.
// dispmap-variant: ITERATIONS
// dispmap-variant: CURVED
// dispmap-variant: CURVED+ITERATIONS
#include "trace.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    if (CURVED_VARIANT && g_curve.k != 0.0) {
        return curved_march(ray, g_curve, pom_sample_count(ray, pc.steps, pc.min_steps, pc.depth_scale), 0u,
                            true);
    }
    return pom_search(ray, pc.steps, pc.min_steps, pc.depth_scale);
}
