"""Moved to :mod:`hybridnav.backends` (the one parallel-execution mechanism, serving ``tune`` and
``compare``); this alias keeps ``from hybridnav.tuner.backends import ...`` working for one
version."""

from hybridnav.backends import *  # noqa: F403
from hybridnav.backends import __all__  # noqa: F401
