"""The scenario TOML schema: validation (:func:`scenario_from_dict`) and loading (:func:`load_scenario`)."""

from __future__ import annotations

import logging
import math
import os
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav import models
from hybridnav.errors import HybridnavError, where
from hybridnav.fileio import MAX_ROBOT_NAME, SAFE_NAME, parse_toml, read_text_file
from hybridnav.limits import (
    MAX_COORDINATE,
    MAX_GRID_CELLS,
    MAX_OBSTACLES,
    MAX_ROBOTS,
    MAX_STEPS,
    MAX_VERTICES,
    grid_cells,
)
from hybridnav.params import Param, short_repr
from hybridnav.world.builtin import _builtin_dir
from hybridnav.world.grid import build_grid
from hybridnav.world.obstacles import (
    _TYPE_OF,
    OBSTACLE_TYPES,
    Circle,
    MovingCircle,
    Obstacle,
    Polygon,
    Rectangle,
    Segment,
)
from hybridnav.world.scenario import GridSpec, Robot, Scenario
from hybridnav.world.world import World

__all__ = ["MODEL_NAMES", "list_scenarios", "load_scenario", "scenario_from_dict"]

log = logging.getLogger(__name__)


#: Robot model names a scenario may use: the registered models with the ``"robot"`` capability.
MODEL_NAMES: tuple[str, ...] = tuple(sorted(n for n, cls in models.MODELS.items()
                                            if "robot" in cls.capabilities))

_TOP_KEYS = ("name", "description", "units", "dt", "max_time", "workspace", "obstacles", "robots", "grid")
_TOP_REQUIRED = ("name", "dt", "max_time", "workspace", "robots")
_WS_KEYS = ("xmin", "xmax", "ymin", "ymax")
_OBSTACLE_KEYS = {
    "circle": ("center", "radius"),
    "segment": ("a", "b"),
    "rectangle": ("min", "max"),
    "polygon": ("points",),
    "moving_circle": ("center", "radius", "velocity", "heading"),
}
_ROBOT_KEYS = ("name", "model", "start", "goal", "goal_follow", "goal_radius", "radius", "initial", "params")
_ROBOT_REQUIRED = ("name", "model", "start")
_GRID_KEYS = ("map", "resolution")


def _tname(v: Any) -> str:
    if isinstance(v, bool):
        return f"boolean {v!r}"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, list):
        return "an array"
    return f"{type(v).__name__} {v!r}"


class _Check:
    """Validation helpers that raise HybridnavError naming the file and dotted key."""

    def __init__(self, source: str | None):
        self.source = source

    def fail(self, key: str, msg: str) -> HybridnavError:
        return HybridnavError(f"{where(self.source, key)}: {msg}")

    def table(self, v: Any, key: str) -> Mapping[str, Any]:
        if not isinstance(v, Mapping):
            raise self.fail(key, f"expected a table, got {_tname(v)}")
        return v

    def keys(self, d: Mapping[str, Any], key: str, allowed: Sequence[str], required: Sequence[str]) -> None:
        for k in d:
            if k not in allowed:
                raise self.fail(_join(key, k), f"unknown key; expected one of: {', '.join(allowed)}")
        for k in required:
            if k not in d:
                raise self.fail(_join(key, k), "missing required key")

    def number(self, v: Any, key: str, *, lo: float | None = None, lo_open: bool = False,
               hi: float | None = None) -> float:
        return Param(0.0, lo=lo, lo_open=lo_open, hi=hi).check(key, v, where(self.source, ""))

    def length(self, v: Any, key: str, *, lo_open: bool = True) -> float:
        """A size in the workspace: positive (or non-negative) and at most MAX_COORDINATE."""
        return self.number(v, key, lo=0.0, lo_open=lo_open, hi=MAX_COORDINATE)

    def string(self, v: Any, key: str, *, nonempty: bool = False) -> str:
        if not isinstance(v, str):
            raise self.fail(key, f"expected a string, got {_tname(v)}")
        if nonempty and not v.strip():
            raise self.fail(key, "expected a non-empty string")
        return v

    def point(self, v: Any, key: str) -> tuple[float, float]:
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise self.fail(key, f"expected a point [x, y], got {_tname(v)}")
        return (self.number(v[0], f"{key}[0]", lo=-MAX_COORDINATE, hi=MAX_COORDINATE),
                self.number(v[1], f"{key}[1]", lo=-MAX_COORDINATE, hi=MAX_COORDINATE))

    def numbers_table(self, v: Any, key: str) -> dict[str, float]:
        d = self.table(v, key)
        return {str(k): self.number(x, _join(key, k)) for k, x in d.items()}


def _join(key: str, sub: str) -> str:
    return f"{key}.{sub}" if key else sub


def _parse_obstacle(chk: _Check, raw: Any, key: str) -> Obstacle:
    d = chk.table(raw, key)
    if "type" not in d:
        raise chk.fail(f"{key}.type", f"missing required key; expected one of: {', '.join(OBSTACLE_TYPES)}")
    kind = chk.string(d["type"], f"{key}.type")
    if kind not in _OBSTACLE_KEYS:
        raise chk.fail(f"{key}.type", f"unknown obstacle type {kind!r}; expected one of: {', '.join(OBSTACLE_TYPES)}")
    fields_ = _OBSTACLE_KEYS[kind]
    chk.keys(d, key, ("type",) + fields_, fields_)
    if kind == "circle":
        c = chk.point(d["center"], f"{key}.center")
        r = chk.length(d["radius"], f"{key}.radius")
        return Circle(c, r)
    if kind == "moving_circle":
        c = chk.point(d["center"], f"{key}.center")
        r = chk.length(d["radius"], f"{key}.radius")
        v = chk.length(d["velocity"], f"{key}.velocity", lo_open=False)
        h = chk.number(d["heading"], f"{key}.heading")
        return MovingCircle(c, r, v, h)
    if kind == "segment":
        a = chk.point(d["a"], f"{key}.a")
        b = chk.point(d["b"], f"{key}.b")
        if a == b:
            raise chk.fail(f"{key}.b", f"expected an end point different from a (zero-length segment at {list(a)})")
        return Segment(a, b)
    if kind == "rectangle":
        lo = chk.point(d["min"], f"{key}.min")
        hi = chk.point(d["max"], f"{key}.max")
        if not (lo[0] < hi[0] and lo[1] < hi[1]):
            raise chk.fail(f"{key}.max", f"expected max > min in both x and y, got min={list(lo)} max={list(hi)}")
        return Rectangle(lo, hi)
    # polygon
    pts_raw = d["points"]
    if not isinstance(pts_raw, list):
        raise chk.fail(f"{key}.points", f"expected an array of points [[x, y], ...], got {_tname(pts_raw)}")
    if len(pts_raw) > MAX_VERTICES:
        raise chk.fail(f"{key}.points", f"expected at most {MAX_VERTICES} points "
                                        f"(hybridnav.limits.MAX_VERTICES), got {len(pts_raw)}")
    pts = tuple(chk.point(p, f"{key}.points[{i}]") for i, p in enumerate(pts_raw))
    if len(pts) < 3:
        raise chk.fail(f"{key}.points", f"expected at least 3 points, got {len(pts)}")
    try:
        return Polygon(pts)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.points", str(exc)) from None


def scenario_from_dict(data: Mapping[str, Any], source: str | os.PathLike[str] | None = None) -> Scenario:
    """Validate a parsed scenario (the TOML schema as a dict) and build a :class:`Scenario`.

    Parameters
    ----------
    data : mapping
        Parsed TOML (see the schema in the README / :mod:`hybridnav.world`).
    source : str or path-like, optional
        File the data came from; used in error messages and to resolve relative grid map paths.

    Returns
    -------
    Scenario

    Raises
    ------
    HybridnavError
        On unknown or missing keys, wrong types, non-finite numbers, an empty workspace,
        non-positive ``dt``/``max_time``, bad obstacles, a start or goal footprint outside the
        workspace or overlapping a static obstacle (starts also moving circles at ``t = 0``),
        overlapping start footprints, unknown models, duplicate robot names, bad goals, or a
        missing grid map. The message names the file and the dotted key.
    """
    src = None if source is None else str(source)
    chk = _Check(src)
    d = chk.table(data, "(top level)")
    chk.keys(d, "", _TOP_KEYS, _TOP_REQUIRED)

    name = chk.string(d["name"], "name", nonempty=True)
    description = chk.string(d.get("description", ""), "description")
    units = chk.string(d.get("units", "m"), "units")
    dt = chk.number(d["dt"], "dt", lo=0.0, lo_open=True)
    max_time = chk.number(d["max_time"], "max_time", lo=0.0, lo_open=True)
    if max_time < dt:
        raise chk.fail("max_time", f"expected max_time >= dt ({dt:g}), got {max_time:g}")
    ratio = max_time / dt            # inf for a subnormal dt: refused below, not ceil'd
    steps = math.ceil(ratio - 1e-9) if math.isfinite(ratio) else math.inf
    if steps > MAX_STEPS:
        raise chk.fail("max_time", f"expected at most {MAX_STEPS} control cycles (max_time / dt, "
                                   f"hybridnav.limits.MAX_STEPS), got {steps:.4g} "
                                   f"(max_time {max_time:g}, dt {dt:g})")

    ws_raw = chk.table(d["workspace"], "workspace")
    chk.keys(ws_raw, "workspace", _WS_KEYS, _WS_KEYS)
    ws = tuple(chk.number(ws_raw[k], f"workspace.{k}", lo=-MAX_COORDINATE, hi=MAX_COORDINATE)
               for k in _WS_KEYS)
    if not ws[0] < ws[1]:
        raise chk.fail("workspace.xmax", f"expected xmax > xmin ({ws[0]:g}), got {ws[1]:g} (empty workspace)")
    if not ws[2] < ws[3]:
        raise chk.fail("workspace.ymax", f"expected ymax > ymin ({ws[2]:g}), got {ws[3]:g} (empty workspace)")

    obs_raw = d.get("obstacles", [])
    if not isinstance(obs_raw, list):
        raise chk.fail("obstacles", f"expected an array of tables ([[obstacles]]), got {_tname(obs_raw)}")
    if len(obs_raw) > MAX_OBSTACLES:
        raise chk.fail("obstacles", f"expected at most {MAX_OBSTACLES} obstacles "
                                    f"(hybridnav.limits.MAX_OBSTACLES), got {len(obs_raw)}")
    obstacles = tuple(_parse_obstacle(chk, o, f"obstacles[{i}]") for i, o in enumerate(obs_raw))
    world = World(ws, obstacles)  # type: ignore[arg-type]

    grid = None
    if "grid" in d:
        g = chk.table(d["grid"], "grid")
        chk.keys(g, "grid", _GRID_KEYS, ())
        gmap = None
        if "map" in g:
            gmap = chk.string(g["map"], "grid.map", nonempty=True)
        res = chk.number(g.get("resolution", 1.0), "grid.resolution", lo=0.0, lo_open=True)
        cells = grid_cells(ws[1] - ws[0], ws[3] - ws[2], res)
        if gmap is None and cells > MAX_GRID_CELLS:
            raise chk.fail("grid.resolution", f"expected a grid of at most {MAX_GRID_CELLS} cells "
                                              f"(hybridnav.limits.MAX_GRID_CELLS), got {cells:.4g} "
                                              f"at resolution {res:g}")
        grid = GridSpec(gmap, res)

    robots = _parse_robots(chk, d["robots"], world, dt)

    scen = Scenario(name, description, units, dt, max_time, world, robots, grid, src)
    if grid is not None and grid.map is not None:
        _check_map(chk, scen)
    return scen


def _robot_params(chk: _Check, raw: Any, key: str, model: str) -> dict[str, float]:
    """A robot's ``params`` table, each value checked against the model's declaration."""
    d = chk.table(raw, key)
    decl = {**models.MODELS[model].parameters, **models.MODELS[model].robot_parameters}
    numeric = sorted(k for k, p in decl.items() if p.kind is float)
    out = {}
    for k, v in d.items():
        p = decl.get(k)
        if p is None:
            raise chk.fail(_join(key, k), f"unknown parameter {k!r} of model {model}; expected "
                                          f"one of: {', '.join(numeric)}")
        if p.kind is not float:
            raise chk.fail(_join(key, k), f"{k} is an option of model {model} that planners "
                                          "choose, not a scenario parameter")
        out[str(k)] = p.check(_join(key, k), v, where(chk.source, ""))
    return out


def _check_model(chk: _Check, key: str, model: str, dt: float, radius: float, has_radius: bool,
                 start, goal, initial: dict[str, float], params: dict[str, float]) -> float:
    """Build the robot's model to validate its params and initial states; return its radius.

    A tractor-trailer's footprint follows from its ``L`` and ``b`` parameters, so it takes no
    ``radius`` key.
    """
    if models.MODELS[model].footprint_from_params and has_radius:
        raise chk.fail(f"{key}.radius", "a tractor_trailer's footprint follows from its params L "
                                        "and b; remove radius (set robots.params.L / b instead)")
    try:
        m = models.get(model, dt=dt, radius=radius, **params)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.params", str(exc)) from None
    try:
        m.initial_state(start, goal if goal is not None else start, initial)
    except HybridnavError as exc:
        raise chk.fail(f"{key}.initial", str(exc)) from None
    return m.radius


def _parse_robots(chk: _Check, raw: Any, world: World, dt: float) -> list[Robot]:
    if not isinstance(raw, list):
        raise chk.fail("robots", f"expected an array of tables ([[robots]]), got {_tname(raw)}")
    if not raw:
        raise chk.fail("robots", "expected at least one robot")
    if len(raw) > MAX_ROBOTS:
        raise chk.fail("robots", f"expected at most {MAX_ROBOTS} robots "
                                 f"(hybridnav.limits.MAX_ROBOTS), got {len(raw)}")
    static = world.static()
    robots: list[Robot] = []
    for i, rr in enumerate(raw):
        key = f"robots[{i}]"
        r = chk.table(rr, key)
        chk.keys(r, key, _ROBOT_KEYS, _ROBOT_REQUIRED)
        name = chk.string(r["name"], f"{key}.name", nonempty=True)
        if not SAFE_NAME.fullmatch(name) or len(name) > MAX_ROBOT_NAME or name in (".", ".."):
            raise chk.fail(f"{key}.name", "expected a name of at most 100 letters, digits, '_', "
                                          "'-' or '.' (it names the robot's result files), got "
                                          f"{short_repr(name)}")
        if any(o.name == name for o in robots):
            raise chk.fail(f"{key}.name", f"expected a unique robot name, {name!r} is used twice")
        model = chk.string(r["model"], f"{key}.model")
        if model not in MODEL_NAMES:
            raise chk.fail(f"{key}.model", f"unknown model {model!r}; expected one of: {', '.join(MODEL_NAMES)}")
        start = chk.point(r["start"], f"{key}.start")
        has_goal, has_follow = "goal" in r, "goal_follow" in r
        if has_goal == has_follow:
            what = "both" if has_goal else "neither"
            raise chk.fail(f"{key}.goal", f"expected exactly one of goal = [x, y] or goal_follow = \"robot\", got {what}")
        goal = chk.point(r["goal"], f"{key}.goal") if has_goal else None
        follow = chk.string(r["goal_follow"], f"{key}.goal_follow", nonempty=True) if has_follow else None
        goal_radius = chk.length(r.get("goal_radius", 0.5), f"{key}.goal_radius")
        radius = chk.length(r.get("radius", 0.5), f"{key}.radius", lo_open=False)
        initial = chk.numbers_table(r.get("initial", {}), f"{key}.initial")
        params = _robot_params(chk, r.get("params", {}), f"{key}.params", model)
        radius = _check_model(chk, key, model, dt, radius, "radius" in r, start, goal, initial,
                              params)

        for what, p in (("start", start), ("goal", goal)):
            if p is None:
                continue
            P = np.asarray([p])
            if not world.inside_workspace(P, radius)[0]:
                raise chk.fail(
                    f"{key}.{what}",
                    f"expected a point whose footprint (radius {radius:g}) lies inside the workspace "
                    f"{list(world.workspace)}, got {list(p)}",
                )
            check = world if what == "start" else static
            c, _, j = check.nearest(P)
            if c[0] < radius:
                obs = check.obstacles[int(j[0])]
                oi = world.obstacles.index(obs)
                raise chk.fail(
                    f"{key}.{what}",
                    f"expected a point whose footprint (radius {radius:g}) is clear of obstacles, "
                    f"got {list(p)} which overlaps obstacles[{oi}] ({_TYPE_OF[type(obs)]})",
                )
        for o in robots:
            if math.dist(o.start, start) < o.radius + radius:
                raise chk.fail(f"{key}.start", f"expected a start whose footprint (radius {radius:g}) does not overlap the start footprint of robot {o.name!r}, got {list(start)}")
        robots.append(Robot(name, model, start, goal, follow, goal_radius, radius, initial, params))

    names = [r.name for r in robots]
    for i, r in enumerate(robots):
        if r.goal_follow is not None:
            if r.goal_follow == r.name:
                raise chk.fail(f"robots[{i}].goal_follow", "expected the name of another robot, got the robot itself")
            if r.goal_follow not in names:
                raise chk.fail(
                    f"robots[{i}].goal_follow",
                    f"expected the name of another robot ({', '.join(n for n in names if n != r.name)}), got {r.goal_follow!r}",
                )
    return robots


def _check_map(chk: _Check, scen: Scenario) -> None:
    """Resolve the grid map now, and check starts/goals lie in free cells of it."""
    try:
        og = build_grid(scen)
    except HybridnavError as exc:
        msg = str(exc)
        if chk.source and not msg.startswith(chk.source):
            raise chk.fail("grid.map", msg) from None
        raise
    for i, r in enumerate(scen.robots):
        for what, p in (("start", r.start), ("goal", r.goal)):
            if p is None:
                continue
            if not og.is_free(np.asarray([p]))[0]:
                raise chk.fail(f"robots[{i}].{what}", f"expected a point in a free cell of grid.map {scen.grid.map!r}, got {list(p)}")



def list_scenarios() -> list[tuple[str, str]]:
    """Built-in scenarios as ``(name, description)`` pairs, sorted by name."""
    out = []
    for entry in _builtin_dir().iterdir():
        if entry.name.endswith(".toml"):
            try:
                desc = str(tomllib.loads(entry.read_text(encoding="utf-8")).get("description", ""))
            except tomllib.TOMLDecodeError:  # pragma: no cover - shipped files are tested
                desc = "(invalid TOML)"
            out.append((entry.name[: -len(".toml")], desc))
    return sorted(out)


def _parse_toml(text: str, source: str) -> dict[str, Any]:
    return parse_toml(text, source, "scenario file")


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load a built-in scenario by name, or a scenario TOML file by path.

    Parameters
    ----------
    name_or_path : str or path-like
        A built-in name (see :func:`list_scenarios`), or a path to a ``.toml`` file. Strings that
        end in ``.toml`` or contain a path separator are paths.

    Returns
    -------
    Scenario

    Raises
    ------
    HybridnavError
        Unknown built-in name, unreadable file, TOML syntax error (the message gives the line), or
        invalid content (see :func:`scenario_from_dict`).
    """
    s = os.fspath(name_or_path)
    is_path = isinstance(name_or_path, os.PathLike) or s.endswith(".toml") or "/" in s or os.sep in s
    if is_path:
        path = Path(s)
        text = read_text_file(path, "scenario file")
        source = str(path)
    else:
        names = sorted(e.name[:-len(".toml")] for e in _builtin_dir().iterdir()
                       if e.name.endswith(".toml"))
        if s not in names:                 # never a file lookup with an arbitrary name
            raise HybridnavError(f"scenario {short_repr(s)}: expected a built-in scenario name "
                                 f"({', '.join(names)}) or a path to a .toml file")
        entry = _builtin_dir().joinpath(f"{s}.toml")
        text = entry.read_text(encoding="utf-8")
        source = str(entry)
    log.debug("loading scenario from %s", source)
    return scenario_from_dict(_parse_toml(text, source), source)
