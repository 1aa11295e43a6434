// Cone stepping over the conservative cone map of the bilinear surface (glsl/cone.comp:
// per cell (M, w), every surface point q satisfies H(q) <= M + dist(q, cell) / w). Used
// by `cone` (with a sampled band and bisection) and `cone-exact` (with the exact
// ray/bilinear-patch solve of glsl/common/pyramid.glsl). Include after trace.glsl and
// pyramid.glsl. Texel space as in pyramid.glsl: x = origin + t dir, h = 1 - t.
//
// Each step, in the cell holding the ray (clamp addressing: cells -1 and W - 1 use the
// nearest cell's cone, with the ray's distance to that cell subtracted):
//   * above the cell's maximum M: the larger of the cone step w (h - M) / (w + |dir|)
//     (Dummer 2006) and the robust minimum step (Ban et al. 2024): to the cell's exit or
//     to the height M, whichever comes first (the surface over the cell is below M);
//   * at or below M ("in the band"): the caller's leaf test over [t, cell exit].
// With CONE_RELAXED (the relaxed cone map) a cone step longer than the robust minimum
// step may end inside the surface, having crossed it at most once: the height at its end
// is tested, and on or below the surface the march returns as if in the band, with
// `t_above` the step's start (the caller's first band sample finds the ray below).
#ifndef DISPMAP_CONE_GLSL
#define DISPMAP_CONE_GLSL

// The cone map: rg32f (M, w) per cell (relaxed: w negated where it is wider than the
// conservative ratio), nearest texel fetches.
layout(set = 0, binding = 8) uniform sampler2D u_cone;

// The cone step is shortened by this fraction: f32 rounding of the step must never end it
// inside the surface it bounds.
const float CONE_SHRINK = 1.0 / 65536.0;

// The cone steps a ray may take before it hands over to the pyramid traversal
// (pyramid_first_hit_from, from the point it reached): a cone step covers at least one
// cell, so a ray crossing more cells than this (a huge depth scale at a grazing angle:
// millions of texels) would otherwise end at the traversal cap without its hit. The
// pyramid skips such open space by whole nodes. Method::loop_bound declares the sum.
const float CONE_BUDGET = 4096.0;

// The ray's march state.
struct ConeRay {
    vec2 origin;
    vec2 dir;
    float len;    // |dir|: horizontal texels per unit of t
    float t_end;  // 1, or where a clamp-addressed ray leaves the decal
    float t_start; // where the march starts: the map's maximum height (nothing above it)
    ivec2 cell;   // the cell holding the ray at t
    float t_lo;   // CONE_PRECISE: the residual of t when t is a cell's exit (exit_residual)
};

// Starts the march where the ray comes down to the map's global maximum (the pyramid's
// root; as the pyramid traversal does): above it there is no surface, and cone steps
// through that open space would cost a fetch each. False when a clamp-addressed ray
// starts outside the decal.
bool cone_start(Ray ray, out ConeRay r) {
    texel_ray(ray, r.origin, r.dir);
    r.len = length(r.dir);
    r.t_end = 1.0;
    ivec2 n = ivec2(pc.map_size);
    r.cell = ivec2(0);
    r.t_lo = 0.0;
    if (pc.addressing == ADDRESSING_CLAMP) {
        if (any(lessThan(ray.uv0, vec2(0.0))) || any(greaterThan(ray.uv0, vec2(1.0)))) {
            return false;
        }
        vec2 dims = vec2(pc.map_size);
        for (int a = 0; a < 2; ++a) {
            if (r.dir[a] > 0.0) {
                r.t_end = min(r.t_end, (dims[a] - 0.5 - r.origin[a]) / r.dir[a]);
            } else if (r.dir[a] < 0.0) {
                r.t_end = min(r.t_end, (-0.5 - r.origin[a]) / r.dir[a]);
            }
        }
        r.t_end = max(r.t_end, 0.0);
    }
    float global_max = pyramid_node_max(ivec2(0), pyramid_levels() - 1);
    r.t_start = min(max(1.0 - global_max, 0.0), r.t_end);
    for (int a = 0; a < 2; ++a) {
#ifdef CONE_PRECISE
        int c = cell_at_precise(r.origin, r.dir, a, r.t_start, 0.0);
#else
        int c = cell_at(r.origin[a] + r.t_start * r.dir[a], r.dir[a]);
#endif
        r.cell[a] = pc.addressing == ADDRESSING_CLAMP ? clamp(c, -1, n[a] - 1) : c;
    }
    return true;
}

// The cell's exit time along the ray (>= t; t_end at most) and the per-axis exit times.
float cone_cell_exit(ConeRay r, float t, out vec2 exit) {
    exit = vec2(1e30);
    for (int a = 0; a < 2; ++a) {
        if (r.dir[a] > 0.0) {
            exit[a] = (float(r.cell[a] + 1) - r.origin[a]) / r.dir[a];
        } else if (r.dir[a] < 0.0) {
            exit[a] = (float(r.cell[a]) - r.origin[a]) / r.dir[a];
        }
    }
    return max(min(min(exit.x, exit.y), r.t_end), t);
}

// The cone map entry of the ray's cell and the ray's distance (texels) from the cell it
// belongs to (0 unless clamp addressing moved the lookup to the nearest cell).
vec2 cone_entry(ConeRay r, float t, out float e) {
    ivec2 n = ivec2(pc.map_size);
    ivec2 look;
    if (pc.addressing == ADDRESSING_REPEAT) {
        look = ivec2(wrap_index(r.cell.x, n.x), wrap_index(r.cell.y, n.y));
        e = 0.0;
    } else {
        look = clamp(r.cell, ivec2(0), n - 1);
        vec2 x = local_at(r.origin, r.dir, t, look);
        e = length(max(max(-x, x - 1.0), vec2(0.0)));
    }
    return texelFetch(u_cone, look, 0).rg;
}

// The exact bilinear height at the ray's point t (texel reads, f32).
float cone_height(ConeRay r, float t) {
    vec2 x = r.origin + t * r.dir;
    return height_exact((x + 0.5) / vec2(pc.map_size));
}

// Moves the ray to t_next > t: across the exit face(s) when t_next is the cell's exit,
// else into the cell holding it (never behind the current one, whatever the rounding).
// With CONE_PRECISE (cone-exact) the cell is found from the exact position (ray_at in
// pyramid.glsl) and a move to the exit keeps t's residual in r.t_lo, so that the leaf's
// exact solve starts on the face crossed, however long the ray.
void cone_move(inout ConeRay r, vec2 exit, float t_exit, float t_next) {
#ifdef CONE_PRECISE
    r.t_lo = 0.0;
    if (t_next == t_exit) {
        float t_cross = t_exit;
        float lo;
        cross_exit(exit, r.cell, r.cell + 1, r.origin, r.dir, 0.0, g_long_ray, t_cross, lo, r.cell);
        // The march stays at t_exit: the crossing's residual relative to it (t_cross is
        // the other face's f32 time when that face came first; the difference is exact).
        precise float rel = (t_cross - t_exit) + lo;
        r.t_lo = rel;
        return;
    }
#endif
    for (int a = 0; a < 2; ++a) {
        if (t_next == t_exit && exit[a] <= exit[1 - a]) {
            r.cell[a] += r.dir[a] > 0.0 ? 1 : -1;
        } else if (t_next > t_exit && r.dir[a] != 0.0) {
#ifdef CONE_PRECISE
            int c = cell_at_precise(r.origin, r.dir, a, t_next, 0.0);
#else
            int c = cell_at(r.origin[a] + t_next * r.dir[a], r.dir[a]);
#endif
            r.cell[a] = r.dir[a] > 0.0 ? max(c, r.cell[a]) : min(c, r.cell[a]);
        }
    }
}

// Cone steps from t until the ray is in the band of its cell (true: t, the cell in `r`,
// its exit `t_exit` and `exit` set) or reaches t_end (false). `t_above` is the start of
// the last step (a point above the surface).
bool cone_advance(inout ConeRay r, inout float t, out float t_exit, out vec2 exit, inout float t_above,
                  inout float step, float cap, inout uint iterations) {
    for (; step < cap; step += 1.0) {
        iterations += 1u;
        t_exit = cone_cell_exit(r, t, exit);
        float e;
        vec2 cone = cone_entry(r, t, e);
        // The band starts at t_band (h = M + margin). The test and the robust step use
        // the same rounded value, so a step that ends at t_band is in the band (comparing
        // h = 1 - t with M + margin instead could round the other way and leave the ray
        // one ulp above the band with a step of zero, forever).
        float t_band = 1.0 - cone.x - SKIP_MARGIN;
        if (t >= t_band) {
            return true;
        }
        float h = 1.0 - t;
        float w = abs(cone.y);
        float s = max(w * (h - cone.x - SKIP_MARGIN) - e, 0.0) / (w + r.len) * (1.0 - CONE_SHRINK);
        float t_next = max(t + s, min(t_exit, t_band));
#ifdef CONE_RELAXED
        // The relaxed map negates the ratio where it is wider than the conservative
        // one; elsewhere the step is conservative and crossed nothing.
        if (cone.y < 0.0 && t + s > min(t_exit, t_band)) {
            float t_probe = min(t_next, r.t_end);
            if (cone_height(r, t_probe) >= 1.0 - t_probe) {
                t_above = t;
                t = t_probe;
                return true;
            }
        }
#endif
        if (t_next >= r.t_end) {
            t_above = t;
            t = r.t_end;
            return false;
        }
        if (t_next >= t_exit) {
            cone_move(r, exit, t_exit, t_next);
        } else {
            r.t_lo = 0.0;
        }
        t_above = t;
        t = t_next;
    }
    return false;
}

#endif
