"""Any dynamical system for the analysis: python-control, CasADi, expressions or do-mpc.

:func:`as_system` turns

* a python-control ``NonlinearIOSystem`` (``ct.nlsys``; its update function is traced with CasADi
  symbols, at ``t = 0`` with the system's ``params``) or a ``ct.StateSpace``,
* a CasADi ``Function`` ``f(x)`` or ``f(x, u)`` returning ``xdot``,
* expressions ``(x, rhs)`` or ``(x, u, rhs)`` in CasADi SX,
* a do-mpc ``Model`` (continuous, after ``setup()``; its parameters from ``params``),

into a :class:`System`: a :class:`~hybridnav.models.Model` whose "target" is a whole equilibrium
state, so that every analysis function (:func:`~hybridnav.analysis.linearize`,
:func:`~hybridnav.analysis.check_lyapunov`, :func:`~hybridnav.analysis.estimate_roa`,
:func:`~hybridnav.analysis.find_equilibria`, :func:`~hybridnav.analysis.basin`, ...) takes it as it
takes a robot model. The analysed closed loop is ``xdot = f(x, u0)`` with the input held at ``u0``
(default 0): close your controller into ``f`` to analyse a closed loop.

Those functions call :func:`as_system` themselves, so a user passes the ``ct.nlsys`` (or the
CasADi ``Function``) directly::

    import control as ct
    pend = ct.nlsys(lambda t, x, u, p: [x[1], -9.81 * np.sin(x[0]) - 0.5 * x[1] + u[0]],
                    states=["theta", "omega"], inputs=["tau"])
    linearize(pend, [0, 0], [0])                       # a ct.StateSpace
    check_lyapunov(pend, V, equilibrium=[0, 0], region={"theta": (-1, 1), "omega": (-1, 1)})
"""

from __future__ import annotations

import hashlib
import pickle
import re
import threading
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as cs
import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.models.base import Model, _named, _Symbols

__all__ = ["System", "as_system"]


class System(Model):
    """A system ``xdot = f(x, u)`` analysed with its input held at ``u0``.

    Parameters
    ----------
    x : casadi.SX
        The state symbols (a column).
    u : casadi.SX or None
        The input symbols (None or empty: no inputs).
    rhs : casadi.SX
        ``xdot``, in ``x`` and ``u`` only.
    states, inputs : sequence of str, optional
        Names (default: the symbols' names, or ``x0, x1, ...``).
    u0 : sequence of float, optional
        The held input (default 0).
    equilibrium : sequence of float, optional
        The default equilibrium of the analysis functions.
    angles : sequence of str
        States that are angles the dynamics see only modulo 2 pi.
    dt : float
        Step of simulations (RK4): confirmations of regions of attraction, basins, the runs that
        seed the equilibrium search.
    name : str
    jit : bool or None
        JIT-compile the rollouts (as for the robot models).
    source : tuple, optional
        ``(python-control or do-mpc object, params)`` it was traced from (:meth:`with_params`
        traces it again).
    """

    name = "system"
    description = "a dynamical system given by its right-hand side"
    capabilities = frozenset()            # not a robot: no scenario can use it
    candidate_name = "1/2 |x - x*|^2"
    smooth_at_target = True

    def __init__(self, x, u, rhs, *, states: Sequence[str] | None = None,
                 inputs: Sequence[str] | None = None, u0: Sequence[float] | None = None,
                 equilibrium: Sequence[float] | None = None, angles: Sequence[str] = (),
                 dt: float = 0.01, name: str = "system", jit: bool | None = None,
                 source: Any = None) -> None:
        x = _column(x, "x")
        u = cs.SX(0, 1) if u is None else _column(u, "u")
        rhs = cs.SX(rhs)
        if rhs.numel() != x.numel():
            raise HybridnavError(
                f"rhs: expected {x.numel()} entries (one per state), got shape {rhs.shape}")
        rhs = cs.vec(rhs)
        free = [str(s) for s in cs.symvar(rhs)
                if not any(cs.is_equal(s, a) for a in cs.symvar(cs.vertcat(x, u)))]
        if free:
            raise HybridnavError(
                f"rhs: depends on symbols that are neither states nor inputs: {', '.join(free)} "
                "(substitute parameter values first, or pass them as params=)")
        # CasADi function names are identifiers ("sys[0]" is python-control's default name)
        # (non-consecutive underscores, not ending in one: CasADi appends "_step")
        self.name = re.sub(r"_+", "_", re.sub(r"\W", "_", str(name))).strip("_") or "system"
        if not (self.name[0].isalpha()):
            self.name = "s_" + self.name
        try:
            self.dt = float(dt)
        except (TypeError, ValueError):
            self.dt = float("nan")
        if isinstance(dt, bool) or not (np.isfinite(self.dt) and self.dt > 0):
            raise HybridnavError(f"system {name}: dt: expected a number > 0, got {dt!r}")
        if x.numel() == 0:
            raise HybridnavError(f"system {name}: expected at least one state, got none")
        self.jit = jit
        self._radius = 0.0
        self.options, self.values = {}, {}
        self.state_names = _names(states, x, "x", "states")
        self.plant_state_names = self.state_names
        self.controller_state_names = ()
        self.input_names = _names(inputs, u, "u", "inputs")
        unknown = sorted(set(angles) - set(self.state_names))
        if unknown:
            raise HybridnavError(f"angles: {unknown[0]!r} is not a state; expected some of "
                                 + ", ".join(self.state_names))
        self.angle_state_names = tuple(angles)
        self.nx = len(self.state_names)
        self.n_plant = self.nx
        self.nu = len(self.input_names)
        self.param_names = ()
        self.sym = _Symbols(
            x=_named(self.state_names), u=_named(self.input_names), p=cs.SX(0, 1),
            target=_named([f"{n}_eq" for n in self.state_names]))
        self._rhs = cs.substitute(rhs, cs.vertcat(x, u), cs.vertcat(self.sym.x, self.sym.u))
        #: the caller's symbols, by name, for candidates built from them
        self.aliases = {str(x[i]): self.sym.x[i] for i in range(self.nx)}
        self.u0 = _vector(np.zeros(self.nu) if u0 is None else u0, "u0", self.nu)
        self.equilibrium = (None if equilibrium is None
                            else _vector(equilibrium, "equilibrium", self.nx))
        self.source = source
        self._local = threading.local()

    @property
    def target_size(self) -> int:
        """The equilibrium is a whole state."""
        return self.nx

    def open_loop(self, x, u, p) -> cs.SX:
        return cs.substitute(self._rhs, cs.vertcat(self.sym.x, self.sym.u), cs.vertcat(x, u))

    def controller(self, x, target, p) -> cs.SX:
        """The held input ``u0``."""
        return cs.SX(cs.DM(self.u0)) if self.nu else cs.SX(0, 1)

    def lyapunov_candidate(self, x=None, target=None) -> cs.SX:
        """``V = 1/2 |x - x*|^2``."""
        x = self.sym.x if x is None else x
        target = self.sym.target if target is None else target
        return 0.5 * cs.sumsqr(x - target)

    def with_params(self, **overrides: Any) -> System:
        """A copy with ``dt``, ``jit`` or ``u0`` changed (a python-control or do-mpc source is
        traced again with other ``params``)."""
        kw = {k: overrides.pop(k) for k in ("dt", "jit", "u0") if k in overrides}
        if overrides:
            if self.source is None:
                raise HybridnavError(
                    f"params: system {self.name} has no parameters "
                    f"({', '.join(sorted(overrides))}); build it with their values")
            src, params = self.source
            return as_system(src, params={**(params or {}), **overrides}, name=self.name,
                             angles=self.angle_state_names, **{"dt": self.dt, **kw})
        return System(self.sym.x, self.sym.u, self._rhs, states=self.state_names,
                      inputs=self.input_names, u0=kw.get("u0", self.u0),
                      equilibrium=self.equilibrium, angles=self.angle_state_names,
                      dt=kw.get("dt", self.dt), name=self.name, jit=kw.get("jit", self.jit),
                      source=self.source)

    def __reduce__(self):
        # the right-hand side travels as a serialized CasADi function of the state and input
        # symbols (SX expressions do not pickle); the rest as they are
        fn = cs.Function("rhs", [self.sym.x, self.sym.u], [self._rhs])
        source = self.source
        try:                # (a python-control source with a lambda does not pickle: without it
            pickle.dumps(source)    # the copy cannot be traced again with other params)
        except Exception:
            source = None
        return (_unpickled, (fn.serialize(), {
            "states": self.state_names, "inputs": self.input_names, "u0": self.u0,
            "equilibrium": self.equilibrium, "angles": self.angle_state_names, "dt": self.dt,
            "name": self.name, "jit": self.jit, "source": source}, list(self.aliases)))

    def _key(self) -> tuple:
        # the right-hand side as CasADi serializes it (its constants to the bit): printed, it
        # rounds constants to a few digits, and two systems differing in one would share the
        # process's caches (equilibria, compiled cycles)
        rhs = cs.Function("rhs", [self.sym.x, self.sym.u], [self._rhs]).serialize()
        text = f"{self.state_names}|{self.input_names}|{rhs}|{self.u0.tolist()}"
        return ("System", self.name, self.dt, hashlib.sha256(text.encode()).hexdigest())

    def retarget(self, X, targets) -> np.ndarray:
        X, _ = self._check_batch(X, targets)
        return X.copy()

    def initial_state(self, start, target, initial=None) -> np.ndarray:
        return _vector(start, "start", self.nx)

    def __repr__(self) -> str:
        return (f"System({self.name!r}, states={list(self.state_names)}, "
                f"inputs={list(self.input_names)})")


def as_system(obj: Any, *, states: Sequence[str] | None = None,
              inputs: Sequence[str] | None = None, u0: Sequence[float] | None = None,
              params: Mapping[str, float] | None = None, equilibrium=None,
              angles: Sequence[str] = (), dt: float = 0.01, name: str | None = None) -> Model:
    """The analysis' view of a system (a :class:`~hybridnav.models.Model` is returned as it is).

    Parameters
    ----------
    obj : Model, control.NonlinearIOSystem, control.StateSpace, casadi.Function, tuple or do-mpc Model
        ``(x, rhs)`` / ``(x, u, rhs)`` are CasADi SX expressions; a ``Function`` takes ``x`` or
        ``(x, u)`` and returns ``xdot``.
    states, inputs : sequence of str, optional
        Names (default: from the source).
    u0 : sequence of float, optional
        The held input of the analysed closed loop (default 0).
    params : dict, optional
        Parameter values: python-control ``params`` (default: the system's own), or a do-mpc
        model's ``_p`` / ``_tvp`` variables (required when it has any).
    equilibrium : sequence of float, optional
        The default equilibrium of the analysis.
    angles : sequence of str
        States that are angles (modulo 2 pi).
    dt : float
        Simulation step (RK4) of the system's rollouts.
    name : str, optional

    Raises
    ------
    HybridnavError
        A source that cannot be traced symbolically (the message says why and what to pass
        instead), sizes that do not match, or symbols without values.
    """
    if isinstance(obj, Model):
        return obj
    plain = (states is None and inputs is None and u0 is None and params is None
             and equilibrium is None and not angles and dt == 0.01 and name is None)
    # the same object gives the same System (its symbols), so a candidate built from one call's
    # result serves the next call — unless what it was traced from changed since (a
    # python-control system's params or update function are mutable)
    key = _source_key(obj)
    cached = getattr(obj, "__dict__", {}).get("_hybridnav_system") if plain else None
    if cached is not None and cached[0] == key:
        return cached[1]
    system = _convert(obj, states=states, inputs=inputs, u0=u0, params=params,
                      equilibrium=equilibrium, angles=angles, dt=dt, name=name)
    if plain and hasattr(obj, "__dict__"):
        obj.__dict__["_hybridnav_system"] = (key, system)
    return system


def _source_key(obj) -> tuple:
    """What a cached conversion depends on besides the object's identity."""
    params = getattr(obj, "params", None)
    try:
        ptext = repr(sorted((str(k), repr(v)) for k, v in dict(params or {}).items()))
    except (TypeError, ValueError):
        ptext = repr(params)
    return (id(getattr(obj, "updfcn", None)), ptext, getattr(obj, "nstates", None),
            getattr(obj, "ninputs", None))


def _convert(obj, *, states, inputs, u0, params, equilibrium, angles, dt, name) -> System:
    common = dict(u0=u0, equilibrium=equilibrium, angles=angles, dt=dt)
    import control as ct

    if isinstance(obj, ct.StateSpace):
        if not obj.isctime():
            raise HybridnavError("system: expected a continuous-time StateSpace (dt = 0)")
        A, B = np.asarray(obj.A, dtype=float), np.asarray(obj.B, dtype=float)
        x, u = cs.SX.sym("x", A.shape[0]), cs.SX.sym("u", B.shape[1])
        rhs = cs.mtimes(cs.DM(A), x) + (cs.mtimes(cs.DM(B), u) if B.shape[1] else 0)
        return System(x, u, rhs, states=states or list(obj.state_labels),
                      inputs=inputs or list(obj.input_labels), name=name or obj.name, **common)
    if isinstance(obj, ct.NonlinearIOSystem):
        return _from_nlsys(obj, states, inputs, params, name, common)
    if isinstance(obj, cs.Function):
        if obj.n_in() not in (1, 2) or obj.n_out() < 1:
            raise HybridnavError(
                f"system: expected a CasADi Function f(x) or f(x, u) -> xdot, got {obj.n_in()} "
                f"inputs and {obj.n_out()} outputs")
        x = cs.SX.sym("x", obj.size1_in(0))
        u = cs.SX.sym("u", obj.size1_in(1)) if obj.n_in() == 2 else None
        try:
            rhs = obj(x, u) if u is not None else obj(x)
        except RuntimeError as exc:
            raise HybridnavError(f"system: the CasADi Function {obj.name()} cannot be evaluated "
                                 f"on SX symbols ({exc}); build it from SX expressions") from None
        if isinstance(rhs, (list, tuple)):
            rhs = rhs[0]
        return System(x, u, rhs, states=states, inputs=inputs, name=name or obj.name(),
                      **common)
    if isinstance(obj, tuple) and len(obj) in (2, 3):
        x, *mid, rhs = obj
        u = mid[0] if mid else None
        if not all(isinstance(v, cs.SX) or v is None for v in (x, u, rhs)):
            raise HybridnavError("system: expected (x, rhs) or (x, u, rhs) as CasADi SX "
                                 "expressions")
        return System(x, u, rhs, states=states, inputs=inputs, name=name or "system", **common)
    if type(obj).__module__.startswith("do_mpc") or (
            hasattr(obj, "_rhs") and hasattr(obj, "model_type")):
        return _from_do_mpc(obj, states, inputs, params, name, common)
    raise HybridnavError(
        f"system: expected a hybridnav model, a python-control NonlinearIOSystem or StateSpace, a "
        f"CasADi Function, (x, u, rhs) expressions or a do-mpc Model, got {type(obj).__name__}")


def _from_nlsys(sys, states, inputs, params, name, common) -> System:
    if not sys.isctime():
        raise HybridnavError(
            f"system {sys.name}: expected a continuous-time system (dt = 0), got dt = {sys.dt}; "
            "the analysis is of ODEs xdot = f(x, u)")
    n, m = sys.nstates, sys.ninputs
    p = {**(sys.params or {}), **(params or {})}
    x, u = cs.SX.sym("x", n), cs.SX.sym("u", m)
    errors = []
    rhs = None
    for xs, us in ((x, u), (np.array([x[i] for i in range(n)], dtype=object),
                            np.array([u[i] for i in range(m)], dtype=object))):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = sys.updfcn(0.0, xs, us, p)
            rhs = cs.vertcat(*[cs.SX(v) for v in np.asarray(out, dtype=object).ravel()]) \
                if not isinstance(out, cs.SX) else out
            break
        except Exception as exc:       # noqa: BLE001 - any failure of the user's function
            errors.append(f"{type(exc).__name__}: {exc}")
    if rhs is not None and _has_nan_constant(rhs):
        # float(symbol) and math.sin(symbol) give NaN silently in CasADi
        errors.append("a state or input was turned into a number (float(), int() or math.*) "
                      "and became NaN")
        rhs = None
    if rhs is None:
        raise HybridnavError(
            f"system {sys.name}: its update function cannot be traced with CasADi symbols "
            f"({errors[-1]}); write it with numpy ufuncs (np.sin, ...) on x[i], or pass the "
            "dynamics as a CasADi Function or (x, u, rhs) expressions")
    return System(x, u, rhs, states=states or list(sys.state_labels),
                  inputs=inputs or list(sys.input_labels), name=name or sys.name,
                  source=(sys, dict(params or {})), **common)


def _from_do_mpc(model, states, inputs, params, name, common) -> System:
    if getattr(model, "model_type", "") != "continuous":
        raise HybridnavError("system: expected a continuous do-mpc model (model_type "
                             f"'continuous'), got {model.model_type!r}")
    if not getattr(model, "flags", {}).get("setup", True):
        raise HybridnavError("system: the do-mpc model is not set up; call model.setup() first")
    try:
        x, u, rhs = model.x.cat, model.u.cat, model._rhs.cat
    except Exception as exc:            # noqa: BLE001
        raise HybridnavError(f"system: the do-mpc model is not set up ({exc}); call "
                             "model.setup() first") from None
    if model.z.cat.numel():
        raise HybridnavError("system: the do-mpc model has algebraic states (_z); only ODE "
                             "models can be analysed")
    subs, vals = [], []
    for kind in ("p", "tvp"):
        struct = getattr(model, kind)
        for label, sym in zip(struct.labels(), cs.vertsplit(struct.cat)):
            key = label.strip("[]").split(",")[0]
            if key not in (params or {}):
                raise HybridnavError(
                    f"params.{key}: the do-mpc model's {kind} variable {key!r} needs a value "
                    "(pass params={...})")
            idx = int(label.strip("[]").split(",")[1]) if "," in label else 0
            try:
                value = np.asarray((params or {})[key], dtype=float).ravel()
            except (TypeError, ValueError):
                value = np.empty(0)
            if not (value.size in (1, idx + 1) or value.size > idx) or not np.all(
                    np.isfinite(value)) or value.size == 0:
                raise HybridnavError(
                    f"params.{key}: expected finite numbers for the do-mpc model's {kind} "
                    f"variable (entry {idx}), got {(params or {})[key]!r}")
            subs.append(sym)
            vals.append(float(value[idx] if value.size > idx else value[0]))
    if subs:
        rhs = cs.substitute(rhs, cs.vertcat(*subs), cs.DM(vals))
    return System(x, u, rhs, states=states or _do_mpc_names(model.x),
                  inputs=inputs or _do_mpc_names(model.u),
                  name=name or "do_mpc_model", source=(model, dict(params or {})), **common)


def _do_mpc_names(struct) -> list[str]:
    """do-mpc's labels ``[name,i]`` as ``name_i``; a scalar variable keeps its plain name."""
    labels = [lab.strip("[]").replace(",", "_") for lab in struct.labels()]
    return [lab[:-2] if lab.endswith("_0") and sum(
        m.startswith(lab[:-2] + "_") for m in labels) == 1 else lab for lab in labels]


def _has_nan_constant(expr: cs.SX) -> bool:
    fn = cs.Function("nan_check", cs.symvar(expr), [expr], {"allow_free": True}) \
        if cs.symvar(expr) else cs.Function("nan_check", [], [expr])
    return any(fn.instruction_id(k) == cs.OP_CONST and np.isnan(fn.instruction_constant(k))
               for k in range(fn.n_instructions()))


def _column(v, key: str) -> cs.SX:
    if not isinstance(v, cs.SX):
        raise HybridnavError(f"{key}: expected CasADi SX symbols, got {type(v).__name__}")
    v = cs.vec(v)
    if not all(v[i].is_symbolic() for i in range(v.numel())):
        raise HybridnavError(f"{key}: expected a vector of plain SX symbols")
    return v


def _names(given, sym, prefix: str, key: str) -> tuple[str, ...]:
    n = int(sym.numel())
    if given is not None:
        names = tuple(str(s) for s in given)
        if len(names) != n or len(set(names)) != n:
            raise HybridnavError(f"{key}: expected {n} distinct names, got {list(names)}")
        return names
    names = tuple(str(sym[i]) for i in range(n))
    if len(set(names)) != n or any(not nm.isidentifier() for nm in names):
        names = tuple(f"{prefix}{i}" for i in range(n))
    return names


def _vector(v, key: str, n: int) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float).ravel()
    except (TypeError, ValueError):
        raise HybridnavError(f"{key}: expected {n} numbers, got {v!r}") from None
    if a.size != n or not np.all(np.isfinite(a)):
        raise HybridnavError(f"{key}: expected {n} finite numbers, got {a.tolist()}")
    return a


def _unpickled(rhs: str, settings: dict[str, Any], aliases: list[str]) -> System:
    """The system :meth:`System.__reduce__` pickled (its states also known by the names of the
    caller's symbols, as the original: candidates built from them are taken)."""
    fn = cs.Function.deserialize(rhs)
    x, u = fn.sx_in(0), fn.sx_in(1)
    system = System(x, u, fn(x, u), **settings)
    system.aliases = {name: system.sym.x[i] for i, name in enumerate(aliases)}
    return system
