"""The escape-circle safety filter: the safe set is invariant, the command changes only when it
must, the planners and the lockstep runs (NumPy and compiled) apply it the same way, and it
removes the collisions EFFC has on generated and trap worlds."""

from __future__ import annotations

import collections
import math
import os

import numpy as np
import pytest

from hybridnav import fuzzy, planners
from hybridnav.fuzzy.family import SystemFamily
from hybridnav.planners.field.safety import escape_filter, escape_radius
from hybridnav.tuner.evaluate import lockstep_effc, scenario_set
from hybridnav.world import Circle, Segment, World
from hybridnav.world.generator import WorldGenerator

SPEED, DT, TURN, MARGIN, R = 0.1, 0.1, math.pi / 4, 0.02, 0.1
PLANNER = {"speed": SPEED, "max_turn": TURN, "stuck_window": 10.0, "stuck_radius": 2.0,
           "safety_margin": MARGIN}


def _world():
    return World((0.0, 2.0, 0.0, 2.0), (Circle((1.0, 1.0), 0.3), Segment((0.2, 1.6), (1.2, 1.9)),
                                        Circle((1.5, 0.4), 0.15)))


def _clearance(world):
    return lambda Q, rows: np.minimum(world.clearance(Q), world.border_clearance(Q))


def _safe(world, X):
    """Whether each state has a free escape circle (the filter's invariant)."""
    rho = escape_radius(SPEED, DT, TURN)
    n = np.stack([-np.sin(X[:, 2]), np.cos(X[:, 2])], axis=1)
    c = _clearance(world)
    here = c(X[:, :2], None)
    circle = np.maximum(c(X[:, :2] + rho * n, None), c(X[:, :2] - rho * n, None)) - rho
    return (here >= R + MARGIN - 1e-9) & (circle >= R + MARGIN - 1e-9)


def _arc(X, V):
    """The exact arc of the heading controller's cycle towards V (turn clipped to TURN)."""
    want = np.remainder(np.arctan2(V[:, 1], V[:, 0]) - X[:, 2] + np.pi, 2 * np.pi) - np.pi
    d = np.clip(want, -TURN, TURN)
    th1 = X[:, 2] + d
    step = SPEED * DT
    small = np.abs(d) < 1e-12
    R_ = step / np.where(small, 1.0, d)
    dx = np.where(small, step * np.cos(X[:, 2]), R_ * (np.sin(th1) - np.sin(X[:, 2])))
    dy = np.where(small, step * np.sin(X[:, 2]), R_ * (np.cos(X[:, 2]) - np.cos(th1)))
    return np.column_stack([X[:, 0] + dx, X[:, 1] + dy, th1])


def test_the_safe_set_is_invariant_under_the_filter():
    world = _world()
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(0, 2, 20000), rng.uniform(0, 2, 20000),
                         rng.uniform(-np.pi, np.pi, 20000)])
    X = X[_safe(world, X)]
    assert len(X) > 5000
    V = rng.normal(size=(len(X), 2))                   # any command, even straight at a wall
    for _ in range(30):                                # thirty cycles of adversarial commands
        Vf, changed = escape_filter(X, V, speed=SPEED, dt=DT, max_turn=TURN, margin=MARGIN,
                                    radius=np.full(len(X), R), clearance=_clearance(world))
        X = _arc(X, Vf)
        assert _safe(world, X).all()
        V = -V + rng.normal(size=V.shape)
    assert changed.any()


def test_it_changes_nothing_far_from_obstacles_or_when_off():
    world = _world()
    X = np.array([[0.4, 0.4, 0.3], [1.0, 1.43, -np.pi / 2]])  # far away; 3 cm from the circle
    V = np.array([[1.0, 0.0], [0.0, -1.0]]) * SPEED        # the second heads into the circle
    Vf, changed = escape_filter(X, V, speed=SPEED, dt=DT, max_turn=TURN, margin=MARGIN,
                                radius=np.full(2, R), clearance=_clearance(world))
    assert changed.tolist() == [False, True] and np.array_equal(Vf[0], V[0])
    assert np.hypot(*Vf[1]) == pytest.approx(SPEED)
    off, none = escape_filter(X, V, speed=SPEED, dt=DT, max_turn=TURN, margin=0.0,
                              radius=np.full(2, R), clearance=_clearance(world))
    assert not none.any() and np.array_equal(off, V)


def _worlds():
    return (WorldGenerator().generate(12, 987654)
            + WorldGenerator(cups=(1, 1), circles=(0, 3), name="cup").generate(6, 5)
            + WorldGenerator(gaps=(1, 1), corridors=(0, 1), circles=(0, 3),
                             name="gc").generate(6, 5))


@pytest.mark.parametrize("native", ["1", "0"])
def test_no_collision_on_worlds_where_effc_collides_and_the_margin_is_kept(native, monkeypatch):
    monkeypatch.setenv("HYBRIDNAV_NATIVE", native)
    st = scenario_set(_worlds())
    fis = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(fis)
    plain = lockstep_effc(st, fam, fam.tables_of([fis]), 1, {**PLANNER, "safety_margin": 0.0})
    safe = lockstep_effc(st, fam, fam.tables_of([fis]), 1, PLANNER)
    assert collections.Counter(plain.outcome.ravel())["collided"] >= 3
    assert not np.isin(safe.outcome, ("collided", "out_of_bounds")).any()
    assert safe.min_clearance.min() >= MARGIN - 1e-6
    assert (safe.outcome == "reached").sum() >= (plain.outcome == "reached").sum()


def test_compiled_and_numpy_cycles_and_the_planner_agree():
    worlds = _worlds()
    st = scenario_set(worlds)
    fis = fuzzy.builtin("effc-tuned")
    fam = SystemFamily(fis)
    args = (st, fam, fam.tables_of([fis]), 1, PLANNER)
    got = lockstep_effc(*args)
    os.environ["HYBRIDNAV_NATIVE"] = "0"
    try:
        want = lockstep_effc(*args)
    finally:
        del os.environ["HYBRIDNAV_NATIVE"]
    assert (got.outcome == want.outcome).all()
    np.testing.assert_allclose(got.path_length, want.path_length, rtol=1e-9)
    for i in (0, 13, 19):                              # run by run, the planner does the same
        r = planners.get("effc", fis=fis, safety_margin=MARGIN).run(worlds[i]).robots[0]
        assert r.outcome == got.outcome[i, 0]
        assert r.path_length == pytest.approx(got.path_length[i, 0], rel=1e-9)


def test_apf_and_the_planners_take_the_margin_and_scale_it():
    from hybridnav.world import load_scenario

    res = planners.get("apf", safety_margin=MARGIN).run(load_scenario("effc-env-a"))
    assert res.params["safety_margin"] == MARGIN and res.robots[0].min_clearance >= MARGIN - 1e-6
    cm = planners.get("effc", safety_margin=0.02).run(load_scenario("fastep-s1"))
    assert cm.params["safety_margin"] == 0.02             # set by the user: not scaled
    assert planners.get("effc").run(load_scenario("fastep-s1")).params["safety_margin"] == 0.0


def test_the_exported_c_filter_is_the_python_filter(tmp_path):
    """The deployment's C filter, compiled and called with a clearance callback, makes the same
    decisions and commands as escape_filter on random states near obstacles."""
    import ctypes
    import shutil
    import subprocess

    from hybridnav.planners.field.deploy import write_deployment

    if shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    settings = {"speed": SPEED, "max_turn": TURN, "stuck_window": 10.0, "stuck_radius": 2.0,
                "safety_margin": MARGIN}
    files = write_deployment(tmp_path, "effc", "effc", settings, dt=DT, radius=R)
    assert files == ["deployment.json", "effc_safety.h", "effc_safety.c"]
    so = tmp_path / "libsafety.so"
    subprocess.run(["gcc", "-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-Wall",
                    "-Werror", "-o", str(so), str(tmp_path / "effc_safety.c"), "-lm"],
                   check=True)
    lib = ctypes.CDLL(str(so))
    CB = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_double, ctypes.c_double, ctypes.c_void_p)
    world = _world()
    clear = _clearance(world)
    cb = CB(lambda qx, qy, ctx: float(clear(np.array([[qx, qy]]), None)[0]))
    fn = lib.effc_safety_filter
    fn.argtypes = [ctypes.c_double] * 3 + [ctypes.POINTER(ctypes.c_double)] * 2 + [CB,
                                                                                  ctypes.c_void_p]
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(0, 2, 400), rng.uniform(0, 2, 400),
                         rng.uniform(-np.pi, np.pi, 400)])
    V = rng.normal(size=(400, 2))
    # states with no safe candidate (inside or against an obstacle: the most-room rule) and
    # states that are not finite (every candidate measured)
    X[-40:-8, :2] = np.array([1.0, 1.0]) + rng.normal(0.0, 0.05, (32, 2))   # in the big circle
    X[-8:] = [[np.nan, 1, 0], [1, np.inf, 0], [1, 1, np.inf], [1, 1, np.nan],
              [-np.inf, 1, 0.3], [1, 1, -np.inf], [np.nan, np.nan, np.nan], [1, 1, 1e300]]
    with np.errstate(invalid="ignore"):
        want, changed = escape_filter(X, V, speed=SPEED, dt=DT, max_turn=TURN, margin=MARGIN,
                                      radius=np.full(400, R), clearance=clear)
    assert changed.sum() > 50
    for i in range(400):
        vx, vy = ctypes.c_double(V[i, 0]), ctypes.c_double(V[i, 1])
        got = fn(X[i, 0], X[i, 1], X[i, 2], ctypes.byref(vx), ctypes.byref(vy), cb, None)
        assert bool(got) == changed[i]
        np.testing.assert_allclose([vx.value, vy.value], want[i], rtol=0, atol=1e-12)
    import json

    info = json.loads((tmp_path / "deployment.json").read_text())
    assert info["safety_margin"] == MARGIN and info["safety_filter"] == "effc_safety.c"
    assert "--set safety_margin=0.02" in info["note"]


def test_every_export_of_the_tuned_system_names_its_safety_filter(tmp_path):
    from hybridnav.fuzzy.export import export

    fs = fuzzy.builtin("effc-tuned")
    for fmt, target in (("c", "effc"), ("fll", "x.fll"), ("fis", "x.fis"), ("fcl", "x.fcl")):
        export(fs, fmt, tmp_path / target)
        files = [tmp_path / "effc.h", tmp_path / "effc.c"] if fmt == "c" else [tmp_path / target]
        text = " ".join(" ".join(f.read_text().split()) for f in files)
        assert "safety_margin = 0.05" in text, fmt


def _attraction_only():
    """A blend-weight system that always says 'go to the goal' (w near 0)."""
    spec = {"format": "hybridnav-fis/1", "name": "attract",
            "inputs": [{"name": n, "range": r, "points": 101, "terms": [{"name": "any", "mf": "trapmf",
                                                          "params": [r[0] - 1, r[0], r[1], r[1] + 1]}]}
                       for n, r in (("dtheta", [0.0, 1.6]), ("alpha", [0.0, 2.0]))],
            "output": {"name": "w", "range": [0.0, 1.0], "points": 101, "terms": [
                {"name": "low", "mf": "trimf", "params": [0.0, 0.0, 0.05]}],
                "defuzz": "centroid", "default": 0.0},
            "rules": [{"if": ["dtheta", "any"], "then": "low"}]}
    return fuzzy.loads(__import__("json").dumps(spec), "attract.json")


def test_each_robot_keeps_the_margin_of_its_own_footprint():
    from hybridnav.world import scenario_from_dict

    def world(robots):
        return scenario_from_dict({
            "name": "pair", "units": "m", "dt": 0.1, "max_time": 60.0,
            "workspace": {"xmin": 0, "xmax": 4, "ymin": 0, "ymax": 4},
            "obstacles": [{"type": "circle", "center": [2.0, 2.0], "radius": 0.4}],
            "robots": robots})
    big = {"name": "big", "model": "unicycle", "start": [0.6, 2.0], "goal": [3.5, 2.0],
           "radius": 0.3, "goal_radius": 0.1, "initial": {"theta": 0.0}}
    small = {"name": "small", "model": "unicycle", "start": [0.3, 0.3], "goal": [0.3, 0.8],
             "radius": 0.1, "goal_radius": 0.1, "initial": {"theta": 1.5}}
    fis = _attraction_only()
    plain = planners.get("effc", fis=fis, scale=1).run(world([big])).robots[0]
    assert plain.outcome == "collided"                         # it drives at the circle
    for robots in ([big], [small, big]):                       # the small robot listed first
        res = planners.get("effc", fis=fis, scale=1, safety_margin=0.1).run(world(robots))
        r = {x.name: x for x in res.robots}["big"]
        assert r.outcome != "collided" and r.min_clearance >= 0.1 - 1e-6


def test_point_robots_keep_the_declared_defaults():
    from hybridnav.world import load_scenario, scenario_from_dict, scenario_to_dict

    d = scenario_to_dict(load_scenario("effc-train-1"))
    d["robots"][0]["radius"] = 0.0
    res = planners.get("apf").run(scenario_from_dict(d))
    assert res.params["scale"] == 1.0 and res.params["speed"] == SPEED


def test_the_replay_command_carries_the_judged_settings(tmp_path):
    import json
    import shlex

    from hybridnav.planners.field.deploy import run_command, write_deployment
    from hybridnav.world import load_scenario

    settings = {"speed": 0.2, "max_turn": TURN, "stuck_window": 10.0, "stuck_radius": 2.0,
                "safety_margin": 0.05}
    cmd = run_command("effc", settings, fis="tuned.json", world="w.toml")
    assert cmd == ("hybridnav run w.toml --planner effc --fis tuned.json "
                   "--set safety_margin=0.05 --set speed=0.2")
    write_deployment(tmp_path, "effc", "effc", settings, dt=DT, radius=R)
    assert cmd.replace("tuned.json", "fis.json").replace("w.toml", "WORLD") in json.loads(
        (tmp_path / "deployment.json").read_text())["note"]
    # the command's settings are the planner's: the same run as the settings passed directly
    args = shlex.split(cmd)
    given = dict(a.split("=") for a in args[args.index("--set") + 1::2])
    scen = load_scenario("effc-env-b")
    a = planners.get("effc", **{k: float(v) for k, v in given.items()}).run(scen).robots[0]
    b = planners.get("effc", **settings).run(scen).robots[0]
    assert a.outcome == b.outcome and a.path_length == b.path_length


def test_bad_filter_arguments_are_refused_by_name():
    from hybridnav import HybridnavError
    from hybridnav.planners.field.deploy import safety_c

    X, V = np.zeros((1, 3)), np.ones((1, 2))
    with pytest.raises(HybridnavError, match="expected a positive speed, dt and max_turn"):
        escape_filter(X, V, speed=SPEED, dt=DT, max_turn=0.0, margin=MARGIN, radius=[R],
                      clearance=_clearance(_world()))
    with pytest.raises(HybridnavError, match=r"expected states \(n, >= 3\)"):
        escape_filter(np.zeros((1, 2)), V, speed=SPEED, dt=DT, max_turn=TURN, margin=MARGIN,
                      radius=[R], clearance=_clearance(_world()))
    with pytest.raises(HybridnavError, match="name: expected a C identifier, got 'effc-tuned'"):
        safety_c("effc-tuned", speed=SPEED, dt=DT, max_turn=TURN, margin=MARGIN, radius=R)
    with pytest.raises(HybridnavError, match="margin: expected a finite positive number"):
        safety_c("effc", speed=SPEED, dt=DT, max_turn=TURN, margin=float("nan"), radius=R)
