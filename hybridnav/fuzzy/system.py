"""The :class:`FuzzySystem` type: ``hybridnav-fis/1`` JSON <-> scikit-fuzzy <-> fast evaluation."""

from __future__ import annotations

import json
import logging
import math
import os
import sys
from collections.abc import Mapping, Sequence
from functools import reduce
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

# not ``from hybridnav.fuzzy import _native``: that imports the package, a cycle
import hybridnav.fuzzy._native as _native  # noqa: PLR0402
from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, read_text_file
from hybridnav.fuzzy.engine import CompiledSystem, universe
from hybridnav.fuzzy.spec import (
    FORMAT,
    And,
    Antecedent,
    Not,
    OutputVariable,
    Rule,
    TermRef,
    Variable,
    antecedent_to_json,
    decode_json,
    parse_system,
    variable_to_json,
)
from hybridnav.params import short_repr

if TYPE_CHECKING:  # pragma: no cover
    from skfuzzy.control import ControlSystem

__all__ = ["FuzzySystem", "load", "loads", "builtin", "builtin_names", "from_skfuzzy"]

log = logging.getLogger(__name__)

_SYSTEMS_PACKAGE = "hybridnav.fuzzy.systems"


class FuzzySystem:
    """A Mamdani fuzzy system with one output, in scikit-fuzzy's semantics.

    Build one with :func:`load`, :func:`loads`, :func:`builtin` or :meth:`from_dict`; the
    constructor takes the already-parsed parts and validates them the same way (it builds the
    JSON form and reads it back). Construction precompiles the evaluator, so
    :meth:`evaluate` does no set-up work (single samples move to a C evaluator later, see
    :meth:`use_native`).

    Parameters
    ----------
    name : str
    inputs : sequence of Variable
    output : OutputVariable
    rules : sequence of Rule
    description : str, optional
    source : str, optional
        Where the system came from (file name), used in error messages.

    Attributes
    ----------
    name, description, inputs, output, rules, source
        As given (``inputs`` and ``rules`` as tuples).
    input_names : tuple of str
        The keyword names :meth:`evaluate` takes, in file order.
    """

    def __init__(self, name: str, inputs: Sequence[Variable], output: OutputVariable,
                 rules: Sequence[Rule], description: str | None = None,
                 source: str | None = None) -> None:
        doc = _to_dict(name, description, tuple(inputs), output, tuple(rules))
        parts = parse_system(doc, source)
        self._init(parts, source)

    def _init(self, parts: Mapping[str, Any], source: str | None) -> None:
        self.name: str = parts["name"]
        self.description: str | None = parts["description"]
        self.inputs: tuple[Variable, ...] = parts["inputs"]
        self.output: OutputVariable = parts["output"]
        self.rules: tuple[Rule, ...] = parts["rules"]
        self.source = source
        self.input_names = tuple(v.name for v in self.inputs)
        self._names = frozenset(self.input_names)
        self._engine = CompiledSystem(self.inputs, self.output, self.rules)
        # single-sample evaluation in C (hybridnav.fuzzy._native): the evaluator once switched,
        # its keyword entry point, and the Python-path evaluations left before asking for it
        self._native: Any = None
        self._fast: Any = None
        self._countdown = _native.AFTER

    # -------------------------------------------------------------------------------- I/O

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], source: str | None = None) -> FuzzySystem:
        """Validate a decoded ``hybridnav-fis/1`` document and build the system.

        Parameters
        ----------
        d : mapping
            The JSON document as Python objects.
        source : str, optional
            File name named in error messages.

        Returns
        -------
        FuzzySystem

        Raises
        ------
        HybridnavError
            The message names the file (if ``source``), the key path (``inputs[0].terms[1].params``)
            and what was expected.
        """
        prefix = f"{source}: " if source else ""
        self = cls.__new__(cls)
        try:
            parts = parse_system(d, source)
            self._init(parts, source)
        except RecursionError:
            raise HybridnavError(f"{prefix}rules: antecedents nested too deeply") from None
        except FloatingPointError as exc:
            key = _overflowing_term(parts)
            raise HybridnavError(f"{prefix}{key}: expected parameters whose membership values are "
                                 f"finite on the universe ({exc})") from None
        return self

    def to_dict(self) -> dict[str, Any]:
        """The ``hybridnav-fis/1`` document (JSON-ready Python objects)."""
        return _to_dict(self.name, self.description, self.inputs, self.output, self.rules)

    def to_json(self) -> str:
        """The ``hybridnav-fis/1`` document as indented JSON text (ends with a newline)."""
        return _format_json(self.to_dict()) + "\n"

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the system as JSON to ``path`` atomically (temporary file, then ``os.replace``).

        Parameters
        ----------
        path : str or path-like

        Returns
        -------
        pathlib.Path
            The written path.
        """
        path = Path(path)
        atomic_write_text(path, self.to_json())
        log.debug("wrote fuzzy system %r to %s", self.name, path)
        return path

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, FuzzySystem):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    def __reduce__(self) -> tuple[Any, ...]:
        # rebuilt from the JSON form (so worker processes get a freshly compiled evaluator);
        # hybridnav never writes pickles to files: the file format is JSON
        return (FuzzySystem.from_dict, (self.to_dict(), self.source))

    def __repr__(self) -> str:
        ins = ", ".join(f"{v.name}[{len(v.terms)}]" for v in self.inputs)
        return (f"<FuzzySystem {self.name!r}: {ins} -> {self.output.name}"
                f"[{len(self.output.terms)}], {len(self.rules)} rules>")

    # ------------------------------------------------------------------------- scikit-fuzzy

    @classmethod
    def from_skfuzzy(cls, system: ControlSystem, *, name: str | None = None,
                     default: float | None = None, description: str = "") -> FuzzySystem:
        """A scikit-fuzzy ``ControlSystem`` as a hybridnav system (the same as
        :func:`hybridnav.fuzzy.from_skfuzzy`).

        Parameters
        ----------
        system : skfuzzy.control.ControlSystem
        name : str, optional
        default : float, optional
            The output when no rule fires (default: the middle of the output universe).
        description : str

        Returns
        -------
        FuzzySystem
        """
        from hybridnav.fuzzy.skfuzzy_import import document

        return cls.from_dict(document(system, name=name, default=default,
                                      description=description), source="from_skfuzzy")

    def to_skfuzzy(self) -> ControlSystem:
        """The equivalent scikit-fuzzy ``ControlSystem``.

        Universes are ``np.linspace(lo, hi, points)``; terms are sampled with scikit-fuzzy's own
        membership functions; rules are ``Rule(antecedent, output[then] % weight)`` with ``&``,
        ``|`` and ``~`` for and/or/not, labelled ``rule0``, ``rule1``, ... The consequent uses
        centroid defuzzification. Inputs that no rule mentions are not part of a scikit-fuzzy
        control system (its graph is built from the rules), so they are absent from the result.

        Returns
        -------
        skfuzzy.control.ControlSystem
            Compute with ``ControlSystemSimulation(cs)``; when no rule fires it leaves the output
            unset (or raises), where :meth:`evaluate` returns ``output.default``.
        """
        import skfuzzy
        from skfuzzy import control as ctrl

        def sk_mf(x: NDArray[np.float64], mf: str, p: Sequence[float]) -> NDArray[np.float64]:
            if mf == "trimf":
                return skfuzzy.trimf(x, list(p))
            if mf == "trapmf":
                return skfuzzy.trapmf(x, list(p))
            return getattr(skfuzzy, mf)(x, *p)

        ants: dict[str, Any] = {}
        for v in self.inputs:
            a = ctrl.Antecedent(universe(v), v.name)
            for t in v.terms:
                a[t.name] = sk_mf(a.universe, t.mf, t.params)
            ants[v.name] = a
        o = self.output
        cons = ctrl.Consequent(universe(o), o.name, defuzzify_method=o.defuzz)
        for t in o.terms:
            cons[t.name] = sk_mf(cons.universe, t.mf, t.params)

        def build(a: Antecedent) -> Any:
            if isinstance(a, TermRef):
                return ants[a.input][a.term]
            if isinstance(a, Not):
                return ~build(a.item)
            parts = [build(x) for x in a.items]
            if isinstance(a, And):
                return reduce(lambda u, w: u & w, parts)
            return reduce(lambda u, w: u | w, parts)

        rules = [ctrl.Rule(build(r.antecedent), cons[r.then] % float(r.weight), label=f"rule{i}")
                 for i, r in enumerate(self.rules)]
        return ctrl.ControlSystem(rules)

    # --------------------------------------------------------------------------- evaluation

    def to_casadi(self, **inputs: Any):
        """The crisp output as one exact CasADi SX expression of the given input expressions.

        The same scikit-fuzzy semantics as :meth:`evaluate` (equal in real arithmetic, to
        rounding in floating point; see :mod:`hybridnav.fuzzy.symbolic`), so a fuzzy controller
        closed around a model can be simulated, linearized and certified by
        :mod:`hybridnav.analysis`. Inputs must be finite.

        Parameters
        ----------
        **inputs : casadi.SX or float
            One keyword per input variable (see :attr:`input_names`).

        Returns
        -------
        casadi.SX

        Raises
        ------
        TypeError
            Missing or unexpected keyword.
        """
        from hybridnav.fuzzy.symbolic import to_casadi

        if inputs.keys() != self._names:
            extra = [n for n in inputs if n not in self._names]
            raise TypeError(f"to_casadi() of fuzzy system {self.name!r} takes the inputs "
                            f"{', '.join(self.input_names)}"
                            + (f"; unexpected {', '.join(extra)}" if extra else ""))
        return to_casadi(self, [inputs[n] for n in self.input_names])

    def evaluate(self, **inputs: ArrayLike) -> NDArray[np.float64] | np.float64:
        """Crisp output for crisp inputs, batched, exactly as scikit-fuzzy computes it.

        Parameters
        ----------
        **inputs : array_like
            One keyword per input variable (see :attr:`input_names`), each a number or an array;
            the shapes must broadcast together. Values outside an input's range are clipped to it
            (as scikit-fuzzy does); NaN gives NaN.

        Returns
        -------
        ndarray or numpy.float64
            The output, with the broadcast shape of the inputs (a ``numpy.float64`` when every
            input is a scalar). Where no rule fires (zero aggregated area) the value is
            ``output.default``.

        Raises
        ------
        TypeError
            Missing or unexpected keyword.
        ValueError
            Shapes that do not broadcast, or non-numeric values.

        Notes
        -----
        One sample at a time, after a few hundred such calls (or at :meth:`use_native`), the
        work moves to a compiled C evaluator where a C compiler is available: the same
        arithmetic in the same order, so the same results bit for bit, in about 0.3 us a call
        instead of 10-20 us (see :mod:`hybridnav.fuzzy._native`).
        """
        fast = self._fast
        if fast is not None:
            out = fast(inputs)  # one sample of Python numbers: the C evaluator, else None
            if out is not None:
                return out
        names = self.input_names
        if inputs.keys() != self._names:
            missing = [n for n in names if n not in inputs]
            extra = [n for n in inputs if n not in self._names]
            raise TypeError(f"evaluate() of fuzzy system {self.name!r} takes the inputs "
                            f"{', '.join(names)}"
                            + (f"; missing {', '.join(missing)}" if missing else "")
                            + (f"; unexpected {', '.join(extra)}" if extra else ""))
        vals = [inputs[n] for n in names]
        if all(isinstance(v, (float, int)) for v in vals):
            return np.float64(self._scalar([float(v) for v in vals]))
        arrs = [np.asarray(v, dtype=np.float64) for v in vals]
        shape = np.broadcast_shapes(*(a.shape for a in arrs))
        size = math.prod(shape)
        if size == 1:
            r = self._scalar([float(a.reshape(-1)[0]) for a in arrs])
            return np.float64(r) if shape == () else np.full(shape, r)
        if size == 0:
            return np.empty(shape)
        flat = [np.broadcast_to(a, shape).reshape(-1) for a in arrs]
        return self._engine.evaluate_batch(flat).reshape(shape)


    def _scalar(self, x: list[float]) -> float:
        """One sample (floats in input order): the C evaluator if switched to (None from it:
        the Python path decides), else the Python path, counting down to asking for it."""
        ev = self._native
        if ev is not None:
            out = ev.scalar(x)
            if out is not None:
                return out
        else:
            self._countdown -= 1
            if self._countdown <= 0:
                self._switch(start=True)
        return self._engine.evaluate_scalar(x)

    def _switch(self, start: bool) -> bool:
        ev, retry = _native.evaluator(self._engine, self.input_names, start=start)
        if ev is not None:
            self._native = ev
            self._fast = ev.kw
        self._countdown = _native.AFTER if retry else sys.maxsize
        return ev is not None

    def use_native(self, wait: bool = True) -> bool:
        """Evaluate single samples with the compiled C evaluator from now on.

        :meth:`evaluate` switches to it by itself after a few hundred single-sample calls, in
        the background and only where a C compiler is available (see
        :mod:`hybridnav.fuzzy._native`); this switches at once, compiling the module in the
        foreground if it is not in the cache yet (about a second, once per machine). The
        results are the same either way, bit for bit.

        Parameters
        ----------
        wait : bool
            Wait for the compiler if the module has to be built (else start the build in the
            background and switch later, as :meth:`evaluate` does).

        Returns
        -------
        bool
            Whether single samples are now evaluated in C (False where there is no compiler or
            ``Python.h``, or with ``HYBRIDNAV_NATIVE=0``).
        """
        if self._native is not None:
            return True
        if wait:
            _native.build(wait=True)
        return self._switch(start=True)


# ------------------------------------------------------------------------------- helpers

def _to_dict(name: str, description: str | None, inputs: Sequence[Variable],
             output: OutputVariable, rules: Sequence[Rule]) -> dict[str, Any]:
    d: dict[str, Any] = {"format": FORMAT, "name": name}
    if description is not None:
        d["description"] = description
    d["inputs"] = [variable_to_json(v) for v in inputs]
    d["output"] = variable_to_json(output)
    rs = []
    for r in rules:
        rd: dict[str, Any] = {"if": antecedent_to_json(r.antecedent), "then": r.then,
                              "weight": r.weight}
        if r.description is not None:
            rd["description"] = r.description
        rs.append(rd)
    d["rules"] = rs
    return d


def _format_json(obj: Any, indent: int = 0, width: int = 100) -> str:
    """Indented JSON that keeps short arrays and objects (terms, ranges, antecedents) on one line."""
    flat = json.dumps(obj, allow_nan=False, ensure_ascii=False)
    if not isinstance(obj, (dict, list)) or len(flat) + indent <= width and not (
            isinstance(obj, dict) and any(isinstance(v, list) and v and isinstance(v[0], dict)
                                          for v in obj.values())):
        return flat
    pad = " " * (indent + 2)
    if isinstance(obj, list):
        if not obj:
            return "[]"
        items = [pad + _format_json(v, indent + 2, width) for v in obj]
        return "[\n" + ",\n".join(items) + "\n" + " " * indent + "]"
    if not obj:
        return "{}"
    items = [pad + json.dumps(k, ensure_ascii=False) + ": " + _format_json(v, indent + 2, width)
             for k, v in obj.items()]
    return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"


def _no_duplicate_keys(source: str | None):
    def hook(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        d: dict[str, Any] = {}
        for k, v in pairs:
            if k in d:
                raise HybridnavError(f"{source + ': ' if source else ''}duplicate key "
                                     f"{short_repr(k)} in a JSON object")
            d[k] = v
        return d
    return hook


def loads(text: str, source: str | None = None) -> FuzzySystem:
    """Read a system from JSON text.

    Parameters
    ----------
    text : str
        A ``hybridnav-fis/1`` JSON document.
    source : str, optional
        Name used in error messages.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        JSON syntax errors (with line and column), duplicate keys, or invalid content (the key
        named; an integer with more digits than Python converts included).
    """
    d = decode_json(text, source, _no_duplicate_keys(source))
    return FuzzySystem.from_dict(d, source)


def load(name_or_path: str | os.PathLike[str]) -> FuzzySystem:
    """Load a fuzzy system from a ``hybridnav-fis/1`` JSON file, or a built-in one by name.

    Parameters
    ----------
    name_or_path : str or path-like
        A path, or a built-in name (:func:`builtin_names`). Strings ending in ``.json`` or
        containing a path separator are paths.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        Unreadable file, unknown built-in name, JSON syntax error (the message gives the file and
        the line), or invalid content (the message gives the file and the key path).
    """
    s = os.fspath(name_or_path)
    if isinstance(name_or_path, os.PathLike) or s.endswith(".json") or "/" in s or os.sep in s:
        text = read_text_file(s, "fuzzy system file")
        log.debug("loading fuzzy system from %s", s)
        return loads(text, s)
    return builtin(s)


def builtin_names() -> list[str]:
    """Names of the built-in fuzzy systems (``hybridnav/fuzzy/systems/*.json``), sorted."""
    root = resources.files(_SYSTEMS_PACKAGE)
    return sorted(e.name[:-5] for e in root.iterdir() if e.name.endswith(".json"))


def builtin(name: str) -> FuzzySystem:
    """A built-in fuzzy system.

    Parameters
    ----------
    name : str
        One of :func:`builtin_names`: ``effc-5rule`` (the EFFC paper's Table 1), ``effc-2rule``
        (its reduced Table 2) or ``effc-tuned`` (the main job's result on its defaults).

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        Unknown name.
    """
    if name not in builtin_names():        # never a file lookup with an arbitrary name
        raise HybridnavError(f"fuzzy system {short_repr(name)}: expected a built-in name "
                             f"({', '.join(builtin_names())}) or a path to a .json file")
    entry = resources.files(_SYSTEMS_PACKAGE).joinpath(f"{name}.json")
    return loads(entry.read_text(encoding="utf-8"), f"{name}.json")


def _overflowing_term(parts: dict[str, Any]) -> str:
    """The key path of the first term whose sampled membership function is not finite."""
    from hybridnav.fuzzy.mf import sample

    variables = [(f"inputs[{i}]", v) for i, v in enumerate(parts["inputs"])]
    variables.append(("output", parts["output"]))
    for where, var in variables:
        x = np.linspace(var.range[0], var.range[1], var.points)
        for j, term in enumerate(var.terms):
            try:
                sample(term.mf, term.params, x)
            except FloatingPointError:
                return f"{where}.terms[{j}].params"
    return "terms"


def from_skfuzzy(system, *, name: str | None = None, default: float | None = None,
                 description: str = "") -> FuzzySystem:
    """The scikit-fuzzy ``ControlSystem`` ``system`` as a :class:`FuzzySystem`.

    Each term's samples become the hybridnav shape (``trimf``, ``trapmf``, ``gaussmf``,
    ``gbellmf``, ``sigmf``, ``zmf``, ``smf``) whose parameters, recovered from them, reproduce
    every sample to 1e-9 and are exactly 0 where scikit-fuzzy's are (whether a rule fires depends
    on it), so the system evaluates as scikit-fuzzy's ``ControlSystemSimulation`` computes.
    Triangles and trapezoids are recovered wherever their corners lie; a bell (``gbellmf``)
    whose centre falls between samples, and some Gaussian, sigmoid and z/s terms, are not yet
    recognized and are refused, naming the term.

    Parameters
    ----------
    system : skfuzzy.control.ControlSystem
        One consequent, centroid defuzzification, the default ``and`` (minimum) and ``or``
        (maximum), evenly spaced universes.
    name : str, optional
        The system's name (default ``"skfuzzy"``).
    default : float, optional
        The output when no rule fires (scikit-fuzzy leaves it unset; default: the middle of the
        output's universe).
    description : str
        Stored with the system.

    Returns
    -------
    FuzzySystem

    Raises
    ------
    HybridnavError
        Naming the variable, term or rule hybridnav cannot represent.
    """
    return FuzzySystem.from_skfuzzy(system, name=name, default=default, description=description)
