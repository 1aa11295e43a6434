#version 460
// dig_corners: the Depth Interval Grid (Judnich & Ling, section 4). One invocation per
// block corner: corner (i, j) is the top-left pixel of block (i, j), i.e. pixel
// (i bx, j by), clamped to the frame for the last row/column of corners. Its ray is
// marched with `steps` fixed steps in height (the paper's "simple linear search with a
// fixed step size") and the normalised ray height of the last sample above the surface
// is stored: the hit lies in [h_stored - 1/steps, h_stored], hence eps1 >= 1/steps.
//
// Output (rgba32f per corner):
//   x: that ray height (1 when the entry point is already on the surface);
//   y: the surface id of the corner pixel (the G-buffer frame's; 0 = no geometry, a pixel of
//      another material, or a clamp-addressed ray that leaves the decal: a silhouette,
//      not a surface point);
//   z: the height fetches spent (the corner pass's share of the iteration count);
//   w: 0.
// Block corners stored as floats, not 8 bits as in the paper: the interval ends are
// then exactly the corner heights and no quantisation step needs to be added to eps.
#include "frame.glsl"

layout(local_size_x = LOCAL_SIZE, local_size_y = LOCAL_SIZE) in;

layout(set = 0, binding = 0) uniform sampler2D u_ray;
layout(set = 0, binding = 1) uniform sampler2D u_depth;
layout(set = 0, binding = 2) uniform usampler2D u_frame;
layout(set = 0, binding = 3) uniform sampler2D u_height;
layout(set = 0, binding = 4, rgba32f) uniform writeonly image2D u_corners;

layout(push_constant) uniform CornerParams {
    uvec2 frame_size;
    uvec2 corner_size;
    uvec2 block;
    uint steps;
    uint addressing;
    uint material;      // the material whose grid this is
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

#include "tiles.glsl"

#include "march.glsl"

void main() {
    ivec2 corner = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(uvec2(corner), pc.corner_size))) {
        return;
    }
    ivec2 pixel = min(corner * ivec2(pc.block), ivec2(pc.frame_size) - 1);
    // No geometry or another material: not a point of this material's surface (a block
    // with such a corner falls back, as at a surface boundary).
    if (texelFetch(u_depth, pixel, 0).r <= 0.0 || gbuffer_material(pixel) != pc.material) {
        imageStore(u_corners, corner, vec4(1.0, 0.0, 0.0, 0.0));
        return;
    }
    vec4 g = texelFetch(u_ray, pixel, 0);
    float surface = gbuffer_surface(pixel);
    uint steps = max(pc.steps, 1u);
    uint iterations = 0u;
    uint below;
    if (!linear_march(Ray(g.xy, g.zw), steps, below, iterations)) {
        imageStore(u_corners, corner, vec4(1.0, 0.0, float(iterations), 0.0));
        return;
    }
    float h = below == 0u ? 1.0 : 1.0 - float(below - 1u) / float(steps);
    imageStore(u_corners, corner, vec4(h, surface, float(iterations), 0.0));
}
