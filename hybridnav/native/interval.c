#include <float.h>
#include <math.h>

/* The interval evaluation of hybridnav.analysis.interval.IntervalFunction for programs of
   arithmetic and exact operations only (input, output, const, add, sub, mul, div, inv, neg,
   twice, assign, sq, sqrt, fabs, fmin, fmax, sign, floor, ceil, the comparisons, not, and, or,
   if_else_zero; no transcendental function):
   box by box, instruction by instruction, the same IEEE operations in the same order as the
   NumPy path (compiled with -ffp-contract=off, no fast math), so the same enclosures and flags.
   Every NumPy operation there is elementwise; this is that element's scalar code. np.minimum /
   np.maximum propagate NaN and return the second operand on ties, as min2 / max2 here. */

enum { I_INPUT, I_OUTPUT, I_CONST, I_ADD, I_SUB, I_MUL, I_DIV, I_INV, I_NEG, I_TWICE, I_ASSIGN,
       I_SQ, I_SQRT, I_FABS, I_FMIN, I_FMAX, I_SIGN, I_FLOOR, I_CEIL, I_LT, I_LE, I_EQ, I_NE,
       I_NOT, I_AND, I_OR, I_IF_ELSE_ZERO };

#define HN_EPS (4 * DBL_EPSILON)
#define HN_TINY 1e-300

static inline double min2(double a, double b)
{
    if (a != a) return a;
    if (b != b) return b;
    return a < b ? a : b;
}

static inline double max2(double a, double b)
{
    if (a != a) return a;
    if (b != b) return b;
    return a > b ? a : b;
}

/* _finite_ends */
static inline void finite_ends(double *l, double *h)
{
    if (*l == INFINITY) *l = DBL_MAX;
    if (*h == -INFINITY) *h = -DBL_MAX;
}

/* _widen */
static inline double widen_lo(double l)
{
    return (l != 0 && isfinite(l)) ? (l - HN_EPS * fabs(l)) - HN_TINY : l;
}

static inline double widen_hi(double h)
{
    return (h != 0 && isfinite(h)) ? (h + HN_EPS * fabs(h)) + HN_TINY : h;
}

/* _underflow of q = x * y (or x / y): its lower and upper bound */
static inline void underflow(double q, double x, double y, double *ql, double *qh)
{
    *ql = *qh = q;
    if (q == 0 && x != 0 && y != 0 && x == x && y == y) {
        if ((x < 0) != (y < 0)) *ql = -HN_TINY;
        else *qh = HN_TINY;
    }
}

/* _times: 0 * inf = 0 */
static inline double times(double x, double y)
{
    double p = x * y;
    if (p != p && (x == 0 || y == 0)) p = 0.0;
    return p;
}

/* _mul (its fast path is this element's slow path where no product is NaN or zero) */
static inline void mul(double a, double b, double c, double d, double *lo, double *hi)
{
    double l, h, l1, h1;
    underflow(times(a, c), a, c, &l, &h);
    underflow(times(a, d), a, d, &l1, &h1);
    l = min2(l, l1);
    h = max2(h, h1);
    underflow(times(b, c), b, c, &l1, &h1);
    l = min2(l, l1);
    h = max2(h, h1);
    underflow(times(b, d), b, d, &l1, &h1);
    *lo = min2(l, l1);
    *hi = max2(h, h1);
}

/* _inv */
static inline void inv(double a, double b, double *lo, double *hi)
{
    double ra = 1.0 / a, rb = 1.0 / b;
    int pn = (a > 0) | (b < 0);
    *lo = pn ? rb : ((a == 0 && b > 0) ? rb : -INFINITY);
    *hi = pn ? ra : ((b == 0 && a < 0) ? ra : INFINITY);
}

/* _truth: surely nonzero, surely zero */
static inline int sure_yes(double a, double b) { return (a > 0) | (b < 0); }
static inline int sure_no(double a, double b) { return (a == 0) & (b == 0); }

/* _compare's result: [1, 1] surely true, [0, 0] surely false, else [0, 1]; whether decided */
static inline int truth_interval(int yes, int no, double *rl, double *rh)
{
    *rl = yes ? 1.0 : 0.0;
    *rh = no ? 0.0 : 1.0;
    return yes | no;
}

static inline double sign1(double x)
{
    return x > 0 ? 1.0 : (x < 0 ? -1.0 : (x == 0 ? 0.0 : x));
}

static inline int positive(double a, unsigned char pos)
{
    return (a > 0) | ((a == 0) & (pos != 0));
}

/* One call: nbox boxes (lo, hi: nbox x nx), the program's n_ins instructions (op, in0, in1, out,
   konst; every slot written once), per-slot clamps (has_clamp, cl, ch) and open-bound flags
   (pos); the outputs out_lo, out_hi, smooth, cont (nbox x n_out). wl, wh (sz_w doubles) and
   flags (3 sz_w bytes: smooth, continuous, defined) are the workspace. */
void hn_interval(long long n_ins, const long long *restrict op, const long long *restrict in0,
                 const long long *restrict in1, const long long *restrict out,
                 const double *restrict konst, long long sz_w, long long nbox, long long nx,
                 long long n_out, const double *restrict lo, const double *restrict hi,
                 const unsigned char *restrict has_clamp, const double *restrict cl,
                 const double *restrict ch, const unsigned char *restrict pos,
                 double *restrict out_lo, double *restrict out_hi,
                 unsigned char *restrict smooth, unsigned char *restrict cont,
                 double *restrict wl, double *restrict wh, unsigned char *restrict flags)
{
    unsigned char *ws = flags, *wc = flags + sz_w, *wd = flags + 2 * sz_w;
    for (long long i = 0; i < nbox; i++) {
        for (long long k = 0; k < n_ins; k++) {
            const long long o = out[k], u = in0[k], v = in1[k];
            double rl, rh, a, b, c = 0, d = 0;
            int ok = 1, def, s, cf, binary = 0, exact_zero = 0, zero_exact = 1, exact = 0;
            int jumps = 0, pick = 0, left = 0, right = 0;
            switch (op[k]) {
            case I_INPUT:
                rl = lo[i * nx + u];
                rh = hi[i * nx + u];
                finite_ends(&rl, &rh);
                if (has_clamp[o]) {
                    rl = max2(rl, cl[o]);
                    rh = min2(rh, ch[o]);
                }
                wl[o] = rl;
                wh[o] = rh;
                ws[o] = wc[o] = wd[o] = 1;
                continue;
            case I_OUTPUT:
                /* u: the slot, o: the output's index */
                if (wd[u]) {
                    out_lo[i * n_out + o] = wl[u];
                    out_hi[i * n_out + o] = wh[u];
                    smooth[i * n_out + o] = ws[u];
                    cont[i * n_out + o] = wc[u];
                } else {
                    out_lo[i * n_out + o] = -INFINITY;
                    out_hi[i * n_out + o] = INFINITY;
                    smooth[i * n_out + o] = 0;
                    cont[i * n_out + o] = 0;
                }
                continue;
            case I_CONST:
                rl = rh = konst[k];
                finite_ends(&rl, &rh);
                wl[o] = rl;
                wh[o] = rh;
                ws[o] = wc[o] = wd[o] = 1;
                continue;
            default:
                break;
            }
            a = wl[u];
            b = wh[u];
            def = wd[u];
            s = ws[u];
            cf = wc[u];
            switch (op[k]) {
            case I_ADD:
                binary = 1;
                c = wl[v]; d = wh[v];
                rl = a + c;
                rh = b + d;
                break;
            case I_SUB:
                binary = 1;
                c = wl[v]; d = wh[v];
                rl = a - d;
                rh = b - c;
                break;
            case I_MUL:
                binary = 1;
                c = wl[v]; d = wh[v];
                mul(a, b, c, d, &rl, &rh);
                break;
            case I_DIV: {
                double il, ih;
                binary = 1;
                c = wl[v]; d = wh[v];
                inv(c, d, &il, &ih);
                finite_ends(&il, &ih);
                mul(a, b, il, ih, &rl, &rh);
                rl = widen_lo(rl);
                rh = widen_hi(rh);
                if (isfinite(a) && isfinite(b) && isfinite(c) && isfinite(d) && (c > 0 || d < 0)) {
                    double ql, qh, l1, h1;
                    underflow(a / c, a, c, &ql, &qh);
                    underflow(a / d, a, d, &l1, &h1);
                    ql = min2(ql, l1);
                    qh = max2(qh, h1);
                    underflow(b / c, b, c, &l1, &h1);
                    ql = min2(ql, l1);
                    qh = max2(qh, h1);
                    underflow(b / d, b, d, &l1, &h1);
                    rl = min2(ql, l1);
                    rh = max2(qh, h1);
                }
                def &= positive(c, pos[v]) | (d < 0);
                break;
            }
            case I_INV:
                inv(a, b, &rl, &rh);
                def &= positive(a, pos[u]) | (b < 0);
                zero_exact = 0;
                break;
            case I_NEG:
                rl = -b;
                rh = -a;
                exact = 1;
                break;
            case I_TWICE:
                rl = 2 * a;
                rh = 2 * b;
                zero_exact = 0;
                break;
            case I_ASSIGN:
                rl = a;
                rh = b;
                exact = 1;
                break;
            case I_SQ: {
                double pa = a * a, pb = b * b;
                int ua = (pa == 0) & (a != 0), ub = (pb == 0) & (b != 0);
                rl = (a <= 0 && b >= 0) ? 0.0 : min2(pa, pb);
                rh = max2(ua ? HN_TINY : pa, ub ? HN_TINY : pb);
                break;
            }
            case I_SQRT:
                rl = sqrt(max2(a, 0.0));
                rh = sqrt(max2(b, 0.0));
                if (b < 0) {
                    rl = -INFINITY;
                    rh = INFINITY;
                }
                ok = a > 0;
                def &= a >= 0;
                jumps = 1;
                zero_exact = 0;
                break;
            case I_FABS:
                rl = (a <= 0 && b >= 0) ? 0.0 : min2(fabs(a), fabs(b));
                rh = max2(fabs(a), fabs(b));
                ok = (a > 0) | (b < 0);
                exact = 1;
                break;
            case I_FMIN:
            case I_FMAX:
                binary = 1;
                c = wl[v]; d = wh[v];
                if (op[k] == I_FMIN) {
                    rl = min2(a, c);
                    rh = min2(b, d);
                    left = b < c;
                    right = d < a;
                } else {
                    rl = max2(a, c);
                    rh = max2(b, d);
                    left = a > d;
                    right = c > b;
                }
                ok = (b < c) | (d < a);
                exact = 1;
                pick = 1;
                break;
            case I_SIGN:
                rl = sign1(a);
                rh = sign1(b);
                ok = (a > 0) | (b < 0);
                exact = 1;
                jumps = 1;
                break;
            case I_FLOOR:
            case I_CEIL:
                rl = op[k] == I_FLOOR ? floor(a) : ceil(a);
                rh = op[k] == I_FLOOR ? floor(b) : ceil(b);
                ok = rl == rh;
                exact = 1;
                jumps = 1;
                break;
            case I_LT:
            case I_LE:
            case I_EQ:
            case I_NE: {
                int yes, no;
                binary = 1;
                c = wl[v]; d = wh[v];
                if (op[k] == I_LT) {
                    yes = b < c;
                    no = a >= d;
                } else if (op[k] == I_LE) {
                    yes = b <= c;
                    no = a > d;
                } else {
                    int same = (a == b) & (c == d) & (a == c), apart = (b < c) | (d < a);
                    yes = op[k] == I_EQ ? same : apart;
                    no = op[k] == I_EQ ? apart : same;
                }
                ok = truth_interval(yes, no, &rl, &rh);
                exact = 1;
                jumps = 1;
                break;
            }
            case I_NOT: {
                int yes = sure_yes(a, b), no = sure_no(a, b);
                rl = yes ? 0.0 : (no ? 1.0 : 0.0);
                rh = yes ? 0.0 : 1.0;
                ok = yes | no;
                exact = 1;
                jumps = 1;
                break;
            }
            case I_AND:
            case I_OR: {
                int y1, n1, y2, n2, one, zero;
                binary = 1;
                c = wl[v]; d = wh[v];
                y1 = sure_yes(a, b); n1 = sure_no(a, b);
                y2 = sure_yes(c, d); n2 = sure_no(c, d);
                if (op[k] == I_AND) {
                    one = y1 & y2;
                    zero = n1 | n2;
                } else {
                    one = y1 | y2;
                    zero = n1 & n2;
                }
                ok = truth_interval(one, zero, &rl, &rh);
                exact = 1;
                jumps = 1;
                break;
            }
            case I_IF_ELSE_ZERO: {
                binary = 1;
                c = wl[v]; d = wh[v];
                left = sure_yes(a, b);
                right = sure_no(a, b);
                rl = left ? c : (right ? 0.0 : min2(c, 0.0));
                rh = left ? d : (right ? 0.0 : max2(d, 0.0));
                ok = left | right;
                exact = 1;
                jumps = 1;
                pick = 2;
                break;
            }
            default:
                return;                                  /* not reached: filtered in Python */
            }
            if (rl != rl || rh != rh) {                  /* _apply: a NaN end is [-inf, inf] */
                rl = -INFINITY;
                rh = INFINITY;
                ok = 0;
            }
            finite_ends(&rl, &rh);
            if (binary) {
                /* a surely false condition gives 0 whatever the value (defined where the
                   condition is) */
                def = (pick == 2 && right && wd[u]) ? 1 : def & wd[v];
                s &= ws[v];
                cf &= wc[v];
            }
            s &= ok;
            if (jumps)
                cf &= ok;
            if (pick == 1) {                             /* fmin / fmax: the side it takes */
                s = left ? ws[u] : (right ? ws[v] : s);
                cf = left ? wc[u] : (right ? wc[v] : cf);
            } else if (pick == 2) {                      /* if_else_zero: the value, or 0 */
                s = left ? ws[v] : (right ? 1 : s);
                cf = left ? wc[v] : (right ? 1 : cf);
            }
            if (!exact) {                                /* _round_out */
                rl = widen_lo(rl);
                rh = widen_hi(rh);
                if (!zero_exact) {
                    exact_zero = (a == 0) | (b == 0);
                    if (binary) exact_zero |= (c == 0) | (d == 0);
                    if (rl == 0 && !exact_zero) rl = -HN_TINY;
                    if (rh == 0 && !exact_zero) rh = HN_TINY;
                }
            }
            if (has_clamp[o]) {
                rl = max2(rl, cl[o]);
                rh = min2(rh, ch[o]);
            }
            wl[o] = rl;
            wh[o] = rh;
            ws[o] = (unsigned char)s;
            wc[o] = (unsigned char)cf;
            wd[o] = (unsigned char)def;
        }
    }
}
