#version 450
// Nearest-hit rays (mirror rays) given in a buffer, one invocation per ray,
// through nearest_walk.glsl's walk. bsrt/rendering/gpu_shade.py's nearest_gpu
// uploads the rays and dispatches it; the tests hold its hits to the CPU's
// (bvh.intersect).

#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"
#include "anyhit.glsl"

uniform int ray_count;  // in this dispatch
uniform double shadow_tol;  // the solve's (set_shadow_uniforms: the same settings as the shadow rays')
uniform int shadow_iterations;
uniform double cull_tol;
uniform int budget;

#include "nearest_walk.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

// 13 per ray: origin (3), unit direction (3), t_min, t_max, the start root's surface (-1: none), u, v,
// radius u, radius v (the exclusion box of traverse.Exclusion)
layout(std430, binding = 2) readonly buffer Rays { double rays[]; };
layout(std430, binding = 3) writeonly buffer OutReals { double out_reals[]; };  // 4 per ray: u, v, t, residual
layout(std430, binding = 4) writeonly buffer OutInts { int out_ints[]; };  // 3 per ray: hit (1, 0, -3), patch, iterations

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= ray_count || gl_LocalInvocationIndex >= uint(GROUP)) return;  // (llvmpipe pads a workgroup to its SIMD width)
    int at = 13 * i;
    dvec3 o = dvec3(rays[at], rays[at + 1], rays[at + 2]);
    dvec3 d = dvec3(rays[at + 3], rays[at + 4], rays[at + 5]);
    dvec4 ex = dvec4(rays[at + 9], rays[at + 10], rays[at + 11], rays[at + 12]);
    dvec4 best;
    int k, iterations;
    int answer = nearest(o, d, rays[at + 6], rays[at + 7], int(rays[at + 8]), ex, best, k, iterations);
    out_reals[4 * i] = best.x;
    out_reals[4 * i + 1] = best.y;
    out_reals[4 * i + 2] = best.z;
    out_reals[4 * i + 3] = best.w;
    out_ints[3 * i] = answer;
    out_ints[3 * i + 1] = k;
    out_ints[3 * i + 2] = iterations;
}
