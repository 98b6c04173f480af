#version 450
// The mirror bounce of one level of shade.glsl's hits, one invocation per hit:
// the port of bsrt/rendering/pipeline.py's bounce (kernels/shading.py's
// mirror_rays, then the mirror ray traced as bvh.intersect traces it: its
// direction normalised as rendering/solve.py's Rays normalises it, from the
// hit's position, t from 0, its root excluded, by nearest_walk.glsl's walk).
// It runs over the level's slots whose hit is on a surface whose material
// reflects (reflectance > 0; gpu_lighting.py lists them) and writes the next
// level's hit (what the mirror ray sees, shaded by shade.glsl in the next
// level's buffers, its view direction the unnormalised mirror direction, as
// the pipeline shades it) and whether that hit reflects in turn.
// bsrt/rendering/gpu_lighting.py's shade_hits_gpu dispatches it between levels.

#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"
#include "anyhit.glsl"

uniform int hit_count;  // slots in each block of the buffers
uniform double shadow_tol;  // the mirror rays' solve: the shadow rays' settings (set_shadow_uniforms)
uniform int shadow_iterations;
uniform double cull_tol;
uniform int budget;
uniform int off_reflectance, off_patch_surface;

#include "nearest_walk.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

layout(std430, binding = 2) readonly buffer HitReals { double hit_reals[]; };  // this level's (shade.glsl's)
layout(std430, binding = 3) readonly buffer HitInts { int hit_ints[]; };
layout(std430, binding = 4) readonly buffer LookReals { double look_reals[]; };  // reflectance (S,)
layout(std430, binding = 5) readonly buffer LookInts { int look_ints[]; };  // patch_surface (P,)
layout(std430, binding = 8) readonly buffer OutReals { double out_reals[]; };  // this level's frames (shade.glsl)
layout(std430, binding = 10) writeonly buffer NextReals { double next_reals[]; };  // the next level's hits
layout(std430, binding = 11) writeonly buffer NextInts { int next_ints[]; };
// 4 blocks of hit_count: bounced (1: a mirror ray left this slot), the mirror ray spent its budget (1),
// not settled (1: llvmpipe's loop limiter; the slot is shaded again on the CPU), the hit it found reflects (1)
layout(std430, binding = 12) writeonly buffer BounceInts { int bounce_ints[]; };
// (written for the listed slots only: gpu_lighting.py reads back the listed slots' blocks and lists the
// next level's slots from them)
#include "slots.glsl"

void main() {
    int i = dispatch_slot();
    if (i < 0) return;
    int surface = hit_ints[3 * i + 2];
    bool mirror = hit_ints[3 * i] == 1 && look_reals[off_reflectance + surface] > 0.0LF;
    int answer = 0, k = -1, iterations = 0;
    dvec4 best = dvec4(0.0LF);
    dvec3 m = dvec3(0.0LF);
    if (mirror) {
        int n3 = 3 * hit_count;  // shade.glsl's out_reals: position at n3 + 3 i, normal at 2 n3 + 3 i, radius at 3 n3 + 2 i
        dvec3 d = dvec3(hit_reals[5 * i + 2], hit_reals[5 * i + 3], hit_reals[5 * i + 4]);
        dvec3 p = dvec3(out_reals[n3 + 3 * i], out_reals[n3 + 3 * i + 1], out_reals[n3 + 3 * i + 2]);
        dvec3 n = dvec3(out_reals[2 * n3 + 3 * i], out_reals[2 * n3 + 3 * i + 1], out_reals[2 * n3 + 3 * i + 2]);
        double s = 2.0LF * (d.x * n.x + d.y * n.y + d.z * n.z);
        m = dvec3(d.x - s * n.x, d.y - s * n.y, d.z - s * n.z);
        double len = sqrt(m.x * m.x + m.y * m.y + m.z * m.z);
        dvec3 unit = dvec3(m.x / len, m.y / len, m.z / len);
        dvec4 ex = dvec4(hit_reals[5 * i], hit_reals[5 * i + 1], out_reals[3 * n3 + 2 * i], out_reals[3 * n3 + 2 * i + 1]);
        double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
        answer = nearest(p, unit, 0.0LF, INF, surface, ex, best, k, iterations);
    }
    next_reals[5 * i] = best.x;
    next_reals[5 * i + 1] = best.y;
    next_reals[5 * i + 2] = m.x;
    next_reals[5 * i + 3] = m.y;
    next_reals[5 * i + 4] = m.z;
    next_ints[3 * i] = !mirror ? -1 : (answer == 1 ? 1 : 0);
    next_ints[3 * i + 1] = answer == 1 ? k : -1;
    next_ints[3 * i + 2] = answer == 1 ? look_ints[off_patch_surface + k] : -1;
    bounce_ints[i] = mirror ? 1 : 0;
    bounce_ints[hit_count + i] = iterations >= budget ? 1 : 0;
    bounce_ints[2 * hit_count + i] = answer == -3 ? 1 : 0;
    bounce_ints[3 * hit_count + i] = answer == 1 && look_reals[off_reflectance + look_ints[off_patch_surface + k]] > 0.0LF ? 1 : 0;
}
