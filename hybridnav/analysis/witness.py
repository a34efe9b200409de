"""What a counterexample may claim: ``V`` and ``Vdot`` at single states, enclosed by interval
arithmetic before any sign is reported.

Floating-point values near zero decide nothing: ``Vdot`` evaluated as ``1e-17`` may be exactly
``-7e-13`` (a stiff sum) or exactly ``-1e-33`` (a quantity vanishing on a curve no float lies on).
:class:`Witness` evaluates the expressions on the degenerate box ``[x, x]``, whose enclosure holds
the exact value of the expression (with its floating-point constants) at ``x``; a sign is claimed
only when the enclosure shows it.
"""

from __future__ import annotations

import casadi as cs
import numpy as np

from hybridnav.analysis.interval import IntervalFunction, UnsupportedOperation

__all__ = ["Witness"]


class Witness:
    """Enclosures of ``V`` and ``Vdot`` at states.

    Parameters
    ----------
    x : casadi.SX
        State symbols.
    V, vdot : casadi.SX
        In ``x`` only.

    Notes
    -----
    Where an expression has no interval extension, the floating-point value stands in (and
    :attr:`exact` is False).
    """

    def __init__(self, x: cs.SX, V: cs.SX, vdot: cs.SX) -> None:
        self._float = cs.Function("witness", [x], [V, vdot])
        try:
            self._interval: IntervalFunction | None = IntervalFunction(x, [V, vdot])
        except UnsupportedOperation:
            self._interval = None
        self.exact = self._interval is not None

    def enclose(self, points) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``, each ``(n, 2)``: the enclosures of ``(V, Vdot)`` at each state."""
        P = np.atleast_2d(np.asarray(points, dtype=float))
        if self._interval is not None:
            lo, hi, _ = self._interval(P, P)
            return lo, hi
        res = self._float.map(len(P))(P.T)
        out = np.stack([np.asarray(r, dtype=float).ravel() for r in res], axis=1)
        nan = np.isnan(out)
        return np.where(nan, -np.inf, out), np.where(nan, np.inf, out)

    def within_level(self, point, level: float | None) -> bool:
        """Whether the state surely lies in ``{V <= level}`` (its V enclosure's upper end at
        most ``level``); always True without a level."""
        return level is None or bool(self.enclose(point)[1][0, 0] <= level)

    def v_negative(self, points) -> np.ndarray:
        """Where ``V < 0`` surely."""
        return self.enclose(points)[1][:, 0] < 0

    def vdot_sign(self, point) -> tuple[str, float, float]:
        """``("positive" | "zero" | "negative" | "rounding", lo, hi)`` of ``Vdot`` at a state.

        ``"zero"`` is an exact zero (the enclosure is ``[0, 0]``); ``"rounding"`` an enclosure
        that holds zero and more, so the sign is not decided there.
        """
        lo, hi = self.enclose(point)
        a, b = float(lo[0, 1]), float(hi[0, 1])
        if a > 0:
            return "positive", a, b
        if a == 0 and b == 0:
            return "zero", a, b
        if b < 0:
            return "negative", a, b
        return "rounding", a, b
