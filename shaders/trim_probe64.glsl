#version 450
// trim64.glsl's answer for given (surface, u, v) points, one invocation
// each: bsrt/rendering/gpu.py's kept_gpu, with which the tests hold the
// float64 trim test of the GPU solve to kernels/trim.py's point_kept.

#include "patches.glsl"
#include "trim64.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

layout(std430, binding = 2) readonly buffer Points { double points[]; };  // 3 per point: surface, u, v
layout(std430, binding = 3) writeonly buffer Kept { int kept[]; };        // 1 per point: 1 kept, 0 removed

uniform int point_count;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= point_count || gl_LocalInvocationIndex >= uint(GROUP)) return;  // (llvmpipe pads a workgroup to its SIMD width)
    kept[i] = trim_kept(int(points[3 * i]), points[3 * i + 1], points[3 * i + 2]) ? 1 : 0;
}
