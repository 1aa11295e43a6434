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
// kappa and the depth's change come from the G-buffer's curve image, which the G-buffer
// pass writes from the screen derivatives of the triangle's interpolants
// (dispmap_gbuffer_curve in glsl/include/dispmap_gbuffer.glsl: exact for the interpolated
// normal and uv scale of the triangle under the pixel, whatever its neighbours are); lat
// from the pixel's centre ray (pc.view_*: the near-plane point at the frame's centre and
// its steps per NDC unit, eye-relative, TraceView on the CPU) and its decoded frame. A
// pixel whose curve is 0 (a flat triangle, the plane, a head-on ray), or whose normal
// faces away from its ray, traces flat.
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
    float f_end;  // its foot (curve_foot(t_end)), where the marchers' steps end
    bool bottom;  // whether t_end is on the offset surface (then a hit is certain)
};
Curve g_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, false);

// The eye-relative position of pixel q's macro surface point (infinite reverse-Z: the
// near-plane point of its centre ray over its depth).
vec3 curve_position(ivec2 q, float depth) {
    vec2 ndc = (vec2(q) + 0.5) / vec2(pc.frame_size) * 2.0 - 1.0;
    vec3 near = pc.view_origin.xyz + ndc.x * pc.view_dx.xyz + ndc.y * pc.view_dy.xyz;
    return near / depth;
}

void curve_extent(inout Curve c);

// The curve of `pixel` (see the top of this file): its curvature and depth change from
// the curve image, the ray's slant from its centre ray and frame.
Curve curve_of(ivec2 pixel, Ray ray) {
    Curve flat_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, false);
#ifdef CURVED
    vec2 stored = texelFetch(u_curve, pixel, 0).xy;
    DispmapFrame f = gbuffer_frame(pixel);
    vec3 N = f.normal;
    vec3 T = f.tangent;
    vec3 B = gbuffer_bitangent(f);
    vec3 V = normalize(curve_position(pixel, texelFetch(u_depth, pixel, 0).r));
    float vz = -dot(V, N);
    if (!(vz > 1e-4)) {
        return flat_curve;
    }
    vec3 lat = (dot(V, T) * T + dot(V, B) * B) / vz;
    float tan2 = dot(lat, lat);
    // kappa D kept below 1 (a radius of curvature above the depth: the offset surface
    // stays a surface).
    float kappa = clamp(stored.x, -4.0, 0.99);
    float k = 0.5 * kappa * tan2;
    if (isinf(k) || isnan(k) || k == 0.0) {
        return flat_curve;
    }
    float g = isnan(stored.y) || isinf(stored.y) ? 0.0 : stored.y;
    Curve c = Curve(k, kappa, kappa * sqrt(tan2), g, 0.0, 0.0, false);
    curve_extent(c);
    return c;
#else
    return flat_curve;
#endif
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

// The ray's height above the offset surface at t, as a fraction of the depth at its foot
// (`foot`: curve_foot(c, t)); the depth relative to the pixel's is linear in the foot, at
// least 1/16.
float curve_h_at(Curve c, float t, float foot) {
    return 1.0 - curve_delta(c, t) / max(1.0 + c.g * foot, 0.0625);
}

float curve_h(Curve c, float t) {
    return curve_h_at(c, t, curve_foot(c, t));
}

// The ray's height at t and its foot's uv (one foot for both).
float curve_point(Curve c, Ray ray, float t, out vec2 uv) {
    float foot = curve_foot(c, t);
    uv = ray.uv0 + foot * ray.P;
    return curve_h_at(c, t, foot);
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

// The ray by its foot: with f the foot's distance along P in units of t (uv = uv0 + f P)
// the foot's angle at the circle's centre is psi = a f, and with the half angle's
// q = (cos(psi / 2), sin(psi / 2) / a) (finite as a -> 0, where it is (1, f / 2)) the
// ray's point is closed and rational in q: S = sin(psi) / a = 2 q.s q.c, C = cos(psi) =
// 1 - 2 a^2 q.s^2, D = C + kappa S (the base circle's radius over the point's), t = S / D
// and delta = (S - 4 k q.s^2) / D (the same curve as curve_delta and curve_foot, no
// cancellation as kappa -> 0, where it is f - k f^2 + ...). So
//     h(f) = 1 - num / den,   num = S - 4 k q.s^2,   den = D max(1 + g f, 1/16),
// with den > 0 on every point of the ray (the radii are positive), and a step of df turns
// q by a fixed rotation: a march uniform in the foot (uniform in uv, as a height-map
// march wants) needs no transcendental and no division per step.
struct CurveAngle {
    float c;  // cos(a f / 2)
    float s;  // sin(a f / 2) / a
};

CurveAngle curve_angle(Curve c, float f) {
    float half_angle = 0.5 * c.a * f;
    return CurveAngle(cos(half_angle), abs(c.a) > 1e-6 ? sin(half_angle) / c.a : 0.5 * f);
}

// q turned by the step r (r = curve_angle(c, df): q becomes the angle of f + df); a2 = a^2.
CurveAngle curve_turn(CurveAngle q, CurveAngle r, float a2) {
    return CurveAngle(q.c * r.c - a2 * (q.s * r.s), q.s * r.c + q.c * r.s);
}

// The half of the step r (the angle of df / 2 from that of df).
CurveAngle curve_halve(CurveAngle r) {
    float c = sqrt(0.5 + 0.5 * r.c);
    return CurveAngle(c, r.s / (2.0 * c));
}

// (num, den) of h at the foot f whose angle is q (h = 1 - num / den, den > 0).
vec2 curve_fraction(Curve c, CurveAngle q, float f) {
    float s2 = q.s * q.s;
    float S = 2.0 * q.s * q.c;
    float D = 1.0 - 2.0 * (c.a * c.a) * s2 + c.kappa * S;
    return vec2(S - 4.0 * c.k * s2, D * max(1.0 + c.g * f, 0.0625));
}

float curve_h_foot(Curve c, CurveAngle q, float f) {
    vec2 nd = curve_fraction(c, q, f);
    return 1.0 - nd.x / nd.y;
}

// The foot of the ray's point at t and its angle q, from the point's direction seen from
// the circle's centre (x, y) = (1 - kappa t, a t) rho: q by the half-angle formulas (the
// angle stays below pi / 2 where this is used), f = curve_foot(c, t) (one atan).
float curve_foot_angle(Curve c, float t, out CurveAngle q) {
    float x = 1.0 - c.kappa * t;
    float rho = length(vec2(x, c.a * t));
    float half_cos = sqrt(0.5 + 0.5 * x / rho);
    q = CurveAngle(half_cos, t / (2.0 * rho * half_cos));
    return curve_foot(c, t);
}

// The bottom's tolerance: t_end is the first t where h <= 0, found to within 1e-6 of the
// depth in h (or to 1e-6 of f_end in the foot), at most CURVE_EXTENT_ITERATIONS Newton
// steps.
const float CURVE_EXTENT_TOL = 1e-6;
const int CURVE_EXTENT_ITERATIONS = 16;

// Sets c.t_end, c.f_end and c.bottom: the first t where h reaches 0 (the offset surface),
// or else where the ray comes back out through the base surface (delta = 0 again: t = 2 /
// (kappa + 2 k), whose foot is twice the foot of the circle ray's lowest point, the
// middle of its chord). Whether the ray reaches the offset: h at that lowest point (a
// concave ray has none: h where it is below the offset circle, doubling t up to 8 times;
// one that is still above the offset there never leaves the shell, and its foot's span
// ends at that last point).
// The root, in the foot f: with den h = den - num = G(f), whose derivative is closed in
// q (dS/df = C, dC/df = -a^2 S, d(4 k q.s^2)/df = 2 k S), Newton's method from the circle's
// closed form (exact when the depth does not change, g = 0: no step), kept in the bracket
// (a step that leaves it bisects).
void curve_extent(inout Curve c) {
    float qa = c.kappa + 2.0 * c.k;
    float t_top = qa > 0.0 ? 2.0 / qa : 3.0e38;
    // The lowest point of the circle ray (the middle of its chord through the base).
    float t_hi = qa > 0.0 ? 0.5 * t_top : max(curve_t_bottom_circle(c), 1.0);
    CurveAngle q_hi;
    float f_hi = curve_foot_angle(c, t_hi, q_hi);
    vec2 nd = curve_fraction(c, q_hi, f_hi);
    for (int i = 0; i < 8 && qa <= 0.0 && nd.x < nd.y; ++i) {
        t_hi *= 2.0;
        f_hi = curve_foot_angle(c, t_hi, q_hi);
        nd = curve_fraction(c, q_hi, f_hi);
    }
    if (nd.x < nd.y) {
        c.t_end = t_top;
        c.f_end = qa > 0.0 ? 2.0 * f_hi : f_hi;
        c.bottom = false;
        return;
    }
    float f_lo = 0.0;
    float f = f_hi;
    CurveAngle q = q_hi;
    float t_c = curve_t_bottom_circle(c);
    if (t_c > 0.0 && t_c < t_hi) {
        f = curve_foot_angle(c, t_c, q);
    }
    float a2 = c.a * c.a;
    for (int i = 0; i < CURVE_EXTENT_ITERATIONS; ++i) {
        nd = curve_fraction(c, q, f);
        float G = nd.y - nd.x;
        if (abs(G) <= CURVE_EXTENT_TOL * nd.y) {
            break;
        }
        if (G > 0.0) {
            f_lo = f;
        } else {
            f_hi = f;
        }
        if (f_hi - f_lo <= CURVE_EXTENT_TOL * f_hi) {
            break;
        }
        float S = 2.0 * q.s * q.c;
        float C = 1.0 - 2.0 * a2 * q.s * q.s;
        float D = C + c.kappa * S;
        float m = 1.0 + c.g * f;
        float dG = (c.kappa * C - a2 * S) * max(m, 0.0625) + (m > 0.0625 ? D * c.g : 0.0)
                   - (C - 2.0 * c.k * S);
        float f_next = f - G / dG;
        f = f_next > f_lo && f_next < f_hi ? f_next : 0.5 * (f_lo + f_hi);
        q = curve_angle(c, f);
    }
    float S = 2.0 * q.s * q.c;
    c.t_end = S / (1.0 - 2.0 * a2 * q.s * q.s + c.kappa * S);
    c.f_end = f;
    c.bottom = true;
}

// The marchers' rotation recurrence is re-anchored on the exact angle every
// CURVE_ANCHOR_STEPS steps: its f32 drift (a few ulps a step) stays near 2e-5 of the
// angle's sine, far below a step.
const uint CURVE_ANCHOR_STEPS = 64u;

// The curved marchers (relief, pom): `steps` samples per unit of t over the ray's span in
// the shell (to the offset surface, or back out through the base surface; at least
// `steps`), spaced equally in the foot (in uv, as a height-map march wants), each
// sample's height compared without a division (s >= h is (1 - s) den <= num); the crossing refined by `refine_steps` bisections of the foot
// (relief) or by the line through the last two samples (pom). A ray that leaves the
// shell, or a clamp ray the decal, without meeting the surface is a miss.
Hit curved_march(Ray ray, Curve c, uint steps, uint refine_steps, bool pom) {
    uint n = uint(min(ceil(float(max(steps, 1u)) * max(c.t_end, 1.0)), 4096.0));
    float df = c.f_end / float(n);
    float a2 = c.a * c.a;
    CurveAngle turn = curve_angle(c, df);
    CurveAngle q = CurveAngle(1.0, 0.0);
    // Carried for pom only (the last two samples' heights and the previous fraction).
    vec2 nd_prev = vec2(0.0, 1.0);
    float s_prev = 0.0;
    float s_last = 0.0;
    // The march finds the crossing and stops, carrying only the sample's index and angle;
    // the refinement runs after the loop (not inside it), so a SIMD CPU device (lavapipe)
    // runs it once per group of lanes. The re-anchoring runs between runs of
    // CURVE_ANCHOR_STEPS samples, not in the sample loop: such a device runs an `if`'s
    // body under a mask whether any lane takes it or not (its sine and cosine every
    // step); the samples and angles are those of re-anchoring inside the loop.
    uint i = 0u;
    bool stop = false;
    while (!stop) {
        uint run_end = i + CURVE_ANCHOR_STEPS;
        for (; i < run_end; ++i) {
            float f = float(i) * df;
            vec2 uv = ray.uv0 + f * ray.P;
            if (i > n || leaves_domain(uv)) {
                stop = true;
                break;
            }
            vec2 nd = curve_fraction(c, q, f);
            float s = height_at(uv);
            if (pom) {
                s_prev = s_last;
                s_last = s;
            }
            if ((1.0 - s) * nd.y <= nd.x || (i == n && c.bottom)) {
                stop = true;
                break;
            }
            if (pom) {
                nd_prev = nd;
            }
            q = curve_turn(q, turn, a2);
        }
        if (!stop) {
            q = curve_angle(c, float(i) * df);
        }
    }
    // Past the end, or off the decal: a miss (every sample before it a fetch).
    float f = float(i) * df;
    if (i > n || leaves_domain(ray.uv0 + f * ray.P)) {
        return miss(ray, i);
    }
    uint iterations = i + 1u;
    if (i == 0u) {
        return Hit(ray.uv0, 1.0, iterations);
    }
    float f_prev = f - df;
    float f_hit;
    CurveAngle q_hit;
    if (pom) {
        vec2 nd = curve_fraction(c, q, f);
        float h = (i == n && c.bottom) ? 0.0 : 1.0 - nd.x / nd.y;
        float above_prev = 1.0 - nd_prev.x / nd_prev.y - s_prev;
        float w = above_prev / (above_prev + (s_last - h));
        f_hit = mix(f_prev, f, w);
        q_hit = curve_angle(c, f_hit);
    } else {
        // Bisection of [f_prev, f]: the middle is the upper end of the part above the
        // surface turned by half the interval, whose angle halves each time.
        float width = df;
        CurveAngle half_turn = turn;
        CurveAngle q_above = curve_angle(c, f_prev);
        float f_above = f_prev;
        for (uint j = 0u; j < refine_steps; ++j) {
            width *= 0.5;
            half_turn = curve_halve(half_turn);
            float f_mid = f_above + width;
            CurveAngle q_mid = curve_turn(q_above, half_turn, a2);
            iterations += 1u;
            vec2 nd_mid = curve_fraction(c, q_mid, f_mid);
            if (!((1.0 - height_at(ray.uv0 + f_mid * ray.P)) * nd_mid.y <= nd_mid.x)) {
                f_above = f_mid;
                q_above = q_mid;
            }
        }
        f_hit = f_above + 0.5 * width;
        q_hit = curve_turn(q_above, curve_halve(half_turn), a2);
    }
    return Hit(ray.uv0 + f_hit * ray.P, curve_h_foot(c, q_hit, f_hit), iterations);
}

#endif
