// Material classification (src/passes/classify.rs, glsl/classify.comp): which pixels a
// material's passes run on. The G-buffer's frame carries the material
// (glsl/include/dispmap_gbuffer.glsl, read through glsl/common/gbuffer.glsl): material
// index + 1, 0 = not displaced. The including shader declares u_frame (and, for a tile
// pass, u_depth) before including this file. `classify` sorts the frame's 8x8 tiles into one list per
// material; each per-material pass is an indirect dispatch of one workgroup per listed
// tile, and an invocation works only on its pixel if the pixel is of the pass's material.
#ifndef DISPMAP_TILES_GLSL
#define DISPMAP_TILES_GLSL

#include "frame.glsl"
#include "gbuffer.glsl"

// Workgroups per row of an indirect dispatch (maxComputeWorkGroupCount[0] >= 65535): a list
// longer than this is dispatched as rows of MAX_TILE_ROW workgroups (glsl/classify.comp).
#define MAX_TILE_ROW 65535u

// The binding of a per-material pass's tile list (src/passes/classify.rs: TILES_BINDING).
#define TILES_BINDING 15

#ifdef DISPMAP_TILE_PASS
// The tiles of the pass's material: tile (x, y) packed as x | y << 16.
layout(set = 0, binding = TILES_BINDING, std430) readonly buffer Tiles {
    uint tiles[];
} u_tiles;

// The pixel of this invocation in its workgroup's tile; false for a workgroup past the
// list (the last row of a list longer than MAX_TILE_ROW may hold entries of earlier
// frames: an invocation re-checks its pixel's material, so such a tile is at worst
// traced twice with the same result).
bool tile_pixel(out ivec2 pixel) {
    uint index = gl_WorkGroupID.y * MAX_TILE_ROW + gl_WorkGroupID.x;
    if (index >= uint(u_tiles.tiles.length())) {
        pixel = ivec2(-1);
        return false;
    }
    uint t = u_tiles.tiles[index];
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
    return tile_pixel(pixel) && all(lessThan(uvec2(pixel), frame_size))
        && pixel_material(pixel) == material;
}
#endif

#endif
