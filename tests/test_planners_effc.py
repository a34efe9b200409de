"""EFFC: the fuzzy inputs, the blend against scikit-fuzzy, the turn limit, pluggable systems."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hybridnav import HybridnavError, fuzzy, planners
from hybridnav.planners.field.effc import effc_force, effc_inputs, effc_inputs_from
from hybridnav.world import Circle, World, load_scenario


def test_inputs_by_hand():
    world = World((-5, 5, -5, 5), (Circle((2.0, 0.0), 0.5),))
    P = np.array([[0.0, 0.0], [0.0, 1.0]])
    goals = np.array([[4.0, 0.0], [0.0, 3.0]])
    dtheta, alpha, f_att, f_rep = effc_inputs(world, P, goals, 0.1, 0.0)
    # robot 0: obstacle dead ahead, 1.5 - 0.1 from the footprint, target 4 away
    assert dtheta[0] == pytest.approx(0.0) and alpha[0] == pytest.approx(1.4 / 4.0)
    np.testing.assert_allclose(f_att[0], [1, 0]), np.testing.assert_allclose(f_rep[0], [-1, 0])
    # robot 1: target straight up, obstacle towards (2, -1)
    to_obs = math.atan2(-1.0, 2.0)
    assert dtheta[1] == pytest.approx(abs(math.pi / 2 - to_obs))
    assert alpha[1] == pytest.approx((math.hypot(2, 1) - 0.5 - 0.1) / 2.0)
    np.testing.assert_allclose(f_rep[1], -np.array([2.0, -1.0]) / math.hypot(2, 1))


def test_velocity_is_the_blend_with_the_weight_scikit_fuzzy_computes():
    from skfuzzy import control as ctrl

    s = load_scenario("effc-env-b")
    fis = fuzzy.builtin("effc-5rule")
    rng = np.random.default_rng(0)
    P = rng.uniform(0, 3, (30, 2))
    P = P[s.world.clearance(P) > 0.15]
    goals = np.tile(s.robots[0].goal, (len(P), 1))
    dtheta, alpha, f_att, f_rep = effc_inputs(s.world, P, goals, 0.1, 0.0)
    F = effc_force(fis.evaluate(dtheta=dtheta, alpha=alpha), f_att, f_rep)
    sim = ctrl.ControlSystemSimulation(fis.to_skfuzzy(), cache=False)
    for d, a, fa, fr, f in zip(dtheta, alpha, f_att, f_rep, F):
        sim.input["dtheta"], sim.input["alpha"] = d, a
        sim.compute()
        w = sim.output.get("w", fis.output.default)
        np.testing.assert_allclose(f, w * fr + (1 - w) * fa, atol=1e-9)


def test_heading_turns_at_most_pi_over_4_per_cycle_at_constant_speed():
    s = load_scenario("effc-env-b")
    r = planners.get("effc").run(s).robots[0]
    assert r.outcome == "reached"
    th = r.states[:, 2]
    turn = np.abs(np.angle(np.exp(1j * np.diff(th))))
    assert turn.max() <= math.pi / 4 + 1e-9
    steps = np.hypot(*np.diff(r.states[:, :2], axis=0).T)
    # constant speed 0.1 m/s: an arc of 0.01 m per cycle (its chord is a little shorter)
    assert steps.max() <= 0.01 + 1e-12 and steps.min() > 0.0092


def test_any_fuzzy_system_can_be_plugged_in(tmp_path):
    d = fuzzy.builtin("effc-2rule").to_dict()
    d["name"] = "mine"
    d["output"]["terms"][1]["params"] = [0.5, 1.0]
    path = tmp_path / "mine.json"
    fuzzy.FuzzySystem.from_dict(d).save(path)
    p = planners.get("effc", fis=str(path))
    assert p.fis.name == "mine"
    res = p.run(load_scenario("effc-train-2"))
    assert res.params["fis"] == str(path)
    assert res.robots[0].outcome in ("reached", "stuck", "collided", "out_of_bounds", "timeout")
    bad = fuzzy.builtin("effc-2rule").to_dict()
    bad["inputs"][1]["name"] = "beta"
    bad["rules"] = [r for r in bad["rules"] if "alpha" not in str(r["if"])]
    with pytest.raises(HybridnavError, match="expected a fuzzy system with the inputs dtheta"):
        planners.get("effc", fis=fuzzy.FuzzySystem.from_dict(bad))
    with pytest.raises(HybridnavError, match="nope.json"):
        planners.get("effc", fis=str(tmp_path / "nope.json"))


def test_effc_records_its_weight_signal(tmp_path):
    from hybridnav.cli import main

    out = tmp_path / "e"
    assert main(["run", "effc-train-1", "--planner", "effc", "--fis", "effc-5rule", "--out",
                 str(out)]) == 0
    assert (out / "signals.png").exists()


def test_a_third_input_clearance_is_fed_the_footprints_gap():
    from hybridnav import HybridnavError
    from hybridnav.planners.field.effc import effc_clearance
    from hybridnav.tuner.heldout import run_systems

    safe = fuzzy.builtin("effc-safe")
    assert safe.input_names == ("dtheta", "alpha", "clearance")
    scen = load_scenario("effc-env-a")
    p = planners.get("effc", fis=safe)
    res = p.run(scen).robots[0]
    # the planner's weight is the system's at the inputs it computes, clearance included
    world = scen.world
    X = res.states[:40]
    clear, near, _ = world.nearest(X[:, :2])
    goals = np.tile(scen.robots[0].goal, (len(X), 1))
    d, a, fa, fr = effc_inputs_from(X[:, :2], goals, clear, near, 0.1)
    c = effc_clearance(clear, 0.1)
    assert np.allclose(c, np.maximum(clear - 0.1, 0.0))
    w = safe.evaluate(dtheta=d, alpha=a, clearance=c)
    assert np.all((0 <= w) & (w <= 1))
    # the lockstep batch (what tuning and judging run) is the planner run by run
    table = run_systems({"safe": safe}, [scen, load_scenario("effc-env-b")], apf=False)
    for name, row in zip(table.scenario, table.itertuples()):
        ref = planners.get("effc", fis=safe).run(load_scenario(name)).robots[0]
        assert row.outcome == ref.outcome
        assert row.path_length == pytest.approx(ref.path_length, rel=1e-9)
    # no obstacle: clearance is inf and the system clips it to its range
    assert effc_clearance(np.array([np.inf]), 0.1)[0] == np.inf
    # a fourth input, or clearance without alpha, is refused
    two = fuzzy.builtin("steer-7rule")
    with pytest.raises(HybridnavError, match=r"inputs dtheta and alpha \(and optionally "
                                             r"clearance\)"):
        planners.get("effc", fis=two)
