// The patch table in float64 for compute shaders: a file that other shaders
// include (no #version here). It mirrors bsrt/kernels/patches.py (point,
// frame, clamp, locate, inside_patch) on the same PatchArrays, uploaded by
// bsrt/rendering/gpu.py as two storage buffers: every float64 array packed
// into reals, every integer array into ints (int32), each array starting at
// the offset its uniform names.
//
// coef: patch k's power-basis coefficients from coef_start[k], laid out
// [i][c][j] (s^i, component c of x, y, z (, w), t^j); bounds (P, 4),
// inv_size (P, 2), domain (M, 4), breaks_u / breaks_v with break_start_u /
// break_start_v (M + 1), grid_start (M), patch_grid (P), degree (P, 2), dim (P).

layout(std430, binding = 0) readonly buffer PatchReals { double reals[]; };
layout(std430, binding = 1) readonly buffer PatchInts { int ints[]; };

uniform int off_coef, off_bounds, off_inv_size, off_domain, off_breaks_u, off_breaks_v;
uniform int off_coef_start, off_degree, off_dim, off_break_start_u, off_break_start_v, off_grid_start, off_patch_grid;

// Homogeneous value (x, y, z, w) of patch k at local (s, t), and with
// derivatives its d/ds and d/dt; Horner's scheme in t then s, as
// kernels/patches.py's _horner (w = 1, its derivatives 0 for dim 3).
void horner(int k, double s, double t, bool derivatives, out dvec4 h, out dvec4 hs, out dvec4 ht) {
    int base = off_coef + ints[off_coef_start + k];
    int p = ints[off_degree + 2 * k], q = ints[off_degree + 2 * k + 1], dim = ints[off_dim + k];
    int stride = q + 1;
    h = dvec4(0.0LF);
    hs = dvec4(0.0LF);
    ht = dvec4(0.0LF);
    for (int i = p; i >= 0; --i) {
        int row = base + i * dim * stride;
        dvec4 a = dvec4(reals[row + q], reals[row + stride + q], reals[row + 2 * stride + q],
                        dim == 4 ? reals[row + 3 * stride + q] : 0.0LF);
        dvec4 ta = dvec4(0.0LF);
        for (int j = q - 1; j >= 0; --j) {
            if (derivatives) ta = ta * t + a;
            a = a * t + dvec4(reals[row + j], reals[row + stride + j], reals[row + 2 * stride + j],
                              dim == 4 ? reals[row + 3 * stride + j] : 0.0LF);
        }
        if (derivatives) {
            hs = hs * s + h;
            ht = ht * s + ta;
        }
        h = h * s + a;
    }
    if (dim == 3) {
        h.w = 1.0LF;
        hs.w = 0.0LF;
        ht.w = 0.0LF;
    }
}

// S(u, v) of patch k at global parameters.
dvec3 patch_point(int k, double u, double v) {
    double s = (u - reals[off_bounds + 4 * k]) * reals[off_inv_size + 2 * k];
    double t = (v - reals[off_bounds + 4 * k + 2]) * reals[off_inv_size + 2 * k + 1];
    dvec4 h, hs, ht;
    horner(k, s, t, false, h, hs, ht);
    return h.xyz / h.w;
}

// S, S_u, S_v of patch k at global (u, v) (the quotient rule for a rational patch).
void patch_frame(int k, double u, double v, out dvec3 S, out dvec3 Su, out dvec3 Sv) {
    double du = reals[off_inv_size + 2 * k], dv = reals[off_inv_size + 2 * k + 1];
    double s = (u - reals[off_bounds + 4 * k]) * du;
    double t = (v - reals[off_bounds + 4 * k + 2]) * dv;
    dvec4 h, hs, ht;
    horner(k, s, t, true, h, hs, ht);
    S = h.xyz / h.w;
    Su = (hs.xyz - S * hs.w) / h.w * du;
    Sv = (ht.xyz - S * ht.w) / h.w * dv;
}

// Index (within the surface) of the span of the sorted breaks reals[off + first .. off + stop - 1] holding x.
int break_span(int off, int first, int stop, double x) {
    int lo = first, hi = stop - 2;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (reals[off + mid] <= x) lo = mid;
        else hi = mid - 1;
    }
    return lo - first;
}

// (u, v) clipped into surface m's domain.
dvec2 clamp_domain(int m, double u, double v) {
    int d = off_domain + 4 * m;
    return dvec2(min(max(u, reals[d]), reals[d + 1]), min(max(v, reals[d + 2]), reals[d + 3]));
}

// The patch of surface m holding (u, v) (outside the domain: the nearest).
int locate_patch(int m, double u, double v) {
    int fu = ints[off_break_start_u + m], su = ints[off_break_start_u + m + 1];
    int fv = ints[off_break_start_v + m], sv = ints[off_break_start_v + m + 1];
    int iu = break_span(off_breaks_u, fu, su, u);
    int iv = break_span(off_breaks_v, fv, sv, v);
    return ints[off_patch_grid + ints[off_grid_start + m] + iu * (sv - fv - 1) + iv];
}

bool inside_patch(int k, double u, double v) {
    int b = off_bounds + 4 * k;
    return reals[b] <= u && u <= reals[b + 1] && reals[b + 2] <= v && v <= reals[b + 3];
}
