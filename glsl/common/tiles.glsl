// Material classification (src/passes/classify.rs, glsl/classify*.comp): which pixels a
// material's passes run on. The G-buffer's frame carries the material
// (glsl/include/dispmap_gbuffer.glsl, read through glsl/common/gbuffer.glsl): material
// index + 1, 0 = not displaced. The including shader declares u_frame (and, for a tile
// pass, u_depth) before including this file. `classify` sorts the frame's 8x8 tiles into
// one list per material, all lists in one buffer per frame slot whose size follows the
// frame only; each per-material pass is an indirect dispatch of one workgroup per listed
// tile, and an invocation works only on its pixel if the pixel is of the pass's material.
#ifndef DISPMAP_TILES_GLSL
#define DISPMAP_TILES_GLSL

#include "frame.glsl"
#ifdef DISPMAP_TILES_NO_GBUFFER
// A classify step that reads no G-buffer (classify_offsets, classify_scatter) declares no
// u_frame, so it gets the table's limit alone (glsl/common/gbuffer.glsl: MAX_MATERIALS).
#define MAX_MATERIALS 1024u
#else
#include "gbuffer.glsl"
#endif

// Workgroups per row of an indirect dispatch (maxComputeWorkGroupCount[0] >= 65535): a list
// longer than this is dispatched as rows of MAX_TILE_ROW workgroups (glsl/classify.comp).
#define MAX_TILE_ROW 65535u

// The binding of a per-material pass's tile lists (src/passes/classify.rs: TILES).
#define TILES_BINDING 15

// The tile buffer of a frame slot (src/passes/classify.rs: TileLists), in words, with
// `tiles` the frame's 8x8 tiles:
// [0, TILE_HEADER_WORDS): per material m, word 2m = the index of its list's first entry,
//   2m + 1 = its length (written by classify_offsets for every table entry);
// [TILE_HEADER_WORDS, + tiles): per tile (row-major) what classify found in it:
//   TILE_EMPTY, TILE_MIXED or its one material;
// [TILE_HEADER_WORDS + tiles, + tiles): the tiles of several materials (packed as below),
//   the list classify_mixed runs over;
// then the entries: each material's list, one after the other (tile (x, y) packed as
//   x | y << 16); at most tiles * LOCAL_SIZE^2 of them, as a tile holds at most
//   LOCAL_SIZE^2 distinct materials.
#define TILE_HEADER_WORDS (2u * MAX_MATERIALS)
#define TILE_EMPTY 0xFFFFFFFFu
#define TILE_MIXED 0xFFFFFFFEu

// The argument buffer of a frame slot, ARGS_WORDS words per table entry: a
// VkDispatchIndirectCommand (x, y, z: (0, 0, 1) before classify), a live flag (1: the entry
// holds a material), the number of tiles holding the material, and the scatter's cursor.
// Entry MAX_MATERIALS (ARGS_MIXED) is the list of tiles of several materials: its dispatch
// and its length.
#define ARGS_WORDS 8u
#define ARGS_LIVE 3u
#define ARGS_COUNT 4u
#define ARGS_CURSOR 5u
#define ARGS_MIXED (ARGS_WORDS * MAX_MATERIALS)

// The push constants of every classify step (src/abi.rs: ClassifyParams).
#define CLASSIFY_PARAMS \
    layout(push_constant) uniform ClassifyParams { \
        uvec2 frame_size;    /* pixels */ \
        uint material_count; /* table entries (live or vacant) */ \
        uint entries_base;   /* the tile buffer's first entry word */ \
        uint flags;          /* CLASSIFY_FLAG_* (the count step) */ \
        uint tile_count;     /* the frame's 8x8 tiles */ \
        uint pad0; \
        uint pad1; \
    } pc;

#ifdef DISPMAP_TILE_PASS
// The slot's tile buffer (layout above).
layout(set = 0, binding = TILES_BINDING, std430) readonly buffer Tiles {
    uint tiles[];
} u_tiles;

// The pixel of this invocation in its workgroup's tile of `material`'s list; false for a
// workgroup past the list (the last row of a list longer than MAX_TILE_ROW).
bool tile_pixel(uint material, out ivec2 pixel) {
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    if (index >= u_tiles.tiles[2u * material + 1u]) {
        pixel = ivec2(-1);
        return false;
    }
    uint t = u_tiles.tiles[u_tiles.tiles[2u * material] + index];
    pixel = ivec2(t & 0xFFFFu, t >> 16) * LOCAL_SIZE + ivec2(gl_LocalInvocationID.xy);
    return true;
}

// The pixel's material: geometry (depth > 0) whose frame names one.
uint pixel_material(ivec2 pixel) {
    if (texelFetch(u_depth, pixel, 0).r <= 0.0) {
        return NOT_DISPLACED;
    }
    return gbuffer_material(pixel);
}

// The pixel of this invocation when it is inside the frame and of `material`; false
// otherwise (the invocation does nothing).
bool material_pixel(uint material, uvec2 frame_size, out ivec2 pixel) {
    return tile_pixel(material, pixel) && all(lessThan(uvec2(pixel), frame_size))
        && pixel_material(pixel) == material;
}
#endif

#endif
