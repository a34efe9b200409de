"""Stability analysis: Lyapunov statuses, equilibria, exact linearization vs python-control, ROA."""

from __future__ import annotations

import json
import math

import casadi as cs
import control
import numpy as np
import pytest
from hybridnav.analysis.linearization import (
    controllability_rank,
    is_stable,
    linearize,
    linearize_expression,
    summarize,
)

from hybridnav import HybridnavError, models
from hybridnav.analysis import check_lyapunov, find_equilibria
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
    """Vdot = -k_rho rho^2 cos(e)^2 vanishes where the heading is perpendicular to the target, on
    a curve no float lies on: at every float state Vdot < 0 exactly, so no state is a
    counterexample; the verdict is undecided (not proved) and names the Vdot = 0 curve."""
    m = models.get("unicycle")
    rep = check_lyapunov(m, target=(0, 0), region={"x": (-5, 5), "y": (-5, 5),
                                                   "theta": (-math.pi, math.pi)})
    assert rep.status == "undecided" and rep.counterexample is None
    assert "zero to rounding" in rep.method
    x, y, th = rep.details["vdot_zero_state"]
    e = math.atan2(-y, -x) - th
    assert abs(math.cos(e)) < 1e-3 and math.hypot(x, y) > 1e-3
    lo, hi = rep.details["worst_vdot_enclosure"]
    assert lo < 0 <= hi


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
    L, Lt, c = m.values["L"], m.values["Lt"], m.values["c"]
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
    k_rho, k_alpha = uni.values["k_rho"], uni.values["k_alpha"]
    np.testing.assert_allclose(polar.A, np.diag([-k_rho, k_rho - k_alpha]), atol=1e-14)
    assert is_stable(polar)


# ---- regions of attraction and sweeps ------------------------------------------------------


def test_point_mass_roa_is_global_when_the_proof_is():
    """The quadratic argument holds on the whole plane: no level caps the region of attraction
    (the old answer, the inscribed level 200, was capped by the box for no reason)."""
    est = estimate_roa(models.get("point_mass"), target=(20, 30), region=BOX, confirm=100)
    assert est.status == "proved" and est.bounded_by == "none"
    assert est.level == math.inf and est.to_dict()["level"] is None
    assert est.confirmed and est.simulated == 100        # starts anywhere in the box


def test_lbcs_roa_stops_at_the_saddle_behind_an_obstacle():
    lb = models.get("lbcs", obstacles=[(25.0, 25.0, 5.0)])
    region = {"x": (-100.0, 150.0), "y": (-100.0, 150.0)}
    eqs = find_equilibria(lb, target=(45, 25), region=region)
    saddle = [e for e in eqs if not e.is_target]
    assert len(saddle) == 1 and saddle[0].kind == "saddle"
    est = estimate_roa(lb, target=(45, 25), region=region, confirm=100)
    assert est.bounded_by == "equilibrium"
    assert est.level == pytest.approx(saddle[0].V, rel=2e-3) and est.level < saddle[0].V
    np.testing.assert_allclose(est.counterexample, saddle[0].state)
    assert est.status == "proved" and est.details["route"] == "certificate"
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
    assert statuses["basin of attraction (simulated grid)"] == "all_converge"
    assert statuses["region of attraction (control.lyap candidate)"] == "proved"
    assert "basin.png" in data["plots"]
    for name in data["plots"]:
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"


def test_analyze_unicycle_reports_lasalle_in_polar_coordinates(tmp_path):
    from hybridnav.analysis.report import analyze

    data = analyze("unicycle", out=tmp_path)
    rows = {c["name"]: c for c in data["checks"]}
    las = rows["LaSalle: V = 1/2 rho^2 in polar error coordinates (rho, e)"]
    assert las["status"] == "proved" and "LaSalle's invariance principle" in las["claim"]
    # not shown strictly decreasing: Vdot = 0 on a curve, zero to rounding at the state found
    assert rows["lyapunov"]["status"] == "undecided"
    x, y, th = rows["lyapunov"]["details"]["vdot_zero_state"]
    tx, ty = data["target"]
    assert abs(math.cos(math.atan2(ty - y, tx - x) - th)) < 1e-3   # facing sideways: Vdot = 0
    report = (tmp_path / "report.md").read_text()
    assert "LaSalle" in report and "Proved: Vdot <= 0 on K" in report


# ---- sound verdicts (issue 13, first part) ------------------------------------------------------


def test_an_indefinite_candidate_is_a_counterexample_not_a_pass():
    pm = models.get("point_mass")
    rep = check_lyapunov(pm, lambda z: (z[1] - 5) ** 2 - (z[0] - 45) ** 2, target=(45, 5),
                         region=BOX)
    assert rep.status == "counterexample"
    x, y = rep.counterexample
    v = (y - 5) ** 2 - (x - 45) ** 2                      # by hand
    assert v < 0 and rep.details["counterexample_V"] == pytest.approx(v)
    assert "V < 0" in rep.method and "re-evaluated" in rep.method


def test_a_failure_hidden_near_the_target_is_found_by_the_local_check():
    """V = ex^2 + ey^2 + k(r) ex ey with k = exp(-r^2 / 0.05^2): positive definite everywhere,
    but with the gains 0.01 and 1, Vdot > 0 in a thin cone within a few centimetres of the target
    (where k > 0.198) — below the sampling's exclusion floor and too thin for 1e5 samples. The
    local quadratic part at the target shows it."""
    pm = models.get("point_mass", alpha1=0.01, alpha2=1.0)
    x, t = pm.sym.x, pm.sym.target
    ex, ey = x[0] - t[0], x[1] - t[1]
    V = ex ** 2 + ey ** 2 + cs.exp(-(ex ** 2 + ey ** 2) / 0.05 ** 2) * ex * ey
    rep = check_lyapunov(pm, V, target=(45, 5), region=BOX)
    assert rep.status == "counterexample", rep.method
    assert "local check" in rep.method
    cx, cy = rep.counterexample
    dx, dy = cx - 45, cy - 5
    k = math.exp(-(dx * dx + dy * dy) / 0.05 ** 2)
    # Vdot by hand: -a1 dx dV/ddx - a2 dy dV/ddy, with dV/ddx = 2dx + k dy + dk/ddx dx dy
    dk_dx, dk_dy = -2 * dx / 0.05 ** 2 * k, -2 * dy / 0.05 ** 2 * k
    vdot = (-0.01 * dx * (2 * dx + k * dy + dk_dx * dx * dy)
            - 1.0 * dy * (2 * dy + k * dx + dk_dy * dx * dy))
    assert vdot > 0 and vdot == pytest.approx(rep.details["counterexample_vdot"], rel=1e-9)
    assert math.hypot(dx, dy) < 0.05


def test_V_expression_with_params_uses_the_changed_model():
    pm = models.get("point_mass")
    x, t = pm.sym.x, pm.sym.target
    V = (x[0] - t[0]) ** 2 + (x[1] - t[1]) ** 2
    rep = check_lyapunov(pm, V, target=(45, 5), region=BOX, params={"alpha1": -0.1})
    assert rep.status == "counterexample"
    rep = check_lyapunov(pm, V, target=(45, 5), region=BOX, params={"alpha1": 0.2})
    assert rep.status == "proved"


def _exact_det(a1, a2, k):
    """det of the Vdot Hessian and of V's, in exact rationals of the floats used."""
    from fractions import Fraction as F

    a1, a2, k = F(a1), F(a2), F(k)
    return 16 * a1 * a2 - 4 * k * k * (a1 + a2) ** 2, 4 - 4 * k * k


def test_the_near_singular_family_is_never_decided_wrongly():
    """V = ex^2 + 2k ex ey + ey^2 for the point mass: Vdot's Hessian is singular at
    k* = 2 sqrt(a1 a2) / (a1 + a2). The status must agree with the exact rational determinant
    whenever it is decided, and be decided away from k*."""
    a1, a2 = 0.1, 0.3
    pm = models.get("point_mass", alpha1=a1, alpha2=a2)
    kstar = 2 * math.sqrt(a1 * a2) / (a1 + a2)
    ks = [kstar] + [kstar + s * 10.0 ** -j for j in range(1, 17) for s in (1, -1)]
    undecided = 0
    for k in ks:
        rep = check_lyapunov(pm, lambda z, t, k=k: (z[0] - t[0]) ** 2 + 2 * k * (z[0] - t[0])
                             * (z[1] - t[1]) + (z[1] - t[1]) ** 2, target=(45, 5), region=BOX,
                             samples=2000, starts=2)
        det_d, det_v = _exact_det(a1, a2, k)
        if rep.status == "proved":
            assert det_d > 0 and det_v > 0, k
        elif rep.status == "counterexample":
            assert det_d <= 0 or det_v <= 0, k
            assert rep.details["counterexample_vdot"] > 0 or rep.details["counterexample_V"] < 0
        else:
            assert rep.status == "undecided", (k, rep.status)
            undecided += 1
            assert abs(k - kstar) < 1e-6, k
    assert 0 < undecided < len(ks)


def test_sweep_columns_agree_with_each_other():
    pm = models.get("point_mass")
    X0 = np.array([[5.0, 45.0], [40.0, 10.0], [44.0, 5.5]])
    table, traj, Vt = closed_loop_sweep(pm, X0, target=(45, 5), steps=400, goal_radius=0.5)
    assert (table.reached == table.time_to_goal.notna()).all()
    assert ((table.max_V_increase > 0) == ~table.V_monotone).all()
    # by hand: the first time within the goal radius
    d = np.hypot(traj[..., 0] - 45, traj[..., 1] - 5)
    assert table.reached.any() and not table.reached.all()
    for i in range(len(X0)):
        if (d[i] <= 0.5).any():
            k = int(np.argmax(d[i] <= 0.5))
            assert table.time_to_goal[i] == pytest.approx(k * pm.dt)
        else:
            assert np.isnan(table.time_to_goal[i]) and not table.reached[i]


def test_a_system_without_inputs_is_not_called_uncontrollable():
    uni = models.get("unicycle")
    z, zdot, names = uni.polar_error_dynamics()
    polar = linearize_expression(z, zdot, [0, 0], names, symbols=uni.sym.p, values=uni.p_value())
    d = summarize(polar).to_dict()
    assert d["n_inputs"] == 0 and d["controllable"] is None
    pm = models.get("point_mass")
    d = summarize(linearize(pm, [45.0, 5.0], target=[45.0, 5.0])).to_dict()
    assert d["n_inputs"] == 2 and d["controllable"] is True


def test_rk4_stability_limit_and_the_simulated_point_mass():
    from hybridnav.analysis.linearization import discrete_step, rk4_stability_limit

    z = rk4_stability_limit()
    R = lambda z: 1 - z + z * z / 2 - z ** 3 / 6 + z ** 4 / 24      # noqa: E731  R(-z) by hand
    assert abs(R(z)) == pytest.approx(1.0, abs=1e-12) and abs(R(z * 0.999)) < 1 < abs(R(z * 1.001))
    assert z == pytest.approx(2.785, abs=1e-3)
    for alpha, stable in ((27.0, True), (28.0, False), (30.0, False)):
        pm = models.get("point_mass", alpha1=alpha, alpha2=alpha, dt=0.1)
        rep = discrete_step(pm, [45.0, 5.0], [45.0, 5.0])
        assert rep.spectral_radius == pytest.approx(abs(R(alpha * 0.1)), rel=1e-12)
        assert rep.stable is stable and (alpha * 0.1 < z) is stable
    # at alpha = 30 the continuous loop is proved stable, but the simulated one diverges:
    pm = models.get("point_mass", alpha1=30.0, alpha2=30.0, dt=0.1)
    assert check_lyapunov(pm, target=(45, 5), region=BOX).status == "proved"
    with pytest.raises(HybridnavError, match=r"simulated step \(RK4, dt = 0.1\) is unstable.*"
                                             r"spectral radius 1.375"):
        estimate_roa(pm, target=(45, 5), region=BOX)
    traj = pm.rollout(np.array([[44.0, 5.0]]), np.array([[45.0, 5.0]]), 50)
    assert abs(traj[0, -1, 0] - 45) > 1.0                     # it really diverges


def test_estimate_roa_reports_the_discrete_step():
    est = estimate_roa(models.get("point_mass"), target=(45, 5), region=BOX, confirm=20)
    step = est.details["discrete_step"]
    assert step["status"] == "stable" and step["spectral_radius"] < 1
    assert step["point"] == pytest.approx([45, 5], abs=1e-6)


def test_linearize_raises_at_kinks_and_jumps():
    uni = models.get("unicycle")
    # facing straight away from the target: the heading error wraps at pi
    with pytest.raises(HybridnavError, match=r"unicycle is not differentiable at .*along (x|y|theta).*"
                                             r"one-sided derivatives"):
        linearize(uni, [1.0, 1.0, math.pi / 4], target=[0.0, 0.0])
    tt = models.get("tractor_trailer")
    # |theta0 - theta1| = pi / 3: the kink of fmax(0, 0.5 - cos(gap)) in its controller
    with pytest.raises(HybridnavError, match="tractor_trailer is not differentiable"):
        linearize(tt, [0.0, 0.0, math.pi / 3, 0.0, 0.0], target=[5.0, 5.0])
    # away from them the linearization stands, and agrees with central differences
    x0 = np.array([0.0, 0.0, 0.4, 0.1, 0.0])
    sys = linearize(tt, x0, target=[5.0, 5.0])
    f = tt.function("closed_loop")
    h = 1e-6
    num = np.column_stack([(np.asarray(f(x0 + h * e, [5.0, 5.0], tt.p_value())).ravel()
                            - np.asarray(f(x0 - h * e, [5.0, 5.0], tt.p_value())).ravel())
                           / (2 * h) for e in np.eye(5)])
    np.testing.assert_allclose(sys.A, num, rtol=1e-6, atol=1e-8)
