"""Interval arithmetic over CasADi SX functions, vectorized over many boxes at once.

:class:`IntervalFunction` walks the algorithm of an SX :class:`casadi.Function` (its instruction
list) and evaluates every operation on intervals ``[lo, hi]`` held as numpy arrays, one entry per
box. The result encloses every value the function takes on each box: this is what the certificate
route of :func:`hybridnav.analysis.check_lyapunov` builds its proofs on.

Soundness
    Every operation returns an interval containing the exact image of its input intervals, widened
    outward by 4 units in the last place plus ``1e-300`` (IEEE arithmetic rounds +, -, *, / and
    sqrt correctly; numpy's exp, log, sin, cos, atan2, ... are accurate to about one ulp).
    Operations that are exact (negation, absolute value, min/max, comparisons, selections) are not
    widened. Overflow is directed: a value that overflows to ``inf`` at a lower end (``exp`` on
    [711, 712], ``1/x`` at a subnormal) stands for "above the largest float", so the lower end
    becomes that largest float (and likewise at an upper end), never an interval holding only
    ``inf`` that a later ``inf/inf`` or ``0*inf`` would turn into a false bound. Domain errors (``log`` of a negative interval, ``sqrt`` of one entirely negative) give
    ``[-inf, inf]``, so no box is ever decided from them.
Smoothness
    Each evaluation also reports, per box and output, whether every operation the output depends
    on was smooth on its input interval (no ``fabs`` at 0, no ``fmin``/``fmax`` switching, no
    ``atan2`` across its branch cut or at the origin, no ``sqrt`` at 0, no jump of ``floor``,
    ``sign`` or a comparison). Derivatives computed by CasADi (``Vdot``, Lie derivatives,
    Hessians) are only trusted where the expressions they differentiate are smooth.
Constraints
    ``clamp={k: (lo, hi)}`` intersects the value of output ``k`` with ``[lo, hi]`` where it is
    computed, so every later use of the same subexpression sees the narrower interval: used for the
    model's admissibility constraints ``g(x) > 0`` (inside the LbCS obstacles ``1/FO`` would
    otherwise be unbounded on boxes touching them). The function is built with common-subexpression
    elimination so that equal subexpressions are shared.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as cs
import numpy as np

from hybridnav.native import interval as native_interval

__all__ = ["IntervalFunction", "UnsupportedOperation"]

_EPS = 4 * np.finfo(float).eps
_TINY = 1e-300
_OPS = {getattr(cs, n): n[3:].lower() for n in dir(cs) if n.startswith("OP_")}
_TWO_PI = 2 * np.pi
_MAX = np.finfo(float).max


class UnsupportedOperation(NotImplementedError):
    """The expression uses an operation without an interval extension here."""


def _finite_ends(lo, hi):
    """Directed overflow: a lower end at ``+inf`` (an overflowed value, or an overflowed constant
    such as CasADi's folded ``exp(800)``) is only known to exceed the largest float, so it
    becomes that float; an upper end at ``-inf`` likewise. Every interval then holds reals."""
    if (lo == np.inf).any():
        lo = np.where(lo == np.inf, _MAX, lo)
    if (hi == -np.inf).any():
        hi = np.where(hi == -np.inf, -_MAX, hi)
    return lo, hi


def _widen(lo, hi):
    """Outward by 4 ulp (and 1e-300); zero and infinite endpoints stay (see :func:`_round_out`)."""
    return (np.where((lo != 0) & np.isfinite(lo), lo - _EPS * np.abs(lo) - _TINY, lo),
            np.where((hi != 0) & np.isfinite(hi), hi + _EPS * np.abs(hi) + _TINY, hi))


#: operations whose zero endpoints are always valid bounds: IEEE sums are zero only when exact;
#: products, quotients and integer powers replace an underflow by +-_TINY on its outer side
#: (:func:`_underflow`), so a zero left is exact or an inner bound
_ZERO_EXACT = {"add", "sub", "mul", "div", "sq", "constpow"}


def _round_out(name, lo, hi, inputs):
    """Outward rounding of an operation's result.

    Nonzero endpoints move out by 4 ulp (and 1e-300). A zero endpoint is kept exact only where it
    cannot be an underflow: for sums, where an input endpoint is exactly zero (a product, quotient
    or odd function of an exact zero), or for even powers of an interval holding zero (whose
    minimum is exactly zero); elsewhere it moves out by 1e-300. Exact zeros matter: LaSalle's
    argument needs ``Vdot <= 0`` with equality.
    """
    lo, hi = _widen(lo, hi)
    if name in _ZERO_EXACT:
        return lo, hi
    exact = np.zeros(lo.shape, dtype=bool)
    for arr in inputs:
        exact |= arr == 0
    return (np.where((lo == 0) & ~exact, -_TINY, lo),
            np.where((hi == 0) & ~exact, _TINY, hi))


def _times(x, y):
    """Endpoint products with 0 * inf = 0 (a zero endpoint is a value, an infinite one a limit)."""
    p = x * y
    nan = np.isnan(p)
    if nan.any():                      # only 0 * inf makes a NaN of two non-NaN ends
        p = np.where(nan & ((x == 0) | (y == 0)), 0.0, p)
    return p


def _underflow(q, x, y):
    """``(lower, upper)`` bounds of ``x * y`` (or ``x / y``) computed as ``q``: where it
    underflowed to 0 from nonzero ``x`` and ``y``, the true value has the sign of ``x y`` and
    a magnitude below the smallest normal float: 0 bounds it on one side, ``+-_TINY`` on the
    other. Everywhere else ``q`` bounds itself (rounding is widened later)."""
    zero = q == 0
    if not zero.any():
        return q, q
    under = zero & (x != 0) & (y != 0) & ~np.isnan(x) & ~np.isnan(y)
    if not under.any():
        return q, q
    neg = (x < 0) != (y < 0)
    return (np.where(under & neg, -_TINY, q), np.where(under & ~neg, _TINY, q))


def _mul(a, b, c, d):
    p = np.stack((a * c, a * d, b * c, b * d))
    if not (np.isnan(p).any() or (p == 0).any()):
        # no 0 * inf and no underflow: each product bounds itself (what the loop below gives)
        return p.min(axis=0), p.max(axis=0)
    lo, hi = [], []
    for x, y in ((a, c), (a, d), (b, c), (b, d)):
        pl, ph = _underflow(_times(x, y), x, y)
        lo.append(pl)
        hi.append(ph)
    return np.min(lo, axis=0), np.max(hi, axis=0)


def _inv(a, b):
    """1 / [a, b]; unbounded where the interval holds 0."""
    ra, rb = 1.0 / a, 1.0 / b
    pos, neg = a > 0, b < 0
    lo = np.where(pos | neg, rb, np.where((a == 0) & (b > 0), rb, -np.inf))
    hi = np.where(pos | neg, ra, np.where((b == 0) & (a < 0), ra, np.inf))
    return lo, hi


def _trig(fn, a, b, peak: float, trough: float):
    """sin or cos over [a, b]: the endpoints' values, and 1 / -1 where the interval holds a peak
    ``peak + 2 k pi`` / a trough ``trough + 2 k pi`` (tested with a margin, so conservatively)."""
    fa, fb = fn(a), fn(b)
    lo, hi = np.minimum(fa, fb), np.maximum(fa, fb)

    def holds(phase):
        return np.ceil((a - phase) / _TWO_PI - 1e-9) <= np.floor((b - phase) / _TWO_PI + 1e-9)

    # beyond 1e8 the phase test loses more than its margin to rounding: no claim there
    wide = ~np.isfinite(a) | ~np.isfinite(b) | (b - a >= _TWO_PI) | (np.maximum(np.abs(a),
                                                                              np.abs(b)) > 1e8)
    hi = np.where(holds(peak) | wide, 1.0, hi)
    lo = np.where(holds(trough) | wide, -1.0, lo)
    return lo, hi


def _monotone(fn, a, b, increasing=True):
    fa, fb = fn(a), fn(b)
    return (fa, fb) if increasing else (fb, fa)


def _atan2(ya, yb, xa, xb):
    """atan2(y, x) over a box: continuous unless the box meets the branch cut (x <= 0, y = 0)."""
    corners = np.stack([np.arctan2(ya, xa), np.arctan2(ya, xb), np.arctan2(yb, xa),
                        np.arctan2(yb, xb)])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    cut = (xa <= 0) & (ya <= 0) & (yb >= 0)
    lo = np.where(cut, -np.pi, lo)
    hi = np.where(cut, np.pi, hi)
    return lo, hi, ~cut


def _powi(a, b, n: int):
    """x ** n for an integer n (even powers are not monotone)."""
    if n == 0:
        return np.ones_like(a), np.ones_like(b)
    if n < 0:
        lo, hi = _powi(a, b, -n)
        return _inv(lo, hi)
    pa, pb = a ** n, b ** n
    # an underflow to 0 from a nonzero base: 0 bounds the true power on one side only
    ua, ub = (pa == 0) & (a != 0), (pb == 0) & (b != 0)
    if n % 2:
        return np.where(ua & (a < 0), -_TINY, pa), np.where(ub & (b > 0), _TINY, pb)
    contains = (a <= 0) & (b >= 0)
    lo = np.where(contains, 0.0, np.minimum(pa, pb))
    return lo, np.maximum(np.where(ua, _TINY, pa), np.where(ub, _TINY, pb))


class IntervalFunction:
    """The interval extension of an SX function of one vector input.

    Parameters
    ----------
    x : casadi.SX
        The input symbols (a column).
    outputs : sequence of casadi.SX
        Expressions in ``x``; each becomes one output (flattened).

    Raises
    ------
    UnsupportedOperation
        When an expression uses an operation without an interval extension here (the message names
        it).
    """

    def __init__(self, x: cs.SX, outputs: Sequence[cs.SX]) -> None:
        self.sizes = [int(o.numel()) for o in outputs]
        flat = cs.vertcat(*[cs.vec(cs.densify(cs.SX(o))) for o in outputs])
        flat = cs.cse(flat)
        fn = cs.Function("interval", [x], [flat], {"live_variables": False})
        self.nx = int(x.numel())
        self.n_out = int(flat.numel())
        self._program = []
        self._out_slot = {}
        # wrapped angles: w = atan2(sin u, cos u) has cos w = cos u and sin w = sin u exactly,
        # which interval arithmetic cannot see across the jump of w at +-pi
        made: dict[int, tuple[str, int]] = {}
        wraps: dict[int, tuple[int, int]] = {}
        for k in range(fn.n_instructions()):
            op = fn.instruction_id(k)
            name = _OPS.get(op, str(op))
            ins, outs = fn.instruction_input(k), fn.instruction_output(k)
            const = fn.instruction_constant(k) if op == cs.OP_CONST else None
            if name == "output":
                self._out_slot[outs[1]] = ins[0]
            elif name not in _SUPPORTED:
                raise UnsupportedOperation(f"no interval extension for the CasADi operation "
                                           f"{name!r}")
            extra = None
            if name in ("sin", "cos"):
                made[outs[0]] = (name, ins[0])
                if ins[0] in wraps:
                    extra = wraps[ins[0]][0 if name == "sin" else 1]
            elif name == "atan2":
                ys, xs = made.get(ins[0]), made.get(ins[1])
                if ys and xs and ys[0] == "sin" and xs[0] == "cos" and ys[1] == xs[1]:
                    wraps[outs[0]] = (ins[0], ins[1])
            self._program.append((name, ins, outs, const, extra))
        self.sz_w = fn.sz_w()
        self._kernel: native_interval.Program | None | bool = False     # False: not built yet

    def _compiled(self) -> native_interval.Program | None:
        """The program in the compiled kernel's form (None: it has operations the kernel
        lacks)."""
        if self._kernel is False:
            self._kernel = native_interval.program(self._program, self.sz_w, self.nx,
                                                   self.n_out)
        return self._kernel

    def __call__(self, lo: np.ndarray, hi: np.ndarray, clamp: Mapping[int, tuple[float, float]]
                 | None = None, continuity: bool = False, _record: dict | None = None):
        """Enclosures of the outputs on each box ``[lo[i], hi[i]]``.

        Parameters
        ----------
        lo, hi : (N, nx) arrays
        clamp : dict, optional
            ``{flat output index: (lo, hi)}`` known bounds on those outputs (constraints).

        Returns
        -------
        out_lo, out_hi : (N, n_out) arrays
        smooth : (N, n_out) bool array
            Whether every operation each output depends on was smooth on the box. Where a
            ``fmin``, ``fmax`` or ``if_else_zero`` surely selects one operand on the box, only
            that operand counts (a saturation that is inactive on the box is smooth there).
        continuous : (N, n_out) bool array
            Only with ``continuity=True``: whether the output is Lipschitz continuous on the box
            (kinks allowed: ``fmin``, ``fmax``, ``fabs``; not jumps: ``floor``, ``sign`` at 0,
            an undecided comparison or selection, ``atan2`` across its cut; nor ``sqrt`` or a
            fractional power at 0, where solutions of ``xdot = f(x)`` need not be unique).

        Where an output may be undefined on a box (an operation it depends on may leave its
        domain: ``log`` or ``sqrt`` of negatives, division by an interval holding zero, ``asin``
        beyond 1, a power of a base that may be <= 0, ``atan2`` at the origin, or a NaN), its
        enclosure is ``[-inf, inf]`` and it is not smooth: nothing can be decided from it.
        """
        with np.errstate(all="ignore"):       # once: overflow and NaN are handled per operation
            return self._call(lo, hi, clamp, continuity, _record)

    def _call(self, lo, hi, clamp, continuity, _record):
        lo = np.asarray(lo, dtype=float)
        hi = np.asarray(hi, dtype=float)
        n = lo.shape[0]
        wl: list = [None] * self.sz_w
        wh: list = [None] * self.sz_w
        ws: list = [None] * self.sz_w           # smoothness per slot (None: smooth everywhere)
        wc: list = [None] * self.sz_w           # continuity per slot (None: continuous)
        wd: list = [None] * self.sz_w           # defined per slot (None: defined everywhere)
        wp: list = [None] * self.sz_w           # > 0 though lo = 0 (clamped to an open bound)
        clamp_slot = {self._out_slot[k]: v for k, v in (clamp or {}).items()
                      if k in self._out_slot}
        if (_record is None and lo.ndim == 2 and lo.shape == hi.shape and lo.shape[1] == self.nx
                and self._compiled() is not None):
            # arithmetic and exact operations only: the compiled kernel, the same operations
            # per box
            done = native_interval.evaluate(self._kernel, lo, hi, clamp_slot)
            if done is not None:
                return done if continuity else done[:3]
        out_lo = np.empty((n, self.n_out))
        out_hi = np.empty((n, self.n_out))
        smooth = np.ones((n, self.n_out), dtype=bool)
        cont = np.ones((n, self.n_out), dtype=bool)
        for name, ins, outs, const, same in self._program:
            if name == "input":
                wl[outs[0]], wh[outs[0]] = _finite_ends(lo[:, ins[1]], hi[:, ins[1]])
                if outs[0] in clamp_slot:
                    cl, ch = clamp_slot[outs[0]]
                    wl[outs[0]] = np.maximum(wl[outs[0]], cl)
                    wh[outs[0]] = np.minimum(wh[outs[0]], ch)
                    wp[outs[0]] = np.full(n, cl == 0)
                continue
            if name == "output":
                out_lo[:, outs[1]], out_hi[:, outs[1]] = wl[ins[0]], wh[ins[0]]
                if ws[ins[0]] is not None:
                    smooth[:, outs[1]] = ws[ins[0]]
                if wc[ins[0]] is not None:
                    cont[:, outs[1]] = wc[ins[0]]
                if wd[ins[0]] is not None:
                    bad = ~wd[ins[0]]
                    out_lo[bad, outs[1]], out_hi[bad, outs[1]] = -np.inf, np.inf
                    smooth[bad, outs[1]] = False
                    cont[bad, outs[1]] = False
                continue
            if name == "const":
                v = np.full(n, float(const))
                wl[outs[0]], wh[outs[0]] = _finite_ends(v, v)
                continue
            a, b = wl[ins[0]], wh[ins[0]]
            c = d = None
            binary = len(ins) > 1 and ins[1] >= 0 and name in _BINARY
            if binary:
                c, d = wl[ins[1]], wh[ins[1]]
            rl, rh, ok = _apply(name, a, b, c, d)
            rl, rh = _finite_ends(rl, rh)
            defined = _and(wd[ins[0]], wd[ins[1]] if binary else None)
            dom = _domain(name, a, b, c, d, wp[ins[0]], wp[ins[1]] if binary else None)
            # (no NaN reaches here: _apply makes a NaN end [-inf, inf] and flags it not ok)
            defined = _and(defined, dom if dom is not None and not dom.all() else None)
            if name == "if_else_zero" and defined is not None:
                # CasADi evaluates cond ? value : 0; a surely false cond gives 0 whatever value is
                _, no = _truth(a, b)
                defined = np.where(no & (wd[ins[0]] if wd[ins[0]] is not None else True), True,
                                   defined)
            if name not in _EXACT:
                rl, rh = _round_out(name, rl, rh, (a, b) if c is None else (a, b, c, d))
            if same is not None:
                # sin/cos of a wrapped angle: that of the angle itself, as smooth as it is
                rl, rh = np.maximum(rl, wl[same]), np.minimum(rh, wh[same])
                flag, cflag = ws[same], wc[same]
            else:
                jump = ok if name in _JUMPS else None
                left, right = _selected(name, a, b, c, d)
                s0, s1 = ws[ins[0]], ws[ins[1]] if binary else None
                c0, c1 = wc[ins[0]], wc[ins[1]] if binary else None
                flag = _and(_and(s0, s1), ok)
                cflag = _and(_and(c0, c1), jump)
                if name == "if_else_zero":     # cond surely true: the value; false: 0
                    flag = _pick(left, s1, right, None, flag, n)
                    cflag = _pick(left, c1, right, None, cflag, n)
                elif left is not None:
                    flag = _pick(left, s0, right, s1, flag, n)
                    cflag = _pick(left, c0, right, c1, cflag, n)
            slot = outs[0]
            if slot in clamp_slot:
                cl, ch = clamp_slot[slot]
                rl, rh = np.maximum(rl, cl), np.minimum(rh, ch)
                wp[slot] = np.full(n, cl == 0)
            wl[slot], wh[slot], ws[slot], wd[slot], wc[slot] = rl, rh, flag, defined, cflag
        if _record is not None:
            _record.update(lo=wl, hi=wh)
        if continuity:
            return out_lo, out_hi, smooth, cont
        return out_lo, out_hi, smooth

    def specialize(self, x: cs.SX, lo, hi) -> list[cs.SX]:
        """The outputs rebuilt for one box ``[lo, hi]`` with every selection that is decided on
        it replaced by the side it takes: ``fmin``/``fmax`` by one operand, ``fabs`` by ``+-x``,
        decided comparisons, ``not``/``and``/``or``, ``sign`` and ``floor`` by constants,
        ``if_else_zero`` by its value or 0.

        On the box the result equals the original function at every point, and it is smooth
        where the remaining operations are: CasADi's derivatives of it are the derivatives of
        the original there (those of the original may be NaN on the box, e.g. ``0 * (x / |x|)``
        for a saturation that is inactive at ``x = 0``).

        Parameters
        ----------
        x : casadi.SX
            The input symbols the function was built from.
        lo, hi : (nx,) arrays
        """
        rec: dict = {}
        self(np.asarray(lo, dtype=float)[None], np.asarray(hi, dtype=float)[None], _record=rec)
        wl, wh = rec["lo"], rec["hi"]
        ops = {v: k for k, v in _OPS.items()}
        sx: list = [None] * self.sz_w
        outs_sx = [cs.SX(0)] * self.n_out
        for name, ins, outs, const, _same in self._program:
            if name == "input":
                sx[outs[0]] = x[ins[1]]
                continue
            if name == "output":
                outs_sx[outs[1]] = sx[ins[0]]
                continue
            if name == "const":
                sx[outs[0]] = cs.SX(float(const))
                continue
            binary = len(ins) > 1 and ins[1] >= 0 and name in _BINARY
            a, b = wl[ins[0]][0], wh[ins[0]][0]
            c, d = (wl[ins[1]][0], wh[ins[1]][0]) if binary else (None, None)
            u = sx[ins[0]]
            v = sx[ins[1]] if binary else None
            r = None
            if name in ("fmin", "fmax"):
                left, right = (b < c, d < a) if name == "fmin" else (a > d, c > b)
                r = u if left else (v if right else None)
            elif name == "fabs":
                r = u if a > 0 else (-u if b < 0 else None)
            elif name == "if_else_zero":
                yes, no = _truth(np.array([a]), np.array([b]))
                r = v if yes[0] else (cs.SX(0) if no[0] else None)
            elif name in _EXACT - {"neg", "fmin", "fmax", "fabs", "assign"}:
                rl, rh = wl[outs[0]][0], wh[outs[0]][0]
                if rl == rh and np.isfinite(rl):
                    r = cs.SX(float(rl))          # decided: a constant on the box
            if r is None:
                op = ops[name]
                r = cs.SX.binary(op, u, v) if binary else cs.SX.unary(op, u)
            sx[outs[0]] = r
        return outs_sx


#: operations that may jump, or lose Lipschitz continuity (sqrt, fractional powers, asin, acos
#: at the ends of their domains: solutions may not be unique there), where their flag is False;
#: the others are Lipschitz continuous where defined (fmin, fmax, fabs: kinks)
_STEPS = {"floor", "ceil", "sign", "lt", "le", "eq", "ne", "not", "and", "or", "if_else_zero",
          "atan2"}
_JUMPS = _STEPS | {"sqrt", "pow", "constpow", "asin", "acos"}


def may_step(x: cs.SX, f: cs.SX) -> bool:
    """Whether ``f`` uses an operation that can jump (a comparison, selection, ``floor``,
    ``sign``, ``atan2`` across its cut): without one, ``f`` is continuous wherever it is defined
    (``sqrt`` or a fractional power at 0 is continuous, only not Lipschitz)."""
    fn = cs.Function("f", [x], [cs.densify(cs.SX(f))], {"live_variables": False})
    return any(_OPS.get(fn.instruction_id(k)) in _STEPS for k in range(fn.n_instructions()))


def _selected(name, a, b, c, d):
    """Where a selection surely takes its first / its second operand (None: not a selection).
    For ``if_else_zero(cond, value)``: where cond is surely nonzero (the value) / surely zero (0)."""
    if name == "fmin":
        return b < c, d < a
    if name == "fmax":
        return a > d, c > b
    if name == "if_else_zero":
        yes, no = _truth(a, b)
        return yes, no
    return None, None


def _pick(left, f_left, right, f_right, both, n):
    """The flag of the operand a selection surely takes; ``both`` where it may take either."""
    def full(f):
        return np.ones(n, dtype=bool) if f is None else f

    if left is None:
        return both
    return np.where(left, full(f_left), np.where(right, full(f_right), full(both)))


def _positive(a, pos):
    """The interval is > 0: its lower end, or lo = 0 from an open bound (``pos``)."""
    return (a > 0) if pos is None else (a > 0) | ((a == 0) & pos)


def _domain(name, a, b, c, d, pos_a, pos_c):
    """Where the operation is defined on the whole input interval (None: everywhere)."""
    if name == "inv":
        return _positive(a, pos_a) | (b < 0)
    if name == "div":
        return _positive(c, pos_c) | (d < 0)
    if name == "log":
        return _positive(a, pos_a)
    if name == "sqrt":
        return a >= 0
    if name in ("asin", "acos"):
        return (a >= -1) & (b <= 1)
    if name == "pow":
        return _positive(a, pos_a)
    if name == "constpow":
        integer = (c == d) & (c == np.round(c))
        return np.where(integer, (c >= 0) | _positive(a, pos_a) | (b < 0),
                        np.where(c > 0, a >= 0, _positive(a, pos_a)))
    if name == "atan2":
        return ~((a <= 0) & (b >= 0) & (c <= 0) & (d >= 0))
    if name == "tan":
        return np.isfinite(a) & np.isfinite(b) & ~(np.ceil((a - np.pi / 2) / np.pi - 1e-9) <= np.floor(
            (b - np.pi / 2) / np.pi + 1e-9))
    return None


def _and(a, b):
    if a is None:
        return b
    return a if b is None else a & b


_BINARY = {"add", "sub", "mul", "div", "pow", "constpow", "atan2", "fmin", "fmax", "lt", "le",
           "eq", "ne", "and", "or", "if_else_zero"}
_EXACT = {"neg", "fabs", "fmin", "fmax", "lt", "le", "eq", "ne", "not", "and", "or",
          "if_else_zero", "sign", "floor", "ceil", "assign"}


def _truth(a, b):
    """(surely nonzero, surely zero) of an interval used as a condition."""
    return (a > 0) | (b < 0), (a == 0) & (b == 0)


def _apply(name, a, b, c, d):
    ok = None
    if name == "add":
        lo, hi = a + c, b + d
    elif name == "sub":
        lo, hi = a - d, b - c
    elif name == "mul":
        lo, hi = _mul(a, b, c, d)
    elif name == "div":
        il, ih = _finite_ends(*_inv(c, d))
        lo, hi = _mul(a, b, il, ih)
        lo, hi = _widen(lo, hi)          # two roundings (1/y, then the product)
        # finite ends and a divisor away from 0: the endpoint quotients, rounded once
        # (1/y alone may overflow where x/y does not: 5.39e-295 / 2.4e-310)
        direct = (np.isfinite(a) & np.isfinite(b) & np.isfinite(c) & np.isfinite(d)
                  & ((c > 0) | (d < 0)))
        if direct.any():
            ql, qh = zip(*(_underflow(x / y, x, y) for x, y in ((a, c), (a, d), (b, c),
                                                                 (b, d))))
            lo = np.where(direct, np.min(ql, axis=0), lo)
            hi = np.where(direct, np.max(qh, axis=0), hi)
    elif name == "inv":
        lo, hi = _inv(a, b)
    elif name == "neg":
        lo, hi = -b, -a
    elif name == "twice":
        lo, hi = 2 * a, 2 * b
    elif name == "assign":
        lo, hi = a, b
    elif name == "sq":
        lo, hi = _powi(a, b, 2)
    elif name == "constpow":
        if np.all(c == d) and np.all(c == np.round(c)) and np.all(c == c[0]):
            lo, hi = _powi(a, b, int(c[0]))
        else:
            lo, hi = _pow(a, b, c, d)
            # x**0.5 or x**1.5 at 0: not smooth (nor Lipschitz below exponent 1)
            ok = (a > 0) | ((c == d) & (c == np.round(c)))
    elif name == "pow":
        lo, hi = _pow(a, b, c, d)
        ok = a > 0
    elif name == "sqrt":
        lo, hi = np.sqrt(np.maximum(a, 0.0)), np.sqrt(np.maximum(b, 0.0))
        bad = b < 0
        lo, hi = np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)
        ok = a > 0
    elif name == "exp":
        lo, hi = _monotone(np.exp, a, b)
    elif name == "log":
        lo, hi = _monotone(np.log, np.maximum(a, 0.0), b)
        bad = b <= 0
        lo, hi = np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)
    elif name == "tan":
        lo, hi = _monotone(np.tan, a, b)
        # a pole pi/2 + k pi inside (tested with a margin) or beyond 1e8: unbounded
        pole = (np.ceil((a - np.pi / 2) / np.pi - 1e-9) <= np.floor((b - np.pi / 2) / np.pi
                                                                      + 1e-9))
        pole |= ~np.isfinite(a) | ~np.isfinite(b) | (np.maximum(np.abs(a), np.abs(b)) > 1e8)
        lo, hi = np.where(pole, -np.inf, lo), np.where(pole, np.inf, hi)
        ok = ~pole
    elif name == "tanh":
        lo, hi = _monotone(np.tanh, a, b)
    elif name == "atan":
        lo, hi = _monotone(np.arctan, a, b)
    elif name == "asin":
        lo, hi = _monotone(np.arcsin, np.clip(a, -1, 1), np.clip(b, -1, 1))
        ok = (a > -1) & (b < 1)
    elif name == "acos":
        lo, hi = _monotone(np.arccos, np.clip(a, -1, 1), np.clip(b, -1, 1), False)
        ok = (a > -1) & (b < 1)
    elif name == "sinh":
        lo, hi = _monotone(np.sinh, a, b)
    elif name == "cosh":
        lo, hi = _powi_like_cosh(a, b)
    elif name == "cos":
        lo, hi = _trig(np.cos, a, b, 0.0, np.pi)
    elif name == "sin":
        lo, hi = _trig(np.sin, a, b, np.pi / 2, -np.pi / 2)
    elif name == "atan2":
        lo, hi, ok = _atan2(a, b, c, d)
        ok = ok & ~((a <= 0) & (b >= 0) & (c <= 0) & (d >= 0))
    elif name == "fabs":
        lo = np.where((a <= 0) & (b >= 0), 0.0, np.minimum(np.abs(a), np.abs(b)))
        hi = np.maximum(np.abs(a), np.abs(b))
        ok = (a > 0) | (b < 0)
    elif name == "fmin":
        lo, hi = np.minimum(a, c), np.minimum(b, d)
        ok = (b < c) | (d < a)
    elif name == "fmax":
        lo, hi = np.maximum(a, c), np.maximum(b, d)
        ok = (b < c) | (d < a)
    elif name == "sign":
        lo, hi = np.sign(a), np.sign(b)
        ok = (a > 0) | (b < 0)
    elif name in ("floor", "ceil"):
        f = np.floor if name == "floor" else np.ceil
        lo, hi = f(a), f(b)
        ok = lo == hi
    elif name in ("lt", "le", "eq", "ne"):
        lo, hi, ok = _compare(name, a, b, c, d)
    elif name == "not":
        yes, no = _truth(a, b)
        lo, hi = np.where(yes, 0.0, np.where(no, 1.0, 0.0)), np.where(yes, 0.0, 1.0)
        ok = yes | no
    elif name in ("and", "or"):
        y1, n1 = _truth(a, b)
        y2, n2 = _truth(c, d)
        if name == "and":
            sure1, sure0 = y1 & y2, n1 | n2
        else:
            sure1, sure0 = y1 | y2, n1 & n2
        lo, hi = np.where(sure1, 1.0, 0.0), np.where(sure0, 0.0, 1.0)
        ok = sure1 | sure0
    elif name == "if_else_zero":
        yes, no = _truth(a, b)
        lo = np.where(yes, c, np.where(no, 0.0, np.minimum(c, 0.0)))
        hi = np.where(yes, d, np.where(no, 0.0, np.maximum(d, 0.0)))
        ok = yes | no
    else:                                 # pragma: no cover - filtered at construction
        raise UnsupportedOperation(name)
    nan = np.isnan(lo) | np.isnan(hi)
    if nan.any():
        lo, hi = np.where(nan, -np.inf, lo), np.where(nan, np.inf, hi)
        ok = ~nan if ok is None else ok & ~nan
    return lo, hi, ok


def _pow(a, b, c, d):
    """x ** y = exp(y log x) for x > 0, each step rounded outward (exp amplifies the rounding of
    its argument by |y log x|); [-inf, inf] where x may be <= 0."""
    ll, lh = _widen(*_monotone(np.log, np.maximum(a, 0.0), b))
    pl, ph = _widen(*_mul(ll, lh, c, d))
    lo, hi = np.exp(pl), np.exp(ph)
    hi = np.where(hi == 0, _TINY, hi)           # x**y > 0 for x > 0: an underflow bounds it below
    bad = a <= 0
    return np.where(bad, -np.inf, lo), np.where(bad, np.inf, hi)


def _powi_like_cosh(a, b):
    ca, cb = np.cosh(a), np.cosh(b)
    lo = np.where((a <= 0) & (b >= 0), 1.0, np.minimum(ca, cb))
    return lo, np.maximum(ca, cb)


def _compare(name, a, b, c, d):
    if name == "lt":
        yes, no = b < c, a >= d
    elif name == "le":
        yes, no = b <= c, a > d
    elif name == "eq":
        yes, no = (a == b) & (c == d) & (a == c), (b < c) | (d < a)
    else:
        no, yes = (a == b) & (c == d) & (a == c), (b < c) | (d < a)
    lo, hi = np.where(yes, 1.0, 0.0), np.where(no, 0.0, 1.0)
    return lo, hi, yes | no


_SUPPORTED = {"input", "output", "const", "add", "sub", "mul", "div", "inv", "neg", "twice",
              "assign", "sq", "constpow", "pow", "sqrt", "exp", "log", "tan", "tanh", "atan",
              "asin",
              "acos", "sinh", "cosh", "cos", "sin", "atan2", "fabs", "fmin", "fmax", "sign",
              "floor", "ceil", "lt", "le", "eq", "ne", "not", "and", "or", "if_else_zero"}


def periodic_in(x: cs.SX, outputs: Sequence[cs.SX], i: int) -> bool:
    """Whether every output is ``2 pi``-periodic in ``x[i]``, shown from the expression graph.

    Sound and conservative: the outputs must depend on ``x[i]`` only through ``sin`` or ``cos``
    (or ``atan2`` of such) of ``k x[i] + (terms without x[i])`` with an integer ``k``; anything
    else (``x[i]`` itself, ``x[i]**2``, ``atan2`` of it, a non-integer multiple) is not shown
    periodic, whatever its values, and the caller must then treat ``x[i]`` as an ordinary
    coordinate (check its faces).
    """
    flat = cs.vertcat(*[cs.vec(cs.densify(cs.SX(o))) for o in outputs])
    fn = cs.Function("periodic", [x], [flat], {"live_variables": False})
    kind: dict[int, tuple[str, float]] = {}   # slot -> ("free" | "affine" | "periodic" | "other", k)
    value: dict[int, float] = {}
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        name = _OPS.get(op, str(op))
        ins, outs = fn.instruction_input(k), fn.instruction_output(k)
        if name == "output":
            if kind.get(ins[0], ("free", 0))[0] in ("affine", "other"):
                return False
            continue
        if name == "input":
            kind[outs[0]] = ("affine", 1.0) if ins[1] == i else ("free", 0.0)
            continue
        if name == "const":
            kind[outs[0]] = ("free", 0.0)
            value[outs[0]] = float(fn.instruction_constant(k))
            continue
        args = [a for a in ins if a >= 0][:2 if name in _BINARY else 1]
        ks = [kind.get(a, ("free", 0.0)) for a in args]
        tags = {t for t, _ in ks}
        out: tuple[str, float]
        if tags <= {"free"}:
            out = ("free", 0.0)
            if name == "neg" and args[0] in value:
                value[outs[0]] = -value[args[0]]
        elif "other" in tags:
            out = ("other", 0.0)
        elif "affine" not in tags:
            out = ("periodic", 0.0)         # any operation on periodic and free operands
        elif name in ("sin", "cos"):
            out = ("periodic", 0.0) if ks[0][1] == round(ks[0][1]) else ("other", 0.0)
        elif name in ("add", "sub") and "periodic" not in tags:
            sign = -1.0 if name == "sub" else 1.0
            kk = ks[0][1] + sign * ks[1][1]
            out = ("affine", kk) if kk != 0 else ("free", 0.0)
        elif name in ("neg", "twice", "assign"):
            out = ("affine", {"neg": -1.0, "twice": 2.0, "assign": 1.0}[name] * ks[0][1])
        elif name == "mul" and tags == {"affine", "free"}:
            j = 1 if ks[0][0] == "affine" else 0
            c = value.get(args[j])
            out = ("affine", ks[1 - j][1] * c) if c is not None and c == round(c) and c != 0 \
                else ("other", 0.0)
        else:
            out = ("other", 0.0)
        kind[outs[0]] = out
    return True


def is_polynomial(x: cs.SX, outputs: Sequence[cs.SX]) -> bool:
    """Whether every output is a polynomial in ``x`` by its expression graph: only sums,
    products, non-negative integer powers and divisions by constants of ``x``.

    ``casadi.is_quadratic`` asks whether the Hessian (by automatic differentiation) is constant,
    which ``sign``, ``fabs``, ``fmin``, ``floor`` or comparisons fool (their derivatives are 0 or
    a selection): ``-x^2 + 3 |x|`` has the constant AD Hessian ``-2``. Callers that rely on
    Taylor's formula being exact check this first.
    """
    flat = cs.vertcat(*[cs.vec(cs.densify(cs.SX(o))) for o in outputs])
    fn = cs.Function("poly", [x], [flat], {"live_variables": False})
    varying: dict[int, bool] = {}
    value: dict[int, float] = {}
    for k in range(fn.n_instructions()):
        name = _OPS.get(fn.instruction_id(k), "")
        ins, outs = fn.instruction_input(k), fn.instruction_output(k)
        if name == "output":
            continue
        if name == "input":
            varying[outs[0]] = True
            continue
        if name == "const":
            varying[outs[0]] = False
            value[outs[0]] = float(fn.instruction_constant(k))
            continue
        args = [a for a in ins if a >= 0][:2 if name in _BINARY else 1]
        var = [varying.get(a, False) for a in args]
        if not any(var):
            varying[outs[0]] = False
            continue
        if name in ("add", "sub", "mul", "neg", "twice", "assign", "sq"):
            pass
        elif name == "div" and not var[1]:
            pass
        elif name == "constpow" and not var[1]:
            e = value.get(args[1])
            if e is None or e < 0 or e != round(e):
                return False
        else:
            return False
        varying[outs[0]] = True
    return True
