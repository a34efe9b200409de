"""How faithfully an export can mean the system: measured before writing it.

Two things can make another engine compute something else from a faithful file:

* **formula terms.** fuzzylite, MATLAB and FCL evaluate the membership formulas; hybridnav
  interpolates each input's ``points`` universe samples. Where the samples do not resolve a term
  (a narrow Z/S split), the outputs differ. :func:`formula_difference` measures the largest
  difference on the input ranges; ``hybridnav export`` writes the sampled form (FLL, FCL) when it
  exceeds :data:`FORMULA_TOLERANCE`.
* **no rule fires.** hybridnav (and the FLL export, through ``default``) returns the output's
  ``default`` there; fuzzylite's ``.fis`` reader returns NaN and MATLAB the middle of the output
  range. :func:`uncovered_fraction` measures where.
"""

from __future__ import annotations

import numpy as np

from hybridnav.fuzzy.system import FuzzySystem

__all__ = ["FORMULA_TOLERANCE", "formula_difference", "uncovered_fraction"]

#: Largest formula-vs-samples output difference, as a fraction of the output range, for which
#: ``hybridnav export`` keeps the formula form of FLL and FCL (else it writes the samples).
FORMULA_TOLERANCE = 1e-3

#: Universe points standing in for the exact formulas.
_FINE_POINTS = 20_001


def _inputs(system: FuzzySystem, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """A grid over the input ranges (2 inputs: ``n x n``), else ``n**2`` seeded random points."""
    if len(system.inputs) <= 2:
        axes = [np.linspace(v.range[0], v.range[1], n) for v in system.inputs]
        mesh = np.meshgrid(*axes, indexing="ij")
        return {v.name: m.ravel() for v, m in zip(system.inputs, mesh)}
    rng = np.random.default_rng(seed)
    return {v.name: rng.uniform(v.range[0], v.range[1], n * n) for v in system.inputs}


def formula_difference(system: FuzzySystem, n: int = 201) -> tuple[float, dict[str, float]]:
    """The largest ``|evaluate - formula evaluate|`` over the input ranges, relative to the output
    range, and the inputs where it occurs.

    The formula evaluation is the same system with every input universe sampled at 20001 points
    (where the interpolation error of every membership function is below 1e-6 of its own
    resolution), which is what an engine evaluating the formulas computes.

    Parameters
    ----------
    system : FuzzySystem
    n : int
        Grid points per input axis (more than two inputs: ``n**2`` random points).

    Returns
    -------
    worst : float
    at : dict
        Input name -> value where the worst difference is.
    """
    d = system.to_dict()
    for v in d["inputs"]:
        v["points"] = max(int(v.get("points", 0) or 0), _FINE_POINTS)
    fine = FuzzySystem.from_dict(d)
    X = _inputs(system, n)
    a = np.asarray(system.evaluate(**X), dtype=float)
    b = np.asarray(fine.evaluate(**X), dtype=float)
    diff = np.abs(a - b)
    span = system.output.range[1] - system.output.range[0]
    k = int(np.nanargmax(diff)) if np.isfinite(diff).any() else 0
    return float(diff[k] / span), {name: float(x[k]) for name, x in X.items()}


def uncovered_fraction(system: FuzzySystem, n: int = 201) -> float:
    """The fraction of the input ranges (an ``n``-per-axis grid) where no rule fires."""
    from hybridnav.fuzzy.family import SystemFamily

    family = SystemFamily(system)
    tables = family.tables_of([system])
    return float(family.uncovered(tables, grid=n)[0])
