"""Stability analysis: Lyapunov statuses, equilibria, exact linearization vs python-control, ROA."""

from __future__ import annotations

import json
import math

import casadi as cs
import control
import numpy as np
import pytest

from hybridnav import HybridnavError, models
from hybridnav.analysis import check_lyapunov, find_equilibria
from hybridnav.analysis.linearize import (
    controllability_rank,
    is_stable,
    linearize,
    linearize_expression,
)
from hybridnav.analysis.roa import estimate_roa
from hybridnav.analysis.sweep import closed_loop_sweep, grid_starts
from hybridnav.world import load_scenario

BOX = {"x": (0.0, 50.0), "y": (0.0, 50.0)}


def test_theorem_1_is_proved_for_positive_gains():
    rep = check_lyapunov(models.get("point_mass", alpha1=0.1, alpha2=0.3), target=(45, 5),
                         region=BOX)
    assert rep.status == "proved"
    assert rep.vdot_nonpositive_proved and rep.counterexample is None
    assert "alpha1" in rep.vdot and "alpha2" in rep.vdot
    assert sorted(rep.details["eig_hessian_vdot"]) == pytest.approx([-0.6, -0.2])
    assert rep.details["equilibrium"] == pytest.approx([45, 5])


def test_negative_gain_gives_a_concrete_counterexample():
    rep = check_lyapunov(models.get("point_mass"), target=(45, 5), region=BOX,
                         params={"alpha1": -0.1})
    assert rep.status == "counterexample"
    x, y = rep.counterexample
    assert 0 <= x <= 50 and 0 <= y <= 50 and (x, y) != (45, 5)
    vdot = 0.1 * (45 - x) ** 2 - 0.1 * (5 - y) ** 2        # -alpha1 dx^2 - alpha2 dy^2 by hand
    assert vdot >= 0 and vdot == pytest.approx(rep.worst_vdot)


def test_non_quadratic_candidate_is_never_proved():
    m = models.get("point_mass")
    x = m.sym.x
    rep = check_lyapunov(m, lambda x, t: (x[0] - t[0]) ** 4 + (x[1] - t[1]) ** 4, target=(25, 25),
                         region=BOX, samples=100_000)
    assert rep.status == "no_counterexample"
    assert rep.details["samples"] >= 100_000 and rep.worst_vdot < 0
    assert "not a proof" in rep.method
    assert x.shape == (2, 1)


def test_unicycle_distance_is_not_a_strict_lyapunov_function():
    """Vdot = -k_rho rho^2 cos(e)^2 vanishes where the heading is perpendicular to the target."""
    m = models.get("unicycle")
    rep = check_lyapunov(m, target=(0, 0), region={"x": (-5, 5), "y": (-5, 5),
                                                   "theta": (-math.pi, math.pi)})
    assert rep.status == "counterexample"
    x, y, th = rep.counterexample
    e = math.atan2(-y, -x) - th
    assert abs(math.cos(e)) < 1e-3 and math.hypot(x, y) > 1e-3


def test_lbcs_gradient_flow_and_its_local_minimum_in_the_trap():
    s = load_scenario("aco-local-minimum")
    robot = s.robots[0]
    lb = models.LbCS.from_scenario(s)
    rep = check_lyapunov(lb, target=robot.goal, region=BOX)
    assert rep.vdot_nonpositive_proved and "gradient flow" in rep.method
    assert rep.status == "counterexample"
    # independent check: the counterexample is a stationary point of L (central differences)
    L = cs.Function("L", [lb.sym.x], [cs.substitute(lb.lyapunov_function(), cs.vertcat(
        lb.sym.target, lb.sym.p), cs.DM(np.r_[robot.goal, lb.p_value()]))])
    z, h = rep.counterexample, 1e-5
    grad = [(float(L(z + h * e)) - float(L(z - h * e))) / (2 * h) for e in np.eye(2)]
    assert np.abs(grad).max() < 1e-5 * max(1.0, float(L(z)))
    eqs = find_equilibria(lb, target=robot.goal, region=BOX)
    assert eqs[0].is_target and eqs[0].kind == "stable"
    minima = [e for e in eqs if not e.is_target and e.kind == "stable"]
    assert minima, "the trap must have a local minimum"
    # the scheme started at the scenario's start stalls in it
    tr = lb.rollout(np.array([robot.start]), np.array([robot.goal]), s.max_steps)[0]
    assert min(np.linalg.norm(tr[-1] - e.state) for e in minima) < 1e-3
    assert np.linalg.norm(tr[-1] - robot.goal) > 10


def test_point_mass_has_only_the_target_as_equilibrium():
    eqs = find_equilibria(models.get("point_mass"), target=(20, 30), region=BOX, starts=50)
    assert len(eqs) == 1 and eqs[0].is_target and eqs[0].kind == "stable"
    assert eqs[0].eigenvalues.real == pytest.approx([-0.1, -0.1])


# ---- linearization ------------------------------------------------------------------------


def _reference(model, x0, u0):
    f = model.function("open_loop")
    p = model.p_value()
    nl = control.nlsys(lambda t, x, u, params: np.asarray(f(x, u, p)).ravel(), None,
                       states=model.n_plant, inputs=model.nu, outputs=model.n_plant)
    return control.linearize(nl, x0, u0)


@pytest.mark.parametrize("name, x0, u0", [
    ("tractor_trailer", [0.0, 0.0, 0.0, 0.0], [1.0, 0.0]),
    ("tractor_trailer", [3.0, -2.0, 0.4, 0.1], [0.7, 0.2]),
    ("unicycle", [0.0, 0.0, 0.3], [0.2, 0.25]),
])
def test_open_loop_linearization_matches_python_control(name, x0, u0):
    m = models.get(name)
    ours = linearize(m, x0, u0)
    ref = _reference(m, x0, u0)
    np.testing.assert_allclose(ours.A, ref.A, atol=1e-6)
    np.testing.assert_allclose(ours.B, ref.B, atol=1e-6)
    assert list(ours.state_labels) == list(m.plant_state_names)
    assert controllability_rank(ours) == np.linalg.matrix_rank(control.ctrb(ref.A, ref.B))


def test_tractor_trailer_straight_driving_by_hand():
    m = models.get("tractor_trailer")
    L, Lt, c = m.params["L"], m.params["Lt"], m.params["c"]
    v = 1.0
    sys = linearize(m, [0, 0, 0, 0], [v, 0.0])
    A = np.zeros((4, 4))
    A[1, 2] = v                      # ydot = v sin th0 + ...
    A[3, 2], A[3, 3] = v / Lt, -v / Lt
    B = np.array([[1, 0], [0, v / 2], [0, v / L], [0, -v / Lt * c / L]])
    np.testing.assert_allclose(sys.A, A, atol=1e-14)
    np.testing.assert_allclose(sys.B, B, atol=1e-14)
    assert controllability_rank(sys) == 4 and not is_stable(sys)
    np.testing.assert_allclose(sys.nominal_rate, [1, 0, 0, 0])


def test_closed_loop_linearizations_at_the_target():
    pm = models.get("point_mass", alpha1=0.2, alpha2=0.05)
    sys = linearize(pm, [3.0, 4.0], target=[3.0, 4.0])
    np.testing.assert_allclose(sys.A, np.diag([-0.2, -0.05]))
    np.testing.assert_allclose(sys.B, np.diag([0.2, 0.05]))
    assert is_stable(sys)
    uni = models.get("unicycle")
    with pytest.raises(HybridnavError, match="unicycle is not differentiable at .* theta"):
        linearize(uni, [1.0, 1.0, 0.0], target=[1.0, 1.0])
    z, zdot, names = uni.polar_error_dynamics()
    polar = linearize_expression(z, zdot, [0, 0], names, symbols=uni.sym.p, values=uni.p_value())
    k_rho, k_alpha = uni.params["k_rho"], uni.params["k_alpha"]
    np.testing.assert_allclose(polar.A, np.diag([-k_rho, k_rho - k_alpha]), atol=1e-14)
    assert is_stable(polar)


# ---- regions of attraction and sweeps ------------------------------------------------------


def test_point_mass_roa_is_the_whole_inscribed_level_set():
    est = estimate_roa(models.get("point_mass"), target=(20, 30), region=BOX, confirm=100)
    assert est.status == "proved" and est.bounded_by == "box"
    assert est.level == pytest.approx(0.5 * 20.0 ** 2, rel=1e-3)   # nearest side x = 0
    assert est.confirmed and est.simulated == 100


def test_lbcs_roa_stops_at_the_saddle_behind_an_obstacle():
    lb = models.get("lbcs", obstacles=[(25.0, 25.0, 5.0)])
    region = {"x": (-100.0, 150.0), "y": (-100.0, 150.0)}
    eqs = find_equilibria(lb, target=(45, 25), region=region)
    saddle = [e for e in eqs if not e.is_target]
    assert len(saddle) == 1 and saddle[0].kind == "saddle"
    est = estimate_roa(lb, target=(45, 25), region=region, confirm=100)
    assert est.bounded_by == "counterexample"
    assert est.level == pytest.approx(saddle[0].V, rel=2e-3)
    assert est.confirmed


def test_tractor_trailer_sweep_reports_the_issue_run():
    m = models.get("tractor_trailer")
    X0, starts = grid_starts(m, (45, 25), np.array([[5.0, 45.0]]), {"theta0": [0.0],
                                                                   "theta1": "theta0"})
    table, traj, Vt = closed_loop_sweep(m, X0, target=(45, 25), steps=3000)
    row = table.iloc[0]
    assert bool(row.reached) and row.max_gap < 0.35 and not bool(row.jackknife)
    assert Vt.shape == (1, 3001) and Vt[0, -1] < 1e-6
    assert list(starts.columns) == ["x0", "y0", "theta0", "theta1"]


def test_region_errors_name_the_state():
    m = models.get("unicycle")
    with pytest.raises(HybridnavError, match="region.theta: missing"):
        check_lyapunov(m, target=(0, 0), region={"x": (-1, 1), "y": (-1, 1)})
    with pytest.raises(HybridnavError, match="region.z: not a state of unicycle"):
        check_lyapunov(m, target=(0, 0), region={"x": (-1, 1), "y": (-1, 1), "theta": (0, 1),
                                                 "z": (0, 1)})
    with pytest.raises(HybridnavError, match=r"region.x: expected finite lo <= hi"):
        check_lyapunov(m, target=(0, 0), region={"x": (1, -1), "y": (-1, 1), "theta": (0, 1)})
    with pytest.raises(HybridnavError, match="V: depends on symbols"):
        check_lyapunov(m, cs.SX.sym("q") ** 2, target=(0, 0),
                       region={"x": (-1, 1), "y": (-1, 1), "theta": (0, 1)})


def test_analyze_writes_json_report_and_plots(tmp_path):
    from hybridnav.cli import main

    assert main(["analyze", "point_mass", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "analysis.json").read_text())
    statuses = {c["name"]: c["status"] for c in data["checks"]}
    assert statuses["lyapunov"] == "proved"
    assert statuses["linearization: closed loop at the target"] == "stable"
    assert statuses["region of attraction"] == "proved"
    assert "| lyapunov | **proved** |" in (tmp_path / "report.md").read_text()
    for name in data["plots"]:
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"
