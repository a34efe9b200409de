"""Scenario TOML loading and validation, the built-in scenarios, and drawing them."""

from __future__ import annotations

import copy
import math
import tomllib

import matplotlib.image as mpimg
import numpy as np
import pytest
from scipy import ndimage

from hybridnav.errors import HybridnavError
from hybridnav.plotting import draw_scenario, save_scenario_png
from hybridnav.world import (
    MODEL_NAMES,
    Circle,
    MovingCircle,
    Polygon,
    Rectangle,
    Segment,
    list_scenarios,
    load_scenario,
    save_scenario,
    scenario_from_dict,
    scenario_to_dict,
    scenario_to_toml,
    toml_dumps,
)
from hybridnav.world.grid import build_grid, rasterize

BUILTIN = [name for name, _ in list_scenarios()]

BASE = {
    "name": "test",
    "description": "a test scenario",
    "units": "cm",
    "dt": 0.1,
    "max_time": 100.0,
    "workspace": {"xmin": 0.0, "xmax": 50.0, "ymin": 0.0, "ymax": 50.0},
    "obstacles": [
        {"type": "circle", "center": [25.0, 25.0], "radius": 4.0},
        {"type": "segment", "a": [10.0, 30.0], "b": [20.0, 30.0]},
        {"type": "rectangle", "min": [30.0, 5.0], "max": [40.0, 10.0]},
        {"type": "polygon", "points": [[5.0, 10.0], [10.0, 10.0], [8.0, 15.0]]},
        {"type": "moving_circle", "center": [40.0, 40.0], "radius": 2.0, "velocity": 1.0, "heading": 0.0},
    ],
    "robots": [
        {"name": "R1", "model": "point_mass", "start": [5.0, 45.0], "goal": [45.0, 5.0]},
        {"name": "R2", "model": "unicycle", "start": [5.0, 25.0], "goal": [45.0, 25.0],
         "initial": {"theta": 0.1}, "params": {"k_rho": 2}},
        {"name": "R3", "model": "tractor_trailer", "start": [45.0, 45.0], "goal_follow": "R1"},
    ],
    "grid": {"resolution": 1.0},
}


def write(tmp_path, data, name="scen.toml"):
    p = tmp_path / name
    p.write_text(toml_dumps(data), encoding="utf-8")
    return p


# ---------------------------------------------------------------------------------------------
# good input
# ---------------------------------------------------------------------------------------------


def test_base_loads_with_defaults(tmp_path):
    s = load_scenario(write(tmp_path, BASE))
    assert s.name == "test" and s.units == "cm" and s.dt == 0.1 and s.max_time == 100.0
    assert s.source.endswith("scen.toml")
    assert [type(o) for o in s.world.obstacles] == [Circle, Segment, Rectangle, Polygon, MovingCircle]
    r1, r2, r3 = s.robots
    assert r1.goal == (45.0, 5.0) and r1.goal_follow is None
    assert r1.goal_radius == 0.5 and r1.radius == 0.5 and r1.initial == {} and r1.params == {}
    assert r2.initial == {"theta": 0.1} and r2.params == {"k_rho": 2.0} and isinstance(r2.params["k_rho"], float)
    assert r3.goal is None and r3.goal_follow == "R1" and r3.radius == pytest.approx(0.9433981132056605)
    assert s.robot("R2") is r2
    assert s.grid.resolution == 1.0 and s.grid.map is None
    assert s.max_steps == 1000
    with pytest.raises(HybridnavError, match="R9"):
        s.robot("R9")


def test_minimal_defaults():
    d = {"name": "m", "dt": 1, "max_time": 10, "workspace": {"xmin": 0, "xmax": 1, "ymin": 0, "ymax": 1},
         "robots": [{"name": "a", "model": "point_mass", "start": [0.5, 0.5], "goal": [0.9, 0.9],
                     "radius": 0.05}]}
    s = scenario_from_dict(d)
    assert s.description == "" and s.units == "m" and s.world.obstacles == () and s.grid is None
    assert s.source is None


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_roundtrip(name, tmp_path):
    s = load_scenario(name)
    assert s.name == name
    assert scenario_from_dict(scenario_to_dict(s), s.source) == s
    assert scenario_from_dict(tomllib.loads(scenario_to_toml(s)), s.source) == s
    if s.grid is None or s.grid.map is None:  # a relative map path would need its directory
        p = save_scenario(s, tmp_path / f"{name}.toml")
        assert load_scenario(p) == s
        assert [f.name for f in tmp_path.iterdir()] == [f"{name}.toml"]  # no temp files left


def test_list_scenarios():
    items = list_scenarios()
    names = [n for n, _ in items]
    assert names == sorted(names)
    expected = {"fastep-s1", "fastep-s2", "fastep-s3", "aco-three-robots", "aco-local-minimum",
                "tractor-trailer-1", "tractor-trailer-3", "effc-train-1", "effc-train-2", "effc-env-a",
                "effc-env-b", "rfd-pso-700", "rfd-pso-20m", "pso-ba-dynamic", "arena",
                "aco-scenario-4", "aco-case-study-2", "tractor-trailer-2", "fastep-case-study-2",
                "aco-s2", "aco-case-study-1", "turtlebot-office"}
    assert expected <= set(names)
    for n, desc in items:
        assert desc, n
        if n != "arena":   # each says whether it reconstructs a paper's figure or is ours
            assert "reconstruction" in desc or "(ours" in desc, n


def test_builtin_scenarios_match_the_papers():
    s = load_scenario("fastep-s1")
    assert (s.robots[0].start, s.robots[0].goal, s.units, s.dt, s.max_time) == ((5, 45), (45, 5), "cm", 0.1, 3000)
    assert s.world.workspace == (0, 50, 0, 50)
    assert {o.radius for o in s.world.obstacles} >= {2.0, 5.0}
    assert load_scenario("fastep-s2").robots[0].start == (5, 5)
    s3 = load_scenario("fastep-s3")
    assert s3.robots[0].start == (5, 25) and any(isinstance(o, Segment) for o in s3.world.obstacles)
    aco = load_scenario("aco-three-robots")
    assert [(r.start, r.goal) for r in aco.robots] == [((5, 45), (45, 5)), ((5, 25), (45, 25)), ((5, 5), (45, 45))]
    tt3 = load_scenario("tractor-trailer-3")
    assert [(r.start, r.goal) for r in tt3.robots] == [(r.start, r.goal) for r in aco.robots]
    assert all(r.model == "tractor_trailer" for r in tt3.robots)
    assert "theta0" in load_scenario("tractor-trailer-1").robots[0].initial
    for k in (1, 2):
        e = load_scenario(f"effc-train-{k}")
        r = e.robots[0]
        assert r.model == "unicycle" and r.start == (0, 0) and r.goal == (3, 3)
        assert r.initial["theta"] == pytest.approx(math.pi / 4) and len(e.world.obstacles) == 1
    assert load_scenario("effc-train-1").world.obstacles != load_scenario("effc-train-2").world.obstacles
    assert 8 <= len(load_scenario("effc-env-b").world.obstacles) <= 10
    rfd = load_scenario("rfd-pso-700")
    assert rfd.world.workspace == (0, 700, 0, 700) and rfd.grid.resolution == 10.0
    assert (rfd.robots[0].start, rfd.robots[0].goal) == ((80, 450), (600, 100))
    pso = load_scenario("pso-ba-dynamic")
    assert pso.robot("robot1").start == (120, 120) and pso.robot("robot1").goal == (20, 60)
    assert pso.robot("robot2").start == (160, 5) and pso.robot("robot2").goal_follow == "robot1"
    assert len(pso.world.static().obstacles) == 6 and 3 <= len(pso.world.moving().obstacles) <= 4
    arena = load_scenario("arena")
    assert arena.grid.map == "movingai:arena" and arena.world.obstacles == ()


def _free_space(s, r):
    """Free-space grid for robot r: the map dilated, or the world rasterized with the robot radius."""
    if s.grid is not None and s.grid.map is not None:
        return build_grid(s, inflate=r.radius)
    xmin, xmax, ymin, ymax = s.world.workspace
    return rasterize(s.world, min(xmax - xmin, ymax - ymin) / 200, inflate=r.radius, border=True)


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_is_solvable_but_not_trivial(name):
    s = load_scenario(name)
    for r in s.robots:
        g = _free_space(s, r)
        labels, _ = ndimage.label(~g.occ)  # 4-connected free cells: conservative
        ends = [r.start] + ([r.goal] if r.goal is not None else [s.robot(r.goal_follow).start])
        cells = g.to_cell(np.array(ends, float))
        lab = labels[cells[:, 1], cells[:, 0]]
        assert lab[0] > 0 and lab[0] == lab[1], f"{name}: {r.name} cannot reach its goal"
        if r.goal is None:
            continue
        a, b = np.array([r.start], float), np.array([r.goal], float)
        if s.grid is not None and s.grid.map is not None:
            t = np.linspace(0, 1, 2000)[:, None]
            blocked = not g.is_free(a * (1 - t) + b * t).all()
        else:
            blocked = bool(s.world.segment_collides(a, b, radius=r.radius)[0])
        if name == "fastep-s1":
            # FAStep-Kinematic's scenario 1: its robot drives there on the kinematics alone
            assert not blocked, f"{name}: {r.name}'s straight start-goal line is blocked"
        else:
            assert blocked, f"{name}: {r.name}'s straight start-goal line is free"


def test_local_minimum_is_a_trap():
    """The attractive + repulsive potential gradient vanishes somewhere inside the cup."""
    s = load_scenario("aco-local-minimum")
    goal = np.array(s.robots[0].goal)
    xs, ys = np.meshgrid(np.linspace(15, 35, 201), np.linspace(15, 35, 201))
    P = np.column_stack([xs.ravel(), ys.ravel()])
    c, q, _ = s.world.nearest(P)
    ok = c > 0.5
    # Khatib-style field: U = 0.5 k |p-g|^2 + 0.5 eta (1/d - 1/d0)^2 within d0
    k, eta, d0 = 1.0, 400.0, 5.0
    grad_att = k * (P - goal)
    d = np.maximum(c, 1e-9)
    unit = (P - q) / d[:, None]
    mag = np.where(d < d0, eta * (1 / d - 1 / d0) / d**2, 0.0)
    grad = grad_att - mag[:, None] * unit
    norm = np.linalg.norm(grad, axis=1)
    norm[~ok] = np.inf
    i = np.argmin(norm)
    assert norm[i] < 0.05 * np.linalg.norm(grad_att[i])  # near-stationary point ...
    assert P[i, 0] < goal[0] - 10  # ... far from the goal, in front of the cup


# ---------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------


def _set(path, value):
    def f(d):
        *head, last = path
        for k in head:
            d = d[k]
        d[last] = value
    return f


def _del(path):
    def f(d):
        *head, last = path
        for k in head:
            d = d[k]
        del d[last]
    return f


BAD = [
    # unknown keys at every level
    ("unknown-top", _set(["speed"], 1.0), "speed"),
    ("unknown-workspace", _set(["workspace", "zmin"], 0.0), "workspace.zmin"),
    ("unknown-circle-key", _set(["obstacles", 0, "a"], [1.0, 1.0]), "obstacles[0].a"),
    ("unknown-segment-key", _set(["obstacles", 1, "radius"], 1.0), "obstacles[1].radius"),
    ("unknown-robot", _set(["robots", 1, "speed"], 1.0), "robots[1].speed"),
    ("unknown-grid", _set(["grid", "cellsize"], 1.0), "grid.cellsize"),
    # missing keys
    ("missing-name", _del(["name"]), "name"),
    ("missing-dt", _del(["dt"]), "dt"),
    ("missing-workspace", _del(["workspace"]), "workspace"),
    ("missing-xmax", _del(["workspace", "xmax"]), "workspace.xmax"),
    ("missing-robots", _del(["robots"]), "robots"),
    ("missing-start", _del(["robots", 1, "start"]), "robots[1].start"),
    ("missing-model", _del(["robots", 0, "model"]), "robots[0].model"),
    ("missing-radius", _del(["obstacles", 0, "radius"]), "obstacles[0].radius"),
    ("missing-type", _del(["obstacles", 2, "type"]), "obstacles[2].type"),
    ("missing-heading", _del(["obstacles", 4, "heading"]), "obstacles[4].heading"),
    # wrong types
    ("dt-string", _set(["dt"], "0.1"), "dt"),
    ("dt-bool", _set(["dt"], True), "dt"),
    ("start-bool", _set(["robots", 0, "start"], [1.0, True]), "robots[0].start[1]"),
    ("start-3d", _set(["robots", 0, "start"], [1.0, 2.0, 3.0]), "robots[0].start"),
    ("workspace-number", _set(["workspace"], 3.0), "workspace"),
    ("obstacles-table", _set(["obstacles"], {"type": "circle"}), "obstacles"),
    ("name-number", _set(["name"], 3), "name"),
    ("model-number", _set(["robots", 0, "model"], 1), "robots[0].model"),
    ("radius-string", _set(["obstacles", 0, "radius"], "4"), "obstacles[0].radius"),
    # NaN / inf
    ("dt-nan", _set(["dt"], float("nan")), "dt"),
    ("center-inf", _set(["obstacles", 0, "center"], [float("inf"), 1.0]), "obstacles[0].center[0]"),
    ("goal-nan", _set(["robots", 0, "goal"], [float("nan"), 1.0]), "robots[0].goal[0]"),
    # values
    ("empty-workspace-x", _set(["workspace", "xmin"], 50.0), "workspace.xmax"),
    ("empty-workspace-y", _set(["workspace", "ymax"], -1.0), "workspace.ymax"),
    ("dt-zero", _set(["dt"], 0.0), "dt"),
    ("max-time-negative", _set(["max_time"], -5.0), "max_time"),
    ("obstacle-radius-negative", _set(["obstacles", 0, "radius"], -1.0), "obstacles[0].radius"),
    ("moving-velocity-negative", _set(["obstacles", 4, "velocity"], -1.0), "obstacles[4].velocity"),
    ("robot-radius-negative", _set(["robots", 0, "radius"], -0.1), "robots[0].radius"),
    ("zero-length-segment", _set(["obstacles", 1, "b"], [10.0, 30.0]), "obstacles[1].b"),
    ("rectangle-min-max", _set(["obstacles", 2, "max"], [40.0, 5.0]), "obstacles[2].max"),
    ("polygon-two-points", _set(["obstacles", 3, "points"], [[5.0, 10.0], [10.0, 10.0]]), "obstacles[3].points"),
    ("polygon-nonconvex", _set(["obstacles", 3, "points"],
                               [[5.0, 10.0], [10.0, 10.0], [7.0, 11.0], [10.0, 15.0], [5.0, 15.0]]),
     "obstacles[3].points"),
    ("unknown-obstacle-type", _set(["obstacles", 0, "type"], "ellipse"), "obstacles[0].type"),
    ("start-outside", _set(["robots", 0, "start"], [-1.0, 45.0]), "robots[0].start"),
    ("start-footprint-outside", _set(["robots", 0, "start"], [0.2, 45.0]), "robots[0].start"),
    ("goal-outside", _set(["robots", 0, "goal"], [45.0, 51.0]), "robots[0].goal"),
    ("start-in-obstacle", _set(["robots", 0, "start"], [25.0, 25.0]), "robots[0].start"),
    ("start-footprint-touches-circle", _set(["robots", 0, "start"], [29.3, 25.0]), "robots[0].start"),
    ("goal-in-rectangle", _set(["robots", 0, "goal"], [35.0, 7.0]), "robots[0].goal"),
    ("goal-on-wall", _set(["robots", 1, "goal"], [15.0, 30.2]), "robots[1].goal"),
    ("start-in-moving-circle", _set(["robots", 0, "start"], [40.0, 41.0]), "robots[0].start"),
    ("start-overlaps-robot", _set(["robots", 1, "start"], [5.5, 45.0]), "robots[1].start"),
    ("unknown-model", _set(["robots", 0, "model"], "car"), "robots[0].model"),
    ("duplicate-name", _set(["robots", 1, "name"], "R1"), "robots[1].name"),
    ("goal-and-follow", _set(["robots", 0, "goal_follow"], "R2"), "robots[0].goal"),
    ("neither-goal", _del(["robots", 0, "goal"]), "robots[0].goal"),
    ("follow-unknown", _set(["robots", 2, "goal_follow"], "R9"), "robots[2].goal_follow"),
    ("follow-self", _set(["robots", 2, "goal_follow"], "R3"), "robots[2].goal_follow"),
    ("goal-radius-zero", _set(["robots", 0, "goal_radius"], 0.0), "robots[0].goal_radius"),
    ("no-robots", _set(["robots"], []), "robots"),
    ("initial-string", _set(["robots", 1, "initial"], {"theta": "north"}), "robots[1].initial.theta"),
    ("initial-bool", _set(["robots", 1, "initial"], {"theta": False}), "robots[1].initial.theta"),
    ("params-not-table", _set(["robots", 1, "params"], [1.0]), "robots[1].params"),
    ("grid-resolution-zero", _set(["grid", "resolution"], 0.0), "grid.resolution"),
    ("grid-map-missing", _set(["grid", "map"], "nowhere.map"), "grid.map"),
    ("grid-map-unknown-builtin", _set(["grid", "map"], "movingai:nowhere"), "grid.map"),
]


@pytest.mark.parametrize("case, mutate, key", BAD, ids=[c[0] for c in BAD])
def test_bad_input_names_file_and_key(tmp_path, case, mutate, key):
    data = copy.deepcopy(BASE)
    mutate(data)
    p = write(tmp_path, data, name=f"{case}.toml")
    with pytest.raises(HybridnavError) as e:
        load_scenario(p)
    msg = str(e.value)
    assert f"{case}.toml" in msg, msg
    assert f": {key}:" in msg, msg  # "file: key: what was expected"
    assert "expected" in msg or "missing" in msg, msg


def test_toml_syntax_error_names_file_and_line(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text('name = "x"\ndt = 0.1\nmax_time = = 3\n')
    with pytest.raises(HybridnavError) as e:
        load_scenario(p)
    assert "broken.toml" in str(e.value) and "line 3" in str(e.value)


def test_missing_file_and_unknown_builtin(tmp_path):
    with pytest.raises(HybridnavError, match="nothere.toml"):
        load_scenario(tmp_path / "nothere.toml")
    with pytest.raises(HybridnavError, match="fastep-s1"):  # lists the available names
        load_scenario("no-such-scenario")


def test_map_grid_checks_start_cell(tmp_path):
    (tmp_path / "tiny.map").write_text("type octile\nheight 3\nwidth 4\nmap\n....\n.TT.\n....\n")
    d = {"name": "tiny", "dt": 0.1, "max_time": 10.0,
         "workspace": {"xmin": 0.0, "xmax": 4.0, "ymin": 0.0, "ymax": 3.0},
         "robots": [{"name": "r", "model": "point_mass", "start": [0.5, 0.5], "goal": [3.5, 2.5],
                     "radius": 0.3}],
         "grid": {"map": "tiny.map"}}
    s = load_scenario(write(tmp_path, d, "tiny.toml"))
    assert build_grid(s).occ.sum() == 2
    d["robots"][0]["goal"] = [1.5, 1.5]
    with pytest.raises(HybridnavError, match=r"tiny2\.toml: robots\[0\]\.goal"):
        load_scenario(write(tmp_path, d, "tiny2.toml"))


def test_model_names_constant():
    from hybridnav.models import MODELS

    # the schema's names are the registered models that can be a scenario's robot
    assert MODEL_NAMES == tuple(sorted(n for n, c in MODELS.items() if "robot" in c.capabilities))
    assert {"point_mass", "tractor_trailer", "unicycle"} <= set(MODEL_NAMES)
    assert "lbcs" not in MODEL_NAMES


# ---------------------------------------------------------------------------------------------
# drawing
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["pso-ba-dynamic", "arena", "fastep-s3"])
def test_save_scenario_png(tmp_path, name):
    s = load_scenario(name)
    out = save_scenario_png(s, tmp_path / f"{name}.png", t=5.0 if name == "pso-ba-dynamic" else 0.0, dpi=50)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(out)
    assert img.shape[0] > 100 and img.shape[1] > 100
    assert img[..., :3].std() > 0.05  # something was drawn
    assert sorted(f.name for f in tmp_path.iterdir()) == [f"{name}.png"]


def test_draw_scenario_artists():
    s = load_scenario("pso-ba-dynamic")
    ax = draw_scenario(s, t=10.0)
    assert ax.get_xlim()[0] < 0 < 200 < ax.get_xlim()[1]
    # six static + four moving + four dashed t=0 outlines + robots' footprints and goal circles
    assert len(ax.patches) >= 6 + 4 + 4 + 2
    texts = {t.get_text() for t in ax.texts}
    assert {"robot1", "robot2"} <= texts
    assert "t = 10" in ax.get_title()


@pytest.mark.parametrize(
    "robot_patch, key, text",
    [
        ({"params": {"alpah1": 0.1}}, "robots[0].params.alpah1", "unknown parameter 'alpah1'"),
        ({"params": {"alpha1": 0.5, "L": 1.0}}, "robots[0].params.L", "unknown parameter 'L'"),
        ({"params": {"alpha1": -0.0}}, "robots[0].params.alpha1", "expected a number in (0, 1e+06], got -0.0"),
        ({"model": "unicycle", "params": {"k_rho": 0.0}}, "robots[0].params.k_rho",
         "expected a positive number, got 0.0"),
        ({"initial": {"theta": 0.3}}, "robots[0].initial", "initial.theta: unknown state"),
        ({"model": "tractor_trailer", "radius": 1.0}, "robots[0].radius",
         "footprint follows from its params L and b"),
    ],
)
def test_model_params_and_initial_states_are_checked_by_the_model(tmp_path, robot_patch, key, text):
    data = {"name": "m", "dt": 0.1, "max_time": 10.0,
            "workspace": {"xmin": 0.0, "xmax": 50.0, "ymin": 0.0, "ymax": 50.0},
            "robots": [{"name": "R1", "model": "point_mass", "start": [5.0, 5.0],
                        "goal": [45.0, 45.0]}]}
    data["robots"][0].update(robot_patch)
    p = write(tmp_path, data, name="m.toml")
    with pytest.raises(HybridnavError) as e:
        load_scenario(p)
    msg = str(e.value)
    assert "m.toml" in msg and f": {key}:" in msg and text in msg, msg


def test_scenario_model_uses_robot_params_and_dt():
    s = load_scenario("tractor-trailer-1")
    m = s.model(s.robots[0].name)
    assert m.name == "tractor_trailer" and m.dt == s.dt
    assert s.robots[0].radius == pytest.approx(m.radius)   # derived from L and b
