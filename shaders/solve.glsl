#version 450
// The seeded root finder in float64 as a compute shader, one invocation per
// (ray, start) item given in buffers: solve_core.glsl's solve_into (the
// loop of bsrt/kernels/roots.py's solve_one, the result into buffers 4 and 5). bsrt/rendering/gpu.py's
// find_roots_gpu uploads the items and dispatches it; map_solve.glsl takes
// the starts from the preliminary map's textures instead.

#define ROOT_BUFFERS
#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

layout(std430, binding = 2) readonly buffer Items { double items[]; };        // 8 per item: origin, direction (unit), u0, v0
layout(std430, binding = 3) readonly buffer ItemSurface { int item_surface[]; }; // 1 per item: the start's surface

uniform int item_count;  // in this dispatch (gpu.py dispatches the items in slices, each with its buffers)

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= item_count || gl_LocalInvocationIndex >= uint(GROUP)) return;  // (llvmpipe pads a workgroup to its SIMD width)
    dvec3 o = dvec3(items[8 * i], items[8 * i + 1], items[8 * i + 2]);
    dvec3 d = dvec3(items[8 * i + 3], items[8 * i + 4], items[8 * i + 5]);
    solve_into(i, o, d, item_surface[i], items[8 * i + 6], items[8 * i + 7]);
}
