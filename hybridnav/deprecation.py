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

import abc
import importlib
import importlib.abc
import importlib.machinery
import os
import sys
import types
import warnings
from typing import Any

__all__ = ["MOVED_MODULES", "REMOVAL", "SINCE", "HybridnavDeprecationWarning", "RenamedAttribute",
           "install", "warn_renamed"]

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


_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def _ours(filename: str) -> bool:
    """Frames a warning should not be attributed to: hybridnav's own, the class machinery's
    (``abc``) and the import system's."""
    return (filename.startswith(_PACKAGE) or filename in ("<frozen abc>", abc.__file__)
            or "importlib" in filename)


def _user_stacklevel() -> int:
    """The ``stacklevel`` (counted as :func:`warnings.warn` counts it from its caller,
    :func:`warn_renamed`) of the first frame outside :func:`_ours`: the user's line."""
    frame, level = sys._getframe(2), 2       # warn_renamed is level 1, its caller 2
    while frame is not None and _ours(frame.f_code.co_filename):
        frame = frame.f_back
        # warnings steps over the import system's bootstrap frames without counting them
        while frame is not None and "importlib._bootstrap" in frame.f_code.co_filename:
            frame = frame.f_back
        level += 1
    return level


def warn_renamed(old: str, new: str) -> None:
    """Warn that ``old`` was renamed ``new`` (a :class:`HybridnavDeprecationWarning`),
    attributed to the first line outside hybridnav (the user's code), so that Python's default
    filters show it there.

    Parameters
    ----------
    old, new : str
        How a user wrote the old name and how to write the new one (e.g. ``"Model.params"``,
        ``"Model.values"``; ``"job.toml: scenarios.heldout"``, ``"scenarios.test"``).
    """
    warnings.warn(_message(old, new), HybridnavDeprecationWarning, stacklevel=_user_stacklevel())


class RenamedAttribute:
    """An attribute's old name: reading it warns and gives the new name's value.

    Setting the old name on an instance sets an instance attribute, as it did before the rename
    (use :meth:`writable` where the old name was a property that set the new one). Read on the
    class, where the new name is an instance attribute only, it is the descriptor itself (so
    ``help`` and ``inspect`` do not warn).

    Parameters
    ----------
    new : str
        The attribute's name now.

    Examples
    --------
    >>> class Model:
    ...     values = {"L": 1.0}
    ...     params = RenamedAttribute.writable("values")   # Model().params warns, gives .values
    """

    def __init__(self, new: str) -> None:
        self.new = new
        self.old = "?"

    @classmethod
    def writable(cls, new: str) -> RenamedAttribute:
        """The old name of a property whose setter set ``new``: setting it warns and sets
        ``new``.

        Parameters
        ----------
        new : str

        Returns
        -------
        RenamedAttribute
        """
        return _WritableRenamed(new)

    def __set_name__(self, owner: type, name: str) -> None:
        self.old = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None and not hasattr(objtype, self.new):
            return self
        owner = (objtype or type(obj)).__name__
        warn_renamed(f"{owner}.{self.old}", f"{owner}.{self.new}")
        return getattr(obj if obj is not None else objtype, self.new)


class _WritableRenamed(RenamedAttribute):
    def __set__(self, obj: Any, value: Any) -> None:
        owner = type(obj).__name__
        warn_renamed(f"{owner}.{self.old}", f"{owner}.{self.new}")
        setattr(obj, self.new, value)


#: what the import system keeps on the alias itself; every other attribute is the target's
_OWN = frozenset({"__name__", "__spec__", "__loader__", "__package__", "__file__", "__path__",
                  "__cached__", "__builtins__", "__doc__", "_target"})


class _Alias(types.ModuleType):
    """A moved module's old name: every attribute is the new module's, read and written (so
    ``mock.patch("old.name.f")`` patches the real module, as when the old name was the module)."""

    def __init__(self, name: str, target: types.ModuleType) -> None:
        super().__init__(name, target.__doc__)
        object.__setattr__(self, "_target", target)

    def __getattr__(self, attr: str) -> Any:
        return getattr(object.__getattribute__(self, "_target"), attr)

    def __setattr__(self, attr: str, value: Any) -> None:
        if attr in _OWN:
            object.__setattr__(self, attr, value)
        else:
            setattr(object.__getattribute__(self, "_target"), attr, value)

    def __delattr__(self, attr: str) -> None:
        if attr in _OWN:
            object.__delattr__(self, attr)
        else:
            delattr(object.__getattribute__(self, "_target"), attr)

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

    def get_code(self, fullname: str) -> None:
        """No code: ``python -m <old name>`` says so (runpy asks for it)."""
        return None

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
