// The slots a dispatch of the mirror chain runs over, for its shaders to include
// (shade.glsl, bounce.glsl, mix.glsl; no #version here). Invocation g takes slot
// slots[g] of a list the host wrote (bsrt/rendering/gpu_lighting.py; use_slots:
// below the first level the slots a mirror ray reached, for bounce.glsl those
// whose hit reflects, for mix.glsl those that sent one), else slot g.

layout(std430, binding = 13) readonly buffer Slots { int slots[]; };
uniform int use_slots;
uniform int item_count;  // invocations in this dispatch

// This invocation's slot, or -1 past the dispatch's items (and in the lanes llvmpipe pads a
// workgroup with to its SIMD width).
int dispatch_slot() {
    int g = int(gl_GlobalInvocationID.x);
    if (g >= item_count || gl_LocalInvocationIndex >= uint(GROUP)) return -1;
    return use_slots != 0 ? slots[g] : g;
}
