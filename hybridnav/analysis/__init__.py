"""Control-theoretic analysis of the kinematic models — and of any system given as a python-control
``nlsys``, a CasADi ``Function``, expressions or a do-mpc model (:func:`as_system`): Lyapunov checks
and certificates, linearization, regions of attraction, equilibria, closed-loop sweeps.

The functions are exported here, python-control style (``from hybridnav.analysis import
linearize``); the modules are named for what they hold (``linearization``, ``lyapunov``,
``certificate``, ``roa``, ``sweep``). ``hybridnav.analysis.report.analyze`` (what ``hybridnav
analyze`` runs) and the plots stay in their modules, so that importing this package does not load
matplotlib.
"""

import sys as _sys
import types as _types

from hybridnav.analysis.certificate import Certificate, certify
from hybridnav.analysis.linearization import (
    DiscreteStepReport,
    LinearizationReport,
    controllability_rank,
    discrete_step,
    is_stable,
    linearize,
    linearize_expression,
    rk4_stability_limit,
    summarize,
)
from hybridnav.analysis.lyapunov import (
    Equilibrium,
    LyapunovReport,
    check_lyapunov,
    find_equilibria,
    lyapunov_functions,
)
from hybridnav.analysis.region import Box, as_box
from hybridnav.analysis.roa import (
    RoaEstimate,
    basin,
    basin_share,
    estimate_roa,
    lyapunov_equation_candidate,
)
from hybridnav.analysis.sweep import closed_loop_sweep, grid_starts
from hybridnav.analysis.system import System, as_system



class _Package(_types.ModuleType):
    """This package, keeping its function ``linearize`` when the deprecated module name
    ``hybridnav.analysis.linearize`` (served by :mod:`hybridnav.deprecation` until 0.4.0) is
    imported: the import system would otherwise set the alias module as the package attribute."""

    def __setattr__(self, name, value):
        if name == "linearize" and isinstance(value, _types.ModuleType):
            return
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package

__all__ = ["Box", "Certificate", "DiscreteStepReport", "Equilibrium", "LinearizationReport",
           "LyapunovReport", "RoaEstimate", "System", "as_box", "as_system", "basin",
           "basin_share", "certify", "check_lyapunov", "closed_loop_sweep",
           "controllability_rank", "discrete_step", "estimate_roa", "find_equilibria",
           "grid_starts", "is_stable", "linearize", "linearize_expression",
           "lyapunov_equation_candidate", "lyapunov_functions", "rk4_stability_limit",
           "summarize"]
