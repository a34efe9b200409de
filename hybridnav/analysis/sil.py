"""Software in the loop: the compiled C controller against the Python evaluator, in closed loop.

:func:`verify` runs the EFFC planner with a :class:`~hybridnav.fuzzy.FuzzySystem` and with its C
export compiled (:class:`hybridnav.fuzzy.export.sil.CompiledFIS`) on the same scenarios and
compares every state and ``w`` sample; ``hybridnav verify`` and the tuner's report call it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hybridnav.fuzzy.export.sil import CompiledFIS

__all__ = ["verify"]


def verify(system, compiled: CompiledFIS, scenarios: Sequence[Any], *,
           seed: int = 0, **planner_params: Any) -> list[dict[str, Any]]:
    """Run the EFFC planner with the Python evaluator and with the compiled C one on each
    scenario; compare trajectories and ``w`` sample by sample.

    Parameters
    ----------
    system : FuzzySystem
        The system the C was exported from.
    compiled : CompiledFIS
    scenarios : sequence of Scenario
    seed : int
    **planner_params
        EFFC parameters (``speed``, ``max_turn``, ...).

    Returns
    -------
    list of dict
        Per scenario and robot: ``scenario``, ``robot``, ``outcome`` (Python's), ``same_outcome``,
        ``samples``, ``max_state_diff`` and ``max_w_diff`` (``inf`` when the runs have different
        lengths).
    """
    from hybridnav.planners.field.effc import EFFC

    rows = []
    for scen in scenarios:
        a = EFFC(fis=system, **planner_params).run(scen, seed=seed)
        b = EFFC(fis=compiled, **planner_params).run(scen, seed=seed)
        for ra, rb in zip(a.robots, b.robots):
            same = ra.states.shape == rb.states.shape
            ds = float(np.max(np.abs(ra.states - rb.states))) if same and ra.states.size else \
                (0.0 if same else float("inf"))
            wa = a.extras.get(f"signals_{ra.name}", {}).get("w", np.zeros(0))
            wb = b.extras.get(f"signals_{rb.name}", {}).get("w", np.zeros(0))
            dw = float(np.max(np.abs(wa - wb))) if wa.shape == wb.shape and wa.size else \
                (0.0 if wa.shape == wb.shape else float("inf"))
            rows.append({"scenario": scen.name, "robot": ra.name, "outcome": ra.outcome,
                         "same_outcome": ra.outcome == rb.outcome, "samples": len(ra.t),
                         "max_state_diff": ds, "max_w_diff": dw})
    return rows
