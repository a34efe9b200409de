"""Software in the loop, in closed loop: the compiled C controller against the Python evaluator.

:func:`verify` runs the EFFC planner with a :class:`~hybridnav.fuzzy.FuzzySystem` and with its C
export compiled (:class:`hybridnav.fuzzy.export.sil.CompiledFIS`: the C runs in a child process,
one pipe round trip per control cycle) on the same scenarios and compares every state and ``w``
sample; ``hybridnav verify`` and the tuner's report call it. The Python run's inputs go to the C
in one batch for the same-inputs comparison.
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
        lengths: a closed loop with a discontinuity — a graze that is a collision in one run, the
        safety filter's decision at its margin — can part on rounding), and
        ``same_inputs_w_diff``: the compiled evaluator's ``w`` against the Python one's on the
        inputs of the Python run, sample by sample (the export's own exactness, whatever the
        loop does).
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
            sig = a.extras.get(f"signals_{ra.name}", {})
            inputs = {k: np.asarray(sig[k]) for k in system.input_names if k in sig}
            if len(inputs) == len(system.input_names) and len(wa):
                wc = np.asarray(compiled.evaluate(**inputs), dtype=float)
                di = float(np.max(np.abs(wc - wa)))
            else:
                di = float("nan")
            rows.append({"scenario": scen.name, "robot": ra.name, "outcome": ra.outcome,
                         "same_outcome": ra.outcome == rb.outcome, "samples": len(ra.t),
                         "max_state_diff": ds, "max_w_diff": dw, "same_inputs_w_diff": di})
    return rows
