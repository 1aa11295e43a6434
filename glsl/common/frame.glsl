// Shared conventions of every dispmap shader (see docs/design.md and src/abi.rs).
#ifndef DISPMAP_FRAME_GLSL
#define DISPMAP_FRAME_GLSL

// Workgroup size of every compute pass (src/gpu/pipeline.rs: LOCAL_SIZE).
#define LOCAL_SIZE 8

// Addressing modes (src/abi.rs: ADDRESSING_*).
#define ADDRESSING_REPEAT 0u
#define ADDRESSING_CLAMP 1u

// The hit buffer: rgba32f = (hit u, hit v, hit height, iteration count).
// Hit uv is in the frame of the G-buffer's uv0 (tile-local for repeat addressing).
// Height < 0 means no hit: no geometry, or a clamp-addressed ray that left [0,1]^2.
#define NO_HIT_HEIGHT (-1.0)

#endif
