"""Random EFFC-scale worlds: seeded, solvable, writable as scenario TOML.

:class:`WorldGenerator` draws single-robot unicycle scenarios: a square workspace (5 m by
default), circles (and optionally segments and axis-aligned rectangles) whose sizes and counts are
drawn from ranges, a start and goal on a diagonal with jitter (or anywhere, far enough apart) and
an initial heading towards the goal with jitter (or uniform). ``clutter`` is the fraction of
obstacles placed in a corridor around the straight start-goal line, where they matter; the rest
are spread over the workspace. Structures that trap reactive controllers — cups facing the
start, corridors, narrow gaps and walls of segments — can be placed across the start-goal line
(off by default).

Every world is **solvable**: its obstacles are rasterized at ``resolution`` inflated by the robot
radius (and kept that far from the border), and a grid path (8-connected, no corner cutting: the
planners' default moves, :func:`hybridnav.world.grid.connected`) must join the start and goal
cells; a world without one is drawn again (up to ``max_tries`` times).

World ``i`` of a set seeded ``seed`` uses ``numpy.random.SeedSequence(seed, spawn_key=(i,))``,
so it does not depend on how many worlds are drawn, and two seeds give disjoint sets.

>>> from hybridnav.world.generator import WorldGenerator
>>> worlds = WorldGenerator(circles=(2, 4)).generate(3, seed=7)   # list of Scenario
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.params import check_range, check_value

__all__ = ["WorldGenerator", "generator_from_table", "GENERATOR_KEYS", "corridor_parts",
           "cup_parts", "gap_parts"]

#: Largest number of worlds one set may ask for (each is checked by a grid search).
MAX_WORLDS = 10_000


@dataclass(frozen=True)
class WorldGenerator:
    """Settings of the random world generator (EFFC scale by default; lengths in metres).

    Parameters
    ----------
    size : float
        Side of the square workspace ``[0, size]^2``.
    circles : (int, int)
        Range of the number of circular obstacles (inclusive).
    radius : (float, float)
        Range of the circles' radii.
    segments, rectangles : (int, int)
        Ranges of the numbers of wall segments and axis-aligned rectangles (default none).
    segment_length, rectangle_size : (float, float)
        Ranges of a segment's length and of a rectangle's side lengths.
    cups, corridors, gaps, walls : (int, int)
        Ranges of the numbers of the structures that trap reactive controllers (default none),
        each placed across the start-goal line (between 0.35 and 0.65 of the way, ``lateral``
        off it) and built of wall segments: a **cup** (a U of ``cup_width`` by ``cup_depth``
        whose opening faces the start: the classic potential-field trap), a **corridor** (two
        parallel walls ``corridor_length`` long along the line, ``corridor_width`` apart), a
        **gap** (a wall across the line, ``gap_wall`` long on each side of a ``gap_width``
        opening) and a **wall** (a polyline of ``wall_pieces`` segments of ``segment_length``,
        each turning up to 90 degrees from the last).
    cup_width, cup_depth, corridor_width, corridor_length, gap_width, gap_wall : (float, float)
        Their size ranges (the openings' defaults are at least ``min_gap``).
    wall_pieces : (int, int)
    lateral : float
        Largest offset of a structure's centre from the start-goal line.
    clutter : float
        Fraction of obstacles placed in the corridor around the start-goal line.
    corridor : float
        Half-width of that corridor (an obstacle centre's distance from the line).
    layout : {"diagonal", "random"}
        ``diagonal``: start and goal near opposite corners (``0.15 size`` from them) of one of
        the four diagonals, each jittered by ``jitter``; ``random``: anywhere, at least
        ``min_distance`` apart.
    jitter : float
        Half-width of the uniform jitter of start and goal (``diagonal``).
    min_distance : float
        Smallest start-goal distance (``random``).
    heading : {"goal", "random"}
        Initial heading: towards the goal plus a uniform jitter of ``heading_jitter`` (rad), or
        uniform in ``[-pi, pi)``.
    heading_jitter : float
    robot_radius, goal_radius : float
    margin : float
        Free gap kept between obstacles and the start and goal footprints.
    min_gap : float
        Narrowest gap between two obstacles, or an obstacle and the border: obstacles either
        overlap (or touch the border) or leave at least this much room (default 0.3: a 0.2 m
        robot passes with half its radius on each side). 0 allows any gap.
    dt, max_time : float
        The scenarios' control step and time budget (s).
    resolution : float
        Grid cell size of the solvability check.
    max_tries : int
        Draws per world before giving up (an error: the settings leave no free passage).
    name : str
        Prefix of the scenario names, ``{name}-{seed}-{index:03d}``.
    """

    size: float = 5.0
    circles: tuple[int, int] = (1, 6)
    radius: tuple[float, float] = (0.15, 0.45)
    segments: tuple[int, int] = (0, 0)
    segment_length: tuple[float, float] = (0.5, 1.5)
    rectangles: tuple[int, int] = (0, 0)
    rectangle_size: tuple[float, float] = (0.2, 0.8)
    cups: tuple[int, int] = (0, 0)
    cup_width: tuple[float, float] = (0.6, 1.2)
    cup_depth: tuple[float, float] = (0.4, 0.8)
    corridors: tuple[int, int] = (0, 0)
    corridor_width: tuple[float, float] = (0.35, 0.7)
    corridor_length: tuple[float, float] = (0.8, 1.6)
    gaps: tuple[int, int] = (0, 0)
    gap_width: tuple[float, float] = (0.3, 0.45)
    gap_wall: tuple[float, float] = (0.8, 1.6)
    walls: tuple[int, int] = (0, 0)
    wall_pieces: tuple[int, int] = (2, 4)
    lateral: float = 0.2
    clutter: float = 0.7
    corridor: float = 0.6
    layout: str = "diagonal"
    jitter: float = 0.4
    min_distance: float = 2.5
    heading: str = "goal"
    heading_jitter: float = 0.5
    robot_radius: float = 0.1
    goal_radius: float = 0.1
    margin: float = 0.15
    min_gap: float = 0.3
    dt: float = 0.1
    max_time: float = 120.0
    resolution: float = 0.025
    max_tries: int = 200
    name: str = "gen"

    def __post_init__(self) -> None:
        checked = _check_settings(asdict(self), "")
        for k, v in checked.items():
            object.__setattr__(self, k, v)

    # ---- drawing --------------------------------------------------------------------------

    def generate(self, count: int, seed: int = 0):
        """``count`` solvable scenarios of the set seeded ``seed`` (world ``i`` is
        :meth:`world` ``(i, seed)``)."""
        count = check_value("", "generate", count, int, 1, MAX_WORLDS)
        seed = check_value("", "seed", seed, int, 0)
        return [self.world(i, seed) for i in range(count)]

    def world(self, index: int, seed: int = 0):
        """World ``index`` of the set seeded ``seed``: a :class:`hybridnav.world.Scenario`."""
        from hybridnav.world.schema import scenario_from_dict

        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))
        name = f"{self.name}-{seed}-{index:03d}"
        misses: dict[str, int] = {}            # what did not fit, per draw that failed
        unsolvable = 0
        for attempt in range(self.max_tries):
            data = self._draw(rng, name, seed, index)
            if isinstance(data, str):
                misses[data] = misses.get(data, 0) + 1
                continue
            scen = scenario_from_dict(data, source=f"generated world {name}")
            if solvable(scen, self.resolution):
                return scen
            unsolvable += 1
        why = [f"{n} with no room for the {what} asked for" for what, n in
               sorted(misses.items(), key=lambda kv: -kv[1])]
        if unsolvable:
            why.append(f"{unsolvable} without a free passage from start to goal")
        raise HybridnavError(
            f"world generator: no solvable world in {self.max_tries} draws for {name} (seed "
            f"{seed}): {'; '.join(why)}; expected settings that fit the {self.size:g} m "
            "workspace and leave a free passage (fewer or smaller obstacles)")

    def _draw(self, rng: np.random.Generator, name: str, seed: int, index: int
              ) -> dict | str:
        """One candidate world's data, or what could not be placed (every obstacle asked for
        is placed or the draw fails: a world never has fewer obstacles than its settings
        say)."""
        L = self.size
        r = self.robot_radius
        lo, hi = r + 1e-9, L - r - 1e-9
        if self.layout == "diagonal":
            k = int(rng.integers(4))                        # which diagonal, which way
            a = np.array([0.15 * L, 0.15 * L])
            b = np.array([0.85 * L, 0.85 * L])
            if k & 1:
                a, b = np.array([a[0], b[1]]), np.array([b[0], a[1]])
            if k & 2:
                a, b = b, a
            start = np.clip(a + rng.uniform(-self.jitter, self.jitter, 2), lo, hi)
            goal = np.clip(b + rng.uniform(-self.jitter, self.jitter, 2), lo, hi)
        else:
            while True:
                start, goal = rng.uniform(lo, hi, 2), rng.uniform(lo, hi, 2)
                if math.dist(start, goal) >= self.min_distance:
                    break
        to_goal = math.atan2(goal[1] - start[1], goal[0] - start[0])
        if self.heading == "goal":
            theta = to_goal + rng.uniform(-self.heading_jitter, self.heading_jitter)
        else:
            theta = rng.uniform(-math.pi, math.pi)
        theta = math.atan2(math.sin(theta), math.cos(theta))
        keep_out = r + self.margin
        obstacles: list[dict] = []

        def center() -> np.ndarray:
            if rng.random() < self.clutter:
                s = rng.uniform(0.2, 0.8)
                d = goal - start
                n = np.array([-d[1], d[0]]) / max(np.hypot(*d), 1e-12)
                return start + s * d + rng.uniform(-self.corridor, self.corridor) * n
            return rng.uniform(0.0, L, 2)

        placed: list = []

        def place(make) -> bool:
            for _ in range(50):
                obs = make(center())
                shape = _shape(obs)
                if not _clear_of(shape, (start, goal), keep_out):
                    continue
                if self.min_gap > 0 and not _no_narrow_gap(shape, placed, L, self.min_gap):
                    continue
                obstacles.append(obs)
                placed.append(shape)
                return True
            return False

        along = goal - start
        u = along / max(float(np.hypot(*along)), 1e-12)
        n = np.array([-u[1], u[0]])

        def on_line() -> np.ndarray:
            return (start + rng.uniform(0.35, 0.65) * along
                    + rng.uniform(-self.lateral, self.lateral) * n)

        def cup(c):
            return cup_parts(c, u, rng.uniform(*self.cup_width), rng.uniform(*self.cup_depth))

        def corridor(c):
            return corridor_parts(c, u, rng.uniform(*self.corridor_width),
                                  rng.uniform(*self.corridor_length))

        def gap(c):
            g = rng.uniform(*self.gap_width)
            return gap_parts(c, u, g, rng.uniform(*self.gap_wall), rng.uniform(*self.gap_wall))

        def wall(c):
            ang = math.atan2(n[1], n[0]) + rng.uniform(-math.pi / 4, math.pi / 4)
            pts = [c]
            for _ in range(int(rng.integers(self.wall_pieces[0], self.wall_pieces[1] + 1))):
                step = rng.uniform(*self.segment_length)
                pts.append(pts[-1] + step * np.array([math.cos(ang), math.sin(ang)]))
                ang += rng.uniform(-math.pi / 2, math.pi / 2)
            shift = (pts[0] + pts[-1]) / 2 - c          # centred on c
            return [_segment(a - shift, b - shift) for a, b in zip(pts[:-1], pts[1:])]

        def place_group(make) -> bool:
            """A structure of several parts: all clear of start and goal, each part keeping
            min_gap from the obstacles placed before it (not from its own parts)."""
            for _ in range(50):
                parts = make(on_line())
                shapes = [_shape(o) for o in parts]
                if not all(_clear_of(sh, (start, goal), keep_out) for sh in shapes):
                    continue
                if self.min_gap > 0 and not all(
                        _no_narrow_gap(sh, placed, L, self.min_gap) for sh in shapes):
                    continue
                obstacles.extend(parts)
                placed.extend(shapes)
                return True
            return False

        # the structures first (they need the room on the line), then the loose obstacles
        for what, count, make in (("cups", self.cups, cup),
                                  ("corridors", self.corridors, corridor),
                                  ("gaps", self.gaps, gap), ("walls", self.walls, wall)):
            if count[1] == 0:            # no draw at all: worlds without these classes unchanged
                continue
            for _ in range(int(rng.integers(count[0], count[1] + 1))):
                if not place_group(make):
                    return what          # a structure asked for did not fit: draw again
        for _ in range(int(rng.integers(self.circles[0], self.circles[1] + 1))):
            if not place(lambda c: {"type": "circle", "center": [float(c[0]), float(c[1])],
                                    "radius": float(rng.uniform(*self.radius))}):
                return "circles"
        for _ in range(int(rng.integers(self.segments[0], self.segments[1] + 1))):
            def seg(c):
                h = rng.uniform(*self.segment_length) / 2
                ang = rng.uniform(0, math.pi)
                u = h * np.array([math.cos(ang), math.sin(ang)])
                return {"type": "segment", "a": [float(v) for v in c - u],
                        "b": [float(v) for v in c + u]}
            if not place(seg):
                return "segments"
        for _ in range(int(rng.integers(self.rectangles[0], self.rectangles[1] + 1))):
            def rect(c):
                w, h = rng.uniform(*self.rectangle_size, 2) / 2
                return {"type": "rectangle", "min": [float(c[0] - w), float(c[1] - h)],
                        "max": [float(c[0] + w), float(c[1] + h)]}
            if not place(rect):
                return "rectangles"
        return {
            "name": name,
            "description": f"generated world {index} of seed {seed} (hybridnav.world.generator)",
            "units": "m", "dt": self.dt, "max_time": self.max_time,
            "workspace": {"xmin": 0.0, "xmax": L, "ymin": 0.0, "ymax": L},
            "obstacles": obstacles,
            "robots": [{"name": "robot", "model": "unicycle",
                        "start": [float(start[0]), float(start[1])],
                        "goal": [float(goal[0]), float(goal[1])],
                        "goal_radius": self.goal_radius, "radius": r,
                        "initial": {"theta": float(theta)}}],
        }


def _segment(a, b) -> dict:
    return {"type": "segment", "a": [float(v) for v in a], "b": [float(v) for v in b]}


def _normal(u: np.ndarray) -> np.ndarray:
    return np.array([-u[1], u[0]])


def cup_parts(c: np.ndarray, u: np.ndarray, width: float, depth: float) -> list[dict]:
    """A cup centred at ``c`` whose opening faces ``-u`` (the start, for ``u`` the unit vector
    from start to goal): the back wall ``depth / 2`` beyond ``c``, ``width`` wide, and two side
    walls ``depth`` long (three segment obstacles)."""
    n, w = _normal(u), width / 2
    back, front = c + depth / 2 * u, c - depth / 2 * u
    return [_segment(back - w * n, back + w * n), _segment(back - w * n, front - w * n),
            _segment(back + w * n, front + w * n)]


def corridor_parts(c: np.ndarray, u: np.ndarray, width: float, length: float) -> list[dict]:
    """Two parallel walls along ``u``, ``length`` long, ``width`` apart, centred at ``c``."""
    n, w, h = _normal(u), width / 2, length / 2
    return [_segment(c - h * u + side * w * n, c + h * u + side * w * n) for side in (-1, 1)]


def gap_parts(c: np.ndarray, u: np.ndarray, width: float, left: float, right: float
              ) -> list[dict]:
    """A wall across ``u`` through ``c`` with an opening ``width`` wide at ``c``: ``left`` and
    ``right`` long on either side."""
    n, g = _normal(u), width / 2
    return [_segment(c + side * g * n, c + side * (g + length) * n)
            for side, length in ((-1, left), (1, right))]


def _shape(obs: dict):
    from hybridnav.world.obstacles import Circle, Rectangle, Segment

    if obs["type"] == "circle":
        return Circle(tuple(obs["center"]), obs["radius"])
    if obs["type"] == "segment":
        return Segment(tuple(obs["a"]), tuple(obs["b"]))
    return Rectangle(tuple(obs["min"]), tuple(obs["max"]))


def _clear_of(shape, points, keep: float) -> bool:
    return bool(np.all(shape.clearance(np.asarray(points, dtype=float)) >= keep))


def _outline(shape, n: int = 96) -> np.ndarray:
    """Points on a shape's boundary (exact for circles' distances to other circles)."""
    from hybridnav.world.obstacles import Circle, Segment

    if isinstance(shape, Circle):
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return np.asarray(shape.center) + shape.radius * np.column_stack([np.cos(a), np.sin(a)])
    A, B = shape._A, shape._B
    s = np.linspace(0, 1, max(2, n // len(A)), endpoint=not isinstance(shape, Segment))
    return (A[:, None] + s[None, :, None] * (B - A)[:, None]).reshape(-1, 2)


def _no_narrow_gap(shape, placed: list, size: float, gap: float) -> bool:
    """Whether ``shape`` overlaps or keeps ``gap`` from every placed obstacle and the border."""
    from hybridnav.world.obstacles import Circle

    pts = _outline(shape)
    border = np.min(np.minimum.reduce([pts[:, 0], size - pts[:, 0], pts[:, 1],
                                       size - pts[:, 1]]))
    if 0 < border < gap:
        return False
    for other in placed:
        if isinstance(shape, Circle) and isinstance(other, Circle):
            d = math.dist(shape.center, other.center) - shape.radius - other.radius
        else:
            d = min(float(np.min(other.clearance(pts))),
                    float(np.min(shape.clearance(_outline(other)))))
        if 0 < d < gap:
            return False
    return True


def solvable(scenario, resolution: float | None = None) -> bool:
    """Whether a grid path joins every robot's start and fixed goal at its inflated radius.

    The static obstacles are rasterized at ``resolution`` (default: 1/200 of the shorter
    workspace side) with cells closer than the robot radius to an obstacle or the border
    blocked; the start and goal cells must be free and joined by a grid path (8-connected without
    corner cutting; :func:`hybridnav.world.grid.connected`).
    """
    from hybridnav.world.grid import connected, rasterize

    xmin, xmax, ymin, ymax = scenario.world.workspace
    res = resolution or min(xmax - xmin, ymax - ymin) / 200.0
    for r in scenario.robots:
        if r.goal is None:
            continue
        grid = rasterize(scenario.world, res, inflate=r.radius, border=True)
        if not connected(grid, r.start[:2], r.goal[:2]):
            return False
    return True


_INT_RANGES = ("circles", "segments", "rectangles", "cups", "corridors", "gaps", "walls")
_FLOAT_RANGES = ("radius", "segment_length", "rectangle_size", "cup_width", "cup_depth",
                 "corridor_width", "corridor_length", "gap_width", "gap_wall")
_CHOICES = {"layout": ("diagonal", "random"), "heading": ("goal", "random")}
#: Keys a generated set takes in a job file (besides ``generate`` and ``seed``).
GENERATOR_KEYS = tuple(f.name for f in fields(WorldGenerator))


def _check_settings(d: Mapping[str, Any], where: str, prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if k in _INT_RANGES:
            out[k] = check_range(where, key, v, int, 0, 1000)
        elif k in _FLOAT_RANGES:
            out[k] = check_range(where, key, v, float, 1e-6)
        elif k in _CHOICES:
            out[k] = check_value(where, key, v, str, choices=_CHOICES[k])
        elif k == "name":
            out[k] = check_value(where, key, v, str)
            if not out[k].strip() or any(c in out[k] for c in "/\\\n"):
                raise HybridnavError(f"{where}{key}: expected a non-empty name without slashes, "
                                     f"got {v!r}")
        elif k == "wall_pieces":
            out[k] = check_range(where, key, v, int, 1, 100)
        elif k == "max_tries":
            out[k] = check_value(where, key, v, int, 1, 10_000)
        elif k in ("clutter",):
            out[k] = check_value(where, key, v, float, 0.0, 1.0)
        elif k in ("size", "dt", "max_time", "resolution", "robot_radius", "goal_radius"):
            out[k] = check_value(where, key, v, float, 1e-6)
        else:                                              # jitter, margin, corridor, ...
            out[k] = check_value(where, key, v, float, 0.0)
    size = out.get("size", 5.0)
    res = out.get("resolution", 0.025)
    if size / res > 2000:
        raise HybridnavError(f"{where}{prefix}resolution: expected at most 2000 cells per side "
                             f"(size / resolution), got {size / res:.0f}")
    if "max_time" in out and "dt" in out and out["max_time"] / out["dt"] > 1_000_000:
        raise HybridnavError(f"{where}{prefix}max_time: expected at most 1e6 steps of dt, got "
                             f"{out['max_time'] / out['dt']:.3g}")
    if "max_time" in out and "dt" in out and out["max_time"] < out["dt"]:
        raise HybridnavError(f"{where}{prefix}max_time: expected max_time >= dt")
    if "robot_radius" in out and "size" in out and out["robot_radius"] * 4 >= out["size"]:
        raise HybridnavError(f"{where}{prefix}robot_radius: expected less than a quarter of the "
                             f"workspace size ({out['size']:g}), got {out['robot_radius']:g}")
    if "min_distance" in out and "size" in out and out.get("layout") == "random" \
            and out["min_distance"] > 0.9 * out["size"]:
        raise HybridnavError(f"{where}{prefix}min_distance: expected at most 0.9 * size "
                             f"({0.9 * out['size']:g}), got {out['min_distance']:g}")
    return out


def generator_from_table(table: Any, where: str, key: str):
    """A generated set from a job file's table ``{generate = N, seed = S, <settings>}``.

    Returns
    -------
    (WorldGenerator, count, seed)

    Raises
    ------
    HybridnavError
        Unknown keys, bad values or settings; the message names ``where`` and ``key``.
    """
    pre = f"{key}." if key else ""
    if not isinstance(table, Mapping):
        raise HybridnavError(f"{where}{key}: expected a table {{generate = N, seed = S, ...}}, "
                             f"got {table!r}")
    allowed = ("generate", "seed", *GENERATOR_KEYS)
    bad = sorted(set(table) - set(allowed))
    if bad:
        raise HybridnavError(f"{where}{pre}{bad[0]}: unknown key; expected one of: "
                             + ", ".join(allowed))
    if "generate" not in table:
        raise HybridnavError(f"{where}{pre}generate: missing; expected the number of worlds")
    count = check_value(where, f"{pre}generate", table["generate"], int, 1, MAX_WORLDS)
    seed = check_value(where, f"{pre}seed", table.get("seed", 0), int, 0)
    settings = {k: v for k, v in table.items() if k not in ("generate", "seed")}
    checked = _check_settings(settings, where, pre)
    try:
        gen = WorldGenerator(**checked)
    except HybridnavError as exc:
        raise HybridnavError(f"{where}{key or 'generator'}: {exc}") from None
    return gen, count, seed
