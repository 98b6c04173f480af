// The seeded root finder in float64 for compute shaders: a file that other
// shaders include (no #version here; patches.glsl and trim64.glsl first).
// solve_one is bsrt/kernels/roots.py's solve_one (newton, gradient, fast;
// its docstring describes the methods) for one (ray, start) item, on the
// patch table of patches.glsl; solve_item is the seeded solve of one item. GRADIENT, FAST, NEWTON, MAX_HALVINGS and
// STALL_STEPS are #defined by bsrt/rendering/gpu.py from the kernels'
// constants; with TRIM_TEST #defined solve_item applies the trims to converged
// roots (trim64.glsl), as rendering/solve.py's find_roots does on the CPU.
// Kept in step with roots.py: the CPU kernel is the reference the tests
// hold this shader to. solve.glsl (items from a buffer) and map_solve.glsl
// (starts from the preliminary map's textures) #define ROOT_BUFFERS and run
// solve_into (solve_item, its result written to storage buffers 4 and 5),
// anyhit.glsl runs solve_one on the hierarchy's pieces.

uniform int method;
uniform int max_iterations;
uniform int stop_on_growth;
uniform double tol2;  // the tolerance squared

// The root of the ray o + t d (d unit) on surface m from the start (u0, v0)
// by method (tol2: the tolerance squared): root = (u, v, t, |residual|),
// patch_index = the patch holding (u, v), converged, iterations taken,
// cosine = |cos| between d and the normal at the last point for NEWTON
// (solve_one's, the hierarchy's grazing test), else NaN. No trims here.
void solve_one(dvec3 o, dvec3 d, int m, double u0, double v0, int method, double tol2, int max_iterations,
               bool stop_on_growth, out dvec4 root, out int patch_index, out bool converged, out int iterations,
               out double cosine) {
    double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
    // e1, e2 perpendicular to d and each other (Duff et al. 2017), as roots.ray_frame
    double sgn = d.z >= 0.0LF ? 1.0LF : -1.0LF;
    double fa = -1.0LF / (sgn + d.z);
    double fb = d.x * d.y * fa;
    dvec3 e1 = dvec3(1.0LF + sgn * d.x * d.x * fa, sgn * fb, -sgn * d.x);
    dvec3 e2 = dvec3(fb, sgn + d.y * d.y * fa, -d.y);
    double c1 = e1.x * o.x + e1.y * o.y + e1.z * o.z;
    double c2 = e2.x * o.x + e2.y * o.y + e2.z * o.z;
    dvec2 uv = clamp_domain(m, u0, v0);
    double u = uv.x, v = uv.y;
    int k = locate_patch(m, u, v);
    double ua = u, va = v, wa = INF;
    int ka = k;
    double a = 0.0LF, b = 0.0LF, c = 0.0LF, dd = 0.0LF;
    double gu = 0.0LF, gv = 0.0LF, h = 0.0LF, rz_prev = 0.0LF;
    bool need_derivatives = true, jacobian_here = false, refresh = false;
    converged = false;
    int halvings = 0, stall = 0;
    iterations = 0;
    double w_prev = INF, w_mark = INF, w = INF;
    dvec3 S = dvec3(0.0LF), Su = dvec3(0.0LF), Sv = dvec3(0.0LF);
    for (int it = 1; it <= max_iterations; ++it) {
        iterations = it;
        if (need_derivatives) patch_frame(k, u, v, S, Su, Sv);
        else S = patch_point(k, u, v);
        double qx = e1.x * S.x + e1.y * S.y + e1.z * S.z - c1;
        double qy = e2.x * S.x + e2.y * S.y + e2.z * S.z - c2;
        w = qx * qx + qy * qy;
        if (w <= tol2) {
            converged = true;
            break;
        }
        if (!(w < INF) || it == max_iterations) break;
        if (w < 0.5LF * w_mark) {
            w_mark = w;
            stall = 0;
        } else {
            stall += 1;
            if (stall >= STALL_STEPS) break;
        }
        double nu, nv;
        if (method == NEWTON) {
            if (stop_on_growth && w > w_prev) break;
            w_prev = w;
            a = e1.x * Su.x + e1.y * Su.y + e1.z * Su.z;
            b = e1.x * Sv.x + e1.y * Sv.y + e1.z * Sv.z;
            c = e2.x * Su.x + e2.y * Su.y + e2.z * Su.z;
            dd = e2.x * Sv.x + e2.y * Sv.y + e2.z * Sv.z;
            double j00 = a * a + c * c, j01 = a * b + c * dd, j11 = b * b + dd * dd;
            double mu = 1e-12LF * (j00 + j11) + 1e-300LF;
            double g0 = a * qx + c * qy, g1 = b * qx + dd * qy;
            double det = (j00 + mu) * (j11 + mu) - j01 * j01;
            nu = u - ((j11 + mu) * g0 - j01 * g1) / det;
            nv = v - ((j00 + mu) * g1 - j01 * g0) / det;
        } else if (w < wa || refresh) {  // accept this point, take a new step
            refresh = false;
            halvings = 0;
            ua = u;
            va = v;
            ka = k;
            wa = w;
            jacobian_here = need_derivatives;
            if (need_derivatives) {
                a = e1.x * Su.x + e1.y * Su.y + e1.z * Su.z;
                b = e1.x * Sv.x + e1.y * Sv.y + e1.z * Sv.z;
                c = e2.x * Su.x + e2.y * Su.y + e2.z * Su.z;
                dd = e2.x * Sv.x + e2.y * Sv.y + e2.z * Sv.z;
            }
            double ru = a * qx + c * qy, rv = b * qx + dd * qy;
            double zu = 2.0LF * ru / (a * a + c * c + 1e-300LF);
            double zv = 2.0LF * rv / (b * b + dd * dd + 1e-300LF);
            double rz = ru * zu + rv * zv;
            if (jacobian_here) {
                gu = zu;
                gv = zv;
            } else {  // fast, second step on the kept J: conjugate to the first
                double beta = rz / (rz_prev + 1e-300LF);
                gu = zu + beta * gu;
                gv = zv + beta * gv;
            }
            rz_prev = rz;
            double jg0 = a * gu + b * gv, jg1 = c * gu + dd * gv;
            h = (ru * gu + rv * gv) / (jg0 * jg0 + jg1 * jg1 + 1e-300LF);
            nu = ua - h * gu;
            nv = va - h * gv;
            need_derivatives = method == GRADIENT || !jacobian_here;
        } else if (method == FAST && !jacobian_here) {  // the kept J no longer helps: recompute it
            u = ua;
            v = va;
            k = ka;
            need_derivatives = true;
            refresh = true;
            continue;
        } else {  // rejected: halve the step from the accepted point
            halvings += 1;
            if (halvings > MAX_HALVINGS) break;
            h *= 0.5LF;
            nu = ua - h * gu;
            nv = va - h * gv;
            need_derivatives = method == GRADIENT;
        }
        dvec2 n = clamp_domain(m, nu, nv);
        double base_u = method == NEWTON ? u : ua, base_v = method == NEWTON ? v : va;
        if (n.x == base_u && n.y == base_v) {  // clipped at the border with nowhere to go
            if (method == FAST && !jacobian_here) {
                u = ua;
                v = va;
                k = ka;
                need_derivatives = true;
                refresh = true;
                continue;
            }
            break;
        }
        u = n.x;
        v = n.y;
        if (!inside_patch(k, u, v)) k = locate_patch(m, u, v);
    }
    double t = d.x * (S.x - o.x) + d.y * (S.y - o.y) + d.z * (S.z - o.z);
    cosine = packDouble2x32(uvec2(0u, 0x7ff80000u));  // NaN
    if (method == NEWTON) {  // the same arithmetic as evaluating the frame again (anyhit.glsl's cosine)
        dvec3 n = dvec3(Su.y * Sv.z - Su.z * Sv.y, Su.z * Sv.x - Su.x * Sv.z, Su.x * Sv.y - Su.y * Sv.x);
        cosine = abs(n.x * d.x + n.y * d.y + n.z * d.z) / max(sqrt(n.x * n.x + n.y * n.y + n.z * n.z), 1e-300LF);
    }
    if (!converged && method != NEWTON && wa < INF && !(w <= wa)) {  // report the best point seen
        u = ua;
        v = va;
        k = ka;
        S = patch_point(k, u, v);
        t = d.x * (S.x - o.x) + d.y * (S.y - o.y) + d.z * (S.z - o.z);
        w = wa;
    }
    root = dvec4(u, v, t, sqrt(w));
    patch_index = k;
}

// The seeded solve of one item with the uniforms' method and settings, the
// trims applied to a converged root (TRIM_TEST) as rendering/solve.py's
// find_roots does: trimmed, a converged root they remove (then not converged).
void solve_item(dvec3 o, dvec3 d, int m, double u0, double v0, out dvec4 root, out int patch_index, out bool converged,
                out int iterations, out bool trimmed) {
    double cosine;
    solve_one(o, d, m, u0, v0, method, tol2, max_iterations, stop_on_growth != 0, root, patch_index, converged,
              iterations, cosine);
    trimmed = false;
#ifdef TRIM_TEST
    if (converged && !trim_kept(m, root.x, root.y)) {
        converged = false;
        trimmed = true;
    }
#endif
}

#ifdef ROOT_BUFFERS
layout(std430, binding = 4) writeonly buffer RootReals { double root_reals[]; };  // 4 per item: u, v, t, residual
layout(std430, binding = 5) writeonly buffer RootInts { int root_ints[]; };       // 4 per item: converged, patch, iterations, trimmed

// solve_item from (u0, v0) on surface m along o + t d, its result written as item i of the root
// buffers (gpu.py's decode_roots reads them); m < 0: no solve, the result of none (patch -1).
void solve_into(int i, dvec3 o, dvec3 d, int m, double u0, double v0) {
    dvec4 root = dvec4(0.0LF);
    int patch_index = -1, iterations = 0;
    bool converged = false, trimmed = false;
    if (m >= 0) solve_item(o, d, m, u0, v0, root, patch_index, converged, iterations, trimmed);
    root_reals[4 * i] = root.x;
    root_reals[4 * i + 1] = root.y;
    root_reals[4 * i + 2] = root.z;
    root_reals[4 * i + 3] = root.w;
    root_ints[4 * i] = converged ? 1 : 0;
    root_ints[4 * i + 1] = patch_index;
    root_ints[4 * i + 2] = iterations;
    root_ints[4 * i + 3] = trimmed ? 1 : 0;
}
#endif
