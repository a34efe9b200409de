"""hybridnav: hybrid mobile-robot navigation.

Robot kinematics written once in CasADi, swarm and potential-field planners that call the compiled
kinematics, Lyapunov/linearization analysis of the same models, and a GA tuner for Mamdani fuzzy
systems. See ``README.md`` and the documentation built from ``docs/``.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

from hybridnav import deprecation as _deprecation
from hybridnav.errors import HybridnavError

try:
    __version__ = _version("hybridnav")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["HybridnavError", "__version__"]

_deprecation.install()   # the old module names of 0.2 warn and serve their new modules until 0.4.0
