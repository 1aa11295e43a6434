// Traversal of the cell-max pyramid (PYRAMID_KIND_CELL, glsl/pyramid.comp) with the
// exact ray / bilinear-patch intersection in the leaf: the GPU twin of the CPU reference
// (cli/src/reference.rs, whose module docs explain the algorithm), in f32. Used by `exact`
// and by `dig-guarded`'s guard. Include after trace.glsl (which brings texels.glsl).
//
// Texel space: x = u W - 0.5, y = v H - 0.5; texel (i, j) at the integer point (i, j);
// cell (i, j) = [i, i + 1] x [j, j + 1], its bound = pyramid level 0 at (i, j) (wrapped
// for repeat addressing; for clamp addressing the decal covers cells -1 ..= W - 1 and the
// half cell -1, whose corners are column/row 0's texels, is bounded by cell 0's value).
// Level L node n covers the cells [n 2^L, min((n + 1) 2^L, W)) of each tile.
#ifndef DISPMAP_PYRAMID_GLSL
#define DISPMAP_PYRAMID_GLSL

layout(set = 0, binding = 4) uniform sampler2D u_pyramid;

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

// Position of the ray at t relative to `cell`: origin + t dir - cell, with the product's
// rounding error recovered by fma so that far along a long ray the local position keeps
// the precision of t rather than of the absolute coordinate.
vec2 local_at(vec2 origin, vec2 dir, float t, ivec2 cell) {
    precise vec2 p = t * dir;
    precise vec2 e = fma(vec2(t), dir, -p);
    precise vec2 local = ((p - vec2(cell)) + origin) + e;
    return local;
}

// The first t in [t_in, t_out] where the ray meets the bilinear patch of `cell`, or -1.
float cell_hit(ivec2 cell, vec2 origin, vec2 dir, float t_in, float t_out) {
    vec4 g = cell_texels(cell);
    float h00 = g.w;
    float h10 = g.z;
    float h01 = g.x;
    float h11 = g.y;
    vec2 f = local_at(origin, dir, t_in, cell);
    float a = h10 - h00;
    float b = h01 - h00;
    float c = h00 - h10 - h01 + h11;
    float qa = c * dir.x * dir.y;
    float qb = a * dir.x + b * dir.y + c * (f.x * dir.y + f.y * dir.x) + 1.0;
    // The entry height in nested-lerp form (exact at texel centres and on plateaus).
    float top = h00 + (h10 - h00) * f.x;
    float bottom = h01 + (h11 - h01) * f.x;
    float qc = top + (bottom - top) * f.y - (1.0 - t_in);
    float s = first_root(qa, qb, qc, t_out - t_in);
    return s < 0.0 ? -1.0 : min(t_in + s, t_out);
}

// The ray in texel space: x = origin + t dir.
void texel_ray(Ray ray, out vec2 origin, out vec2 dir) {
    vec2 dims = vec2(pc.map_size);
    origin = ray.uv0 * dims - 0.5;
    dir = ray.P * dims;
}

// Leaves the node [lo, hi) that the ray exits at t_exit (per-axis exit times `exit`):
// true with `result` when the traversal ends there (the ray's end: at t = 1 the ray is at
// h = 0 <= H and always hits, rounding may have hidden the root in the last cell; or -1
// when a clamp-addressed ray left the decal, only through rounding at its border); else
// false with `cell` in the next node (across the exit face(s), the other axis recomputed
// inside the node's range), `t` = t_exit and one level up.
bool leave_node(vec2 exit, ivec2 lo, ivec2 hi, vec2 origin, vec2 dir, float t_exit, float t_end, int top,
                inout ivec2 cell, inout float t, inout int level, out float result) {
    result = -1.0;
    if (t_exit >= t_end) {
        result = t_end >= 1.0 ? 1.0 : -1.0;
        return true;
    }
    ivec2 n_cells = ivec2(pc.map_size);
    for (int a = 0; a < 2; ++a) {
        if (exit[a] <= exit[1 - a]) {
            cell[a] = dir[a] > 0.0 ? hi[a] : lo[a] - 1;
        } else {
            cell[a] = clamp(cell_at(origin[a] + t_exit * dir[a], dir[a]), lo[a], hi[a] - 1);
        }
    }
    if (pc.addressing == ADDRESSING_CLAMP && (any(lessThan(cell, ivec2(-1))) || any(greaterThanEqual(cell, n_cells)))) {
        return true;
    }
    t = t_exit;
    level = min(level + 1, top);
    return false;
}

// The finest level whose nodes are at least `cells` cells wide (a restart level).
int level_for_span(float cells) {
    int top = int(pc.pyramid_levels) - 1;
    return clamp(int(ceil(log2(max(cells, 1.0)))), 0, top);
}

// The exact first intersection of `ray` along t in [t_start, t_stop] (t = 1 - h) with
// the part of the height field the ray crosses: for clamp addressing, a ray that starts
// outside the decal enters it further on (the self-shadowing pass's light rays, which
// reach the macro surface outside the decal); for a ray starting inside, the clip is a
// no-op. Returns t, or -1 (see pyramid_first_hit_from).
float pyramid_segment_hit(Ray ray, float t_start, float t_stop, int start_level, inout uint iterations) {
    ivec2 n_cells = ivec2(pc.map_size);
    vec2 dims = vec2(pc.map_size);
    vec2 origin, dir;
    texel_ray(ray, origin, dir);
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
    int top = int(pc.pyramid_levels) - 1;
    float global_max = texelFetch(u_pyramid, ivec2(0), top).r;
    float t = max(t_begin, 1.0 - global_max);
    if (t > t_end) {
        return -1.0;
    }
    ivec2 cell;
    for (int a = 0; a < 2; ++a) {
        int c = cell_at(origin[a] + t * dir[a], dir[a]);
        cell[a] = pc.addressing == ADDRESSING_CLAMP ? clamp(c, -1, n_cells[a] - 1) : c;
    }
    // No higher than the finest level whose nodes span the ray's remaining travel: a
    // node wider than that is entered only to descend (every level bounds its cells, so
    // any start level finds the same first hit; the steps from the root down to here
    // were 3 to 12 of every pixel's).
    float travel = max(abs(dir.x), abs(dir.y)) * (t_end - t);
    int level = min(clamp(start_level, 0, top), level_for_span(travel));
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
            float node_max = texelFetch(u_pyramid, node, level).r;
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
                if (leave_node(exit, lo, hi, origin, dir, t_exit, t_end, top, cell, t, level, result)) {
                    return result;
                }
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
        float th = cell_hit(cell, origin, dir, t, t_exit);
        if (th >= 0.0) {
            return th;
        }
        float result;
        if (leave_node(exit, lo, hi, origin, dir, t_exit, t_end, top, cell, t, level, result)) {
            return result;
        }
        step += 1.0;
    }
    return -1.0;
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
    return pyramid_first_hit_from(ray, t_start, t_stop, int(pc.pyramid_levels) - 1, iterations);
}

#endif
