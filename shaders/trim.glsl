// The trim test "is (u, v) of surface m kept?" in GLSL: a file that other
// shaders include (bsrt/gl.py's loader expands the include line; no
// #version here; moderngl would expand any include line it sees, even in a
// comment, so none is spelled out here).
// It mirrors bsrt/kernels/trim.py's point_kept on the same TrimTable
// (bsrt/trim.py), uploaded once per scene by bsrt/trim_gl.py into textures
// read with texelFetch (OpenGL 3.3 core: no storage buffers needed), in
// float32: the answer agrees with the float64 kernels except within float32
// rounding of the curves (tests/test_trim_gl.py).
//
// The even-odd rule: a ray from (u, v) toward +u; a monotone piece counts
// when v lies in its half-open v-range [min(v_a, v_b), max(v_a, v_b)) and
// its one crossing of the row lies right of u. The surface's band of v lists
// its pieces by decreasing u_max: the scan stops at the first piece wholly
// left of u; a piece wholly right of u counts at once; else its end points
// decide when both lie on one side of u; else a segment by one cross
// product; else the root of V(s) = v is bracketed (Newton steps pushed 1 %
// past the root, bisection when the bracket stops halving) until both ends
// of the bracket lie on one side of u (U is monotone too).
//
// Each texture is a 2-D array of rows of textureSize(t, 0).x texels; item i
// is texel (i % width, i / width).

uniform isampler2D trim_surface;   // per surface m: (trimmed 0/1, band_first, band_count, 0)
uniform sampler2D trim_band;       // per surface m: (band_v0, band_scale, 0, 0)
uniform isampler2D trim_band_start;// per band b: (band_start[b], band_start[b + 1], 0, 0): its entries
uniform isampler2D trim_entry;     // per band entry e: (entry_piece, that piece's degree, 0, 0)
uniform sampler2D trim_entry_box;  // per band entry e: (u_min, u_max, v_lo, v_hi) of its piece
uniform sampler2D trim_ends;       // per piece k: (u_a, v_a, u_b, v_b)
uniform sampler2D trim_coef;       // per piece k and power i <= degree: texel k * trim_coef_stride + i = (x, y, w, 0)
uniform int trim_coef_stride;      // the table's largest degree + 1

const int TRIM_SOLVE_STEPS = 80;   // float32: the bracket reaches neighbouring floats long before

ivec2 trim_texel(int i, int width) {
    return ivec2(i % width, i / width);
}

ivec4 trim_fetch_i(isampler2D t, int i) {
    return texelFetch(t, trim_texel(i, textureSize(t, 0).x), 0);
}

vec4 trim_fetch_f(sampler2D t, int i) {
    return texelFetch(t, trim_texel(i, textureSize(t, 0).x), 0);
}

// (x, y, w) of piece k (degree d) at s, and (dy/ds, dw/ds) in deriv (Horner, power basis).
vec3 trim_eval(int k, int d, float s, out vec2 deriv) {
    int base = k * trim_coef_stride;
    vec3 p = trim_fetch_f(trim_coef, base + d).xyz;
    vec2 dp = vec2(0.0);
    for (int i = d - 1; i >= 0; --i) {
        dp = dp * s + p.yz;
        p = p * s + trim_fetch_f(trim_coef, base + i).xyz;
    }
    deriv = dp;
    return p;
}

// Does the curved piece k (degree d, ends e = (ua, va, ub, vb), monotone) cross the row v right
// of u? v in its half-open v-range and u strictly between ua and ub assumed. point_kept's
// _solve_right, step for step.
bool trim_solve_right(int k, int d, vec4 e, float u, float v) {
    float up = u - e.x;  // local coordinates: the piece's origin is its start
    float vp = v - e.y;
    float sigma = e.w > e.y ? 1.0 : -1.0;
    bool ga = e.x > u;
    bool gb = e.z > u;
    vec2 deriv;
    vec3 p = trim_eval(k, d, 0.0, deriv);
    float fa = sigma * (p.y - vp * p.z);
    p = trim_eval(k, d, 1.0, deriv);
    float fb = sigma * (p.y - vp * p.z);
    if (!(fa < 0.0)) {
        return ga;
    }
    if (!(fb >= 0.0)) {
        return gb;
    }
    float a = 0.0;
    float b = 1.0;
    float s = fa / (fa - fb);
    float width = 1.0;
    for (int step = 0; step < TRIM_SOLVE_STEPS; ++step) {
        if (!(a < s && s < b)) {
            s = 0.5 * (a + b);
            if (!(a < s && s < b)) {  // neighbouring floats: (u, v) is on the curve
                break;
            }
        }
        p = trim_eval(k, d, s, deriv);
        float f = sigma * (p.y - vp * p.z);
        bool g = p.x - up * p.z > 0.0;
        if (f < 0.0) {
            a = s;
            ga = g;
        } else if (f > 0.0) {
            b = s;
            gb = g;
        } else {
            return g;
        }
        if (ga == gb) {
            return ga;
        }
        if (step % 3 == 2) {  // the bracket must halve every third step at least
            if (b - a > 0.5 * width) {
                s = 0.5 * (a + b);
                width = b - a;
                continue;
            }
            width = b - a;
        }
        float slope = sigma * (deriv.x - vp * deriv.y);
        s = slope > 0.0 ? s - 1.01 * f / slope : 0.5 * (a + b);
    }
    return gb;
}

// A surface's two texels, fetched once (a caller may fetch them per vertex and pass them on):
// surface = trim_fetch_i(trim_surface, m), band_map = trim_fetch_f(trim_band, m).

// The index (for trim_band_start) of the surface's band holding v (the end bands reach to infinity).
int trim_band_of(ivec4 surface, vec4 band_map, float v) {
    float x = (v - band_map.x) * band_map.y;
    if (!(x > 0.0)) {
        return surface.y;
    }
    if (x >= float(surface.z)) {
        return surface.y + surface.z - 1;
    }
    return surface.y + int(x);
}

// Is (u, v) of the surface inside an odd number of its loops, or is
// the surface untrimmed?
bool trim_kept_at(ivec4 surface, vec4 band_map, float u, float v) {
    if (surface.x == 0) {
        return true;
    }
    ivec2 entries = trim_fetch_i(trim_band_start, trim_band_of(surface, band_map, v)).xy;
    bool inside = false;
    for (int e = entries.x; e < entries.y; ++e) {
        vec4 box = trim_fetch_f(trim_entry_box, e);
        if (!(box.y > u)) {  // sorted by decreasing u_max: every piece left is left of u
            break;
        }
        if (!(box.z <= v && v < box.w)) {
            continue;
        }
        if (box.x > u) {
            inside = !inside;
            continue;
        }
        ivec4 entry = trim_fetch_i(trim_entry, e);
        vec4 ends = trim_fetch_f(trim_ends, entry.x);
        bool right = ends.x > u;
        if (right != (ends.z > u)) {  // the ends straddle u
            if (entry.y == 1) {  // a segment: which side of it (u, v) lies
                float cross = (ends.z - ends.x) * (v - ends.y) - (u - ends.x) * (ends.w - ends.y);
                right = ends.w > ends.y ? cross > 0.0 : cross < 0.0;
            } else {
                right = trim_solve_right(entry.x, entry.y, ends, u, v);
            }
        }
        if (right) {
            inside = !inside;
        }
    }
    return inside;
}

// Does the segment from a to b meet the rectangle [c - r, c + r] (r >= 0)? Its box meets the
// rectangle and the rectangle's corners do not all lie strictly on one side of its line.
bool trim_segment_meets(vec2 a, vec2 b, vec2 c, vec2 r) {
    if (any(greaterThan(min(a, b), c + r)) || any(lessThan(max(a, b), c - r))) {
        return false;
    }
    vec2 d = b - a;
    vec2 q = c - a;
    float centre = d.x * q.y - d.y * q.x;  // the side of c, times |d|
    float spread = abs(d.x) * r.y + abs(d.y) * r.x;  // how far the corners' sides reach from it
    return abs(centre) <= spread;
}

const int TRIM_NEAR_CHORDS = 8;   // a curved piece is cut into this many parts in trim_near

// Does a trim curve of the surface pass through the rectangle [u - du, u + du] x [v - dv, v + dv]
// (du, dv >= 0)? Segments exactly; a curved piece by its parts between s = i / TRIM_NEAR_CHORDS:
// with boxes false, by the parts' chords (off the curve by their sagitta: a heuristic, for the
// preview's fast view, which keeps the fragments it says are near a curve, growing each face by
// about a pixel over the seams); with boxes true, by the box of each part's two ends, which holds
// the part (the piece is monotone in u and in v), so the answer is never no when a curve passes
// (up to float32 rounding) but may be yes for one within a part's box: the preliminary map's, which
// must never discard a fragment whose interpolated (u, v) may be off a kept point. Not part of
// point_kept.
bool trim_near_at(ivec4 surface, vec4 band_map, float u, float v, float du, float dv, bool boxes) {
    if (surface.x == 0) {
        return false;
    }
    vec2 c = vec2(u, v);
    vec2 r = vec2(du, dv);
    int last = trim_band_of(surface, band_map, v + dv);
    for (int band = trim_band_of(surface, band_map, v - dv); band <= last; ++band) {
        ivec2 entries = trim_fetch_i(trim_band_start, band).xy;
        for (int e = entries.x; e < entries.y; ++e) {
            vec4 box = trim_fetch_f(trim_entry_box, e);
            if (box.y < u - du) {  // sorted by decreasing u_max
                break;
            }
            if (!(box.x <= u + du && box.z <= v + dv && box.w >= v - dv)) {
                continue;
            }
            ivec4 entry = trim_fetch_i(trim_entry, e);
            vec4 ends = trim_fetch_f(trim_ends, entry.x);
            if (entry.y == 1) {
                if (trim_segment_meets(ends.xy, ends.zw, c, r)) {
                    return true;
                }
                continue;
            }
            vec2 local = c - ends.xy;  // the piece's coefficients are relative to its start
            vec2 a = vec2(0.0);
            vec2 deriv;
            for (int i = 1; i <= TRIM_NEAR_CHORDS; ++i) {
                vec3 p = trim_eval(entry.x, entry.y, float(i) / float(TRIM_NEAR_CHORDS), deriv);
                vec2 b = p.xy / p.z;
                bool meets = boxes ? all(lessThanEqual(min(a, b), local + r)) && all(greaterThanEqual(max(a, b), local - r))
                                   : trim_segment_meets(a, b, local, r);
                if (meets) {
                    return true;
                }
                a = b;
            }
        }
    }
    return false;
}

// trim_kept_at for surface m (0-based, as in the TrimTable).
bool trim_kept(int m, float u, float v) {
    return trim_kept_at(trim_fetch_i(trim_surface, m), trim_fetch_f(trim_band, m), u, v);
}
