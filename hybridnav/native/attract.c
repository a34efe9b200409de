/* The firefly attraction loop of hybridnav.planners.swarm.firefly._attraction_moves, around
   NumPy's exp: the caller computes exp of what hn_attract_step leaves in `arg` (NumPy's exp can
   differ from the C library's by an ulp), everything else is here, operation for operation as
   the NumPy loop does it (compiled with -ffp-contract=off: no fused multiply-add).
   Only for d <= 2, where NumPy's einsum of a row with itself is d0*d0 + d1*d1 exactly. */

typedef struct {
    long long n, d, m;        /* fireflies, dimensions, fireflies with a value (sorted first) */
    const double *Xs;         /* (n, d) positions at the start, sorted by brightness */
    double *Ys;               /* (n, d) positions as they move, sorted */
    const double *E;          /* (rows, d) random steps, in the order they were drawn: for each
                                 attraction one row per mover, the movers in index order */
    const long long *order;   /* (n) index of the firefly at each sorted position */
    const long long *first;   /* (J) the movers of the p-th brightest: first[p] .. m - 1 */
    double *diff;             /* (n, d) scratch: x_p - y_i */
    double *arg;              /* (n) exp's argument, -gamma r^2 */
    const double *ex;         /* (n) its exp, from the caller */
    long long *row;           /* (n) scratch: the row of E of each mover of the attraction */
    long long *rank;          /* (n) scratch: movers before each index */
    long long off;            /* rows of E taken by the attractions before */
    double inv_diag2, neg_gamma, scale, beta_min;
} hn_attract;

/* Finish the attraction of the (p-1)-th brightest (exp of its arguments in ex) unless p == 0,
   then prepare the p-th's unless p == J: its movers' differences, exp arguments and rows of E.
   Returns the number of movers of p (0 when p == J). */
long long hn_attract_step(hn_attract *a, long long p, long long J)
{
    const long long n = a->n, d = a->d, m = a->m;
    if (p > 0) {
        const long long s = a->first[p - 1];
        for (long long i = 0; i < m - s; i++) {
            double beta = a->scale * a->ex[i] + a->beta_min;
            double *y = a->Ys + (s + i) * d;
            const double *df = a->diff + i * d;
            const double *e = a->E + a->row[i] * d;
            for (long long c = 0; c < d; c++)
                y[c] = y[c] + (beta * df[c] + e[c]);
        }
        a->off += m - s;
    }
    if (p >= J)
        return 0;
    const long long s = a->first[p];
    /* the movers' rows: the attraction's block, the movers in index order */
    for (long long i = 0; i < n; i++)
        a->rank[i] = 0;
    for (long long q = s; q < m; q++)
        a->rank[a->order[q]] = 1;
    for (long long i = 0, c = 0; i < n; i++) {
        long long mover = a->rank[i];
        a->rank[i] = c;
        c += mover;
    }
    const double *x = a->Xs + p * d;
    for (long long i = 0; i < m - s; i++) {
        const double *y = a->Ys + (s + i) * d;
        double *df = a->diff + i * d;
        double r2;
        a->row[i] = a->off + a->rank[a->order[s + i]];
        df[0] = x[0] - y[0];
        r2 = df[0] * df[0];
        if (d == 2) {
            df[1] = x[1] - y[1];
            r2 = r2 + df[1] * df[1];
        }
        a->arg[i] = a->neg_gamma * (r2 * a->inv_diag2);
    }
    return m - s;
}
