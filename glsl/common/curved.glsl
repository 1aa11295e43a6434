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
    bool bottom;  // whether t_end is on the offset surface (then a hit is certain)
};
Curve g_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, false);

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
    Curve flat_curve = Curve(0.0, 0.0, 0.0, 0.0, 0.0, false);
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
    Curve c = Curve(k, kappa, kappa * sqrt(tan2), g, 0.0, false);
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

// The bottom's tolerance: t_end is the first t where h <= 0, found to within 1e-6 of the
// depth in h (or to 1e-6 of t_end in t), at most CURVE_EXTENT_ITERATIONS evaluations.
const float CURVE_EXTENT_TOL = 1e-6;
const int CURVE_EXTENT_ITERATIONS = 16;

// Sets c.t_end and c.bottom: the first t where h reaches 0 (the offset surface), or else
// where the ray comes back out through the base surface (delta = 0 again: t = 2 /
// (kappa + 2 k)). The root: the circle's closed form (exact when the depth does not
// change, g = 0), then regula falsi with the Illinois modification in the bracket from
// the circle ray's lowest point.
void curve_extent(inout Curve c) {
    float qa = c.kappa + 2.0 * c.k;
    float t_top = qa > 0.0 ? 2.0 / qa : 3.0e38;
    // The lowest point of the circle ray (the middle of its chord through the base).
    float t_hi = qa > 0.0 ? 0.5 * t_top : max(curve_t_bottom_circle(c), 1.0);
    float h_hi = curve_h(c, t_hi);
    for (int i = 0; i < 8 && qa <= 0.0 && h_hi > 0.0; ++i) {
        t_hi *= 2.0;
        h_hi = curve_h(c, t_hi);
    }
    if (h_hi > 0.0) {
        c.t_end = t_top;
        c.bottom = false;
        return;
    }
    float t_lo = 0.0;
    float h_lo = 1.0;
    float t_c = curve_t_bottom_circle(c);
    if (t_c > t_lo && t_c < t_hi) {
        float h = curve_h(c, t_c);
        if (h > 0.0) {
            t_lo = t_c;
            h_lo = h;
        } else {
            t_hi = t_c;
            h_hi = h;
        }
    }
    float f_lo = h_lo;
    float f_hi = h_hi;
    int kept = 0;
    for (int i = 0; i < CURVE_EXTENT_ITERATIONS && h_hi < -CURVE_EXTENT_TOL
         && t_hi - t_lo > CURVE_EXTENT_TOL * t_hi; ++i) {
        float t = clamp((t_lo * f_hi - t_hi * f_lo) / (f_hi - f_lo), t_lo, t_hi);
        float h = curve_h(c, t);
        if (h > 0.0) {
            t_lo = t;
            h_lo = h;
            f_lo = h;
            f_hi = kept == 1 ? 0.5 * f_hi : f_hi;
            kept = 1;
        } else {
            t_hi = t;
            h_hi = h;
            f_hi = h;
            f_lo = kept == -1 ? 0.5 * f_lo : f_lo;
            kept = -1;
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
    float t = 0.0;
    float h = 1.0;
    float s = 0.0;
    bool crossed = false;
    // The march finds the crossing and stops; the refinement runs after the loop (not
    // inside it), so a SIMD CPU device (lavapipe) runs it once per group of lanes.
    uint i = 0u;
    for (; i <= n; ++i) {
        t = i == n ? t_end : float(i) * dt;
        vec2 uv;
        h = curve_point(c, ray, t, uv);
        if (leaves_domain(uv)) {
            break;
        }
        h = (i == n && c.bottom) ? 0.0 : h;
        iterations += 1u;
        s = height_at(uv);
        if (s >= h) {
            crossed = true;
            break;
        }
        t_prev = t;
        above_prev = h - s;
    }
    if (!crossed) {
        return miss(ray, iterations);
    }
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
            vec2 uv_mid;
            float h_mid = curve_point(c, ray, t_mid, uv_mid);
            if (height_at(uv_mid) >= h_mid) {
                t_below = t_mid;
            } else {
                t_above = t_mid;
            }
        }
        t_hit = 0.5 * (t_above + t_below);
    }
    vec2 uv_hit;
    float h_hit = curve_point(c, ray, t_hit, uv_hit);
    return Hit(uv_hit, h_hit, iterations);
}

#endif
