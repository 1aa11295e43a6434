#version 460
// pyramid: pyramidal displacement mapping (Oh, Ki & Lee 2006).
//
// Section 3.1, the pyramid: level 0 bounds each texel, every level above holds the
// maximum height (the paper's minimum displacement) of its 2x2 children, built on the GPU
// by the min-reduce chain (glsl/pyramid.comp, PYRAMID_KIND_FOOTPRINT). Choice where the
// paper is vague: the paper's level 0 is the texel itself (the point-sampled surface),
// but the surface it finally renders is the bilinear one (section 3.3), which can rise
// above a texel's value inside its footprint (Fig. 15/17); our level 0 is the maximum of
// the bilinear surface over the texel's footprint, so a node's bound holds for the
// surface that is shaded and no bump is jumped over.
//
// Section 3.2, the traversal, in texel-footprint coordinates x = u W (texel i covers
// [i, i + 1)): start at the root with the ray advanced to the root's bound; at each
// level read the node holding the ray's current point; if the ray is above the node's
// bound, advance it to that bound (P' = P + E d) when that point is still inside the
// node, and go down a level; if the advance would leave the node, stop at the node's
// boundary instead (the nearest boundary plane when both x and y are crossed, Fig. 12),
// step into the neighbouring node and go one level up (a crossing may need a coarser
// node again); if the ray is not above the bound, go down a level.
//
// Section 3.3, bilinear magnification: at the leaf the ray has reached the bound of the
// texel; the bilinear height is sampled half a texel backward (P_b) and half a texel
// forward (P_f) along the ray, with a = ray - surface at P_b and b = surface - ray at P_f,
// and the hit is lerp(P_b, P_f, a / (a + b)). When P_f is still above the surface the
// bilinear surface was not hit ("do not stop tracing", Fig. 17): the ray moves on to P_f
// and the traversal resumes at the current level. The backward point is never placed
// before the point where the traversal entered the leaf (the ray is above the surface
// all the way there, as every bound passed was conservative). Beyond the paper: when
// P_f is above the surface, the eighths of [P, P_f] are tested too (the first one below
// the surface replaces P_f): a grazing ray can dip under a ridge and leave it again
// within half a texel, which the two samples cannot see. Measured on issue 3's scenes:
// the paper's two samples give 0.08-0.29% artifacts, quarter checks 0.05-0.18% for
// about 5% more fetches, eighth checks 0.016-0.081% for about 10% more (the issue's
// 0.1% on every scene); every remaining miss dips less than 1.8e-3 of the depth under
// the surface (tests/methods.rs: PYRAMID_SKIM).
//
// Section 3.4, minification: the traversal stops at a coarsest level (`--max-level`, or
// with TRACE_FLAG_AUTO_LEVEL the floor of footprint_level in trace.glsl: the log2 of the
// pixel's texel footprint from the G-buffer's neighbouring entry points, the same level
// the LOD blend uses); a hit at a level above 0 is where the ray meets that node's bound, without the bilinear refinement (the surface flattens with distance, as
// in the paper's Fig. 18).
//
// Iterations: one per pyramid fetch, two per refinement, one per eighth check.
// dispmap-variant: ITERATIONS
#include "trace.glsl"
#include "pyramid.glsl"

Hit trace_ray(Ray ray, ivec2 pixel) {
    ivec2 n_cells = ivec2(pc.map_size);
    vec2 dims = vec2(pc.map_size);
    vec2 origin, dir;
    texel_ray_at(ray, 0.0, origin, dir);
    int top = int(pc.pyramid_levels) - 1;
    int leaf = min(int(pc.max_level), top);
    if ((pc.flags & TRACE_FLAG_AUTO_LEVEL) != 0u) {
        // The shared footprint level (trace.glsl), set by main().
        leaf = min(int(floor(g_footprint_level)), top);
    }
    float t_end = 1.0;
    if (pc.addressing == ADDRESSING_CLAMP) {
        if (leaves_domain(ray.uv0)) {
            return miss(ray, 0u);
        }
        for (int a = 0; a < 2; ++a) {
            if (dir[a] > 0.0) {
                t_end = min(t_end, (dims[a] - origin[a]) / dir[a]);
            } else if (dir[a] < 0.0) {
                t_end = min(t_end, -origin[a] / dir[a]);
            }
        }
        t_end = max(t_end, 0.0);
    }
    uint iterations = 1u;
    // The root: advance the ray to its bound.
    float t = max(0.0, 1.0 - texelFetch(u_pyramid, ivec2(0), top).r);
    // Half a texel along the ray's dominant axis, in t.
    float half_texel = 0.5 / max(max(abs(dir.x), abs(dir.y)), 1e-30);
    // Where the ray is known to be above the surface (the start of the leaf's search).
    float t_safe = t;
    int level = top;
    ivec2 cell = ivec2(0);
    bool fresh = true; // the cell must be recomputed from t
    float span = abs(dir.x) + abs(dir.y) + 4.0;
    float cap = min(4.0 * float(top + 2) * span + 64.0, TRAVERSAL_CAP);
    // Two loops: the inner one only traverses until the ray sits on a leaf's bound; the
    // leaf's refinement follows it, and when the bilinear surface is not hit the
    // traversal resumes. The same steps in the same order as one loop with the refinement
    // inside it, but a SIMD CPU driver (lavapipe runs 8 pixels in lockstep with masks)
    // pays for a branch that any lane takes on every iteration: inside the traversal
    // loop the refinement's ten fetches were paid whenever any pixel of the group was at
    // a leaf; here a group pays once per round in which its pixels reach their leaves.
    float step = 0.0;
    while (step < cap && t <= t_end) {
        bool at_leaf = false;
        for (; step < cap && t <= t_end; step += 1.0) {
            if (fresh) {
                for (int a = 0; a < 2; ++a) {
                    int c = cell_at_precise(origin, dir, a, t, 0.0);
                    cell[a] = pc.addressing == ADDRESSING_CLAMP ? clamp(c, 0, n_cells[a] - 1) : c;
                }
                fresh = false;
            }
            ivec2 lo, hi, node;
            node_range(cell.x, n_cells.x, level, lo.x, hi.x, node.x);
            node_range(cell.y, n_cells.y, level, lo.y, hi.y, node.y);
            iterations += 1u;
            float bound = texelFetch(u_pyramid, node, level).r;
            vec2 exit = vec2(1e30);
            for (int a = 0; a < 2; ++a) {
                if (dir[a] > 0.0) {
                    exit[a] = (float(hi[a]) - origin[a]) / dir[a];
                } else if (dir[a] < 0.0) {
                    exit[a] = (float(lo[a]) - origin[a]) / dir[a];
                }
            }
            float t_exit = max(min(exit.x, exit.y), t);
            float t_adv = 1.0 - bound;
            if (t_adv > t) {
                // The ray is above the node's bound.
                if (t_adv < t_exit) {
                    // Advance to the bound inside the node, then look closer.
                    t = t_adv;
                    t_safe = t;
                    if (level > leaf) {
                        level -= 1;
                        fresh = true;
                        continue;
                    }
                    // At the leaf: the leaf test below.
                } else {
                    // Node crossing: stop at the boundary, step across the nearest plane.
                    if (t_exit >= t_end) {
                        step = cap; // past the end: no leaf, stop both loops
                        break;
                    }
                    // Across the exit face at the exact crossing (pyramid.glsl:
                    // cross_exit), so that long rays keep their cells.
                    float exit_lo;
                    cross_exit(exit, lo, hi, origin, dir, 0.0, g_long_ray, t_exit, exit_lo, cell);
                    t = t_exit;
                    t_safe = t;
                    level = min(level + 1, top);
                    continue;
                }
            } else if (level > leaf) {
                // The ray is at or below the bound here: look closer.
                level -= 1;
                continue;
            }
            at_leaf = true;
            break;
        }
        if (!at_leaf) {
            break;
        }
        // Leaf reached with the ray on the texel's bound.
        if (leaf > 0) {
            return hit_at(ray, 1.0 - t, iterations);
        }
        float t_b = max(t - half_texel, t_safe);
        float t_f = min(t + half_texel, t_end);
        float h_b = 1.0 - t_b;
        float h_f = 1.0 - t_f;
        iterations += 2u;
        // Positions from t, not from h = 1 - t: near the top of the surface an ulp of h
        // is a long way along a grazing ray (6e-8 |P|: 3.5 texels of a 1024 map at
        // depth scale 1000 and 1 degree, more than the half-texel steps themselves).
        float a_above = max(h_b - height_exact(ray.uv0 + t_b * ray.P), 0.0);
        float b_below = height_exact(ray.uv0 + t_f * ray.P) - h_f;
        float t_below = t_f;
        if (b_below < 0.0) {
            // A ridge can rise above the ray and fall back within the step (a grazing
            // ray skimming a peak): also test [P, P_f] at its eighths and, at the first
            // one below the surface, take the crossing between P_b and that point.
            for (int q = 1; q <= 7; ++q) {
                float t_m = mix(t, t_f, 0.125 * float(q));
                float h_m = 1.0 - t_m;
                iterations += 1u;
                float b_mid = height_exact(ray.uv0 + t_m * ray.P) - h_m;
                if (b_mid >= 0.0) {
                    t_below = t_m;
                    b_below = b_mid;
                    break;
                }
            }
        }
        if (b_below >= 0.0) {
            float w = a_above + b_below > 0.0 ? a_above / (a_above + b_below) : 0.0;
            float t_hit = mix(t_b, t_below, w);
            return Hit(ray.uv0 + t_hit * ray.P, 1.0 - t_hit, iterations);
        }
        // The bilinear surface was not hit: move on to P_f and keep traversing.
        if (t_f >= t_end) {
            break;
        }
        t = t_f;
        t_safe = t;
        fresh = true;
        step += 1.0;
    }
    if (t_end >= 1.0) {
        // At h = 0 the ray is on or below every surface.
        return hit_at(ray, 0.0, iterations);
    }
    return miss(ray, iterations);
}
