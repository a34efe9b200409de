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

/* The boxes of hybridnav.planners.step.sweep._stretch_boxes: lo, hi (na, nst, 2) of the points
   pts[a, s, j, :] (na, n1, m, 2; element strides s0, s1, s2, the coordinates adjacent) of each
   stretch g, samples g * stride to min((g + 1) * stride, n1 - 1), all m points. Minima and maxima
   are exact; a NaN coordinate makes that coordinate of the box NaN, as np.min does. */
void hn_stretch_boxes(long long na, long long n1, long long m, long long nst, long long stride,
                      const double *restrict pts, long long s0, long long s1, long long s2,
                      double *restrict lo, double *restrict hi)
{
    const double nan = __builtin_nan("");
    for (long long a = 0; a < na; a++) {
        const double *row = pts + a * s0;
        for (long long g = 0; g < nst; g++) {
            long long k0 = g * stride, k1 = k0 + stride;
            if (k1 > n1 - 1)
                k1 = n1 - 1;
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
            double *L = lo + (a * nst + g) * 2, *H = hi + (a * nst + g) * 2;
            L[0] = nx ? nan : lx;
            H[0] = nx ? nan : hx;
            L[1] = ny ? nan : ly;
            H[1] = ny ? nan : hy;
        }
    }
}

/* Whether anything may come within thr of each box [lo, hi] (M, 2): the workspace border
   (xmin, xmax, ymin, ymax; a NaN corner is near it) or one of the obstacle boxes, as
   hn_boxes_near; out (M) is `border | frozen.any(axis=-1)` of sweep._Sweep._near_each. */
void hn_near_any(long long M, const double *restrict lo, const double *restrict hi, double thr,
                 double xmin, double xmax, double ymin, double ymax, long long K,
                 const double *restrict olo, const double *restrict ohi,
                 const double *restrict opad, unsigned char *restrict out)
{
    for (long long i = 0; i < M; i++) {
        const double lx = lo[2 * i], ly = lo[2 * i + 1], hx = hi[2 * i], hy = hi[2 * i + 1];
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
        out[i] = (unsigned char)near;
    }
}
