#version 450
// The seeded solve started from the preliminary map where it lies: one
// invocation per pixel of one tile of the map (shaders/prelim.glsl's two
// passes, triangles and lines, still in their framebuffers' textures). Each
// merges the passes and decodes the seed as bsrt/kernels/prelim.py's
// decode_tile does, then runs solve_core.glsl's solve_into from it along
// the pixel's camera ray (the result into buffers 4 and 5). bsrt/rendering/gpu_map.py draws the tiles and
// dispatches this, then reads back, once per band, the merged map and the
// roots together (the CPU needs the map for the suspect-pixel rules).

#define ROOT_BUFFERS
#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

// The tile: (w, h) texels, OpenGL's row 0 at the bottom; colour r = surface
// index + 1 (0: empty), g, b = (u, v) normalised over the surface's domain.
layout(binding = 0) uniform sampler2D tri_color;
layout(binding = 1) uniform sampler2D tri_distance;
layout(binding = 2) uniform sampler2D line_color;
layout(binding = 3) uniform sampler2D line_distance;

layout(std430, binding = 2) readonly buffer Directions { double directions[]; };  // 3 per pixel of the band: unit
layout(std430, binding = 3) writeonly buffer OutMap { vec4 out_map[]; };           // 1 per pixel: merged r, g, b, distance

uniform dvec3 eye;        // every camera ray's origin
uniform int float_map;    // 1: 32-bit float channels, 0: the 8-bit map (eq. 6)
uniform int band_width;   // pixels per row of the band (the film's width)
uniform int row0;         // the band row of the tile's top row
uniform int col0;         // the band column of the tile's left column
uniform int first_texel;  // this dispatch's first texel of the tile (row-major from the bottom row)
uniform int texel_count;  // texels in this dispatch

void main() {
    int n = int(gl_GlobalInvocationID.x);
    if (n >= texel_count || gl_LocalInvocationIndex >= uint(GROUP)) return;  // (llvmpipe pads a workgroup to its SIMD width)
    ivec2 size = textureSize(tri_color, 0);
    int texel = first_texel + n;
    ivec2 at = ivec2(texel % size.x, texel / size.x);
    int p = (row0 + size.y - 1 - at.y) * band_width + col0 + at.x;
    vec4 tri = texelFetch(tri_color, at, 0), line = texelFetch(line_color, at, 0);
    float dist = texelFetch(tri_distance, at, 0).r;
    vec4 c = tri;
    // a line pixel wins where it has a surface and the triangles have none, or show another surface farther away
    if (line.r != 0.0 && (tri.r == 0.0 || (line.r != tri.r && texelFetch(line_distance, at, 0).r < dist))) {
        c = line;
        dist = texelFetch(line_distance, at, 0).r;
    }
    if (float_map == 0) c = round(c * 255.0);  // the 8-bit map's bytes, exactly
    int m = int(roundEven(c.r)) - 1;
    out_map[p] = vec4(c.rgb, dist);
    precise double u0 = 0.0LF, v0 = 0.0LF;  // eq. 6, no fused multiply-add
    if (m >= 0) {
        double g = float_map != 0 ? double(c.g) : double(c.g) / 255.0LF;
        double b = float_map != 0 ? double(c.b) : double(c.b) / 255.0LF;
        int dm = off_domain + 4 * m;
        u0 = reals[dm] + (reals[dm + 1] - reals[dm]) * g;
        v0 = reals[dm + 2] + (reals[dm + 3] - reals[dm + 2]) * b;
    }
    solve_into(p, eye, dvec3(directions[3 * p], directions[3 * p + 1], directions[3 * p + 2]), m, u0, v0);
}
