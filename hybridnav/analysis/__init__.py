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

from hybridnav.analysis import linearization as _linearization
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

# ``hybridnav.analysis.linearize`` was the module until 0.2; it is the function now. The old
# ``from hybridnav.analysis.linearize import ...`` keeps working for one version through this alias.
_sys.modules[__name__ + ".linearize"] = _linearization

__all__ = ["Box", "Certificate", "DiscreteStepReport", "Equilibrium", "LinearizationReport",
           "LyapunovReport", "RoaEstimate", "System", "as_box", "as_system", "basin",
           "basin_share", "certify", "check_lyapunov", "closed_loop_sweep",
           "controllability_rank", "discrete_step", "estimate_roa", "find_equilibria",
           "grid_starts", "is_stable", "linearize", "linearize_expression",
           "lyapunov_equation_candidate", "lyapunov_functions", "rk4_stability_limit",
           "summarize"]
