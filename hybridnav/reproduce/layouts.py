"""Layout sensitivity: does a claim's verdict survive small changes of a reconstructed world?

The papers show their worlds as figures only, so every scenario of a protocol is a
reconstruction, and a verdict can come from our layout rather than from the method (a cup
exactly symmetric about the start-goal line gives a nearest-point force blend an equilibrium
that a slightly shifted cup does not have). For every row where a claim does not hold in our
runs, :func:`layout_sensitivity` reruns the claim's planners, in both profiles, on a family of
perturbed layouts of that row's scenario (:func:`perturbed_layouts`) and judges the claim on
each by the same rule as the main table (:func:`hybridnav.reproduce.report.row_verdict`). The
report gives the share of layouts where it holds.

The family, in this order (the first ``count`` that apply):

* ``mirror-x`` / ``mirror-y``: the whole scenario reflected about the workspace's vertical /
  horizontal centre line (obstacles, starts, goals and headings). The problem is the same up
  to symmetry; a verdict that changes exposes ties and numerical asymmetries.
* ``start+`` / ``start-``: every robot's start moved sideways, perpendicular to its start-goal
  line, by ``jitter`` times its start-goal distance.
* ``jitter-K``: every free-standing obstacle moved by a random offset of length up to
  ``jitter`` times the (first robot's) start-goal distance, drawn from the seed. Obstacles
  whose bounding boxes touch move together, and those touching the workspace's edge (outer
  walls and the walls attached to them) stay: moving a piece of a wall would open a gap the
  layout does not have. No obstacle leaves the workspace.

:data:`JITTER` (5 % of the start-goal distance) is what reading a layout off a paper's figure
cannot pin down better: it is what "within what the paper's description allows" means here,
since the papers describe none of these worlds in numbers. A perturbed layout is kept only if
every robot's start and goal stay clear of obstacles and inside the workspace, and, where the
grid search can plan for the robots, A* still finds every robot a path (a layout that closes
the passage tests nothing); a jitter that fails is drawn again (up to :data:`TRIES` times).
Scenarios on a grid map file can only have their starts moved.
"""

from __future__ import annotations

import copy
import math
import re
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.reproduce.protocols import JITTER, Protocol

if TYPE_CHECKING:                            # the command line imports this module: kept light
    import pandas as pd

    from hybridnav.world import Scenario

__all__ = ["JITTER", "LAYOUTS", "LAYOUT_FILE", "LAYOUT_RUNS", "LAYOUT_TAG", "MAX_LAYOUTS", "TRIES", "failing_rows", "layout_sensitivity",
           "perturbed_layouts"]

#: perturbed layouts per row (the CLI's ``--layouts``; 0: no sensitivity runs)
LAYOUTS = 8
#: the most ``--layouts`` takes
MAX_LAYOUTS = 100
#: runs per planner and layout (at most the reproduction's runs)
LAYOUT_RUNS = 5
#: a perturbed layout's tag
LAYOUT_TAG = re.compile(r"mirror-[xy]|start[+-]|jitter-[1-9]\d*")
#: the file name of a written layout: ``<scenario>.<tag>.toml``
LAYOUT_FILE = re.compile(rf"[\w-]+\.({LAYOUT_TAG.pattern})\.toml")
#: draws per jittered layout before it is given up
TRIES = 20

_VIEWS = ("paper profile", "hybridnav profile")


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def _mirror(data: dict[str, Any], axis: int) -> dict[str, Any] | None:
    """``data`` reflected about the workspace's centre line across ``axis`` (0: x' = xmin +
    xmax - x; 1: y' likewise); None where it cannot be (a grid map file, an unknown state)."""
    if data.get("grid", {}).get("map") is not None:
        return None
    ws = data["workspace"]
    c = ws["xmin"] + ws["xmax"] if axis == 0 else ws["ymin"] + ws["ymax"]

    def flip(p):
        q = list(p)
        q[axis] = c - q[axis]
        return q

    def heading(a):                       # the direction (cos a, sin a) reflected
        return _wrap(math.pi - a) if axis == 0 else _wrap(-a)

    for o in data["obstacles"]:
        if o["type"] == "rectangle":
            lo, hi = list(o["min"]), list(o["max"])
            lo[axis], hi[axis] = c - o["max"][axis], c - o["min"][axis]
            o["min"], o["max"] = lo, hi
        elif o["type"] == "polygon":
            o["points"] = [flip(p) for p in reversed(o["points"])]   # keep the orientation
        else:
            for key in ("center", "a", "b"):
                if key in o:
                    o[key] = flip(o[key])
            if "heading" in o:
                o["heading"] = heading(o["heading"])
    from hybridnav.models import MODELS

    for r in data["robots"]:
        for key in ("start", "goal"):
            if key in r:
                r[key] = flip(r[key])
        model = MODELS.get(r.get("model"))
        initial = r.setdefault("initial", {})
        for key in getattr(model, "plant_state_names", ())[2:]:
            if key.startswith("theta"):          # a heading left out is 0: mirrored, it is not
                initial.setdefault(key, 0.0)
        for key, value in initial.items():
            if key.startswith("theta"):
                r["initial"][key] = heading(value)
            elif key == "xi":                 # an angle relative to the heading: mirrored
                r["initial"][key] = -value
            else:
                return None
    return data


def _sideways(robot: dict[str, Any], distance: float) -> list[float]:
    """The robot's start moved ``distance`` to the left of its start-goal line."""
    sx, sy = robot["start"]
    gx, gy = robot.get("goal", (sx + 1.0, sy))
    d = math.hypot(gx - sx, gy - sy) or 1.0
    return [sx - distance * (gy - sy) / d, sy + distance * (gx - sx) / d]


def _scale(data: dict[str, Any]) -> float:
    """The first robot's start-goal distance (the workspace's width without a goal)."""
    r = data["robots"][0]
    if "goal" in r:
        return math.dist(r["start"], r["goal"])
    return data["workspace"]["xmax"] - data["workspace"]["xmin"]


def _shifted(data: dict[str, Any], sign: float, jitter: float) -> dict[str, Any]:
    for r in data["robots"]:
        d = math.dist(r["start"], r["goal"]) if "goal" in r else _scale(data)
        r["start"] = _sideways(r, sign * jitter * d)
    return data


def _bounds(o: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box ``(lo, hi)`` of an obstacle of the scenario schema (a moving circle's
    at its start)."""
    if "center" in o:
        c = np.asarray(o["center"], dtype=float)
        return c - o["radius"], c + o["radius"]
    if "min" in o:
        return np.asarray(o["min"], dtype=float), np.asarray(o["max"], dtype=float)
    P = np.asarray(o["points"] if "points" in o else [o["a"], o["b"]], dtype=float)
    return P.min(axis=0), P.max(axis=0)


def _free_groups(data: dict[str, Any]) -> list[list[int]]:
    """The obstacles that may move, in rigid groups: obstacles whose bounding boxes touch move
    together (the pieces of one wall, a wall and what leans on it), and a group touching the
    workspace's edge does not move (an outer wall, a room's wall attached to it: moving it would
    open a gap the layout does not have or push it out of the workspace)."""
    ws = data["workspace"]
    lo_ws = np.array([ws["xmin"], ws["ymin"]])
    hi_ws = np.array([ws["xmax"], ws["ymax"]])
    tol = 1e-9 * float(np.max(hi_ws - lo_ws))
    boxes = [_bounds(o) for o in data["obstacles"]]
    parent = list(range(len(boxes)))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, (lo_i, hi_i) in enumerate(boxes):
        for j in range(i):
            lo_j, hi_j = boxes[j]
            if (lo_i <= hi_j + tol).all() and (lo_j <= hi_i + tol).all():
                parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(boxes)):
        groups.setdefault(root(i), []).append(i)
    return [g for g in groups.values()
            if not any((boxes[i][0] <= lo_ws + tol).any() or (boxes[i][1] >= hi_ws - tol).any()
                       for i in g)]


def _jittered(data: dict[str, Any], rng: np.random.Generator, jitter: float
              ) -> dict[str, Any] | None:
    """Every free-standing group of obstacles (:func:`_free_groups`) moved rigidly by a random
    offset of length up to ``jitter`` times the start-goal distance; None where the scenario
    cannot be jittered (a grid map file, no free obstacle) or an obstacle would leave the
    workspace (the caller draws again)."""
    if data.get("grid", {}).get("map") is not None:
        return None
    groups = _free_groups(data)
    if not groups:
        return None
    radius = jitter * _scale(data)
    ws = data["workspace"]
    lo_ws = np.array([ws["xmin"], ws["ymin"]])
    hi_ws = np.array([ws["xmax"], ws["ymax"]])
    for group in groups:
        a = rng.uniform(0.0, 2.0 * math.pi)
        dx, dy = radius * math.sqrt(rng.uniform()) * np.array([math.cos(a), math.sin(a)])
        for i in group:
            o = data["obstacles"][i]
            for key in ("center", "a", "b", "min", "max"):
                if key in o:
                    o[key] = [o[key][0] + dx, o[key][1] + dy]
            if "points" in o:
                o["points"] = [[x + dx, y + dy] for x, y in o["points"]]
            lo, hi = _bounds(o)
            if (lo < lo_ws).any() or (hi > hi_ws).any():
                return None                   # out of the workspace: not this layout
    return data


def _usable(scenario: Scenario) -> bool:
    """Every robot's start and goal are clear and inside; A* finds every robot a path where the
    grid search can plan for the robots."""
    from hybridnav import planners

    world = scenario.world
    for r in scenario.robots:
        pts = [r.start] + ([r.goal] if r.goal is not None else [])
        P = np.asarray(pts, dtype=float)
        if (world.clearance(P, radius=r.radius) <= 0).any() or \
                not world.inside_workspace(P, r.radius).all():
            return False
    astar = planners.get("astar", margin=0.0)
    try:
        astar.check_scenario(scenario)
    except HybridnavError:
        return True                          # not a disk the grid search plans for
    return all(plan.found for plan in astar.plans(scenario)
               if plan is not None) if any(r.goal is not None for r in scenario.robots) else True


def perturbed_layouts(scenario: Scenario, count: int = LAYOUTS, *, seed: int = 0,
                      jitter: float = JITTER) -> list[tuple[str, Scenario]]:
    """The first ``count`` usable perturbed layouts of ``scenario`` (see the module's text).

    Parameters
    ----------
    scenario : Scenario
    count : int
        How many (fewer where the scenario allows fewer: a grid map file only moves starts).
    seed : int
        Seeds the jitters (with the scenario's name: each row draws its own).
    jitter : float
        Start and obstacle moves as a fraction of the start-goal distance.

    Returns
    -------
    list of (tag, Scenario)
        Each layout is named ``<scenario>.<tag>`` (``mirror-x``, ``start+``, ``jitter-3``...).
    """
    from hybridnav.world import scenario_from_dict, scenario_to_dict

    if not (math.isfinite(jitter) and 0 < jitter < 1):
        raise HybridnavError(f"layouts: jitter: expected a fraction in (0, 1), got {jitter!r}")
    base = scenario_to_dict(scenario)
    out: list[tuple[str, Scenario]] = []

    def add(tag: str, data: dict[str, Any] | None) -> bool:
        if data is None or len(out) >= count:
            return False
        data["name"] = f"{scenario.name}.{tag}"
        data["description"] = f"{scenario.name}, perturbed: {tag} (layout sensitivity)"
        try:
            s = scenario_from_dict(data)
        except HybridnavError:
            return False
        if not _usable(s):
            return False
        out.append((tag, s))
        return True

    add("mirror-x", _mirror(copy.deepcopy(base), 0))
    add("mirror-y", _mirror(copy.deepcopy(base), 1))
    add("start+", _shifted(copy.deepcopy(base), 1.0, jitter))
    add("start-", _shifted(copy.deepcopy(base), -1.0, jitter))
    rng = np.random.default_rng([seed, zlib.crc32(scenario.name.encode())])
    k = 0
    while len(out) < count and base.get("grid", {}).get("map") is None and \
            _free_groups(base):
        k += 1
        for _ in range(TRIES):
            if add(f"jitter-{k}", _jittered(copy.deepcopy(base), rng, jitter)):
                break
        else:
            break                             # this world leaves no room: fewer layouts
    return out


def failing_rows(protocol: Protocol, summary: pd.DataFrame) -> list[tuple[int, str]]:
    """``(claim index, row label)`` of every row where a claim does not hold in our runs, in
    either profile, or cannot be tested because both planners gave one result in every run
    (deterministic: one comparison, which the perturbed layouts turn into several)."""
    from hybridnav.reproduce.report import row_verdict

    out = []
    for i, claim in enumerate(protocol.claims):
        for row in protocol.rows:
            if claim.rows and row.label not in claim.rows:
                continue
            if any(row_verdict(protocol, claim, summary, view, row)[0] is False
                   or (row_verdict(protocol, claim, summary, view, row)[0] is None
                       and row_verdict(protocol, claim, summary, view, row, single=True)[0]
                       is not None)
                   for view in _VIEWS):
                out.append((i, row.label))
    return out


def layout_sensitivity(protocol: Protocol, summary: pd.DataFrame, *, count: int = LAYOUTS,
                       runs: int = LAYOUT_RUNS, seed: int = 0, workers: int = 1,
                       dask: str | Any | None = None, folder: str | Path | None = None,
                       progress: Callable[[int, int], None] | None = None,
                       jitter: float = JITTER) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Rerun every claim that does not hold on perturbed layouts of its rows.

    Parameters
    ----------
    protocol : Protocol
    summary : DataFrame
        The reproduction's own summary (which claims fail where).
    count : int
        Perturbed layouts per row.
    runs : int
        Runs per planner and layout.
    seed, workers, dask, progress
        As for :func:`hybridnav.experiments.compare`.
    folder : str or Path, optional
        Where the layouts are written as scenario files (``layouts/<scenario>.<tag>.toml``;
        default a temporary folder).
    jitter : float
        See :func:`perturbed_layouts`.

    Returns
    -------
    verdicts : DataFrame
        One row per claim, row, layout and profile: ``claim`` (its index), ``text``, ``row``,
        ``scenario``, ``layout``, ``view``, ``verdict`` (True / False / None), ``detail``.
    summary : DataFrame
        ``summarize_runs`` of the layout runs (empty when no claim fails).
    """
    import dataclasses
    import tempfile

    import pandas as pd

    from hybridnav.experiments.compare import PlannerSpec, compare
    from hybridnav.reproduce.report import row_verdict
    from hybridnav.reproduce.variants import label_for, levels, variants
    from hybridnav.world import load_scenario, save_scenario

    failing = failing_rows(protocol, summary)
    columns = ["claim", "text", "row", "scenario", "layout", "view", "verdict", "detail"]
    if not failing or count < 1:
        return pd.DataFrame(columns=columns), pd.DataFrame()
    rows = {row.label: row for row in protocol.rows}
    wanted = {swept for i, _ in failing for name in (protocol.claims[i].a,
                                                       protocol.claims[i].b) if name
              for profile in ("paper", "hybridnav")
              for _, swept in levels(protocol, name, label_for(protocol, name, profile))}
    specs = [PlannerSpec(label, name, params) for label, name, params in variants(protocol)
             if label in wanted]
    tmp = None
    if folder is None:
        tmp = tempfile.TemporaryDirectory(prefix="hybridnav-layouts-")
        folder = tmp.name
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.toml"):       # an earlier run's layouts (only names we write)
        if LAYOUT_FILE.fullmatch(old.name) and old.name.split(".")[0] in {
                row.scenario for row in protocol.rows}:
            old.unlink()
    try:
        layouts: dict[str, list[tuple[str, str]]] = {}     # row label -> [(tag, file)]
        for label in dict.fromkeys(lb for _, lb in failing):
            scenario = load_scenario(rows[label].scenario)
            layouts[label] = []
            for tag, layout in perturbed_layouts(scenario, count, seed=seed, jitter=jitter):
                path = folder / f"{layout.name}.toml"
                save_scenario(layout, path)
                layouts[label].append((tag, str(path)))
        files = [f for items in layouts.values() for _, f in items]
        if not files:
            return pd.DataFrame(columns=columns), pd.DataFrame()
        _, lsummary = compare(specs, files, runs, seed=seed, workers=workers, dask=dask,
                              progress=progress)
    finally:
        if tmp is not None:
            tmp.cleanup()
    out = []
    for i, label in failing:
        claim = protocol.claims[i]
        for tag, _ in layouts[label]:
            moved = dataclasses.replace(rows[label], scenario=f"{rows[label].scenario}.{tag}")
            for view in _VIEWS:
                verdict, detail = row_verdict(protocol, claim, lsummary, view, moved,
                                              single=True)
                out.append({"claim": i, "text": claim.text, "row": label,
                            "scenario": rows[label].scenario, "layout": tag, "view": view,
                            "verdict": verdict, "detail": detail})
    return pd.DataFrame(out, columns=columns), lsummary
