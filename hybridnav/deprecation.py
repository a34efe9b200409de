"""One deprecation policy: an old name keeps working for one minor version and warns.

Every renamed module, attribute or file key warns with a :class:`HybridnavDeprecationWarning` (a
``DeprecationWarning``) whose message names the old name, the new one and the version that
removes the old one (:data:`REMOVAL`), e.g. ``hybridnav.grid is deprecated since 0.3.0 and will be
removed in 0.4.0: use hybridnav.world.grid``.

* Moved modules are listed in :data:`MOVED_MODULES` (old dotted name -> new). Importing an old name
  imports the new module and returns a thin alias module that warns once, at import, and hands
  out the new module's attributes (the same objects, so ``isinstance`` and identity hold).
  Nothing is imported until an old name is used.
* Renamed attributes and keys call :func:`warn_renamed`.

``python -W error::DeprecationWarning`` (or pytest's ``filterwarnings``) turns every use of an old
name into an error, which is how the test suite keeps hybridnav itself on the new names. The
command line shows these warnings (Python hides ``DeprecationWarning`` outside ``__main__`` by
default).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from typing import Any

__all__ = ["MOVED_MODULES", "REMOVAL", "SINCE", "HybridnavDeprecationWarning", "RenamedAttribute",
           "deprecated_modules", "install", "warn_renamed"]

#: the version that deprecated the names below, and the one that removes them
SINCE = "0.3.0"
REMOVAL = "0.4.0"

_PLANNERS = {"apf": "field.apf", "effc": "field.effc", "hapf": "field.hapf", "pbpf": "field.pbpf",
             "lockstep": "field.lockstep", "worldstack": "field.worldstack",
             "fastepk": "step.fastepk", "acok": "step.acok", "stepping": "step.base",
             "stepfit": "step.stepfit", "paths": "path.planners", "gridsearch": "path.gridsearch",
             "rfd_core": "path.rfd_core", "psoba_sensors": "psoba.sensors"}

#: old module name -> the module that replaced it (importing the old name warns)
MOVED_MODULES: dict[str, str] = {
    "hybridnav.grid": "hybridnav.world.grid",
    "hybridnav.worldgen": "hybridnav.world.generator",
    "hybridnav.tuner.backends": "hybridnav.backends",
    "hybridnav.analysis.compare": "hybridnav.experiments.compare",
    "hybridnav.analysis.convergence": "hybridnav.experiments.convergence",
    "hybridnav.analysis.sil": "hybridnav.fuzzy.export.closedloop",
    "hybridnav.analysis.linearize": "hybridnav.analysis.linearization",
    **{f"hybridnav.planners.{old}": f"hybridnav.planners.{new}" for old, new in _PLANNERS.items()},
}


class HybridnavDeprecationWarning(DeprecationWarning):
    """An old hybridnav name was used; the message names its replacement and removal version."""


def _message(old: str, new: str) -> str:
    return f"{old} is deprecated since {SINCE} and will be removed in {REMOVAL}: use {new}"


def warn_renamed(old: str, new: str, stacklevel: int = 3) -> None:
    """Warn that ``old`` was renamed ``new`` (a :class:`HybridnavDeprecationWarning`).

    Parameters
    ----------
    old, new : str
        How a user wrote the old name and how to write the new one (e.g. ``"Model.params"``,
        ``"Model.values"``; ``"scenarios.heldout in job.toml"``, ``"scenarios.test"``).
    stacklevel : int
        As in :func:`warnings.warn`; the default points at the caller of the function that calls
        this one.
    """
    warnings.warn(_message(old, new), HybridnavDeprecationWarning, stacklevel=stacklevel)


class RenamedAttribute:
    """A class attribute's old name: reading or setting it warns and uses the new name.

    Parameters
    ----------
    new : str
        The attribute's name now.

    Examples
    --------
    >>> class Model:
    ...     values = {"L": 1.0}
    ...     params = RenamedAttribute("values")      # Model().params warns, gives .values
    """

    def __init__(self, new: str) -> None:
        self.new = new
        self.old = self.owner = "?"

    def __set_name__(self, owner: type, name: str) -> None:
        self.owner, self.old = owner.__name__, name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        owner = (objtype or type(obj)).__name__
        warn_renamed(f"{owner}.{self.old}", f"{owner}.{self.new}")
        return getattr(obj if obj is not None else objtype, self.new)

    def __set__(self, obj: Any, value: Any) -> None:
        owner = type(obj).__name__
        warn_renamed(f"{owner}.{self.old}", f"{owner}.{self.new}")
        setattr(obj, self.new, value)


class _Alias(types.ModuleType):
    """A moved module's old name: every attribute is the new module's."""

    def __init__(self, name: str, target: types.ModuleType) -> None:
        super().__init__(name, target.__doc__)
        object.__setattr__(self, "_target", target)

    def __getattr__(self, attr: str) -> Any:
        return getattr(object.__getattribute__(self, "_target"), attr)

    def __dir__(self) -> list[str]:
        return dir(object.__getattribute__(self, "_target"))


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names of :data:`MOVED_MODULES` (and nothing else)."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None):
        if fullname not in MOVED_MODULES:
            return None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=False)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        new = MOVED_MODULES[spec.name]
        # attributed to the import statement: warnings skips importlib's own frames
        warnings.warn(_message(spec.name, new), HybridnavDeprecationWarning, stacklevel=2)
        return _Alias(spec.name, importlib.import_module(new))

    def exec_module(self, module: types.ModuleType) -> None:
        old = module.__name__
        if old == "hybridnav.analysis.linearize":
            # ``import hybridnav.analysis.linearize as lin`` binds the package attribute
            # ``linearize`` -- the function, since 0.3.0 -- so the function carries the old
            # module's names for as long as the old name is served
            target = object.__getattribute__(module, "_target")
            for name in target.__all__:
                setattr(target.linearize, name, getattr(target, name))


_FINDER = _Finder()


def install() -> None:
    """Serve the old module names (done once when :mod:`hybridnav` is imported)."""
    if _FINDER not in sys.meta_path:
        sys.meta_path.append(_FINDER)


def deprecated_modules() -> list[str]:
    """The old module names still served, sorted (for tools that walk the package).

    Returns
    -------
    list of str
    """
    return sorted(MOVED_MODULES)
