// Traversal of the cell-max pyramid (PYRAMID_KIND_CELL, glsl/pyramid.comp) with the
// exact ray / bilinear-patch intersection in the leaf: the GPU twin of the CPU reference
// (cli/src/reference.rs, whose module docs explain the algorithm), in f32. Used by `exact`
// and by `dig-guarded`'s guard. Include after trace.glsl (which brings texels.glsl). It
// picks its levels differently from the reference (a start level of at most
// START_LEVEL_CAP, and a climb after a skip only where `climb` allows it): fewer steps,
// the same cells tested, the same first hit.
//
// Texel space: x = u W - 0.5, y = v H - 0.5; texel (i, j) at the integer point (i, j);
// cell (i, j) = [i, i + 1] x [j, j + 1], its bound = pyramid level 0 at (i, j) (wrapped
// for repeat addressing; for clamp addressing the decal covers cells -1 ..= W - 1 and the
// half cell -1, whose corners are column/row 0's texels, is bounded by cell 0's value).
// Level L node n covers the cells [n 2^L, min((n + 1) 2^L, W)) of each tile.
// The bound pyramid stores every level in the map's own format for 8- and 16-bit maps;
// for other maps (R32_SFLOAT) levels 1 and up only (src/passes/pyramid.rs): there a
// cell's bound is the maximum of its 4 corner texels, read from the map
// (pyramid_node_max; the traversal's loop tests such a cell instead, segment_hit), and
// the image's mip L - 1 holds level L. pc.pyramid_levels: bits
// 0-15 the levels (level 0 to the root), bit 16 set where level 0 is not stored.
#ifndef DISPMAP_PYRAMID_GLSL
#define DISPMAP_PYRAMID_GLSL

layout(set = 0, binding = 4) uniform sampler2D u_pyramid;

// The maximum of a cell's 4 corner texels (cell_texels): level 0 of the pyramid.
float cell_max(vec4 g) {
    return max(max(g.w, g.z), max(g.x, g.y));
}

// Levels of the bound pyramid, level 0 to the root.
int pyramid_levels() {
    return int(pc.pyramid_levels & 0xffffu);
}

// Whether the pyramid's image stores level 0 (mip L holds level L); else mip L - 1 does.
bool pyramid_level0_stored() {
    return (pc.pyramid_levels & 0x10000u) == 0u;
}

// The bound of level-`level` node `node` (its index within the level, as node_range
// gives it): from the pyramid's image, or level 0 from the map's texels where the image
// does not store it.
float pyramid_node_max(ivec2 node, int level) {
    if (pyramid_level0_stored()) {
        return texelFetch(u_pyramid, node, level).r;
    }
    return level == 0 ? cell_max(cell_texels(node)) : texelFetch(u_pyramid, node, level - 1).r;
}

// A skip needs the ray to clear the node's bound by this much: f32 rounding of the exit
// height must never skip a node the ray touches.
const float SKIP_MARGIN = 1.0 / 1048576.0;

// The level-`level` node holding `cell` along one axis of `n` cells: its cell range
// [lo, hi) (in the ray's unbounded cell coordinates) and its index within the level.
void node_range(int cell, int n, int level, out int lo, out int hi, out int node) {
    if (pc.addressing == ADDRESSING_REPEAT) {
        int local = wrap_index(cell, n);
        int base = cell - local;
        node = local >> level;
        lo = base + (node << level);
        hi = base + min((node + 1) << level, n);
    } else if (cell < 0) {
        node = 0;
        lo = -1;
        hi = 0;
    } else {
        node = min(cell, n - 1) >> level;
        lo = node << level;
        hi = min((node + 1) << level, n);
    }
}

// The cell holding coordinate x for a ray moving with `d` along that axis: on an exact
// boundary a ray moving backwards is in the cell behind it.
int cell_at(float x, float d) {
    float f = floor(x);
    return (d < 0.0 && f == x) ? int(f) - 1 : int(f);
}

// q(s) = (a s + b) s + c.
float quad(float a, float b, float c, float s) {
    return (a * s + b) * s + c;
}

// The root of q in [l, r] where it increases through 0, given q(l) < 0 <= q(r).
float increasing_root(float a, float b, float c, float l, float r) {
    float disc = b * b - 4.0 * a * c;
    if (disc >= 0.0) {
        float sq = sqrt(disc);
        // (-b + sq) / 2a without cancellation; the first form also covers a = 0.
        float root = b >= 0.0 ? 2.0 * c / (-b - sq) : (-b + sq) / (2.0 * a);
        float tol = 1e-5 * (r - l);
        if (!isnan(root) && !isinf(root) && root >= l - tol && root <= r + tol) {
            return clamp(root, l, r);
        }
    }
    // Rounding made the closed form unusable: bisect the bracket.
    float lo = l, hi = r;
    for (int i = 0; i < 40; ++i) {
        float mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) {
            break;
        }
        if (quad(a, b, c, mid) >= 0.0) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    return hi;
}

// The smallest s in [0, len] with q(s) >= 0, or -1.
float first_root(float a, float b, float c, float len) {
    if (c >= 0.0) {
        return 0.0;
    }
    if (!(len > 0.0)) {
        return -1.0;
    }
    float vertex = a != 0.0 ? -b / (2.0 * a) : -1.0;
    float mid = (vertex > 0.0 && vertex < len) ? vertex : len;
    if (quad(a, b, c, mid) >= 0.0) {
        return increasing_root(a, b, c, 0.0, mid);
    }
    if (mid < len && quad(a, b, c, len) >= 0.0) {
        return increasing_root(a, b, c, mid, len);
    }
    return -1.0;
}

// Exact products and sums: glsl/include/dispmap_double_float.glsl (shared with the
// pixel rays of the G-buffer), under the names this file has always used.
#include "../include/dispmap_double_float.glsl"

vec2 split_f32(float x) {
    return dispmap_split_f32(x);
}

float two_product(float a, float b, vec2 bs, out float e) {
    return dispmap_two_product(a, b, bs, e);
}

float two_sum(float a, float b, out float e) {
    return dispmap_two_sum(a, b, e);
}

// The texel-space ray being traversed, beyond its f32 origin and dir (set by texel_ray,
// or texel_ray_at for the `pyramid` method's coordinates): g_origin_lo and g_dir_lo, the
// rounding of uv0 W - 0.5 and P W (0 for a power-of-two map, whose products are exact:
// without them a 1000-texel map's ray is off by 6e-8 of its length, 0.01 texels after
// 1.6e5 texels, enough to misjudge a skim on a steep flank), and g_dir_split, dir's
// halves for two_product.
vec2 g_origin_lo = vec2(0.0);
vec2 g_dir_lo = vec2(0.0);
vec4 g_dir_split = vec4(0.0);
// Whether the ray is long: |dir| above SHORT_RAY_TEXELS on an axis. A short ray's
// positions stay below 2^13 texels, where f32 keeps 1e-3 of a texel without the exact
// products: it has no residuals, ray_at takes the plain form (2 operations instead of
// about 25) and its crossings are the plain ones (cross_exit).
bool g_long_ray = false;
vec2 g_inv_dir = vec2(0.0);
const float SHORT_RAY_TEXELS = 4096.0;

// The ray in coordinates x = uv dims - shift (shift 0.5: texel space, texel centres on
// integers; 0: texel footprints): x = origin + t dir, with the globals above. `uv0 dims`
// is below 2^23 for any uv0 in a tile, so subtracting the shift is exact.
void texel_ray_at(Ray ray, float shift, out vec2 origin, out vec2 dir) {
    vec2 dims = vec2(pc.map_size);
    origin = ray.uv0 * dims - shift;
    dir = ray.P * dims;
    g_long_ray = max(abs(dir.x), abs(dir.y)) > SHORT_RAY_TEXELS;
    g_origin_lo = vec2(0.0);
    g_dir_lo = vec2(0.0);
    g_dir_split = vec4(0.0);
    if (g_long_ray) {
        for (int a = 0; a < 2; ++a) {
            vec2 ds = split_f32(dims[a]);
            float e;
            float o = two_product(ray.uv0[a], dims[a], ds, e);
            g_origin_lo[a] = e;
            origin[a] = o - shift;
            dir[a] = two_product(ray.P[a], dims[a], ds, e);
            g_dir_lo[a] = e;
        }
        g_dir_split = vec4(split_f32(dir.x), split_f32(dir.y));
    }
    // Residuals and lengths in a cell multiply by these (no per-step division; the
    // axes with dir = 0 never use theirs).
    g_inv_dir = vec2(dir.x != 0.0 ? 1.0 / dir.x : 0.0, dir.y != 0.0 ? 1.0 / dir.y : 0.0);
}

// The ray in texel space: x = origin + t dir.
void texel_ray(Ray ray, out vec2 origin, out vec2 dir) {
    texel_ray_at(ray, 0.5, origin, dir);
}

// One axis of the texel-space ray (scalars: a runtime index into a vector would cost a
// CPU driver a trip through memory): origin, dir, their residuals and dir's halves.
struct AxisRay {
    float o;
    float d;
    float o_lo;
    float d_lo;
    vec2 ds;
    float inv_d;
};

AxisRay axis_ray(vec2 origin, vec2 dir, bool y) {
    return y ? AxisRay(origin.y, dir.y, g_origin_lo.y, g_dir_lo.y, g_dir_split.zw, g_inv_dir.y)
             : AxisRay(origin.x, dir.x, g_origin_lo.x, g_dir_lo.x, g_dir_split.xy, g_inv_dir.x);
}

// origin + (t + t_lo) dir along one axis (with the ray's residuals) as s + r: s the f32
// sum of the product and the origin, r what rounding left out (two_product, two_sum).
// `s - k` for an integer k within a cell of s is exact, so a position relative to its
// cell keeps about 1e-7 texels wherever the ray is, where origin + t dir in f32 keeps an
// ulp of the absolute coordinate (0.03 texels at 5e5 texels: depth scale 100 at 10
// degrees, 8 texels at 1.4e8 on its grazing rows).
float ray_at(AxisRay ray, float t, float t_lo, bool long_ray, out float r) {
    if (!long_ray) {
        // Short: f32 positions below 2^13 texels, no residuals (texel_ray_at).
        r = 0.0;
        return ray.o + t * ray.d;
    }
    float e_prod, e_sum;
    float p = two_product(t, ray.d, ray.ds, e_prod);
    float s = two_sum(p, ray.o, e_sum);
    precise float rest = e_sum + (e_prod + (t_lo * ray.d + (ray.o_lo + t * ray.d_lo)));
    r = rest;
    return s;
}

// Position of the ray at t + t_lo relative to `cell`: origin + (t + t_lo) dir - cell, to
// about 1e-7 texels (ray_at). t_lo: the residual of an exit time (exit_residual).
vec2 local_at(vec2 origin, vec2 dir, float t, float t_lo, bool long_ray, ivec2 cell) {
    float rx, ry;
    float sx = ray_at(axis_ray(origin, dir, false), t, t_lo, long_ray, rx);
    float sy = ray_at(axis_ray(origin, dir, true), t, t_lo, long_ray, ry);
    precise vec2 local = (vec2(sx, sy) - vec2(cell)) + vec2(rx, ry);
    return local;
}

vec2 local_at(vec2 origin, vec2 dir, float t, ivec2 cell) {
    return local_at(origin, dir, t, 0.0, g_long_ray, cell);
}

// The residual of an exit time: t = (face - origin) / dir rounded to f32 is t + lo
// exactly (up to f32 of lo itself), lo = (face - (origin + t dir)) / dir with the
// position from ray_at (face - s is exact: s is within rounding of the face). A ray of
// |dir| texels per unit of t is placed by an f32 t only to about 6e-8 |dir| texels; with
// the residual, positions at an exit (the other axis' cell, a leaf's entry point) keep
// their precision along rays of any length an int cell index holds. A per-skip cost, on
// the exit axis, on long rays only: on a short ray (g_long_ray) the residual moves a
// position by less than an ulp of t times 4096 texels (2.4e-4 texels) and is left at 0.
float exit_residual(float face, AxisRay ray, float t, bool long_ray) {
    if (!long_ray) {
        return 0.0;
    }
    float r;
    float s = ray_at(ray, t, 0.0, long_ray, r);
    precise float num = (face - s) - r;
    return num * ray.inv_d;
}

// The cell holding origin + (t + t_lo) dir along one axis, for a ray moving with `dir`
// (cell_at's rule on an exact boundary), from the position relative to a nearby integer
// (ray_at).
int cell_at_precise(AxisRay ray, float t, float t_lo, bool long_ray) {
    float r;
    float s = ray_at(ray, t, t_lo, long_ray, r);
    float k = floor(s);
    precise float local = (s - k) + r;
    float whole = floor(local);
    k += whole;
    local -= whole;
    return (ray.d < 0.0 && local == 0.0) ? int(k) - 1 : int(k);
}

// cell_at_precise along axis a (0: x, 1: y).
int cell_at_precise(vec2 origin, vec2 dir, int a, float t, float t_lo) {
    return cell_at_precise(axis_ray(origin, dir, a == 1), t, t_lo, g_long_ray);
}

// The first t from t_in on (up to t_end) where the ray meets the bilinear patch of
// `cell` (its corner texels `g`: cell_texels), or -1; t_in + t_in_lo is the exact entry time (t_in_lo: the exit_residual of
// the face crossed). The solve runs in the cell's own coordinates: the local entry point
// (local_at) and the length of the ray's part in the cell from it. Along a long ray one
// ulp of t spans a sizeable part of a cell (0.017 texels at t = 1e-3 and |P| = 1.4e5
// tiles of a 1024 map), so the length as a difference of the f32 entry and exit times
// would be off by percents, and the quadratic at the cell's exit by the surface's rise
// over that part (8e-4 of the depth on rocks): a hit in open air.
float cell_hit(ivec2 cell, vec4 g, vec2 origin, vec2 dir, float t_in, float t_in_lo, float t_end, bool long_ray) {
    float h00 = g.w;
    float h10 = g.z;
    float h01 = g.x;
    float h11 = g.y;
    vec2 f = local_at(origin, dir, t_in, t_in_lo, long_ray, cell);
    float len = (t_end - t_in) - t_in_lo;
    for (int k = 0; k < 2; ++k) {
        if (dir[k] > 0.0) {
            len = min(len, (1.0 - f[k]) * g_inv_dir[k]);
        } else if (dir[k] < 0.0) {
            len = min(len, -f[k] * g_inv_dir[k]);
        }
    }
    float a = h10 - h00;
    float b = h01 - h00;
    float c = h00 - h10 - h01 + h11;
    float qa = c * dir.x * dir.y;
    float qb = a * dir.x + b * dir.y + c * (f.x * dir.y + f.y * dir.x) + 1.0;
    // The entry height in nested-lerp form (exact at texel centres and on plateaus).
    float top = h00 + (h10 - h00) * f.x;
    float bottom = h01 + (h11 - h01) * f.x;
    float qc = (top + (bottom - top) * f.y - (1.0 - t_in)) + t_in_lo;
    float s = first_root(qa, qb, qc, max(len, 0.0));
    return s < 0.0 ? -1.0 : min(t_in + (s + t_in_lo), t_end);
}

// Moves the ray out of the box of cells [lo, hi) through its exit: `exit` holds the
// per-axis exit times (f32), t_exit their minimum or t_exit = t when rounding put them
// below the current t (whose residual is t_lo_in). Sets `cell` to the cell entered,
// t_exit and t_lo to the exact crossing (exit_residual). The f32 exit times cannot order
// two crossings that are closer than their rounding (0.03 texels of a corner along a ray
// of 1e6 texels), so the other axis' position at the chosen crossing is found exactly
// (cell_at_precise): when it is already past its face, that face came first and the ray
// leaves through it (both when they coincide). A clamp into the box here would put the
// ray in a cell it is not in, whose patch, extrapolated, can reach it: a hit in open air.
void cross_exit(vec2 exit, ivec2 lo, ivec2 hi, vec2 origin, vec2 dir, float t_lo_in, bool long_ray,
                inout float t_exit, out float t_lo, inout ivec2 cell) {
    if (!long_ray) {
        // A short ray: f32 positions keep 1e-3 texels (SHORT_RAY_TEXELS); the plain crossing.
        t_lo = t_exit == min(exit.x, exit.y) ? 0.0 : t_lo_in;
        for (int a = 0; a < 2; ++a) {
            if (exit[a] <= exit[1 - a]) {
                cell[a] = dir[a] > 0.0 ? hi[a] : lo[a] - 1;
            } else {
                cell[a] = clamp(cell_at(origin[a] + t_exit * dir[a], dir[a]), lo[a], hi[a] - 1);
            }
        }
        return;
    }
    // e: the exit axis (x on a tie), o: the other one; scalars, no runtime indices.
    bool sw = exit.y < exit.x;
    AxisRay re = axis_ray(origin, dir, sw);
    AxisRay ro = axis_ray(origin, dir, !sw);
    float exit_e = sw ? exit.y : exit.x;
    float exit_o = sw ? exit.x : exit.y;
    int lo_e = sw ? lo.y : lo.x;
    int hi_e = sw ? hi.y : hi.x;
    int lo_o = sw ? lo.x : lo.y;
    int hi_o = sw ? hi.x : hi.y;
    int face_e = re.d > 0.0 ? hi_e : lo_e;
    int face_o = ro.d > 0.0 ? hi_o : lo_o;
    int beyond_e = re.d > 0.0 ? hi_e : lo_e - 1;
    int beyond_o = ro.d > 0.0 ? hi_o : lo_o - 1;
    t_lo = t_exit == exit_e ? exit_residual(float(face_e), re, t_exit, long_ray) : t_lo_in;
    int co = ro.d != 0.0 ? cell_at_precise(ro, t_exit, t_lo, long_ray) : (sw ? cell.x : cell.y);
    bool past = ro.d > 0.0 ? co >= hi_o : co < lo_o;
    int ce;
    if (!past) {
        ce = beyond_e;
        co = clamp(co, lo_o, hi_o - 1);
    } else {
        // The other face came first (or at the same time).
        float t_o = max(exit_o, t_exit);
        float lo_t_o = exit_residual(float(face_o), ro, t_o, long_ray);
        int ca = cell_at_precise(re, t_o, lo_t_o, long_ray);
        co = beyond_o;
        if (re.d > 0.0 ? ca < hi_e : ca >= lo_e) {
            ce = clamp(ca, lo_e, hi_e - 1);
            t_exit = t_o;
            t_lo = lo_t_o;
        } else {
            ce = beyond_e;
        }
    }
    cell = sw ? ivec2(co, ce) : ivec2(ce, co);
}

// Leaves the node [lo, hi) that the ray exits at t_exit (per-axis exit times `exit`):
// true with `result` when the traversal ends there (the ray's end: at t = 1 the ray is at
// h = 0 <= H and always hits, rounding may have hidden the root in the last cell; or -1
// when a clamp-addressed ray left the decal, only through rounding at its border); else
// false with `cell` in the next node (cross_exit), `t` and `t_lo` at the exact crossing
// and one level up.
bool leave_node(vec2 exit, ivec2 lo, ivec2 hi, vec2 origin, vec2 dir, float t_exit, float t_end, int top,
                bool long_ray, inout ivec2 cell, inout float t, inout float t_lo, inout int level,
                out float result) {
    result = -1.0;
    if (t_exit >= t_end) {
        result = t_end >= 1.0 ? 1.0 : -1.0;
        return true;
    }
    float exit_lo;
    cross_exit(exit, lo, hi, origin, dir, t_exit == t ? t_lo : 0.0, long_ray, t_exit, exit_lo, cell);
    ivec2 n_cells = ivec2(pc.map_size);
    if (pc.addressing == ADDRESSING_CLAMP && (any(lessThan(cell, ivec2(-1))) || any(greaterThanEqual(cell, n_cells)))) {
        return true;
    }
    t = t_exit;
    t_lo = exit_lo;
    level = min(level + 1, top);
    return false;
}

// Whether the two step rules below (the climb rule and START_LEVEL_CAP) apply: a
// specialization constant set from the device (Context::traversal_rules: on for CPU
// devices, off for GPUs). Both only change how many steps a traversal takes, never
// its hit. On lavapipe (8 invocations in lockstep) they save 8-14% of `exact`'s time;
// on an NVIDIA H200 `exact` ran in 0.87-0.95x the time with them off (BENCHMARKS.md,
// run V): on 32-wide warps the extra per-step work costs more than the steps it saves.
layout(constant_id = 1) const bool TRAVERSAL_RULES = true;

// The level after a skip of a level-`was` node from `from` into `cell`, where leave_node
// climbed to `level` (was + 1, or the top): the climb stands only when the node entered
// is the first of its parent along every axis the ray crossed (in the direction of
// travel). Otherwise that parent also holds the node just skipped and the part of the
// map beside it, so its bound is at least as high as the two together and the step that
// tests it mostly fails and descends again: one wasted step per skip, which staying at
// the skipped level saves.
// The doubling rule of rectangle-maximum traversals (a segment's side doubles only where
// the ray's offset is a multiple of the doubled side) for the pyramid's aligned nodes:
// 0.74-0.77x the steps on the bundled maps (docs/methods.md, "Traversal steps"). A
// heuristic (any level is correct): the parity of the node in unbounded cell coordinates
// is its parity in the tile for power-of-two maps, and may be off across the tile seam
// of others.
int climb(int was, int level, ivec2 from, ivec2 cell, vec2 dir) {
    if (!TRAVERSAL_RULES) {
        return level;
    }
    bool first = true;
    for (int a = 0; a < 2; ++a) {
        if (cell[a] != from[a]) {
            int odd = (cell[a] >> was) & 1;
            first = first && (dir[a] > 0.0 ? odd == 0 : odd == 1);
        }
    }
    return first ? level : was;
}

// The highest level a traversal starts at. The ray starts at the map's highest point,
// so the nodes that span its whole travel (levels 9-10 of a 1024 map) hold that point,
// the ray fails them and descends one level per step; from nodes of 32 cells a ray in
// open space climbs back in one or two steps per level (climb). Measured on the bundled
// maps (SIMD-8 steps, against no cap): 3: 1.04 / 0.84 / 1.11x (rocks / bricks /
// mountains), 4: 0.98 / 0.85 / 1.05x, 5: 0.95 / 0.87 / 1.01x, 7: 0.95 / 0.94 / 0.98x.
const int START_LEVEL_CAP = 5;

// The finest level whose nodes are at least `cells` cells wide (a restart level).
int level_for_span(float cells) {
    int top = pyramid_levels() - 1;
    return clamp(int(ceil(log2(max(cells, 1.0)))), 0, top);
}

// The exact first intersection of `ray` along t in [t_start, t_stop] (t = 1 - h) with
// the part of the height field the ray crosses: for clamp addressing, a ray that starts
// outside the decal enters it further on (the self-shadowing pass's light rays, which
// reach the macro surface outside the decal); for a ray starting inside, the clip is a
// no-op. Returns t, or -1 (see pyramid_first_hit_from).
float segment_hit(vec2 origin, vec2 dir, float t_start, float t_stop, int start_level, bool long_ray,
                  inout uint iterations) {
    ivec2 n_cells = ivec2(pc.map_size);
    vec2 dims = vec2(pc.map_size);
    float t_end = t_stop;
    float t_begin = t_start;
    if (pc.addressing == ADDRESSING_CLAMP) {
        for (int a = 0; a < 2; ++a) {
            if (dir[a] > 0.0) {
                t_begin = max(t_begin, (-0.5 - origin[a]) / dir[a]);
                t_end = min(t_end, (dims[a] - 0.5 - origin[a]) / dir[a]);
            } else if (dir[a] < 0.0) {
                t_begin = max(t_begin, (dims[a] - 0.5 - origin[a]) / dir[a]);
                t_end = min(t_end, (-0.5 - origin[a]) / dir[a]);
            } else if (origin[a] < -0.5 || origin[a] > dims[a] - 0.5) {
                return -1.0;
            }
        }
        t_end = max(t_end, 0.0);
    }
    int top = pyramid_levels() - 1;
    float global_max = pyramid_node_max(ivec2(0), top);
    float t = max(t_begin, 1.0 - global_max);
    if (t > t_end) {
        return -1.0;
    }
    // t's residual: 0 at the start (t is the exact value it is given).
    float t_lo = 0.0;
    ivec2 cell;
    for (int a = 0; a < 2; ++a) {
        int c = cell_at_precise(axis_ray(origin, dir, a == 1), t, 0.0, long_ray);
        cell[a] = pc.addressing == ADDRESSING_CLAMP ? clamp(c, -1, n_cells[a] - 1) : c;
    }
    // No higher than the finest level whose nodes span the ray's remaining travel: a
    // node wider than that is entered only to descend (every level bounds its cells, so
    // any start level finds the same first hit; the steps from the root down to here
    // were 3 to 12 of every pixel's). Nor above START_LEVEL_CAP.
    float travel = max(abs(dir.x), abs(dir.y)) * (t_end - t);
    int level = min(min(clamp(start_level, 0, top), level_for_span(travel)), TRAVERSAL_RULES ? START_LEVEL_CAP : top);
    // Each skip moves a cell index by >= 1 along the ray and follows at most `top`
    // descents: the cap is only reached through a bug (then: no hit), or at
    // TRAVERSAL_CAP (frame.glsl), within the loop budget of a lavapipe invocation.
    float span = abs(dir.x) + abs(dir.y) + 4.0;
    float cap = min(2.0 * float(top + 2) * span + 16.0, TRAVERSAL_CAP);
    // Two loops: the inner one only traverses until the ray reaches a leaf cell it does
    // not clear; the cell's exact test follows it, and on a miss the traversal resumes.
    // The same steps in the same order as one loop with the test inside it, but a SIMD
    // CPU driver (lavapipe runs 8 pixels in lockstep with masks) pays for a branch that
    // any lane takes on every iteration: inside the loop the cell test (4 fetches and a
    // quadratic) was paid whenever any pixel of the group was at a leaf.
    // Where the pyramid does not store level 0, a level-0 node is never skipped: the
    // leaf test runs on it (the exact test of the cell's texels, which finds no root
    // where the ray clears them) and a miss leaves the cell exactly as a skip would
    // (the same leave_node), so the hits and the step counts are those of a traversal
    // with level 0 stored. No texel read in this loop: on lavapipe a gather there (even
    // one never taken) made every traversal 1.4x slower.
    bool stored0 = pyramid_level0_stored();
    int mip_shift = stored0 ? 0 : 1;
    float step = 0.0;
    while (step < cap) {
        bool at_leaf = false;
        ivec2 lo, hi;
        vec2 exit;
        float t_exit;
        for (; step < cap; step += 1.0) {
            ivec2 node;
            node_range(cell.x, n_cells.x, level, lo.x, hi.x, node.x);
            node_range(cell.y, n_cells.y, level, lo.y, hi.y, node.y);
            iterations += 1u;
            float node_max = texelFetch(u_pyramid, node, max(level - mip_shift, 0)).r;
            if (level < mip_shift) {
                node_max = 2.0;
            }
            exit = vec2(1e30);
            for (int a = 0; a < 2; ++a) {
                if (dir[a] > 0.0) {
                    exit[a] = (float(hi[a]) - origin[a]) / dir[a];
                } else if (dir[a] < 0.0) {
                    exit[a] = (float(lo[a]) - origin[a]) / dir[a];
                }
            }
            t_exit = max(min(min(exit.x, exit.y), t_end), t);
            if (1.0 - t_exit > node_max + SKIP_MARGIN) {
                // The ray stays above everything in the node: skip it.
                float result;
                ivec2 from = cell;
                int was = level;
                if (leave_node(exit, lo, hi, origin, dir, t_exit, t_end, top, long_ray, cell, t, t_lo, level, result)) {
                    return result;
                }
                level = climb(was, level, from, cell, dir);
            } else if (level > 0) {
                level -= 1;
            } else {
                at_leaf = true;
                break;
            }
        }
        if (!at_leaf) {
            break;
        }
        float th = cell_hit(cell, cell_texels(cell), origin, dir, t, t_lo, t_end, long_ray);
        if (th >= 0.0) {
            return th;
        }
        float result;
        ivec2 from = cell;
        int was = level;
        if (leave_node(exit, lo, hi, origin, dir, t_exit, t_end, top, long_ray, cell, t, t_lo, level, result)) {
            return result;
        }
        level = climb(was, level, from, cell, dir);
        step += 1.0;
    }
    return -1.0;
}

// The traversal in two copies: for short rays (plain f32 positions, the lean loop they
// always had) and for long ones (exact positions, g_long_ray). `long_ray` is a constant
// in each call, so the compiler drops the other arithmetic from each copy: one loop with
// both (the choice per operation) cost about a third more time on short rays in lavapipe
// (more code, more registers), although the long-ray operations never ran there.
float pyramid_segment_hit(Ray ray, float t_start, float t_stop, int start_level, inout uint iterations) {
    vec2 origin, dir;
    texel_ray(ray, origin, dir);
    if (g_long_ray) {
        return segment_hit(origin, dir, t_start, t_stop, start_level, true, iterations);
    }
    return segment_hit(origin, dir, t_start, t_stop, start_level, false, iterations);
}

// Whether `ray` is short in texel space (texel_ray_at's g_long_ray is false for it).
bool pyramid_ray_short(Ray ray) {
    vec2 dir = ray.P * vec2(pc.map_size);
    return max(abs(dir.x), abs(dir.y)) <= SHORT_RAY_TEXELS;
}

// pyramid_segment_hit for a short ray (pyramid_ray_short): its short copy alone, the same
// result, so that a program whose rays are all short holds no long-ray traversal (a CPU
// driver runs both copies' instructions for every group of lanes wherever both are
// called).
float pyramid_short_segment_hit(Ray ray, float t_start, float t_stop, int start_level, inout uint iterations) {
    vec2 origin, dir;
    texel_ray(ray, origin, dir);
    return segment_hit(origin, dir, t_start, t_stop, start_level, false, iterations);
}

// The exact first intersection of `ray` along t in [t_start, t_stop] (t = 1 - h):
// returns t, or -1 when there is none (a clamp-addressed ray leaving the decal, or no
// crossing before t_stop < 1). The traversal starts at level `start_level` (any level
// is correct: every level bounds its cells; a short segment starts low). `iterations`
// counts the traversal steps (one pyramid or one cell fetch each).
float pyramid_first_hit_from(Ray ray, float t_start, float t_stop, int start_level, inout uint iterations) {
    if (pc.addressing == ADDRESSING_CLAMP && (any(lessThan(ray.uv0, vec2(0.0))) || any(greaterThan(ray.uv0, vec2(1.0))))) {
        return -1.0;
    }
    return pyramid_segment_hit(ray, t_start, t_stop, start_level, iterations);
}

// pyramid_first_hit_from starting at the root.
float pyramid_first_hit(Ray ray, float t_start, float t_stop, inout uint iterations) {
    return pyramid_first_hit_from(ray, t_start, t_stop, pyramid_levels() - 1, iterations);
}

#endif
