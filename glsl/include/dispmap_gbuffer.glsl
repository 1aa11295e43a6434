// dispmap's G-buffer contract for a host engine's fragment shader (and dispmap's own
// glsl/gbuffer.frag, so there is one source of truth). Include it, fill a
// DispmapSurface per fragment and write the three colour outputs it returns; the depth
// attachment is the host's own reverse-Z depth. Formats and channels (src/embed/mod.rs,
// src/passes/gbuffer.rs):
//
//   ray     R32G32B32A32_SFLOAT  (uv0.x, uv0.y, P.x, P.y): the entry uv (reduced to [0, 1)
//           for repeat addressing, so rays keep full precision far from the origin) and the
//           parallax vector P = depth_scale * V_ts.xy / max(-V_ts.z, min_cos), in uv units
//           (the uv offset after descending the full displacement depth).
//   normal  R16G16B16A16_SFLOAT  world-space unit normal N (xyz); w = surface id > 0 (a chart
//           with continuous uvs; 0 = cleared, no geometry). DIG trusts a block only when its
//           corners share the id.
//   tangent R16G16B16A16_SFLOAT  world-space unit tangent T along +u (xyz); w = the material
//           and the handedness: w = handedness * (material + 1), where material is the
//           index of a material in the pass's table (DisplacementPass::add_material,
//           MaterialId::index, 0..1023; f16 holds these integers exactly) and
//           B = sign(w) * cross(N, T) is the unit bitangent along +v. w = 0 means *not
//           displaced*: the pass neither traces nor shades the pixel nor writes its
//           corrected depth, and the depth resolve keeps the host's depth there (clear the
//           attachment to 0 so that pixels without geometry read as not displaced too).
//           A G-buffer of one material writes +-1 (material 0), as dispmap_gbuffer_encode
//           does.
//   depth   D32_SFLOAT           reverse-Z, cleared to 0: 0 means no geometry.
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

// The pass's value for a pixel without displacement (tangent.w).
#define DISPMAP_NOT_DISPLACED 0.0

// The same fragment seen from the other side of the surface (a two-sided open mesh, such
// as the inside of a vase): the normal reversed, T and B kept, so the map keeps its uv
// directions and is carved into the surface from the side the eye is on (the handedness
// the encoders write flips with it). A host that draws two-sided geometry calls it for a
// back face before dispmap_gbuffer_encode_material; the pass needs nothing else.
DispmapSurface dispmap_surface_back_side(DispmapSurface s) {
    s.normal = -s.normal;
    return s;
}

// Encodes one fragment of material `material` (its index in the pass's table). Returns
// false for a back face (discard it).
bool dispmap_gbuffer_encode_material(DispmapSurface s, uint material, out vec4 ray, out vec4 normal,
                                     out vec4 tangent) {
    vec3 V = normalize(s.world_pos - s.camera_pos);
    vec3 v_ts = vec3(dot(V, s.tangent), dot(V, s.bitangent), dot(V, s.normal));
    ray = vec4(0.0);
    normal = vec4(0.0);
    tangent = vec4(0.0);
    if (v_ts.z >= 0.0) {
        return false;
    }
    vec2 P = s.depth_scale * v_ts.xy / max(-v_ts.z, s.min_cos);
    vec2 uv0 = s.addressing == DISPMAP_ADDRESSING_REPEAT ? s.uv - floor(s.uv) : s.uv;
    ray = vec4(uv0, P);
    normal = vec4(s.normal, s.surface_id);
    float handedness = dot(cross(s.normal, s.tangent), s.bitangent) < 0.0 ? -1.0 : 1.0;
    tangent = vec4(s.tangent, handedness * (float(material) + 1.0));
    return true;
}

// Encodes one fragment of material 0 (a pass with one material). Returns false for a back
// face (discard it).
bool dispmap_gbuffer_encode(DispmapSurface s, out vec4 ray, out vec4 normal, out vec4 tangent) {
    return dispmap_gbuffer_encode_material(s, 0u, ray, normal, tangent);
}

// Encodes one fragment of geometry that is not displaced (a character, a pipe): its
// normal and tangent for the host's own shading, tangent.w = DISPMAP_NOT_DISPLACED, no
// ray. The pass leaves such pixels as the host drew them.
void dispmap_gbuffer_encode_flat(vec3 normal_ws, vec3 tangent_ws, float surface_id, out vec4 ray,
                                 out vec4 normal, out vec4 tangent) {
    ray = vec4(0.0);
    normal = vec4(normal_ws, surface_id);
    tangent = vec4(tangent_ws, DISPMAP_NOT_DISPLACED);
}

#endif
