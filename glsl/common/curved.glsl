// Curved macro geometry in the trace (TRACE_FLAG_CURVED): the ray's depth below the
// curved base surface, a miss when it crosses the shell, and the per-pixel curvature it
// needs. Included by trace.glsl after search.glsl; docs/methods.md ("Curved surfaces")
// explains the model and its limits.
//
// In tangent space the flat trace's ray has height h(t) = 1 - t above the inward offset
// at uv0 + t P. On a curved base the surface under the ray bends away from (convex) or
// towards (concave) the tangent plane by (1/2) p'.N' t^2, where p' is the world step of
// the ray's foot per unit t and N' = dN/dt the normal's change along it (the second
// fundamental form of the step), while the ray descends t D below the tangent plane (D
// the world depth). Its height above the offset surface, as a fraction of D:
//     h(t) = 1 - t + k t^2,   k = (p'.N') / (2 D) = (lat . (J P)) / 2,
// with lat = (V.T T + V.B B) / -V.N the world lateral step per unit depth (D cancels) and
// J = dN/duv, so J P is the normal's change per unit t. A ray with k > 1/4 never reaches
// the offset (h = 0): if it meets no relief before h climbs back to 1 at t = 1 / k, it
// has left the shell through the base surface: a miss. That is the second-order form;
// curve_h below traces the osculating circle of the normal section (exact on a sphere),
// with the ray's foot projected radially and the depth following the local uv scale.
//
// k comes from the G-buffer without an extra channel: J from the pixel's right / down
// neighbours (left / up at the frame's edge) on the same surface and material, whose uv
// and normal differences give dN/duv by a 2 x 2 solve; V from the pixel's centre ray
// (pc.view_*: the near-plane point at the frame's centre and its steps per NDC unit,
// eye-relative, TraceView on the CPU). A pixel without neighbours on both axes, or on a
// crease (a neighbour's normal more than 60 degrees away: a cube edge, a two-sided rim),
// or whose normal faces away from its ray, gets k = 0: the flat trace.
#ifndef DISPMAP_CURVED_GLSL
#define DISPMAP_CURVED_GLSL

// The pixel's curve (see above), set by main() when TRACE_FLAG_CURVED is on; k = 0: the
// flat trace.
struct Curve {
    float k;      // the quadric coefficient: h(t) = 1 - t + k t^2 + O(t^3)
    float kappa;  // the normal curvature along the ray in units of the depth (kappa D)
    float a;      // kappa D tan(theta), theta the ray's angle from the normal
    float g;      // the depth's relative change along the ray's foot, per unit of t
    float t_end;  // where the ray reaches the offset surface, or leaves the shell
    bool bottom;  // whether t_end is on the offset surface (then a hit is certain)
};
Curve g_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, false);

// The eye-relative position of pixel q's macro surface point (infinite reverse-Z: the
// near-plane point of its centre ray over its depth).
vec3 curve_position(ivec2 q) {
    vec2 ndc = (vec2(q) + 0.5) / vec2(pc.frame_size) * 2.0 - 1.0;
    vec3 near = pc.view_origin.xyz + ndc.x * pc.view_dx.xyz + ndc.y * pc.view_dy.xyz;
    return near / texelFetch(u_depth, q, 0).r;
}

// A neighbour of `pixel` along axis `a` (the +a side first) on the same material and
// surface, its normal within 60 degrees of N: its pixel and the side (+1 / -1). False
// when neither side qualifies.
bool curve_neighbour(ivec2 pixel, int a, vec3 N, float surface, out ivec2 q, out float side) {
    for (int i = 0; i < 2; ++i) {
        q = pixel;
        side = i == 0 ? 1.0 : -1.0;
        q[a] += i == 0 ? 1 : -1;
        if (q[a] < 0 || q[a] >= int(pc.frame_size[a]) || pixel_material(q) != pc.material) {
            continue;
        }
        if (gbuffer_surface(q) != surface || dot(gbuffer_normal(q), N) < 0.5) {
            continue;
        }
        return true;
    }
    return false;
}

// The uv step from uv0 to pixel q's entry, times `side` (per pixel towards +a).
vec2 curve_duv(ivec2 q, vec2 uv0, float side) {
    vec2 d = texelFetch(u_ray, q, 0).xy - uv0;
    if (pc.addressing == ADDRESSING_REPEAT) {
        d -= round(d);
    }
    return side * d;
}

// The uv and normal steps per pixel towards +a at `pixel`: central over its two
// neighbours when the other side (of q, on side `side`) qualifies too, else one-sided.
void curve_step(ivec2 pixel, int a, ivec2 q, float side, vec2 uv0, vec3 N, float surface,
                out vec2 duv, out vec3 dn) {
    duv = curve_duv(q, uv0, side);
    dn = side * (gbuffer_normal(q) - N);
    ivec2 o = pixel;
    o[a] -= int(side);
    if (o[a] < 0 || o[a] >= int(pc.frame_size[a]) || pixel_material(o) != pc.material) {
        return;
    }
    vec3 n = gbuffer_normal(o);
    if (gbuffer_surface(o) != surface || dot(n, N) < 0.5) {
        return;
    }
    duv = 0.5 * (duv - curve_duv(o, uv0, side));
    dn = 0.5 * (dn - side * (n - N));
}

// The 2 x 2 determinant of the uv steps, or 0 when they are (nearly) parallel.
float curve_det(vec2 du0, vec2 du1) {
    float det = du0.x * du1.y - du1.x * du0.y;
    return abs(det) > 1e-6 * (dot(du0, du0) + dot(du1, du1)) ? det : 0.0;
}

// The log of the local uv scale S = sqrt(|dp/du| |dp/dv|) (world length of one uv unit)
// at pixel q, from its neighbours' positions and uvs; false without two neighbours.
bool curve_log_scale(ivec2 q, vec3 N, float surface, out float log_s) {
    log_s = 0.0;
    ivec2 q0, q1;
    float s0, s1;
    if (!curve_neighbour(q, 0, N, surface, q0, s0) || !curve_neighbour(q, 1, N, surface, q1, s1)) {
        return false;
    }
    vec2 uv = texelFetch(u_ray, q, 0).xy;
    vec2 du0 = curve_duv(q0, uv, s0);
    vec2 du1 = curve_duv(q1, uv, s1);
    float det = curve_det(du0, du1);
    if (det == 0.0) {
        return false;
    }
    vec3 p = curve_position(q);
    vec3 dp0 = s0 * (curve_position(q0) - p);
    vec3 dp1 = s1 * (curve_position(q1) - p);
    vec3 dpdu = (dp0 * du1.y - dp1 * du0.y) / det;
    vec3 dpdv = (dp1 * du0.x - dp0 * du1.x) / det;
    float area = length(dpdu) * length(dpdv);
    if (!(area > 0.0) || isinf(area)) {
        return false;
    }
    log_s = 0.5 * log(area);
    return true;
}

void curve_extent(inout Curve c);

// The curve of `pixel` (see the top of this file).
Curve curve_of(ivec2 pixel, Ray ray) {
    Curve flat_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, false);
    DispmapFrame f = gbuffer_frame(pixel);
    vec3 N = f.normal;
    vec3 T = f.tangent;
    vec3 B = gbuffer_bitangent(f);
    float surface = gbuffer_surface(pixel);
    vec3 V = normalize(curve_position(pixel));
    float vz = -dot(V, N);
    if (!(vz > 1e-4)) {
        return flat_curve;
    }
    ivec2 q0, q1;
    float s0, s1;
    if (!curve_neighbour(pixel, 0, N, surface, q0, s0) || !curve_neighbour(pixel, 1, N, surface, q1, s1)) {
        return flat_curve;
    }
    // Central differences where both sides qualify (the f16 normals' rounding halves and
    // the first-order bias of a one-sided step goes), else one-sided.
    vec2 du0, du1;
    vec3 dn0, dn1;
    curve_step(pixel, 0, q0, s0, ray.uv0, N, surface, du0, dn0);
    curve_step(pixel, 1, q1, s1, ray.uv0, N, surface, du1, dn1);
    float det = curve_det(du0, du1);
    if (det == 0.0) {
        return flat_curve;
    }
    // With M = [du0 du1] (columns) and w = M^-1 P: J P = [dn0 dn1] w, and a gradient's
    // component along P is its two differences dotted with w.
    vec2 w = vec2(du1.y * ray.P.x - du1.x * ray.P.y, du0.x * ray.P.y - du0.y * ray.P.x) / det;
    vec3 dN = dn0 * w.x + dn1 * w.y;
    vec3 lat = (dot(V, T) * T + dot(V, B) * B) / vz;
    float tan2 = dot(lat, lat);
    float k = 0.5 * dot(lat, dN);
    // The curvature in units of the depth, kappa D = 2 k / tan^2(theta), kept below 1 (a
    // radius of curvature above the depth: the offset surface stays a surface).
    float kappa = tan2 > 1e-12 ? clamp(2.0 * k / tan2, -4.0, 0.99) : 0.0;
    if (isinf(k) || isnan(k) || isnan(kappa) || k == 0.0) {
        return flat_curve;
    }
    // The depth is depth_scale local uv units (src/mesh.rs): its change along the ray
    // from the uv scale's at the pixel and its two neighbours (0 where one is unknown).
    float g = 0.0;
    float l, l0, l1;
    if (curve_log_scale(pixel, N, surface, l) && curve_log_scale(q0, N, surface, l0)
        && curve_log_scale(q1, N, surface, l1)) {
        // One-sided steps here (the scale's neighbours are q0 and q1).
        vec2 e0 = curve_duv(q0, ray.uv0, s0);
        vec2 e1 = curve_duv(q1, ray.uv0, s1);
        float d1 = curve_det(e0, e1);
        vec2 v = d1 == 0.0 ? vec2(0.0)
            : vec2(e1.y * ray.P.x - e1.x * ray.P.y, e0.x * ray.P.y - e0.y * ray.P.x) / d1;
        g = s0 * (l0 - l) * v.x + s1 * (l1 - l) * v.y;
        g = isnan(g) || isinf(g) ? 0.0 : g;
    }
    Curve c = Curve(0.5 * kappa * tan2, kappa, kappa * sqrt(tan2), g, 0.0, false);
    curve_extent(c);
    return c;
}

// The ray in the plane of its normal section, the base surface there a circle of
// curvature kappa (its osculating circle: exact on a sphere, second-order elsewhere), the
// offset surface the concentric circle a depth further in. With x = t D tan(theta) and
// z = t D the ray's lateral travel and depth below the tangent plane, its depth below the
// circle, in units of D, is
//     delta(t) = (2 t - (kappa + 2 k) t^2) / (1 + sqrt((1 - kappa t)^2 + 2 kappa k t^2))
// (kappa, k and t in depth units; no cancellation as kappa -> 0, where it is
// t - k t^2 + ...), and h(t) = 1 - delta(t).
float curve_delta(Curve c, float t) {
    float km = c.kappa * t;
    float root = sqrt((1.0 - km) * (1.0 - km) + 2.0 * km * c.k * t);
    return (2.0 - (c.kappa + 2.0 * c.k) * t) * t / (1.0 + root);
}

// The ray's foot at t: the base point on the circle's radius through the ray's point
// (the surface point whose normal passes through it, as a displaced surface is built),
// as a distance along P in units of t: the angle at the centre over kappa tan(theta).
float curve_foot(Curve c, float t) {
    float y = c.a * t;
    float x = 1.0 - c.kappa * t;
    return abs(c.a) > 1e-6 ? atan(y, x) / c.a : t / x;
}

vec2 curve_uv(Curve c, Ray ray, float t) {
    return ray.uv0 + curve_foot(c, t) * ray.P;
}

// The depth at the foot, relative to the pixel's (linear in the foot, at least 1/16).
float curve_depth(Curve c, float t) {
    return max(1.0 + c.g * curve_foot(c, t), 0.0625);
}

// The ray's height above the offset surface at t, as a fraction of the depth there.
float curve_h(Curve c, float t) {
    return 1.0 - curve_delta(c, t) / curve_depth(c, t);
}

// Where the circle ray (no depth change) reaches the offset circle of radius 1/kappa - 1
// ((kappa + 2 k) t^2 - 2 t + 2 - kappa = 0, the nearer root), or -1 when it turns back
// up first.
float curve_t_bottom_circle(Curve c) {
    float qa = c.kappa + 2.0 * c.k;
    float qc = 2.0 - c.kappa;
    float d = 1.0 - qa * qc;
    return d >= 0.0 ? qc / (1.0 + sqrt(d)) : -1.0;
}

// Sets c.t_end and c.bottom: the first t where h reaches 0 (the offset surface), found
// by bisection (h's bracket from the circle's), or else where the ray comes back out
// through the base surface (delta = 0 again: t = 2 / (kappa + 2 k)).
void curve_extent(inout Curve c) {
    float qa = c.kappa + 2.0 * c.k;
    float t_top = qa > 0.0 ? 2.0 / qa : 3.0e38;
    // The lowest point of the circle ray (the middle of its chord through the base).
    float t_hi = qa > 0.0 ? 0.5 * t_top : max(curve_t_bottom_circle(c), 1.0);
    for (int i = 0; i < 8 && qa <= 0.0 && curve_h(c, t_hi) > 0.0; ++i) {
        t_hi *= 2.0;
    }
    if (curve_h(c, t_hi) > 0.0) {
        c.t_end = t_top;
        c.bottom = false;
        return;
    }
    float t_lo = 0.0;
    for (int i = 0; i < 24; ++i) {
        float t_mid = 0.5 * (t_lo + t_hi);
        if (curve_h(c, t_mid) > 0.0) {
            t_lo = t_mid;
        } else {
            t_hi = t_mid;
        }
    }
    c.t_end = t_hi;
    c.bottom = true;
}

// The curved marchers (relief, pom): `steps` equal steps in t per unit of t over the ray's
// span in the shell (to the offset surface, or back out through the base surface), at
// least `steps`; the crossing refined by `refine_steps` bisections in t (relief) or by the
// line through the last two samples (pom). A ray that leaves the shell, or a clamp ray the
// decal, without meeting the surface is a miss.
Hit curved_march(Ray ray, Curve c, uint steps, uint refine_steps, bool pom) {
    float t_end = c.t_end;
    uint n = uint(min(ceil(float(max(steps, 1u)) * max(t_end, 1.0)), 4096.0));
    float dt = t_end / float(n);
    uint iterations = 0u;
    float t_prev = 0.0;
    float above_prev = 0.0;
    for (uint i = 0u; i <= n; ++i) {
        float t = i == n ? t_end : float(i) * dt;
        vec2 uv = curve_uv(c, ray, t);
        if (leaves_domain(uv)) {
            return miss(ray, iterations);
        }
        float h = (i == n && c.bottom) ? 0.0 : curve_h(c, t);
        iterations += 1u;
        float s = height_at(uv);
        if (s >= h) {
            if (i == 0u) {
                return Hit(ray.uv0, 1.0, iterations);
            }
            float t_hit;
            if (pom) {
                float w = above_prev / (above_prev + (s - h));
                t_hit = mix(t_prev, t, w);
            } else {
                float t_above = t_prev;
                float t_below = t;
                for (uint j = 0u; j < refine_steps; ++j) {
                    float t_mid = 0.5 * (t_above + t_below);
                    iterations += 1u;
                    if (height_at(curve_uv(c, ray, t_mid)) >= curve_h(c, t_mid)) {
                        t_below = t_mid;
                    } else {
                        t_above = t_mid;
                    }
                }
                t_hit = 0.5 * (t_above + t_below);
            }
            return Hit(curve_uv(c, ray, t_hit), curve_h(c, t_hit), iterations);
        }
        t_prev = t;
        above_prev = h - s;
    }
    return miss(ray, iterations);
}

#endif
