#version 330 core
// Preliminary map (Sisojevs & Glazs 2.1): every surface rasterised with
// red = surface index + 1 and green/blue = its u/v parameters normalised to
// [0, 1] over the surface's domain. A second target holds the distance from
// the eye, so the solver can tell a root on the visible layer from one behind.
//
// The TRIM_TEST variant draws the cells that trim curves cross (bsrt/prelim.py
// draws the others with the plain program: the test's code slows llvmpipe
// down even where it does not run): a fragment whose (u, v) is outside its
// surface's trim loops (trim.glsl, the CPU kernels' even-odd test on the same
// table) and farther than the cell's reach (along u and along v) from every
// trim curve is discarded, so the depth test keeps the nearest *kept* surface.
// The reach bounds how far the interpolated (u, v) may be from the (u, v) of
// the surface point the pixel sees (prelim._param_per_pixel): a fragment that
// may show a kept point is never discarded.

#if defined TRIM_TEST
#include "trim.glsl"
#endif

#if defined VERTEX_SHADER

uniform mat4 clip_from_eye;   // eye-relative world position -> clip space
in vec3 position;             // world position minus the eye
in vec2 uv;                   // normalised parameters in [0, 1]
in float surface_id;          // surface index + 1
#if defined TRIM_TEST
in vec2 param;                // (u, v) in the surface's knot domain
in vec2 reach;                // the trim test's margin along u and v (knot units), one per cell
out vec2 frag_param;
flat out vec2 frag_reach;
flat out ivec4 frag_trim_surface;  // the surface's trim texels, fetched per vertex, not per fragment
flat out vec4 frag_trim_band;
#endif

out vec3 eye_offset;
out vec2 frag_uv;
flat out float frag_id;

void main() {
    eye_offset = position;
    frag_uv = uv;
    frag_id = surface_id;
#if defined TRIM_TEST
    frag_param = param;
    frag_reach = reach;
    int m = int(surface_id + 0.5) - 1;
    frag_trim_surface = trim_fetch_i(trim_surface, m);
    frag_trim_band = trim_fetch_f(trim_band, m);
#endif
    gl_Position = clip_from_eye * vec4(position, 1.0);
}

#elif defined FRAGMENT_SHADER

uniform float id_scale;       // 1 for the float map, 1/255 for the 8-bit map
uniform float inv_far;        // 1 / the far plane's distance: the depth test runs on linear distance

in vec3 eye_offset;
in vec2 frag_uv;
flat in float frag_id;
#if defined TRIM_TEST
in vec2 frag_param;
flat in vec2 frag_reach;
flat in ivec4 frag_trim_surface;
flat in vec4 frag_trim_band;
#endif

layout(location = 0) out vec4 map_color;
layout(location = 1) out float eye_distance;

void main() {
#if defined TRIM_TEST
    if (!trim_kept_at(frag_trim_surface, frag_trim_band, frag_param.x, frag_param.y)
        && !trim_near_at(frag_trim_surface, frag_trim_band, frag_param.x, frag_param.y, frag_reach.x, frag_reach.y, true)) {
        discard;
    }
#endif
    map_color = vec4(frag_id * id_scale, clamp(frag_uv, 0.0, 1.0), 1.0);
    eye_distance = length(eye_offset);
    // Linear depth: the same resolution everywhere between the eye and the far
    // plane (a perspective depth buffer loses it all when the eye sits inside
    // the scene's box and the near plane must come close).
    gl_FragDepth = clamp(eye_distance * inv_far, 0.0, 1.0);
}

#endif
