"""Shared helpers of the find_equilibria / estimate_roa review tests (test_equilibria_review*.py):
a 2-state general system's symbols and default region, and the two calls with the analysis's
warnings silenced."""

from __future__ import annotations

import warnings

import casadi as cs
import numpy as np

from hybridnav.analysis import estimate_roa, find_equilibria

#: the states x_0, x_1 of the review systems, and their default region
X = cs.SX.sym("x", 2)
R = {"x_0": (-2, 2), "x_1": (-2, 2)}


def eqs(f, region=R, x=X, equilibrium=(0, 0), **kw):
    """find_equilibria of the general system (x, f)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return find_equilibria((x, f), equilibrium=list(equilibrium), region=region, **kw)


def states(found):
    """The equilibria's states as lists (for assertion messages)."""
    return [np.asarray(e.state, dtype=float).tolist() for e in found]


def roa(*args, **kw):
    """estimate_roa(*args, **kw)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return estimate_roa(*args, **kw)
