// The trim test "is (u, v) of surface m kept?" in float64 for compute
// shaders: a file that other shaders include (no #version here), after
// patches.glsl, whose storage buffers (reals, ints) also hold the trim
// table (bsrt/rendering/gpu.py packs bsrt/kernels/trim.py's TrimTable there,
// each array at the offset its uniform names). It is a line-by-line port of
// kernels/trim.py's point_kept (the even-odd rule on monotone rational
// Bezier pieces, banded over v; that module's docstring explains each
// step), in float64 like the kernel, so the answers agree exactly.
//
// Arrays: per surface trim_trimmed, trim_band_first, trim_band_count (ints),
// trim_band_v0, trim_band_scale (reals); per piece trim_degree (ints),
// trim_coef ((K, trim_coef_rows, 3) reals), trim_ends ((K, 4) reals); per
// band trim_band_start (ints, B + 1); per entry trim_entry_piece (ints),
// trim_entry_box ((E, 4) reals).

uniform int off_trim_trimmed, off_trim_band_first, off_trim_band_count, off_trim_band_v0, off_trim_band_scale;
uniform int off_trim_degree, off_trim_coef, off_trim_ends, off_trim_band_start, off_trim_entry_piece;
uniform int off_trim_entry_box;
uniform int trim_coef_rows;  // D + 1, the largest piece degree plus one

#define TRIM_SOLVE_STEPS 200

double trim_c(int k, int i, int c) { return reals[off_trim_coef + (k * trim_coef_rows + i) * 3 + c]; }

// Does the curved piece k (degree d, from (ua, va) to (ub, vb)) cross the row v right of u? (_solve_right)
bool trim_solve_right(int k, int d, double ua, double va, double ub, double vb, double u, double v) {
    double up = u - ua, vp = v - va;
    double sigma = vb > va ? 1.0LF : -1.0LF;
    bool ga = ua > u, gb = ub > u;
    double y0 = trim_c(k, 0, 1), w0 = trim_c(k, 0, 2);  // s = 0: the constant row
    double fa = sigma * (y0 - vp * w0);
    double y1 = 0.0LF, w1 = 0.0LF;  // s = 1: the sum of the rows (Horner at 1, as the kernel)
    y1 = trim_c(k, d, 1);
    w1 = trim_c(k, d, 2);
    for (int i = d - 1; i >= 0; --i) {
        y1 = y1 * 1.0LF + trim_c(k, i, 1);
        w1 = w1 * 1.0LF + trim_c(k, i, 2);
    }
    double fb = sigma * (y1 - vp * w1);
    if (!(fa < 0.0LF)) return ga;
    if (!(fb >= 0.0LF)) return gb;
    double a = 0.0LF, b = 1.0LF;
    double s = fa / (fa - fb);
    double width = 1.0LF;
    for (int step = 0; step < TRIM_SOLVE_STEPS; ++step) {
        if (!(a < s && s < b)) {
            s = 0.5LF * (a + b);
            if (!(a < s && s < b)) break;
        }
        double x = trim_c(k, d, 0), y = trim_c(k, d, 1), w = trim_c(k, d, 2);
        double dy = 0.0LF, dw = 0.0LF;
        for (int i = d - 1; i >= 0; --i) {
            dy = dy * s + y;
            dw = dw * s + w;
            x = x * s + trim_c(k, i, 0);
            y = y * s + trim_c(k, i, 1);
            w = w * s + trim_c(k, i, 2);
        }
        double f = sigma * (y - vp * w);
        bool g = x - up * w > 0.0LF;
        if (f < 0.0LF) {
            a = s;
            ga = g;
        } else if (f > 0.0LF) {
            b = s;
            gb = g;
        } else {
            return g;
        }
        if (ga == gb) return ga;
        if (step % 3 == 2) {
            if (b - a > 0.5LF * width) {
                s = 0.5LF * (a + b);
                width = b - a;
                continue;
            }
            width = b - a;
        }
        double slope = sigma * (dy - vp * dw);
        s = slope > 0.0LF ? s - 1.01LF * f / slope : 0.5LF * (a + b);
    }
    return gb;
}

// The band of surface m holding v (_band).
int trim_band(int m, double v) {
    int count = ints[off_trim_band_count + m];
    double x = (v - reals[off_trim_band_v0 + m]) * reals[off_trim_band_scale + m];
    if (!(x > 0.0LF)) return ints[off_trim_band_first + m];
    if (x >= double(count)) return ints[off_trim_band_first + m] + count - 1;
    return ints[off_trim_band_first + m] + int(x);
}

// Is (u, v) of surface m inside an odd number of its loops (or is m untrimmed)? (point_kept)
bool trim_kept(int m, double u, double v) {
    if (ints[off_trim_trimmed + m] == 0) return true;
    int band = trim_band(m, v);
    bool inside = false;
    int stop = ints[off_trim_band_start + band + 1];
    for (int e = ints[off_trim_band_start + band]; e < stop; ++e) {
        int box = off_trim_entry_box + 4 * e;
        if (!(reals[box + 1] > u)) break;
        if (!(reals[box + 2] <= v && v < reals[box + 3])) continue;
        if (reals[box] > u) {
            inside = !inside;
            continue;
        }
        int k = ints[off_trim_entry_piece + e];
        int at = off_trim_ends + 4 * k;
        double ua = reals[at], va = reals[at + 1], ub = reals[at + 2], vb = reals[at + 3];
        bool right = ua > u;
        if (right != (ub > u)) {
            int d = ints[off_trim_degree + k];
            if (d == 1) {
                double cross = (ub - ua) * (v - va) - (u - ua) * (vb - va);
                right = vb > va ? cross > 0.0LF : cross < 0.0LF;
            } else {
                right = trim_solve_right(k, d, ua, va, ub, vb, u, v);
            }
        }
        if (right) inside = !inside;
    }
    return inside;
}
