#include <math.h>

/* The box-to-box pruning test of hybridnav.planners.step.sweep._boxes_near: whether each
   obstacle box [olo, ohi] (K, 2), padded by opad, is closer than thr to each box [lo, hi] (M, 2).
   Operation for operation NumPy's (compiled with -ffp-contract=off): the gaps are
   np.maximum(np.maximum(a, b), 0.0), whose NaN propagates (a box with a NaN corner is near
   everything: here a flag), and near is !(gx*gx + gy*gy >= reach*reach) with reach = thr + opad. */

/* out is (K, M): obstacle by obstacle, so the loop over the boxes vectorizes */
void hn_boxes_near(long long M, long long K, const double *restrict lo,
                   const double *restrict hi, const double *restrict olo,
                   const double *restrict ohi, const double *restrict opad, double thr,
                   unsigned char *restrict out)
{
    for (long long k = 0; k < K; k++) {
        const double reach = thr + opad[k];
        const double r2 = reach * reach;
        const double olx = olo[2 * k], oly = olo[2 * k + 1];
        const double ohx = ohi[2 * k], ohy = ohi[2 * k + 1];
        unsigned char *restrict o = out + k * M;
        for (long long i = 0; i < M; i++) {
            double ax = olx - hi[2 * i], bx = lo[2 * i] - ohx;
            double ay = oly - hi[2 * i + 1], by = lo[2 * i + 1] - ohy;
            /* np.maximum propagates NaN: a NaN gap makes the sum NaN and the box near */
            int nan = (ax != ax) | (bx != bx) | (ay != ay) | (by != by);
            double gx = ax > bx ? ax : bx, gy = ay > by ? ay : by;
            gx = gx > 0.0 ? gx : 0.0;
            gy = gy > 0.0 ? gy : 0.0;
            o[i] = (unsigned char)(nan | !(gx * gx + gy * gy >= r2));
        }
    }
}

/* The box lo, hi (2 each) of the points row[k * s1 + j * s2 + {0, 1}] of samples k0..k1 (all
   m points): minima and maxima are exact; a NaN coordinate makes that coordinate of the box NaN,
   as np.min does. */
static inline void stretch_box(const double *restrict row, long long k0, long long k1,
                               long long s1, long long m, long long s2, double *restrict L,
                               double *restrict H)
{
    const double nan = __builtin_nan("");
    double lx = row[k0 * s1], ly = row[k0 * s1 + 1], hx = lx, hy = ly;
    int nx = 0, ny = 0;
    for (long long k = k0; k <= k1; k++) {
        const double *p = row + k * s1;
        for (long long j = 0; j < m; j++, p += s2) {
            const double x = p[0], y = p[1];
            nx |= x != x;
            ny |= y != y;
            lx = x < lx ? x : lx;
            hx = x > hx ? x : hx;
            ly = y < ly ? y : ly;
            hy = y > hy ? y : hy;
        }
    }
    L[0] = nx ? nan : lx;
    H[0] = nx ? nan : hx;
    L[1] = ny ? nan : ly;
    H[1] = ny ? nan : hy;
}

/* The boxes of hybridnav.planners.step.sweep._stretch_boxes: lo, hi (na, nst, 2) of the points
   pts[a, s, j, :] (na, n1, m, 2; element strides s0, s1, s2, the coordinates adjacent) of each
   stretch g, samples g * stride to min((g + 1) * stride, n1 - 1), all m points. */
void hn_stretch_boxes(long long na, long long n1, long long m, long long nst, long long stride,
                      const double *restrict pts, long long s0, long long s1, long long s2,
                      double *restrict lo, double *restrict hi)
{
    for (long long a = 0; a < na; a++) {
        for (long long g = 0; g < nst; g++) {
            long long k0 = g * stride, k1 = k0 + stride;
            if (k1 > n1 - 1)
                k1 = n1 - 1;
            stretch_box(pts + a * s0, k0, k1, s1, m, s2, lo + (a * nst + g) * 2,
                        hi + (a * nst + g) * 2);
        }
    }
}

/* Whether the box [lx, hx] x [ly, hy] comes within thr of the workspace border (xmin, xmax,
   ymin, ymax; a NaN corner is near it) or of one of the K obstacle boxes [olo, ohi] padded by
   opad, as hn_boxes_near tests each. */
static inline int near_box(double lx, double ly, double hx, double hy, double thr, double xmin,
                           double xmax, double ymin, double ymax, long long K,
                           const double *restrict olo, const double *restrict ohi,
                           const double *restrict opad)
{
    int near = !((lx - xmin >= thr) & (xmax - hx >= thr) & (ly - ymin >= thr)
                 & (ymax - hy >= thr));
    for (long long k = 0; k < K && !near; k++) {
        double reach = thr + opad[k];
        double ax = olo[2 * k] - hx, bx = lx - ohi[2 * k];
        double ay = olo[2 * k + 1] - hy, by = ly - ohi[2 * k + 1];
        int nan = (ax != ax) | (bx != bx) | (ay != ay) | (by != by);
        double gx = ax > bx ? ax : bx, gy = ay > by ? ay : by;
        gx = gx > 0.0 ? gx : 0.0;
        gy = gy > 0.0 ? gy : 0.0;
        near = nan | !(gx * gx + gy * gy >= reach * reach);
    }
    return near;
}

/* Whether anything may come within thr of each box [lo, hi] (M, 2): the workspace border
   (xmin, xmax, ymin, ymax; a NaN corner is near it) or one of the obstacle boxes, as
   hn_boxes_near; out (M) is `border | frozen.any(axis=-1)` of sweep._Sweep._near_each. */
void hn_near_any(long long M, const double *restrict lo, const double *restrict hi, double thr,
                 double xmin, double xmax, double ymin, double ymax, long long K,
                 const double *restrict olo, const double *restrict ohi,
                 const double *restrict opad, unsigned char *restrict out)
{
    for (long long i = 0; i < M; i++)
        out[i] = (unsigned char)near_box(lo[2 * i], lo[2 * i + 1], hi[2 * i], hi[2 * i + 1], thr,
                                         xmin, xmax, ymin, ymax, K, olo, ohi, opad);
}

/* Each footprint disk's box along a stretch and whether anything frozen may come near it: the
   disk centres C[i, k, j, :] (ns, n1, nd, 2; element strides s0, s1, s2, the coordinates
   adjacent) give, per stretch i and disk j, the box lo, hi (ns, nd, 2) of samples 0..n1-1
   (as hn_stretch_boxes) and near (ns, nd) as hn_near_any with the disk's threshold thr[j]. */
void hn_disks_near(long long ns, long long n1, long long nd, const double *restrict C,
                   long long s0, long long s1, long long s2, const double *restrict thr,
                   double xmin, double xmax, double ymin, double ymax, long long K,
                   const double *restrict olo, const double *restrict ohi,
                   const double *restrict opad, double *restrict lo, double *restrict hi,
                   unsigned char *restrict out)
{
    for (long long i = 0; i < ns; i++)
        for (long long j = 0; j < nd; j++) {
            double *L = lo + (i * nd + j) * 2, *H = hi + (i * nd + j) * 2;
            stretch_box(C + i * s0 + j * s2, 0, n1 - 1, s1, 1, s2, L, H);
            out[i * nd + j] = (unsigned char)near_box(L[0], L[1], H[0], H[1], thr[j], xmin,
                                                      xmax, ymin, ymax, K, olo, ohi, opad);
        }
}

/* The end of each move in one block of sweep._integrate: the rollout samples traj[a, k, :]
   (na, n1; element strides s0, s1, the position first) towards the targets P (na, 2) give the
   boxes lo, hi (na, nst, 2) of the positions along each stretch (as hn_stretch_boxes) and, for
   a row where one of those boxes comes within reach2 of its target (np.maximum's NaN: not
   within), first[a]: the first of the samples 1..n1-1 with hypot(x - px, y - py) <= reach, minus
   one; -1 where there is none. */
void hn_reach_first(long long na, long long n1, long long nst, long long stride,
                    const double *restrict traj, long long s0, long long s1,
                    const double *restrict P, double reach, double reach2,
                    double *restrict lo, double *restrict hi, long long *restrict first)
{
    const int far = reach > 1e-150 && reach < 1e150;
    const double far2 = reach * reach * (1.0 + 1e-9);
    for (long long a = 0; a < na; a++) {
        const double *row = traj + a * s0;
        const double px = P[2 * a], py = P[2 * a + 1];
        int close = 0;
        for (long long g = 0; g < nst; g++) {
            long long k0 = g * stride, k1 = k0 + stride;
            if (k1 > n1 - 1)
                k1 = n1 - 1;
            double *L = lo + (a * nst + g) * 2, *H = hi + (a * nst + g) * 2;
            stretch_box(row, k0, k1, s1, 1, 2, L, H);
            double ax = L[0] - px, bx = px - H[0], ay = L[1] - py, by = py - H[1];
            int nan = (ax != ax) | (bx != bx) | (ay != ay) | (by != by);
            double gx = ax > bx ? ax : bx, gy = ay > by ? ay : by;
            gx = gx > 0.0 ? gx : 0.0;
            gy = gy > 0.0 ? gy : 0.0;
            close |= !nan & (gx * gx + gy * gy <= reach2);
        }
        first[a] = -1;
        if (!close)
            continue;
        for (long long k = 1; k < n1; k++) {
            const double *p = row + k * s1;
            const double dx = p[0] - px, dy = p[1] - py;
            /* hypot (within an ulp of the distance) exceeds reach wherever the squares' sum
               (within a few ulps of its square) exceeds far2 = reach^2 (1 + 1e-9): asked only
               where it may not (an inf or NaN sum: hypot is inf or NaN too). Only for reach
               whose square is far from subnormal, where the sums' error is relative. */
            if (far && dx * dx + dy * dy > far2)
                continue;
            if (hypot(dx, dy) <= reach) {
                first[a] = k - 1;
                break;
            }
        }
    }
}

/* The pruning of sweep._Sweep.touches for pieces A -> B (M, 2 each): their boxes lo, hi (M, 2;
   np.minimum and np.maximum: a NaN coordinate gives NaN), whether each comes within thr of the
   workspace border, border (M), and of each obstacle box, out (K, M) as hn_boxes_near. */
void hn_pieces_near(long long M, const double *restrict A, const double *restrict B, double thr,
                    double xmin, double xmax, double ymin, double ymax, long long K,
                    const double *restrict olo, const double *restrict ohi,
                    const double *restrict opad, double *restrict lo, double *restrict hi,
                    unsigned char *restrict border, unsigned char *restrict out)
{
    const double nan = __builtin_nan("");
    for (long long i = 0; i < 2 * M; i++) {
        const double a = A[i], b = B[i];
        const int n = (a != a) | (b != b);
        lo[i] = n ? nan : a < b ? a : b;
        hi[i] = n ? nan : a > b ? a : b;
    }
    for (long long i = 0; i < M; i++)
        border[i] = (unsigned char)!((lo[2 * i] - xmin >= thr) & (xmax - hi[2 * i] >= thr)
                                     & (lo[2 * i + 1] - ymin >= thr)
                                     & (ymax - hi[2 * i + 1] >= thr));
    hn_boxes_near(M, K, lo, hi, olo, ohi, opad, thr, out);
}

/* ---- the exact swept-disk test against static obstacles (World.segment_collides) ---------- */

/* np.minimum / np.maximum: NaN if either is NaN */
static inline double np_min(double a, double b) { return (a != a || b != b) ? a + b : (a < b ? a : b); }
static inline double np_max(double a, double b) { return (a != a || b != b) ? a + b : (a > b ? a : b); }

/* geometry._project: the distance from P to the segment A-B, the same operations */
static inline double project(double px, double py, double ax, double ay, double bx, double by)
{
    const double abx = bx - ax, aby = by - ay, apx = px - ax, apy = py - ay;
    const double den = abx * abx + aby * aby, num = apx * abx + apy * aby;
    double s = den > 0.0 ? num / den : 0.0;
    s = s < 0.0 ? 0.0 : s;              /* np.clip: NaN stays NaN */
    s = s > 1.0 ? 1.0 : s;
    const double qx = ax + s * abx, qy = ay + s * aby;
    return hypot(px - qx, py - qy);
}

/* Whether the move A[i] -> B[i] (a disk of radius r) hits obstacle obs[i] of a static world:
 * World.singles()[obs[i]].segment_collides for each pair, the same IEEE operations (circles:
 * the centre's distance to the move minus the radius below r; segments and polygon edges: the
 * segment-segment distance below r or a proper crossing; closed polygons also Cyrus-Beck
 * through the interior). ccol[k]: circle column of obstacle k or -1; gcol[k]: its edge group. */
void hn_static_hits(long long M, const double *restrict A, const double *restrict B,
                    const long long *restrict obs, double r, const long long *restrict ccol,
                    const long long *restrict gcol, const double *restrict c0,
                    const double *restrict cr, const double *restrict eA,
                    const double *restrict eB, const long long *restrict gstart,
                    const unsigned char *restrict closed, unsigned char *restrict out)
{
    for (long long i = 0; i < M; i++) {
        const double ax = A[2 * i], ay = A[2 * i + 1], bx = B[2 * i], by = B[2 * i + 1];
        const long long k = obs[i];
        int hit = 0;
        if (ccol[k] >= 0) {
            const long long c = ccol[k];
            const double d = project(c0[2 * c], c0[2 * c + 1], ax, ay, bx, by);
            hit = d - cr[c] < r;
        } else {
            const long long g = gcol[k];
            const double dpx = bx - ax, dpy = by - ay;
            double lo = -__builtin_inf(), hi = __builtin_inf();
            int dead = 0;
            for (long long e = gstart[g]; e < gstart[g + 1]; e++) {
                const double qax = eA[2 * e], qay = eA[2 * e + 1];
                const double qbx = eB[2 * e], qby = eB[2 * e + 1];
                double d = np_min(np_min(project(ax, ay, qax, qay, qbx, qby),
                                         project(bx, by, qax, qay, qbx, qby)),
                                  np_min(project(qax, qay, ax, ay, bx, by),
                                         project(qbx, qby, ax, ay, bx, by)));
                const double dqx = qbx - qax, dqy = qby - qay;
                const double o1 = dpx * (qay - ay) - dpy * (qax - ax);
                const double o2 = dpx * (qby - ay) - dpy * (qbx - ax);
                const double o3 = dqx * (ay - qay) - dqy * (ax - qax);
                const double o4 = dqx * (by - qay) - dqy * (bx - qax);
                const int proper = (((o1 > 0) & (o2 < 0)) | ((o1 < 0) & (o2 > 0)))
                                   & (((o3 > 0) & (o4 < 0)) | ((o3 < 0) & (o4 > 0)));
                if (proper) d = 0.0;
                hit |= (d < r) | proper;
                if (closed[g]) {        /* _through_interior, edge by edge */
                    const double num = dqx * (ay - qay) - dqy * (ax - qax);
                    const double den = dqx * dpy - dqy * dpx;
                    const double root = -num / den;
                    lo = np_max(lo, den > 0 ? root : -__builtin_inf());
                    hi = np_min(hi, den < 0 ? root : __builtin_inf());
                    dead |= (den == 0) & (num <= 0);
                }
            }
            if (closed[g]) {
                lo = np_max(lo, 0.0);
                hi = np_min(hi, 1.0);
                hit |= (lo < hi) & !dead;
            }
        }
        out[i] = (unsigned char)hit;
    }
}
