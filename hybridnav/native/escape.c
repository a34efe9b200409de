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
    int ok[HN_ESCAPE_CANDIDATES + 1];
    d[0] = want;
    double dl = (mt - -mt) / (HN_ESCAPE_CANDIDATES - 1);     /* np.linspace(-mt, mt, 9) */
    for (int i = 0; i < HN_ESCAPE_CANDIDATES; ++i) d[1 + i] = i * dl + -mt;
    d[HN_ESCAPE_CANDIDATES] = mt;
    double need = p->radius + p->margin;
    for (int i = 0; i <= HN_ESCAPE_CANDIDATES; ++i) {
        double th1 = theta + d[i], x1, y1;
        if (fabs(d[i]) < 1e-12) {                  /* the cycle's arc: straight */
            x1 = x + step * cos(theta);
            y1 = y + step * sin(theta);
        } else {                                   /* the cycle's arc: constant turn rate */
            double R = step / d[i];
            x1 = x + R * (sin(th1) - sin(theta));
            y1 = y + R * (cos(theta) - cos(th1));
        }
        double nx = -sin(th1), ny = cos(th1);
        double c0 = clearance(x1, y1, ctx);
        double cl = clearance(x1 + rho * nx, y1 + rho * ny, ctx);
        double cr = clearance(x1 - rho * nx, y1 - rho * ny, ctx);
        circle[i] = hn_escape_max(cl, cr) - rho;
        ok[i] = c0 >= need && circle[i] >= need;
        if (i == 0 && ok[0]) return 0;             /* the wanted change ends safe */
    }
    int best = -1;
    double bs = -INFINITY;
    for (int i = 0; i <= HN_ESCAPE_CANDIDATES; ++i)
        if (ok[i] && (best < 0 || -fabs(d[i] - want) > bs)) { bs = -fabs(d[i] - want); best = i; }
    if (best < 0) {                                /* none safe: the most room */
        bs = -INFINITY;
        best = 0;
        for (int i = 0; i <= HN_ESCAPE_CANDIDATES; ++i) {
            double v = isnan(circle[i]) ? -INFINITY : circle[i];
            if (v > bs) { bs = v; best = i; }
        }
    }
    double pick = theta + d[best];
    *vx = p->speed * cos(pick);
    *vy = p->speed * sin(pick);
    return 1;
}

#endif
