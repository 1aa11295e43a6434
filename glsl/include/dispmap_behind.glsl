// dispmap_behind.glsl: the "behind" layer's rule, shared by dispmap's own G-buffer shaders
// and a host engine's (docs/embedding.md, "What a miss shows").
//
// A displaced ray that leaves its surface without meeting it (a clamp-addressed ray that
// leaves the decal, a curved ray that leaves the relief's shell) is a miss: hit height
// -1 in the hit height image. What the pixel should show is the next surface along its view ray,
// which a one-layer G-buffer does not hold. The behind layer is a second G-buffer pass,
// drawn after the first frame's trace, whose fragment shader keeps a fragment only where
// `dispmap_behind_keep` says so: at a pixel whose first-layer trace missed, behind the
// first layer's surface. The displacement pass is then recorded on that layer (its own
// frame slot, its own hit images, the same colour image) and traces and shades only the
// pixels the layer covers.
#ifndef DISPMAP_INCLUDE_BEHIND_GLSL
#define DISPMAP_INCLUDE_BEHIND_GLSL

// The hit height image's miss (NO_HIT_HEIGHT in src/abi.rs): a displaced ray that met nothing.
#define DISPMAP_MISS_HEIGHT (-1.0)
// A fragment nearer than this fraction of the first layer's reverse-Z depth behind it is
// the first layer's own surface drawn again (same triangle, same depth up to rounding).
#define DISPMAP_BEHIND_MARGIN 1e-5

// Whether the behind layer may cover a pixel: its first-layer trace missed
// (`first_hit_height`, the hit buffer's z) on geometry (`first_depth`, the first layer's
// G-buffer depth, reverse-Z, 0 = no geometry). A host may write this into a stencil or
// depth mask before drawing the layer's objects (docs/embedding.md, "What a miss shows").
bool dispmap_behind_missed(float first_hit_height, float first_depth) {
    return first_hit_height == DISPMAP_MISS_HEIGHT && first_depth > 0.0;
}

// Whether a fragment of the behind layer is kept: `first_hit_height` is the first layer's
// hit height at the pixel (the hit height image's value), `first_depth` its G-buffer depth
// (reverse-Z, 0 = no geometry), `depth` the fragment's own depth (reverse-Z: smaller is
// farther).
bool dispmap_behind_keep(float first_hit_height, float first_depth, float depth) {
    return dispmap_behind_missed(first_hit_height, first_depth)
        && depth < first_depth * (1.0 - DISPMAP_BEHIND_MARGIN);
}

// (A compute shader, which has no derivatives, defines DISPMAP_BEHIND_NO_DERIVATIVES
// before including this file to leave the next function out.)
#ifndef DISPMAP_BEHIND_NO_DERIVATIVES
// Whether a fragment's triangle faces the eye: its own plane (from the screen derivatives
// of `eye_rel`, the fragment's position relative to the eye), oriented by `normal`, its
// interpolated normal. Call it in uniform control flow (before any discard). The layer
// draws a one-sided mesh's fragment only where this holds: near an outline the mesh's far
// side, whose interpolated normals still face the eye, lies behind the missed pixels, but
// it is where a missed ray leaves a convex shell, not a surface it meets (the first layer
// keeps such fragments hidden behind the near side; the layer must not draw them).
bool dispmap_behind_faces_eye(vec3 eye_rel, vec3 normal) {
    vec3 face = cross(dFdx(eye_rel), dFdy(eye_rel));
    face = dot(face, normal) < 0.0 ? -face : face;
    return dot(face, eye_rel) <= 0.0;
}
#endif

#endif
