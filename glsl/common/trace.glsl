// The trace pass: everything a method shares. A method file defines
//     Hit trace_ray(Ray ray, ivec2 pixel);
// after including this file; `main` below reads the G-buffer, calls it and writes the
// hit images. Bindings and push constants mirror src/passes/trace.rs and src/abi.rs.
// Methods that read more (the pyramid, the DIG corner grid) declare those bindings in
// their own includes (pyramid.glsl, dig.glsl).
#ifndef DISPMAP_TRACE_GLSL
#define DISPMAP_TRACE_GLSL

#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// G-buffer: rgba32f (uv0.x, uv0.y, P.x, P.y); depth (reverse-Z: 0 = no geometry).
layout(set = 0, binding = 0) uniform sampler2D u_ray;
layout(set = 0, binding = 1) uniform sampler2D u_depth;
// The height field (linear filtering, the map's addressing).
layout(set = 0, binding = 2) uniform sampler2D u_height;
// The hit images: the hit's uv and its height (< 0: no hit).
layout(set = 0, binding = 3, rg32f) uniform writeonly image2D u_hit_uv;
#if defined(TRIAGE) || defined(OVERLAP)
// The mesh walk's triage and overlap step read the first trace's hit heights (and write
// the hits they decide).
layout(set = 0, binding = 7, r32f) uniform image2D u_hit_height;
#else
layout(set = 0, binding = 7, r32f) uniform writeonly image2D u_hit_height;
#endif
#ifdef WALK
// The mesh walk's three lists of pixels (src/passes/trace.rs, `walk_list_bytes`): lists
// 0 and 2, appended to by the walked material's first trace (the FIRST variant, over its
// tiles: the pixels its flat trace may not be the walk's; list 2 those whose flat path
// only passes overlapping flat regions) and run by the triage (the TRIAGE variant, an
// indirect dispatch of the list's arguments) and the overlap step (the OVERLAP variant,
// indirect too); list 1, appended to by the first trace (the pixels the triage would list)
// and the triage (the pixels whose trace may differ from the walk) and run by the walk
// (the WALK variant, indirect too). Each list's header: its dispatch's workgroups along x,
// y and z, then its count of pixels. The record resets the headers to (0, 1, 1, 0) before
// the first trace.
layout(set = 0, binding = 13, std430)
#if !defined(TRIAGE) && !defined(FIRST) && !defined(OVERLAP)
readonly
#endif
buffer WalkList {
    uint head[12];  // list 0's header, list 1's, list 2's
    // The first half: list 0 from its start, list 2 from its end (the first trace lists a
    // pixel in one of them at most); the second half: list 1. Each pixel x | y << 16.
    uint pixels[];
} u_walk_list;
#endif
#ifdef ITERATIONS
// The iteration counts (the ITERATIONS variant: the pass's iteration output on).
layout(set = 0, binding = 9, r32ui) uniform writeonly uimage2D u_iterations;
#endif
// G-buffer frame: the material (glsl/common/tiles.glsl) and the surface id (DIG's corner
// test, the footprint's neighbours), read through glsl/common/gbuffer.glsl.
layout(set = 0, binding = 6) uniform usampler2D u_frame;

layout(push_constant) uniform TraceParams {
    uvec2 frame_size;   // pixels
    uvec2 map_size;     // texels
    uint steps;         // linear steps over the full depth (the quality)
    uint refine_steps;  // binary-search steps after the linear march
    uint addressing;    // ADDRESSING_*
    uint flags;         // TRACE_FLAG_*
    uint min_steps;     // pom: n_min
    uint segments;      // secant: segments of the ray
    uvec2 block;        // dig: block size in pixels
    uvec2 corner_size;  // dig: corner-grid size
    float eps;          // dig: eps1 = eps2
    uint max_level;     // pyramid: coarsest traversal level
    uint pyramid_levels;// levels of the bound pyramid (0: none); bit 16: level 0 not stored
    float depth_scale;  // displacement depth in tile units
    float lod_threshold;// TRACE_FLAG_LOD: the mip level from which pixels take bump mapping
    uint material;      // the material this dispatch traces (its tiles: binding 15)
    // TRACE_FLAG_CURVED: the pixel's centre ray, eye-relative (curved.glsl): the point of
    // the near plane at the frame's centre and its steps per NDC unit along x and y; their
    // w: the eye's world position x, y, z (the mesh walk, walk.glsl).
    vec4 view_origin;
    vec4 view_dx;
    vec4 view_dy;
} pc;

#define DISPMAP_TILE_PASS
#include "tiles.glsl"

// The pyramid method picks its coarsest level from the pixel's texel footprint.
#define TRACE_FLAG_AUTO_LEVEL 1u
// Level of detail (Tatarchuk 2006): pixels whose footprint level reaches lod_threshold
// take the bump result without tracing; a one-level band below it blends toward it.
#define TRACE_FLAG_LOD 2u
// Curved macro geometry (curved.glsl): each pixel's curve from the G-buffer's curve image
// and its view ray; methods that honour it trace the curved ray.
#define TRACE_FLAG_CURVED 4u
// Whether this pipeline holds the curved path at all: the CURVED variant of the methods
// that trace curved geometry (exact, relief, pom); every other pipeline, and every
// material not traced as curved, is compiled without it (its registers and code size are
// the flat trace's, and it binds no curve image). TRACE_FLAG_CURVED selects it per
// dispatch within the curved variant (off: no camera this frame).
#ifdef CURVED
const bool CURVED_VARIANT = true;
// The G-buffer's curve image (R16G16_SFLOAT, glsl/include/dispmap_gbuffer.glsl's
// dispmap_gbuffer_curve): the normal curvature along the pixel's ray in units of the
// depth, and the depth's relative change along it.
layout(set = 0, binding = 11) uniform sampler2D u_curve;
#else
const bool CURVED_VARIANT = false;
#endif

#include "march.glsl"
#include "texels.glsl"

#include "search.glsl"
#include "curved.glsl"

// The hit at ray parameter t = 1 - h, its position from t itself (uv0 + t P): through
// h = 1 - t, t would be rounded to an ulp of h, which along a long
// ray (6e-8 |P|: 4 texels of a 1024 map at |P| = 6e4 tiles) is more than a texel. The
// exact family's hits.
Hit hit_at_t(Ray ray, float t, uint iterations) {
    return Hit(fma(vec2(t), ray.P, ray.uv0), 1.0 - t, iterations);
}

// The texels one pixel spans: the larger of the entry point's steps to the right and
// down neighbours (the left / upper one at the frame's last column / row), with the tile
// wraps of uv0 (reduced to [0, 1) for repeat addressing) removed by taking the nearest
// image of the difference. A neighbour without geometry, of another material or on
// another surface (another chart: its uvs are not continuous with this pixel's) gives no
// step; with neither, the
// footprint is 0 (no minification known: full detail). Compute shaders have no implicit
// derivatives, so this is the finite-difference |d uv / d pixel| the hardware would use.
float footprint_texels(ivec2 pixel, vec2 uv0) {
    float texels = 0.0;
    float surface = gbuffer_surface(pixel);
    for (int a = 0; a < 2; ++a) {
        ivec2 q = pixel;
        q[a] += q[a] + 1 < int(pc.frame_size[a]) ? 1 : -1;
        if (q[a] < 0 || pixel_material(q) != pc.material || gbuffer_surface(q) != surface) {
            continue;
        }
        vec2 d = texelFetch(u_ray, q, 0).xy - uv0;
        if (pc.addressing == ADDRESSING_REPEAT) {
            d -= round(d);
        }
        texels = max(texels, length(d * vec2(pc.map_size)));
    }
    return texels;
}

// The pixel's mip level: log2 of its texel footprint, 0 when magnified (<= 1 texel).
// Shared by the pyramid's automatic coarsest level (Oh et al. 3.4: floor of it) and the
// LOD blend to bump mapping (Tatarchuk 2006).
float footprint_level(ivec2 pixel, vec2 uv0) {
    return log2(max(footprint_texels(pixel, uv0), 1.0));
}

// The pixel's footprint level, set by main() before trace_ray when a flag needs it
// (TRACE_FLAG_AUTO_LEVEL or TRACE_FLAG_LOD); 0 otherwise.
float g_footprint_level = 0.0;

// The bump-mapping result (the far-LOD fallback and the `bump` method): the surface point
// below the entry point, one fetch.
Hit bump_hit(Ray ray) {
    if (leaves_domain(ray.uv0)) {
        return miss(ray, 0u);
    }
    return Hit(ray.uv0, height_at(ray.uv0), 1u);
}

Hit trace_ray(Ray ray, ivec2 pixel);
#ifdef WALK
// The mesh walk's dispatches (exact.comp's WALK variants) define them.
#if defined(FIRST)
// What the first trace decides for `pixel` (its flat hit's height `h`): walk_first in
// glsl/common/walk.glsl. Where it is listed: the walk list's number.
const int WALK_FIRST_KEEP = -1;    // its flat hit is the walk's
const int WALK_FIRST_TRIAGE = 0;   // the triage runs on it (walk list 0)
const int WALK_FIRST_WALK = 1;     // the walk runs on it (walk list 1)
const int WALK_FIRST_OVERLAP = 2;  // the overlap step runs on it (walk list 2)
int walk_pixel_first(ivec2 pixel, float h);
#elif defined(TRIAGE)
// What the triage decides for a pixel (walk_triage in glsl/common/walk.glsl).
const int WALK_KEEP = 0;      // the first trace's hit stands
const int WALK_LIST = 1;      // the walk runs on it
const int WALK_OVERLAP = 2;   // an overlapping shell's relief is met first: `hit`
int walk_pixel_triage(ivec2 pixel, Ray ray, out Hit hit);
#elif defined(OVERLAP)
// What the overlap step decides for a pixel the first trace listed for it: the first
// trace's hit stands, `hit` replaces it, or the walk runs on it (list 1).
const int WALK_OVERLAP_KEEP = 0;
const int WALK_OVERLAP_HIT = 1;
const int WALK_OVERLAP_WALK = 2;
int walk_pixel_overlap(ivec2 pixel, Ray ray, out Hit hit);
#else
bool walk_pixel(ivec2 pixel, Ray ray, out Hit hit);
#endif
#endif

// trace_ray with the LOD blend (TRACE_FLAG_LOD; Tatarchuk 2006 section 3.3: bump mapping
// beyond a threshold mip level, and near it "the fractional part of the current mip
// level as the interpolation parameter"). With the pixel's footprint level l and the
// threshold L, w = clamp(l - (L - 1), 0, 1):
//   w = 0 (l <= L - 1): the method's hit, untouched;
//   w = 1 (l >= L): the bump hit (uv0, H(uv0)) without tracing (1 fetch);
//   in between: the traced hit blended toward the bump hit, (u, v, h) = mix(traced,
//   bump, w): the hit point slides along the straight line from the traced point to the
//   surface point under the entry, so the parallax offset fades out continuously and the
//   shading normal, read at the blended uv, with it (the paper lerps the two lit
//   colours; a hit buffer holds points, and shading the lerped point is the same
//   transition for one shade pass). A traced miss (a clamp-addressed ray leaving the
//   decal) stays a miss in the band, keeping the silhouette until bump mapping takes
//   over. Iterations: the trace's plus the bump fetch. Every height_at here (the
//   method's and the bump fetch) samples the mip chain at level l (main).
Hit trace_lod(Ray ray, ivec2 pixel) {
    if ((pc.flags & TRACE_FLAG_LOD) == 0u) {
        return trace_ray(ray, pixel);
    }
    float w = clamp(g_footprint_level - (pc.lod_threshold - 1.0), 0.0, 1.0);
    if (w >= 1.0) {
        return bump_hit(ray);
    }
    Hit traced = trace_ray(ray, pixel);
    if (w <= 0.0 || traced.h < 0.0) {
        return traced;
    }
    Hit bump = bump_hit(ray);
    if (bump.h < 0.0) {
        return traced;
    }
    return Hit(mix(traced.uv, bump.uv, w), mix(traced.h, bump.h, w), traced.iterations + bump.iterations);
}

#ifdef WALK
// The walk's workgroups at most along x: the least maxComputeWorkGroupCount[0] Vulkan
// allows (the triage counts no more; the walk's invocations then take the listed pixels a
// whole dispatch apart). A workgroup is LOCAL_SIZE squared, 64, pixels: 1 << 6.
const uint WALK_MAX_GROUPS = 65535u;
const uint WALK_GROUP_SHIFT = 6u;
#if LOCAL_SIZE != 8
#error "WALK_GROUP_SHIFT assumes 8x8 workgroups"
#endif
#endif

#ifdef WALK
// Pixels each half of the walk lists' array holds: lists 0 and 2 together, list 1.
uint walk_list_capacity() {
    return uint(u_walk_list.pixels.length()) >> 1u;
}

// Where the `i`th pixel of list `list` is in the array (`capacity`: walk_list_capacity).
uint walk_list_slot(uint list, uint i, uint capacity) {
    return list == 2u ? capacity - 1u - i : list * capacity + i;
}

#if defined(TRIAGE) || defined(FIRST) || defined(OVERLAP)
// Appends `pixel` to walk list `list` (0, 1 or 2), counting its dispatch's workgroups
// (at most WALK_MAX_GROUPS).
void walk_list_push(uint list, ivec2 pixel) {
    uint i = atomicAdd(u_walk_list.head[4u * list + 3u], 1u);
    uint capacity = walk_list_capacity();
    if (i < capacity) {
        u_walk_list.pixels[walk_list_slot(list, i, capacity)] = uint(pixel.x) | (uint(pixel.y) << 16);
        if ((i & ((1u << WALK_GROUP_SHIFT) - 1u)) == 0u && (i >> WALK_GROUP_SHIFT) < WALK_MAX_GROUPS) {
            atomicAdd(u_walk_list.head[4u * list], 1u);
        }
    }
}
#endif
#endif

// One pixel of the material: its hit into the hit images (the walk's first trace: and
// whether to list it; the triage: its decision).
void trace_pixel(ivec2 pixel) {
    vec4 g = texelFetch(u_ray, pixel, 0);
    if ((pc.flags & (TRACE_FLAG_AUTO_LEVEL | TRACE_FLAG_LOD)) != 0u) {
        g_footprint_level = footprint_level(pixel, g.xy);
    }
    if ((pc.flags & TRACE_FLAG_LOD) != 0u) {
        // The marchers' height_at (and the bump fallback) sample the prefiltered map at
        // the footprint level; the exact texel reads (texel_height: pyramid, exact, the
        // DIG guard) stay on level 0.
        g_height_lod = g_footprint_level;
    }
#ifndef WALK
    if (CURVED_VARIANT && (pc.flags & TRACE_FLAG_CURVED) != 0u) {
        g_curve = curve_of(pixel, Ray(g.xy, g.zw));
    }
#endif
#if defined(WALK) && defined(FIRST)
    // The walked material's first trace (exact.comp's WALK+FIRST variant): the flat trace,
    // and the pixels it may not be the walk's listed for the triage.
    Hit hit = trace_lod(Ray(g.xy, g.zw), pixel);
    imageStore(u_hit_uv, pixel, vec4(hit.uv, 0.0, 0.0));
    imageStore(u_hit_height, pixel, vec4(hit.h));
#ifdef ITERATIONS
    imageStore(u_iterations, pixel, uvec4(hit.iterations));
#endif
    if ((pc.flags & TRACE_FLAG_CURVED) != 0u) {
        // One append for the three lists (each call site of an atomic costs a CPU
        // driver's every group of lanes).
        int list = walk_pixel_first(pixel, hit.h);
        if (list != WALK_FIRST_KEEP) {
            walk_list_push(uint(list), pixel);
        }
    }
#elif defined(WALK) && defined(TRIAGE)
    // The mesh walk's triage (exact.comp's WALK+TRIAGE variant): lists the pixels whose
    // walk can differ from the first trace, and counts the walk's workgroups (at most
    // WALK_MAX_GROUPS). (A level-of-detail blend records the curved trace instead, no
    // triage.)
    Hit hit;
    int decision = (pc.flags & TRACE_FLAG_LOD) == 0u ? walk_pixel_triage(pixel, Ray(g.xy, g.zw), hit) : WALK_KEEP;
    if (decision == WALK_OVERLAP) {
        imageStore(u_hit_uv, pixel, vec4(hit.uv, 0.0, 0.0));
        imageStore(u_hit_height, pixel, vec4(hit.h));
    } else if (decision == WALK_LIST) {
        walk_list_push(1u, pixel);
    }
#elif defined(WALK) && defined(OVERLAP)
    // The mesh walk's overlap step (exact.comp's WALK+OVERLAP variant): the hits in the
    // overlapping regions' relief it finds replace the first trace's (whose iteration
    // counts they keep, as the triage's do); a pixel it leaves to the walk is listed.
    Hit hit;
    int decision = walk_pixel_overlap(pixel, Ray(g.xy, g.zw), hit);
    if (decision == WALK_OVERLAP_HIT) {
        imageStore(u_hit_uv, pixel, vec4(hit.uv, 0.0, 0.0));
        imageStore(u_hit_height, pixel, vec4(hit.h));
    } else if (decision == WALK_OVERLAP_WALK) {
        walk_list_push(1u, pixel);
    }
#else
#ifdef WALK
    // The mesh walk's dispatch (exact.comp's WALK variant) over the listed pixels; a
    // pixel on no walked triangle (or whose ray does not go into its shell) takes the
    // curved trace's circle model.
    Hit hit;
    if (!walk_pixel(pixel, Ray(g.xy, g.zw), hit)) {
        g_curve = curve_of(pixel, Ray(g.xy, g.zw));
        hit = trace_ray(Ray(g.xy, g.zw), pixel);
    }
#else
    Hit hit = trace_lod(Ray(g.xy, g.zw), pixel);
#endif
    imageStore(u_hit_uv, pixel, vec4(hit.uv, 0.0, 0.0));
    imageStore(u_hit_height, pixel, vec4(hit.h));
#ifdef ITERATIONS
    imageStore(u_iterations, pixel, uvec4(hit.iterations));
#endif
#endif
}

// One workgroup per tile of the material's list (the walk: per 64 listed pixels); pixels
// of other materials, flat ones and those without geometry are left alone (`classify`
// wrote the hits of the last two).
void main() {
#if defined(WALK) && !defined(FIRST)
    // The triage, the overlap step and the walk: the pixels of their list (0 and 2: the
    // first trace's, 1: the triage's), an invocation each (an indirect dispatch of the
    // list's own arguments).
#if defined(TRIAGE)
    const uint list = 0u;
#elif defined(OVERLAP)
    const uint list = 2u;
#else
    const uint list = 1u;
#endif
    uint capacity = walk_list_capacity();
    uint count = min(u_walk_list.head[4u * list + 3u], capacity);
    uint stride = gl_NumWorkGroups.x << WALK_GROUP_SHIFT;
    for (uint index = (gl_WorkGroupID.x << WALK_GROUP_SHIFT) + gl_LocalInvocationIndex;
         index < count; index += stride) {
        uint packed = u_walk_list.pixels[walk_list_slot(list, index, capacity)];
        trace_pixel(ivec2(packed & 0xFFFFu, packed >> 16));
    }
#else
    ivec2 pixel;
    if (!material_pixel(pc.material, pc.frame_size, pixel)) {
        return;
    }
    trace_pixel(pixel);
#endif
}

#endif
