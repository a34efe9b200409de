"""The compiled control cycle (``lockstep.c``) bound to NumPy: a fuzzy family's batched evaluation
and the whole EFFC lockstep run in one call.

:func:`family_evaluate` is :meth:`hybridnav.fuzzy.family.SystemFamily.evaluate` in C;
:func:`effc_run` is :func:`hybridnav.planners.field.effc.effc_lockstep` — nearest obstacle,
EFFC's inputs, the fuzzy blend weight, the force, the model step (CasADi's generated C for the
model, compiled into the same library) and the outcome tests, every control cycle of every robot —
without returning to Python. Both return ``None`` where they do not apply (no compiler, kernels
switched off, a model whose body is not one disk, a family beyond the kernel's fixed sizes), and
the caller runs its NumPy path. Results agree with the NumPy path to rounding (sums in another
order; the tests compare them).
"""

from __future__ import annotations

import ctypes
from ctypes import POINTER, Structure, c_double, c_int, c_int64, c_void_p
from typing import Any

import numpy as np

from hybridnav import native
from hybridnav.fuzzy.spec import And, Not, Or, TermRef

__all__ = ["apf_run", "available", "effc_run", "family_evaluate"]

_MAX_IN, _MAX_TERMS, _MAX_STACK, _MAX_T = 16, 64, 64, 64
#: cells per side of the nearest-obstacle candidate grid (``WorldStack.cells``); 0 searches every
#: obstacle at every query (the same answers, slower)
CELLS = 32


class _Family(Structure):
    _fields_ = [("n_in", c_int), ("n_terms", c_void_p), ("n_pts", c_void_p),
                ("xin", c_void_p), ("tin", c_void_p), ("inv", c_void_p), ("T", c_int), ("M", c_int),
                ("xout", c_void_p), ("dxh", c_void_p), ("c1", c_void_p), ("c2", c_void_p),
                ("wt", c_void_p), ("wm", c_void_p),
                ("tout", c_void_p), ("tmax", c_void_p), ("R", c_int), ("weights", c_void_p),
                ("cons", c_void_p), ("ante", c_void_p), ("prog", c_void_p),
                ("prog_start", c_void_p), ("default_out", c_double), ("runs", c_void_p),
                ("NB", c_int)]

#: turning samples per output term the kernel's bisection takes (a term with more is scanned)
_MAX_TURNS = 8


def monotone_runs(output: np.ndarray, most: int = _MAX_TURNS) -> np.ndarray:
    """The turning samples of each output term's samples ``output`` ``(K, T, M)``: ``(K, T,
    most + 1)`` int32, per term the count ``n`` (``-1``: more than ``most``, or a NaN sample)
    and then the ``n`` samples where the direction (up or down; flat keeps the last) changes.
    Between two turning samples (and the ends) a term never decreases or never increases, so
    a level's crossings are found by bisection."""
    K, T, M = output.shape
    runs = np.full((K, T, most + 1), -1, dtype=np.int32)
    if M < 3:
        runs[..., 0] = 0
        return runs
    d = np.sign(np.diff(output, axis=2))                       # (K, T, M - 1)
    last = np.maximum.accumulate(np.where(d != 0, np.arange(M - 1), 0), axis=2)
    way = np.take_along_axis(d, last, axis=2)                  # flat: the last direction
    turn = way[..., 1:] != way[..., :-1]                       # at sample j + 1
    count = turn.sum(axis=2)
    kk, tt, jj = np.nonzero(turn)
    start = (np.cumsum(count.ravel()) - count.ravel())[kk * T + tt]
    rank = np.arange(len(kk)) - start
    ok = rank < most
    runs[kk[ok], tt[ok], 1 + rank[ok]] = jj[ok] + 1
    runs[..., 0] = np.where((count > most) | np.isnan(output).any(axis=2), -1, count)
    return runs


class _Stack(Structure):
    _fields_ = [("E", c_int), ("C", c_int), ("G", c_int), ("Ed", c_int), ("Kp", c_int),
                ("moving", c_int), ("c0", c_void_p), ("cv", c_void_p), ("cr", c_void_p),
                ("eA", c_void_p), ("eB", c_void_p), ("owner", c_void_p), ("closed", c_void_p),
                ("perm", c_void_p), ("has", c_void_p), ("ws", c_void_p),
                ("g_start", c_void_p), ("cells", c_int), ("cell_geo", c_void_p),
                ("cell_off", c_void_p), ("cell_col", c_void_p), ("kof", c_void_p)]


class _Run(Structure):
    _fields_ = [("N", c_int64), ("nx", c_int), ("steps", c_int), ("window", c_int),
                ("dt", c_double), ("speed", c_double), ("stuck_radius", c_double),
                ("foot_radius", c_double), ("div_x", c_double), ("div_y", c_double),
                ("env", c_void_p), ("member", c_void_p), ("repeats", c_int64),
                ("in_dtheta", c_int), ("in_alpha", c_int), ("in_clear", c_int),
                ("safety", c_double), ("max_turn", c_double), ("X", c_void_p),
                ("goals", c_void_p), ("goal_r", c_void_p), ("budget", c_void_p),
                ("radius", c_void_p), ("noise", c_void_p), ("noise_members", c_int64),
                ("noise_steps", c_int64), ("status", c_void_p), ("length", c_void_p),
                ("t_end", c_void_p), ("min_clear", c_void_p), ("paths", c_void_p),
                ("field", c_int), ("xi", c_double), ("sigma0", c_double), ("eta", c_double),
                ("rho0", c_double), ("force_tol", c_double), ("gains", c_void_p)]

_FIELD_EFFC, _FIELD_APF = 0, 1


class _Keep:
    """Arrays whose memory a structure points into (kept alive with it)."""

    def __init__(self) -> None:
        self.arrays: list[Any] = []

    def ptr(self, a, dtype) -> int:
        a = np.ascontiguousarray(a, dtype=dtype)
        self.arrays.append(a)
        return a.ctypes.data

    def ptrs(self, arrays, dtype) -> int:
        held = [np.ascontiguousarray(a, dtype=dtype) for a in arrays]
        self.arrays += held
        table = (c_void_p * max(1, len(held)))(*[h.ctypes.data for h in held])
        self.arrays.append(table)
        return ctypes.addressof(table)


_LIBS: dict[tuple, ctypes.CDLL | None] = {}


def _library(model=None) -> ctypes.CDLL | None:
    """The kernel library (with ``model``'s step linked in), looked up once per process."""
    if not native.enabled():
        return None
    key = (native.cache_dir(), None if model is None else model._key())
    if key not in _LIBS:
        code = native.source("escape.c") + "\n" + native.source("lockstep.c")
        if model is None:
            lib = native.build("family", "#define HN_NO_MODEL 1\n" + code)
        else:
            lib = native.build(f"lockstep-{model.name}", _model_code(model) + "\n" + code)
        try:
            if lib is not None:
                lib.hn_family_eval.argtypes = [POINTER(_Family), c_int64, c_void_p, c_void_p,
                                               c_void_p]
                lib.hn_family_eval.restype = c_int
                if model is not None:
                    lib.hn_effc_run.argtypes = [POINTER(_Family), POINTER(_Stack),
                                                POINTER(_Run)]
                    lib.hn_effc_run.restype = c_int
        except AttributeError:             # a library without the kernel's functions
            lib = None
        _LIBS[key] = lib
    return _LIBS[key]


_MODEL_CODE: dict[tuple, str] = {}


def _model_code(model) -> str:
    """CasADi's generated C for one control cycle of ``model`` as ``hn_model_step``."""
    key = model._key()
    if key not in _MODEL_CODE:
        import casadi as cs

        single = model._step_single()
        x = cs.SX.sym("x", model.nx)
        tg = cs.SX.sym("target", model.target_size)
        fn = cs.Function("hn_model_step", [x, tg], [single(x, tg)])
        cg = cs.CodeGenerator("hn_model_step.c", {"with_header": False})
        cg.add(fn)
        _MODEL_CODE[key] = cg.dump()
    return _MODEL_CODE[key]


def _program(family) -> tuple[list[int], list[int]] | None:
    """Each template rule's antecedent as a postfix program (term, NOT, AND n, OR n)."""
    prog: list[int] = []
    starts = [0]
    depth_max = 0

    def emit(a, depth: int) -> int:
        nonlocal depth_max
        depth_max = max(depth_max, depth + 1)
        if isinstance(a, TermRef):
            i, j = family._term_index[(a.input, a.term)]
            prog.extend((1, i, j))
        elif isinstance(a, Not):
            emit(a.item, depth)
            prog.append(2)
        else:
            for n, item in enumerate(a.items):
                emit(item, depth + n)
            prog.extend((3 if isinstance(a, And) else 4, len(a.items)))
            assert isinstance(a, (And, Or))
        return depth_max

    for rule in family.rules:
        emit(rule.antecedent, 0)
        starts.append(len(prog))
    if depth_max > _MAX_STACK:
        return None
    return prog, starts


def _fits(family, tables) -> bool:
    """Whether ``tables`` are a table set of ``family`` the kernel can read without leaving its
    arrays: shapes, consequents and rule codes in range (tables are mutable after
    :meth:`SystemFamily.tables` checked them; where they do not fit, the NumPy path runs and
    says what is wrong)."""
    K, T, R = tables.size, len(family.output.terms), len(family.rules)
    terms = [len(v.terms) for v in family.inputs]
    if len(terms) > _MAX_IN or max(terms) > _MAX_TERMS or T > _MAX_T:
        return False
    if len(tables.inputs) != len(terms) or any(
            np.shape(t) != (K, n, len(x)) for t, n, x in zip(tables.inputs, terms, family.x_in)):
        return False
    if (np.shape(tables.output) != (K, T, len(family.x_out))
            or np.shape(tables.weights) != (K, R) or np.shape(tables.consequents) != (K, R)):
        return False
    cons = np.asarray(tables.consequents)
    if cons.size and (cons.min() < 0 or cons.max() >= T):
        return False
    if tables.antecedents is not None:
        codes = np.asarray(tables.antecedents)
        if codes.shape != (K, R, len(terms)):
            return False
        if codes.size and (codes.min() < 0
                           or np.any(codes > 2 * np.array(terms)[None, None, :])):
            return False
    return True


def _family_struct(family, tables, keep: _Keep, runs: bool = True) -> _Family | None:
    terms = [len(v.terms) for v in family.inputs]
    T = len(family.output.terms)
    if not _fits(family, tables):
        return None
    prog = None
    if tables.antecedents is None:
        prog = getattr(family, "_native_program", False)
        if prog is False:
            prog = family._native_program = _program(family)
        if prog is None:
            return None
    f = _Family()
    f.n_in = len(terms)
    f.n_terms = keep.ptr(terms, np.int32)
    f.n_pts = keep.ptr([len(x) for x in family.x_in], np.int32)
    f.xin = keep.ptrs(family.x_in, np.float64)
    f.tin = keep.ptrs(tables.inputs, np.float64)
    f.inv = keep.ptr([(len(x) - 1) / (x[-1] - x[0]) if len(x) > 1 and x[-1] > x[0] else 0.0
                      for x in family.x_in], np.float64)
    f.T, f.M = T, len(family.x_out)
    f.xout = keep.ptr(family.x_out, np.float64)
    xs = family.x_out
    x0, dx = xs[:-1], np.diff(xs)              # the coefficients upsampled_centroid uses
    dxh, c1, c2 = dx / 2.0, dx * x0 / 2.0, dx * dx / 6.0
    f.dxh, f.c1, f.c2 = keep.ptr(dxh, np.float64), keep.ptr(c1, np.float64), keep.ptr(c2, np.float64)
    wt, wm = np.zeros(len(xs)), np.zeros(len(xs))
    wt[:-1] += dxh                             # sample m opens interval m ...
    wt[1:] += dxh                              # ... and closes interval m - 1
    wm[:-1] += c1 + c2
    wm[1:] += c1 + 2.0 * c2
    f.wt, f.wm = keep.ptr(wt, np.float64), keep.ptr(wm, np.float64)
    f.tout = keep.ptr(tables.output, np.float64)
    f.tmax = keep.ptr(tables.output.max(axis=2), np.float64)
    f.R = len(family.rules)
    f.weights = keep.ptr(tables.weights, np.float64)
    f.cons = keep.ptr(tables.consequents, np.int64)
    f.ante = None if tables.antecedents is None else keep.ptr(tables.antecedents, np.int64)
    if prog is not None:
        f.prog = keep.ptr(prog[0] or [0], np.int32)
        f.prog_start = keep.ptr(prog[1], np.int32)
    f.default_out = float(family.output.default)
    if runs:
        f.runs = keep.ptr(monotone_runs(np.asarray(tables.output, dtype=np.float64)), np.int32)
        f.NB = _MAX_TURNS
    return f


def _loaded(family, tables, model=None, runs: bool = True):
    """``(lib, keep, family struct)`` for a kernel call, or ``None`` (no kernel, or tables it
    cannot read safely); ``runs``: with the output terms' monotone runs (worth their cost
    over many evaluations)."""
    lib = _library(model)
    if lib is None:
        return None
    keep = _Keep()
    f = _family_struct(family, tables, keep, runs)
    return None if f is None else (lib, keep, f)


def family_evaluate(family, tables, member: np.ndarray, inputs) -> np.ndarray | None:
    """:meth:`SystemFamily.evaluate` compiled, or ``None`` where the kernel does not apply."""
    B = len(member)
    ready = _loaded(family, tables, runs=B >= 256)
    if ready is None:
        return None
    lib, keep, f = ready
    member = np.ascontiguousarray(member, dtype=np.int64)
    if B and (member.min() < 0 or member.max() >= tables.size):
        return None                        # NumPy's indexing (wrapping, IndexError) decides
    X = np.empty((len(family.inputs), B))
    for i, v in enumerate(family.inputs):
        x = np.asarray(inputs[v.name], dtype=float).ravel()
        if x.shape != (B,):
            return None                    # NumPy's broadcasting rules decide
        X[i] = x
    out = np.empty(B)
    if lib.hn_family_eval(ctypes.byref(f), B, member.ctypes.data, X.ctypes.data,
                          out.ctypes.data) < 0:
        raise MemoryError("the compiled fuzzy evaluation could not allocate its work memory")
    return out


def _stack_struct(stack, keep: _Keep) -> _Stack:
    s = _Stack()
    s.E = len(stack.worlds)
    s.C, s.G, s.Ed, s.Kp = stack.C, stack.G, stack.eA.shape[1], stack.perm.shape[1]
    if not stack.K:
        s.Kp = 0
    s.moving = int(bool(stack.moving))
    s.c0, s.cv, s.cr = (keep.ptr(stack.c0, np.float64), keep.ptr(stack.cv, np.float64),
                        keep.ptr(stack.cr, np.float64))
    s.eA, s.eB = keep.ptr(stack.eA, np.float64), keep.ptr(stack.eB, np.float64)
    s.owner = keep.ptr(stack.owner, np.int64)
    s.closed = keep.ptr(stack.closed, np.uint8)
    s.perm = keep.ptr(stack.perm, np.int64)
    s.has = keep.ptr(stack.has_obstacles, np.uint8)
    s.ws = keep.ptr(stack.ws, np.float64)
    s.g_start = keep.ptr(stack.g_start, np.int64)
    cells = stack.cells(CELLS) if CELLS else None
    if cells is not None:
        geo, off, col = cells
        s.cells = CELLS
        s.cell_geo = keep.ptr(geo, np.float64)
        s.cell_off = keep.ptr(off, np.int64)
        s.cell_col = keep.ptr(col, np.int32)
        s.kof = keep.ptr(stack.column_obstacle(), np.int32)
    return s


def _single_disk(model) -> bool:
    from hybridnav.models.base import Model

    return type(model).footprint is Model.footprint


def effc_run(batch, family, tables, planner: dict[str, Any], *, repeats: int, noise,
             radius: np.ndarray, record_paths: bool):
    """The EFFC lockstep run of ``batch`` (:func:`hybridnav.planners.field.lockstep.prepare`)
    compiled: the arrays of :func:`hybridnav.planners.field.lockstep.finish`, or ``None``."""
    model = batch.model
    names = [v.name for v in family.inputs]
    if not _single_disk(model) or sorted(names) not in (["alpha", "dtheta"],
                                                        ["alpha", "clearance", "dtheta"]):
        return None
    repeats = int(repeats)
    if repeats < 1 or (batch.M - 1) // repeats >= tables.size:
        return None                        # the NumPy path says what is wrong
    if noise is not None:
        noise = np.asarray(noise)
        if (noise.ndim != 4 or noise.shape[:2] != (3, batch.E) or noise.shape[2] < batch.M
                or noise.shape[3] < 1):
            return None
    ready = _loaded(family, tables, model)
    if ready is None:
        return None
    lib, keep, f = ready
    r = _Run()
    r.field = _FIELD_EFFC
    r.repeats = repeats
    r.in_dtheta, r.in_alpha = names.index("dtheta"), names.index("alpha")
    r.in_clear = names.index("clearance") if "clearance" in names else -1
    if noise is not None:
        r.noise = keep.ptr(noise, np.float64)
        r.noise_members, r.noise_steps = noise.shape[2], noise.shape[3]
    return _field_run(lib, keep, f, r, batch, planner, radius, record_paths)


def apf_run(batch, values: dict[str, Any], *, radius: np.ndarray, record_paths: bool,
            gains: np.ndarray | None = None):
    """The APF lockstep run of ``batch`` compiled (the ``apf`` planner's ``values``): the arrays
    of :func:`hybridnav.planners.field.lockstep.finish`, or ``None`` where the kernel does not
    apply.

    ``gains`` ``(members, 3)``: each member's own ``xi, eta, rho0`` (PBPF's population) instead
    of those of ``values``."""
    model = batch.model
    if not _single_disk(model):
        return None
    if gains is not None:
        gains = np.asarray(gains, dtype=float)
        if gains.shape != (batch.M, 3):
            return None
    lib = _library(model)
    if lib is None:
        return None
    keep = _Keep()
    r = _Run()
    r.field = _FIELD_APF
    r.repeats = 1
    r.in_clear = -1
    r.xi, r.sigma0, r.eta = float(values["xi"]), float(values["sigma0"]), float(values["eta"])
    r.rho0, r.force_tol = float(values["rho0"]), float(values["force_tol"])
    if gains is not None:
        r.gains = keep.ptr(gains, np.float64)
    return _field_run(lib, keep, None, r, batch, values, radius, record_paths)


def _field_run(lib, keep: _Keep, f, r: _Run, batch, planner: dict[str, Any],
               radius: np.ndarray, record_paths: bool):
    """Fill the run's common fields, call the kernel, and finish the batch."""
    from hybridnav.planners.field.lockstep import finish, stuck_cycles

    model = batch.model
    s = _stack_struct(batch.stack, keep)
    N = batch.N
    X = np.ascontiguousarray(batch.X, dtype=np.float64)
    status = np.zeros(N, dtype=np.int32)
    length = np.zeros(N)
    t_end = np.full(N, np.nan)
    min_clear = np.full(N, np.inf)
    paths = None
    if record_paths:
        paths = np.zeros((N, batch.steps + 1, 2))
        paths[:, 0] = X[:, :2]
    r.N, r.nx, r.steps = N, model.nx, batch.steps
    r.window = stuck_cycles(planner["stuck_window"], batch.dt, batch.steps)
    r.dt, r.speed = batch.dt, float(planner["speed"])
    r.stuck_radius = float(planner["stuck_radius"])
    r.foot_radius = float(model.radius)
    r.div_x, r.div_y = (float(d) for d in model.carrot_divisor())
    r.env = keep.ptr(batch.env, np.int64)
    r.member = keep.ptr(batch.member, np.int64)
    r.safety = float(planner.get("safety_margin", 0.0))
    if getattr(model, "options", {}).get("controller") != "heading":
        r.safety = 0.0          # as lockstep_field: the filter steers heading-controlled robots
        #                         (and reads x[2] as the heading)
    r.max_turn = float(planner["max_turn"])
    r.X = X.ctypes.data
    r.goals = keep.ptr(batch.goals, np.float64)
    r.goal_r = keep.ptr(batch.goal_r, np.float64)
    r.budget = keep.ptr(batch.budget, np.int64)
    r.radius = keep.ptr(radius, np.float64)
    r.status = status.ctypes.data
    r.length, r.t_end = length.ctypes.data, t_end.ctypes.data
    r.min_clear = min_clear.ctypes.data
    r.paths = None if paths is None else paths.ctypes.data
    code = lib.hn_effc_run(None if f is None else ctypes.byref(f), ctypes.byref(s),
                           ctypes.byref(r))
    if code < 0:
        raise MemoryError("the compiled control cycle could not allocate its work memory")
    batch.X[...] = X
    return finish(batch, status.astype(int), length, t_end, min_clear, paths)


def available() -> bool:
    """Whether the compiled kernels can be built here."""
    return _library() is not None
