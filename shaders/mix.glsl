#version 450
// A level of the mirror chain mixed with the next, one invocation per slot: the
// port of kernels/shading.py's mix_reflections (colour = (1 - r) colour + r
// reflected, r the surface's reflectance) where bounce.glsl sent a mirror ray
// from the slot, and the next level's counts (shadow rays, rays out of budget,
// not settled, mirror rays) added to this level's, with the bounce's own.
// bsrt/rendering/gpu_lighting.py's shade_hits_gpu dispatches it once per level,
// the deepest first, so the first level ends with each hit's whole colour.

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

uniform int hit_count;  // slots in each block of the buffers
uniform int off_reflectance;

layout(std430, binding = 3) readonly buffer HitInts { int hit_ints[]; };  // this level's hits: surface at 3 i + 2
layout(std430, binding = 4) readonly buffer LookReals { double look_reals[]; };  // reflectance (S,)
layout(std430, binding = 8) buffer OutReals { double out_reals[]; };  // this level's colour: 3 i
layout(std430, binding = 9) buffer OutInts { int out_ints[]; };  // 4 blocks of hit_count (shade.glsl's)
layout(std430, binding = 10) readonly buffer NextReals { double next_reals[]; };  // the next level's out_reals
layout(std430, binding = 11) readonly buffer NextInts { int next_ints[]; };  // the next level's out_ints
layout(std430, binding = 12) readonly buffer BounceInts { int bounce_ints[]; };  // bounce.glsl's
#include "slots.glsl"

void main() {
    int i = dispatch_slot();
    if (i < 0) return;
    if (bounce_ints[i] == 0) return;
    double r = look_reals[off_reflectance + hit_ints[3 * i + 2]];
    out_reals[3 * i] = (1.0LF - r) * out_reals[3 * i] + r * next_reals[3 * i];
    out_reals[3 * i + 1] = (1.0LF - r) * out_reals[3 * i + 1] + r * next_reals[3 * i + 1];
    out_reals[3 * i + 2] = (1.0LF - r) * out_reals[3 * i + 2] + r * next_reals[3 * i + 2];
    int n = hit_count;
    out_ints[i] += next_ints[i];
    out_ints[n + i] += next_ints[n + i] + bounce_ints[n + i];
    out_ints[2 * n + i] += next_ints[2 * n + i] + bounce_ints[2 * n + i];
    out_ints[3 * n + i] += next_ints[3 * n + i] + 1;
}
