"""Control-theoretic analysis of the kinematic models: Lyapunov checks, linearization, regions of
attraction, equilibria."""

from hybridnav.analysis.lyapunov import (
    Equilibrium,
    LyapunovReport,
    check_lyapunov,
    find_equilibria,
    lyapunov_functions,
)
from hybridnav.analysis.region import Box, as_box

__all__ = ["Box", "Equilibrium", "LyapunovReport", "as_box", "check_lyapunov", "find_equilibria",
           "lyapunov_functions"]
