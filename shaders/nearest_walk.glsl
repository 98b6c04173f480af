// The nearest-hit walk through Martin et al.'s hierarchy in float64 for
// compute shaders: a file that other shaders include (no #version here),
// after patches.glsl, trim64.glsl, solve_core.glsl and anyhit.glsl, whose
// includer declares the solve's uniforms shadow_tol, shadow_iterations,
// cull_tol and budget. A port of bsrt/kernels/traverse.py's trace_rays
// without any_hit (a depth-first walk, nearer child first, nodes entered
// beyond the nearest root so far skipped; per piece anyhit.glsl's
// piece_root, the same per-piece solve as the shadow rays'), written as
// anyhit.glsl's walk is: flat loops left by their conditions, a ray whose
// loops ran into llvmpipe's loop limiter answered -3 (not settled).
// nearest.glsl runs it on rays given in a buffer, bounce.glsl on the mirror
// rays of shade.glsl's hits.

double stack_t[STACK];  // the entry distance of each node on the walk's stack

// The nearest valid root of the ray o + t d (d unit), t_min < t < t_max: 1 (best = (u, v, t, residual),
// best_k its patch), 0 none, -3 not settled (llvmpipe's loop limiter ran out). iterations: Newton's;
// once budget is spent no further piece is solved (trace_rays's "Budget").
int nearest(dvec3 o, dvec3 d, double t_min, double t_max, int ex_m, dvec4 ex, out dvec4 best, out int best_k,
            out int iterations) {
    double INF = packDouble2x32(uvec2(0u, 0x7ff00000u));
    double sgn = d.z >= 0.0LF ? 1.0LF : -1.0LF;  // roots.ray_frame
    double fa = -1.0LF / (sgn + d.z);
    double fb = d.x * d.y * fa;
    dvec3 e1 = dvec3(1.0LF + sgn * d.x * d.x * fa, sgn * fb, -sgn * d.x);
    dvec3 e2 = dvec3(fb, sgn + d.y * d.y * fa, -d.y);
    dvec3 inv = dvec3(abs(d.x) > 1e-300LF ? 1.0LF / d.x : (d.x < 0.0LF ? -1e300LF : 1e300LF),
                      abs(d.y) > 1e-300LF ? 1.0LF / d.y : (d.y < 0.0LF ? -1e300LF : 1e300LF),
                      abs(d.z) > 1e-300LF ? 1.0LF / d.z : (d.z < 0.0LF ? -1e300LF : 1e300LF));
    best = dvec4(0.0LF, 0.0LF, INF, 0.0LF);
    best_k = -1;
    iterations = 0;
    // the start's leaf is skipped unless the ray leaves it grazing (trace_rays)
    bool skip_start = ex_m >= 0 && !grazing(locate_patch(ex_m, ex.x, ex.y), ex.x, ex.y, d);
    dvec2 nf = slab(0, o, inv);
    int top = 0;
    if (nf.x <= nf.y && nf.y >= t_min && nf.x <= t_max) {
        stack[0] = 0;
        stack_t[0] = nf.x;
        top = 1;
    }
    bool spent = false;
    int leaf = 0, leaf_stop = 0;  // the leaves of the tree leaf popped last, not yet tried
    while (!spent && (leaf < leaf_stop || top > 0)) {  // one leaf or one node per turn
        if (leaf < leaf_stop) {
            spent = iterations >= budget;
            bool start = false;
            if (skip_start && hier_ints[off_leaf_surface + leaf] == ex_m) {
                int at = off_leaf_rect + 4 * leaf;
                start = hier_reals[at] <= ex.x && ex.x <= hier_reals[at + 1] && hier_reals[at + 2] <= ex.y &&
                        ex.y <= hier_reals[at + 3];
            }
            dvec2 span = obb_slab(leaf, o, d);
            if (!spent && !start && span.x <= span.y && span.y >= t_min && span.x <= t_max && span.x < best.z) {
                int p = hier_ints[off_leaf_degree + 2 * leaf], q = hier_ints[off_leaf_degree + 2 * leaf + 1];
                double t_far = min(t_max, best.z);
                int net = leaf_source(leaf);
                if (straddles(net, p, q, o, e1, e2, d, t_min, t_far, cull_tol)) {
                    dvec4 root;
                    int k;
                    bool found = piece_root(leaf, net, p, q, o, d, e1, e2, t_min, t_far, shadow_tol, shadow_iterations,
                                            cull_tol, ex_m, ex, false, iterations, root, k);
                    if (found && root.z < best.z) {
                        best = root;
                        best_k = k;
                    }
                }
            }
            leaf += 1;
        } else {
            top -= 1;
            int node = stack[top];
            int left = hier_ints[off_node_left + node];
            if (stack_t[top] < best.z && left < 0) {
                leaf = hier_ints[off_node_first + node];
                leaf_stop = leaf + hier_ints[off_node_count + node];
            } else if (stack_t[top] < best.z) {
                int right = hier_ints[off_node_right + node];
                dvec2 a = slab(left, o, inv), b = slab(right, o, inv);
                bool hit1 = a.x <= a.y && a.y >= t_min && a.x <= t_max && a.x < best.z;
                bool hit2 = b.x <= b.y && b.y >= t_min && b.x <= t_max && b.x < best.z;
                // both children (the farther pushed first), one, or none; a full stack drops what the CPU's drops
                int push = hit1 && hit2 && top + 2 <= STACK ? 2 : (hit1 || hit2 ? 1 : 0);
                bool right_nearer = a.x > b.x;  // the nearer is pushed last: walked first
                int under = push == 2 ? (right_nearer ? left : right) : (hit1 ? left : right);
                stack[min(top, STACK - 1)] = under;
                stack_t[min(top, STACK - 1)] = under == left ? a.x : b.x;
                stack[min(top + 1, STACK - 1)] = right_nearer ? right : left;
                stack_t[min(top + 1, STACK - 1)] = right_nearer ? b.x : a.x;
                top += push;
            }
        }
    }
    return !loops_whole() ? -3 : (best_k >= 0 ? 1 : 0);
}
