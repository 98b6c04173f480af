// Any-hit (shadow) rays through Martin et al.'s hierarchy of flat pieces in
// float64 for compute shaders: a file that other shaders include (no
// #version here), after patches.glsl, trim64.glsl and solve_core.glsl. A
// line-by-line port of bsrt/kernels/lighting.py's occluded (the walk) and
// kernels/traverse.py's _solve_piece, _root_in, _slab and _obb_slab,
// kernels/hulls.py's straddles, and kernels/crossings.py's crosses_once
// and holds_once (their
// docstrings explain each step), one ray at a time (the CPU walks packets of
// nearby hits' rays together: fewer box tests, the same answer per ray),
// without the hint (a leaf that blocked a ray of the CPU's previous packet,
// tried first there: it changes the order pieces are tried in, not whether a
// ray is blocked), with the retries' nets made where the kernels copy them
// (the same nets, the same order: below) and,
// for shadow rays, without the final Newton step on a grazing root (it moves
// t, not the answer; nearest.glsl's mirror rays take it). The CPU kernels are the reference the tests hold this to. The
// loops leave by their conditions, never by return, break or continue inside
// (with those, Mesa 22's llvmpipe mixed up the lanes of a SIMD group whose
// invocations left at different points: some then skipped their next light).
// llvmpipe also ends every loop of an invocation once all its loops together
// have turned 65,535 times (gallivm's loop limiter, LP_MAX_TGSI_LOOP_ITERATIONS,
// one count shared by every loop of a shader): from then on each loop stops
// after one turn, silently. A long walk (a water-lily shadow ray of 643 Newton
// iterations) ran into it and missed its blocker, and a cut-short Newton loop
// can also pass a false root for a blocker; occluded answers -3 wherever the
// count ran out (as nearest_walk.glsl does), and the host traces those rays on the
// CPU (gpu_shade.py, gpu_lighting.py). A GPU has no such limit.
//
// The hierarchy (rendering/bvh.py's BVHArrays, packed by
// rendering/gpu_shade.py) lies in storage buffers 6 (float64) and 7 (int32),
// each array at the offset its uniform names. NET_PM, NET_QM (the nets'
// largest p + 1, q + 1), RETRY_DEPTH, STACK, GRAZING_COSINE, RECT_SLACK and
// ROUNDING are #defined by gpu_shade.py from the kernels' values.

layout(std430, binding = 6) readonly buffer HierarchyReals { double hier_reals[]; };
layout(std430, binding = 7) readonly buffer HierarchyInts { int hier_ints[]; };

uniform int off_node_bounds, off_leaf_rect, off_leaf_obb, off_patch_net, off_leaf_net;
uniform int off_node_left, off_node_right, off_node_first, off_node_count, off_leaf_surface, off_leaf_net_row;
uniform int off_leaf_degree, off_leaf_planar, off_leaf_kept;
uniform int canary_turns;  // 2 (gpu_shade.hierarchy_shader): a uniform, so loops_whole's loop is not unrolled

#define SCRATCH (4 * RETRY_DEPTH + 8)  // the retries' rectangles (traverse.py's scratch: the same cap)
#define CHAIN (RETRY_DEPTH > 1 ? RETRY_DEPTH - 1 : 1)  // nets 0 .. CHAIN - 1: the piece cut at depth 1, 2, ...
#define HALF CHAIN  // the u half of the quarter being tried
#define QUARTER (CHAIN + 1)  // the quarter being tried
#define NET_POINTS (NET_PM * NET_QM)
#define NET_SIZE (NET_POINTS * 4)  // doubles per net in the hierarchy's buffer: (x, y, z, w) per control point
#define POINT(s, i, j) net_point4(s, (i) * NET_QM + (j))  // control point (i, j) of net s (read)
#define SLOT(s, i, j) nets[(s) * NET_POINTS + (i) * NET_QM + (j)]  // of slot s of nets (written)

// Per invocation: the nets of the quarters being cut (one per depth below the leaf, whose net is read
// where it lies, in the hierarchy's buffer), the quarter being tried and its u half, the retries'
// rectangles, depths and quarter codes, and the walk's stack. A GPU keeps such arrays in local memory,
// and the walk's time follows the traffic to them (measured on an H200: 26 KB an invocation when the
// retries' 24 nets were arrays of doubles, each double in a 16-byte slot of its own). So a net is held
// as dvec4 control points; a ray that needs no retry touches none of them; and the retries keep
// rectangles, not nets: a quarter waiting on the stack is cut again from its parent's net when its turn
// comes, with the same de Casteljau steps, so its net has the same bits as the kernels' (traverse.py
// keeps and copies nets).
dvec4 nets[(CHAIN + 2) * NET_POINTS];
dvec2 projected[NET_POINTS];  // crosses_once's coefficients across the ray
dvec4 rects[SCRATCH];
int depths[SCRATCH];
int codes[SCRATCH];  // which quarter of its parent: 2 x the u half + the v half (0: lower, 1: upper)
dvec4 tmp[NET_PM > NET_QM ? NET_PM : NET_QM];
int stack[STACK];

// The net of leaf as a net source: -1 - its offset in the hierarchy's buffer (flatten.leaf_net: its own
// row, or its patch's). A net source s >= 0 is slot s of nets.
int leaf_source(int leaf) {
    int row = hier_ints[off_leaf_net_row + leaf];
    return -1 - (row >= 0 ? off_leaf_net + row * NET_SIZE : off_patch_net + (-1 - row) * NET_SIZE);
}

// Control point k (= i NET_QM + j) of net source s, homogeneous.
dvec4 net_point4(int s, int k) {
    dvec4 point;
    if (s >= 0) {
        point = nets[s * NET_POINTS + k];
    } else {
        int at = -1 - s + 4 * k;
        point = dvec4(hier_reals[at], hier_reals[at + 1], hier_reals[at + 2], hier_reals[at + 3]);
    }
    return point;
}

// Have this invocation's loops all run their course? (false: llvmpipe's loop limiter ran out, the
// file's head) A loop of canary_turns turns that ends after one tells.
bool loops_whole() {
    int k = 0;
    while (k < canary_turns) k += 1;
    return k == canary_turns;
}

// Entry and exit distances of a ray (origin, inverse direction) into node's box.
dvec2 slab(int node, dvec3 o, dvec3 inv) {
    int b = off_node_bounds + 6 * node;
    double t1 = (hier_reals[b] - o.x) * inv.x, t2 = (hier_reals[b + 3] - o.x) * inv.x;
    double near = min(t1, t2), far = max(t1, t2);
    t1 = (hier_reals[b + 1] - o.y) * inv.y;
    t2 = (hier_reals[b + 4] - o.y) * inv.y;
    near = max(near, min(t1, t2));
    far = min(far, max(t1, t2));
    t1 = (hier_reals[b + 2] - o.z) * inv.z;
    t2 = (hier_reals[b + 5] - o.z) * inv.z;
    return dvec2(max(near, min(t1, t2)), min(far, max(t1, t2)));
}

// Entry and exit distances of a ray into leaf's oriented box.
dvec2 obb_slab(int leaf, dvec3 o, dvec3 d) {
    int b = off_leaf_obb + 15 * leaf;
    dvec3 r = o - dvec3(hier_reals[b], hier_reals[b + 1], hier_reals[b + 2]);
    double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
    double near = -INF, far = INF;
    for (int k = 0; k < 3; ++k) {
        double ax = hier_reals[b + 3 + 3 * k], ay = hier_reals[b + 4 + 3 * k], az = hier_reals[b + 5 + 3 * k];
        double oo = ax * r.x + ay * r.y + az * r.z;
        double dd = ax * d.x + ay * d.y + az * d.z;
        if (abs(dd) < 1e-300LF) dd = 1e-300LF;
        double half_ = hier_reals[b + 12 + k];
        double t1 = (-half_ - oo) / dd, t2 = (half_ - oo) / dd;
        near = max(near, min(t1, t2));
        far = min(far, max(t1, t2));
    }
    return dvec2(near, far);
}

// |cos| between the unit d and the normal of patch k at (u, v) below GRAZING_COSINE? (traverse._grazing)
bool grazing(int k, double u, double v, dvec3 d) {
    dvec3 S, Su, Sv;
    patch_frame(k, u, v, S, Su, Sv);
    dvec3 n = dvec3(Su.y * Sv.z - Su.z * Sv.y, Su.z * Sv.x - Su.x * Sv.z, Su.x * Sv.y - Su.y * Sv.x);
    double c = abs(n.x * d.x + n.y * d.y + n.z * d.z) / max(sqrt(n.x * n.x + n.y * n.y + n.z * n.z), 1e-300LF);
    return c < GRAZING_COSINE;
}

dvec3 net_point(int s, int i, int j) {
    dvec4 point = POINT(s, i, j);
    return point.xyz / point.w;
}

// Control point (i, j) of net source s across the ray (e1, e2), from o.
dvec2 across(int s, int i, int j, dvec3 o, dvec3 e1, dvec3 e2) {
    dvec3 r = net_point(s, i, j) - o;
    return dvec2(dot(e1, r), dot(e2, r));
}

// Does [lo, hi] come within reach of 0 (the ray, on an axis across it)?
bool holds_zero(double lo, double hi, double reach) {
    return lo <= reach && hi >= -reach;
}

// Can the ray meet the piece with net source s before t_far? Its control points in the ray's frame
// (e1, e2 across, d along) surround the ray within tol along e1, e2, the corners' normal seen across
// the ray and across each border chord (kernels/hulls.py, which says why).
bool straddles(int s, int p, int q, dvec3 o, dvec3 e1, dvec3 e2, dvec3 d, double t_min, double t_far, double tol) {
    double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
    dvec3 c = cross(net_point(s, p, q) - net_point(s, 0, 0), net_point(s, 0, q) - net_point(s, p, 0));
    double a = dot(e1, c), b = dot(e2, c);
    dvec2 k0 = across(s, 0, 0, o, e1, e2), k1 = across(s, p, 0, o, e1, e2);
    dvec2 k2 = across(s, p, q, o, e1, e2), k3 = across(s, 0, q, o, e1, e2);
    dvec2 n0 = dvec2(k0.y - k1.y, k1.x - k0.x), n1 = dvec2(k1.y - k2.y, k2.x - k1.x);  // each chord's normal
    dvec2 n2 = dvec2(k2.y - k3.y, k3.x - k2.x), n3 = dvec2(k3.y - k0.y, k0.x - k3.x);
    double xlo = INF, ylo = INF, zlo = INF, nlo = INF, xhi = -INF, yhi = -INF, zhi = -INF, nhi = -INF;
    dvec4 clo = dvec4(INF), chi = dvec4(-INF);
    for (int i = 0; i <= p; ++i) {
        for (int j = 0; j <= q; ++j) {
            dvec4 point = POINT(s, i, j);
            double w = point.w;
            double px = point.x / w - o.x, py = point.y / w - o.y, pz = point.z / w - o.z;
            double x = e1.x * px + e1.y * py + e1.z * pz;
            double y = e2.x * px + e2.y * py + e2.z * pz;
            double z = d.x * px + d.y * py + d.z * pz;
            xlo = min(xlo, x);
            xhi = max(xhi, x);
            ylo = min(ylo, y);
            yhi = max(yhi, y);
            zlo = min(zlo, z);
            zhi = max(zhi, z);
            nlo = min(nlo, a * x + b * y);
            nhi = max(nhi, a * x + b * y);
            dvec4 along = dvec4(n0.x * x + n0.y * y, n1.x * x + n1.y * y, n2.x * x + n2.y * y, n3.x * x + n3.y * y);
            clo = min(clo, along);
            chi = max(chi, along);
        }
    }
    return xlo <= tol && xhi >= -tol && ylo <= tol && yhi >= -tol && zhi + tol >= t_min && zlo - tol < t_far &&
           holds_zero(nlo, nhi, tol * sqrt(a * a + b * b)) && holds_zero(clo.x, chi.x, tol * length(n0)) &&
           holds_zero(clo.y, chi.y, tol * length(n1)) && holds_zero(clo.z, chi.z, tol * length(n2)) &&
           holds_zero(clo.w, chi.w, tol * length(n3));
}

// One half (which 0: the lower, 1: the upper) of net source src cut at its midpoint along axis 0 (u)
// or 1 (v) into slot dst: nets.split_half's de Casteljau steps, the four coordinates at once, the other half dropped.
void half_net(int src, int dst, int p, int q, int axis, int which) {
    int n = axis == 0 ? p : q, other = axis == 0 ? q : p;
    for (int j = 0; j <= other; ++j) {
        for (int i = 0; i <= n; ++i) tmp[i] = axis == 0 ? POINT(src, i, j) : POINT(src, j, i);
        for (int r = 0; r <= n; ++r) {
            if (r > 0) {
                for (int i = 0; i <= n - r; ++i) tmp[i] = 0.5LF * (tmp[i] + tmp[i + 1]);
            }
            int at = which == 0 ? r : n - r;
            if (axis == 0) {
                SLOT(dst, at, j) = tmp[which == 0 ? 0 : n - r];
            } else {
                SLOT(dst, j, at) = tmp[which == 0 ? 0 : n - r];
            }
        }
    }
}

// Quarter code (2 x the u half + the v half) of net source src into slot dst, through HALF (the four quarters' cut of
// traverse._solve_piece: u first, then v). half_too false: HALF already holds src's u half.
void quarter_net(int src, int dst, int p, int q, int code, bool half_too) {
    if (half_too) half_net(src, HALF, p, q, 0, code >> 1);
    half_net(HALF, dst, p, q, 1, code & 1);
}

// Does the ray from o (frame e1, e2) meet the piece with net source s at most once along its whole
// line? (crossings.crosses_once: the same arithmetic and rounding bound; the projected coefficients
// go to projected.) One flat loop over the pairs of differences, left by its condition (the file's
// head says why).
bool crosses_once(int s, int p, int q, dvec3 o, dvec3 e1, dvec3 e2) {
    double reach = 0.0LF;  // a bound on the coefficients' terms, for their rounding
    double ro = abs(o.x) + abs(o.y) + abs(o.z);
    for (int i = 0; i <= p; ++i) {
        for (int j = 0; j <= q; ++j) {
            dvec4 point = POINT(s, i, j);
            double w = point.w;
            precise double x = point.x - o.x * w, y = point.y - o.y * w, z = point.z - o.z * w;
            precise double gx = e1.x * x + e1.y * y + e1.z * z, gy = e2.x * x + e2.y * y + e2.z * z;
            projected[i * NET_QM + j] = dvec2(gx, gy);
            reach = max(reach, abs(point.x) + abs(point.y) + abs(point.z));
            reach = max(reach, ro * abs(w));
        }
    }
    // a difference of two coefficients is off by at most slack: a determinant counts only with its
    // sign beyond what that error can change
    double slack = 64.0LF * ROUNDING * reach;
    double sign = 0.0LF;
    bool once = true;
    int along_u = p * (q + 1), along_v = (p + 1) * q;
    for (int n = 0; once && n < along_u * along_v; ++n) {
        int a = n / along_v, b = n - a * along_v;  // the difference a along u, b along v
        int i = a / (q + 1), j = a - i * (q + 1), k = b / q, m = b - k * q;
        dvec2 g0 = projected[i * NET_QM + j], gu = projected[(i + 1) * NET_QM + j];
        dvec2 g1 = projected[k * NET_QM + m], gv = projected[k * NET_QM + m + 1];
        precise double ax = gu.x - g0.x, ay = gu.y - g0.y;
        precise double bx = gv.x - g1.x, by = gv.y - g1.y;
        precise double d = ax * by - ay * bx;
        precise double margin = slack * (abs(ax) + abs(ay) + abs(bx) + abs(by) + 2.0LF * slack);
        if (sign == 0.0LF) sign = d > 0.0LF ? 1.0LF : -1.0LF;
        once = d * sign > margin;
    }
    return once && sign != 0.0LF;
}

// Does the piece with net source s and parameter rectangle r hold (u, v), and does the ray's line cross
// it at most once? Then a root at (u, v) is the piece's only one (crossings.holds_once).
bool holds_once(int s, int p, int q, dvec4 r, double u, double v, dvec3 o, dvec3 e1, dvec3 e2) {
    return r.x <= u && u <= r.y && r.z <= v && v <= r.w && crosses_once(s, p, q, o, e1, e2);
}

// 0: not a hit; 1: a hit; 2: the excluded start root; 3: a root of the piece that is not a hit (_root_in).
// ex: the start root's (u, v, radius u, radius v) on surface ex_m.
int root_in(int m, dvec4 rect, bool kept, double u, double v, double t, double t_min, double t_max, int ex_m,
            dvec4 ex) {
    if (m == ex_m && abs(u - ex.x) <= ex.z && abs(v - ex.y) <= ex.w) return 2;
    double su = RECT_SLACK * (rect.y - rect.x);
    double sv = RECT_SLACK * (rect.w - rect.z);
    if (!(rect.x - su <= u && u <= rect.y + su && rect.z - sv <= v && v <= rect.w + sv)) return 0;
    if (!(t_min < t && t < t_max)) return 3;
#ifdef TRIM_TEST
    if (!(kept && rect.x <= u && u <= rect.y && rect.z <= v && v <= rect.w) && !trim_kept(m, u, v)) return 3;
#endif
    return 1;
}

// The valid root of piece leaf (net: its net's source, leaf_source; p, q its degrees) with t_min < t < t_far
// nearest the ray's origin, or with any_hit the first found (traverse._solve_piece: Newton from the
// centre, quarters where it found nothing or a grazing root, culled where their hull misses the ray
// or their one crossing is the start; a grazing nearest root takes one more Newton step, not with
// any_hit: it moves t, not the answer): found, best = (u, v, t, residual), best_k its patch.
// iterations: Newton's, added to.
bool piece_root(int leaf, int net, int p, int q, dvec3 o, dvec3 d, dvec3 e1, dvec3 e2, double t_min, double t_far,
                double tol, int max_iter, double cull_tol, int ex_m, dvec4 ex, bool any_hit, inout int iterations,
                out dvec4 best, out int best_k) {
    int m = hier_ints[off_leaf_surface + leaf];
    int at = off_leaf_rect + 4 * leaf;
    dvec4 rect = dvec4(hier_reals[at], hier_reals[at + 1], hier_reals[at + 2], hier_reals[at + 3]);
    bool kept = hier_ints[off_leaf_kept + leaf] != 0;
    double tol2 = tol * tol;
    dvec4 root;
    int k, its;
    bool ok;
    double c;
    solve_one(o, d, m, 0.5LF * (rect.x + rect.y), 0.5LF * (rect.z + rect.w), NEWTON, tol2, max_iter, true, root, k,
              ok, its, c);
    iterations += its;
    int state = ok ? root_in(m, rect, kept, root.x, root.y, root.z, t_min, t_far, ex_m, ex) : 0;
    bool found = state == 1;
    best = found ? root : dvec4(0.0LF, 0.0LF, packDouble2x32(uvec2(0u, 0x7ff00000u)), 0.0LF);
    best_k = found ? k : -1;
    double best_c = c;  // |cos| at the best root
    // the retries on quarters, depth-first (rectangles in rects, the net of the piece cut at depth d > 0
    // in slot d - 1 of nets); none after a root that is not grazing, a planar piece's only when its
    // centre start found nothing
    rects[0] = rect;
    depths[0] = 0;
    codes[0] = 0;
    bool retry = RETRY_DEPTH > 0 && !(found && any_hit) && (state == 0 || c < GRAZING_COSINE);
    int top = retry && (state == 0 || hier_ints[off_leaf_planar + leaf] == 0) ? 1 : 0;
    // the quarter tried next (of first .. first + 3; none yet), their depth, and their parent's net
    int s = 4, first = 0, dnext = 0, parent = net;
    while (!(found && any_hit) && (s < first + 4 || top > 0)) {  // one quarter, or one piece cut, per turn
        if (s < first + 4) {
            int code = s - first;
            quarter_net(parent, QUARTER, p, q, code, (code & 1) == 0);
            dvec4 sr = rects[s];
            // culled where the hull misses the ray, or where the quarter's one crossing is the start, excluded
            if (straddles(QUARTER, p, q, o, e1, e2, d, t_min, min(t_far, best.z), cull_tol) &&
                !(m == ex_m && holds_once(QUARTER, p, q, sr, ex.x, ex.y, o, e1, e2))) {
                solve_one(o, d, m, 0.5LF * (sr.x + sr.y), 0.5LF * (sr.z + sr.w), NEWTON, tol2, max_iter, true, root,
                          k, ok, its, c);
                iterations += its;
                state = ok ? root_in(m, rect, kept, root.x, root.y, root.z, t_min, t_far, ex_m, ex) : 0;
                if (state == 1 && root.z < best.z) {
                    found = true;
                    best = root;
                    best_k = k;
                    best_c = c;
                }
                // a root of this quarter: cut further only if it is grazing, not after a root that is not
                // a hit and is the quarter's only one
                bool again = state == 0 || (c < GRAZING_COSINE && !(state != 1 && holds_once(QUARTER, p, q, sr,
                                                                                           root.x, root.y, o, e1, e2)));
                if (again && dnext < RETRY_DEPTH) {  // keep it: move it down to the stack's top
                    rects[top] = sr;
                    codes[top] = code;
                    depths[top] = dnext;
                    top += 1;
                }
            }
            s += 1;
        } else {
            top -= 1;
            // quarters in slots top .. top + 3 (the kernels' cap: their nets in the scratch, two spare, one
            // for crosses_once)
            if (depths[top] < RETRY_DEPTH && top + 7 <= SCRATCH) {
                // its net, cut from its parent's (still in the slot of the depth above: the stack pops all
                // of a piece's quarters before anything pushed earlier; the leaf's in the buffer)
                int depth = depths[top];
                if (depth > 0) quarter_net(depth == 1 ? net : depth - 2, depth - 1, p, q, codes[top], true);
                parent = depth == 0 ? net : depth - 1;
                dvec4 r = rects[top];
                double um = 0.5LF * (r.x + r.y), vm = 0.5LF * (r.z + r.w);
                dnext = depths[top] + 1;
                rects[top] = dvec4(r.x, um, r.z, vm);
                rects[top + 1] = dvec4(r.x, um, vm, r.w);
                rects[top + 2] = dvec4(um, r.y, r.z, vm);
                rects[top + 3] = dvec4(um, r.y, vm, r.w);
                first = top;
                s = top;
            }
        }
    }
    if (found && !any_hit && best_c < GRAZING_COSINE) {
        // t of a grazing root is off by up to its residual / |cos|: one more Newton step takes the residual
        // down to rounding; kept if it is a valid root of this piece that near
        solve_one(o, d, m, best.x, best.y, NEWTON, 0.0LF, 2, true, root, k, ok, its, c);
        iterations += its;
        if (root.w < best.w && abs(root.z - best.z) * best_c <= 4.0LF * best.w &&
            root_in(m, rect, kept, root.x, root.y, root.z, t_min, t_far, ex_m, ex) == 1) {
            best = root;
            best_k = k;
        }
    }
    return found;
}

// Does piece leaf hold a valid root with 0 < t < t_max? (lighting._leaf_blocks: the oriented box,
// the hull, then piece_root's first root). iterations: Newton's, added to.
bool leaf_blocks(int leaf, dvec3 o, dvec3 d, dvec3 e1, dvec3 e2, double t_max, double tol, int max_iter,
                 double cull_tol, int ex_m, dvec4 ex, inout int iterations) {
    dvec2 span = obb_slab(leaf, o, d);
    if (!(span.x <= span.y && span.y >= 0.0LF && span.x <= t_max)) return false;
    int p = hier_ints[off_leaf_degree + 2 * leaf], q = hier_ints[off_leaf_degree + 2 * leaf + 1];
    int net = leaf_source(leaf);
    if (!straddles(net, p, q, o, e1, e2, d, 0.0LF, t_max, cull_tol)) return false;
    dvec4 root;
    int k;
    return piece_root(leaf, net, p, q, o, d, e1, e2, 0.0LF, t_max, tol, max_iter, cull_tol, ex_m, ex, true, iterations,
                      root, k);
}

// Any-hit shadow ray from o along the unit d with 0 < t < t_max (lighting.occluded): 1 blocked,
// 0 not, -2 not blocked within budget Newton iterations (taken as lit, counted as out of budget),
// -3 not found blocked before llvmpipe's loop limiter ran out (not settled: the file's head).
// ex_m, ex: the start root's surface and (u, v, radius u, radius v) (ex_m -1: none). iterations:
// Newton's, in all.
int occluded(dvec3 o, dvec3 d, double t_max, double tol, int max_iter, double cull_tol, int budget, int ex_m,
             dvec4 ex, out int iterations) {
    double sgn = d.z >= 0.0LF ? 1.0LF : -1.0LF;  // roots.ray_frame
    double fa = -1.0LF / (sgn + d.z);
    double fb = d.x * d.y * fa;
    dvec3 e1 = dvec3(1.0LF + sgn * d.x * d.x * fa, sgn * fb, -sgn * d.x);
    dvec3 e2 = dvec3(fb, sgn + d.y * d.y * fa, -d.y);
    bool skip_start = ex_m >= 0 && !grazing(locate_patch(ex_m, ex.x, ex.y), ex.x, ex.y, d);
    iterations = 0;
    dvec3 inv = dvec3(abs(d.x) > 1e-300LF ? 1.0LF / d.x : (d.x < 0.0LF ? -1e300LF : 1e300LF),
                      abs(d.y) > 1e-300LF ? 1.0LF / d.y : (d.y < 0.0LF ? -1e300LF : 1e300LF),
                      abs(d.z) > 1e-300LF ? 1.0LF / d.z : (d.z < 0.0LF ? -1e300LF : 1e300LF));
    dvec2 nf = slab(0, o, inv);
    if (!(nf.x <= nf.y && nf.y >= 0.0LF && nf.x <= t_max)) return 0;
    stack[0] = 0;
    int top = 1;
    int result = 0;
    int leaf = 0, leaf_stop = 0;  // the leaves of the tree leaf popped last, not yet tried
    while (result == 0 && (leaf < leaf_stop || top > 0)) {  // one leaf or one node per turn
        if (leaf < leaf_stop) {
            // the start's own leaf, skipped unless the ray leaves it grazing and may cross it more than once
            bool start = false;
            if (hier_ints[off_leaf_surface + leaf] == ex_m) {
                int at = off_leaf_rect + 4 * leaf;
                start = hier_reals[at] <= ex.x && ex.x <= hier_reals[at + 1] && hier_reals[at + 2] <= ex.y &&
                        ex.y <= hier_reals[at + 3];
            }
            if (start && !skip_start) {
                start = crosses_once(leaf_source(leaf), hier_ints[off_leaf_degree + 2 * leaf], hier_ints[off_leaf_degree + 2 * leaf + 1],
                                     o, e1, e2);
            }
            if (!start) {
                if (leaf_blocks(leaf, o, d, e1, e2, t_max, tol, max_iter, cull_tol, ex_m, ex, iterations)) {
                    result = 1;
                } else if (iterations >= budget) {
                    result = -2;
                }
            }
            leaf += 1;
        } else {
            top -= 1;
            int node = stack[top];
            int left = hier_ints[off_node_left + node];
            if (left < 0) {
                leaf = hier_ints[off_node_first + node];
                leaf_stop = leaf + hier_ints[off_node_count + node];
            } else {
                int right = hier_ints[off_node_right + node];
                dvec2 a = slab(left, o, inv), b = slab(right, o, inv);
                bool hit1 = a.x <= a.y && a.y >= 0.0LF && a.x <= t_max;
                bool hit2 = b.x <= b.y && b.y >= 0.0LF && b.x <= t_max;
                // both children (the farther pushed first), one, or none; a full stack drops what the CPU's drops
                int push = hit1 && hit2 && top + 2 <= STACK ? 2 : (hit1 || hit2 ? 1 : 0);
                stack[min(top, STACK - 1)] = push == 2 || !hit1 ? right : left;
                stack[min(top + 1, STACK - 1)] = left;
                top += push;
            }
        }
    }
    return !loops_whole() ? -3 : result;  // a blocker found after the limiter cut a loop short may be false
}
