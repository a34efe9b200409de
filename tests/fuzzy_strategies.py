"""Hypothesis strategies for random fuzzy systems, shared by the fuzzy test modules."""

from __future__ import annotations

import os

import numpy as np
from hypothesis import strategies as st

#: examples of the long fuzz run (``HYBRIDNAV_FUZZ_EXAMPLES=N``), else each test's own count
_LONG = os.environ.get("HYBRIDNAV_FUZZ_EXAMPLES", "").strip()


def examples(default: int) -> int:
    """``default`` (the default run's count), or the count ``HYBRIDNAV_FUZZ_EXAMPLES`` asks for."""
    return int(_LONG) if _LONG else default


MFS = ["zmf", "smf", "trimf", "trapmf", "gaussmf", "gbellmf", "sigmf"]


@st.composite
def terms(draw, lo: float, hi: float, points: int, n: int) -> list[dict]:
    w = hi - lo
    grid = np.linspace(lo, hi, points)
    snap = draw(st.booleans())

    def coord() -> float:
        if snap:
            return float(grid[draw(st.integers(0, points - 1))])
        return draw(st.floats(lo - 0.25 * w, hi + 0.25 * w, allow_nan=False))

    out = []
    for j in range(n):
        mf = draw(st.sampled_from(MFS))
        if mf in ("zmf", "smf"):
            a, b = sorted([coord(), coord()])
            if not a < b:
                b = a + 0.3 * w
            p = [a, b]
        elif mf == "trimf":
            p = sorted(coord() for _ in range(3))
        elif mf == "trapmf":
            p = sorted(coord() for _ in range(4))
        elif mf == "gaussmf":
            p = [coord(), draw(st.floats(0.01, 0.6)) * w]
        elif mf == "gbellmf":
            p = [draw(st.floats(0.01, 0.6)) * w, draw(st.floats(0.2, 5.0)), coord()]
        else:
            p = [coord(), draw(st.sampled_from([-1.0, 1.0])) * draw(st.floats(0.5, 40.0)) / w]
        out.append({"name": f"t{j}", "mf": mf, "params": p})
    return out


@st.composite
def variables(draw, name: str, min_points: int = 11, min_terms: int = 2) -> dict:
    """A variable with 2-4 (or ``min_terms``-4) random terms over a random range."""
    lo = draw(st.floats(-5.0, 5.0))
    hi = lo + draw(st.floats(0.1, 10.0))
    points = draw(st.one_of(st.integers(min_points, 31), st.integers(11, 201)))
    n = draw(st.integers(min_terms, 4))
    return {"name": name, "range": [lo, hi], "points": points,
            "terms": draw(terms(lo, hi, points, n))}


def antecedents(inputs: list[dict]) -> st.SearchStrategy:
    leaves = st.sampled_from([[v["name"], t["name"]] for v in inputs for t in v["terms"]])
    return st.recursive(
        leaves,
        lambda kids: st.one_of(
            st.fixed_dictionaries({"and": st.lists(kids, min_size=1, max_size=3)}),
            st.fixed_dictionaries({"or": st.lists(kids, min_size=1, max_size=3)}),
            st.fixed_dictionaries({"not": kids}),
        ),
        max_leaves=6,
    )
