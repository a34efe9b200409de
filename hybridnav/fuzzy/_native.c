/* _native.c -- CompiledSystem.evaluate_scalar (hybridnav/fuzzy/engine.py) in C.
 *
 * One CPython extension module for every fuzzy system: an Evaluator holds one system's tables
 * (packed by hybridnav/fuzzy/_native.py from the engine's own lists) and repeats the Python
 * scalar path operation for operation, in the same order, so that (compiled with
 * -ffp-contract=off, IEEE double, no -ffast-math) its results are the Python path's bit for bit:
 * the same bisections, the same min/max comparisons (Python's min keeps the first of equal
 * values), the same left-to-right sums. Where the Python path leaves plain arithmetic (the
 * direct centroid when the aggregated area is tiny) or would order crossing points by a
 * comparison with NaN, evaluation answers "defer" and the caller uses the Python path.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#define HN_LAYOUT 1          /* the packing of _native.py this code reads */
#define HN_OP_AND 0
#define HN_OP_OR 1
#define HN_OP_NOT 2
#define HN_EPS 2.220446049250313e-16  /* numpy's finfo(float).eps */
#define HN_HEADER 16

typedef struct { Py_ssize_t M, nt, xs, F, S; } hn_in;          /* offsets into D */
typedef struct { Py_ssize_t op, n, kids; } hn_node;            /* kids: offset into I */
typedef struct { Py_ssize_t n, rules; } hn_cut;                /* rules: offset into I */
typedef struct { double sign; Py_ssize_t n, terms, L, lv, pq; } hn_sub;
typedef struct { Py_ssize_t L, levels, rows; } hn_cross;       /* rows: L + 2 row starts in I */

typedef struct {
    PyObject_HEAD
    Py_ssize_t n_in, K, n_prog, R, T, n_sub, M, N, n_mu;
    PyObject *names;          /* tuple of interned str: the keyword names, in input order */
    PyObject *f64;            /* numpy.float64 (the type evaluate returns) */
    int f64_direct;           /* numpy.float64 has float's layout: fill it in directly */
    double *D;
    int64_t *I;
    hn_in *in;
    hn_node *prog;
    hn_cut *cut;
    hn_sub *sub;
    hn_cross *cross;
    Py_ssize_t roots, weights, positive, xo, Fo, So, W;
    double dflt, tiny;
} hn_ev;

/* ------------------------------------------------------------------------------- evaluation */

/* bisect.bisect_left(a, x) */
static Py_ssize_t hn_bisect_left(const double *a, Py_ssize_t n, double x)
{
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (a[mid] < x) lo = mid + 1; else hi = mid;
    }
    return lo;
}

/* bisect.bisect_right(a, x) */
static Py_ssize_t hn_bisect_right(const double *a, Py_ssize_t n, double x)
{
    Py_ssize_t lo = 0, hi = n;
    while (lo < hi) {
        Py_ssize_t mid = (lo + hi) / 2;
        if (x < a[mid]) hi = mid; else lo = mid + 1;
    }
    return lo;
}

/* Python's min(a, b) and max(a, b): the first argument unless the second compares below
 * (above) it */
static double hn_min(double a, double b) { return b < a ? b : a; }
static double hn_max(double a, double b) { return b > a ? b : a; }

/* The output for inputs x (already floats). Returns 0 with *out set, or 1: defer to the Python
 * path (it computes the direct centroid, or orders NaN crossing points its own way). */
static int hn_evaluate(const hn_ev *e, const double *x, double *out)
{
    const double *D = e->D;
    const int64_t *I = e->I;
    const Py_ssize_t T = e->T, M = e->M;
    double mu[e->n_mu], strength[e->R], cuts[T];
    Py_ssize_t live[T], n_live = 0;
    double px[e->N + 1], pa[e->N + 1];
    Py_ssize_t pi[e->N + 1], order[e->N + 1];
    char done[e->N + 1];
    Py_ssize_t i, t, n, k = 0, n_pts = 0;
    double area = 0.0, mom = 0.0;
    const double *xs = D + e->xo, *Fo = D + e->Fo, *So = D + e->So;

    /* inputs: NaN -> NaN; clip; np.interp by the precomputed slopes */
    for (i = 0; i < e->n_in; ++i) {
        const hn_in *p = &e->in[i];
        const double *ix = D + p->xs;
        const double *F, *S;
        double v = x[i], d;
        Py_ssize_t j;
        if (v != v) { *out = v; return 0; }
        v = v < ix[0] ? ix[0] : v > ix[p->M - 1] ? ix[p->M - 1] : v;
        j = hn_bisect_right(ix, p->M, v) - 1;
        d = v - ix[j];
        F = D + p->F + j * p->nt;
        S = D + p->S + j * p->nt;
        for (t = 0; t < p->nt; ++t) mu[k++] = S[t] * d + F[t];
    }
    /* antecedent nodes: min / max of the children (first of equals), 1 - x */
    for (n = 0; n < e->n_prog; ++n) {
        const hn_node *q = &e->prog[n];
        const int64_t *kid = I + q->kids;
        double r = mu[kid[0]];
        Py_ssize_t c;
        if (q->op == HN_OP_NOT)
            r = 1.0 - r;
        else if (q->op == HN_OP_AND)
            for (c = 1; c < q->n; ++c) r = hn_min(r, mu[kid[c]]);
        else
            for (c = 1; c < q->n; ++c) r = hn_max(r, mu[kid[c]]);
        mu[k++] = r;
    }
    for (n = 0; n < e->R; ++n) strength[n] = mu[I[e->roots + n]] * D[e->weights + n];
    for (t = 0; t < T; ++t) {
        const int64_t *r = I + e->cut[t].rules;
        double c = strength[r[0]];
        for (n = 1; n < e->cut[t].n; ++n) c = hn_max(c, strength[r[n]]);
        cuts[t] = c;
    }

    /* _defuzz_scalar */
    for (t = 0; t < T; ++t) if (cuts[t] > 0.0) live[n_live++] = t;
    for (n = 0; n < n_live; ++n) if (I[e->positive + live[n]]) break;
    if (n == n_live) { *out = e->dflt; return 0; }
    if (e->n_sub) {
        for (n = 0; n < e->n_sub; ++n) {
            const hn_sub *s = &e->sub[n];
            const int64_t *st = I + s->terms;
            double c = cuts[st[0]];
            Py_ssize_t m;
            for (m = 1; m < s->n; ++m) c = hn_min(c, cuts[st[m]]);
            if (c > 0.0) {
                const double *pq = D + s->pq;   /* Pa, Pm, Qa, Qm: L + 1 each */
                const Py_ssize_t L1 = s->L + 1;
                k = hn_bisect_left(D + s->lv, s->L, c);
                area += s->sign * (pq[k] + c * pq[2 * L1 + k]);
                mom += s->sign * (pq[L1 + k] + c * pq[3 * L1 + k]);
            }
        }
    } else {
        /* A = max over live terms of min(f_t, c_t), term by term as np.minimum/np.maximum;
         * (area, moment) = cumsum(W * A)[:, -1]: sequential sums from the first product */
        const double *W = D + e->W, *f = Fo + live[0] * M;
        double A[M], c = cuts[live[0]];
        Py_ssize_t j;
        for (j = 0; j < M; ++j) A[j] = hn_min(f[j], c);
        for (n = 1; n < n_live; ++n) {
            f = Fo + live[n] * M;
            c = cuts[live[n]];
            for (j = 0; j < M; ++j) A[j] = hn_max(A[j], hn_min(f[j], c));
        }
        for (j = 0; j < M; ++j) {
            if (j == 0) {
                area = W[0] * A[0];
                mom = W[M] * A[0];
            } else {
                area += W[j] * A[j];
                mom += W[M + j] * A[j];
            }
        }
    }
    /* crossing points, generated term by term as the Python path does */
    for (t = 0; t < T; ++t) {
        const double c = cuts[t];
        const hn_cross *cr = &e->cross[t];
        const int64_t *row;
        Py_ssize_t r0, r1;
        if (!(c > 0.0)) continue;
        k = hn_bisect_left(D + cr->levels, cr->L, c);
        row = I + cr->rows;
        r0 = (Py_ssize_t)row[k];
        r1 = (Py_ssize_t)row[k + 1];
        for (; r0 < r1; ++r0) {
            const Py_ssize_t j = (Py_ssize_t)I[r0];
            const double *f = Fo + t * M;
            const double x0 = xs[j];
            const double p = x0 + (c - f[j]) * (xs[j + 1] - x0) / (f[j + 1] - f[j]);
            const double d = p - x0;
            double ap = 0.0;
            for (n = 0; n < n_live; ++n) {
                const Py_ssize_t s = live[n];
                const double v = hn_min(So[s * M + j] * d + Fo[s * M + j], cuts[s]);
                ap = n == 0 ? v : hn_max(ap, v);
            }
            pi[n_pts] = j;
            px[n_pts] = p;
            pa[n_pts] = ap;
            done[n_pts] = 0;
            ++n_pts;
        }
    }
    /* per interval, in the order of first appearance (the Python dict's), points sorted by
     * (position, generation order): the triangles they add */
    for (n = 0; n < n_pts; ++n) {
        Py_ssize_t g = 0, m, a;
        double x1, lx, ly, a1;
        if (done[n]) continue;
        i = pi[n];
        for (m = n; m < n_pts; ++m)
            if (pi[m] == i) { done[m] = 1; order[g++] = m; }
        if (g > 1) {
            for (m = 0; m < g; ++m) if (px[order[m]] != px[order[m]]) return 1;
            for (m = 1; m < g; ++m) {             /* stable insertion sort by position */
                const Py_ssize_t v = order[m];
                for (a = m; a > 0 && px[v] < px[order[a - 1]]; --a) order[a] = order[a - 1];
                order[a] = v;
            }
        }
        x1 = xs[i + 1];
        lx = xs[i];
        ly = a1 = 0.0;
        for (m = 0; m < n_live; ++m) {
            const Py_ssize_t s = live[m];
            const double v0 = hn_min(Fo[s * M + i], cuts[s]);
            const double v1 = hn_min(Fo[s * M + i + 1], cuts[s]);
            ly = m == 0 ? v0 : hn_max(ly, v0);
            a1 = m == 0 ? v1 : hn_max(a1, v1);
        }
        for (m = 0; m < g; ++m) {
            const double p = px[order[m]], ap = pa[order[m]];
            const double da = 0.5 * ((x1 - lx) * ap - (x1 - p) * ly - (p - lx) * a1);
            area += da;
            mom += da * (lx + p + x1) * (1.0 / 3.0);
            lx = p;
            ly = ap;
        }
    }
    if (area < e->tiny) return 1;                   /* all activations tiny: the direct path */
    *out = mom / hn_max(area, HN_EPS);
    return 0;
}

/* -------------------------------------------------------------------------------- Python API */

static PyObject *hn_float64(const hn_ev *e, double r)
{
    PyObject *o, *f;
    if (e->f64_direct) {
        /* what numpy's own PyArrayScalar_New + PyArrayScalar_ASSIGN do: numpy.float64 is a
         * float subclass with float's layout (checked when the evaluator was made) */
        PyTypeObject *tp = (PyTypeObject *)e->f64;
        o = tp->tp_alloc(tp, 0);
        if (o) ((PyFloatObject *)o)->ob_fval = r;
        return o;
    }
    f = PyFloat_FromDouble(r);
    if (!f) return NULL;
    o = PyObject_CallOneArg(e->f64, f);
    Py_DECREF(f);
    return o;
}

/* float(v) for a float or an int (also subclasses, as Python's float() converts them);
 * 1 if v is neither, -1 on error (an int too large) */
static int hn_as_double(PyObject *v, double *x)
{
    if (PyFloat_CheckExact(v)) { *x = PyFloat_AS_DOUBLE(v); return 0; }
    if (PyLong_CheckExact(v)) {
        *x = PyLong_AsDouble(v);
        return *x == -1.0 && PyErr_Occurred() ? -1 : 0;
    }
    if (PyFloat_Check(v) || PyLong_Check(v)) {
        PyObject *f = PyNumber_Float(v);
        if (!f) return -1;
        *x = PyFloat_AS_DOUBLE(f);
        Py_DECREF(f);
        return 0;
    }
    return 1;
}

PyDoc_STRVAR(hn_kw_doc,
"kw(inputs, /)\n--\n\n"
"evaluate(**inputs) for a dict holding exactly the input names, each a float or an int:\n"
"numpy.float64. None for anything else (other keys, arrays), or where the Python path decides\n"
"(a tiny aggregated area).");

static PyObject *hn_kw(hn_ev *e, PyObject *d)
{
    PyObject *vals[e->n_in];
    double x[e->n_in], r;
    Py_ssize_t i, j;
    if (!PyDict_Check(d) || PyDict_GET_SIZE(d) != e->n_in) Py_RETURN_NONE;
    for (i = 0; i < e->n_in; ++i) {
        vals[i] = PyDict_GetItemWithError(d, PyTuple_GET_ITEM(e->names, i));  /* borrowed */
        if (!vals[i]) {
            if (PyErr_Occurred()) return NULL;
            Py_RETURN_NONE;
        }
        if (!PyFloat_Check(vals[i]) && !PyLong_Check(vals[i])) Py_RETURN_NONE;
    }
    /* then converted in order, as float(v) would (held: a subclass's __float__ runs code) */
    for (i = 0; i < e->n_in; ++i) Py_INCREF(vals[i]);
    for (i = 0; i < e->n_in; ++i)
        if (hn_as_double(vals[i], &x[i])) break;
    for (j = 0; j < e->n_in; ++j) Py_DECREF(vals[j]);
    if (i < e->n_in) return NULL;
    if (hn_evaluate(e, x, &r)) Py_RETURN_NONE;
    return hn_float64(e, r);
}

PyDoc_STRVAR(hn_scalar_doc,
"scalar(x, /)\n--\n\n"
"CompiledSystem.evaluate_scalar(x) for a list of floats (one per input, in order): a float,\n"
"or None where the Python path decides (a tiny aggregated area).");

static PyObject *hn_scalar(hn_ev *e, PyObject *seq)
{
    double x[e->n_in], r;
    Py_ssize_t i;
    if (!PyList_Check(seq) || PyList_GET_SIZE(seq) != e->n_in) {
        PyErr_SetString(PyExc_TypeError, "scalar() takes a list of one float per input");
        return NULL;
    }
    for (i = 0; i < e->n_in; ++i) {
        PyObject *v = PyList_GET_ITEM(seq, i);
        if (!PyFloat_Check(v)) {
            PyErr_SetString(PyExc_TypeError, "scalar() takes a list of one float per input");
            return NULL;
        }
        x[i] = PyFloat_AS_DOUBLE(v);
    }
    if (hn_evaluate(e, x, &r)) Py_RETURN_NONE;
    return PyFloat_FromDouble(r);
}

/* --------------------------------------------------------------------------- construction */

/* offset o with n entries inside a table of size z */
static int hn_fits(int64_t o, int64_t n, Py_ssize_t z)
{
    return o >= 0 && n >= 0 && o <= (int64_t)z && n <= (int64_t)z - o;
}

#define HN_BAD(msg) do { PyErr_SetString(PyExc_ValueError, "Evaluator: " msg); return -1; } while (0)
#define HN_NEED(cond, msg) do { if (!(cond)) HN_BAD(msg); } while (0)

/* Read the packed layout (see _native.py, _pack) and check every offset. */
static int hn_parse(hn_ev *e, Py_ssize_t nI, Py_ssize_t nD)
{
    const int64_t *I = e->I;
    const double *D = e->D;
    int64_t o, m;
    Py_ssize_t i, t;
    HN_NEED(nI >= HN_HEADER && I[0] == HN_LAYOUT, "layout version");
    e->n_in = (Py_ssize_t)I[1];
    e->K = (Py_ssize_t)I[2];
    e->n_prog = (Py_ssize_t)I[3];
    e->R = (Py_ssize_t)I[4];
    e->T = (Py_ssize_t)I[5];
    e->n_sub = (Py_ssize_t)I[6];
    e->M = (Py_ssize_t)I[7];
    e->N = (Py_ssize_t)I[8];
    HN_NEED(I[1] >= 1 && I[1] <= 4096 && I[2] >= 1 && I[3] >= 0 && I[4] >= 1 && I[5] >= 1
            && I[6] >= 0 && I[7] >= 2 && I[8] >= 0, "sizes");
    HN_NEED(I[2] + I[3] + I[4] + I[5] + I[7] + I[8] <= 200000, "too large for the stack");
    e->n_mu = e->K + e->n_prog;
    HN_NEED(nD >= 2, "constants");
    e->dflt = D[0];
    e->tiny = D[1];
    e->in = PyMem_Calloc((size_t)e->n_in, sizeof(hn_in));
    e->prog = PyMem_Calloc((size_t)e->n_prog + 1, sizeof(hn_node));
    e->cut = PyMem_Calloc((size_t)e->T, sizeof(hn_cut));
    e->sub = PyMem_Calloc((size_t)e->n_sub + 1, sizeof(hn_sub));
    e->cross = PyMem_Calloc((size_t)e->T, sizeof(hn_cross));
    if (!e->in || !e->prog || !e->cut || !e->sub || !e->cross) { PyErr_NoMemory(); return -1; }

    o = HN_HEADER;                 /* the records follow the header, in this order */
    HN_NEED(hn_fits(o, 5 * (int64_t)e->n_in, nI), "inputs");
    m = 0;
    for (i = 0; i < e->n_in; ++i, o += 5) {
        hn_in *p = &e->in[i];
        p->M = (Py_ssize_t)I[o]; p->nt = (Py_ssize_t)I[o + 1];
        p->xs = (Py_ssize_t)I[o + 2]; p->F = (Py_ssize_t)I[o + 3]; p->S = (Py_ssize_t)I[o + 4];
        HN_NEED(I[o] >= 2 && I[o + 1] >= 1 && I[o] <= nD && I[o + 1] <= nD, "input sizes");
        HN_NEED(hn_fits(p->xs, p->M, nD) && hn_fits(p->F, p->M * p->nt, nD)
                && hn_fits(p->S, p->M * p->nt, nD), "input tables");
        m += p->nt;
    }
    HN_NEED(m == e->K, "leaf count");
    HN_NEED(hn_fits(o, 3 * (int64_t)e->n_prog, nI), "nodes");
    for (i = 0; i < e->n_prog; ++i, o += 3) {
        hn_node *q = &e->prog[i];
        q->op = (Py_ssize_t)I[o]; q->n = (Py_ssize_t)I[o + 1]; q->kids = (Py_ssize_t)I[o + 2];
        HN_NEED(I[o] >= 0 && I[o] <= 2 && I[o + 1] >= 1 && hn_fits(q->kids, q->n, nI), "node");
        HN_NEED(q->op != HN_OP_NOT || q->n == 1, "NOT node");
        for (t = 0; t < q->n; ++t)
            HN_NEED(I[q->kids + t] >= 0 && I[q->kids + t] < e->K + i, "node child");
    }
    HN_NEED(hn_fits(o, 2, nI), "rules");
    e->roots = (Py_ssize_t)I[o]; e->weights = (Py_ssize_t)I[o + 1];
    o += 2;
    HN_NEED(hn_fits(e->roots, e->R, nI) && hn_fits(e->weights, e->R, nD), "rule tables");
    for (i = 0; i < e->R; ++i)
        HN_NEED(I[e->roots + i] >= 0 && I[e->roots + i] < e->n_mu, "rule root");
    HN_NEED(hn_fits(o, 2 * (int64_t)e->T, nI), "cuts");
    for (t = 0; t < e->T; ++t, o += 2) {
        hn_cut *c = &e->cut[t];
        c->n = (Py_ssize_t)I[o]; c->rules = (Py_ssize_t)I[o + 1];
        HN_NEED(c->n >= 1 && hn_fits(c->rules, c->n, nI), "cut");
        for (i = 0; i < c->n; ++i)
            HN_NEED(I[c->rules + i] >= 0 && I[c->rules + i] < e->R, "cut rule");
    }
    HN_NEED(hn_fits(o, 5, nI), "output");
    e->positive = (Py_ssize_t)I[o]; e->xo = (Py_ssize_t)I[o + 1]; e->Fo = (Py_ssize_t)I[o + 2];
    e->So = (Py_ssize_t)I[o + 3]; e->W = (Py_ssize_t)I[o + 4];
    o += 5;
    HN_NEED(hn_fits(e->positive, e->T, nI) && hn_fits(e->xo, e->M, nD)
            && hn_fits(e->Fo, e->T * e->M, nD) && hn_fits(e->So, e->T * e->M, nD)
            && (e->n_sub || hn_fits(e->W, 2 * e->M, nD)), "output tables");
    HN_NEED(hn_fits(o, 6 * (int64_t)e->n_sub, nI), "subsets");
    for (i = 0; i < e->n_sub; ++i, o += 6) {
        hn_sub *s = &e->sub[i];
        s->sign = I[o] > 0 ? 1.0 : -1.0;
        s->n = (Py_ssize_t)I[o + 1]; s->terms = (Py_ssize_t)I[o + 2]; s->L = (Py_ssize_t)I[o + 3];
        s->lv = (Py_ssize_t)I[o + 4]; s->pq = (Py_ssize_t)I[o + 5];
        HN_NEED(s->n >= 1 && hn_fits(s->terms, s->n, nI) && s->L >= 1 && s->L < nD
                && hn_fits(s->lv, s->L, nD) && hn_fits(s->pq, 4 * (s->L + 1), nD), "subset");
        for (t = 0; t < s->n; ++t)
            HN_NEED(I[s->terms + t] >= 0 && I[s->terms + t] < e->T, "subset term");
    }
    HN_NEED(hn_fits(o, 3 * (int64_t)e->T, nI), "crossings");
    m = 0;
    for (t = 0; t < e->T; ++t, o += 3) {
        hn_cross *c = &e->cross[t];
        int64_t width = 0;
        c->L = (Py_ssize_t)I[o]; c->levels = (Py_ssize_t)I[o + 1]; c->rows = (Py_ssize_t)I[o + 2];
        HN_NEED(c->L >= 1 && c->L < nI && hn_fits(c->levels, c->L, nD)
                && hn_fits(c->rows, c->L + 2, nI), "crossing table");
        for (i = 0; i <= c->L; ++i) {
            const int64_t a = I[c->rows + i], b = I[c->rows + i + 1];
            int64_t q;
            HN_NEED(a <= b && hn_fits(a, b - a, nI), "crossing row");
            for (q = a; q < b; ++q)
                HN_NEED(I[q] >= 0 && I[q] < e->M - 1, "crossing interval");
            if (b - a > width) width = b - a;
        }
        m += width;
    }
    HN_NEED(m <= e->N, "crossing slots");
    return 0;
}

static void hn_dealloc(hn_ev *e)
{
    Py_XDECREF(e->names);
    Py_XDECREF(e->f64);
    PyMem_Free(e->D);
    PyMem_Free(e->I);
    PyMem_Free(e->in);
    PyMem_Free(e->prog);
    PyMem_Free(e->cut);
    PyMem_Free(e->sub);
    PyMem_Free(e->cross);
    Py_TYPE(e)->tp_free((PyObject *)e);
}

static void *hn_copy(PyObject *obj, Py_ssize_t item, Py_ssize_t *n)
{
    Py_buffer b;
    void *out;
    if (PyObject_GetBuffer(obj, &b, PyBUF_SIMPLE) < 0) return NULL;
    if (b.len % item) {
        PyBuffer_Release(&b);
        PyErr_SetString(PyExc_ValueError, "Evaluator: table size");
        return NULL;
    }
    out = PyMem_Malloc((size_t)b.len + 1);
    if (!out) { PyBuffer_Release(&b); PyErr_NoMemory(); return NULL; }
    memcpy(out, b.buf, (size_t)b.len);
    *n = b.len / item;
    PyBuffer_Release(&b);
    return out;
}

static PyObject *hn_new(PyTypeObject *type, PyObject *args, PyObject *kwds)
{
    PyObject *names, *f64, *ints, *dbls;
    Py_ssize_t nI = 0, nD = 0, i;
    hn_ev *e;
    static char *kwlist[] = {"names", "float64", "ints", "doubles", NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!OOO:Evaluator", kwlist, &PyTuple_Type,
                                     &names, &f64, &ints, &dbls))
        return NULL;
    if (!PyType_Check(f64) || !PyType_IsSubtype((PyTypeObject *)f64, &PyFloat_Type)) {
        PyErr_SetString(PyExc_TypeError, "Evaluator: float64 must be a float subclass");
        return NULL;
    }
    e = (hn_ev *)type->tp_alloc(type, 0);
    if (!e) return NULL;
    e->I = hn_copy(ints, sizeof(int64_t), &nI);
    if (!e->I) goto fail;
    e->D = hn_copy(dbls, sizeof(double), &nD);
    if (!e->D) goto fail;
    if (hn_parse(e, nI, nD) < 0) goto fail;
    if (PyTuple_GET_SIZE(names) != e->n_in) {
        PyErr_SetString(PyExc_ValueError, "Evaluator: one name per input");
        goto fail;
    }
    e->names = PyTuple_New(e->n_in);
    if (!e->names) goto fail;
    for (i = 0; i < e->n_in; ++i) {
        PyObject *s = PyTuple_GET_ITEM(names, i);
        if (!PyUnicode_CheckExact(s)) {
            PyErr_SetString(PyExc_TypeError, "Evaluator: names must be str");
            goto fail;
        }
        Py_INCREF(s);
        PyUnicode_InternInPlace(&s);
        PyTuple_SET_ITEM(e->names, i, s);
    }
    Py_INCREF(f64);
    e->f64 = f64;
    e->f64_direct = ((PyTypeObject *)f64)->tp_basicsize == (Py_ssize_t)sizeof(PyFloatObject)
                    && ((PyTypeObject *)f64)->tp_itemsize == 0;
    if (e->f64_direct) {           /* check it: a value made both ways must compare equal */
        PyObject *a = hn_float64(e, 0.375), *b = PyObject_CallFunction(f64, "d", 0.375);
        int same = a && b && Py_TYPE(a) == Py_TYPE(b)
                   && PyObject_RichCompareBool(a, b, Py_EQ) == 1
                   && PyFloat_AsDouble(b) == 0.375;
        Py_XDECREF(a);
        Py_XDECREF(b);
        PyErr_Clear();
        e->f64_direct = same;
    }
    return (PyObject *)e;
fail:
    Py_DECREF(e);
    return NULL;
}

static PyMethodDef hn_methods[] = {
    {"kw", (PyCFunction)hn_kw, METH_O, hn_kw_doc},
    {"scalar", (PyCFunction)hn_scalar, METH_O, hn_scalar_doc},
    {NULL, NULL, 0, NULL}
};

static PyObject *hn_get_names(hn_ev *e, void *closure)
{
    (void)closure;
    Py_INCREF(e->names);
    return e->names;
}

static PyObject *hn_get_direct(hn_ev *e, void *closure)
{
    (void)closure;
    return PyBool_FromLong(e->f64_direct);
}

static PyGetSetDef hn_getset[] = {
    {"names", (getter)hn_get_names, NULL, "the input names, in order", NULL},
    {"float64_direct", (getter)hn_get_direct, NULL,
     "whether numpy.float64 results are filled in directly (else made by calling the type)",
     NULL},
    {NULL, NULL, NULL, NULL, NULL}
};

static PyTypeObject hn_type = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "_hybridnav_fuzzy_native.Evaluator",
    .tp_basicsize = sizeof(hn_ev),
    .tp_dealloc = (destructor)hn_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Evaluator(names, float64, ints, doubles): one fuzzy system's scalar path in C",
    .tp_methods = hn_methods,
    .tp_getset = hn_getset,
    .tp_new = hn_new,
};

static struct PyModuleDef hn_module = {
    PyModuleDef_HEAD_INIT, "_hybridnav_fuzzy_native",
    "hybridnav's fuzzy scalar evaluator in C (built by hybridnav/fuzzy/_native.py)", -1,
    NULL, NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__hybridnav_fuzzy_native(void)
{
    PyObject *m;
    if (PyType_Ready(&hn_type) < 0) return NULL;
    m = PyModule_Create(&hn_module);
    if (!m) return NULL;
    Py_INCREF(&hn_type);
    if (PyModule_AddObject(m, "Evaluator", (PyObject *)&hn_type) < 0
        || PyModule_AddIntConstant(m, "LAYOUT", HN_LAYOUT) < 0) {
        Py_DECREF(&hn_type);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
