"""The fixed part of the generated C source: the static functions every export contains.

:func:`runtime` returns them for one prefix; :mod:`hybridnav.fuzzy.export.c` writes the tables,
the rule code and the plain-universe integral (``plain``) around them. The arithmetic follows
:class:`hybridnav.fuzzy.engine.CompiledSystem`'s scalar path operation for operation, so that the
C and Python evaluators agree to rounding; where every activation is tiny the direct polyline
centroid (``<p>_centroid_direct``, scikit-fuzzy's loop) is used, as the Python evaluator does.
"""

from __future__ import annotations

__all__ = ["runtime"]

_LOWER_BOUND = r"""
/* first k with lv[k] >= c (bisect_left) */
static int @p_lower_bound(const @p_real *lv, int n, @p_real c)
{
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (lv[mid] < c) lo = mid + 1; else hi = mid;
    }
    return lo;
}
"""

_TEMPLATE = r"""
/* NaN by its bits (exponent all ones, mantissa not zero): -ffast-math may drop a v != v test,
 * it cannot drop this one */
static int @p_isnan(@p_real v)
{
    union { @p_real r; uint32_t u32; uint64_t u64; } b;
    b.u64 = 0;
    b.r = v;
    if (sizeof v == sizeof(uint32_t))
        return (b.u32 & 0x7fffffffu) > 0x7f800000u;
    return (b.u64 & 0x7fffffffffffffffu) > 0x7ff0000000000000u;
}

static @p_real @p_min(@p_real a, @p_real b) { return b < a ? b : a; }
static @p_real @p_max(@p_real a, @p_real b) { return b > a ? b : a; }

/* largest j with x[j] <= v, for x[0] <= v <= x[m-1] (numpy's interval). On a uniform grid
 * (inv = (m - 1) / (hi - lo) > 0) the guess (v - lo) * inv is off by at most a step or two of
 * rounding and corrected against the samples; otherwise binary search. */
static int @p_interval(const @p_real *x, int m, @p_real v, @p_real lo, @p_real inv)
{
    int j, hi;
    if (inv > 0) {
        @p_real g = (v - lo) * inv;
        j = g >= (@p_real)(m - 1) ? m - 1 : g > 0 ? (int)g : 0;
        while (j > 0 && x[j] > v) --j;
        while (j < m - 1 && x[j + 1] <= v) ++j;
        return j;
    }
    if (v >= x[m - 1]) return m - 1;
    j = 0;
    hi = m - 1;
    while (hi - j > 1) {
        int mid = j + (hi - j) / 2;
        if (x[mid] <= v) j = mid; else hi = mid;
    }
    return j;
}

/* memberships of v in the nt terms of one input: np.interp with the precomputed slopes s
 * (f, s sample-major: entry j * nt + t), inputs outside the range count as its nearest end */
static void @p_fuzzify(@p_real v, const @p_real *x, const @p_real *f, const @p_real *s, int m,
                       int nt, @p_real lo, @p_real inv, @p_real *mu)
{
    int j, t;
    @p_real d;
    if (v < x[0]) v = x[0];
    if (v > x[m - 1]) v = x[m - 1];
    j = @p_interval(x, m, v, lo, inv);
    d = v - x[j];
    f += j * nt;
    s += j * nt;
    if (d == 0)
        for (t = 0; t < nt; ++t) mu[t] = f[t];
    else
        for (t = 0; t < nt; ++t) mu[t] = s[t] * d + f[t];
}

@lower_bound
/* the interval i in [a, b) where (f[i] >= c) != (f[i+1] >= c), or -1: f is monotone on a..b,
 * so the test flips at most once there (binary search) */
static int @p_flip(const @p_real *f, int a, int b, @p_real c)
{
    const int s = f[a] >= c;
    if ((f[b] >= c) == s) return -1;
    while (b - a > 1) {
        int mid = a + (b - a) / 2;
        if ((f[mid] >= c) == s) a = mid; else b = mid;
    }
    return a;
}

/* aggregated output max_t min(cut[t], f_t) at universe sample i */
static @p_real @p_agg(const @p_real cut[@P_N_OUT_TERMS], int i)
{
    @p_real y = 0;
    int t;
    for (t = 0; t < @P_N_OUT_TERMS; ++t)
        if (cut[t] > 0) y = @p_max(y, @p_min(cut[t], @p_out_f[t * @P_M + i]));
    return y;
}

/* skfuzzy's _interp_universe_fast for every positive cut: the points where a sampled term
 * crosses its cut, at most one per monotone run of a term, into ci (interval) and cp (position),
 * sorted by (interval, position); returns how many */
static int @p_crossings(const @p_real cut[@P_N_OUT_TERMS], int ci[@P_N_RUNS + 1],
                        @p_real cp[@P_N_RUNS + 1])
{
    int t, r, k, n = 0;
    const @p_real *x = @p_out_x;
    for (t = 0; t < @P_N_OUT_TERMS; ++t) {
        const @p_real c = cut[t], *f = @p_out_f + t * @P_M;
        if (!(c > 0)) continue;
        for (r = @p_out_run0[t]; r < @p_out_run0[t + 1]; ++r) {
            const int j = @p_flip(f, @p_out_runs[2 * r], @p_out_runs[2 * r + 1], c);
            @p_real p;
            if (j < 0) continue;
            p = x[j] + (c - f[j]) * (x[j + 1] - x[j]) / (f[j + 1] - f[j]);
            for (k = n; k > 0 && (ci[k - 1] > j || (ci[k - 1] == j && cp[k - 1] > p)); --k) {
                ci[k] = ci[k - 1];
                cp[k] = cp[k - 1];
            }
            ci[k] = j;
            cp[k] = p;
            ++n;
        }
    }
    return n;
}

/* skfuzzy's loop, used where every activation is tiny: the universe upsampled at the cut
 * crossings, max_t min(cut[t], term t) at every point, defuzz.centroid of that polyline (the
 * points are visited in order, one segment at a time: no array of the universe's size) */
static @p_real @p_centroid_direct(const @p_real cut[@P_N_OUT_TERMS])
{
    /* (+1 and zeros: compilers cannot see that n <= N_RUNS; -Os and sanitizers warn) */
    @p_real px[@P_N_RUNS + 1] = {0};
    int ci[@P_N_RUNS + 1] = {0};
    @p_real x1 = 0, y1 = 0, sum_ma = 0, sum_a = 0;
    int t, i, k, first = 1;
    const @p_real *x = @p_out_x;
    const int n = @p_crossings(cut, ci, px);  /* sorted by position: the intervals are */

    i = 0;
    k = 0;
    while (i < @P_M || k < n) {
        @p_real x2, y2 = 0;
        if (k >= n || (i < @P_M && x[i] <= px[k])) {
            x2 = x[i];
            y2 = @p_agg(cut, i);
            ++i;
        } else {
            int j = @p_interval(x, @P_M, px[k], 0, 0);
            @p_real d = px[k] - x[j];
            x2 = px[k];
            for (t = 0; t < @P_N_OUT_TERMS; ++t)
                if (cut[t] > 0) {
                    const @p_real *f = @p_out_f + t * @P_M, *s = @p_out_s + t * @P_M;
                    y2 = @p_max(y2, @p_min(cut[t], d == 0 ? f[j] : s[j] * d + f[j]));
                }
            ++k;
        }
        /* skfuzzy.defuzz.centroid, segment (x1, y1)-(x2, y2) */
        if (!first && !((y1 == y2 && y2 == 0) || x1 == x2)) {
            @p_real moment, area;
            if (y1 == y2) {
                moment = (@p_real)0.5 * (x1 + x2);
                area = (x2 - x1) * y1;
            } else if (y1 == 0 && y2 != 0) {
                moment = (@p_real)2.0 / (@p_real)3.0 * (x2 - x1) + x1;
                area = (@p_real)0.5 * (x2 - x1) * y2;
            } else if (y2 == 0 && y1 != 0) {
                moment = (@p_real)1.0 / (@p_real)3.0 * (x2 - x1) + x1;
                area = (@p_real)0.5 * (x2 - x1) * y1;
            } else {
                moment = (@p_real)2.0 / (@p_real)3.0 * (x2 - x1) * (y2 + (@p_real)0.5 * y1)
                         / (y1 + y2) + x1;
                area = (@p_real)0.5 * (x2 - x1) * (y1 + y2);
            }
            sum_ma += moment * area;
            sum_a += area;
        }
        x1 = x2;
        y1 = y2;
        first = 0;
    }
    return sum_ma / (sum_a > @P_EPS ? sum_a : @P_EPS);
}

/* centroid of max_t min(cut[t], term t) on skfuzzy's upsampled universe, from tables: the
 * plain-universe integral, then for every crossing point the triangle it adds to its interval;
 * moments are taken about the range's midpoint MID (rounding then scales with the range's width,
 * not with its distance from 0) */
static @p_real @p_defuzzify(const @p_real cut[@P_N_OUT_TERMS])
{
    @p_real area = 0, mom = 0, lx = 0, ly = 0, a1 = 0;
    @p_real cp[@P_N_RUNS + 1] = {0}, ca[@P_N_RUNS + 1] = {0};  /* (+1, zeros: see px above) */
    int ci[@P_N_RUNS + 1] = {0};
    int t, s, i, k, n, fired = 0;
    const @p_real *x = @p_out_x;

    for (t = 0; t < @P_N_OUT_TERMS; ++t)
        if (cut[t] > 0 && @p_out_positive[t]) fired = 1;
    if (!fired) return @P_DEFAULT;
@plain
    /* the crossing points, and the aggregated output at each (np.interp on its interval) */
    n = @p_crossings(cut, ci, cp);
    for (k = 0; k < n; ++k) {
        const int j = ci[k];
        const @p_real d = cp[k] - x[j];
        @p_real y = 0;
        for (s = 0; s < @P_N_OUT_TERMS; ++s)
            if (cut[s] > 0)
                y = @p_max(y, @p_min(@p_out_s[s * @P_M + j] * d + @p_out_f[s * @P_M + j], cut[s]));
        ca[k] = y;
    }
    /* inserting p (value ap) between (lx, ly) and the interval's right end (x1, a1) adds the
     * triangle (lx, 0), (p, ap - line(p)), (x1, 0) */
    for (k = 0; k < n; ++k) {
        @p_real x1, da;
        i = ci[k];
        if (k == 0 || ci[k - 1] != i) {
            lx = x[i];
            ly = @p_agg(cut, i);
            a1 = @p_agg(cut, i + 1);
        }
        x1 = x[i + 1];
        da = (@p_real)0.5 * ((x1 - lx) * ca[k] - (x1 - cp[k]) * ly - (cp[k] - lx) * a1);
        area += da;
        mom += da * ((lx - @P_MID) + (cp[k] - @P_MID) + (x1 - @P_MID)) * @P_THIRD;
        lx = cp[k];
        ly = ca[k];
    }
    if (area < @P_TINY) return @p_centroid_direct(cut);  /* the identities' rounding matters */
    return @P_MID + mom / (area > @P_EPS ? area : @P_EPS);
}
"""


def runtime(p: str, plain: str, *, subsets: bool) -> str:
    """The static C functions for prefix ``p``, with ``plain`` (the statements that set ``area``
    and ``mom`` to the plain-universe integral) inside ``<p>_defuzzify``.

    Parameters
    ----------
    p : str
        The lower-case prefix (a C identifier); macros use its upper case.
    plain : str
        C statements, indented by four spaces.
    subsets : bool
        Whether ``plain`` uses the subset tables (and so ``<p>_lower_bound``).

    Returns
    -------
    str
    """
    text = _TEMPLATE.replace("@lower_bound", _LOWER_BOUND.lstrip("\n") if subsets else "")
    return text.replace("@plain", plain).replace("@P", p.upper()).replace("@p", p)
