#version 450
// Any-hit shadow rays given in a buffer, one invocation per ray: anyhit.glsl's
// occluded (the port of bsrt/kernels/lighting.py's). bsrt/rendering/gpu_shade.py's
// occluded_gpu uploads the rays and dispatches it; the tests hold its answers
// to the CPU's walk.

#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"
#include "anyhit.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

// 12 per ray: origin (3), unit direction (3), t_max, the start root's surface (-1: none), u, v,
// radius u, radius v (the exclusion box of traverse.Exclusion)
layout(std430, binding = 2) readonly buffer ShadowRays { double shadow_rays[]; };
layout(std430, binding = 3) writeonly buffer Blocked { int blocked[]; };  // 2 per ray: occluded's answer (-3: to the CPU), iterations

uniform int ray_count;  // in this dispatch
uniform double shadow_tol;
uniform int shadow_iterations;
uniform double cull_tol;
uniform int budget;

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= ray_count || gl_LocalInvocationIndex >= uint(GROUP)) return;  // (llvmpipe pads a workgroup to its SIMD width)
    int at = 12 * i;
    dvec3 o = dvec3(shadow_rays[at], shadow_rays[at + 1], shadow_rays[at + 2]);
    dvec3 d = dvec3(shadow_rays[at + 3], shadow_rays[at + 4], shadow_rays[at + 5]);
    dvec4 ex = dvec4(shadow_rays[at + 8], shadow_rays[at + 9], shadow_rays[at + 10], shadow_rays[at + 11]);
    int iterations;
    blocked[2 * i] = occluded(o, d, shadow_rays[at + 6], shadow_tol, shadow_iterations, cull_tol, budget,
                              int(shadow_rays[at + 7]), ex, iterations);
    blocked[2 * i + 1] = iterations;
}
