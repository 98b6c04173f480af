#version 330 core
// The trim test (trim.glsl) at given points, for tests and diagnostics
// (bsrt.trim_gl.kept_gl): point i lands on texel (i % width, i / width) of
// a float target, and its fragment writes 1 where (u, v) is kept, 0 where not.

#if defined VERTEX_SHADER

uniform ivec2 target_size;   // (width, height) of the target
in vec2 param;               // (u, v)
in float surface;            // index into the trim table

flat out vec2 probe_param;
flat out int probe_surface;

void main() {
    vec2 texel = vec2(float(gl_VertexID % target_size.x), float(gl_VertexID / target_size.x)) + 0.5;
    probe_param = param;
    probe_surface = int(surface + 0.5);
    gl_Position = vec4(2.0 * texel / vec2(target_size) - 1.0, 0.0, 1.0);
}

#elif defined FRAGMENT_SHADER

#include "trim.glsl"

flat in vec2 probe_param;
flat in int probe_surface;

out float kept;

void main() {
    kept = trim_kept(probe_surface, probe_param.x, probe_param.y) ? 1.0 : 0.0;
}

#endif
