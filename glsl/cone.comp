#version 460
// cone: the conservative cone map of the bilinear surface, one invocation per cell (see
// src/passes/cone.rs for the definition and the proof sketch; docs/cones.md for the
// choices). Texel space as in glsl/common/pyramid.glsl: cell (i, j) = [i, i + 1] x
// [j, j + 1] between texel centres, its maximum M = the cell pyramid's level 0 (the
// maximum of its 4 corner texels; where the pyramid's image stores levels 1 and up only,
// mip L - 1 holds level L: pyramid_at, and M is read from the texels).
//
// Output (rg32f): (M, w). w is the cone ratio (texels of horizontal distance per unit of
// height): every point q of the surface satisfies H(q) <= M + dist(q, C) / w, dist the
// Euclidean distance in texels from q to the cell's square C. A ray above M anywhere over
// C can therefore advance by w (h - M) / (w + |d|) (|d| its horizontal texels per unit
// of height) without meeting the surface.
//
// Every other cell D gives an upper bound on w; w is their minimum (and CONE_RATIO_MAX):
//   * cells within WINDOW cells (brute force on their 4 corner texels): the bilinear patch
//     is linear along each axis, so on D, at a distance g + f (f in [0, 1]) from C along
//     an axis, H <= (1 - f) N + f F (N, F the maxima of D's near and far edges), and the
//     distance to C is at least g + f: the bound holds at f = 0 and 1, hence everywhere
//     (both sides are linear in f). The axis that allows the larger w is used; for a
//     diagonal neighbour (sharing one corner, <= M) also sqrt(2) max(other corners - M).
//   * beyond the window: the max pyramid (Valasek & Ban 2022): at each level L >= 1 the 8
//     neighbours of the node holding C, each bounded by its node maximum at the larger
//     of its gap to C and WINDOW (every cell outside the window is at least WINDOW cells
//     away along one axis). The levels' 3x3 blocks nest and the root's covers the map;
//     with repeat addressing the tiles beyond the root's 3x3 copies are at least
//     min(W, H) texels away (bounded by the global maximum).
// Clamp addressing: cells -1 and W - 1 (half inside the decal; their corners are the
// clamped edge texels) are surface like any other; cells beyond them are never reached.
//
// RELAXED (the relaxed cone map of `relaxed-cone`; (M, w_relaxed), w_relaxed negated
// where it is wider than the conservative w, so that the trace tests the surface only
// there): a window cell D whose bilinear patch never falls along any direction a ray
// leaving C can cross it in ("monotone outward": per axis, D's edges non-decreasing away
// from C, or equal where D is in C's column or row, which rays cross either way) gives no
// bound; beyond the window the falls pyramids replace the max pyramid (node_falls).
// Everything else is bounded as above.
// A ray that starts over C above M and steps to the cone's boundary then crosses the
// surface at most once (src/passes/cone.rs has the argument), so one height test at the
// step's end tells whether the step passed a hit.
// dispmap-variant: RELAXED
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_height;
layout(set = 0, binding = 1) uniform sampler2D u_pyramid;
layout(set = 0, binding = 2, rg32f) uniform writeonly image2D u_cone;
#ifdef RELAXED
// The falls pyramids (PYRAMID_KIND_FALLS in glsl/pyramid.comp), quadrants (+x, +y),
// (-x, +y), (+x, -y), (-x, -y): per node the highest cell corner whose patch falls going
// that way (0 where none does).
layout(set = 0, binding = 3) uniform sampler2D u_falls_pp;
layout(set = 0, binding = 4) uniform sampler2D u_falls_np;
layout(set = 0, binding = 5) uniform sampler2D u_falls_pn;
layout(set = 0, binding = 6) uniform sampler2D u_falls_nn;
#endif

layout(push_constant) uniform ConeParams {
    uvec2 map_size;  // texels = cells per axis
    uint levels;     // levels of the cell pyramid
    uint addressing; // ADDRESSING_*
} pc;

// pc.levels: bits 0-15 the cell pyramid's levels, bit 16 set where its image does not
// store level 0 (mip L - 1 holds level L).
bool level0_stored() {
    return (pc.levels & 0x10000u) == 0u;
}

// The cell pyramid's level-`level` node (level >= 1, or level 0 where it is stored).
float pyramid_at(ivec2 node, int level) {
    return texelFetch(u_pyramid, node, level0_stored() ? level : level - 1).r;
}

#include "texels.glsl"

// Cells per side of the brute-force window around a cell (its half width).
#define WINDOW 4
#define SIDE (2 * WINDOW + 2)
// The widest cone stored: a flat neighbourhood gives no bound.
const float CONE_RATIO_MAX = 65536.0;

// g / v for v > 0, else no bound.
float ratio(float g, float v) {
    return v > 0.0 ? g / v : CONE_RATIO_MAX;
}

#ifdef RELAXED
// Whether a window cell at offset (di, dj) from C with corners a00..a11 (x, y local) is
// monotone outward: along x, non-decreasing away from C (equal when di == 0: rays cross
// it both ways); along y the same.
bool monotone_outward(int di, int dj, float a00, float a10, float a01, float a11) {
    bool x_ok = di > 0 ? (a00 <= a10 && a01 <= a11)
              : di < 0 ? (a10 <= a00 && a11 <= a01)
                       : (a00 == a10 && a01 == a11);
    bool y_ok = dj > 0 ? (a00 <= a01 && a10 <= a11)
              : dj < 0 ? (a01 <= a00 && a11 <= a10)
                       : (a00 == a01 && a10 == a11);
    return x_ok && y_ok;
}
#endif

#ifdef RELAXED
// The relaxed bound of the pyramid node `kk` of `level`, at offset `off` (ring position)
// from the node holding C: the maximum of the cells in it that fall along some direction
// a ray from C can cross them in (the quadrants of off's signs, both ways along an axis
// where off is 0).
float node_falls(ivec2 kk, int level, ivec2 off) {
    float v = 0.0;
    if (off.y >= 0) {
        if (off.x >= 0) {
            v = max(v, texelFetch(u_falls_pp, kk, level).r);
        }
        if (off.x <= 0) {
            v = max(v, texelFetch(u_falls_np, kk, level).r);
        }
    }
    if (off.y <= 0) {
        if (off.x >= 0) {
            v = max(v, texelFetch(u_falls_pn, kk, level).r);
        }
        if (off.x <= 0) {
            v = max(v, texelFetch(u_falls_nn, kk, level).r);
        }
    }
    return v;
}
#endif

// One axis of a window cell at offset `o` (|o| >= 1): near- and far-edge maxima above M.
float axis_bound(int o, float near_max, float far_max) {
    float g = float(abs(o) - 1);
    return min(ratio(g, near_max), ratio(g + 1.0, far_max));
}

// The level-`level` node `k` of an axis of `n` cells (`nl` nodes): its cell range
// [lo, hi) in the unbounded cell coordinates around tile 0; false when it does not exist
// (clamp addressing, outside the map).
bool node_cells(int k, int n, int nl, int level, out int kk, out int lo, out int hi) {
    int shift = 0;
    kk = k;
    if (pc.addressing == ADDRESSING_REPEAT) {
        if (k < 0) {
            kk = k + nl;
            shift = -n;
        } else if (k >= nl) {
            kk = k - nl;
            shift = n;
        }
    } else if (k < 0 || k >= nl) {
        return false;
    }
    lo = (kk << level) + shift;
    hi = min((kk + 1) << level, n) + shift;
    if (pc.addressing == ADDRESSING_CLAMP && kk == 0) {
        lo = -1;
    }
    return true;
}

// The pyramid levels whose nodes hold the whole workgroup (2^level >= LOCAL_SIZE, and
// the workgroup's cells are aligned to LOCAL_SIZE): the neighbour nodes of such a level
// are the same for every invocation, so their ranges and maxima are found once per
// workgroup (8 per level; levels SHARED_LEVEL .. 15 cover any map of up to 32768 cells).
#define SHARED_LEVEL 3
#define RING_SLOTS (8 * (16 - SHARED_LEVEL))
// The 8 neighbours, in the order of the per-invocation loop (rows -1, 0, 1).
const ivec2 RING[8] = ivec2[](ivec2(-1, -1), ivec2(0, -1), ivec2(1, -1), ivec2(-1, 0),
                              ivec2(1, 0), ivec2(-1, 1), ivec2(0, 1), ivec2(1, 1));
shared ivec4 s_ring_cells[RING_SLOTS]; // lo.x, lo.y, hi.x, hi.y
shared float s_ring_max[RING_SLOTS];   // the node maximum; -1 where no node exists
#ifdef RELAXED
shared float s_ring_falls[RING_SLOTS]; // node_falls; -1 where no node exists
#endif

void main() {
    ivec2 c = ivec2(gl_GlobalInvocationID.xy);
    ivec2 n = ivec2(pc.map_size);
    int top_level = int(pc.levels & 0xffffu) - 1;
    {
        ivec2 group = ivec2(gl_WorkGroupID.xy) * LOCAL_SIZE;
        for (int slot = int(gl_LocalInvocationIndex); slot < RING_SLOTS; slot += LOCAL_SIZE * LOCAL_SIZE) {
            int level = SHARED_LEVEL + (slot >> 3);
            ivec2 off = RING[slot & 7];
            float node_max = -1.0;
            float falls = -1.0;
            ivec4 cells = ivec4(0);
            if (level <= top_level) {
                ivec2 a = group >> level;
                ivec2 nl = (n + (1 << level) - 1) >> level;
                ivec2 kk, lo, hi;
                if (node_cells(a.x + off.x, n.x, nl.x, level, kk.x, lo.x, hi.x)
                    && node_cells(a.y + off.y, n.y, nl.y, level, kk.y, lo.y, hi.y)) {
                    node_max = pyramid_at(kk, level);
#ifdef RELAXED
                    falls = node_falls(kk, level, off);
#endif
                    cells = ivec4(lo, hi);
                }
            }
            s_ring_cells[slot] = cells;
            s_ring_max[slot] = node_max;
#ifdef RELAXED
            s_ring_falls[slot] = falls;
#endif
        }
    }
    barrier();
    if (any(greaterThanEqual(c, n))) {
        return;
    }
    vec4 g = cell_texels(c);
    float m = level0_stored() ? pyramid_at(c, 0) : max(max(g.w, g.z), max(g.x, g.y));
    float w = CONE_RATIO_MAX;
#ifdef RELAXED
    float w_relaxed = CONE_RATIO_MAX;
#endif

    // The window's corner texels, rows c.y - WINDOW .. c.y + WINDOW + 1.
    float t[SIDE * SIDE];
    for (int j = 0; j < SIDE; ++j) {
        for (int i = 0; i < SIDE; ++i) {
            t[j * SIDE + i] = texel_height(c + ivec2(i - WINDOW, j - WINDOW)) - m;
        }
    }
    for (int dj = -WINDOW; dj <= WINDOW; ++dj) {
        for (int di = -WINDOW; di <= WINDOW; ++di) {
            ivec2 d = c + ivec2(di, dj);
            if ((di == 0 && dj == 0)
                || (pc.addressing == ADDRESSING_CLAMP && (any(lessThan(d, ivec2(-1))) || any(greaterThan(d, n - 1))))) {
                continue;
            }
            int k = (dj + WINDOW) * SIDE + di + WINDOW;
            // Corners above M (local x, y in {0, 1}).
            float a00 = t[k], a10 = t[k + 1], a01 = t[k + SIDE], a11 = t[k + SIDE + 1];
            float top = max(max(a00, a10), max(a01, a11));
            if (top <= 0.0) {
                continue;
            }
            vec2 gap = vec2(max(abs(di) - 1, 0), max(abs(dj) - 1, 0));
            float bound = ratio(length(gap), top);
            if (di != 0) {
                float lower = max(a00, a01), upper = max(a10, a11);
                bound = max(bound, di > 0 ? axis_bound(di, lower, upper) : axis_bound(di, upper, lower));
            }
            if (dj != 0) {
                float lower = max(a00, a10), upper = max(a01, a11);
                bound = max(bound, dj > 0 ? axis_bound(dj, lower, upper) : axis_bound(dj, upper, lower));
            }
            if (abs(di) == 1 && abs(dj) == 1) {
                // The shared corner is one of C's (<= M), so `top` is the maximum of
                // the other three: H - M <= (fx + fy) top <= sqrt(2) |f| top.
                bound = max(bound, ratio(1.0, sqrt(2.0) * top));
            }
            w = min(w, bound);
#ifdef RELAXED
            if (!monotone_outward(di, dj, a00, a10, a01, a11)) {
                w_relaxed = min(w_relaxed, bound);
            }
#endif
        }
    }

    // Beyond the window: the pyramid's neighbour rings, levels below SHARED_LEVEL per
    // invocation, the others from the workgroup's table.
    for (int level = 1; level <= min(top_level, SHARED_LEVEL - 1); ++level) {
        ivec2 a = c >> level;
        ivec2 nl = (n + (1 << level) - 1) >> level;
        for (int oy = -1; oy <= 1; ++oy) {
            for (int ox = -1; ox <= 1; ++ox) {
                if (ox == 0 && oy == 0) {
                    continue;
                }
                ivec2 kk, lo, hi;
                if (!node_cells(a.x + ox, n.x, nl.x, level, kk.x, lo.x, hi.x)
                    || !node_cells(a.y + oy, n.y, nl.y, level, kk.y, lo.y, hi.y)) {
                    continue;
                }
                // A node's falls never exceed its maximum: nothing to bound either way.
                float rise = pyramid_at(kk, level) - m;
                if (rise <= 0.0) {
                    continue;
                }
                vec2 gap = vec2(max(max(lo - (c + 1), c - hi), ivec2(0)));
                float dist = max(length(gap), float(WINDOW));
                w = min(w, ratio(dist, rise));
#ifdef RELAXED
                w_relaxed = min(w_relaxed, ratio(dist, node_falls(kk, level, ivec2(ox, oy)) - m));
#endif
            }
        }
    }
    int shared_slots = 8 * max(top_level - SHARED_LEVEL + 1, 0);
    for (int slot = 0; slot < shared_slots; ++slot) {
        // Heights are >= 0, so a missing node (-1) never rises above m.
        float rise = s_ring_max[slot] - m;
        if (rise <= 0.0) {
            continue;
        }
        ivec4 cells = s_ring_cells[slot];
        vec2 gap = vec2(max(max(cells.xy - (c + 1), c - cells.zw), ivec2(0)));
        float dist = max(length(gap), float(WINDOW));
        w = min(w, ratio(dist, rise));
#ifdef RELAXED
        w_relaxed = min(w_relaxed, ratio(dist, s_ring_falls[slot] - m));
#endif
    }
    if (pc.addressing == ADDRESSING_REPEAT) {
        // The global maximum (level 0 on a 1 x 1 map: its one cell, whose maximum is m).
        float rise = (top_level > 0 || level0_stored() ? pyramid_at(ivec2(0), top_level) : m) - m;
        float dist = max(float(min(n.x, n.y)), float(WINDOW));
        w = min(w, ratio(dist, rise));
#ifdef RELAXED
        w_relaxed = min(w_relaxed, ratio(dist, node_falls(ivec2(0), top_level, ivec2(0)) - m));
#endif
    }
#ifdef RELAXED
    // Negative where the relaxed cone is wider than the conservative one: only there may
    // a step end inside the surface (the trace tests it there only).
    imageStore(u_cone, c, vec4(m, w_relaxed > w ? -w_relaxed : w_relaxed, 0.0, 0.0));
#else
    imageStore(u_cone, c, vec4(m, w, 0.0, 0.0));
#endif
}
