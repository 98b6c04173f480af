#version 450
// Direct lighting of hits in float64, one invocation per hit and light (a
// dispatch per light, in order, each adding its term to the colour): the port of
// bsrt/kernels/lighting.py's shade_hits (per hit: shading.surface_frame, the
// exclusion box of its secondary rays, one any-hit shadow ray per light the
// point faces through anyhit.glsl's occluded, shading.radiance). It shades each
// level of the mirror chain (bsrt/rendering/gpu_lighting.py's shade_hits_gpu: the
// camera rays' hits, then what their mirror rays see, bounce.glsl, and so on,
// mixed by mix.glsl); a slot of a level that no mirror ray reached (hit -1) is
// passed over. Ambient occlusion and the ground's contact shadow stay with the
// caller (rendering/pipeline.py), which gets each first-level hit's position,
// normal and exclusion box from here. Dispatched once per light: with a loop over the
// lights around the walk's loops, Mesa 22's llvmpipe mixed up the invocations
// of a SIMD group (anyhit.glsl). The one difference from the kernel: GLSL has
// no float64 pow, so the specular power is taken by squaring for a whole
// exponent (a few ulps from pow), else in float32 (a relative error near
// 1e-5 of the highlight, far below the 8-bit image's step).
// LIGHT_AMBIENT, LIGHT_POINT and POLE_STEPS are #defined from kernels/shading.py.

#include "patches.glsl"
#include "trim64.glsl"
#include "solve_core.glsl"
#include "anyhit.glsl"

layout(local_size_x = GROUP) in;  // #defined by bsrt/rendering/gpu.py

layout(std430, binding = 2) readonly buffer HitReals { double hit_reals[]; };  // 5 per hit: u, v, ray direction (unit)
layout(std430, binding = 3) readonly buffer HitInts { int hit_ints[]; };       // 3 per hit: hit (1, 0, -1), patch, surface
// The materials and lights (offsets off_NAME): material_of (S,) ints; albedo (M, 3), specular (M,),
// shininess (M,), light_position (L, 3), light_direction (L, 3), strength (L, 3), background (3,) reals;
// kind (L,) ints (rendering/shade.py's light_arrays).
layout(std430, binding = 4) readonly buffer LookReals { double look_reals[]; };
layout(std430, binding = 5) readonly buffer LookInts { int look_ints[]; };
// One block after the other, each hit_count long, so that each is read back straight into its array:
// colour (3 per hit, linear RGB, the lights before this one's added up), position (3), normal (3, facing
// the ray's origin), radius (2)
layout(std430, binding = 8) buffer OutReals { double out_reals[]; };
// Blocks as out_reals', 1 per hit, so far: shadow rays, out of budget, not settled (occluded's -3: the hit
// is shaded again on the CPU), mirror rays (0 here: mix.glsl adds the chain's)
layout(std430, binding = 9) buffer OutInts { int out_ints[]; };
#include "slots.glsl"

uniform int off_material_of, off_albedo, off_specular, off_shininess, off_kind;
uniform int off_light_position, off_light_direction, off_strength, off_background;
uniform int light;  // the light of this dispatch (one per dispatch, in order, adding to the colour; -1: none)
uniform int hit_count;  // slots in each block of the buffers
uniform double eps;     // the exclusion box's half-width in scene units
uniform double shadow_tol;
uniform int shadow_iterations;
uniform double cull_tol;
uniform int budget;

dvec3 look3(int off, int i) { return dvec3(look_reals[off + 3 * i], look_reals[off + 3 * i + 1], look_reals[off + 3 * i + 2]); }

// Position, unit normal (facing the origin of a ray along t) and |S_u|, |S_v| of patch k at (u, v) (surface_frame).
void surface_frame(int k, double u, double v, dvec3 t, out dvec3 S, out dvec3 n, out dvec2 speed) {
    dvec3 Su, Sv;
    patch_frame(k, u, v, S, Su, Sv);
    double su = sqrt(Su.x * Su.x + Su.y * Su.y + Su.z * Su.z);
    double sv = sqrt(Sv.x * Sv.x + Sv.y * Sv.y + Sv.z * Sv.z);
    speed = dvec2(su, sv);
    n = dvec3(Su.y * Sv.z - Su.z * Sv.y, Su.z * Sv.x - Su.x * Sv.z, Su.x * Sv.y - Su.y * Sv.x);
    double len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (!(len > 1e-12LF * su * sv)) {
        int b = off_bounds + 4 * k;
        double cu = 0.5LF * (reals[b] + reals[b + 1]), cv = 0.5LF * (reals[b + 2] + reals[b + 3]);
        double steps[] = POLE_STEPS;
        for (int s = 0; s < steps.length(); ++s) {
            dvec3 P, Pu, Pv;
            patch_frame(k, u + 2.0LF * steps[s] * (cu - u), v + 2.0LF * steps[s] * (cv - v), P, Pu, Pv);
            n = dvec3(Pu.y * Pv.z - Pu.z * Pv.y, Pu.z * Pv.x - Pu.x * Pv.z, Pu.x * Pv.y - Pu.y * Pv.x);
            len = sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
            if (len > 0.0LF) break;
        }
    }
    if (!(len > 0.0LF)) {
        n = dvec3(0.0LF);
        len = 1.0LF;
    }
    if (n.x * t.x + n.y * t.y + n.z * t.z > 0.0LF) len = -len;
    n = dvec3(n.x / len, n.y / len, n.z / len);
}

// x^y for 0 <= x <= 1: by squaring for a whole y below 8192 (float64, within a few ulps of the
// kernel's pow), else in float32 (GLSL has no float64 pow). Unrolled, no loop (anyhit.glsl says why).
#define POWER_STEP r *= (e & 1) != 0 ? b : 1.0LF; b *= b; e >>= 1;
double power_of(double x, double y) {
    if (y == floor(y) && y >= 0.0LF && y < 8192.0LF) {
        double r = 1.0LF, b = x;
        int e = int(y);
        POWER_STEP POWER_STEP POWER_STEP POWER_STEP POWER_STEP POWER_STEP POWER_STEP
        POWER_STEP POWER_STEP POWER_STEP POWER_STEP POWER_STEP POWER_STEP
        return r;
    }
    return x > 0.0LF ? double(pow(float(x), float(y))) : (y == 0.0LF ? 1.0LF : 0.0LF);
}

void main() {
    int i = dispatch_slot();
    if (i < 0) return;
    double NaN = packDouble2x32(uvec2(0u, 0x7ff80000u));
    double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
    int n3 = 3 * hit_count;  // out_reals: colour at 3 i, position at n3 + 3 i, normal at 2 n3 + 3 i, radius at 3 n3 + 2 i
    if (hit_ints[3 * i] < 0) return;  // no mirror ray reached this slot of the level (not listed in slots)
    out_ints[3 * hit_count + i] = 0;
    if (hit_ints[3 * i] == 0) {
        dvec3 bg = look3(off_background, 0);
        out_reals[3 * i] = bg.x;
        out_reals[3 * i + 1] = bg.y;
        out_reals[3 * i + 2] = bg.z;
        for (int c = 0; c < 3; ++c) {
            out_reals[n3 + 3 * i + c] = NaN;
            out_reals[2 * n3 + 3 * i + c] = NaN;
        }
        out_reals[3 * n3 + 2 * i] = NaN;
        out_reals[3 * n3 + 2 * i + 1] = NaN;
        out_ints[i] = 0;
        out_ints[hit_count + i] = 0;
        out_ints[2 * hit_count + i] = 0;
        return;
    }
    int k = hit_ints[3 * i + 1], surface = hit_ints[3 * i + 2];
    double u = hit_reals[5 * i], v = hit_reals[5 * i + 1];
    dvec3 view = dvec3(hit_reals[5 * i + 2], hit_reals[5 * i + 3], hit_reals[5 * i + 4]);
    dvec3 p, n;
    dvec2 speed;
    surface_frame(k, u, v, view, p, n, speed);
    int b = off_bounds + 4 * k;
    double ru = min(speed.x > 0.0LF ? eps / speed.x : INF, 0.25LF * (reals[b + 1] - reals[b]));
    double rv = min(speed.y > 0.0LF ? eps / speed.y : INF, 0.25LF * (reals[b + 3] - reals[b + 2]));
    int m = look_ints[off_material_of + surface];
    dvec3 albedo = look3(off_albedo, m);
    bool first = light <= 0;
    dvec3 colour = first ? dvec3(0.0LF) : dvec3(out_reals[3 * i], out_reals[3 * i + 1], out_reals[3 * i + 2]);
    int rays = first ? 0 : out_ints[i], exhausted = first ? 0 : out_ints[hit_count + i];
    int unsettled = first ? 0 : out_ints[2 * hit_count + i];
    int kind = light < 0 ? -1 : look_ints[off_kind + light];  // light -1: a scene without lights
    dvec3 strength = light < 0 ? dvec3(0.0LF) : look3(off_strength, light);
    if (kind == LIGHT_AMBIENT) {
        colour += albedo * strength;
    } else if (kind >= 0) {
        dvec3 l;
        double dist, falloff;
        if (kind == LIGHT_POINT) {
            l = look3(off_light_position, light) - p;
            dist = sqrt(l.x * l.x + l.y * l.y + l.z * l.z);
            double d = max(dist, 1e-300LF);
            l = dvec3(l.x / d, l.y / d, l.z / d);
            falloff = 1.0LF / (dist * dist);
        } else {
            l = look3(off_light_direction, light);
            dist = INF;
            falloff = 1.0LF;
        }
        double cos_l = n.x * l.x + n.y * l.y + n.z * l.z;
        if (cos_l > 0.0LF) {  // else facing away: no shadow ray, nothing added
            rays += 1;
            double length = sqrt(l.x * l.x + l.y * l.y + l.z * l.z);  // the tracer's own normalisation (Rays)
            int its;
            int blocked = occluded(p, dvec3(l.x / length, l.y / length, l.z / length), dist, shadow_tol,
                                   shadow_iterations, cull_tol, budget, surface, dvec4(u, v, ru, rv), its);
            if (blocked == -2) exhausted += 1;
            if (blocked == -3) unsettled += 1;
            if (blocked != 1) {  // visible
                double specular = look_reals[off_specular + m], shininess = look_reals[off_shininess + m];
                dvec3 hv = l - view;
                double h = max(sqrt(hv.x * hv.x + hv.y * hv.y + hv.z * hv.z), 1e-300LF);
                double cos_h = min(max((n.x * hv.x + n.y * hv.y + n.z * hv.z) / h, 0.0LF), 1.0LF);
                double power = power_of(cos_h, shininess);
                colour += (albedo * cos_l + specular * power) * strength * falloff;
            }
        }
    }
    out_reals[3 * i] = colour.x;
    out_reals[3 * i + 1] = colour.y;
    out_reals[3 * i + 2] = colour.z;
    out_reals[n3 + 3 * i] = p.x;
    out_reals[n3 + 3 * i + 1] = p.y;
    out_reals[n3 + 3 * i + 2] = p.z;
    out_reals[2 * n3 + 3 * i] = n.x;
    out_reals[2 * n3 + 3 * i + 1] = n.y;
    out_reals[2 * n3 + 3 * i + 2] = n.z;
    out_reals[3 * n3 + 2 * i] = ru;
    out_reals[3 * n3 + 2 * i + 1] = rv;
    out_ints[i] = rays;
    out_ints[hit_count + i] = exhausted;
    out_ints[2 * hit_count + i] = unsettled;
}
