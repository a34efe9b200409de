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
