"""What a Lyapunov check decided: :class:`LyapunovReport` and its statuses."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hybridnav.fileio import json_ready

__all__ = ["STATUSES", "LyapunovReport"]

log = logging.getLogger(__name__)


STATUSES = ("proved", "no_counterexample", "counterexample", "undecided")


@dataclass
class LyapunovReport:
    """What :func:`check_lyapunov` decided and how.

    Attributes
    ----------
    status : str
        ``"proved"``, ``"no_counterexample"``, ``"counterexample"`` or ``"undecided"``.
    V, vdot : str
        The candidate and its derivative along the closed loop, as readable expressions (with the
        model's parameter and target symbols ``x1, y1``).
    counterexample : ndarray or None
        A state with ``Vdot >= 0`` or with ``V < 0`` (only when ``status == "counterexample"``;
        ``details["counterexample_V"]`` and ``details["counterexample_vdot"]`` hold its values).
    worst_vdot : float
        The largest ``Vdot`` seen in the region away from the equilibrium.
    worst_state : ndarray or None
        Where it was seen.
    method : str
        How the status was decided.
    vdot_nonpositive_proved : bool
        ``Vdot <= 0`` everywhere was established exactly (quadratic forms, a gradient flow or a
        certificate).
    claim : str
        When ``status == "proved"``: what was proved and on which set.
    route : str
        Which argument decided: ``"quadratic"``, ``"certificate"`` (interval branch and bound),
        ``"lasalle"`` (branch and bound on LaSalle's conditions), ``"sampling"``, ``"ipopt"``,
        ``"gradient_flow"`` or ``"local"``.
    details : dict
        Numbers behind the decision (eigenvalues, sample counts, optimizer runs, ...).
    """

    status: str
    V: str
    vdot: str
    counterexample: np.ndarray | None
    worst_vdot: float
    worst_state: np.ndarray | None
    method: str
    vdot_nonpositive_proved: bool = False
    claim: str = ""
    route: str = ""
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "status": self.status,
            "claim": self.claim,
            "route": self.route,
            "V": self.V,
            "vdot": self.vdot,
            "counterexample": None if self.counterexample is None else self.counterexample.tolist(),
            "worst_vdot": _num(self.worst_vdot),
            "worst_state": None if self.worst_state is None else self.worst_state.tolist(),
            "method": self.method,
            "vdot_nonpositive_proved": self.vdot_nonpositive_proved,
            "details": json_ready(self.details),
        }


def _counterexample(report: LyapunovReport, both, state, method: str,
                    witness=None) -> LyapunovReport:
    """Record a counterexample after re-evaluating V and Vdot there (and their interval
    enclosures, from ``witness``, which the caller has checked decide the sign)."""
    state = np.asarray(state, dtype=float).ravel()
    v, d = (float(np.asarray(a).item()) for a in both(state))
    report.status = "counterexample"
    report.counterexample = state
    report.worst_state = state
    report.worst_vdot = d
    report.details.update(counterexample_V=v, counterexample_vdot=d)
    encl = ""
    if witness is not None and witness.exact:
        lo, hi = witness.enclose(state)
        report.details.update(counterexample_V_enclosure=[float(lo[0, 0]), float(hi[0, 0])],
                              counterexample_vdot_enclosure=[float(lo[0, 1]), float(hi[0, 1])])
        encl = (f"; interval enclosures V in [{lo[0, 0]:.6g}, {hi[0, 0]:.6g}], Vdot in "
                f"[{lo[0, 1]:.6g}, {hi[0, 1]:.6g}]")
    report.method = f"{method} (re-evaluated there: V = {v:.6g}, Vdot = {d:.6g}{encl})"
    return report


def _num(v: float) -> float | None:
    v = float(v)
    return v if np.isfinite(v) else None
