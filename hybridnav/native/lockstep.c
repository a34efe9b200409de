/* hybridnav's compiled control cycle: the lockstep field simulation of EFFC controllers.
 *
 * One call simulates every (world, member) robot for the whole run: per control cycle the
 * nearest obstacle in the robot's own world (WorldStack's packed arrays), EFFC's inputs, the
 * robot's fuzzy system (a SystemFamily member's sampled tables, scikit-fuzzy's Mamdani
 * semantics with the upsampled centroid), the force blend, the model step (CasADi's generated
 * code for the model, linked in as hn_model_step) and the outcome tests. The arithmetic follows
 * hybridnav/planners/field/{lockstep,effc,worldstack}.py and hybridnav/fuzzy/family.py
 * operation for operation; sums run in another order than NumPy's, so results agree to
 * rounding. hn_family_eval is the fuzzy part alone (SystemFamily.evaluate).
 *
 * Compiled without -ffast-math and with -ffp-contract=off: IEEE semantics (NaN tests, no fused
 * multiply-add) as NumPy computes.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- fuzzy family ------------------------------------------------------------------------- */

typedef struct {
    int n_in;                  /* inputs */
    const int32_t *n_terms;    /* per input */
    const int32_t *n_pts;      /* per input: universe points */
    const double **xin;        /* per input: universe (n_pts) */
    const double **tin;        /* per input: table (K, terms, pts) */
    const double *inv;         /* per input: (pts - 1) / (hi - lo), 0 for a non-uniform grid */
    int T, M;                  /* output terms and points */
    const double *xout;        /* (M) */
    const double *dxh, *c1, *c2; /* (M - 1): dx / 2, dx x0 / 2, dx^2 / 6 */
    const double *wt, *wm;     /* (M): the trapezoid sums' weights of each sample */
    const double *tout;        /* (K, T, M) */
    const double *tmax;        /* (K, T): each output term's largest sample */
    int R;                     /* rules */
    const double *weights;     /* (K, R) */
    const int64_t *cons;       /* (K, R) output-term index */
    const int64_t *ante;       /* (K, R, n_in) term codes, or NULL: the template's program */
    const int32_t *prog;       /* per rule a postfix program (see family_native.py) */
    const int32_t *prog_start; /* (R + 1) offsets into prog */
    double default_out;
    /* (K, T, NB + 1) or NULL: per output term its number of turning samples n (or -1: scan it
     * sample by sample), then the n turning samples; between two of them (and the ends) the
     * term's samples never decrease or never increase */
    const int32_t *runs;
    int NB;
} hn_family;

enum { OP_TERM = 1, OP_NOT = 2, OP_AND = 3, OP_OR = 4 };
#define HN_MAX_IN 16
#define HN_MAX_TERMS 64
#define HN_MAX_STACK 64
#define HN_MAX_T 64


/* four doubles (GCC's vector extension: AVX where the clone has it, else SSE pairs) */
typedef double hn_v4 __attribute__((vector_size(32)));
typedef long long hn_v4i __attribute__((vector_size(32)));
static inline hn_v4 hn_load(const double *p) { hn_v4 v; memcpy(&v, p, sizeof v); return v; }
static inline void hn_store(double *p, hn_v4 v) { memcpy(p, &v, sizeof v); }
/* a < b ? a : b and a > b ? a : b lane by lane (np.minimum / np.maximum where no NaN) */
static inline hn_v4 hn_vmin(hn_v4 a, hn_v4 b)
{
    hn_v4i m = a < b;
    return (hn_v4)(((hn_v4i)a & m) | ((hn_v4i)b & ~m));
}
static inline hn_v4 hn_vmax(hn_v4 a, hn_v4 b)
{
    hn_v4i m = a > b;
    return (hn_v4)(((hn_v4i)a & m) | ((hn_v4i)b & ~m));
}

static double hn_maximum(double a, double b) { return (isnan(a) || isnan(b)) ? NAN : (b > a ? b : a); }

/* largest j with xs[j] <= v (searchsorted right - 1), xs[0] <= v <= xs[n - 1]. On a uniform
 * grid (inv = (n - 1) / (hi - lo) > 0) the guess (v - xs[0]) inv is off by at most a step or two
 * of rounding and is corrected against the samples; otherwise binary search. */
static int hn_interval(const double *xs, int n, double v, double inv)
{
    if (inv > 0) {
        double g = (v - xs[0]) * inv;
        int j = g >= (double)(n - 1) ? n - 1 : g > 0 ? (int)g : 0;
        while (j > 0 && xs[j] > v) --j;
        while (j < n - 1 && xs[j + 1] <= v) ++j;
        return j;
    }
    int lo = 0, hi = n;          /* first index with xs[i] > v */
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (xs[mid] <= v) lo = mid + 1; else hi = mid;
    }
    return lo - 1;
}

static double hn_rule(const hn_family *f, int r, const double *mu)
{
    double st[HN_MAX_STACK];
    int sp = 0;
    for (int p = f->prog_start[r]; p < f->prog_start[r + 1];) {
        int op = f->prog[p++];
        if (op == OP_TERM) {
            int i = f->prog[p++], j = f->prog[p++];
            st[sp++] = mu[i * HN_MAX_TERMS + j];
        } else if (op == OP_NOT) {
            st[sp - 1] = 1.0 - st[sp - 1];
        } else {
            int n = f->prog[p++];
            double acc = st[sp - n];
            for (int q = 1; q < n; ++q)
                acc = op == OP_AND ? fmin(acc, st[sp - n + q]) : fmax(acc, st[sp - n + q]);
            sp -= n;
            st[sp++] = acc;
        }
    }
    return st[0];
}

/* one sample of member k; x[i] in the family's input order */
__attribute__((target_clones("avx512f", "avx2", "default")))
static double hn_fuzzy(const hn_family *f, int64_t k, const double *x, double *work)
{
    double mu[HN_MAX_IN * HN_MAX_TERMS];
    for (int i = 0; i < f->n_in; ++i) {
        double v = x[i];
        if (isnan(v)) return NAN;
        const double *xs = f->xin[i];
        int n = f->n_pts[i], nt = f->n_terms[i];
        double xc = v < xs[0] ? xs[0] : v;            /* np.minimum(np.maximum(x, lo), hi) */
        xc = xc > xs[n - 1] ? xs[n - 1] : xc;
        int idx = hn_interval(xs, n, xc, f->inv[i]);
        if (idx > n - 2) idx = n - 2;
        double x0 = xs[idx];
        double frac = (xc - x0) / (xs[idx + 1] - x0);
        const double *tab = f->tin[i] + (size_t)k * nt * n;
        for (int j = 0; j < nt; ++j) {
            double y0 = tab[(size_t)j * n + idx], y1 = tab[(size_t)j * n + idx + 1];
            mu[i * HN_MAX_TERMS + j] = y0 + (y1 - y0) * frac;
        }
    }
    const int T = f->T, M = f->M, R = f->R;
    double cut[HN_MAX_T], c3[HN_MAX_T];
    int used[HN_MAX_T];
    for (int t = 0; t < T; ++t) { cut[t] = 0.0; used[t] = 0; }
    for (int r = 0; r < R; ++r) {
        double s;
        if (f->ante) {
            const int64_t *code = f->ante + ((size_t)k * R + r) * f->n_in;
            int any = 0;
            s = NAN;
            for (int i = 0; i < f->n_in; ++i) {
                int64_t c = code[i];
                int nt = f->n_terms[i];
                double v;
                if (c == 0) v = NAN;
                else if (c <= nt) v = mu[i * HN_MAX_TERMS + (c - 1)];
                else v = 1.0 - mu[i * HN_MAX_TERMS + (c - 1 - nt)];
                if (c != 0) any = 1;
                s = fmin(s, v);
            }
            if (!any) s = 1.0;
        } else {
            s = hn_rule(f, r, mu);
        }
        s *= f->weights[(size_t)k * R + r];
        if (isnan(s)) return NAN;          /* a NaN strength makes the output NaN */
        int t = (int)f->cons[(size_t)k * R + r];
        used[t] = 1;
        if (s > cut[t]) cut[t] = s;
    }
    for (int t = 0; t < T; ++t) {
        if (!used[t]) cut[t] = 0.0;
        c3[t] = (used[t] && cut[t] > 0) ? cut[t] : INFINITY;
    }
    const double *F = f->tout + (size_t)k * T * M;
    const double *xs = f->xout;
    double *A = work;
    /* max_m A[m] > 0 exactly when some term with a positive cut has a positive sample */
    int fires = 0;
    for (int t = 0; t < T; ++t) fires |= cut[t] > 0 && f->tmax[(size_t)k * T + t] > 0;
    if (!fires) return f->default_out;
    /* the aggregated curve on the grid (np.minimum / np.maximum: no NaN reaches here) and its
     * trapezoid sums, area sum_i dx (ya + yb) / 2 and moment sum_i (ya + yb) dx x0 / 2 +
     * (ya + 2 yb) dx^2 / 6, as dot products with per-sample weights (wt, wm: each sample's
     * share of its two intervals), in eight partial sums */
    double ta[8] = {0}, tm[8] = {0};
    const double *wt = f->wt, *wm = f->wm;
    int m = 0;
    {   /* lanes l and l + 4 of the two vectors are the partial sums l and l + 4 */
        hn_v4 ta0 = {0, 0, 0, 0}, ta1 = ta0, tm0 = ta0, tm1 = ta0;
        for (; m + 8 <= M; m += 8) {
            hn_v4 c0 = {cut[0], cut[0], cut[0], cut[0]};
            hn_v4 a0 = hn_vmin(hn_load(F + m), c0), a1 = hn_vmin(hn_load(F + m + 4), c0);
            for (int t = 1; t < T; ++t) {
                const double *Ft = F + (size_t)t * M + m;
                hn_v4 ct = {cut[t], cut[t], cut[t], cut[t]};
                a0 = hn_vmax(hn_vmin(hn_load(Ft), ct), a0);
                a1 = hn_vmax(hn_vmin(hn_load(Ft + 4), ct), a1);
            }
            hn_store(A + m, a0);
            hn_store(A + m + 4, a1);
            ta0 += a0 * hn_load(wt + m);
            ta1 += a1 * hn_load(wt + m + 4);
            tm0 += a0 * hn_load(wm + m);
            tm1 += a1 * hn_load(wm + m + 4);
        }
        for (int l = 0; l < 4; ++l) {
            ta[l] = ta0[l]; ta[l + 4] = ta1[l]; tm[l] = tm0[l]; tm[l + 4] = tm1[l];
        }
    }
    for (; m < M; ++m) {
        double a = F[m] < cut[0] ? F[m] : cut[0];
        for (int t = 1; t < T; ++t) {
            double v = F[(size_t)t * M + m] < cut[t] ? F[(size_t)t * M + m] : cut[t];
            a = v > a ? v : a;
        }
        A[m] = a;
        ta[0] += a * wt[m];
        tm[0] += a * wm[m];
    }
    const double *dxh = f->dxh, *c1 = f->c1, *c2 = f->c2;
    double total = ((ta[0] + ta[1]) + (ta[2] + ta[3])) + ((ta[4] + ta[5]) + (ta[6] + ta[7]));
    double moment = ((tm[0] + tm[1]) + (tm[2] + tm[3])) + ((tm[4] + tm[5]) + (tm[6] + tm[7]));
    /* scikit-fuzzy adds each used term's crossings of its positive cut level: on the
     * intervals holding one, the polyline through them replaces the trapezoid */
    int *hit = (int *)(work + M), nhit = 0;      /* intervals with a crossing (< M) */
    for (int t = 0; t < T; ++t) {
        const double c = c3[t], *Ft = F + (size_t)t * M;
        if (c == INFINITY) continue;
        const int32_t *rb = f->runs ? f->runs + ((size_t)k * T + t) * (f->NB + 1) : NULL;
        if (rb && rb[0] >= 0) {
            /* on a monotone run [a, b] the test F >= c changes at most once: where it does,
             * bisection finds it (the same intervals as the scan below) */
            for (int i = 0, a = 0; i <= rb[0]; ++i) {
                int b = i < rb[0] ? rb[1 + i] : M - 1;
                int pa = Ft[a] >= c;
                if (pa != (Ft[b] >= c)) {
                    int lo = a, hi = b;
                    while (hi - lo > 1) {
                        int mid = lo + (hi - lo) / 2;
                        if ((Ft[mid] >= c) == pa) lo = mid; else hi = mid;
                    }
                    int q = nhit;                   /* insert lo, sorted, once */
                    while (q > 0 && hit[q - 1] > lo) --q;
                    if (!(q > 0 && hit[q - 1] == lo)) {
                        memmove(hit + q + 1, hit + q, sizeof(int) * (nhit - q));
                        hit[q] = lo;
                        ++nhit;
                    }
                }
                a = b;
            }
            continue;
        }
        int prev = Ft[0] >= c;
        for (int m = 1; m < M; ++m) {
            if (m + 8 <= M) {                      /* skip blocks without a change */
                int same = 0;
                for (int l = 0; l < 8; ++l) same += (Ft[m + l] >= c) == prev;
                if (same == 8) { m += 7; continue; }
            }
            int cur = Ft[m] >= c;
            if (cur != prev) {
                int q = nhit;                       /* insert m - 1, sorted, once */
                while (q > 0 && hit[q - 1] > m - 1) --q;
                if (!(q > 0 && hit[q - 1] == m - 1)) {
                    memmove(hit + q + 1, hit + q, sizeof(int) * (nhit - q));
                    hit[q] = m - 1;
                    ++nhit;
                }
            }
            prev = cur;
        }
    }
    for (int h = 0; h < nhit; ++h) {
        int j = hit[h];
        double x0 = xs[j], x1 = xs[j + 1], dx = x1 - x0;
        double pts[HN_MAX_T + 2];
        int np_ = T + 2;
        pts[0] = x0;
        pts[T + 1] = x1;
        for (int t = 0; t < T; ++t) {
            double Fl = F[(size_t)t * M + j], Fr = F[(size_t)t * M + j + 1];
            int ct = (Fl >= c3[t]) != (Fr >= c3[t]);
            pts[1 + t] = ct ? x0 + (cut[t] - Fl) * dx / (Fr - Fl) : x0;
        }
        for (int p = 1; p < np_; ++p) {          /* insertion sort (np.sort) */
            double v = pts[p];
            int q = p - 1;
            while (q >= 0 && pts[q] > v) { pts[q + 1] = pts[q]; --q; }
            pts[q + 1] = v;
        }
        double ga = 0.0, fa = 0.0, fm = 0.0;
        for (int p = 0; p < np_; ++p) {
            double fr = (pts[p] - x0) / dx, g = 0.0;
            for (int t = 0; t < T; ++t) {
                double G0 = F[(size_t)t * M + j], G1 = F[(size_t)t * M + j + 1];
                double v = G0 + (G1 - G0) * fr;
                v = v < cut[t] ? v : cut[t];
                g = t == 0 ? v : (v > g ? v : g);
            }
            if (p > 0) {
                double xa = pts[p - 1], w = pts[p] - xa;
                fa += 0.5 * w * (ga + g);
                fm += w * (xa * (ga + g) / 2.0 + w * (ga + 2.0 * g) / 6.0);
            }
            ga = g;
        }
        double sj = A[j] + A[j + 1];
        total += fa - sj * dxh[j];
        moment += fm - (sj * c1[j] + (sj + A[j + 1]) * c2[j]);
    }
    return moment / fmax(total, DBL_EPSILON);
}

/* SystemFamily.evaluate: B samples, member[b], inputs x[i * B + b] */
int hn_family_eval(const hn_family *f, int64_t B, const int64_t *member, const double *x,
                    double *out)
{
    double xb[HN_MAX_IN];
    double *work = malloc(sizeof(double) * 2 * f->M);    /* the curve, then the hit list */
    if (!work) return -1;
    for (int64_t b = 0; b < B; ++b) {
        for (int i = 0; i < f->n_in; ++i) xb[i] = x[(size_t)i * B + b];
        out[b] = hn_fuzzy(f, member[b], xb, work);
    }
    free(work);
    return 0;
}

/* ---- packed worlds (WorldStack) ----------------------------------------------------------- */

typedef struct {
    int E, C, G, Ed, Kp;       /* worlds, circle / group / edge / obstacle-order columns */
    int moving;
    const double *c0, *cv, *cr;     /* (E, C, 2), (E, C, 2), (E, C) */
    const double *eA, *eB;          /* (E, Ed, 2) */
    const int64_t *owner;           /* (E, Ed) */
    const uint8_t *closed;          /* (E, G) */
    const int64_t *perm;            /* (E, Kp) column of obstacle k in [circles | groups | inf] */
    const uint8_t *has;             /* (E) */
    const double *ws;               /* (E, 4) */
    const int64_t *g_start;         /* (E, G + 1) edges of group g: [g_start[g], g_start[g + 1]) */
    int cells;                      /* cells per side of the candidate grid, 0: none */
    const double *cell_geo;         /* (E, 4) x0, y0, cells per unit x, per unit y */
    const int64_t *cell_off;        /* (E cells^2 + 1) offsets into cell_col */
    const int32_t *cell_col;        /* columns that can be nearest somewhere in the cell */
    const int32_t *kof;             /* (E, C + G) obstacle index (world order) of each column */
} hn_stack;

/* the candidate columns of the cell holding P (WorldStack.cells), or -1: search them all */
static int64_t hn_cell(const hn_stack *s, int64_t e, double px, double py)
{
    if (!s->cells) return -1;
    const double *g = s->cell_geo + 4 * (size_t)e;
    double fx = (px - g[0]) * g[2], fy = (py - g[1]) * g[3];
    if (!(fx >= 0.0 && fx < s->cells && fy >= 0.0 && fy < s->cells)) return -1;
    return ((int64_t)e * s->cells + (int64_t)fy) * s->cells + (int64_t)fx;
}

/* one group's signed distance at P and its nearest edge (first minimum): the minimum of its
 * edges' distances, negative inside a closed group (left of every edge) */
static void hn_group(const hn_stack *s, int64_t e, int g, double px, double py, double *D,
                     int *gedge, double *tmp_de, double *tmp_q)
{
    const int C = s->C, Ed = s->Ed;
    const int64_t *gs = s->g_start + (size_t)e * (s->G + 1);
    double crmin = INFINITY, amin = INFINITY;
    D[C + g] = INFINITY;
    gedge[g] = -1;
    for (int64_t j = gs[g]; j < gs[g + 1]; ++j) {
        size_t q = (size_t)e * Ed + j;
        double ax = s->eA[2 * q], ay = s->eA[2 * q + 1];
        double bx = s->eB[2 * q], by = s->eB[2 * q + 1];
        double abx = bx - ax, aby = by - ay, apx = px - ax, apy = py - ay;
        double den = abx * abx + aby * aby, num = apx * abx + apy * aby;
        double u = den > 0.0 ? num / den : 0.0;
        u = u < 0.0 ? 0.0 : u;
        u = u > 1.0 ? 1.0 : u;
        double qx = ax + u * abx, qy = ay + u * aby;
        /* sqrt(dx^2 + dy^2) is within two ulps of hypot (which NumPy calls): it settles the
         * edges far from the nearest, and only the others get hypot below */
        double dx = px - qx, dy = py - qy, a = sqrt(dx * dx + dy * dy);
        tmp_de[j] = a;
        tmp_q[2 * j] = qx;
        tmp_q[2 * j + 1] = qy;
        double cr = abx * apy - aby * apx;
        if (cr < crmin) crmin = cr;
        if (a < amin) amin = a;
    }
    for (int64_t j = gs[g]; j < gs[g + 1]; ++j) {
        double a = tmp_de[j];
        if (a > amin + 1e-12 * (1.0 + a + amin))
            continue;                  /* farther than the nearest by far more than rounding */
        double de = hypot(px - tmp_q[2 * j], py - tmp_q[2 * j + 1]);
        if (gedge[g] < 0 || de < D[C + g]) { D[C + g] = de; gedge[g] = (int)j; }
    }
    if (crmin > 0.0 && s->closed[(size_t)e * s->G + g]) D[C + g] = -D[C + g];
}

/* signed distance of every column (C + G + 1) of world e at P; for groups also the nearest edge
 * index (first minimum) */
static void hn_columns(const hn_stack *s, int64_t e, double px, double py, double t, double *D,
                       int *gedge, double *tmp_de, double *tmp_q)
{
    const int C = s->C, G = s->G, Ed = s->Ed;
    /* circles: sqrt(dx^2 + dy^2) is within two ulps of libm's hypot (which NumPy calls) at a
     * fraction of its cost, so it finds the few circles that can be nearest; only those get
     * hypot, and every distance that can be the minimum is NumPy's to the bit */
    double amin = INFINITY, dmin = 0.0;
    for (int c = 0; c < C; ++c) {
        size_t q = ((size_t)e * C + c);
        double cx = s->c0[2 * q], cy = s->c0[2 * q + 1];
        if (s->moving) { cx = cx + t * s->cv[2 * q]; cy = cy + t * s->cv[2 * q + 1]; }
        double dx = px - cx, dy = py - cy, d = sqrt(dx * dx + dy * dy);
        D[c] = d - s->cr[q];
        tmp_q[2 * (size_t)(Ed + c)] = d;
        if (D[c] < amin) { amin = D[c]; dmin = d; }
    }
    for (int c = 0; c < C; ++c) {
        double d = tmp_q[2 * (size_t)(Ed + c)];
        if (!(D[c] <= amin + 1e-12 * (1.0 + d + dmin)) && !isnan(amin) && amin != INFINITY)
            continue;                      /* farther than the nearest by far more than rounding */
        size_t q = ((size_t)e * C + c);
        double cx = s->c0[2 * q], cy = s->c0[2 * q + 1];
        if (s->moving) { cx = cx + t * s->cv[2 * q]; cy = cy + t * s->cv[2 * q + 1]; }
        double h = hypot(px - cx, py - cy);
        tmp_q[2 * (size_t)(Ed + c) + 1] = h;   /* the nearest point's normal reuses it */
        D[c] = h - s->cr[q];
    }
    for (int g = 0; g < G; ++g)            /* (padding edges belong to no group) */
        hn_group(s, e, g, px, py, D, gedge, tmp_de, tmp_q);
    D[C + G] = INFINITY;
}

/* WorldStack.nearest at one point: clearance, nearest surface point (NaN without obstacles) */
static double hn_nearest(const hn_stack *s, int64_t e, double px, double py, double t,
                         double *D, int *gedge, double *tmp_de, double *tmp_q,
                         double *nx, double *ny)
{
    *nx = NAN;
    *ny = NAN;
    if (!s->Kp || !s->has[e]) return INFINITY;
    int64_t cell = hn_cell(s, e, px, py);
    if (cell >= 0) {       /* only the columns that can be nearest here (all finite: P is) */
        const int C = s->C, CG = s->C + s->G;
        const int64_t i0 = s->cell_off[cell], i1 = s->cell_off[cell + 1];
        /* circles first by sqrt(dx^2 + dy^2) (within two ulps of hypot; its scale kept beside
         * it), groups exactly: only the candidates within rounding of the smallest get hypot */
        double amin = INFINITY, smin = 0.0;
        for (int64_t i = i0; i < i1; ++i) {
            int c = s->cell_col[i];
            double a, sc = 0.0;
            if (c < C) {
                size_t q = ((size_t)e * C + c);
                double dx = px - s->c0[2 * q], dy = py - s->c0[2 * q + 1];
                sc = sqrt(dx * dx + dy * dy);
                a = sc - s->cr[q];
                tmp_q[2 * (size_t)(s->Ed + c)] = sc;
            } else {
                hn_group(s, e, c - C, px, py, D, gedge, tmp_de, tmp_q);
                a = D[c];
            }
            D[c] = a;
            if (a < amin) { amin = a; smin = sc; }
        }
        int bcol = -1, bk = 0;
        double bd = INFINITY, bh = 0.0;
        for (int64_t i = i0; i < i1; ++i) {
            int c = s->cell_col[i], k = s->kof[(size_t)e * CG + c];
            double d = D[c], h = 0.0;
            if (c < C) {
                double sc = tmp_q[2 * (size_t)(s->Ed + c)];
                if (d > amin + 1e-12 * (1.0 + sc + smin))
                    continue;          /* farther than the nearest by far more than rounding */
                size_t q = ((size_t)e * C + c);
                h = hypot(px - s->c0[2 * q], py - s->c0[2 * q + 1]);
                d = h - s->cr[q];
            } else if (d > amin + 1e-12 * (1.0 + smin)) {
                continue;
            }
            if (bcol < 0 || d < bd || (d == bd && k < bk)) { bcol = c; bk = k; bd = d; bh = h; }
        }
        if (bcol < C) {
            size_t q = (size_t)e * C + bcol;
            double cx = s->c0[2 * q], cy = s->c0[2 * q + 1], ux = 1.0, uy = 0.0;
            if (bh != 0.0) { ux = (px - cx) / bh; uy = (py - cy) / bh; }
            *nx = cx + s->cr[q] * ux;
            *ny = cy + s->cr[q] * uy;
        } else {
            int j = gedge[bcol - C];
            if (j >= 0) { *nx = tmp_q[2 * j]; *ny = tmp_q[2 * j + 1]; }
        }
        return bd;
    }
    hn_columns(s, e, px, py, t, D, gedge, tmp_de, tmp_q);
    int best = 0;
    double bd = D[s->perm[(size_t)e * s->Kp]];
    for (int k = 1; k < s->Kp; ++k) {
        double d = D[s->perm[(size_t)e * s->Kp + k]];
        if (d < bd) { bd = d; best = k; }
    }
    int64_t col = s->perm[(size_t)e * s->Kp + best];
    if (col < s->C) {
        size_t q = (size_t)e * s->C + col;
        double cx = s->c0[2 * q], cy = s->c0[2 * q + 1];
        if (s->moving) { cx = cx + t * s->cv[2 * q]; cy = cy + t * s->cv[2 * q + 1]; }
        double dx = px - cx, dy = py - cy, ux = 1.0, uy = 0.0;
        double n = tmp_q[2 * (size_t)(s->Ed + col) + 1];     /* hypot(dx, dy) */
        if (n != 0.0) { ux = dx / n; uy = dy / n; }
        *nx = cx + s->cr[q] * ux;
        *ny = cy + s->cr[q] * uy;
    } else if (col < s->C + s->G) {
        int j = gedge[col - s->C];
        if (j >= 0) { *nx = tmp_q[2 * j]; *ny = tmp_q[2 * j + 1]; }
    }
    return bd;
}

static double hn_border(const hn_stack *s, int64_t e, double px, double py)
{
    const double *w = s->ws + 4 * (size_t)e;
    double dxa = px - w[0], dxb = w[1] - px, dya = py - w[2], dyb = w[3] - py;
    double dx_in = dxa < dxb ? dxa : dxb, dy_in = dya < dyb ? dya : dyb;
    double inside = dx_in < dy_in ? dx_in : dy_in;
    if (inside >= 0.0) return inside;
    double dx = -dx_in > 0.0 ? -dx_in : 0.0, dy = -dy_in > 0.0 ? -dy_in : 0.0;
    return -hypot(dx, dy);
}

/* ---- the EFFC lockstep run ---------------------------------------------------------------- */
#ifndef HN_NO_MODEL

typedef struct {
    int64_t N;                 /* robots: E * members */
    int nx, steps, window;
    double dt, speed, stuck_radius, foot_radius;
    double div_x, div_y;       /* carrot: X[:2] + V / div */
    const int64_t *env;        /* (N) */
    const int64_t *member;     /* (N) index into the population (noise) */
    int64_t repeats;           /* tables member = member / repeats */
    int in_dtheta, in_alpha;   /* positions of the inputs in the family's order */
    int in_clear;              /* position of the optional input clearance, or -1 */
    double safety, max_turn;   /* the escape-circle filter's margin (0: off), turn limit */
    double *X;                 /* (N, nx) in/out */
    const double *goals;       /* (N, 2) */
    const double *goal_r;      /* (N) */
    const int64_t *budget;     /* (N) steps */
    const double *radius;      /* (E) robot radius for alpha */
    const double *noise;       /* (3, E, Mtot, nsteps) or NULL */
    int64_t noise_members, noise_steps;
    int32_t *status;           /* (N) outcome codes */
    double *length, *t_end, *min_clear;
    double *paths;             /* (N, steps + 1, 2) or NULL */
    int field;                 /* HN_FIELD_EFFC (the family f) or HN_FIELD_APF (f unused) */
    double xi, sigma0, eta, rho0, force_tol;   /* APF's gains (apf.py) */
    const double *gains;       /* (members, 3): xi, eta, rho0 per member (PBPF), or NULL */
} hn_run;

enum { HN_FIELD_EFFC = 0, HN_FIELD_APF = 1 };

/* CasADi's generated model step (linked from the model's code) */
int hn_model_step(const double **arg, double **res, long long int *iw, double *w, int mem);
int hn_model_step_work(long long int *sz_arg, long long int *sz_res, long long int *sz_iw,
                       long long int *sz_w);

enum { RUNNING = 0, REACHED = 1, COLLIDED = 2, OUT_OF_BOUNDS = 3, STUCK = 4, TIMEOUT = 5 };

typedef struct {
    double *D, *tmp_de, *tmp_q;
    int *gedge;
    double *clear, *near;      /* (N), (N, 2): the nearest obstacle at the last check */
} hn_work;

static void hn_check(const hn_stack *s, const hn_run *r, hn_work *w, int64_t n, double t)
{
    const double *x = r->X + (size_t)n * r->nx;
    int64_t e = r->env[n];
    /* the nearest obstacle now: the clearance here, and the field's input at the next cycle
     * (same position, same time) */
    double c0 = hn_nearest(s, e, x[0], x[1], t, w->D, w->gedge, w->tmp_de, w->tmp_q,
                           &w->near[2 * n], &w->near[2 * n + 1]);
    w->clear[n] = c0;
    double clear = c0 - r->foot_radius;
    if (clear < r->min_clear[n] || isnan(clear)) r->min_clear[n] = clear;
    int inside = hn_border(s, e, x[0], x[1]) >= r->foot_radius;
    /* the squared distance settles all but the boundary case, where hypot decides */
    double gx = x[0] - r->goals[2 * n], gy = x[1] - r->goals[2 * n + 1], gr = r->goal_r[n];
    double g2 = gx * gx + gy * gy;
    int reached = g2 > gr * gr * (1.0 + 1e-9) ? 0 : hypot(gx, gy) <= gr;
    int code = clear < 0 ? COLLIDED : (!inside ? OUT_OF_BOUNDS : (reached ? REACHED : 0));
    if (code) { r->status[n] = code; r->t_end[n] = t; }
}

/* clearance of (qx, qy) in world e at time t: nearest obstacle or the border */
static double hn_clear_at(const hn_stack *s, hn_work *w, int64_t e, double qx, double qy,
                          double t)
{
    double nxp = 0.0, nyp = 0.0;
    double c = s->Kp ? hn_nearest(s, e, qx, qy, t, w->D, w->gedge, w->tmp_de, w->tmp_q, &nxp,
                                  &nyp) : INFINITY;
    double b = hn_border(s, e, qx, qy);
    return b < c || isnan(b) ? b : c;      /* np.minimum */
}

/* the escape filter's view of one robot's world (escape.c, prepended to this file) */
typedef struct { const hn_stack *s; hn_work *w; int64_t e; double t; } hn_clear_ctx;

static double hn_clear_cb(double qx, double qy, void *ctx)
{
    hn_clear_ctx *c = (hn_clear_ctx *)ctx;
    return hn_clear_at(c->s, c->w, c->e, qx, qy, c->t);
}

/* APF's force at robot n (apf.py's apf_lockstep field): the attraction, plus the repulsion of
 * every obstacle of its world whose footprint clearance is within rho0 (summed in the world's
 * obstacle order, as np.sum over the columns); NaN where the force is below force_tol xi sigma0
 * (a local minimum). The gains are the run's, or member n's row of r->gains (PBPF's search). */
static void hn_apf_field(const hn_stack *s, const hn_run *r, hn_work *w, int64_t n, double t,
                         double *Fx, double *Fy)
{
    const double *x = r->X + (size_t)n * r->nx;
    double px = x[0], py = x[1];
    int64_t e = r->env[n];
    double xi = r->xi, eta = r->eta, rho0 = r->rho0;
    if (r->gains) {
        const double *gm = r->gains + 3 * (size_t)r->member[n];
        xi = gm[0]; eta = gm[1]; rho0 = gm[2];
    }
    double Dx = px - r->goals[2 * n], Dy = py - r->goals[2 * n + 1];
    double dist = hypot(Dx, Dy);
    double scale = dist <= r->sigma0 ? xi : xi * r->sigma0 / (dist > 0 ? dist : 1.0);
    double fx = -scale * Dx, fy = -scale * Dy;
    if (s->Kp) {
        const int C = s->C, CG = s->C + s->G;
        double rad = r->radius[e], sx = 0.0, sy = 0.0;
        for (int k = 0; k < s->Kp; ++k) {
            int64_t col = s->perm[(size_t)e * s->Kp + k];
            if (col >= CG) continue;               /* padding: +inf, never within rho0 */
            double d, qx = 0.0, qy = 0.0;
            if (col < C) {
                size_t q = (size_t)e * C + col;
                double cx = s->c0[2 * q], cy = s->c0[2 * q + 1];
                if (s->moving) { cx = cx + t * s->cv[2 * q]; cy = cy + t * s->cv[2 * q + 1]; }
                double dx = px - cx, dy = py - cy;
                /* sqrt is within two ulps of hypot: far circles are settled without it */
                double sq = sqrt(dx * dx + dy * dy);
                if (!(sq - s->cr[q] - rad
                      <= rho0 + 1e-12 * (1.0 + sq + fabs(s->cr[q]) + fabs(rad) + rho0)))
                    continue;                       /* (NaN: never within rho0 either) */
                double h = hypot(dx, dy), ux = 1.0, uy = 0.0;
                d = h - s->cr[q];
                if (h != 0.0) { ux = dx / h; uy = dy / h; }
                qx = cx + s->cr[q] * ux;
                qy = cy + s->cr[q] * uy;
            } else {
                int g = (int)(col - C);
                hn_group(s, e, g, px, py, w->D, w->gedge, w->tmp_de, w->tmp_q);
                d = w->D[col];
                int j = w->gedge[g];
                if (j < 0) continue;                /* a group without edges: +inf */
                qx = w->tmp_q[2 * j];
                qy = w->tmp_q[2 * j + 1];
            }
            double rho = hn_maximum(d - rad, 1e-9);
            if (!(rho <= rho0)) continue;
            double mag = eta * (1.0 / rho - 1.0 / rho0) / (rho * rho);
            double ax = px - qx, ay = py - qy, norm = hypot(ax, ay);
            double dn = norm > 0 ? norm : 1.0;
            sx += mag * (ax / dn);
            sy += mag * (ay / dn);
        }
        fx = fx + sx;
        fy = fy + sy;
    }
    if (hypot(fx, fy) <= r->force_tol * xi * r->sigma0) { fx = NAN; fy = NAN; }
    *Fx = fx;
    *Fy = fy;
}

int hn_effc_run(const hn_family *f, const hn_stack *s, hn_run *r)
{
    const int64_t N = r->N;
    const int nx = r->nx, W = r->window;
    long long sz_arg, sz_res, sz_iw, sz_w;
    hn_model_step_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    const double **arg = malloc(sizeof(double *) * (sz_arg > 2 ? sz_arg : 2));
    double **res = malloc(sizeof(double *) * (sz_res > 1 ? sz_res : 1));
    long long *iw = malloc(sizeof(long long) * (sz_iw > 0 ? sz_iw : 1));
    double *mw = malloc(sizeof(double) * (sz_w > 0 ? sz_w : 1));
    int cols = s->C + s->G + 1;
    hn_work w;
    w.D = malloc(sizeof(double) * cols);
    w.gedge = malloc(sizeof(int) * (s->G + 1));
    w.tmp_de = malloc(sizeof(double) * (s->Ed + s->G + 1));
    w.tmp_q = malloc(sizeof(double) * 2 * (s->Ed + s->C + 1));
    w.clear = malloc(sizeof(double) * N);
    w.near = malloc(sizeof(double) * 2 * N);
    double *V = malloc(sizeof(double) * 2 * N);
    double *last = calloc(2 * N, sizeof(double));
    double *ring = W ? calloc((size_t)(W + 1) * N * 2, sizeof(double)) : NULL;
    double *xn = malloc(sizeof(double) * nx);
    double *fwork = malloc(sizeof(double) * 2 * (f ? f->M : 1));
    if (!arg || !res || !iw || !mw || !w.D || !w.gedge || !w.tmp_de || !w.tmp_q || !V || !last
        || (W && !ring) || !xn || !fwork || !w.clear || !w.near) {
        free(arg); free(res); free(iw); free(mw); free(w.D); free(w.gedge); free(w.tmp_de);
        free(w.tmp_q); free(V); free(last); free(ring); free(xn); free(fwork); free(w.clear); free(w.near);
        return -1;
    }
    for (int64_t n = 0; n < N; ++n) hn_check(s, r, &w, n, 0.0);
    int64_t last_noise = r->noise_steps - 1;
    double fx[HN_MAX_IN];
    for (int i = 0; i < HN_MAX_IN; ++i) fx[i] = 0.0;
    int k;
    for (k = 0; k < r->steps; ++k) {
        int64_t running = 0;
        for (int64_t n = 0; n < N; ++n) running += r->status[n] == RUNNING;
        if (!running) break;
        double t = k * r->dt;
        /* the field of every running robot */
        for (int64_t n = 0; n < N; ++n) {
            V[2 * n] = 0.0;
            V[2 * n + 1] = 0.0;
            if (r->status[n] != RUNNING) continue;
            if (r->field == HN_FIELD_APF) {
                hn_apf_field(s, r, &w, n, t, V + 2 * n, V + 2 * n + 1);
                continue;
            }
            const double *x = r->X + (size_t)n * nx;
            double px = x[0], py = x[1];
            int64_t e = r->env[n];
            double clear = w.clear[n], nxp = w.near[2 * n], nyp = w.near[2 * n + 1];
            double tgx = r->goals[2 * n] - px, tgy = r->goals[2 * n + 1] - py;
            double dg = hypot(tgx, tgy), dgs = dg > 0 ? dg : 1.0;
            double fax = tgx / dgs, fay = tgy / dgs;
            int none = isinf(clear);
            if (none) { nxp = px; nyp = py; }
            double ax = px - nxp, ay = py - nyp, dn = hypot(ax, ay), dns = dn > 0 ? dn : 1.0;
            double frx = ax / dns, fry = ay / dns;
            if (clear < 0) { frx *= -1.0; fry *= -1.0; }
            double ang = atan2(tgy, tgx) - atan2(-fry, -frx);
            double dtheta = fabs(atan2(sin(ang), cos(ang)));
            double dobs = hn_maximum(clear - r->radius[e], 0.0);
            double alpha = dobs / (dg > 0 ? dg : DBL_MIN);
            if (none) { dtheta = M_PI; alpha = INFINITY; frx = 0.0; fry = 0.0; }
            size_t nz = 0;
            if (r->noise) {
                int64_t i = k < last_noise ? k : last_noise;
                int64_t E = s->E, Mt = r->noise_members, S = r->noise_steps;
                nz = ((size_t)e * Mt + r->member[n]) * S + i;
                size_t plane = (size_t)E * Mt * S;
                dtheta = dtheta + r->noise[plane + nz];
                alpha = hn_maximum(alpha * (1.0 + r->noise[2 * plane + nz]), 0.0);
                if (!none) dobs = hn_maximum(dobs * (1.0 + r->noise[2 * plane + nz]), 0.0);
            }
            fx[r->in_dtheta] = dtheta;
            fx[r->in_alpha] = alpha;
            if (r->in_clear >= 0) fx[r->in_clear] = none ? INFINITY : dobs;
            double wgt = hn_fuzzy(f, r->member[n] / r->repeats, fx, fwork);
            double Fx = wgt * frx + (1.0 - wgt) * fax, Fy = wgt * fry + (1.0 - wgt) * fay;
            if (none) { Fx = fax; Fy = fay; }
            if (r->noise) {
                double a = r->noise[nz], c = cos(a), sn = sin(a);
                double gx = c * Fx - sn * Fy, gy = sn * Fx + c * Fy;
                Fx = gx;
                Fy = gy;
            }
            V[2 * n] = Fx;
            V[2 * n + 1] = Fy;
        }
        /* NaN: local minimum (stuck); zero: keep the last command; scale to the speed */
        for (int64_t n = 0; n < N; ++n) {
            double vx = V[2 * n], vy = V[2 * n + 1], norm = hypot(vx, vy);
            if (r->status[n] == RUNNING && isnan(norm)) { r->status[n] = STUCK; r->t_end[n] = t; }
            double sc = r->speed / (norm > 0 ? norm : 1.0);
            vx = vx * sc;
            vy = vy * sc;
            if (!(norm > 0)) { vx = last[2 * n]; vy = last[2 * n + 1]; }
            else { last[2 * n] = vx; last[2 * n + 1] = vy; }
            V[2 * n] = vx;
            V[2 * n + 1] = vy;
        }
        if (r->safety > 0) {
            hn_escape_params ep = {r->speed, r->dt, r->max_turn, r->safety, r->foot_radius};
            for (int64_t n = 0; n < N; ++n) {
                if (r->status[n] != RUNNING) continue;
                const double *x = r->X + (size_t)n * nx;
                double b = hn_border(s, r->env[n], x[0], x[1]), c = w.clear[n];
                hn_clear_ctx cc = {s, &w, r->env[n], t};
                hn_escape_filter(&ep, x[0], x[1], x[2], V + 2 * n, V + 2 * n + 1, hn_clear_cb,
                                 &cc, b < c || isnan(b) ? b : c);
            }
        }
        double tn = (k + 1) * r->dt;
        for (int64_t n = 0; n < N; ++n) {
            if (r->status[n] != RUNNING) continue;
            double *x = r->X + (size_t)n * nx;
            double tg[2] = {x[0] + V[2 * n] / r->div_x, x[1] + V[2 * n + 1] / r->div_y};
            arg[0] = x;
            arg[1] = tg;
            res[0] = xn;
            if (hn_model_step(arg, res, iw, mw, 0)) {
                free(arg); free(res); free(iw); free(mw); free(w.D); free(w.gedge);
                free(w.tmp_de); free(w.tmp_q); free(V); free(last); free(ring); free(xn); free(fwork); free(w.clear); free(w.near);
                return -2;
            }
            /* EFFC: sqrt, within an ulp of hypot (the tuner's results are the compiled cycle's);
             * APF: hypot, NumPy's lengths to the bit (PBPF ranks its members by them, and
             * near-tied members would be ordered by the rounding) */
            double ddx = xn[0] - x[0], ddy = xn[1] - x[1];
            r->length[n] += r->field == HN_FIELD_APF ? hypot(ddx, ddy)
                                                      : sqrt(ddx * ddx + ddy * ddy);
            memcpy(x, xn, sizeof(double) * nx);
            hn_check(s, r, &w, n, tn);
        }
        if (r->paths)
            for (int64_t n = 0; n < N; ++n) {
                double *p = r->paths + ((size_t)n * (r->steps + 1) + k + 1) * 2;
                p[0] = r->X[(size_t)n * nx];
                p[1] = r->X[(size_t)n * nx + 1];
            }
        if (W) {
            double *slot = ring + (size_t)((k + 1) % (W + 1)) * N * 2;
            for (int64_t n = 0; n < N; ++n) {
                slot[2 * n] = r->X[(size_t)n * nx];
                slot[2 * n + 1] = r->X[(size_t)n * nx + 1];
            }
            if (k + 1 >= W) {
                const double *oldest = ring + (size_t)((k + 2) % (W + 1)) * N * 2;
                for (int64_t n = 0; n < N; ++n) {
                    if (r->status[n] != RUNNING) continue;
                    double px = r->X[(size_t)n * nx], py = r->X[(size_t)n * nx + 1];
                    double gr = r->goal_r[n];
                    if (!(hypot(px - oldest[2 * n], py - oldest[2 * n + 1])
                          < 2 * r->stuck_radius * gr)) continue;
                    double mx = 0.0, my = 0.0;
                    for (int j = 0; j <= W; ++j) {
                        mx += ring[((size_t)j * N + n) * 2];
                        my += ring[((size_t)j * N + n) * 2 + 1];
                    }
                    mx /= (W + 1);
                    my /= (W + 1);
                    /* the largest squared distance settles the test unless it is within
                     * rounding of the threshold (or NaN): then hypot decides, as NumPy does */
                    double thr = r->stuck_radius * gr, m2 = 0.0;
                    for (int j = 0; j <= W; ++j) {
                        double dx = ring[((size_t)j * N + n) * 2] - mx;
                        double dy = ring[((size_t)j * N + n) * 2 + 1] - my;
                        double d2 = dx * dx + dy * dy;
                        if (!(d2 <= m2)) m2 = d2;     /* NaN sticks */
                    }
                    int stuck;
                    int sure = thr > 0.0 && thr < 1e150;
                    if (sure && m2 < thr * thr * (1.0 - 1e-9)) stuck = 1;
                    else if (sure && m2 > thr * thr * (1.0 + 1e-9)) stuck = 0;
                    else {
                        double span = -INFINITY;
                        for (int j = 0; j <= W; ++j) {
                            double d = hypot(ring[((size_t)j * N + n) * 2] - mx,
                                             ring[((size_t)j * N + n) * 2 + 1] - my);
                            if (d > span || isnan(d)) span = isnan(span) ? span : d;
                        }
                        stuck = span < thr;
                    }
                    if (stuck) { r->status[n] = STUCK; r->t_end[n] = tn; }
                }
            }
        }
        for (int64_t n = 0; n < N; ++n)
            if (r->status[n] == RUNNING && k + 1 >= r->budget[n]) {
                r->status[n] = TIMEOUT;
                r->t_end[n] = tn;
            }
    }
    free(arg); free(res); free(iw); free(mw); free(w.D); free(w.gedge); free(w.tmp_de);
    free(w.tmp_q); free(V); free(last); free(ring); free(xn); free(fwork); free(w.clear); free(w.near);
    return k;
}
#endif
