"""The kinematic model base class: symbolic CasADi declaration, compiled batched stepping.

A model declares, once, in CasADi SX:

* its state ``x`` (plant states, then controller states such as the tractor-trailer's ``xi``),
  its input ``u`` and its parameters ``p``, each with names;
* its open-loop right-hand side ``f(x_plant, u, p)``;
* its go-to-point controller ``u = k(x, target, p)`` and the dynamics of its controller states;
* the closed loop ``xdot = F(x, target, p)``.

Planners call :meth:`Model.step` and :meth:`Model.rollout` with whole batches: ``X`` is ``(N, nx)``
and ``targets`` is ``(N, 2)``. Both integrate the closed loop with fixed-step RK4 (the controller is
evaluated inside every RK4 stage, or held over the step for zero-order-hold controllers).

Where a C compiler works they run in :mod:`hybridnav.models.kernel`: CasADi's algorithm of one
control cycle emitted as C, compiled once per machine for every batch size and horizon, bit for bit
CasADi's compiled path, large batches split over threads. Otherwise (``jit=False``,
``HYBRIDNAV_JIT=0``, ``HYBRIDNAV_NATIVE=0``, no compiler) CasADi functions are built once per batch
size, shared between equal models in the process, optionally JIT-compiled with the system C compiler
(silent fallback to CasADi's virtual machine when no compiler works), and called through
:meth:`casadi.Function.buffer` on NumPy arrays the wrapper keeps alive, so the hot loop pays no
per-call ``DM`` conversion.

Memory layout: a CasADi ``(nx, N)`` matrix is column-major, which is exactly the memory of a
C-contiguous NumPy ``(N, nx)`` array, so batches cross the boundary without transposes.
"""

from __future__ import annotations

import dataclasses
import threading
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi as cs
import numpy as np

import hybridnav.models.kernel as _kernel
from hybridnav.deprecation import RenamedAttribute
from hybridnav.errors import HybridnavError
from hybridnav.models.compile import _Buffered, _compile, evaluate_rows, jit_available
from hybridnav.params import Param, check_real

__all__ = ["Model", "wrap_angle", "jit_available"]


#: Largest batch one CasADi rollout function takes (larger batches run in chunks); only where
#: there is no compiled kernel (:mod:`hybridnav.models.kernel`).
_ROLLOUT_CHUNK = 4096


def _chunks(n: int) -> list[int]:
    """Batch sizes a CasADi rollout of ``n`` robots runs in: chunks of :data:`_ROLLOUT_CHUNK`,
    then the rest's binary digits down to 16, then what is left (at most 8) in one piece
    (10,000 = 2 x 4096 + 1024 + 512 + 256 + 16). Compiled functions come in the sizes they came
    in when batches were padded to the next power of two (1 to 8, then powers of two up to
    4096), and no robot slot is padding."""
    sizes = [_ROLLOUT_CHUNK] * (n // _ROLLOUT_CHUNK)
    rest = n % _ROLLOUT_CHUNK
    while rest > 8:
        size = 1 << (rest.bit_length() - 1)
        sizes.append(size)
        rest -= size
    return sizes + [rest] if rest else sizes

_DT = Param(0.1, "control and integration step (s)", lo=0.0, lo_open=True)
_RADIUS = Param(0.5, "footprint radius of a disk-shaped robot", lo=0.0)

def wrap_angle(a):
    """Wrap an angle (CasADi expression) to ``(-pi, pi]`` via ``atan2(sin a, cos a)``."""
    return cs.atan2(cs.sin(a), cs.cos(a))


# --------------------------------------------------------------------------------------------
# The model base class
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Symbols:
    """The model's symbols: state ``x``, input ``u``, parameters ``p``, target ``(x1, y1)``."""

    x: cs.SX
    u: cs.SX
    p: cs.SX
    target: cs.SX


class Model(ABC):
    """A kinematic robot model with its go-to-point controller, compiled for batches.

    Subclasses set the class attributes and implement :meth:`open_loop`, :meth:`controller` and,
    when they have controller states, :meth:`controller_dynamics`.

    Parameters
    ----------
    dt : float
        Control and integration step in seconds (fixed-step RK4).
    jit : bool or None
        JIT-compile the batched functions with the C compiler. ``None`` (default) compiles when a
        compiler works and falls back silently otherwise.
    radius : float
        Footprint radius of a disk-shaped robot (models with a body shape derive theirs).
    **params
        Numeric model parameters overriding :attr:`defaults`, and the model's options (see
        :attr:`option_defaults`), e.g. ``alpha1=0.2`` or ``controller="heading"``.

    The parameters are kept in :attr:`values` (and :attr:`options`); :meth:`step` and
    :meth:`rollout` follow values changed there in place (their compiled code is built again).
    A model pickles as its class and settings (process pools, Dask workers).
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    plant_state_names: ClassVar[tuple[str, ...]] = ()
    controller_state_names: ClassVar[tuple[str, ...]] = ()
    #: what the model offers other parts, which ask for capabilities rather than names:
    #: ``"robot"`` (a scenario's robot may be this model; the world's schema takes its model names
    #: from here), ``"disk"`` (a one-disk footprint), ``"holonomic"`` (velocity is the input),
    #: ``"heading_control"`` (a constant-speed heading controller option), ``"trailer"``
    capabilities: ClassVar[frozenset[str]] = frozenset({"robot"})
    #: the footprint follows from parameters (a scenario gives no ``radius`` for the robot)
    footprint_from_params: ClassVar[bool] = False
    #: the built-in scenario ``hybridnav analyze MODEL`` uses by default (None: not analysable)
    analysis_scenario: ClassVar[str | None] = None
    #: what ``analyze`` checks, as the model declares it: the other states' values in the (x, y)
    #: slices of its plots; whether the closed loop is smooth at the target (then its
    #: linearization there, the simulated step, regions of attraction and the basin are checked);
    #: the inputs of straight driving for an open-loop linearization (None: none); the name of
    #: its Lyapunov candidate in reports
    analysis_slice: ClassVar[dict[str, float]] = {}
    smooth_at_target: ClassVar[bool] = False
    straight_driving: ClassVar[tuple[float, ...] | None] = None
    candidate_name: ClassVar[str] = "1/2 distance^2"
    #: the unit of that candidate (figures: ``V``, ``dV/dt``); ``"length²"`` for half a squared
    #: distance, None where it has no one unit
    candidate_unit: ClassVar[str | None] = "length²"
    #: states that are angles the dynamics see only modulo 2 pi (the analysis identifies the faces
    #: -pi and pi of a region spanning a whole turn)
    angle_state_names: ClassVar[tuple[str, ...]] = ()
    input_names: ClassVar[tuple[str, ...]] = ()
    #: the unit of each state (the figures' axis labels): ``"length"`` is the scenario's length
    #: unit, ``"rad"`` an angle; see :mod:`hybridnav.plotting.labels`
    state_units: ClassVar[dict[str, str]] = {"x": "length", "y": "length"}
    #: the model's settings, declared once: real-valued :class:`~hybridnav.params.Param` entries
    #: are its numeric parameters (the vector ``p`` in declaration order), the others (strings
    #: with choices, tuples) its options
    parameters: ClassVar[dict[str, Param]] = {}
    #: stricter declarations of some parameters where the model drives a robot in a scenario
    #: (``robots[i].params``): e.g. the point mass's gains, which the analysis may set to any
    #: sign to show an unstable loop, but a robot needs positive
    robot_parameters: ClassVar[dict[str, Param]] = {}
    #: derived from :attr:`parameters` (never written by hand; old models that set them instead
    #: of ``parameters`` still work for one version)
    defaults: ClassVar[dict[str, float]] = {}
    param_docs: ClassVar[dict[str, str]] = {}
    infinite_ok: ClassVar[frozenset[str]] = frozenset()
    option_defaults: ClassVar[dict[str, Any]] = {}
    option_choices: ClassVar[dict[str, tuple]] = {}
    #: ``"continuous"``: the controller is evaluated inside every RK4 stage (the closed loop is an
    #: ODE); ``"zoh"``: the input is computed at the start of each control cycle and held.
    hold: str = "continuous"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "parameters" not in cls.__dict__ and any(
                k in cls.__dict__ for k in ("defaults", "option_defaults")):
            # a model written against the five parallel dicts: one declaration from them, the
            # parent's declaration (bounds, docs) kept for every key it had
            inherited = cls.parameters
            docs = cls.__dict__.get("param_docs", {})

            def old(k, v, numeric):
                p = inherited.get(k)
                if p is not None:
                    return dataclasses.replace(p, default=float(v) if numeric else v,
                                               doc=docs.get(k, p.doc))
                if numeric:
                    return Param(float(v), docs.get(k, ""), allow_inf=k in cls.infinite_ok)
                return Param(v, "", choices=cls.option_choices.get(k),
                             kind=None if isinstance(v, str) else object)

            cls.parameters = {**{k: old(k, v, True) for k, v in cls.defaults.items()},
                              **{k: old(k, v, False) for k, v in cls.option_defaults.items()}}
        # an integer-valued numeric parameter is a real one (the vector p is real)
        cls.parameters = {k: dataclasses.replace(p, default=float(p.default), kind=float)
                          if p.kind is int else p for k, p in cls.parameters.items()}
        decl = cls.parameters
        cls.defaults = {k: p.default for k, p in decl.items() if p.kind is float}
        cls.param_docs = {k: p.doc for k, p in decl.items()}
        cls.infinite_ok = frozenset(k for k, p in decl.items() if p.allow_inf)
        cls.option_defaults = {k: p.default for k, p in decl.items() if p.kind is not float}
        cls.option_choices = {k: p.choices for k, p in decl.items()
                              if p.kind is not float and p.choices is not None}

    def __init__(self, dt: float = 0.1, jit: bool | None = None, radius: float = 0.5,
                 **params: Any) -> None:
        where = f"model {self.name}: "
        self.dt = _DT.check("dt", dt, where)
        self.jit = jit
        self._radius = _RADIUS.check("radius", radius, where)
        options = dict(self.option_defaults)
        values = dict(self.defaults)
        for key, value in params.items():
            if key not in self.parameters:
                raise HybridnavError(
                    f"model {self.name}: unknown parameter {key!r}; expected one of: "
                    + ", ".join(sorted(self.parameters)))
            checked = self.parameters[key].check(key, value, where)
            (values if key in values else options)[key] = checked
        self.options = options
        self.values = values
        self._validate_params()
        self.state_names = tuple(self.plant_state_names) + tuple(self.controller_state_names)
        self.nx = len(self.state_names)
        self.n_plant = len(self.plant_state_names)
        self.nu = len(self.input_names)
        self.param_names = tuple(self.defaults)
        # one named scalar symbol per entry, so expressions print readably ("alpha1*(x1-x)")
        self.sym = _Symbols(
            x=_named(self.state_names),
            u=_named(self.input_names),
            p=_named(self.param_names),
            target=_named(("x1", "y1")),
        )
        self._local = threading.local()
        self._checked = self._settings()

    @property
    def target_size(self) -> int:
        """Entries of a target: a robot's ``(x1, y1)``, the first two states' values."""
        return 2

    def __reduce__(self):
        # pickled as its class and its settings (process pools, Dask): the CasADi symbols, the
        # compiled functions and the per-thread buffers are rebuilt where it is unpickled
        self._recheck(self._settings())
        return (_rebuild, (type(self), {"dt": self.dt, "jit": self.jit, "radius": self._radius},
                           {**self.values, **self.options}))

    # ---- what subclasses provide -------------------------------------------------------------

    @abstractmethod
    def open_loop(self, x, u, p) -> cs.SX:
        """Open-loop right-hand side of the plant states, ``f(x_plant, u, p)``."""

    @abstractmethod
    def controller(self, x, target, p) -> cs.SX:
        """Go-to-point control law ``u = k(x, target, p)`` (``x`` is the full state)."""

    def controller_dynamics(self, x, target, p) -> cs.SX:
        """Derivatives of the controller states (empty for models without any)."""
        return cs.SX(0, 1)

    def body_rates(self, u, p) -> cs.SX | None:
        """The commanded linear speed and turn rate ``(v, omega)`` of the inputs ``u`` (CasADi
        expressions in ``u`` and ``p``), what the control-effort metric integrates; None (the
        default): the model does not say, and its runs have no such metric."""
        return None

    def commanded_rates(self, X, targets) -> np.ndarray | None:
        """The commanded ``(v, omega)`` of a batch ``(N, 2)``: the controller's input at the
        states ``X`` for ``targets`` (what a zero-order-hold controller holds over the coming
        cycle; for a continuous one its value at the cycle's start), through
        :meth:`body_rates`; None when the model has none."""
        X, targets = self._check_batch(X, targets)
        def build():
            # (None, for a model without rates, is kept too; options such as the controller
            # shape the expression). The parameters stay an input: folding their values in lets
            # CasADi reassociate products of constants ((k_alpha*e)*L -> (k_alpha*L)*e), which
            # changes the last bits for most values
            s = self.sym
            rates = self.body_rates(self.controller(s.x, s.target, s.p), s.p)
            return None if rates is None else cs.Function("rates", [s.x, s.target, s.p], [rates])

        fn, now = self._for_settings("_rates_fn", build)
        if fn is None:
            return None
        n = len(X)
        if n == 0:
            return np.zeros((0, 2))
        # bound to NumPy buffers (per thread: a buffer is not re-entrant): a CasADi call with
        # its argument conversions costs some 300 us, more than the planners' whole cycle
        buffers = getattr(self._local, "rates", None)
        if buffers is None:
            buffers = self._local.rates = {}
        b = buffers.get((n, now))
        if b is None:
            if len(buffers) > 16:
                buffers.pop(next(iter(buffers)))
            # p is one column shared by the n robots (not repeated per robot)
            b = buffers[(n, now)] = _Buffered(fn.map(f"rates_{n}", "serial", n, [2], []),
                                       [(n, self.nx), (n, self.target_size),
                                        (len(self.param_names),)], [(n, 2)])
        b.ins[0][...] = X
        b.ins[1][...] = targets
        b.ins[2][...] = self.p_value()
        b()
        return b.outs[0].copy()

    def _validate_params(self) -> None:
        """Check what one declaration cannot say, e.g. relations between values (subclasses
        raise :class:`HybridnavError`)."""

    #: old name of :attr:`values`; warns, removed in 0.4.0
    params = RenamedAttribute.writable("values")

    # ---- symbolic views ------------------------------------------------------------------------

    def p_dict(self, p) -> dict[str, Any]:
        """Map parameter names to the entries of a parameter vector ``p`` (symbolic or numeric)."""
        return {n: p[i] for i, n in enumerate(self.param_names)}

    def closed_loop(self, x=None, target=None, p=None) -> cs.SX:
        """Closed-loop right-hand side ``F(x, target, p)`` (defaults: the model's symbols).

        For zero-order-hold models this is the flow with the input computed from the same ``x``
        (the continuous-time idealization); :meth:`step` holds the input over a cycle instead.
        """
        s = self.sym
        x = s.x if x is None else x
        target = s.target if target is None else target
        p = s.p if p is None else p
        u = self.controller(x, target, p)
        plant = self.open_loop(x[: self.n_plant], u, p)
        return cs.vertcat(plant, self.controller_dynamics(x, target, p))

    def with_params(self, **overrides: Any) -> Model:
        """A copy of this model with some parameters or options (or ``dt``, ``jit``,
        ``radius``) changed."""
        base = {"dt": self.dt, "jit": self.jit, "radius": self._radius}
        for key in base:
            if key in overrides:
                base[key] = overrides.pop(key)
        return type(self)(**base, **{**self.values, **self.options, **overrides})

    def lyapunov_candidate(self, x=None, target=None) -> cs.SX:
        """The default Lyapunov candidate ``V = 1/2 ((x1 - x)^2 + (y1 - y)^2)``."""
        x = self.sym.x if x is None else x
        target = self.sym.target if target is None else target
        return 0.5 * ((target[0] - x[0]) ** 2 + (target[1] - x[1]) ** 2)

    def state_constraints(self, x=None, p=None) -> cs.SX:
        """Expressions that are positive exactly on the admissible states (default: none).

        The analysis tools restrict their regions to ``{x : every entry > 0}`` (for LbCS: the free
        space, outside every obstacle).
        """
        return cs.SX(0, 1)

    def admissible(self, X) -> np.ndarray:
        """Whether each state of a batch ``(N, nx)`` satisfies :meth:`state_constraints`."""
        X = np.asarray(X, dtype=float).reshape(-1, self.nx)
        def build():
            g = self.state_constraints()
            return False if g.numel() == 0 else cs.Function("g", [self.sym.x, self.sym.p], [g])

        fn, _ = self._for_settings("_admissible_fn", build)   # (called in tight loops)
        if fn is False:
            return np.ones(len(X), dtype=bool)
        (vals,) = evaluate_rows(fn, X, self.p_value())
        return np.all(vals > 0, axis=1)

    def p_value(self) -> np.ndarray:
        """The numeric parameter vector in :attr:`param_names` order."""
        return np.array([self.values[n] for n in self.param_names], dtype=float)

    def function(self, kind: str = "closed_loop") -> cs.Function:
        """A CasADi function of the model's symbols.

        ``kind`` is ``"closed_loop"`` (``x, target, p -> xdot``), ``"open_loop"``
        (``x_plant, u, p -> xdot_plant``), ``"controller"`` (``x, target, p -> u``) or ``"step"``
        (``x, target, p -> x_next``, one RK4 control cycle).
        """
        s = self.sym
        if kind == "closed_loop":
            return cs.Function("closed_loop", [s.x, s.target, s.p], [self.closed_loop()],
                               ["x", "target", "p"], ["xdot"])
        if kind == "open_loop":
            xp = s.x[: self.n_plant]
            xps = cs.SX.sym("x", self.n_plant)
            f = cs.substitute(self.open_loop(xp, s.u, s.p), xp, xps) if self.n_plant else xp
            return cs.Function("open_loop", [xps, s.u, s.p], [f], ["x", "u", "p"], ["xdot"])
        if kind == "controller":
            return cs.Function("controller", [s.x, s.target, s.p],
                               [self.controller(s.x, s.target, s.p)], ["x", "target", "p"], ["u"])
        if kind == "step":
            return cs.Function("step", [s.x, s.target, s.p], [self._rk4_expr()],
                               ["x", "target", "p"], ["x_next"])
        raise HybridnavError(
            f"model {self.name}: function kind: expected closed_loop, open_loop, controller or step,"
            f" got {kind!r}"
        )

    def _rk4_expr(self) -> cs.SX:
        s, h = self.sym, self.dt
        x, t, p = s.x, s.target, s.p
        if self.hold == "zoh":
            u = self.controller(x, t, p)

            def rhs(z):
                plant = self.open_loop(z[: self.n_plant], u, p)
                return cs.vertcat(plant, self.controller_dynamics(z, t, p))
        else:

            def rhs(z):
                return self.closed_loop(z, t, p)

        k1 = rhs(x)
        k2 = rhs(x + h / 2 * k1)
        k3 = rhs(x + h / 2 * k2)
        k4 = rhs(x + h * k3)
        return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    # ---- compiled batched evaluation ------------------------------------------------------------

    def _key(self) -> tuple:
        return (type(self).__qualname__, self.dt, tuple(sorted(self.values.items())),
                tuple(sorted((k, repr(v)) for k, v in self.options.items())))

    def _use_jit(self) -> bool:
        return jit_available() if self.jit is None else bool(self.jit) and jit_available()

    def _compiled_kernel(self) -> _kernel.Kernel | None:
        """The model cycle compiled in C (:mod:`hybridnav.models.kernel`), or None: ``jit=False``,
        compiling switched off or impossible; then CasADi's ``map`` runs the batches. Chosen at
        the model's first batch from the environment (``HYBRIDNAV_SIMD``, ``HYBRIDNAV_NATIVE``,
        ``HYBRIDNAV_JIT``) as it is then; built again when :attr:`values` or :attr:`options`
        were changed in place since (the parameters are folded into its code)."""
        return self._for_settings(
            "_kernel", lambda: None if self.jit is False or not _kernel.allowed()
            else _kernel.get(self, _kernel.wanted()))[0]

    def _for_settings(self, name: str, build):
        """``(value, settings)``: what ``build()`` makes of the current settings, kept in
        ``self.__dict__[name]`` and built again (after :meth:`_recheck`) when :attr:`values`,
        :attr:`options` or ``dt`` were changed in place since."""
        now = self._settings()
        got = self.__dict__.get(name)
        if got is None or not _same(got[0], now):
            self._recheck(now)
            now = self._settings()                  # (as checked: ints made floats)
            got = self.__dict__[name] = (now, build())
        return got[1], got[0]

    def _recheck(self, now: tuple) -> None:
        """Validate :attr:`values`, :attr:`options` and ``dt`` when they differ from the settings
        last checked (changed in place), as the constructor does (:class:`HybridnavError` naming
        the key)."""
        checked = self.__dict__.setdefault("_checked", now)
        if _same(checked, now):
            return
        where = f"model {self.name}: "
        self.dt = _DT.check("dt", self.dt, where)
        for held, own, other in ((self.values, set(self.param_names), "options"),
                                 (self.options, set(self.option_defaults), "values")):
            for key in held:
                if key not in own:
                    raise HybridnavError(
                        f"{where}{key}: " + (f"set in the wrong place; it belongs in "
                                             f"model.{other}" if key in self.parameters else
                                             "unknown parameter; expected one of: "
                                             + ", ".join(sorted(self.parameters))))
            for key in sorted(own - set(held)):
                raise HybridnavError(f"{where}{key}: missing; expected "
                                     f"{self.parameters[key].describe()}")
        for key, value in list(self.values.items()) + list(self.options.items()):
            (self.values if key in self.values else self.options)[key] = \
                self.parameters[key].check(key, value, where)
        self._validate_params()
        self.__dict__["_checked"] = self._settings()

    def _settings(self) -> tuple:
        """What the compiled functions fold in, cheaply compared (a call costs ~0.3 us)."""
        return (self.dt, tuple(self.values.items()), tuple(self.options.items()))

    def _step_single(self) -> cs.Function:
        """One control cycle of one robot with the numeric parameters folded in."""
        s = self.sym
        x_next = cs.substitute(self._rk4_expr(), s.p, cs.DM(self.p_value()))
        return cs.Function(f"{self.name}_step", [s.x, s.target], [x_next])

    def _buffered(self, kind: str, n: int, steps: int = 1) -> _Buffered:
        cache = getattr(self._local, "buffers", None)
        if cache is None:
            cache = self._local.buffers = {}
        # (the parameters are folded in: values changed in place need other functions)
        now = self._settings()
        self._recheck(now)
        bkey = (kind, n, steps, now)
        b = cache.get(bkey)
        if b is not None:
            return b
        nx = self.nx
        if kind == "step":

            def build():
                return self._step_single().map(n)

            fn = _compile(self._key() + ("step", n), build, self._use_jit())
            b = _Buffered(fn, [(n, nx), (n, self.target_size)], [(n, nx)])
        else:

            def build():
                single = self._step_single()
                acc = single.mapaccum(f"{self.name}_acc", steps)
                x0 = cs.MX.sym("x0", nx)
                tg = cs.MX.sym("target", self.target_size)
                per_robot = cs.Function(f"{self.name}_rollout1", [x0, tg],
                                        [acc(x0, cs.repmat(tg, 1, steps))])
                return per_robot.map(n)

            fn = _compile(self._key() + ("rollout", n, steps), build, self._use_jit())
            b = _Buffered(fn, [(n, nx), (n, self.target_size)], [(n, steps, nx)])
        if len(cache) > 64:
            cache.pop(next(iter(cache)))
        cache[bkey] = b
        return b

    def _check_batch(self, X, targets) -> tuple[np.ndarray, np.ndarray]:
        X = np.asarray(X, dtype=float)
        targets = np.asarray(targets, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.nx:
            raise HybridnavError(
                f"model {self.name}: X: expected an (N, {self.nx}) array of states "
                f"({', '.join(self.state_names)}), got shape {X.shape}"
            )
        if targets.shape != (X.shape[0], self.target_size):
            raise HybridnavError(
                f"model {self.name}: targets: expected an ({X.shape[0]}, {self.target_size}) "
                f"array, got shape {targets.shape}"
            )
        return X, targets

    def step(self, X, targets, out: np.ndarray | None = None) -> np.ndarray:
        """Advance a batch of robots by one control cycle ``dt`` (closed loop, RK4).

        Parameters
        ----------
        X : array_like, shape (N, nx)
            States in :attr:`state_names` order.
        targets : array_like, shape (N, 2)
            The point each robot's controller drives to.
        out : ndarray, shape (N, nx), optional
            Where to write the result (may be ``X`` itself).

        Returns
        -------
        ndarray, shape (N, nx)
        """
        X, targets = self._check_batch(X, targets)
        n = X.shape[0]
        if n == 0:
            return np.zeros((0, self.nx)) if out is None else out
        k = self._compiled_kernel()
        if k is not None:
            X, targets = np.ascontiguousarray(X), np.ascontiguousarray(targets)
            # the kernel reads a robot's state before it writes that robot's result, so out may
            # be X itself
            direct = out is None or (out is X and out.dtype == np.float64)
            res = np.empty((n, self.nx)) if out is None else out if direct else np.empty_like(X)
            _kernel.run(k, X, targets, res, 1, self.nx, self.nx)
            if not direct:
                out[...] = res
            return res if out is None else out
        b = self._buffered("step", n)
        b.ins[0][...] = X
        b.ins[1][...] = targets
        b()
        if out is None:
            return b.outs[0].copy()
        out[...] = b.outs[0]
        return out

    def rollout(self, X0, targets, steps: int) -> np.ndarray:
        """Simulate a batch of robots for ``steps`` control cycles towards fixed targets.

        Parameters
        ----------
        X0 : array_like, shape (N, nx)
        targets : array_like, shape (N, 2)
        steps : int
            Number of control cycles (>= 0).

        Returns
        -------
        ndarray, shape (N, steps + 1, nx)
            ``[:, 0]`` is ``X0``; ``[:, k]`` the state at ``t = k * dt``.
        """
        X0, targets = self._check_batch(X0, targets)
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
            raise HybridnavError(
                f"model {self.name}: steps: expected a non-negative integer, got {steps!r}"
            )
        n, steps = X0.shape[0], int(steps)
        traj = np.empty((n, steps + 1, self.nx))
        traj[:, 0] = X0
        if n == 0 or steps == 0:
            return traj
        k = self._compiled_kernel()
        if k is not None:
            # one compiled function for every batch size and horizon, writing into traj
            _kernel.run(k, np.ascontiguousarray(X0), np.ascontiguousarray(targets), traj, steps,
                        (steps + 1) * self.nx, self.nx, offset=self.nx)
            return traj
        # CasADi's map: batches of varying size (swarm planners filter their candidates) share
        # compiled functions of power-of-two sizes up to _ROLLOUT_CHUNK (see _chunks). Every
        # robot is integrated independently, so chunking changes no result.
        lo = 0
        for size in _chunks(n):
            b = self._buffered("rollout", size, steps)
            b.ins[0][...] = X0[lo:lo + size]
            b.ins[1][...] = targets[lo:lo + size]
            b()
            traj[lo:lo + size, 1:] = b.outs[0]
            lo += size
        return traj

    # ---- states, targets, footprints -------------------------------------------------------------

    def initial_state(self, start, target, initial: Mapping[str, float] | None = None) -> np.ndarray:
        """The state vector of a robot at ``start`` that is about to drive to ``target``.

        ``initial`` gives other states by name (default 0); controller states are then set for the
        target by :meth:`retarget`.
        """
        initial = dict(initial or {})
        x = np.zeros(self.nx)
        x[0], x[1] = float(start[0]), float(start[1])
        for key, value in initial.items():
            if key not in self.state_names[2:]:
                raise HybridnavError(
                    f"model {self.name}: initial.{key}: unknown state; expected one of: "
                    + ", ".join(self.state_names[2:])
                )
            x[self.state_names.index(key)] = check_real(f"initial.{key}", value)
        return self.retarget(x[None, :], np.asarray(target, dtype=float)[None, :])[0]

    def carrot(self, X, velocity) -> np.ndarray:
        """Targets that make the controller command (about) ``velocity`` now, shape ``(N, 2)``.

        Reactive planners (potential fields) want a velocity; the models take a target point.
        The default puts the target one second of that velocity ahead; models whose controller
        can be inverted exactly override it.
        """
        X = np.asarray(X, dtype=float).reshape(-1, self.nx)
        return X[:, :2] + np.asarray(velocity, dtype=float).reshape(-1, 2) / np.array(
            self.carrot_divisor())

    def carrot_divisor(self) -> tuple[float, float]:
        """``(dx, dy)`` with :meth:`carrot` ``= X[:, :2] + velocity / (dx, dy)``: one second of
        the velocity ahead (``(1, 1)``) unless a model's controller is inverted exactly (the
        compiled control cycle uses the same numbers)."""
        return (1.0, 1.0)

    def retarget(self, X, targets) -> np.ndarray:
        """Reset the controller states of a batch for new targets (identity without any)."""
        X, _ = self._check_batch(X, targets)
        return X.copy()

    @property
    def radius(self) -> float:
        """Radius of the disk covering the whole robot footprint."""
        return self._radius

    def footprint(self, X) -> tuple[np.ndarray, np.ndarray]:
        """Disks covering the robot body for collision checks.

        Returns
        -------
        centers : ndarray, shape (N, m, 2)
        radii : ndarray, shape (m,)
        """
        X = np.asarray(X, dtype=float).reshape(-1, self.nx)
        return X[:, None, :2].copy(), np.array([self.radius])

    def outline(self, X) -> list[np.ndarray] | None:
        """The robot's body as polygons, for drawing (collision checks use :meth:`footprint`).

        Parameters
        ----------
        X : array_like, shape (N, nx)
            States.

        Returns
        -------
        list of ndarray, shape (N, k, 2), or None
            One array of ``k`` corners per body (e.g. a tractor and its trailer); None for a
            robot whose body is its footprint's disks (a disk robot).
        """
        return None

    @property
    def footprint_extent(self) -> float | None:
        """An upper bound on how far the footprint reaches from the robot's position: every
        disk of :meth:`footprint` lies within this distance of the state's ``(x, y)``
        (``max_j |c_j - (x, y)| + r_j``); collision checks prune with it. ``None``: unknown (a
        model that overrides :meth:`footprint` says it too)."""
        if type(self).footprint is Model.footprint:
            return self.radius
        return None

    def closed_loop_at(self, target) -> cs.SX:
        """The closed loop driving to ``target``, in the state symbols only (the target and the
        parameter values substituted): what the analysis integrates, certifies and solves."""
        s = self.sym
        values = cs.DM(np.concatenate([np.asarray(target, dtype=float).ravel(), self.p_value()]))
        return cs.substitute(self.closed_loop(), cs.vertcat(s.target, s.p), values)

    def to_nlsys(self, kind: str = "closed_loop", name: str | None = None):
        """The model as a python-control ``NonlinearIOSystem``.

        ``kind="closed_loop"``: states :attr:`state_names`, inputs the target (``x1, y1``; a
        general system's: none, its input held), ``xdot = F(x, target)``; ``"open_loop"``: the
        plant states, inputs :attr:`input_names`, ``xdot = f(x, u)``. Outputs are the states.
        The update function calls the model's CasADi function (numeric), so
        ``control.linearize``, ``control.input_output_response`` and friends work on it.
        """
        import control

        p = self.p_value()
        if kind == "closed_loop":
            f = self.function("closed_loop")
            target_in = not hasattr(self, "u0")       # a general system holds its input
            inputs = [str(v) for v in cs.vertsplit(self.sym.target)] if target_in else []
            fixed = getattr(self, "equilibrium", None)
            fixed = np.zeros(self.target_size) if fixed is None else fixed

            def upd(t, x, u, params):
                return np.asarray(f(x, u if target_in else fixed, p)).ravel()

            states = list(self.state_names)
        elif kind == "open_loop":
            f = self.function("open_loop")

            def upd(t, x, u, params):
                return np.asarray(f(x, u, p)).ravel()

            states, inputs = list(self.plant_state_names), list(self.input_names)
        else:
            raise HybridnavError(f"model {self.name}: kind: expected 'closed_loop' or "
                                 f"'open_loop', got {kind!r}")
        return control.nlsys(upd, None, states=states, inputs=inputs, outputs=states,
                             name=name or f"{self.name}_{kind}")

    def numeric_closed_loop(self):
        """A NumPy-callable ``F(x, target) -> xdot`` for one robot (for scipy integrators)."""
        f = self.function("closed_loop")
        p = self.p_value()

        def rhs(x, target):
            return np.asarray(f(x, target, p)).ravel()

        return rhs

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v:g}" for k, v in self.values.items())
        opts = "".join(f", {k}={v!r}" for k, v in self.options.items())
        return f"{type(self).__name__}(dt={self.dt:g}, {params}{opts})"


def _same(a, b) -> bool:
    """``a == b`` for settings tuples; False where a value does not compare (an array)."""
    try:
        return bool(a == b)
    except (ValueError, TypeError):
        return False


def _rebuild(cls, base: dict[str, Any], params: dict[str, Any]) -> Model:
    """A model of class ``cls`` with these settings and parameters (:meth:`Model.__reduce__`)."""
    return cls(**base, **params)


def _named(names: Sequence[str]) -> cs.SX:
    """A column of scalar SX symbols with the given names (valid as a Function input)."""
    return cs.vertcat(*[cs.SX.sym(n) for n in names]) if names else cs.SX(0, 1)
