#version 460
// exact (beyond the papers; in the spirit of maximum mipmaps, Tevs, Ihrke & Seidel 2008):
// the cell-max pyramid bounds every bilinear cell (level 0: the max of its 4 corner
// texels; above: the max of the children), so a skipped node can never hold a part of
// the surface the ray reaches; the leaf cell is intersected exactly (the quadratic of
// the bilinear patch along the ray, stable root, bisection when rounding defeats the
// closed form). See glsl/common/pyramid.glsl; it agrees with the CPU reference
// (cli/src/reference.rs) to f32 precision. The surface is the map's exact bilinear
// interpolation (texelFetch), not the hardware filter (8-bit weights on lavapipe).
//
// On curved meshes (TRACE_FLAG_CURVED, k = g_curve != 0: glsl/common/curved.glsl) the ray
// h(t) = 1 - t + k t^2 is traced as a polyline: its descending part (to the offset
// surface, or to the turning point t = 1 / 2k) in chords whose distance from the parabola
// is at most CURVE_CHORD_TOL of the depth, each chord a straight ray the pyramid
// intersects exactly; the part that climbs back to the base surface (k > 1/4, only near
// outlines) by a march in steps of at most one texel with the exact bilinear height,
// refined by bisection. No hit before the ray leaves the shell: a miss.
//
// For a pass given the meshes (src/mesh/walk.rs), a curved material is traced in four
// dispatches that walk the mesh's own triangles (glsl/common/walk.glsl) instead of the
// curved trace: the WALK+FIRST variant over the material's tiles (the flat trace, listing
// the pixels it cannot tell from the meshes' convex flat regions are the walk's), the
// CURVED+WALK+OVERLAP variant over those of them whose straight path in their flat region
// only passes the shells of overlapping flat regions (a cube's edges: those regions'
// relief intersected along it), the CURVED+WALK+TRIAGE variant over the others (keeping,
// resolving or listing each) and the CURVED+WALK variant over the pixels the triage
// listed (the walk; the circle model for a pixel on no walked triangle). Separate pipelines keep each program to the pixels that
// need it (a CPU driver runs every instruction of a program for every group of lanes,
// taken or not: the walk's code in the curved trace ran it about 2.5 times slower).
// dispmap-variant: ITERATIONS
// dispmap-variant: CURVED
// dispmap-variant: CURVED+ITERATIONS
// dispmap-variant: CURVED+WALK
// dispmap-variant: CURVED+WALK+ITERATIONS
// dispmap-variant: CURVED+WALK+TRIAGE
// dispmap-variant: CURVED+WALK+OVERLAP
// dispmap-variant: WALK+FIRST
// dispmap-variant: WALK+FIRST+ITERATIONS
#include "trace.glsl"
#include "pyramid.glsl"
#ifdef WALK
#include "walk.glsl"

// The eye-relative entry point of `pixel` (its macro surface point) and the eye's world
// position: where every walk step starts.
vec3 walk_pixel_entry(ivec2 pixel) {
    return curve_position(pixel, texelFetch(u_depth, pixel, 0).r);
}
vec3 walk_pixel_eye() {
    return vec3(pc.view_origin.w, pc.view_dx.w, pc.view_dy.w);
}

#if defined(FIRST)
// What the first trace decides for `pixel` (its flat hit's height `h`).
int walk_pixel_first(ivec2 pixel, float h) {
    return walk_first(walk_pixel_entry(pixel), walk_pixel_eye(), gbuffer_frame(pixel).normal,
                      gbuffer_surface(pixel), h);
}
#elif defined(OVERLAP)
// The overlap step of `pixel` (its G-buffer ray `ray`): walk_region_overlaps' decision.
int walk_pixel_overlap(ivec2 pixel, Ray ray, out Hit hit) {
    hit = miss(ray, 0u);
    if ((pc.flags & TRACE_FLAG_CURVED) == 0u) {
        return WALK_OVERLAP_KEEP;
    }
    return walk_region_overlaps(ray, walk_pixel_entry(pixel), walk_pixel_eye(), gbuffer_frame(pixel).normal,
                                gbuffer_surface(pixel), imageLoad(u_hit_height, pixel).r, hit);
}
#elif defined(TRIAGE)
// The mesh walk's triage of `pixel` (its G-buffer ray `ray`): walk_triage's decision.
int walk_pixel_triage(ivec2 pixel, Ray ray, out Hit hit) {
    hit = miss(ray, 0u);
    if ((pc.flags & TRACE_FLAG_CURVED) == 0u) {
        return WALK_KEEP;
    }
    return walk_triage(ray, walk_pixel_entry(pixel), walk_pixel_eye(), gbuffer_frame(pixel).normal,
                       gbuffer_surface(pixel), imageLoad(u_hit_height, pixel).r, hit);
}
#else
// The walk of `pixel` (its G-buffer ray `ray`): true with its hit, false where the
// pixel takes the circle model (on no walked triangle).
bool walk_pixel(ivec2 pixel, Ray ray, out Hit hit) {
    hit = miss(ray, 0u);
    if ((pc.flags & TRACE_FLAG_CURVED) == 0u) {
        return false;
    }
    return walk_trace(ray, walk_pixel_entry(pixel), walk_pixel_eye(), gbuffer_frame(pixel).normal,
                      gbuffer_surface(pixel), hit);
}
#endif
#endif

// A chord's largest height error, as a fraction of the depth (1 / 1024: a quarter of an
// 8-bit height step).
const float CURVE_CHORD_TOL = 1.0 / 1024.0;
// Chords at most; steps of the climbing march at most; bisections of its crossing.
const float CURVE_MAX_CHORDS = 64.0;
const float CURVE_MAX_CLIMB_STEPS = 2048.0;
const uint CURVE_CLIMB_BISECTIONS = 24u;

Hit curved_exact(Ray ray, Curve c) {
    uint iterations = 0u;
    if (pc.addressing == ADDRESSING_CLAMP && (any(lessThan(ray.uv0, vec2(0.0))) || any(greaterThan(ray.uv0, vec2(1.0))))) {
        return miss(ray, iterations);
    }
    float qa = c.kappa + 2.0 * c.k;
    // The descending part: to the offset surface, or to the circle ray's lowest point.
    float t_desc = c.bottom ? c.t_end : (qa > 0.0 ? 1.0 / qa : c.t_end);
    // h'' is about 2 k + kappa along the ray.
    float bend = 2.0 * abs(c.k) + abs(c.kappa) + abs(c.g);
    float n = clamp(ceil(t_desc / sqrt(8.0 * CURVE_CHORD_TOL / bend)), 1.0, CURVE_MAX_CHORDS);
    int top = int(pc.pyramid_levels) - 1;
    float ta = 0.0;
    float ha = 1.0;
    float fa = 0.0;
    for (float i = 1.0; i <= n; i += 1.0) {
        float tb = i == n ? t_desc : t_desc * (i / n);
        float fb = curve_foot(c, tb);
        float hb = (i == n && c.bottom) ? 0.0 : curve_h_at(c, tb, fb);
        if (!(ha - hb > 1e-6)) {
            break;
        }
        vec2 uva = ray.uv0 + fa * ray.P;
        vec2 pc_dir = (ray.P * (fb - fa)) / (ha - hb);
        // The chord as a tangent-space ray h = 1 - s from (uva, ha): s in [1 - ha, 1 - hb].
        Ray chord = Ray(uva - (1.0 - ha) * pc_dir, pc_dir);
        float s = pyramid_segment_hit(chord, 1.0 - ha, 1.0 - hb, top, iterations);
        if (s >= 0.0) {
            return Hit(uva + (s - (1.0 - ha)) * pc_dir, 1.0 - s, iterations);
        }
        ta = tb;
        ha = hb;
        fa = fb;
    }
    if (c.bottom && ta >= c.t_end) {
        // The last chord ends on the offset surface, which every height reaches: only a
        // clamp ray that left the decal gets here.
        return miss(ray, iterations);
    }
    // The rest, from ta (the turning point, or the last chord too flat to intersect) to
    // t_end (back out through the base surface, or the offset surface).
    float t_top = c.t_end;
    float travel = length(ray.P * vec2(pc.map_size)) * (curve_foot(c, t_top) - curve_foot(c, ta));
    float m = clamp(ceil(travel), 1.0, CURVE_MAX_CLIMB_STEPS);
    float dt = (t_top - ta) / m;
    float t_prev = ta;
    float t = ta;
    bool crossed = false;
    // The crossing's bisection after the loop, not inside it (once per SIMD group of
    // lanes on a CPU device).
    for (float j = 1.0; j <= m; j += 1.0) {
        t = j == m ? t_top : ta + j * dt;
        vec2 uv;
        float h = curve_point(c, ray, t, uv);
        if (leaves_domain(uv)) {
            break;
        }
        iterations += 1u;
        h = (j == m && c.bottom) ? 0.0 : h;
        if (height_exact(uv) >= h) {
            crossed = true;
            break;
        }
        t_prev = t;
    }
    if (!crossed) {
        return miss(ray, iterations);
    }
    float t_above = t_prev;
    float t_below = t;
    for (uint b = 0u; b < CURVE_CLIMB_BISECTIONS; ++b) {
        float t_mid = 0.5 * (t_above + t_below);
        iterations += 1u;
        vec2 uv_mid;
        float h_mid = curve_point(c, ray, t_mid, uv_mid);
        if (height_exact(uv_mid) >= h_mid) {
            t_below = t_mid;
        } else {
            t_above = t_mid;
        }
    }
    vec2 uv_below;
    float h_below = curve_point(c, ray, t_below, uv_below);
    return Hit(uv_below, h_below, iterations);
}

Hit trace_ray(Ray ray, ivec2 pixel) {
    if (CURVED_VARIANT && g_curve.k != 0.0) {
        return curved_exact(ray, g_curve);
    }
    uint iterations = 0u;
    float t = pyramid_first_hit(ray, 0.0, 1.0, iterations);
    if (t < 0.0) {
        return miss(ray, iterations);
    }
    return hit_at_t(ray, t, iterations);
}
