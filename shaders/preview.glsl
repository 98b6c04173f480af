#version 330 core
// Preview window (bsrt preview). Two passes in one program:
//
// - the fast view (image_pass false): the preliminary map's tessellation
//   lit per vertex (Gouraud: llvmpipe draws many frames a second) with the
//   scene's own Blinn-Phong lights and materials, the formulas of
//   bsrt/shade.py (normals turned to the eye, inverse-square point lights),
//   sRGB-encoded, so it looks like the exact image while the camera moves;
//   in the TRIM_TEST variant (for the triangles that trim curves cross)
//   each fragment carries its (u, v) and surface, and the trim test
//   (trim.glsl, the CPU kernels' even-odd test on the same table) discards
//   the fragments outside the surface's trim loops, grown by trim_grow
//   pixels (the tessellations of two faces meeting at a trimmed edge place
//   it up to about a pixel apart: without the margin the background shows
//   through the seam);
// - the image pass (image_pass true): a full-screen quad (4 vertices of a
//   triangle strip, no attributes) showing an sRGB image texture: the exact
//   image of a refinement level, or the preliminary map's picture.

#if defined TRIM_TEST
// The variant for the triangles that trim curves cross (view.py draws the
// others, and the image pass, with the plain program: the test's code slows
// llvmpipe down even where it does not run). Both stages read the textures.
#include "trim.glsl"
#endif

#if defined VERTEX_SHADER

#define MAX_LIGHTS 8

uniform bool image_pass;
uniform mat4 clip_from_local;            // local = world - origin (scene box centre)
uniform vec3 eye;                        // local eye position
uniform int light_count;
uniform int light_kind[MAX_LIGHTS];      // 0 ambient, 1 point, 2 directional
uniform vec3 light_vector[MAX_LIGHTS];   // point: local position; directional: unit vector toward the light
uniform vec3 light_strength[MAX_LIGHTS]; // color * intensity, linear RGB

in vec3 position;                        // local position (float32)
in vec3 normal;                          // unit surface normal (either side)
in vec3 albedo;                          // linear RGB
in vec2 gloss;                           // (specular, shininess)
#if defined TRIM_TEST
in vec2 param;                           // (u, v) in the surface's knot domain
in float surface;                        // surface index (as in the scene), a whole number
out vec2 frag_param;
flat out ivec4 frag_trim_surface;        // the surface's trim texels, fetched per vertex, not per fragment
flat out vec4 frag_trim_band;
#endif

out vec3 frag_color;                     // sRGB
out vec2 frag_uv;

vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 radiance(vec3 p, vec3 n) {
    vec3 view = normalize(p - eye);
    if (dot(n, view) > 0.0) {
        n = -n;  // face the eye, as the ray tracer does
    }
    vec3 to_eye = -view;
    vec3 sum = vec3(0.0);
    for (int k = 0; k < light_count; ++k) {
        vec3 strength = light_strength[k];
        if (light_kind[k] == 0) {
            sum += albedo * strength;
            continue;
        }
        vec3 to_light;
        float falloff = 1.0;
        if (light_kind[k] == 1) {
            vec3 d = light_vector[k] - p;
            float d2 = dot(d, d);
            to_light = d * inversesqrt(d2);
            falloff = 1.0 / d2;
        } else {
            to_light = light_vector[k];
        }
        float cos_l = dot(n, to_light);
        if (cos_l <= 0.0) {
            continue;
        }
        vec3 half_vector = to_light + to_eye;
        half_vector /= max(length(half_vector), 1e-30);
        float cos_h = clamp(dot(n, half_vector), 0.0, 1.0);
        sum += (albedo * cos_l + gloss.x * pow(cos_h, gloss.y)) * strength * falloff;
    }
    return sum;
}

void main() {
    if (image_pass) {
        vec2 corner = vec2(float(gl_VertexID & 1), float((gl_VertexID >> 1) & 1));
        frag_uv = corner;
        frag_color = vec3(0.0);
        gl_Position = vec4(2.0 * corner - 1.0, 0.0, 1.0);
        return;
    }
    frag_uv = vec2(0.0);
#if defined TRIM_TEST
    frag_param = param;
    int m = int(surface + 0.5);
    frag_trim_surface = trim_fetch_i(trim_surface, m);
    frag_trim_band = trim_fetch_f(trim_band, m);
#endif
    frag_color = srgb_encode(radiance(position, normalize(normal)));
    gl_Position = clip_from_local * vec4(position, 1.0);
}

#elif defined FRAGMENT_SHADER

uniform bool image_pass;

#if defined TRIM_TEST
uniform float trim_grow;                 // pixels: a fragment this near (along x or y) to a kept point is kept
#endif
uniform sampler2D image;                 // sRGB image, row 0 at the bottom

in vec3 frag_color;
in vec2 frag_uv;
#if defined TRIM_TEST
in vec2 frag_param;
flat in ivec4 frag_trim_surface;
flat in vec4 frag_trim_band;
#endif

out vec4 color;

void main() {
#if defined TRIM_TEST
    // kept: inside the trim loops, or within trim_grow pixels (along x and y) of a curve
    vec2 reach = trim_grow * (abs(dFdx(frag_param)) + abs(dFdy(frag_param)));  // in uniform control flow
    if (!trim_kept_at(frag_trim_surface, frag_trim_band, frag_param.x, frag_param.y)
        && !trim_near_at(frag_trim_surface, frag_trim_band, frag_param.x, frag_param.y, reach.x, reach.y, false)) {
        discard;
    }
#endif
    color = vec4(image_pass ? texture(image, frag_uv).rgb : frag_color, 1.0);
}

#endif
