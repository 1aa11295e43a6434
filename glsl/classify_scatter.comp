#version 460
// classify, step 3 of 4 (src/passes/classify.rs): writes every tile of one material into
// that material's list, at the place glsl/classify_offsets.comp gave the list. One
// invocation per tile (no shared memory, no barrier): it reads the tile's summary
// (glsl/classify.comp) and, for a tile of one material, takes the list's next entry.
// Tiles of several materials are glsl/classify_mixed.comp's. The order of a list's entries
// is the order the invocations ran in; every pass re-checks its pixel's material, so the
// order changes no result.
#include "frame.glsl"
#define DISPMAP_TILES_NO_GBUFFER
#include "tiles.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

// The slot's tile buffer: this step reads the summaries and writes the entries.
layout(set = 0, binding = 0, std430) buffer Tiles {
    uint tiles[];
} u_tiles;
// The slot's arguments: this step advances the cursors.
layout(set = 0, binding = 1, std430) buffer Args {
    uint args[];
} u_args;

CLASSIFY_PARAMS

void main() {
    uvec2 grid = (pc.frame_size + uvec2(LOCAL_SIZE - 1)) / uvec2(LOCAL_SIZE);
    uvec2 tile = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(tile, grid))) {
        return;
    }
    uint m = u_tiles.tiles[TILE_HEADER_WORDS + tile.y * grid.x + tile.x];
    if (m < MAX_MATERIALS) {
        uint i = atomicAdd(u_args.args[ARGS_WORDS * m + ARGS_CURSOR], 1u);
        u_tiles.tiles[i] = tile.x | (tile.y << 16);
    }
}
