"""Equilibria of closed loops (multistart Newton), classified by their Jacobian's eigenvalues."""

from __future__ import annotations

import copy
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as cs
import numpy as np
from scipy.optimize import root

from hybridnav.analysis.region import Box, as_box
from hybridnav.analysis.verdict import _num
from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model
from hybridnav.models.compile import _Buffered, evaluate_rows

__all__ = ["Equilibrium", "find_equilibria"]

log = logging.getLogger(__name__)


@dataclass
class Equilibrium:
    """An equilibrium of a closed loop: state, Jacobian eigenvalues and their classification."""

    state: np.ndarray
    eigenvalues: np.ndarray
    kind: str        # "stable", "saddle", "unstable" or "degenerate"
    V: float
    is_target: bool

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"state": self.state.tolist(),
                "eigenvalues": [[float(e.real), float(e.imag)] for e in self.eigenvalues],
                "kind": self.kind, "V": _num(self.V), "is_target": self.is_target}


def find_equilibria(
    model: Model,
    *,
    target: Sequence[float] | None = None,
    region: Mapping[str, Sequence[float]] | Box,
    equilibrium: Sequence[float] | None = None,
    seed: int = 0,
    starts: int = 400,
) -> list[Equilibrium]:
    """Equilibria of the closed loop in a region, by multistart Newton (scipy ``root``).

    Newton starts from ``starts`` uniform samples, from the points of a dense sample where the
    vector field is smallest, and from the end points of 200-second closed-loop runs (which
    settle in stable equilibria, however small their basin).

    A Newton end point ``z`` counts when interval arithmetic (outward rounded) on the box
    ``z +- 1e-9 x`` (the region's extent in each state; at least 64 ulps of ``z``) proves a zero
    there (the Krawczyk test), or ``f(z)`` is 0 to rounding, or the box cannot be cleared of a
    zero -- tests in the state's units, not the field's, so a slow field's small values are not
    taken for zeros and a fast field's zeros are not refused. A zero is excluded from a box by
    the field's enclosure, or by its centred form preconditioned with the inverse and the
    singular vectors of the Jacobian (no dependency blow-up, and two components that vanish on
    parallel curves but never together are seen), row by row where only some rows are smooth.
    Where neither decides, the box is bisected (each part along the state that widens the
    enclosure most) and the parts that exclude a zero dropped: the point is refused when none is
    left (a field that only comes within rounding-sized distance of 0), or when more than 4,096
    parts are left or the call's bisection budget (400 rounds) is spent (undecided: not claimed),
    and counts when a part is left on which the field is continuous, or, where it may jump
    (``if_else``, ``floor``, ``sign``, ``atan2`` across its cut), where the components that may
    jump are 0 to rounding at a point of that part where they are decided (or exactly 0): a
    jump across 0 is no zero, and a zero strictly between two floats of such a component is
    missed. The same holds for ``f(z)`` itself. Points
    within a millionth of the region's extent in every state, or whose boxes overlap, are one
    equilibrium. Only admissible states count (see
    :meth:`hybridnav.models.Model.state_constraints`).

    Each is classified by the eigenvalues of the exact Jacobian at ``z``: ``"degenerate"`` where
    a perturbation as large as the Jacobian's uncertainty (how far it can move over the zero's
    box -- where no zero was proved in it, over twice the Newton step ``|J(z)^-1| |f(z)|`` that
    ``f(z)``'s rounding allows -- plus rounding) can put an eigenvalue on the imaginary axis
    (the smallest singular value of ``J - i w I`` over ``w``), or the Jacobian is not finite;
    else ``"stable"`` (all real parts negative: a local minimum of ``V`` for a gradient flow),
    ``"unstable"`` or ``"saddle"``.

    Parameters
    ----------
    model : Model or any system :func:`~hybridnav.analysis.system.as_system` takes
    target : (float, float), optional
        The target the closed loop drives to (a robot model).
    region : dict or Box
        Bounds of every state (``{name: (lo, hi)}``).
    seed : int
        Seeds the sampled starts.
    starts : int
        Uniform random Newton starts (besides the smallest-field points and the run ends).
    equilibrium : sequence of float, optional
        For a general system: the equilibrium state of interest (reported as ``is_target``).
    """
    model, tgt = resolve(model, target, equilibrium)
    box = as_box(model, region)
    for key, v in (("seed", seed), ("starts", starts)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < (1 if key ==
                                                                                 "starts" else 0):
            raise HybridnavError(f"{key}: expected a {'positive' if key == 'starts' else 'non-negative'} "
                                 f"integer, got {v!r}")
    key = (model._key(), tuple(tgt), tuple(box.lower), tuple(box.upper), int(seed), int(starts))
    if key not in _EQUILIBRIA:
        if len(_EQUILIBRIA) >= 32:
            _EQUILIBRIA.pop(next(iter(_EQUILIBRIA)))
        _EQUILIBRIA[key] = _find_equilibria(model, tgt, box, seed, starts)
    return copy.deepcopy(_EQUILIBRIA[key])


#: find_equilibria's results, by model, target, region, seed and starts (deterministic, and the
#: analysis asks the same question several times: the check, the ROA, its candidates)
_EQUILIBRIA: dict[tuple, list[Equilibrium]] = {}


def _find_equilibria(model: Model, tgt: np.ndarray, box: Box, seed: int, starts: int
                     ) -> list[Equilibrium]:
    s = model.sym
    values = cs.DM(np.concatenate([tgt, model.p_value()]))
    f = model.closed_loop_at(tgt)
    v = cs.substitute(model.lyapunov_candidate(), cs.vertcat(s.target, s.p), values)
    F = cs.Function("F", [s.x], [f, cs.jacobian(f, s.x), v])
    rng = np.random.default_rng(seed)
    X0 = box.sample(starts, rng)
    X0 = X0[model.admissible(X0)]
    # small basins are easy to miss with uniform starts: also start from the points of a dense
    # sample where |F| is smallest, and from where short closed-loop runs end up
    dense = box.sample(50 * starts, rng)
    dense = dense[model.admissible(dense)]
    if len(dense):
        fd = evaluate_rows(cs.Function("f", [s.x], [f]), dense)[0].T
        norm = np.linalg.norm(np.where(np.isfinite(fd), fd, np.inf), axis=0)
        runs = model.rollout(dense[:starts], np.tile(tgt, (min(starts, len(dense)), 1)),
                             min(int(round(200.0 / model.dt)), 5000))[:, -1]
        runs = runs[np.all(np.isfinite(runs), axis=1) & box.contains(runs)]
        X0 = np.vstack([X0, dense[np.argsort(norm)[:starts // 2]], runs])
    span = float(np.max(box.upper - box.lower)) or 1.0
    # Newton calls f and its Jacobian tens of times per start: each through a CasADi buffer
    # (CasADi's matrices convert to NumPy through Python lists) and on its own (F computes all
    # three); the same expressions, so the same values
    nx = model.nx
    fb = _Buffered(cs.Function("f", [s.x], [cs.densify(f)]), [(nx,)], [(nx,)])
    jb = _Buffered(cs.Function("J", [s.x], [cs.densify(cs.jacobian(f, s.x))]), [(nx,)],
                   [(nx * nx,)])

    def fun(z):
        fb.ins[0][:] = z
        fb()
        return fb.outs[0].copy()

    def jac(z):
        jb.ins[0][:] = z
        jb()
        return jb.outs[0].reshape(nx, nx, order="F").copy()

    cands = []
    for x0 in X0:
        with np.errstate(all="ignore"):
            sol = root(fun, x0, jac=jac, method="hybr", tol=1e-14)
        z = sol.x
        fz, jz, vz = (np.asarray(a) for a in F(z))
        if not np.all(np.isfinite(fz)):
            continue
        if not box.contains(z) or not model.admissible(z[None])[0]:
            continue
        cands.append((z, fz.ravel(), jz, vz))
    widths = np.asarray(box.upper, dtype=float) - np.asarray(box.lower, dtype=float)
    extent = np.where(widths > 0, widths, span)
    near = 1e-6 * extent
    tests = _ZeroTests(s.x, f, cands, span, extent)
    found: list[Equilibrium] = []
    radii: list[np.ndarray] = []
    for i, (z, fz, jz, vz) in enumerate(cands):
        if tests.excluded_fast(i):
            continue
        r = tests.radius[i]
        # the same equilibrium again: within a millionth of the region's extent in every state
        # (each state's own: one long side must not merge points of a short one), or within
        # the two zero boxes
        if any(np.all(np.abs(z - e.state) <= np.maximum(near, r + re))
               for e, re in zip(found, radii)):
            continue
        if not tests.accepted(i):
            continue
        eig, kind = _classify(jz, tests.jacobian_spread(i))
        is_target = bool(np.all(np.abs(z[:len(tgt)] - tgt) <= near[:len(tgt)]))
        found.append(Equilibrium(z, eig, kind, float(vz.item()), is_target))
        radii.append(r)
    found.sort(key=lambda e: (not e.is_target, e.V))
    return found


#: half-width of the box around a Newton end point that is tested for a zero, relative to the
#: region's extent in each state (and at least 64 ulps of the point)
ZERO_BOX = 1e-9


class _ZeroTests:
    """Whether each Newton end point ``z`` is an equilibrium, tested on ``X = z +- r``,
    ``r = ZERO_BOX x`` the region's extent per state (at least 64 ulps of ``z``), with
    outward-rounded interval arithmetic.

    A zero in a box is excluded by the enclosure of ``f`` on it, or, where ``f`` is smooth on
    it, by the centred form ``P f(c) + P J(box) (box - c)``, which holds ``P f(x)`` for every
    ``x`` in the box (the mean value theorem, row by row) for any matrix ``P``: the inverse of
    ``J(z)`` (a scale-free test, free of the dependency that widens ``f``'s own enclosure), and
    the left singular vectors of ``J(z)`` (its near-null rows see ``f1 - f2 = 1e-10`` through a
    singular Jacobian).

    ``z`` is refused when a zero in ``X`` is excluded, and accepted when the Krawczyk operator
    proves one there, or ``f(z)`` is 0 to rounding. Otherwise (a degenerate or non-smooth zero,
    or a field that only comes close to 0) ``X`` is bisected, each part along the state that
    widens the enclosure most (never a state ``f`` does not depend on), and the parts that
    exclude a zero are dropped (up to ``SUBDIVIDE_ROUNDS`` rounds): ``z`` is refused when none
    is left, or when more than ``SUBDIVIDE_BOXES`` are (undecided: a curve of parts, of zeros or
    of near-zeros; the Newton ends whose boxes meet that box are refused too), and accepted when
    a part is left on which ``f`` is continuous (interval flags), or, where it may jump (an
    undecided ``if_else``, ``floor``, ``atan2`` across its cut), where the components that may
    jump are 0 to rounding at a point of the part (``z``, its centre or a corner) where they are
    decided, or exactly 0 (an ``if_else`` condition the point's rounding leaves open gives both
    branches' hull, no value), and -- ``f`` having a step operation -- the other components are
    0 to rounding at that point too: a jump across 0 is no zero. The call spends at most
    ``SUBDIVIDE_BUDGET`` rounds on points it refuses (an accepted point's rounds are given
    back); the points left when it is spent are undecided.
    Without an interval extension of ``f`` (an operation it lacks), the Newton step at ``z`` must
    be within ``r`` and ``f(z)`` in the range of the Jacobian, and ``|f(z)| < 1e-9 max(1, span)``.
    """

    def __init__(self, x: cs.SX, f: cs.SX, cands: list, span: float,
                 extent: np.ndarray) -> None:
        from hybridnav.analysis.interval import (IntervalFunction, UnsupportedOperation,
                                                 may_step)

        self.cands, self.span = cands, span
        self.n = n = int(x.numel())
        Z = np.array([c[0] for c in cands], dtype=float).reshape(len(cands), n)
        # a billionth of the region's extent per state (not of |z|: two zeros 0.15 apart at
        # 1e8 have boxes of their own), and never below 64 ulps of z (where Newton ends)
        self.radius = np.maximum(ZERO_BOX * extent[None, :], 64.0 * np.spacing(np.abs(Z)))
        self.proved: set[int] = set()
        self.undecided: list[tuple[np.ndarray, np.ndarray]] = []
        self.rounds_left = SUBDIVIDE_BUDGET
        self.ifn = None
        if not len(cands):
            return
        try:
            self.ifn = IntervalFunction(x, [f, cs.jacobian(f, x)])
        except UnsupportedOperation:
            return
        self.lo, self.hi, self.smooth, self.cont = self.ifn(Z - self.radius, Z + self.radius,
                                                            continuity=True)
        self.plo, self.phi, _, self.pcont = self.ifn(Z, Z, continuity=True)
        self.steps = may_step(x, f)

    def _small(self, i: int) -> bool:
        return bool(np.linalg.norm(self.cands[i][1]) < 1e-9 * max(1.0, self.span))

    def excluded_fast(self, i: int) -> bool:
        """The enclosure of ``f`` on the box leaves out 0 in some component."""
        if self.ifn is None:
            return False
        n = self.n
        return bool(np.any(self.lo[i, :n] > 0) or np.any(self.hi[i, :n] < 0))

    def _preconditioners(self, i: int) -> tuple[list[np.ndarray], np.ndarray | None]:
        """The centred form's row combinations: the identity, ``J(z)``'s inverse (also
        returned, for Krawczyk) and its left singular vectors."""
        jz, n = self.cands[i][2], self.n
        pre, Y = [np.eye(n)], None
        if np.all(np.isfinite(jz)):
            try:
                Y = np.linalg.inv(jz)
                pre.append(Y)
            except np.linalg.LinAlgError:
                Y = None
            pre.append(np.linalg.svd(jz)[0].T)
        return pre, Y

    def accepted(self, i: int) -> bool:
        z, fz, jz, _ = self.cands[i]
        r, n = self.radius[i], self.n
        if self.ifn is None:
            try:
                step = np.linalg.lstsq(jz, fz, rcond=None)[0]
            except np.linalg.LinAlgError:
                return False
            resid = np.linalg.norm(fz - jz @ step)
            return bool(np.all(np.abs(step) <= r) and resid <= 1e-6 * np.linalg.norm(fz)
                        and self._small(i))
        if self.excluded_fast(i):
            return False
        fl, fh = self.plo[i, :n], self.phi[i, :n]
        Jl, Jh = self._jacobian_box(i)
        pre, Y = self._preconditioners(i)
        ok = _smooth_rows(self.smooth[i:i + 1, :n], Jl[None], Jh[None], fl[None], fh[None])[0]
        if _centred_excludes(fl[None], fh[None], Jl[None], Jh[None], ok[None], r[None], pre)[0]:
            return False                            # no zero in the box
        if (Y is not None and ok.all() and np.all(np.isfinite(Y))
                and _krawczyk(Y, (fl + fh) / 2, (fh - fl) / 2, (Jl + Jh) / 2, (Jh - Jl) / 2, r)):
            self.proved.add(i)
            return True                             # exactly one zero in the box
        if np.all((fl <= 0) & (fh >= 0)) and (not self.steps or np.all(
                self.pcont[i, :n] | ((fl == 0) & (fh == 0)))):
            return True           # f(z) is 0 to rounding (where a condition is decided at z)
        lo, hi = z - r, z + r
        if any(np.all((lo <= uh) & (ul <= hi)) for ul, uh in self.undecided):
            return False            # on the curve of a box the bisection left undecided
        return self._subdivided(i, pre)

    def _subdivided(self, i: int, pre: list[np.ndarray]) -> bool:
        # (the budget bounds the rounds spent on points refused: those of a point accepted are
        # given back, since each equilibrium is bisected once -- its neighbours are the same)
        start = self.rounds_left
        found = self._bisect(i, pre)
        if found:
            self.rounds_left = start
        return found

    def _bisect(self, i: int, pre: list[np.ndarray]) -> bool:
        """Bisect the zero box of ``i``, dropping the parts that exclude a zero: whether a part
        is left where ``f`` is continuous, or where the components that may jump are 0 to
        rounding at a point of it."""
        z, n = self.cands[i][0], self.n
        lo, hi = (z - self.radius[i])[None], (z + self.radius[i])[None]
        blo, bhi, cont = self.lo[i:i + 1], self.hi[i:i + 1], self.cont[i:i + 1, :n]
        for _ in range(SUBDIVIDE_ROUNDS):
            if self.rounds_left <= 0:
                # the call's bisection budget is spent (hundreds of Newton ends near a curve of
                # near-zeros): undecided, not claimed
                self.undecided.append((z - self.radius[i], z + self.radius[i]))
                return False
            self.rounds_left -= 1
            # split each part along the state whose width, times the Jacobian's column,
            # widens the enclosure most (a state f does not depend on is not split)
            L = np.maximum(np.abs(blo[:, n:]), np.abs(bhi[:, n:])).reshape(-1, n, n, order="F")
            w = hi - lo
            with np.errstate(invalid="ignore"):
                score = np.where(np.isfinite(L), L, np.inf).sum(axis=1) * w
            score = np.where(np.isnan(score), np.inf, score)
            rel = w / self.radius[i]
            # (a part whose Jacobian vanishes: by its width relative to the zero box; among
            # unbounded columns, the widest relative to it)
            flat = np.all(score == 0, axis=1)
            score[flat] = rel[flat]
            unbounded = np.isinf(score)
            score = np.where(unbounded.any(axis=1)[:, None],
                             np.where(unbounded, rel, -1.0), score)
            # only states a part can still be split in (wider than adjacent floats)
            middle = (lo + hi) / 2
            splittable = (middle > lo) & (middle < hi)
            score = np.where(splittable, score, -2.0)
            j = np.argmax(score, axis=1)
            rows = np.arange(len(lo))
            mid = middle[rows, j]
            can = splittable[rows, j]
            if not can.any():
                break
            keep_lo, keep_hi = lo[~can], hi[~can]
            lo, hi, j, mid = lo[can], hi[can], j[can], mid[can]
            left_hi, right_lo = hi.copy(), lo.copy()
            k = np.arange(len(lo))
            left_hi[k, j], right_lo[k, j] = mid, mid
            lo = np.vstack([keep_lo, lo, right_lo])
            hi = np.vstack([keep_hi, left_hi, hi])
            blo, bhi, smooth, cont = self.ifn(lo, hi, continuity=True)
            c = (lo + hi) / 2
            clo, chi, _ = self.ifn(c, c)
            Jl = blo[:, n:].reshape(-1, n, n, order="F")
            Jh = bhi[:, n:].reshape(-1, n, n, order="F")
            ok = _smooth_rows(smooth[:, :n], Jl, Jh, clo[:, :n], chi[:, :n])
            out = (np.any(blo[:, :n] > 0, axis=1) | np.any(bhi[:, :n] < 0, axis=1)
                   | _centred_excludes(clo[:, :n], chi[:, :n], Jl, Jh, ok,
                                       np.maximum(c - lo, hi - c), pre))
            lo, hi, blo, bhi, cont = lo[~out], hi[~out], blo[~out], bhi[~out], cont[~out, :n]
            if not len(lo):
                return False                        # every part excludes a zero
            if len(lo) > SUBDIVIDE_BOXES:
                # a curve of parts nothing excludes yet (of zeros, or of near-zeros a finer
                # bisection would exclude): undecided within the budget, so not claimed (nor
                # the other Newton ends whose boxes meet this one)
                self.undecided.append((z - self.radius[i], z + self.radius[i]))
                return False
        # without an operation that can jump, f is continuous wherever it is defined (a finite
        # enclosure): sqrt at 0 is not Lipschitz, but continuous
        jumps = ~cont
        if not self.steps:
            jumps &= ~(np.isfinite(blo[:, :n]) & np.isfinite(bhi[:, :n]))
        if (~jumps).all(axis=1).any():
            return True                             # a part where f is continuous is left
        # test points of every part, in one batch: its ends, its centre, z where it holds z,
        # and (n <= 4) its corners
        pts, owner = [lo, hi, (lo + hi) / 2], [np.arange(len(lo))] * 3
        inside = np.all((lo <= z) & (z <= hi), axis=1)
        pts.append(np.broadcast_to(z, (int(inside.sum()), n)))
        owner.append(np.nonzero(inside)[0])
        if n <= 4:
            pick = np.array(np.meshgrid(*[[0, 1]] * n, indexing="ij")).reshape(n, -1).T
            for corner in pick.astype(bool):
                pts.append(np.where(corner, hi, lo))
                owner.append(np.arange(len(lo)))
        P, owner = np.vstack(pts), np.concatenate(owner)
        plo, phi, _, pcont = self.ifn(P, P, continuity=True)
        plo, phi, pcont = plo[:, :n], phi[:, :n], pcont[:, :n]
        if not self.steps:              # (sqrt or a power at 0: continuous, only not Lipschitz)
            pcont = np.isfinite(plo) & np.isfinite(phi)
        # (exactly 0 is a value whatever the branches: sign(0) sqrt|0|)
        pcont = pcont | ((plo == 0) & (phi == 0))
        # a point where the jumping components are decided (a condition the point's rounding
        # leaves open gives the hull of both branches, no value) and 0 to rounding -- with a
        # step operation in f, every component there: where a jump meets 0 the others must
        # vanish too (sign(x) = 0 only at x = 0)
        holds = (plo <= 0) & (phi >= 0)
        rest = ~jumps[owner] & (holds if self.steps else True)
        return bool(np.any(np.all((holds & pcont) | rest, axis=1)))

    def _jacobian_box(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """The enclosure of the Jacobian on box ``i``: its lower and upper bound matrices."""
        n = self.n
        return (self.lo[i, n:].reshape(n, n, order="F"),
                self.hi[i, n:].reshape(n, n, order="F"))

    def jacobian_spread(self, i: int) -> float:
        """How far the Jacobian can be from ``J(z)`` at a zero near ``z`` (its enclosure's
        largest deviation, 2-norm bound): on the zero box where Krawczyk proved the zero in it;
        otherwise also over where ``f(z)``'s uncertainty lets the zero be (twice the Newton
        step ``|J(z)^-1| |f(z)|``: a zero ``1 - cos x`` hides by rounding to 0). Without an
        interval extension, ``1e-12 |J(z)|`` for its evaluation's rounding."""
        n, z, jz = self.n, self.cands[i][0], self.cands[i][2]
        if self.ifn is None:          # only J(z)'s evaluation: its rounding, generously
            return 1e-12 * float(np.linalg.norm(jz, 2)) if np.all(np.isfinite(jz)) else np.inf
        Jl, Jh = self._jacobian_box(i)
        if i not in self.proved:
            fa = np.maximum(np.abs(self.plo[i, :n]), np.abs(self.phi[i, :n]))
            _, Y = self._preconditioners(i)
            reach = 2.0 * (np.abs(Y) @ fa) if Y is not None else np.zeros(n)
            R = np.where(np.isfinite(reach), np.maximum(self.radius[i], reach), np.inf)
            blo, bhi, _ = self.ifn((z - R)[None], (z + R)[None])
            Jl = blo[0, n:].reshape(n, n, order="F")
            Jh = bhi[0, n:].reshape(n, n, order="F")
        dev = np.maximum(np.abs(Jh - jz), np.abs(jz - Jl))
        if not np.all(np.isfinite(dev)):
            return np.inf
        return float(np.linalg.norm(dev, "fro"))


#: the zero box's bisection when no test decides it: rounds, and the most parts kept
SUBDIVIDE_ROUNDS = 64
SUBDIVIDE_BOXES = 4096
#: bisection rounds one find_equilibria call spends in all (each evaluates its parts' enclosures
#: once, as a batch); the Newton ends left when it is spent are undecided and not reported
SUBDIVIDE_BUDGET = 400


def _smooth_rows(smooth, Jl, Jh, fl, fh) -> np.ndarray:
    """Per box, the rows of ``f`` smooth on it with a finite Jacobian row there and a finite
    ``f(c)``: the mean value theorem holds for them (and for combinations of them only)."""
    return (smooth & np.all(np.isfinite(Jl) & np.isfinite(Jh), axis=2)
            & np.isfinite(fl) & np.isfinite(fh))


def _centred_excludes(fl, fh, Jl, Jh, ok, r, pre) -> np.ndarray:
    """Per box ``b`` (centre ``c``, half-widths ``r[b]``, ``f(c)`` in ``[fl, fh]``, ``J`` in
    ``[Jl, Jh]`` on it, rows ``ok`` smooth): whether the centred form ``P f(c) + P J (x - c)``
    leaves out 0 in a row for some ``P`` in ``pre`` -- rows combining smooth rows only, the
    float products and sums rounded up (a relative 1e-12 of every term, and 1e-300)."""
    with np.errstate(invalid="ignore", over="ignore"):    # (rows not ok: masked out)
        fm, fr = np.where(ok, (fl + fh) / 2, 0.0), np.where(ok, (fh - fl) / 2, 0.0)
        Jm = np.where(ok[:, :, None], (Jl + Jh) / 2, 0.0)
        Jr = np.where(ok[:, :, None], (Jh - Jl) / 2, 0.0)
    out = np.zeros(len(fm), dtype=bool)
    for P in pre:
        rows = (np.all((P[None] == 0) | ok[:, None, :], axis=2)
                & np.all(np.isfinite(P), axis=1)[None])
        if not rows.any():
            continue
        P = np.where(np.isfinite(P), P, 0.0)
        aP = np.abs(P)
        center = fm @ P.T
        aPJr = aP @ Jr                                  # (B, k, n): P times each box's matrix
        rc = r[:, :, None]
        width = fr @ aP.T + ((np.abs(P @ Jm) + aPJr) @ rc)[:, :, 0]
        width += 1e-12 * (np.abs(fm) @ aP.T + ((aP @ np.abs(Jm) + aPJr) @ rc)[:, :, 0])
        out |= np.any(rows & (np.abs(center) > width * (1 + 1e-12) + 1e-300), axis=1)
    return out


def _classify(jz: np.ndarray, spread: float) -> tuple[np.ndarray, str]:
    """The eigenvalues of ``J(z)`` and the kind of equilibrium: ``"degenerate"`` where a
    perturbation of the Jacobian as large as its uncertainty (its spread over the zero's box,
    plus rounding) can put an eigenvalue on the imaginary axis -- the smallest singular value of
    ``J - i w I`` over ``w`` (the distance to the axis's pseudospectrum; right for Jordan blocks,
    whose eigenvalues move like a root of the perturbation) is no larger -- else by the signs of
    the real parts. A non-finite Jacobian is degenerate."""
    from scipy.optimize import minimize_scalar

    n = jz.shape[0]
    if not np.all(np.isfinite(jz)):
        return np.full(n, np.nan + 0j), "degenerate"
    eig = np.linalg.eigvals(jz)
    norm = float(np.linalg.norm(jz, 2))
    # the spread encloses J(z)'s evaluation error; the SVD adds a few eps |J| of its own
    delta = spread + 4 * n * np.finfo(float).eps * norm + 1e-300
    eye = np.eye(n)

    def smin(w: float) -> float:
        return float(np.linalg.svd(jz - 1j * w * eye, compute_uv=False)[-1])

    # the minimum over w lies near the imaginary parts of the eigenvalues nearest the axis:
    # start there (and at 0), refine each locally
    starts = sorted({0.0, *np.abs(eig.imag).tolist()})
    dist = min(smin(w) for w in starts)
    if dist > delta:
        for w in starts:
            step = max(abs(w), norm, 1e-300) * 0.5
            res = minimize_scalar(smin, bounds=(max(0.0, w - step), w + step), method="bounded",
                                  options={"xatol": 1e-12 * max(abs(w), norm, 1e-300)})
            dist = min(dist, float(res.fun))
            if not dist > delta:
                break
    re = eig.real
    if not dist > delta:
        return eig, "degenerate"
    if np.all(re < 0):
        return eig, "stable"
    if np.all(re > 0):
        return eig, "unstable"
    return eig, "saddle"


def _target(target, model: Model | None = None) -> np.ndarray:
    """The target as a vector: a robot's ``(x1, y1)``, or a system's whole equilibrium state."""
    k = 2 if model is None else model.target_size
    try:
        t = np.asarray(target, dtype=float).ravel()
    except (TypeError, ValueError):
        t = None
    if t is None or t.shape != (k,) or not np.all(np.isfinite(t)):
        if not hasattr(model, "equilibrium"):        # a robot model
            raise HybridnavError(f"target: expected two finite numbers (x1, y1), got {target!r}")
        raise HybridnavError(
            f"equilibrium: expected {k} finite numbers ({', '.join(model.state_names)}), got "
            f"{target!r}")
    return t


def resolve(model, target=None, equilibrium=None) -> tuple[Model, np.ndarray]:
    """The analysed model (:func:`~hybridnav.analysis.system.as_system` of any system) and its
    target or equilibrium, validated.

    Raises
    ------
    HybridnavError
        Both or neither given (a system's own ``equilibrium`` is the default), or wrong sizes.
    """
    from hybridnav.analysis.system import as_system

    model = as_system(model)
    if target is not None and equilibrium is not None:
        raise HybridnavError("equilibrium: pass target= or equilibrium=, not both")
    t = equilibrium if equilibrium is not None else target
    if t is None:
        t = getattr(model, "equilibrium", None)
    if t is None:
        what = ("equilibrium: required (the state the analysis is about, "
                f"{', '.join(model.state_names)})" if hasattr(model, "equilibrium")
                else "target: required (the point (x1, y1) the closed loop drives to)")
        raise HybridnavError(what)
    return model, _target(t, model)


def verify_zero(x, f, c, radii=(1e-10, 1e-8, 1e-6, 1e-4)) -> dict[str, Any] | None:
    """A box around ``c`` that provably holds exactly one zero of ``f`` (the Krawczyk test).

    With ``Y`` the inverse of the Jacobian at ``c`` and ``X = c + [-r, r]``,
    ``K(X) = c - Y f(c) + (I - Y J(X)) (X - c)`` is enclosed by interval arithmetic
    (:class:`~hybridnav.analysis.interval.IntervalFunction`); ``K(X)`` inside ``X`` proves a
    unique zero of ``f`` in ``X`` (Krawczyk 1969, Moore 1977).

    Parameters
    ----------
    x : casadi.SX
        The symbols.
    f : casadi.SX
        As many expressions as symbols.
    c : array_like
        The approximate zero.
    radii : sequence of float
        Half-widths tried, relative to ``1 + |c|``.

    Returns
    -------
    dict or None
        ``{"center", "radius"}`` of the box, or None when no radius passes.
    """
    from hybridnav.analysis.interval import IntervalFunction, UnsupportedOperation

    c = np.asarray(c, dtype=float).ravel()
    n = len(c)
    try:
        F = IntervalFunction(x, [f, cs.jacobian(f, x)])
    except UnsupportedOperation:
        return None
    pl, ph, _ = F(c[None], c[None])
    J = (pl[0, n:] + ph[0, n:]).reshape(n, n, order="F") / 2
    try:
        Y = np.linalg.inv(J)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(Y)):
        return None
    fm, fr = (pl[0, :n] + ph[0, :n]) / 2, (ph[0, :n] - pl[0, :n]) / 2
    for rel in radii:
        r = rel * (1.0 + np.abs(c))
        ol, oh, sm = F((c - r)[None], (c + r)[None])
        # the Jacobian's enclosure bounds f's slopes only where f is smooth on the box (a jump
        # of f has derivative 0 by automatic differentiation)
        if not (np.all(np.isfinite(ol)) and np.all(np.isfinite(oh)) and sm[0].all()):
            continue
        Jl = ol[0, n:].reshape(n, n, order="F")
        Jh = oh[0, n:].reshape(n, n, order="F")
        if _krawczyk(Y, fm, fr, (Jl + Jh) / 2, (Jh - Jl) / 2, r):
            return {"center": c.tolist(), "radius": r.tolist()}
    return None


def _krawczyk(Y, fm, fr, Jm, Jr, r) -> bool:
    """Whether ``K(X) = c - Y f(c) + (I - Y J(X)) (X - c)`` lies inside ``X = c +- r``: exactly
    one zero of ``f`` in ``X`` (Krawczyk 1969, Moore 1977). ``f(c)`` is ``fm +- fr`` and
    ``J(X)`` is ``Jm +- Jr``, enclosures; the float sums and products are rounded up."""
    aY = np.abs(Y)
    reach = np.abs(Y @ fm) + aY @ fr + (np.abs(np.eye(len(r)) - Y @ Jm) + aY @ Jr) @ r
    return bool(np.all(reach * (1 + 1e-12) + 1e-300 < r))
