// Shared conventions of every dispmap shader (see docs/design.md and src/abi.rs).
#ifndef DISPMAP_FRAME_GLSL
#define DISPMAP_FRAME_GLSL

// Workgroup size of every compute pass (src/gpu/pipeline.rs: LOCAL_SIZE).
#define LOCAL_SIZE 8

// Addressing modes (src/abi.rs: ADDRESSING_*).
#define ADDRESSING_REPEAT 0u
#define ADDRESSING_CLAMP 1u

// Steps a hierarchical traversal (pyramid, exact, dig-guarded, hard shadows of those) may
// take per invocation: lavapipe ends an invocation after 65,535 loop iterations of all
// its loops together, silently (src/method.rs: LOOP_LIMIT); a traversal that reaches
// this cap stops with no hit instead. The cap counts the traversal's steps; what else
// loops per step is small (the two-axis loops unroll; the leaf root's bisection runs
// only when rounding defeats the closed form). Real traversals take tens to a few
// thousand steps (the benchmark's p99 and maxima).
#define TRAVERSAL_CAP 16384.0

// The hit buffer: rgba32f = (hit u, hit v, hit height, iteration count).
// Hit uv is in the frame of the G-buffer's uv0 (tile-local for repeat addressing).
// Height < 0 means no hit: no geometry, or a clamp-addressed ray that left [0,1]^2.
#define NO_HIT_HEIGHT (-1.0)
// The hit height of a pixel of flat geometry (G-buffer frame's material 0: not displaced), set
// by the classification pass (glsl/classify.comp); never traced or shaded.
#define NOT_DISPLACED_HEIGHT (-2.0)

#endif
