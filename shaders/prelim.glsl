#version 330 core
// Preliminary map (Sisojevs & Glazs 2.1): every surface rasterised with
// red = surface index + 1 and green/blue = its u/v parameters normalised to
// [0, 1] over the surface's domain. A second target holds the distance from
// the eye, so the solver can tell a root on the visible layer from one behind.

#if defined VERTEX_SHADER

uniform mat4 clip_from_eye;   // eye-relative world position -> clip space
in vec3 position;             // world position minus the eye
in vec2 uv;                   // normalised parameters in [0, 1]
in float surface_id;          // surface index + 1

out vec3 eye_offset;
out vec2 frag_uv;
flat out float frag_id;

void main() {
    eye_offset = position;
    frag_uv = uv;
    frag_id = surface_id;
    gl_Position = clip_from_eye * vec4(position, 1.0);
}

#elif defined FRAGMENT_SHADER

uniform float id_scale;       // 1 for the float map, 1/255 for the 8-bit map
uniform float inv_far;        // 1 / the far plane's distance: the depth test runs on linear distance

in vec3 eye_offset;
in vec2 frag_uv;
flat in float frag_id;

layout(location = 0) out vec4 map_color;
layout(location = 1) out float eye_distance;

void main() {
    map_color = vec4(frag_id * id_scale, clamp(frag_uv, 0.0, 1.0), 1.0);
    eye_distance = length(eye_offset);
    // Linear depth: the same resolution everywhere between the eye and the far
    // plane (a perspective depth buffer loses it all when the eye sits inside
    // the scene's box and the near plane must come close).
    gl_FragDepth = clamp(eye_distance * inv_far, 0.0, 1.0);
}

#endif
