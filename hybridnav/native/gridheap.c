/* The heap search of hybridnav.planners.path.gridsearch._search (A*, and Dijkstra with h = 0) in
 * C99: the same graph, keys, tie rule and updates, so the same path, length and expanded count.
 *
 * The padded grid's cells are nodes 0..n-1; masks[u] has bit k set when move k (offset offs[k],
 * cost costs[k]) is legal from u. A node is pushed with the key (f // q, -g, node), f = g + h,
 * `//` being Python's float floor division (reproduced below), and closed at its first pop; its
 * g and parent change only on a strict improvement, neighbours taken in bit order. Entries are
 * distinct (a node is pushed again only with a smaller g) and their keys finite (the caller
 * refuses resolutions whose path lengths or key quantum would overflow or underflow: a NaN key
 * would leave the order partial), so any correct priority queue pops them in the order heapq
 * does.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct {
    double k1, k2;
    int64_t v;
} hn_entry;

/* Python's float // (CPython's _float_div_mod), whose fmod costs ~100 ns at the quotients of
 * the keys here (~1e11: fmod's loop runs over the exponents' difference). The quotient's floor
 * is read from vx / wx directly when its fractional part is clear of 0 and 1 by more than four
 * times that division's rounding error: both give floor(vx / wx) exactly there (CPython's
 * rounding errors stay below 0.5 for quotients below 2**51, and it snaps to the nearest integer). */
static double hn_floordiv_slow(double vx, double wx);

static double hn_floordiv(double vx, double wx)
{
    double d = vx / wx;
    double fl = floor(d), fr = d - fl, tol = fabs(d) * 4.5e-16;
    if (fr > tol && fr < 1.0 - tol && fabs(d) < 0x1p51)
        return fl;
    return hn_floordiv_slow(vx, wx);
}

static double hn_floordiv_slow(double vx, double wx)
{
    double mod = fmod(vx, wx);
    double div = (vx - mod) / wx, fl;
    if (mod) {
        if ((wx < 0) != (mod < 0))
            div -= 1.0;
    }
    if (div) {
        fl = floor(div);
        if (div - fl > 0.5)
            fl += 1.0;
        return fl;
    }
    return copysign(0.0, vx / wx);
}

/* tuple order: (k1, k2, v) lexicographically, floats compared with < and == as Python does */
static int hn_less(const hn_entry *a, const hn_entry *b)
{
    if (a->k1 != b->k1)
        return a->k1 < b->k1;
    if (a->k2 != b->k2)
        return a->k2 < b->k2;
    return a->v < b->v;
}

static void hn_sift_up(hn_entry *heap, int64_t i)
{
    hn_entry e = heap[i];
    while (i > 0) {
        int64_t p = (i - 1) / 2;
        if (!hn_less(&e, &heap[p]))
            break;
        heap[i] = heap[p];
        i = p;
    }
    heap[i] = e;
}

static void hn_sift_down(hn_entry *heap, int64_t size)
{
    hn_entry e = heap[0];
    int64_t i = 0;
    for (;;) {
        int64_t c = 2 * i + 1;
        if (c >= size)
            break;
        if (c + 1 < size && hn_less(&heap[c + 1], &heap[c]))
            c++;
        if (!hn_less(&heap[c], &e))
            break;
        heap[i] = heap[c];
        i = c;
    }
    heap[i] = e;
}

/* Search from s to t (h: see hn_h). g, parent and closed are n-long scratch arrays
 * (overwritten); out[0]
 * receives the number of nodes expanded, *out_g the path's length g[t]. Returns the number of cells of the path
 * written into path (start first), 0 when t is unreachable, -1 when memory runs out. */
/* The heuristic of node v: h[v] from the table (mode 0), or computed as gridsearch's
 * _heuristic_table computes it with NumPy -- the same IEEE operations in the same order: zero
 * (mode 1), Manhattan (dx + dy) * scale (mode 2), octile (max + c min) * scale (mode 3), with
 * dx = |col - gx|, dy = |row - gy| on the padded grid of width wp. */
static double hn_h(int64_t v, int mode, const double *h, int64_t wp, double gx, double gy,
                   double c, double scale)
{
    if (mode == 0)
        return h[v];
    if (mode == 1)
        return 0.0;
    double dx = fabs((double)(v % wp) - gx), dy = fabs((double)(v / wp) - gy);
    if (mode == 2)
        return (dx + dy) * scale;
    return ((dx > dy ? dx : dy) + c * (dx < dy ? dx : dy)) * scale;
}

int64_t hn_grid_search(int64_t n, int64_t s, int64_t t, const uint8_t *masks,
                       const int64_t *offs, const double *costs, const double *h, double q,
                       int64_t mode, int64_t wp, double gx, double gy, double c, double scale,
                       double *g, int64_t *parent, uint8_t *closed, double *out_g,
                       int64_t *out, int64_t *path)
{
    int64_t cap = 1024, size = 0, expanded = 0, found = 0, len = 0;
    hn_entry *heap = malloc((size_t)cap * sizeof *heap);
    if (!heap)
        return -1;
    for (int64_t i = 0; i < n; i++) {
        g[i] = INFINITY;
        parent[i] = -1;
        closed[i] = 0;
    }
    g[s] = 0.0;
    heap[size].k1 = hn_floordiv(hn_h(s, (int)mode, h, wp, gx, gy, c, scale), q);
    heap[size].k2 = -0.0;
    heap[size].v = s;
    size++;
    while (size) {
        int64_t u = heap[0].v;
        size--;
        if (size) {
            heap[0] = heap[size];
            hn_sift_down(heap, size);
        }
        if (closed[u])
            continue;
        closed[u] = 1;
        expanded++;
        if (u == t) {
            found = 1;
            break;
        }
        double gu = g[u];
        unsigned m = masks[u];
        for (int k = 0; k < 8; k++) {
            if (!(m >> k & 1u))
                continue;
            int64_t v = u + offs[k];
            double nv = gu + costs[k];
            if (nv < g[v] && !closed[v]) {
                g[v] = nv;
                parent[v] = u;
                if (size == cap) {
                    hn_entry *more = realloc(heap, (size_t)(2 * cap) * sizeof *heap);
                    if (!more) {
                        free(heap);
                        return -1;
                    }
                    heap = more;
                    cap *= 2;
                }
                heap[size].k1 = hn_floordiv(nv + hn_h(v, (int)mode, h, wp, gx, gy, c, scale), q);
                heap[size].k2 = -nv;
                heap[size].v = v;
                hn_sift_up(heap, size);
                size++;
            }
        }
    }
    free(heap);
    out[0] = expanded;
    if (!found)
        return 0;
    *out_g = g[t];
    for (int64_t v = t; v != s; v = parent[v])
        path[len++] = v;
    path[len++] = s;
    for (int64_t i = 0, j = len - 1; i < j; i++, j--) {
        int64_t x = path[i];
        path[i] = path[j];
        path[j] = x;
    }
    return len;
}
