// The mesh walk: `exact`'s curved trace on the mesh's own triangles (the CURVED variant of
// glsl/trace/exact.comp; src/mesh/walk.rs builds the buffer, docs/methods.md "Curved
// surfaces" explains the model). Included by exact.comp after trace.glsl.
//
// The displaced surface of a mesh is, at barycentric b of a triangle, the base point
// p(b) = sum b_i p_i moved inwards along the interpolated normal N(b) = sum b_i n_i by
// (1 - H(uv(b))) of the depth d(b) = depth_scale sum b_i s_i (s_i the vertices' local uv
// scale): the surface cli/src/silhouette.rs tessellates and traces in f64. Every point X
// of a triangle's shell is X = p(b) - tau N(b) for one (b, tau), its foot b (where a
// normal of the base surface passes through X) and its depth fraction t = tau |N(b)| /
// d(b). The walk follows the pixel's straight view ray through these shells: at each
// sample it solves for (b, tau) by Newton's method from the previous sample (the map
// from (b1, b2, tau) to X is quadratic; from a nearby start two iterations reach f32
// precision), and where b leaves the triangle it steps to the neighbour across that edge
// (the buffer's adjacency, matched by position, so a ray crosses uv seams and a cube's
// edges). The ray is inside the relief where H(uv(b)) >= 1 - t; the samples are at most
// one texel of uv apart (and at most an eighth of the depth), and the first crossing is
// refined by bisection. The ray misses where it leaves the shell: back out through the
// base surface (t < 0) or over a boundary edge of an open mesh.
//
// Exact against that model up to the one-texel sampling (a bump narrower than a texel's
// bilinear cell can fit between two samples of a ray that grazes it) and f32; the
// tangent-plane circle model (curved.glsl) stays the path of pixels that are on none of
// the buffer's triangles (a host that gave no meshes: an empty buffer).
#ifndef DISPMAP_WALK_GLSL
#define DISPMAP_WALK_GLSL

// The walk buffer (src/mesh/walk.rs, words): a header, the triangles, the start grid.
//   0..3  the grid's lower corner (f32 bits), 3: cells per unit length (f32 bits)
//   4..6  the grid's cells along x, y, z; 7: the triangle count (0: no walk)
//   8     the first word of the triangles; 9: of the cells' offsets; 10: of the cells'
//         lists; 11: of the overlap lists; 12: of the plane lists
// A triangle is WALK_TRIANGLE_WORDS words: per corner (p.xyz, s, n.xyz, uv.xy), then its
// neighbours across the edges opposite corners 0, 1 and 2 (WALK_NONE: a boundary edge),
// its surface id, the first and count of the triangles whose shells overlap its own
// (sharing a corner's position where the normals part: a cube's edges and corners), its
// flatness bits, and the first and count of those triangles' distinct planes (unit
// normal, offset, largest local uv scale: WALK_PLANE_WORDS each).
// The buffer is read as a uniform texel buffer of four words a texel (a CPU driver
// gathers a texel for its lanes at once, where it reads a storage buffer one lane and one
// word at a time): walk_word reads one word, walk_v3 three, walk_tri a triangle's nine
// texels (WALK_TRIANGLE_WORDS is a multiple of four, and so is the header's length).
layout(set = 0, binding = 12) uniform usamplerBuffer u_walk;

uint walk_word(uint i) {
    uvec4 t = texelFetch(u_walk, int(i >> 2u));
    uint c = i & 3u;
    return c == 0u ? t.x : (c == 1u ? t.y : (c == 2u ? t.z : t.w));
}

const uint WALK_TRIANGLE_WORDS = 36u;
const uint WALK_PLANE_WORDS = 5u;
// The flatness bits (src/mesh/walk.rs): the triangle is flat; the neighbour across edge e
// continues it flat (bit 1 << e).
const uint WALK_FLAT = 1u;
const uint WALK_FLAT_EDGE = 2u;
const uint WALK_CORNER_WORDS = 9u;
const uint WALK_NONE = 0xffffffffu;
// Newton iterations per sample from the previous sample's solution; on entering a
// triangle (from its centre).
const int WALK_NEWTON = 2;
const int WALK_NEWTON_ENTER = 5;
// Hops between neighbours to locate one point.
const int WALK_MAX_HOPS = 12;
// Samples along a ray at most; bisections of its crossing.
const float WALK_MAX_STEPS = 16384.0;
const int WALK_BISECTIONS = 16;
// Halvings of a chord at most; its largest distance from the walked path at its middle,
// in texels of uv and as a fraction of the depth.
const int WALK_CHORD_HALVINGS = 10;
const float WALK_CHORD_TEXELS = 1.0 / 16.0;
const float WALK_CHORD_DEPTH = 1.0 / 1024.0;
// A barycentric this far below 0 is outside the triangle.
const float WALK_INSIDE = -1e-5;

float walk_f(uint i) {
    return uintBitsToFloat(walk_word(i));
}

// Words i, i + 1 and i + 2: from the two texels they lie in.
vec3 walk_v3(uint i) {
    uvec4 a = texelFetch(u_walk, int(i >> 2u));
    uvec4 b = texelFetch(u_walk, int(i >> 2u) + 1);
    uint c = i & 3u;
    uvec3 w = c == 0u ? a.xyz : (c == 1u ? a.yzw : (c == 2u ? uvec3(a.zw, b.x) : uvec3(a.w, b.xy)));
    return uintBitsToFloat(w);
}

// One triangle, in the form the solve uses: corner 0 and the edges from it.
struct WalkTri {
    vec3 p0, e1, e2;   // base points
    vec3 n0, f1, f2;   // vertex normals (the side's: negated for a back side)
    vec3 s;            // s0, s1 - s0, s2 - s0: the local uv scales
    vec2 uv0, du1, du2;
    uvec3 adj;
    uvec2 overlaps;    // first (in the overlap list), count
    uint flags;        // WALK_FLAT, WALK_FLAT_EDGE << e
    uvec2 planes;      // first (in the plane list), count
};

// The first texel of triangle t (WALK_TRIANGLE_WORDS / 4 texels from the header's
// word 8, a multiple of four).
int walk_tri_texel(uint t) {
    return int((walk_word(8u) >> 2u) + t * (WALK_TRIANGLE_WORDS / 4u));
}

WalkTri walk_tri(uint t, float side) {
    // Nine texels, the words picked by constant indices (no local array: a CPU driver
    // keeps a dynamically indexed array in memory). Words: corner c's p at 9c, s at
    // 9c + 3, n at 9c + 4, uv at 9c + 7; the neighbours at 27, the overlaps at 31, the
    // flags at 33, the planes at 34.
    int b = walk_tri_texel(t);
    uvec4 t0 = texelFetch(u_walk, b);
    uvec4 t1 = texelFetch(u_walk, b + 1);
    uvec4 t2 = texelFetch(u_walk, b + 2);
    uvec4 t3 = texelFetch(u_walk, b + 3);
    uvec4 t4 = texelFetch(u_walk, b + 4);
    uvec4 t5 = texelFetch(u_walk, b + 5);
    uvec4 t6 = texelFetch(u_walk, b + 6);
    uvec4 t7 = texelFetch(u_walk, b + 7);
    uvec4 t8 = texelFetch(u_walk, b + 8);
    vec3 p0 = uintBitsToFloat(t0.xyz);
    vec3 p1 = uintBitsToFloat(uvec3(t2.yzw));
    vec3 p2 = uintBitsToFloat(uvec3(t4.zw, t5.x));
    float s0 = uintBitsToFloat(t0.w);
    float s1 = uintBitsToFloat(t3.x);
    float s2 = uintBitsToFloat(t5.y);
    vec3 n0 = side * uintBitsToFloat(t1.xyz);
    vec3 n1 = side * uintBitsToFloat(uvec3(t3.yzw));
    vec3 n2 = side * uintBitsToFloat(uvec3(t5.zw, t6.x));
    vec2 uv0 = uintBitsToFloat(uvec2(t1.w, t2.x));
    vec2 uv1 = uintBitsToFloat(t4.xy);
    vec2 uv2 = uintBitsToFloat(t6.yz);
    return WalkTri(p0, p1 - p0, p2 - p0, n0, n1 - n0, n2 - n0, vec3(s0, s1 - s0, s2 - s0),
                   uv0, uv1 - uv0, uv2 - uv0, uvec3(t6.w, t7.xy), uvec2(t7.w, t8.x), t8.y, t8.zw);
}

// Triangle t's corner positions (what the start and the overlap tests need first).
void walk_corners(uint t, out vec3 p0, out vec3 p1, out vec3 p2) {
    int b = walk_tri_texel(t);
    uvec4 t0 = texelFetch(u_walk, b);
    uvec4 t2 = texelFetch(u_walk, b + 2);
    uvec4 t4 = texelFetch(u_walk, b + 4);
    uvec4 t5 = texelFetch(u_walk, b + 5);
    p0 = uintBitsToFloat(t0.xyz);
    p1 = uintBitsToFloat(t2.yzw);
    p2 = uintBitsToFloat(uvec3(t4.zw, t5.x));
}

vec3 walk_normal(WalkTri T, vec2 b) {
    return T.n0 + b.x * T.f1 + b.y * T.f2;
}

vec2 walk_uv(WalkTri T, vec2 b) {
    return T.uv0 + b.x * T.du1 + b.y * T.du2;
}

// The depth fraction t of the point (b, tau): tau |N(b)| over d(b).
float walk_t(WalkTri T, vec3 q) {
    float d = pc.depth_scale * (T.s.x + q.x * T.s.y + q.y * T.s.z);
    return q.z * length(walk_normal(T, q.xy)) / max(d, 1e-30);
}

// The Jacobian's columns of X(b1, b2, tau) = p(b) - tau N(b) at q.
void walk_jacobian(WalkTri T, vec3 q, out vec3 c1, out vec3 c2, out vec3 c3) {
    c1 = T.e1 - q.z * T.f1;
    c2 = T.e2 - q.z * T.f2;
    c3 = -walk_normal(T, q.xy);
}

// Newton's method for X = p(b) - tau N(b) from q, `n` iterations (Cramer's rule).
vec3 walk_solve(WalkTri T, vec3 X, vec3 q, int n) {
    for (int i = 0; i < n; ++i) {
        vec3 c1, c2, c3;
        walk_jacobian(T, q, c1, c2, c3);
        vec3 r = X - (T.p0 + q.x * T.e1 + q.y * T.e2 + c3 * q.z);
        vec3 c23 = cross(c2, c3);
        float det = dot(c1, c23);
        if (!(abs(det) > 0.0)) {
            break;
        }
        vec3 dq = vec3(dot(r, c23), dot(c1, cross(r, c3)), dot(c1, cross(c2, r))) / det;
        q += dq;
        // Converged (a flat triangle's map is affine: one iteration).
        if (!(dot(dq, dq) > 1e-14)) {
            break;
        }
    }
    return q;
}

// The change of q per unit of the ray's parameter along direction R.
vec3 walk_rate(WalkTri T, vec3 q, vec3 R) {
    vec3 c1, c2, c3;
    walk_jacobian(T, q, c1, c2, c3);
    vec3 c23 = cross(c2, c3);
    float det = dot(c1, c23);
    if (!(abs(det) > 0.0)) {
        return vec3(0.0);
    }
    return vec3(dot(R, c23), dot(c1, cross(R, c3)), dot(c1, cross(c2, R))) / det;
}

// The change of the depth fraction t (walk_t) per unit of the ray's parameter, from q's
// (`rate`: walk_rate).
float walk_t_rate(WalkTri T, vec3 q, vec3 rate) {
    vec3 N = walk_normal(T, q.xy);
    float n = length(N);
    float dn = dot(N, rate.x * T.f1 + rate.y * T.f2) / max(n, 1e-30);
    float d = max(pc.depth_scale * (T.s.x + q.x * T.s.y + q.y * T.s.z), 1e-30);
    float dd = pc.depth_scale * (rate.x * T.s.y + rate.y * T.s.z);
    return (rate.z * n + q.z * dn) / d - q.z * n * dd / (d * d);
}

// Where the walk is: its triangle (index and data), the point's (b1, b2, tau), and the
// integer uv shift gathered crossing seams (so that uv stays continuous along the ray).
struct WalkAt {
    uint tri;
    WalkTri T;
    vec3 q;
    vec2 shift;
};

// The uv of a located point: its triangle's uv at its barycentrics clamped into the
// triangle (a point located within WALK_INSIDE of an edge reads the edge's uv, not a uv a
// hair past a clamp-addressed decal's edge), moved by whole tiles (`tiles`: those of the
// seams the walk crossed and the pixel's uv0 reduction) so that it stays continuous
// along the ray from the pixel's uv0.
vec2 walk_at_uv(WalkAt at, vec2 tiles) {
    vec2 b = max(at.q.xy, vec2(0.0));
    b /= max(b.x + b.y, 1.0);
    return walk_uv(at.T, b) + at.shift + tiles;
}

// Locates X starting from `at`: true with `at` on the triangle whose prism holds X's foot;
// false where the foot leaves the mesh over a boundary edge (or the hops run out).
bool walk_locate(inout WalkAt at, vec3 X, float side, int newton) {
    vec3 q = walk_solve(at.T, X, at.q, newton);
    for (int hop = 0; hop < WALK_MAX_HOPS; ++hop) {
        float b0 = 1.0 - q.x - q.y;
        float m = min(b0, min(q.x, q.y));
        if (m >= WALK_INSIDE) {
            at.q = q;
            return true;
        }
        uint edge = m == b0 ? 0u : (m == q.x ? 1u : 2u);
        uint next = edge == 0u ? at.T.adj.x : (edge == 1u ? at.T.adj.y : at.T.adj.z);
        if (next == WALK_NONE) {
            return false;
        }
        vec2 uv_here = walk_uv(at.T, q.xy);
        WalkTri N = walk_tri(next, side);
        vec3 qn = walk_solve(N, X, vec3(1.0 / 3.0, 1.0 / 3.0, q.z), WALK_NEWTON_ENTER);
        // Across a seam the two triangles' uvs at the point differ by whole tiles, which a
        // repeating map keeps continuous (a clamped map's uvs are the triangles' own).
        if (pc.addressing == ADDRESSING_REPEAT) {
            at.shift += round(uv_here - walk_uv(N, qn.xy));
        }
        at.tri = next;
        at.T = N;
        q = qn;
    }
    return false;
}

// Whether a segment whose ends lie `d` above a plane (signed distances) can meet the slab
// from `above` depths above the plane to `below` depths under it (`depth` the depth):
// false when both ends lie on one side of it.
bool walk_slab_near(vec2 d, float depth, float above, float below) {
    return !(min(d.x, d.y) > above * depth || max(d.x, d.y) < -below * depth);
}

// Whether the segment from Xa to Xb can meet triangle N's shell (N as walk_tri reads it for
// the side): false when both ends lie on one side of the slab from its base plane to its
// deepest offset (every point of a shell whose vertex normals are within a right angle of
// its plane's normal lies in it; an eighth of the depth is kept to each side).
bool walk_near(WalkTri N, vec3 Xa, vec3 Xb) {
    vec3 n = cross(N.e1, N.e2);
    n *= sign(dot(n, N.n0)) * inversesqrt(max(dot(n, n), 1e-37));
    float depth = pc.depth_scale * max(N.s.x, max(N.s.x + N.s.y, N.s.x + N.s.z));
    vec3 p0 = N.p0;
    return walk_slab_near(vec2(dot(Xa - p0, n), dot(Xb - p0, n)), depth, 0.125, 1.125);
}

// The hit at ray parameter s met in an overlapping triangle's relief, written in `at`'s
// triangle's frame (its foot and depth there, the triangle extended past its edges): the
// hit's uv and height then give the hit's position in the pixel's tangent frame, which
// the corrected depth and the motion vectors rebuild from them (`hit_depth`), while the
// other triangle's chart is another uv map.
Hit walk_hit_in(WalkAt at, vec3 X, vec2 tiles, uint iterations) {
    vec3 q = walk_solve(at.T, X, at.q, WALK_NEWTON_ENTER);
    return Hit(walk_uv(at.T, q.xy) + at.shift + tiles, 1.0 - clamp(walk_t(at.T, q), 0.0, 1.0),
               iterations);
}

// The whole tiles that move an overlapping triangle N's uv (at its point qa) next to
// `at`'s continuous uv (repeat addressing; a clamped map reads N's own uv).
vec2 walk_tiles_in(WalkAt at, WalkTri N, vec3 qa, vec2 tiles) {
    return pc.addressing == ADDRESSING_REPEAT
        ? tiles + at.shift + round(walk_uv(at.T, at.q.xy) - walk_uv(N, qa.xy))
        : vec2(0.0);
}

// Whether the segment from Xa to Xb can meet the shell of an overlapping triangle of T:
// walk_near's slab test on the distinct planes of T's overlapping triangles (five words
// each, not a triangle's corners).
bool walk_planes_near(WalkTri T, vec3 Xa, vec3 Xb, float side) {
    uint base = walk_word(12) + T.planes.x * WALK_PLANE_WORDS;
    for (uint k = 0u; k < T.planes.y; ++k) {
        uint w = base + k * WALK_PLANE_WORDS;
        vec3 n = side * walk_v3(w);
        float o = side * walk_f(w + 3u);
        float depth = pc.depth_scale * walk_f(w + 4u);
        vec2 d = vec2(dot(Xa, n), dot(Xb, n)) - o;
        if (walk_slab_near(d, depth, 0.125, 1.125)) {
            return true;
        }
    }
    return false;
}

// Whether a point of the neighbour N (solved: q) is in its shell and inside its relief.
bool walk_in_relief(WalkTri N, vec3 q, vec2 tiles) {
    float t = walk_t(N, q);
    if (!(min(1.0 - q.x - q.y, min(q.x, q.y)) >= WALK_INSIDE && t >= 0.0)) {
        return false;
    }
    vec2 b = max(q.xy, vec2(0.0));
    b /= max(b.x + b.y, 1.0);
    vec2 uv = walk_uv(N, b) + tiles;
    return !leaves_domain(uv) && height_exact(uv) >= 1.0 - t;
}

// The overlapping triangles of T (the first 32 of its list) whose shell the segment from Xa
// to Xb can meet (walk_near), as bits: the loops below then run their solves and
// traversals once per such triangle, not once per overlapping triangle (a CPU driver's
// lanes run a loop's body as often as the lane that needs it most).
uint walk_overlap_mask(WalkTri T, vec3 Xa, vec3 Xb, float side) {
    uint mask = 0u;
    uint list = walk_word(11) + T.overlaps.x;
    uint n = min(T.overlaps.y, 32u);
    for (uint k = 0u; k < n; ++k) {
        if (walk_near(walk_tri(walk_word(list + k), side), Xa, Xb)) {
            mask |= 1u << k;
        }
    }
    return mask;
}

// The next overlapping triangle to test, its index in T's overlap list: the lowest bit of
// `mask` (cleared), then those past the first 32 (`beyond` counts them); false when none
// is left.
bool walk_next_overlap(WalkTri T, inout uint mask, inout uint beyond, out uint k) {
    if (mask != 0u) {
        k = uint(findLSB(mask));
        mask &= mask - 1u;
        return true;
    }
    k = 32u + beyond;
    beyond += 1u;
    return k < T.overlaps.y;
}

// Where the shells of two triangles overlap (inside the solid along a crease, where their
// normals part), the ray can meet the other's relief while it walks this one's shell: the
// surface is every piece's, as the reference's. Tests the triangles overlapping `at`'s
// for a crossing into their relief between the ray parameters sa (the point of `at`) and
// sb: true with the first such crossing, refined by bisection, in `hit`.
bool walk_overlaps(WalkAt at, vec3 X0, vec3 R, float sa, float sb, float side, vec2 tiles,
                   inout uint iterations, out Hit hit) {
    hit = Hit(vec2(0.0), NO_HIT_HEIGHT, 0u);
    if (!walk_planes_near(at.T, X0 + sa * R, X0 + sb * R, side)) {
        return false;
    }
    float s_first = sb;
    uint list = walk_word(11) + at.T.overlaps.x;
    uint mask = walk_overlap_mask(at.T, X0 + sa * R, X0 + sb * R, side);
    uint beyond = 0u;
    uint k;
    while (walk_next_overlap(at.T, mask, beyond, k)) {
        uint t = walk_word(list + k);
        WalkTri N = walk_tri(t, side);
        if (k >= 32u && !walk_near(N, X0 + sa * R, X0 + sb * R)) {
            continue;
        }
        vec3 qa = walk_solve(N, X0 + sa * R, vec3(1.0 / 3.0, 1.0 / 3.0, at.q.z), WALK_NEWTON_ENTER);
        iterations += 1u;
        vec2 tiles_n = walk_tiles_in(at, N, qa, tiles);
        // A crossing of its surface: from a point in its shell above its relief (not an
        // entry through the side of its shell, or from below its offset surface).
        float ta = walk_t(N, qa);
        if (!(min(1.0 - qa.x - qa.y, min(qa.x, qa.y)) >= WALK_INSIDE && ta >= 0.0 && ta <= 1.0)
            || walk_in_relief(N, qa, tiles_n)) {
            continue;
        }
        vec3 qb = walk_solve(N, X0 + s_first * R, qa, WALK_NEWTON_ENTER);
        iterations += 1u;
        if (!walk_in_relief(N, qb, tiles_n)) {
            continue;
        }
        float lo = sa;
        float hi = s_first;
        for (int j = 0; j < WALK_BISECTIONS; ++j) {
            float mid = 0.5 * (lo + hi);
            vec3 qm = walk_solve(N, X0 + mid * R, qb, WALK_NEWTON);
            iterations += 1u;
            if (walk_in_relief(N, qm, tiles_n)) {
                hi = mid;
                qb = qm;
            } else {
                lo = mid;
            }
        }
        s_first = hi;
        hit.h = 0.0;
    }
    if (hit.h >= 0.0) {
        hit = walk_hit_in(at, X0 + s_first * R, tiles, iterations);
        return true;
    }
    return false;
}

// The first parameter u in [0, 1] of the chord from qa to qb (a triangle's (b1, b2, t),
// taken as linear along the chord: exact on a flat triangle) where the point is inside
// the triangle's shell (every barycentric >= 0, 0 <= t <= 1): clipped to [u0, u1], empty
// when u0 > u1.
// One constraint a + u d >= 0 of walk_clip on the interval u.
vec2 walk_clip_one(vec2 u, float a, float d) {
    if (d > 0.0) {
        u.x = max(u.x, -a / d);
    } else if (d < 0.0) {
        u.y = min(u.y, -a / d);
    } else if (a < 0.0) {
        u.y = -1.0;
    }
    return u;
}

vec2 walk_clip(vec3 qa, vec3 qb) {
    vec2 u = vec2(0.0, 1.0);
    u = walk_clip_one(u, 1.0 - qa.x - qa.y, (qa.x + qa.y) - (qb.x + qb.y));
    u = walk_clip_one(u, qa.x, qb.x - qa.x);
    u = walk_clip_one(u, qa.y, qb.y - qa.y);
    // 0 <= t <= 1
    u = walk_clip_one(u, qa.z, qb.z - qa.z);
    u = walk_clip_one(u, 1.0 - qa.z, qa.z - qb.z);
    return u;
}

// walk_overlaps for a chord from A (`at`, ray parameter sa) to sb, each overlapping
// triangle's part of the chord (clipped to its shell, taken as straight in its uv and
// depth) intersected exactly by the pyramid: the first crossing into an overlapping
// triangle's relief through its surface (not at the clipped start, where the chord enters
// its shell through a side or starts inside its relief), as the chord's fraction `u_hit`.
// `near`: the caller has found that the chord comes near the overlapping planes
// (walk_planes_near, true), which is then not tested again.
bool walk_overlaps_chord(WalkAt at, vec3 X0, vec3 R, float sa, float sb, float side, vec2 tiles,
                         bool near, inout uint iterations, inout float u_hit, out Hit hit) {
    hit = Hit(vec2(0.0), NO_HIT_HEIGHT, 0u);
    if (!near && !walk_planes_near(at.T, X0 + sa * R, X0 + sb * R, side)) {
        return false;
    }
    int top = pyramid_levels() - 1;
    uint list = walk_word(11) + at.T.overlaps.x;
    uint mask = walk_overlap_mask(at.T, X0 + sa * R, X0 + sb * R, side);
    uint beyond = 0u;
    uint k;
    while (walk_next_overlap(at.T, mask, beyond, k)) {
        uint t = walk_word(list + k);
        WalkTri N = walk_tri(t, side);
        if (k >= 32u && !walk_near(N, X0 + sa * R, X0 + sb * R)) {
            continue;
        }
        vec3 qa = walk_solve(N, X0 + sa * R, vec3(1.0 / 3.0, 1.0 / 3.0, at.q.z), WALK_NEWTON_ENTER);
        vec3 qb = walk_solve(N, X0 + sb * R, qa, WALK_NEWTON_ENTER);
        iterations += 2u;
        vec3 ta = vec3(qa.xy, walk_t(N, qa));
        vec3 tb = vec3(qb.xy, walk_t(N, qb));
        vec2 u = walk_clip(ta, tb);
        if (!(u.x < u.y) || !(tb.z > ta.z) || u.x >= u_hit) {
            continue;
        }
        vec2 tiles_n = walk_tiles_in(at, N, qa, tiles);
        vec3 q0 = mix(ta, tb, u.x);
        vec3 q1 = mix(ta, tb, u.y);
        vec2 uv0 = walk_uv(N, q0.xy) + tiles_n;
        vec2 uv1 = walk_uv(N, q1.xy) + tiles_n;
        vec2 dir = (uv1 - uv0) / (q1.z - q0.z);
        float sh = pyramid_segment_hit(Ray(uv0 - q0.z * dir, dir), q0.z, q1.z, top, iterations);
        if (!(sh > q0.z + 1e-6)) {
            continue;
        }
        float uh = mix(u.x, u.y, (sh - q0.z) / (q1.z - q0.z));
        if (uh < u_hit) {
            u_hit = uh;
            hit.h = 0.0;
        }
    }
    if (hit.h >= 0.0) {
        hit = walk_hit_in(at, X0 + mix(sa, sb, u_hit) * R, tiles, iterations);
        return true;
    }
    return false;
}

// The start: the triangle of the surface `surface` whose base holds the point X (world),
// from the grid's cell of X. False when no triangle is near enough (not a walked mesh).
bool walk_start(vec3 X, float surface, float side, out WalkAt at) {
    at = WalkAt(0u, WalkTri(vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0),
                            vec3(0.0), vec2(0.0), vec2(0.0), vec2(0.0), uvec3(0u), uvec2(0u), 0u,
                            uvec2(0u)),
                vec3(0.0), vec2(0.0));
    vec3 lo = walk_v3(0u);
    float inv_cell = walk_f(3u);
    uvec3 dims = uvec3(walk_word(4), walk_word(5), walk_word(6));
    vec3 c = floor((X - lo) * inv_cell);
    if (any(lessThan(c, vec3(0.0))) || any(greaterThanEqual(c, vec3(dims)))) {
        return false;
    }
    uvec3 cell = uvec3(c);
    uint index = (cell.z * dims.y + cell.y) * dims.x + cell.x;
    uint offsets = walk_word(9);
    uint lists = walk_word(10);
    uint first = walk_word(offsets + index);
    uint last = walk_word(offsets + index + 1u);
    float best = 1e30;
    // A base point off the triangle's plane by more than this (in cells) is not on it.
    float tolerance = 1e-2 / inv_cell;
    uint chosen = 0u;
    vec2 chosen_b = vec2(0.0);
    for (uint k = first; k < last; ++k) {
        uint t = walk_word(lists + k);
        vec3 p0, p1, p2;
        walk_corners(t, p0, p1, p2);
        vec3 e1 = p1 - p0;
        vec3 e2 = p2 - p0;
        vec3 n = cross(e1, e2);
        float area2 = dot(n, n);
        if (!(area2 > 0.0)) {
            continue;
        }
        vec3 r = X - p0;
        float dist = abs(dot(r, n)) * inversesqrt(area2);
        vec2 b = vec2(dot(cross(r, e2), n), dot(cross(e1, r), n)) / area2;
        float outside = max(0.0, -min(1.0 - b.x - b.y, min(b.x, b.y)));
        float score = dist + outside / inv_cell;
        uint surface_word = walk_word(walk_word(8) + t * WALK_TRIANGLE_WORDS + 30u);
        if (float(surface_word) != surface) {
            score += 1.0 / inv_cell;
        }
        if (score < best) {
            best = score;
            chosen = t;
            chosen_b = b;
        }
    }
    at = WalkAt(chosen, walk_tri(chosen, side), vec3(chosen_b, 0.0), vec2(0.0));
    return best <= tolerance;
}

// Where the straight path from `at` (a flat triangle's base point X0) to X1 (down the
// pixel's ray, in the shell) stays: WALK_PATH_LEAVES (out of the triangle, not into a
// neighbour that continues it flat), WALK_PATH_IN (in the triangle) or WALK_PATH_ACROSS
// (into that neighbour, which holds its end); `near`: whether an overlapping shell of
// the triangles it crosses comes near it.
const int WALK_PATH_LEAVES = 0;
const int WALK_PATH_IN = 1;
const int WALK_PATH_ACROSS = 2;
int walk_flat_path(WalkAt at, vec3 X0, vec3 X1, float side, out bool near) {
    near = walk_planes_near(at.T, X0, X1, side);
    vec3 q = walk_solve(at.T, X1, at.q, 1);
    float b0 = 1.0 - q.x - q.y;
    float m = min(b0, min(q.x, q.y));
    if (m >= 0.0) {
        return WALK_PATH_IN;
    }
    uint edge = m == b0 ? 0u : (m == q.x ? 1u : 2u);
    if ((at.T.flags & (WALK_FLAT_EDGE << edge)) == 0u) {
        return WALK_PATH_LEAVES;
    }
    // The path crosses that edge once (both triangles are convex): the neighbour holds
    // its end.
    WalkTri N = walk_tri(edge == 0u ? at.T.adj.x : (edge == 1u ? at.T.adj.y : at.T.adj.z), side);
    vec3 qn = walk_solve(N, X1, vec3(1.0 / 3.0, 1.0 / 3.0, q.z), 1);
    if (min(1.0 - qn.x - qn.y, min(qn.x, qn.y)) < 0.0) {
        return WALK_PATH_LEAVES;
    }
    // The neighbour's own overlapping shells too.
    near = near || walk_planes_near(N, X0, X1, side);
    return WALK_PATH_ACROSS;
}

// The start of a pixel's walk: its triangle and base point under the entry `entry`
// (eye-relative; `eye`: the eye's world position) on the surface `surface`, the side
// (`frame_normal`: the G-buffer's normal; a two-sided mesh's back side is displaced the
// other way), the ray's world direction `R` and the base point `X0`. False where the
// pixel is on no walked triangle or its ray does not go into the shell (the curved
// trace's result stands).
bool walk_begin(vec3 entry, vec3 eye, vec3 frame_normal, float surface, out WalkAt at,
                out vec3 X0, out vec3 R, out float side) {
    X0 = entry + eye;
    R = normalize(entry);
    side = 1.0;
    if (walk_word(7) == 0u || !walk_start(X0, surface, 1.0, at)) {
        return false;
    }
    side = dot(frame_normal, walk_normal(at.T, at.q.xy)) < 0.0 ? -1.0 : 1.0;
    if (side < 0.0) {
        at.T = walk_tri(at.tri, side);
    }
    // The walk starts on the triangle's own base point under the entry.
    X0 = at.T.p0 + at.q.x * at.T.e1 + at.q.y * at.T.e2;
    return dot(R, walk_normal(at.T, at.q.xy)) < 0.0;
}

#if defined(FIRST) || defined(OVERLAP)
// The walk's flat regions (src/mesh/regions.rs): the table of surface ids from the
// header's word 13 (texels; 0: no region), its entries in word 14. A region's texels:
// (n, o) its plane, (s, E, P, O) its local uv scale (bits) and counts, its affine uv map
// (two texels: u = U . X + u0, v = V . X + v0), E edge texels (inside: m . X >= c), P
// plane pairs, then its O overlapping regions' first texels, four a texel. O's bit
// WALK_REGION_UNLISTED: an overlapping triangle is in no listed region.
const uint WALK_REGION_UNLISTED = 0x80000000u;
// A table entry's word 2: the surface has no flat triangle.
const uint WALK_SURFACE_CURVED = 1u;

// The table entry of the surface `surface`: its regions' first texel and count, and its
// flags (zero where the table has none).
uvec4 walk_surface_entry(float surface) {
    uint table = walk_word(13u);
    uint key = uint(surface);
    if (table == 0u || key >= walk_word(14u)) {
        return uvec4(0u);
    }
    return texelFetch(u_walk, int(table + key));
}

// The first texel of the overlapping regions' list of the region whose first texel is
// `r` and whose counts are `counts` (past its plane, counts, uv map, edges and planes).
int walk_region_list(int r, uvec4 counts) {
    return r + 4 + int(counts.y) + 2 * int(counts.z);
}

// The texels of the region whose first texel is `r`.
int walk_region_texels(int r) {
    uvec4 counts = texelFetch(u_walk, r + 1);
    return walk_region_list(r, counts) - r + int(((counts.w & 0xffffu) + 3u) >> 2u);
}

// The region of a surface (its table entry `bucket`, walk_surface_entry) whose plane holds
// the point X (world), seen from its front (`frame_normal`: the G-buffer's normal): its
// first texel, -1 for none.
int walk_region_of(vec3 X, vec3 frame_normal, uvec4 bucket) {
    float tolerance = 1e-2 / walk_f(3u);
    int found = -1;
    int b = int(bucket.x);
    for (uint r = 0u; r < bucket.y; ++r) {
        vec4 plane = uintBitsToFloat(texelFetch(u_walk, b));
        if (found < 0 && abs(dot(plane.xyz, X) - plane.w) <= tolerance
            && dot(frame_normal, plane.xyz) > 0.0) {
            found = b;
        }
        b += walk_region_texels(b);
    }
    return found;
}

// The straight path of the pixel's ray (direction R) in region `r` from its entry X's base
// point A (on the plane) down to the first trace's hit height `h` (the offset surface for
// a miss), B: false where the ray does not go down into the region's shell.
bool walk_region_path(int r, vec3 X, vec3 R, float h, out vec3 A, out vec3 B) {
    vec4 plane = uintBitsToFloat(texelFetch(u_walk, r));
    float cos_in = -dot(R, plane.xyz);
    A = X - (dot(plane.xyz, X) - plane.w) * plane.xyz;
    B = A;
    if (!(cos_in > 1e-3)) {
        return false;
    }
    float fraction = h >= 0.0 ? 1.0 - min(h, 1.0) : 1.0;
    B = A + (fraction * pc.depth_scale * uintBitsToFloat(texelFetch(u_walk, r + 1).x) / cos_in) * R;
    return true;
}
#endif

#ifdef FIRST
// Whether the walked material's first trace, flat, has met the walk's own hit: the pixel
// (eye-relative entry `entry`, `eye` the eye's world position, its G-buffer normal and
// surface id) lies on the front of a flat region of its surface, and its ray's straight
// path from the entry down to the trace's hit height `h` (to the offset surface for a
// miss) stays inside the region's prism (both ends inside its convex outline) and clear
// of every overlapping plane's slab (walk_planes_near's test, exact for a plane of flat
// triangles: their shells are straight prisms): there the walk follows that path in one
// flat chord, the same straight tangent-space ray the trace intersected (WALK_FIRST_KEEP).
// A path inside the prism that comes near an overlapping slab, in a region whose
// overlapping triangles are all in listed regions, goes to the overlap step
// (WALK_FIRST_OVERLAP); a path that leaves the prism, and a pixel of a surface without a
// flat triangle, to the walk (WALK_FIRST_WALK: the triage would list them); every other
// pixel to the triage. A handful of texel fetches and no solve: the triage's cheap cases
// without its program.
int walk_first(vec3 entry, vec3 eye, vec3 frame_normal, float surface, float h) {
    vec3 X = entry + eye;
    uvec4 bucket = walk_surface_entry(surface);
    if ((bucket.z & WALK_SURFACE_CURVED) != 0u) {
        return WALK_FIRST_WALK;
    }
    int found = walk_region_of(X, frame_normal, bucket);
    vec3 A, B;
    if (found < 0 || !walk_region_path(found, X, normalize(entry), h, A, B)) {
        return WALK_FIRST_TRIAGE;
    }
    uvec4 counts = texelFetch(u_walk, found + 1);
    bool inside = true;
    int e = found + 4;
    for (uint k = 0u; k < counts.y; ++k) {
        vec4 edge = uintBitsToFloat(texelFetch(u_walk, e + int(k)));
        inside = inside && min(dot(edge.xyz, A), dot(edge.xyz, B)) >= edge.w;
    }
    bool near = false;
    int p = e + int(counts.y);
    for (uint k = 0u; k < counts.z; ++k) {
        vec4 q = uintBitsToFloat(texelFetch(u_walk, p + 2 * int(k)));
        // The slab's depth, and its reach above the plane and below it in depths.
        vec3 reach = uintBitsToFloat(texelFetch(u_walk, p + 2 * int(k) + 1).xyz);
        float depth = pc.depth_scale * reach.x;
        vec2 d = vec2(dot(A, q.xyz), dot(B, q.xyz)) - q.w;
        near = near || walk_slab_near(d, depth, reach.y, reach.z);
    }
    if (!inside) {
        // The path leaves the region's prism, out of its flat triangles' (the triage
        // would list it).
        return WALK_FIRST_WALK;
    }
    if (!near) {
        return WALK_FIRST_KEEP;
    }
    return (counts.w & WALK_REGION_UNLISTED) == 0u ? WALK_FIRST_OVERLAP : WALK_FIRST_TRIAGE;
}
#endif

#ifdef OVERLAP
// Region `o`'s uv at the point X (its affine map; the foot of X on its plane).
vec2 walk_region_uv(int o, vec3 X) {
    vec4 mu = uintBitsToFloat(texelFetch(u_walk, o + 2));
    vec4 mv = uintBitsToFloat(texelFetch(u_walk, o + 3));
    return vec2(dot(mu.xyz, X) + mu.w, dot(mv.xyz, X) + mv.w);
}

// Region `o`'s depth fraction at the point X: its depth under the plane over the depth.
float walk_region_t(int o, vec3 X) {
    vec4 plane = uintBitsToFloat(texelFetch(u_walk, o));
    float depth = pc.depth_scale * uintBitsToFloat(texelFetch(u_walk, o + 1).x);
    return (plane.w - dot(plane.xyz, X)) / max(depth, 1e-30);
}

// The part [u.x, u.y] of the segment from A to B (as fractions of it) inside region o's
// shell (its prism, 0 <= t <= 1) where the segment goes down into it; empty (u.x >= u.y)
// elsewhere. `t`: the depth fractions at A and B.
vec2 walk_region_clip(int o, vec3 A, vec3 B, out vec2 t) {
    t = vec2(walk_region_t(o, A), walk_region_t(o, B));
    vec2 u = vec2(0.0, 1.0);
    if (!(t.y > t.x)) {
        return vec2(1.0, 0.0);
    }
    u = walk_clip_one(u, t.x, t.y - t.x);
    u = walk_clip_one(u, 1.0 - t.x, t.x - t.y);
    uint edges = texelFetch(u_walk, o + 1).y;
    for (uint k = 0u; k < edges; ++k) {
        vec4 edge = uintBitsToFloat(texelFetch(u_walk, o + 4 + int(k)));
        float ea = dot(edge.xyz, A) - edge.w;
        u = walk_clip_one(u, ea, (dot(edge.xyz, B) - edge.w) - ea);
    }
    return u;
}

// The first texel of the `k`th overlapping region of the region at `r` (its list from
// texel `list`).
int walk_region_overlap(int list, uint k) {
    uvec4 four = texelFetch(u_walk, list + int(k >> 2u));
    uint c = k & 3u;
    return int(c == 0u ? four.x : (c == 1u ? four.y : (c == 2u ? four.z : four.w)));
}

// The overlap step of a pixel the first trace sent it (WALK_FIRST_OVERLAP): its straight
// path in its flat region down to the first trace's hit (height `h`) passes overlapping
// shells; each overlapping region's part of the path (clipped to its prism and depth,
// straight in its uv and depth: its map is affine) is intersected exactly by the pyramid.
// True with the first crossing into such a region's relief through its surface (not at
// the clipped start, where the path enters its shell through a side) in `hit`, written in
// the pixel's own region's frame (as walk_hit_in: its foot and depth there); false: the
// first trace's hit stands. The same model as the triage's per-triangle test
// (walk_overlaps_chord), a region at a time: no solve, one clip and one traversal per
// overlapping face. The traversals are the pyramid's short-ray copy alone (half the
// code): a pixel whose part of a region is a long ray in texel space goes to the walk
// (WALK_OVERLAP_WALK, glsl/common/trace.glsl).
int walk_region_overlaps(Ray ray, vec3 entry, vec3 eye, vec3 frame_normal, float surface,
                         float h, out Hit hit) {
    hit = miss(ray, 0u);
    vec3 X = entry + eye;
    int r = walk_region_of(X, frame_normal, walk_surface_entry(surface));
    vec3 A, B;
    if (r < 0 || !walk_region_path(r, X, normalize(entry), h, A, B)) {
        return WALK_OVERLAP_KEEP;
    }
    uvec4 counts = texelFetch(u_walk, r + 1);
    int list = walk_region_list(r, counts);
    uint n = min(counts.w & 0xffffu, 32u);
    // The regions whose shell the path enters, as bits: the traversal's loop below then
    // runs once per such region (a CPU driver's lanes run a loop's body as often as the
    // lane that needs it most).
    uint mask = 0u;
    for (uint k = 0u; k < n; ++k) {
        vec2 t;
        vec2 u = walk_region_clip(walk_region_overlap(list, k), A, B, t);
        if (u.x < u.y) {
            mask |= 1u << k;
        }
    }
    int top = pyramid_levels() - 1;
    uint iterations = 0u;
    float u_hit = 1.0;
    bool found = false;
    while (mask != 0u) {
        uint k = uint(findLSB(mask));
        mask &= mask - 1u;
        int o = walk_region_overlap(list, k);
        vec2 t;
        vec2 u = walk_region_clip(o, A, B, t);
        if (!(u.x < u.y) || u.x >= u_hit) {
            continue;
        }
        vec3 X0 = mix(A, B, u.x);
        vec3 X1 = mix(A, B, u.y);
        float t0 = mix(t.x, t.y, u.x);
        float t1 = mix(t.x, t.y, u.y);
        // Its uv moved by whole tiles next to the pixel's (repeat addressing).
        vec2 tiles = pc.addressing == ADDRESSING_REPEAT ? round(ray.uv0 - walk_region_uv(o, A)) : vec2(0.0);
        vec2 uv0 = walk_region_uv(o, X0) + tiles;
        vec2 uv1 = walk_region_uv(o, X1) + tiles;
        vec2 dir = (uv1 - uv0) / (t1 - t0);
        Ray segment = Ray(uv0 - t0 * dir, dir);
        if (!pyramid_ray_short(segment)) {
            return WALK_OVERLAP_WALK;
        }
        float sh = pyramid_short_segment_hit(segment, t0, t1, top, iterations);
        if (!(sh > t0 + 1e-6)) {
            continue;
        }
        float uh = mix(u.x, u.y, (sh - t0) / (t1 - t0));
        if (uh < u_hit) {
            u_hit = uh;
            found = true;
        }
    }
    if (!found) {
        return WALK_OVERLAP_KEEP;
    }
    vec3 Xh = mix(A, B, u_hit);
    vec2 tiles = pc.addressing == ADDRESSING_REPEAT ? round(ray.uv0 - walk_region_uv(r, A)) : vec2(0.0);
    hit = Hit(walk_region_uv(r, Xh) + tiles, 1.0 - clamp(walk_region_t(r, Xh), 0.0, 1.0), iterations);
    return WALK_OVERLAP_HIT;
}
#endif

#ifdef TRIAGE
// The mesh walk's triage of a pixel the first trace listed (its tangent-space ray `ray`,
// the first trace's hit height `h`: < 0 for a miss). The first trace's flat hit stands
// where the ray starts in the relief (every trace gives the hit at the entry), or the
// pixel is on a flat triangle whose straight path down to the trace's hit (to the offset
// surface where it missed) stays in its prism (or the flat neighbour's) and passes no
// overlapping shell: the flat trace is the walk's model itself there. Where that path
// stays in its own triangle's prism but passes overlapping shells (along a cube's
// edges), the walk's first step is done here: the overlapping triangles' relief along the
// path, intersected exactly (walk_overlaps_chord), gives the hit in `hit` when it comes
// before the trace's. Every other pixel is listed, those on no walked triangle too (the
// walk gives them the circle model).
int walk_triage(Ray ray, vec3 entry, vec3 eye, vec3 frame_normal, float surface, float h,
                out Hit hit) {
    hit = miss(ray, 0u);
    WalkAt at;
    vec3 X0, R;
    float side;
    // Off the walked triangles, or a ray that does not go into the shell: the walk's
    // circle model (the first trace was flat).
    if (!walk_begin(entry, eye, frame_normal, surface, at, X0, R, side)) {
        return WALK_LIST;
    }
    if (height_exact(ray.uv0) >= 1.0) {
        return WALK_KEEP;
    }
    if ((at.T.flags & WALK_FLAT) == 0u) {
        return WALK_LIST;
    }
    float cos_in = -dot(R, normalize(at.T.n0));
    if (!(cos_in > 1e-3)) {
        return WALK_LIST;
    }
    // The depth fraction is linear along a flat triangle's path: 1 - h at the hit.
    float fraction = h >= 0.0 ? 1.0 - min(h, 1.0) : 1.0;
    float s1 = fraction * pc.depth_scale * at.T.s.x / cos_in;
    bool near;
    int path = walk_flat_path(at, X0, X0 + s1 * R, side, near);
    if (path == WALK_PATH_LEAVES || (near && path == WALK_PATH_ACROSS)) {
        return WALK_LIST;
    }
    if (!near) {
        return WALK_KEEP;
    }
    vec2 tiles = pc.addressing == ADDRESSING_REPEAT ? round(ray.uv0 - walk_uv(at.T, at.q.xy)) : vec2(0.0);
    uint iterations = 1u;
    float u_hit = 1.0;
    // The path stays in the triangle (WALK_PATH_IN), so `near` is its planes' test.
    return walk_overlaps_chord(at, X0, R, 0.0, s1, side, tiles, true, iterations, u_hit, hit)
        ? WALK_OVERLAP : WALK_KEEP;
}
#else
// The walk of `ray` (the pixel's tangent-space ray: uv0 and P) on the walked mesh, from
// the pixel's eye-relative entry point `entry`, for a pixel the triage listed: true with
// the hit or miss in `hit`, false where the pixel is on no walked triangle or its ray does
// not go into the shell (the caller's circle model).
bool walk_trace(Ray ray, vec3 entry, vec3 eye, vec3 frame_normal, float surface,
                out Hit hit) {
    hit = miss(ray, 0u);
    WalkAt at;
    vec3 X0, R;
    float side;
    if (!walk_begin(entry, eye, frame_normal, surface, at, X0, R, side)) {
        return false;
    }
    vec2 map = vec2(pc.map_size);
    // The G-buffer's uv0 is the entry's uv reduced to [0, 1) (repeat addressing).
    vec2 tiles = pc.addressing == ADDRESSING_REPEAT ? round(ray.uv0 - walk_uv(at.T, at.q.xy)) : vec2(0.0);
    uint iterations = 1u;
    WalkAt prev = at;
    float s_prev = 0.0;
    float s = 0.0;
    bool crossed = false;
    int top = pyramid_levels() - 1;
    float chord_ds = 1e30;
    for (float i = 0.0; i < WALK_MAX_STEPS; i += 1.0) {
        // Descending, the path is followed in chords, each intersected exactly by the
        // pyramid as a straight tangent-space ray (one call below). On a flat triangle
        // the path is straight to where it leaves the triangle's prism (found exactly,
        // the barycentrics and depth being linear along it): one chord there, then on
        // into the neighbour or out of the shell. Elsewhere a chord is as long as its
        // middle stays within WALK_CHORD_TEXELS and WALK_CHORD_DEPTH of the walked path.
        float t_a = walk_t(at.T, at.q);
        vec2 uv_a = walk_at_uv(at, tiles);
        bool chord = false;
        bool flat_chord = false;
        float cds = 0.0;
        float t_b = 0.0;
        vec2 uv_b = uv_a;
        WalkAt B = at;
        float texel_ds = 0.0;
        if ((at.T.flags & WALK_FLAT) != 0u) {
            float cos_in = -dot(R, normalize(at.T.n0));
            float depth = pc.depth_scale * at.T.s.x;
            if (cos_in > 1e-3 && t_a < 1.0 && depth > 0.0) {
                float s1 = s + (1.0 - t_a) * depth / cos_in;
                vec3 q1 = walk_solve(at.T, X0 + s1 * R, at.q, 1);
                vec3 a = vec3(at.q.xy, t_a);
                vec3 b = vec3(q1.xy, 1.0);
                vec2 u = walk_clip(a, b);
                if (u.x <= 1e-6 && u.y > 0.0) {
                    vec3 c = mix(a, b, u.y);
                    cds = u.y * (s1 - s);
                    t_b = c.z;
                    uv_b = walk_uv(at.T, c.xy) + at.shift + tiles;
                    chord = true;
                    flat_chord = true;
                }
            }
        }
        if (!chord) {
            vec3 rate = walk_rate(at.T, at.q, R);
            float t_rate = walk_t_rate(at.T, at.q, rate);
            vec2 duv = (rate.x * at.T.du1 + rate.y * at.T.du2) * map;
            texel_ds = 1.0 / max(max(abs(duv.x), abs(duv.y)), 1e-30);
            cds = t_rate > 0.0 && t_a < 1.0 ? min(2.0 * chord_ds, (1.0 - t_a) / t_rate * 1.0625) : 0.0;
            for (int k = 0; k < WALK_CHORD_HALVINGS && cds > texel_ds; ++k) {
                WalkAt M = at;
                B = at;
                iterations += 2u;
                if (walk_locate(M, X0 + (s + 0.5 * cds) * R, side, WALK_NEWTON_ENTER)
                    && walk_locate(B, X0 + (s + cds) * R, side, WALK_NEWTON_ENTER)) {
                    float t_m = walk_t(M.T, M.q);
                    t_b = walk_t(B.T, B.q);
                    vec2 uv_m = walk_at_uv(M, tiles);
                    uv_b = walk_at_uv(B, tiles);
                    if (t_m > t_a && t_b > t_m
                        && length((uv_m - 0.5 * (uv_a + uv_b)) * map) <= WALK_CHORD_TEXELS
                        && abs(t_m - 0.5 * (t_a + t_b)) <= WALK_CHORD_DEPTH) {
                        chord = true;
                        break;
                    }
                }
                cds *= 0.5;
            }
        }
        if (chord) {
            float t_end = min(t_b, 1.0);
            vec2 dir = (uv_b - uv_a) / (t_b - t_a);
            float sh = pyramid_segment_hit(Ray(uv_a - t_a * dir, dir), t_a, t_end, top, iterations);
            float u_hit = sh >= 0.0 ? (sh - t_a) / (t_b - t_a) : 2.0;
            Hit overlap;
            if (at.T.overlaps.y > 0u
                && walk_overlaps_chord(at, X0, R, s, s + cds, side, tiles, false, iterations, u_hit,
                                       overlap)) {
                overlap.iterations = iterations;
                hit = overlap;
                return true;
            }
            if (sh >= 0.0) {
                hit = Hit(uv_a + (sh - t_a) * dir, 1.0 - sh, iterations);
                return true;
            }
            if (t_b >= 1.0 || leaves_domain(uv_b)) {
                // Only a clamp-addressed chord that left the decal gets past the offset.
                hit.iterations = iterations;
                return true;
            }
            if (flat_chord) {
                // Past the prism's side: the neighbour's shell, or out of the shell.
                s += cds * (1.0 + 1e-4);
                iterations += 1u;
                if (!walk_locate(at, X0 + s * R, side, WALK_NEWTON_ENTER) || walk_t(at.T, at.q) < 0.0) {
                    hit.iterations = iterations;
                    return true;
                }
            } else {
                chord_ds = cds;
                at = B;
                s += cds;
            }
            continue;
        }
        // No chord here (the path turns, leaves the shell or bends within two texels):
        // the next try starts short, so that sampling past such a place does not pay a
        // full set of halvings at every sample.
        chord_ds = texel_ds;
        // Else (climbing back, a turning point, an exit, or a chord shorter than a texel)
        // the path is sampled: steps of at most one texel of uv and an eighth of the depth.
        vec3 rate = walk_rate(at.T, at.q, R);
        vec2 duv = (rate.x * at.T.du1 + rate.y * at.T.du2) * map;
        float uv_rate = max(abs(duv.x), abs(duv.y));
        float t_rate = walk_t_rate(at.T, at.q, rate);
        float ds = 1.0 / max(max(uv_rate, 8.0 * abs(t_rate)), 1e-30);
        prev = at;
        s_prev = s;
        s += ds;
        bool inside = walk_locate(at, X0 + s * R, side, WALK_NEWTON);
        iterations += 1u;
        bool exits = !inside || walk_t(at.T, at.q) < 0.0;
        if (exits) {
            // The sample left the shell (over a boundary edge, into a neighbour's shell
            // from outside, or back through the base): the last point inside is found,
            // and the ray is tested up to it.
            WalkAt last = prev;
            float s_in = s_prev;
            float s_out = s;
            for (int k = 0; k < WALK_BISECTIONS; ++k) {
                float s_mid = 0.5 * (s_in + s_out);
                WalkAt mid = last;
                iterations += 1u;
                if (walk_locate(mid, X0 + s_mid * R, side, WALK_NEWTON) && walk_t(mid.T, mid.q) >= 0.0) {
                    s_in = s_mid;
                    last = mid;
                } else {
                    s_out = s_mid;
                }
            }
            at = last;
            s = s_in;
        }
        Hit overlap;
        if (at.T.overlaps.y + prev.T.overlaps.y > 0u
            && walk_overlaps(prev, X0, R, s_prev, s, side, tiles, iterations, overlap)) {
            hit = overlap;
            return true;
        }
        // Where the ray turns back towards the base between the two samples (t'
        // changes sign: near outlines), its deepest point is found by bisection on the
        // sign of t' and tested: a ray that only touches the relief there is not
        // stepped over.
        if (t_rate > 0.0 && s > s_prev) {
            vec3 rate_end = walk_rate(at.T, at.q, R);
            if (!(walk_t_rate(at.T, at.q, rate_end) > 0.0)) {
                WalkAt lo = prev;
                float s_lo = s_prev;
                float s_hi = s;
                for (int k = 0; k < WALK_BISECTIONS; ++k) {
                    float s_mid = 0.5 * (s_lo + s_hi);
                    WalkAt mid = lo;
                    iterations += 1u;
                    if (walk_locate(mid, X0 + s_mid * R, side, WALK_NEWTON)
                        && walk_t_rate(mid.T, mid.q, walk_rate(mid.T, mid.q, R)) > 0.0) {
                        s_lo = s_mid;
                        lo = mid;
                    } else {
                        s_hi = s_mid;
                    }
                }
                vec2 uv = walk_at_uv(lo, tiles);
                if (s_lo > s_prev && !leaves_domain(uv) && height_exact(uv) >= 1.0 - walk_t(lo.T, lo.q)) {
                    at = lo;
                    s = s_lo;
                    crossed = true;
                    break;
                }
            }
        }
        if (s <= s_prev) {
            break;
        }
        vec2 uv = walk_at_uv(at, tiles);
        if (leaves_domain(uv)) {
            break;
        }
        if (height_exact(uv) >= 1.0 - walk_t(at.T, at.q)) {
            crossed = true;
            break;
        }
        if (exits) {
            break;
        }
    }
    if (!crossed) {
        hit.iterations = iterations;
        return true;
    }
    // Bisection between the last sample above the surface and the first below.
    WalkAt below = at;
    float s_above = s_prev;
    float s_below = s;
    for (int k = 0; k < WALK_BISECTIONS; ++k) {
        float s_mid = 0.5 * (s_above + s_below);
        WalkAt mid = prev;
        if (!walk_locate(mid, X0 + s_mid * R, side, WALK_NEWTON)) {
            s_above = s_mid;
            continue;
        }
        iterations += 1u;
        float t = walk_t(mid.T, mid.q);
        vec2 uv = walk_at_uv(mid, tiles);
        if (height_exact(uv) >= 1.0 - t) {
            s_below = s_mid;
            below = mid;
        } else {
            s_above = s_mid;
            prev = mid;
        }
    }
    float t_hit = clamp(walk_t(below.T, below.q), 0.0, 1.0);
    vec2 uv_hit = walk_at_uv(below, tiles);
    hit = Hit(uv_hit, 1.0 - t_hit, iterations);
    return true;
}
#endif

#endif
