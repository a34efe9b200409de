/* The escape-circle safety filter for constant-speed unicycles, in C99 with libm.
 *
 * hybridnav (hybridnav/planners/field/safety.py) runs the same operations in NumPy; the tuner's
 * compiled control cycle (lockstep.c) includes this file, and a tuning job with a safety margin
 * exports it beside the fuzzy controller, so the deployed filter is the one that was judged.
 *
 * A robot moving at constant `speed` that turns `max_turn` per control cycle `dt` drives round a
 * circle of radius rho = speed dt / max_turn. A state is safe when one of its two such circles
 * (left, right), widened by the robot radius and `margin`, is free: from there the robot can
 * circle for ever. Each cycle the wanted heading change is kept when the state it ends in is
 * safe, else the nearest safe one of HN_ESCAPE_CANDIDATES changes over [-max_turn, max_turn]
 * is taken (turning on along a free circle always is), else the one with the most room.
 *
 * `clearance(qx, qy, ctx)` is the signed distance from a point to the nearest obstacle or the
 * workspace border (the robot's map or range sensor); `here` its value at the robot (NAN: the
 * filter asks for it). Far from everything nothing else is asked.
 */
#include <math.h>

#ifndef M_PI                                       /* not in strict C99 */
#define M_PI 3.14159265358979323846
#endif

#ifndef HN_ESCAPE_DEFINED
#define HN_ESCAPE_DEFINED

#ifndef HN_ESCAPE_TYPES
#define HN_ESCAPE_TYPES
/* signed distance from (qx, qy) to the nearest obstacle or the workspace border */
typedef double (*hn_clearance_fn)(double qx, double qy, void *ctx);

/* the robot (constant speed, control cycle, largest heading change per cycle, radius) and the
 * room kept beyond its radius */
typedef struct {
    double speed, dt, max_turn, margin, radius;
} hn_escape_params;
#endif

#define HN_ESCAPE_CANDIDATES 9

/* NaN-propagating maximum (np.maximum) */
static double hn_escape_max(double a, double b) { return (isnan(a) || isnan(b)) ? NAN : (b > a ? b : a); }

/* np.remainder(a, b): the sign of b */
static double hn_escape_rem(double a, double b)
{
    double m = fmod(a, b);
    if (m != 0.0 && ((b < 0) != (m < 0))) m += b;
    return m;
}

/* The end (x1, y1) of one cycle turning by d from (x, y, theta), and (qx, qy): the offset of
 * its left escape circle's centre (the right one's is minus it) */
static void hn_escape_arc(double x, double y, double theta, double ct, double st, double d,
                          double step, double rho, double *x1, double *y1, double *qx, double *qy)
{
    double th1 = theta + d, c1 = cos(th1), s1 = sin(th1);   /* ct, st: cos, sin of theta */
    if (fabs(d) < 1e-12) {                         /* the cycle's arc: straight */
        *x1 = x + step * ct;
        *y1 = y + step * st;
    } else {                                       /* the cycle's arc: constant turn rate */
        double R = step / d;
        *x1 = x + R * (s1 - st);
        *y1 = y + R * (ct - c1);
    }
    *qx = rho * -s1;
    *qy = rho * c1;
}

/* Make the command (vx, vy) of a robot at (x, y) heading theta safe; returns 1 when it changed
 * it (to speed along the chosen heading), 0 when it left it as it was. */
static int hn_escape_filter(const hn_escape_params *p, double x, double y, double theta,
                            double *vx, double *vy, hn_clearance_fn clearance, void *ctx,
                            double here)
{
    if (!(p->margin > 0)) return 0;
    double mt = p->max_turn, step = p->speed * p->dt, rho = p->speed * p->dt / mt;
    if (isnan(here)) here = clearance(x, y, ctx);
    if (here - p->radius >= p->margin + 2 * rho + 2 * step + 1e-12) return 0;
    if (!isfinite(*vx) || !isfinite(*vy)) return 0;
    double want = hn_escape_rem(atan2(*vy, *vx) - theta + M_PI, 2 * M_PI) - M_PI;
    want = want < -mt ? -mt : (want > mt ? mt : want);
    double d[HN_ESCAPE_CANDIDATES + 1], circle[HN_ESCAPE_CANDIDATES + 1];
    double px[HN_ESCAPE_CANDIDATES + 1], py[HN_ESCAPE_CANDIDATES + 1];
    double qx[HN_ESCAPE_CANDIDATES + 1], qy[HN_ESCAPE_CANDIDATES + 1];
    int order[HN_ESCAPE_CANDIDATES + 1], has_l[HN_ESCAPE_CANDIDATES + 1];
    double cl_v[HN_ESCAPE_CANDIDATES + 1];
    d[0] = want;
    double dl = (mt - -mt) / (HN_ESCAPE_CANDIDATES - 1);     /* np.linspace(-mt, mt, 9) */
    for (int i = 0; i < HN_ESCAPE_CANDIDATES; ++i) d[1 + i] = i * dl + -mt;
    d[HN_ESCAPE_CANDIDATES] = mt;
    double need = p->radius + p->margin;
    for (int i = 0; i <= HN_ESCAPE_CANDIDATES; ++i) {
        order[i] = i;
        has_l[i] = 0;
        circle[i] = NAN;
        px[i] = NAN;                               /* the arc's end: on first use */
    }
    double ct = cos(theta), st = sin(theta);
#define HN_ESCAPE_ARC(i) do { if (isnan(px[i])) hn_escape_arc(x, y, theta, ct, st, d[i], step, \
                                                          rho, &px[i], &py[i], &qx[i], &qy[i]); \
                            } while (0)
    /* The candidates are tried nearest to the wanted change first (ties: the lower index; the
     * wanted change itself first), and the first safe one is taken: the pick of scoring them all.
     * With a finite state every clearance is finite, so a test one value settles needs no other.
     * A state that is not finite has no safe candidate (every clearance is NaN or -inf): then
     * every circle is measured for the most-room rule. */
    int finite = isfinite(x) && isfinite(y) && isfinite(theta);
    for (int i = 2; i <= HN_ESCAPE_CANDIDATES; ++i) {
        int o = order[i], j = i;
        double a = fabs(d[o] - want);
        while (j > 1 && fabs(d[order[j - 1]] - want) > a) { order[j] = order[j - 1]; --j; }
        order[j] = o;
    }
    int best = -1;
    for (int k = 0; finite && k <= HN_ESCAPE_CANDIDATES; ++k) {
        int i = order[k];
        HN_ESCAPE_ARC(i);
        if (!(clearance(px[i], py[i], ctx) >= need)) continue;     /* unsafe whatever the circles */
        double cl = clearance(px[i] + qx[i], py[i] + qy[i], ctx);
        cl_v[i] = cl;
        has_l[i] = 1;
        if (cl - rho >= need) { best = i; break; }                 /* max(cl, cr) - rho >= need */
        double cr = clearance(px[i] - qx[i], py[i] - qy[i], ctx);
        circle[i] = hn_escape_max(cl, cr) - rho;
        if (circle[i] >= need) { best = i; break; }
    }
    if (best == 0) return 0;                       /* the wanted change ends safe */
    if (best < 0) {                                /* none safe: the most room */
        double bs = -INFINITY;
        best = 0;
        for (int i = 0; i <= HN_ESCAPE_CANDIDATES; ++i) {
            if (!finite || !has_l[i] || isnan(circle[i])) {
                HN_ESCAPE_ARC(i);
                double cl = has_l[i] ? cl_v[i] : clearance(px[i] + qx[i], py[i] + qy[i], ctx);
                double cr = clearance(px[i] - qx[i], py[i] - qy[i], ctx);
                circle[i] = hn_escape_max(cl, cr) - rho;
            }
            double v = isnan(circle[i]) ? -INFINITY : circle[i];
            if (v > bs) { bs = v; best = i; }
        }
    }
#undef HN_ESCAPE_ARC
    double pick = theta + d[best];
    *vx = p->speed * cos(pick);
    *vy = p->speed * sin(pick);
    return 1;
}

#endif
