// dispmap's G-buffer contract for a host engine's fragment shader (and dispmap's own
// glsl/gbuffer.frag, so there is one source of truth). Include it, fill a
// DispmapSurface per fragment and write the two colour outputs it returns; the depth
// attachment is the host's own reverse-Z depth. Formats and channels (src/embed/mod.rs,
// src/passes/gbuffer.rs), 28 bytes a pixel:
//
//   ray     R32G32B32A32_SFLOAT  (uv0.x, uv0.y, P.x, P.y): the entry uv (reduced to [0, 1)
//           for repeat addressing, so rays keep full precision far from the origin) and the
//           parallax vector P = depth_scale * V_ts.xy / max(-V_ts.z, min_cos), in uv units
//           (the uv offset after descending the full displacement depth).
//   frame   R32G32_UINT          the shading frame, the material and the surface id in 64
//           bits (dispmap_frame_pack below; read them back with dispmap_frame_unpack):
//           * N, the world-space unit normal, octahedral (Meyer et al. 2010), 14 bits a
//             coordinate;
//           * T, the world-space unit tangent along +u, as its angle (13 bits) in the
//             plane of N from the basis dispmap_frame_basis builds from the decoded N;
//           * the handedness (1 bit): B = handedness * cross(N, T) is the unit bitangent
//             along +v;
//           * material + 1 (11 bits), the material's index in the pass's table
//             (DisplacementPass::add_material, MaterialId::index, 0..1023); 0 means *not
//             displaced*: the pass neither traces nor shades the pixel nor writes its
//             corrected depth, and the depth resolve keeps the host's depth there (clear
//             the attachment to 0 so that pixels without geometry read as not displaced
//             too);
//           * the surface id (11 bits, ids 1..2048 kept modulo 2048): one id per chart of
//             continuous uvs. DIG trusts a block only when its corners share the id.
//           Axis-aligned frames (a plane, a box) decode exactly; any other N or T within
//           about 1.3e-4 (N) and 3.8e-4 (T) radians.
//   depth   D32_SFLOAT           reverse-Z, cleared to 0: 0 means no geometry.
//   curve   R16G16_SFLOAT        only for materials traced curved
//           (DisplacementPass::set_material_curved), cleared to 0: the surface's normal
//           curvature along the pixel's ray and the depth's change along it
//           (dispmap_gbuffer_curve below).
//
// depth_scale is the displacement depth in uv (tile) units: with T and B of unit length a
// tile is one world unit, and the same depth_scale means the same depth in tiles on any
// surface, whatever its world size. V is the unit view direction (eye to fragment) and
// V_ts = (V.T, V.B, V.N). Back faces (V_ts.z >= 0: the eye below the surface) have nothing
// to displace: dispmap_gbuffer_encode returns false and the caller discards them, unless
// the geometry is two-sided (dispmap_surface_back_side below).
// Precision far from the origin: interpolate the position relative to the eye (vertex
// position minus eye, then world_pos = that, camera_pos = vec3(0)), so V keeps its bits
// near the eye wherever the eye is; and give uv tile-local enough that the f32
// interpolant keeps sub-texel precision (the reduction to [0, 1) below cannot restore
// bits lost before it: at 1e4 tiles one ulp is 2^-10 tiles). On dispmap's plane and quad
// do not interpolate at all: dispmap_plane_pixel_ray (dispmap_plane.glsl) gives each
// pixel's entry from its own centre ray, which interpolation near the horizon misses by
// tens of texels.
#ifndef DISPMAP_INCLUDE_GBUFFER_GLSL
#define DISPMAP_INCLUDE_GBUFFER_GLSL

#define DISPMAP_ADDRESSING_REPEAT 0u
#define DISPMAP_ADDRESSING_CLAMP 1u

// Everything the G-buffer needs about one fragment of the macro surface.
struct DispmapSurface {
    vec3 world_pos;     // fragment position (world space; or eye-relative, see below)
    vec3 camera_pos;    // eye position (world space; vec3(0) with an eye-relative world_pos)
    vec2 uv;            // texture coordinates, one unit = one tile of the height map
    vec3 normal;        // unit surface normal N (world space)
    vec3 tangent;       // unit tangent T = direction of +u (world space)
    vec3 bitangent;     // unit bitangent B = direction of +v (world space)
    float surface_id;   // > 0, one id per chart of continuous uvs
    float depth_scale;  // displacement depth in uv units (same value as the pass's)
    float min_cos;      // lower bound of -V_ts.z, e.g. 1e-4: keeps P finite when grazing
    uint addressing;    // DISPMAP_ADDRESSING_REPEAT or DISPMAP_ADDRESSING_CLAMP
};

// The material field of a pixel without displacement (dispmap_frame_pack's
// material_plus_one).
#define DISPMAP_NOT_DISPLACED 0u

// Octahedral coordinates in [-1, 1]^2 of a unit vector (exact for the axes).
vec2 dispmap_oct_encode(vec3 n) {
    n /= abs(n.x) + abs(n.y) + abs(n.z);
    vec2 p = n.xy;
    if (n.z < 0.0) {
        p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    }
    return p;
}

// The unit vector of octahedral coordinates p.
vec3 dispmap_oct_decode(vec2 p) {
    vec3 n = vec3(p, 1.0 - abs(p.x) - abs(p.y));
    if (n.z < 0.0) {
        n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    }
    return normalize(n);
}

// Quantisation of an octahedral coordinate to 14 bits and back (snorm: -1, 0 and 1 exact).
// Ties round to even (roundEven, not round, whose ties are the implementation's), as
// the CPU twin does (src/passes/gbuffer/frame.rs: f32::round_ties_even).
uint dispmap_snorm14(float x) {
    return uint(int(roundEven(clamp(x, -1.0, 1.0) * 8191.0)) + 8191);
}
float dispmap_unsnorm14(uint q) {
    return float(int(q & 0x3FFFu) - 8191) / 8191.0;
}

// An orthonormal basis (b1, b2) of the plane of the unit vector n (Duff et al. 2017,
// "Building an Orthonormal Basis, Revisited"): the reference of the tangent's angle.
void dispmap_frame_basis(vec3 n, out vec3 b1, out vec3 b2) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float b = n.x * n.y * a;
    b1 = vec3(1.0 + sgn * n.x * n.x * a, sgn * b, -sgn * n.x);
    b2 = vec3(b, sgn + n.y * n.y * a, -n.y);
}

// The angles of the tangent: 8192 steps a turn.
#define DISPMAP_TANGENT_STEPS 8192.0

// A frame of the G-buffer, decoded.
struct DispmapFrame {
    vec3 normal;             // unit N
    vec3 tangent;            // unit T, orthogonal to N
    float handedness;        // +1 or -1: B = handedness * cross(N, T)
    uint material_plus_one;  // 0: not displaced
    uint surface_id;         // 1..2048
};

// Packs a fragment's frame (unit N, unit T, the sign of handedness, material + 1 in
// 0..1024, surface id >= 1) into the frame target's two words.
uvec2 dispmap_frame_pack(vec3 normal, vec3 tangent, float handedness, uint material_plus_one,
                         float surface_id) {
    vec2 p = dispmap_oct_encode(normal);
    uint ou = dispmap_snorm14(p.x);
    uint ov = dispmap_snorm14(p.y);
    // The tangent's angle from the basis the decoder builds from the quantised normal.
    vec3 n = dispmap_oct_decode(vec2(dispmap_unsnorm14(ou), dispmap_unsnorm14(ov)));
    vec3 b1, b2;
    dispmap_frame_basis(n, b1, b2);
    float angle = atan(dot(tangent, b2), dot(tangent, b1));
    uint k = uint(int(roundEven(angle * (DISPMAP_TANGENT_STEPS / 6.283185307179586)))) & 0x1FFFu;
    uint id = (uint(max(surface_id, 0.0) + 0.5) - 1u) & 0x7FFu;
    uint x = ou | (ov << 14) | ((id & 0xFu) << 28);
    uint y = k | (handedness < 0.0 ? 1u << 13 : 0u) | (min(material_plus_one, 0x7FFu) << 14)
        | ((id >> 4) << 25);
    return uvec2(x, y);
}

// The material + 1 of a frame (0: not displaced), without decoding the rest.
uint dispmap_frame_material_plus_one(uvec2 bits) {
    return (bits.y >> 14) & 0x7FFu;
}

// The surface id of a frame (1..2048), without decoding the rest.
uint dispmap_frame_surface_id(uvec2 bits) {
    return ((bits.x >> 28) | ((bits.y >> 25) << 4)) + 1u;
}

// The unit normal of a frame, without decoding the rest.
vec3 dispmap_frame_normal(uvec2 bits) {
    return dispmap_oct_decode(vec2(dispmap_unsnorm14(bits.x), dispmap_unsnorm14(bits.x >> 14)));
}

// Unpacks a frame (the inverse of dispmap_frame_pack, within its quantisation).
DispmapFrame dispmap_frame_unpack(uvec2 bits) {
    DispmapFrame f;
    f.normal = dispmap_frame_normal(bits);
    vec3 b1, b2;
    dispmap_frame_basis(f.normal, b1, b2);
    uint k = bits.y & 0x1FFFu;
    // A quarter turn at a time (exact), the rest by cos and sin of an angle < pi / 2.
    float a = float(k & 0x7FFu) * (6.283185307179586 / DISPMAP_TANGENT_STEPS);
    vec2 cs = vec2(cos(a), sin(a));
    uint quarter = k >> 11;
    cs = quarter == 0u ? cs : quarter == 1u ? vec2(-cs.y, cs.x) : quarter == 2u ? -cs : vec2(cs.y, -cs.x);
    f.tangent = cs.x * b1 + cs.y * b2;
    f.handedness = (bits.y & (1u << 13)) != 0u ? -1.0 : 1.0;
    f.material_plus_one = dispmap_frame_material_plus_one(bits);
    f.surface_id = dispmap_frame_surface_id(bits);
    return f;
}

// The same fragment seen from the other side of the surface (a two-sided open mesh, such
// as the inside of a vase): the normal reversed, T and B kept, so the map keeps its uv
// directions and is carved into the surface from the side the eye is on (the handedness
// the encoders write flips with it). A host that draws two-sided geometry calls it for a
// back face before dispmap_gbuffer_encode_material; the pass needs nothing else.
DispmapSurface dispmap_surface_back_side(DispmapSurface s) {
    s.normal = -s.normal;
    return s;
}

// Encodes one fragment of material `material` (its index in the pass's table) into the
// ray and frame targets. Returns false for a back face (discard it).
bool dispmap_gbuffer_encode_material(DispmapSurface s, uint material, out vec4 ray, out uvec2 frame) {
    vec3 V = normalize(s.world_pos - s.camera_pos);
    vec3 v_ts = vec3(dot(V, s.tangent), dot(V, s.bitangent), dot(V, s.normal));
    ray = vec4(0.0);
    frame = uvec2(0u);
    if (v_ts.z >= 0.0) {
        return false;
    }
    vec2 P = s.depth_scale * v_ts.xy / max(-v_ts.z, s.min_cos);
    vec2 uv0 = s.addressing == DISPMAP_ADDRESSING_REPEAT ? s.uv - floor(s.uv) : s.uv;
    ray = vec4(uv0, P);
    float handedness = dot(cross(s.normal, s.tangent), s.bitangent) < 0.0 ? -1.0 : 1.0;
    frame = dispmap_frame_pack(s.normal, s.tangent, handedness, material + 1u, s.surface_id);
    return true;
}

// The screen derivatives the curve output needs (dispmap_gbuffer_curve): `uv` the
// interpolated uv, `normal` the interpolated vertex normal *before* normalising, `scale`
// the interpolated local uv scale sqrt(|dP/du| |dP/dv|) of the vertices (src/mesh.rs
// Vertex::scale; any constant for a surface whose scale does not change). Call it in
// uniform control flow, before any discard (derivatives of a quad whose invocations left
// are undefined). The interpolants are affine in the triangle's barycentrics, so their
// differences within the quad give the triangle's own changes per uv exactly, whatever
// surrounds the pixel.
struct DispmapCurveInputs {
    vec2 dux;
    vec2 duy;
    vec3 dnx;
    vec3 dny;
    float dsx;
    float dsy;
    vec3 normal;
    float scale;
};

// (A macro, so that compute shaders may include this file: pass plain variables.)
#define dispmap_curve_inputs(uv, normal, scale) \
    DispmapCurveInputs(dFdxFine(uv), dFdyFine(uv), dFdxFine(normal), dFdyFine(normal), \
        dFdxFine(scale), dFdyFine(scale), normal, scale)

// The curve output of a fragment of a curved mesh (the curve target, read by the trace's
// curved path, glsl/common/curved.glsl): x = kappa D, the normal curvature of the base
// surface along the ray's lateral direction times the displacement depth D (positive
// where the surface bends away from the eye, a convex one), kept in [-4, 0.99]; y = the
// depth's relative change along the ray's foot per unit of depth descended,
// d(log scale)/dt (the depth is depth_scale local uv scales). `s` is the fragment as
// encoded (after dispmap_surface_back_side for a back face), `d` its derivatives
// (dispmap_curve_inputs), `P` the ray target's zw as written (after any correction of P).
vec2 dispmap_gbuffer_curve(DispmapSurface s, DispmapCurveInputs d, vec2 P) {
    float det = d.dux.x * d.duy.y - d.duy.x * d.dux.y;
    float len = length(d.normal);
    vec3 V = normalize(s.world_pos - s.camera_pos);
    float vz = -dot(V, s.normal);
    if (!(abs(det) > 0.0) || !(len > 0.0) || !(d.scale > 0.0) || !(vz > 0.0)) {
        return vec2(0.0);
    }
    // A quantity's change per unit t along the ray's foot (uv step P per unit t): its
    // screen differences times w = M^-1 P, M the 2 x 2 matrix of the uv differences.
    vec2 w = vec2(d.duy.y * P.x - d.duy.x * P.y, d.dux.x * P.y - d.dux.y * P.x) / det;
    vec3 n = d.normal / len;
    vec3 dm = d.dnx * w.x + d.dny * w.y;
    // The change of the normalised normal, reversed with it on a back face.
    vec3 dN = (dm - n * dot(n, dm)) / len * (dot(n, s.normal) < 0.0 ? -1.0 : 1.0);
    vec3 lat = (dot(V, s.tangent) * s.tangent + dot(V, s.bitangent) * s.bitangent) / vz;
    float tan2 = dot(lat, lat);
    float kappa = tan2 > 1e-12 ? clamp(dot(lat, dN) / tan2, -4.0, 0.99) : 0.0;
    float g = clamp((d.dsx * w.x + d.dsy * w.y) / d.scale, -1.0e4, 1.0e4);
    vec2 c = vec2(kappa, g);
    return any(isnan(c)) ? vec2(0.0) : c;
}

// Encodes one fragment of material 0 (a pass with one material). Returns false for a back
// face (discard it).
bool dispmap_gbuffer_encode(DispmapSurface s, out vec4 ray, out uvec2 frame) {
    return dispmap_gbuffer_encode_material(s, 0u, ray, frame);
}

// Encodes one fragment of geometry that is not displaced (a character, a pipe): its
// normal and tangent for the host's own shading (handedness +1), material
// DISPMAP_NOT_DISPLACED, no ray. The pass leaves such pixels as the host drew them.
void dispmap_gbuffer_encode_flat(vec3 normal_ws, vec3 tangent_ws, float surface_id, out vec4 ray,
                                 out uvec2 frame) {
    ray = vec4(0.0);
    frame = dispmap_frame_pack(normal_ws, tangent_ws, 1.0, DISPMAP_NOT_DISPLACED, surface_id);
}

#endif
