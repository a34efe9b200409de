"""Mamdani fuzzy systems: the ``hybridnav-fis/1`` JSON format, scikit-fuzzy, a fast exact evaluator.

>>> from hybridnav import fuzzy
>>> fis = fuzzy.builtin("effc-2rule")
>>> w = fis.evaluate(dtheta=[0.1, 1.4], alpha=[0.2, 1.0])   # batched, any broadcastable shapes

:class:`FuzzySystem` reads and writes the ``hybridnav-fis/1`` JSON format (``load``, ``loads``,
``FuzzySystem.from_dict``, ``to_dict``, ``save``), converts to a scikit-fuzzy ``ControlSystem``
(``to_skfuzzy``), and evaluates batches with scikit-fuzzy's exact semantics (``evaluate``).
Plots live in :mod:`hybridnav.fuzzy.plots` (imported on demand: it needs matplotlib).
Export for deployment (JSON, fuzzylite FLL, MATLAB .fis, IEC 61131-7 FCL, standalone C) and
import of FLL / .fis files live in :mod:`hybridnav.fuzzy.export`; the main entry points are
re-exported here: ``export``, ``export_to_file``, ``load_any``, ``read_fll``, ``read_fis``.
This subpackage does not import the tuner, the planners or the CLI.
"""

# after the system module: the export subpackage builds on it. Binding ``export`` here makes
# ``fuzzy.export`` the function; the subpackage stays importable as ``hybridnav.fuzzy.export``
# (``from hybridnav.fuzzy.export import to_c``).
from hybridnav.fuzzy.export import (  # noqa: E402
    export,
    export_to_file,
    load_any,
    read_fis,
    read_fll,
)
from hybridnav.fuzzy.mf import MF_PARAMS
from hybridnav.fuzzy.spec import (
    FORMAT,
    And,
    Not,
    Or,
    OutputVariable,
    Rule,
    Term,
    TermRef,
    Variable,
)
from hybridnav.fuzzy.system import (FuzzySystem, builtin, builtin_names, from_skfuzzy, load,
                                    loads)

__all__ = [
    "FORMAT", "MF_PARAMS", "FuzzySystem", "load", "loads", "builtin", "builtin_names",
    "Term", "Variable", "OutputVariable", "Rule", "TermRef", "And", "Or", "Not",
    "export", "export_to_file", "load_any", "read_fll", "read_fis", "from_skfuzzy",
]
