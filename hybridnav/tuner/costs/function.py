"""A user's own cost: :class:`FunctionCost` (what MATLAB's ``tunefis(fis, paramset, costfcn)``
does), from a Python callable or, in a job file, a ``module:function`` reference.

The function's signature, by ``batch``:

``batch=False`` (default)
    ``f(system) -> float`` (or a sequence of ``objectives`` floats): called once per candidate
    with a :class:`hybridnav.fuzzy.FuzzySystem`.
``batch=True``
    ``f(candidates, context) -> array (n,) or (n, m)``: called once per chunk with a
    :class:`~hybridnav.tuner.costs.base.Candidates` batch (``candidates.systems``,
    ``candidates.evaluate(inputs)`` for one batched evaluation of them all, ``candidates.X``)
    and the :class:`~hybridnav.tuner.costs.base.Context` (seed, role, generation, indices).

Values are minimized; NaN counts as ``+inf``. A function given as ``"module:function"`` is
imported where it runs (each worker process or Dask worker imports the module; ``path`` is put
on ``sys.path`` first, so a module beside the job file works on local workers).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.tuner.costs.base import Candidates, Context, Cost

__all__ = ["FunctionCost", "resolve_function"]


def resolve_function(spec: str, path: str | None = None, where: str = "") -> Callable:
    """The callable a ``"module:function"`` reference names."""
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise HybridnavError(f"{where}function: expected 'module:function', got {spec!r}")
    mod, name = spec.split(":")
    if path and path not in sys.path:
        sys.path.insert(0, path)
    try:
        module = importlib.import_module(mod)
    except Exception as exc:        # any error while importing the user's module
        raise HybridnavError(f"{where}function: cannot import module {mod!r} "
                             f"({type(exc).__name__}: {exc})") from None
    obj: Any = module
    for part in name.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            raise HybridnavError(f"{where}function: module {mod!r} has no {name!r}")
    if not callable(obj):
        raise HybridnavError(f"{where}function: {spec!r} is not callable")
    return obj


class FunctionCost(Cost):
    """A cost computed by a user's function.

    Parameters
    ----------
    f : callable or str
        The function, or ``"module:function"`` (imported where it runs).
    batch : bool
        False: ``f(system) -> value(s)`` per candidate; True: ``f(candidates, context)`` per
        chunk (see the module docstring).
    objectives : int or sequence of str
        The number of objectives (or their names); default 1.
    path : str, optional
        A folder put on ``sys.path`` before importing a ``"module:function"``.
    """

    def __init__(self, f: Callable | str, *, batch: bool = False,
                 objectives: int | tuple[str, ...] | list[str] = 1,
                 path: str | Path | None = None) -> None:
        super().__init__()
        if isinstance(objectives, int) and not isinstance(objectives, bool) and objectives >= 1:
            self.objective_names = tuple(f"objective_{i}" for i in range(objectives)) \
                if objectives > 1 else ("cost",)
        elif (isinstance(objectives, (list, tuple)) and objectives
              and all(isinstance(o, str) for o in objectives)):
            self.objective_names = tuple(objectives)
        else:
            raise HybridnavError(f"objectives: expected a positive integer or a list of names, "
                                 f"got {objectives!r}")
        if not isinstance(batch, bool):
            raise HybridnavError(f"batch: expected true or false, got {batch!r}")
        self.batch = batch
        self.path = None if path is None else str(path)
        if isinstance(f, str):
            self.spec: str | None = f
            self._f = resolve_function(f, self.path)      # fail now, not on a worker
        elif callable(f):
            self.spec = None
            self._f = f
        else:
            raise HybridnavError(f"f: expected a callable or 'module:function', got {f!r}")

    def __getstate__(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        if self.spec is not None:          # imported again where it runs
            d["_f"] = None
        return d

    @property
    def function(self) -> Callable:
        if self._f is None:
            self._f = resolve_function(self.spec, self.path)
        return self._f

    @property
    def name(self) -> str:
        """``module:function`` of the function."""
        return self.spec or (f"{getattr(self._f, '__module__', '?')}:"
                             f"{getattr(self._f, '__qualname__', repr(self._f))}")

    def config(self) -> dict[str, Any]:
        import hashlib
        import marshal

        code = getattr(self.function, "__code__", None)
        try:      # the function's code too: two lambdas share a name, not a meaning
            digest = hashlib.sha256(marshal.dumps(code)).hexdigest() if code else None
        except ValueError:
            digest = None
        return {"kind": "python", "function": self.name, "code": digest, "batch": self.batch,
                "objectives": list(self.objective_names)}

    def describe(self) -> str:
        return f"the user function {self.config()['function']} (minimized)"

    def _call(self, *args):
        try:
            return self.function(*args)
        except HybridnavError:
            raise
        except Exception as exc:        # the user's code: say whose error it is
            import logging

            logging.getLogger(__name__).debug("cost function failed", exc_info=True)
            how = "f(candidates, context)" if self.batch else "f(system)"
            raise HybridnavError(f"cost function {self.name}: raised {type(exc).__name__}: "
                                 f"{exc} (called as {how}; batch={self.batch})") from None

    def evaluate(self, candidates: Candidates, context: Context) -> np.ndarray:
        if self.batch:
            return self.objectives(self._call(candidates, context), len(candidates))
        rows = []
        for s in candidates.systems:
            v = self._call(s)
            try:
                if np.iscomplexobj(v):
                    raise TypeError("complex")
                rows.append(np.ravel(np.asarray(v, dtype=float)) if v is not None
                            else np.full(self.n_objectives, np.nan))
            except (TypeError, ValueError, OverflowError):
                raise HybridnavError(f"cost function {self.name}: expected "
                                     f"{self.n_objectives} real number(s) per system, got "
                                     f"{str(v)[:60]!r}") from None
        if len({len(r) for r in rows}) > 1:
            raise HybridnavError(f"cost function {self.name}: expected {self.n_objectives} "
                                 "number(s) per system, got lists of different lengths")
        return self.objectives(np.array(rows, dtype=float), len(candidates))
