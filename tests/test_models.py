"""Kinematic models: closed forms, scipy references, batching, targets, errors."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hybridnav import HybridnavError, models


def reference(model, x0, target, t_end, dt_out):
    """solve_ivp (Radau, rtol = atol = 1e-10) of the model's closed loop."""
    rhs = model.numeric_closed_loop()
    t_eval = np.arange(0, t_end + 1e-9, dt_out)
    sol = solve_ivp(lambda t, x: rhs(x, target), (0, t_end), x0, method="Radau",
                    rtol=1e-10, atol=1e-10, t_eval=t_eval)
    assert sol.success
    return sol.y.T


def test_point_mass_matches_closed_form():
    m = models.get("point_mass")                       # alpha1 = alpha2 = 0.1
    x0 = np.array([[5.0, 45.0], [-3.0, 2.0]])
    tg = np.array([[45.0, 5.0], [0.0, 0.0]])
    steps = 300
    traj = m.rollout(x0, tg, steps)
    t = np.arange(steps + 1) * m.dt
    exact_x = tg[:, None, 0] + (x0[:, None, 0] - tg[:, None, 0]) * np.exp(-0.1 * t)
    exact_y = tg[:, None, 1] + (x0[:, None, 1] - tg[:, None, 1]) * np.exp(-0.1 * t)
    assert np.abs(traj[..., 0] - exact_x).max() < 1e-8
    assert np.abs(traj[..., 1] - exact_y).max() < 1e-8


@pytest.mark.parametrize("dt, tol", [(0.1, 1e-4), (0.01, 1e-7)])
def test_tractor_trailer_matches_radau(dt, tol):
    m = models.get("tractor_trailer", dt=dt)
    target = np.array([45.0, 25.0])
    x0 = m.initial_state([5.0, 45.0], target, {"theta0": -0.3, "theta1": -0.2})
    steps = round(30.0 / dt)
    ours = m.rollout(x0[None], target[None], steps)[0]
    ref = reference(m, x0, target, 30.0, dt)
    assert ref.shape == ours.shape
    assert np.abs(ours - ref).max() < tol


@pytest.mark.parametrize("dt, tol", [(0.1, 1e-4), (0.01, 1e-7)])
def test_unicycle_go_to_point_matches_radau(dt, tol):
    m = models.get("unicycle", dt=dt, wheel_max=0.6)
    target = np.array([2.0, 3.0])
    x0 = m.initial_state([0.0, 0.0], target, {"theta": 0.2})
    steps = round(30.0 / dt)
    ours = m.rollout(x0[None], target[None], steps)[0]
    ref = reference(m, x0, target, 30.0, dt)
    assert np.abs(ours - ref).max() < tol


def test_unicycle_heading_controller_holds_input_over_each_cycle():
    """Zero-order hold: per cycle, the input from the cycle's start state, integrated exactly."""
    m = models.get("unicycle", controller="heading", speed=0.1, dt=0.1)
    ctrl = m.function("controller")
    f = m.function("open_loop")
    p = m.p_value()
    x = np.array([0.0, 0.0, 3.0])       # facing away: the turn is clipped to pi/4 per cycle
    target = np.array([3.0, 3.0])
    ours = m.rollout(x[None], target[None], 40)[0]
    for k in range(40):
        u = np.asarray(ctrl(x, target, p)).ravel()
        omega = (u[1] - u[0]) / m.values["L"]
        assert abs(omega * m.dt) <= math.pi / 4 + 1e-12
        sol = solve_ivp(lambda t, z: np.asarray(f(z, u, p)).ravel(), (0, m.dt), x,
                        method="Radau", rtol=1e-12, atol=1e-12)
        x = sol.y[:, -1]
        # RK4 on a 45-degree arc per cycle: about 1e-6 m of truncation error per cycle
        assert np.abs(ours[k + 1] - x).max() < 1e-5
    # the first cycles turn by exactly the limit
    assert ours[1, 2] - ours[0, 2] == pytest.approx(-math.pi / 4, abs=1e-9)


@pytest.mark.parametrize("name", sorted(models.MODELS))
def test_batched_rollout_equals_single_robot_rollouts(name):
    m = models.get(name)
    rng = np.random.default_rng(3)
    n = 7
    starts = rng.uniform(0, 10, (n, 2))
    targets = rng.uniform(0, 10, (n, 2))
    inits = {"tractor_trailer": {"theta0": 0.4, "theta1": 0.3}, "unicycle": {"theta": 1.0}}
    X0 = np.array([m.initial_state(s, t, inits.get(name)) for s, t in zip(starts, targets)])
    batch = m.rollout(X0, targets, 50)
    for i in range(n):
        single = m.rollout(X0[i:i + 1], targets[i:i + 1], 50)
        np.testing.assert_array_equal(batch[i], single[0])
    # step() repeated is the rollout
    X = X0.copy()
    for k in range(50):
        X = m.step(X, targets)
    np.testing.assert_allclose(X, batch[:, -1], rtol=0, atol=1e-12)


def test_casadi_rollout_runs_whole_chunks_without_padding(monkeypatch):
    """CasADi's map (the path without the compiled kernel) runs 10,000 robots in functions of
    4096, 4096, 1024, 512, 256 and 16 robots, not 3 x 4096 = 12,288 slots; each robot's result
    is its own rollout's."""
    from hybridnav.models.base import _chunks

    monkeypatch.setenv("HYBRIDNAV_NATIVE", "0")
    for n in (1, 7, 9, 17, 4097, 10_000, 12_288):
        sizes = _chunks(n)
        assert sum(sizes) == n and max(sizes) <= 4096
        assert all(s <= 8 or s & (s - 1) == 0 for s in sizes)
    assert _chunks(10_000) == [4096, 4096, 1024, 512, 256, 16]
    m = models.get("point_mass", jit=False)          # the virtual machine: nothing to compile
    rng = np.random.default_rng(2)
    X0, T = rng.uniform(0, 10, (10_000, 2)), rng.uniform(0, 10, (10_000, 2))
    traj = m.rollout(X0, T, 3)
    assert sorted(k[1] for k in m._local.buffers if k[0] == "rollout") == [16, 256, 512, 1024,
                                                                           4096]
    for i in (0, 4095, 8191, 9983, 9999):
        np.testing.assert_array_equal(traj[i], m.rollout(X0[i:i + 1], T[i:i + 1], 3)[0])


@pytest.mark.parametrize("name", sorted(models.MODELS))
def test_jit_and_virtual_machine_agree(name):
    if not models.jit_available():
        pytest.skip("no working C compiler here")
    rng = np.random.default_rng(5)
    mj = models.get(name, jit=True)
    mv = models.get(name, jit=False)
    X0 = np.column_stack([rng.uniform(0, 5, (4, 2)), rng.uniform(-0.5, 0.5, (4, mj.nx - 2))])
    tg = rng.uniform(5, 10, (4, 2))
    np.testing.assert_allclose(mj.rollout(X0, tg, 30), mv.rollout(X0, tg, 30), rtol=0, atol=1e-12)


def _grid_starts(radii, n_bearings, heading_errors):
    """Starts around the origin and initial headings = bearing to the origin - error."""
    out = []
    for r in radii:
        for a in np.linspace(-math.pi, math.pi, n_bearings, endpoint=False):
            bearing = math.atan2(-math.sin(a), -math.cos(a))
            for de in heading_errors:
                out.append(((r * math.cos(a), r * math.sin(a)), bearing - de))
    return out


@pytest.mark.parametrize("name, key, steps", [("point_mass", None, 2000),
                                              ("unicycle", "theta", 600)])
def test_holonomic_and_unicycle_reach_target_from_every_start_and_heading(name, key, steps):
    m = models.get(name)
    errors = np.linspace(-math.pi, math.pi, 8, endpoint=False) if key else [0.0]
    starts = _grid_starts((1.0, 5.0, 20.0), 8, errors)
    X0 = np.array([m.initial_state(s, (0, 0), {key: h} if key else {}) for s, h in starts])
    final = m.rollout(X0, np.zeros((len(X0), 2)), steps)[:, -1]
    assert np.hypot(final[:, 0], final[:, 1]).max() < 1e-3


def test_tractor_trailer_reaches_target_from_far_starts_with_any_heading_error_up_to_90_degrees():
    m = models.get("tractor_trailer")
    starts = _grid_starts((20.0, 40.0), 8, np.linspace(-math.pi / 2, math.pi / 2, 7))
    X0 = np.array([m.initial_state(s, (0, 0), {"theta0": h, "theta1": h}) for s, h in starts])
    traj = m.rollout(X0, np.zeros((len(X0), 2)), 3000)
    dist = np.hypot(traj[:, -1, 0], traj[:, -1, 1])
    assert dist.max() < 0.05
    # the trailer never jackknifes on the way (|theta0 - theta1| stays well below pi/2)
    assert np.abs(traj[..., 2] - traj[..., 3]).max() < 1.0


def test_tractor_trailer_orbits_a_target_that_is_too_close_to_turn_onto():
    """The papers' law is unstable within about 9L/7 of the target (see the module docstring)."""
    m = models.get("tractor_trailer")
    for error in (0.3, 1.0):
        x0 = m.initial_state((10.0, 0.0), (0, 0), {"theta0": math.pi - error,
                                                   "theta1": math.pi - error})
        traj = m.rollout(x0[None], np.zeros((1, 2)), 3000)[0]
        dist = np.hypot(traj[-600:, 0], traj[-600:, 1])    # the last minute
        assert 0.5 < dist.min() and dist.max() < 2 * m.values["L"]


def test_tractor_trailer_filter_law_reaches_without_jackknife_and_paper_law_circles():
    target = np.array([45.0, 25.0])
    good = models.get("tractor_trailer")
    x0 = good.initial_state([5.0, 45.0], target)
    tr = good.rollout(x0[None], target[None], 3000)[0]
    assert np.hypot(*(tr[-1, :2] - target)) < 1e-3
    assert np.abs(tr[:, 2] - tr[:, 3]).max() < 0.35
    paper = models.get("tractor_trailer", xi_law="paper")
    tr = paper.rollout(paper.initial_state([5.0, 45.0], target)[None], target[None], 3000)[0]
    assert np.hypot(*(tr[-1, :2] - target)) > 30.0   # still far away after 300 s


def test_tractor_trailer_retarget_sets_xi_to_heading_error():
    m = models.get("tractor_trailer")
    X = np.array([[0.0, 0.0, 3.0, 3.0, 0.0]])
    X2 = m.retarget(X, [[-1.0, -0.1]])
    err = math.atan2(-0.1, -1.0) - 3.0
    assert X2[0, 4] == pytest.approx(math.atan2(math.sin(err), math.cos(err)))
    assert X[0, 4] == 0.0  # the input is not modified


def test_tractor_trailer_footprint_covers_both_bodies():
    m = models.get("tractor_trailer")
    q = m.values
    X = np.array([[10.0, 5.0, 0.7, -0.4, 0.0]])
    centers, radii = m.footprint(X)
    assert centers.shape == (1, len(radii), 2)
    u0 = np.array([math.cos(0.7), math.sin(0.7)])
    n0 = np.array([-u0[1], u0[0]])
    u1 = np.array([math.cos(-0.4), math.sin(-0.4)])
    n1 = np.array([-u1[1], u1[0]])
    s = np.linspace(-0.5, 0.5, 41)
    tractor = [X[0, :2] + a * q["L"] * u0 + w * q["b"] * n0 for a in s for w in s]
    hitch = X[0, :2] - (q["L"] / 2 + q["c"]) * u0
    trailer = [hitch - (a + 0.5) * q["Lt"] * u1 + w * q["b"] * n1 for a in s for w in s]
    pts = np.array(tractor + trailer)
    d = np.linalg.norm(pts[:, None, :] - centers[0][None], axis=2) - radii[None]
    assert d.min(axis=1).max() <= 1e-12
    assert m.radius == pytest.approx(math.hypot(q["L"], q["b"]) / 2)


def test_point_mass_function_views():
    m = models.get("point_mass", alpha1=0.3, alpha2=0.2)
    f = m.function("closed_loop")
    xdot = np.asarray(f([1.0, 2.0], [4.0, 6.0], m.p_value())).ravel()
    np.testing.assert_allclose(xdot, [0.9, 0.8])
    assert m.state_names == ("x", "y")
    assert m.function("open_loop").size1_in(0) == 2


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: models.get("bicycle"), "unknown model 'bicycle'; expected one of: lbcs, point_mass"),
        (lambda: models.get("point_mass", alpah1=0.1), "unknown parameter 'alpah1'"),
        (lambda: models.get("point_mass", alpha1="fast"), "alpha1: expected a number"),
        (lambda: models.get("point_mass", alpha1=float("nan")), "alpha1: expected a finite number"),
        (lambda: models.get("point_mass", dt=0.0), "dt: expected a positive number"),
        (lambda: models.get("tractor_trailer", L=-1.0), "L: expected a positive number"),
        (lambda: models.get("tractor_trailer", xi_law="magic"), "xi_law: expected one of"),
        (lambda: models.get("unicycle", controller="pid"), "controller: expected one of"),
        (lambda: models.get("point_mass").step(np.zeros((3, 3)), np.zeros((3, 2))),
         "X: expected an (N, 2) array"),
        (lambda: models.get("point_mass").rollout(np.zeros((3, 2)), np.zeros((2, 2)), 5),
         "targets: expected an (3, 2) array"),
        (lambda: models.get("point_mass").rollout(np.zeros((1, 2)), np.zeros((1, 2)), -1),
         "steps: expected a non-negative integer"),
        (lambda: models.get("unicycle").initial_state([0, 0], [1, 1], {"phi": 1.0}),
         "initial.phi: unknown state; expected one of: theta"),
    ],
)
def test_bad_input_raises_hybridnav_error(call, message):
    with pytest.raises(HybridnavError) as info:
        call()
    assert message in str(info.value)
    assert isinstance(info.value, ValueError)


def test_empty_batch_and_zero_steps():
    m = models.get("unicycle")
    assert m.step(np.zeros((0, 3)), np.zeros((0, 2))).shape == (0, 3)
    traj = m.rollout(np.ones((2, 3)), np.zeros((2, 2)), 0)
    assert traj.shape == (2, 1, 3)
    np.testing.assert_array_equal(traj[:, 0], np.ones((2, 3)))


def test_without_a_working_compiler_the_models_fall_back_silently(tmp_path):
    """CC points nowhere: JIT fails, the VM runs, results are the same, nothing is printed."""
    import subprocess
    import sys

    code = (
        "import numpy as np\n"
        "from hybridnav import models\n"
        "assert not models.jit_available()\n"
        "m = models.get('tractor_trailer')\n"
        "x0 = m.initial_state([5.0, 45.0], [45.0, 25.0])\n"
        "print(repr(m.rollout(x0[None], np.array([[45.0, 25.0]]), 50)[0, -1].tolist()))\n"
    )
    env = dict(__import__("os").environ, CC=str(tmp_path / "no-such-compiler"))
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    m = models.get("tractor_trailer")
    x0 = m.initial_state([5.0, 45.0], [45.0, 25.0])
    expected = m.rollout(x0[None], np.array([[45.0, 25.0]]), 50)[0, -1]
    np.testing.assert_allclose(eval(proc.stdout), expected, rtol=0, atol=1e-12)
    assert list(tmp_path.iterdir()) == []          # no generated C files in the working folder


def test_a_model_without_body_rates_builds_its_controller_once(monkeypatch):
    """commanded_rates of a model whose body_rates are None (the point mass) answers None from
    its cache: the controller is not rebuilt symbolically every control cycle (it was, at
    half of a FAStep run's time)."""
    m = models.get("point_mass")
    calls = []
    original = type(m).controller
    monkeypatch.setattr(type(m), "controller",
                        lambda self, *a: calls.append(1) or original(self, *a))
    X, T = np.zeros((3, m.nx)), np.ones((3, 2))
    assert m.commanded_rates(X, T) is None
    assert m.commanded_rates(X, T) is None
    assert len(calls) == 1
    u = models.get("unicycle")
    np.testing.assert_allclose(u.commanded_rates(np.zeros((2, u.nx)), np.ones((2, 2))),
                               u.commanded_rates(np.zeros((2, u.nx)), np.ones((2, 2))))


def test_commanded_rates_follow_the_parameter_values_and_equal_casadis_call():
    """The control effort's body rates (buffered per thread and batch size, the parameter values
    folded in) equal a plain CasADi call bit for bit, for batches of 1 and many, and follow
    values changed in place."""
    import casadi as cs

    m = models.get("unicycle", controller="heading", speed=0.2, max_turn=0.3)
    s = m.sym
    fn = cs.Function("r", [s.x, s.target, s.p], [m.body_rates(m.controller(s.x, s.target, s.p),
                                                              s.p)])
    rng = np.random.default_rng(5)
    for n in (1, 1, 9, 400):
        X, T = rng.normal(size=(n, m.nx)) * 3, rng.normal(size=(n, 2)) * 3
        ref = np.asarray(fn.map(n)(X.T, T.T, m.p_value())).reshape(2, n).T
        assert np.array_equal(m.commanded_rates(X, T), ref)
    X, T = np.array([[0.0, 0.0, 0.1]]), np.array([[1.0, 1.0]])
    assert m.commanded_rates(X, T)[0, 0] == 0.2
    m.values["speed"] = 0.5
    assert m.commanded_rates(X, T)[0, 0] == 0.5
    assert models.get("point_mass").commanded_rates(X[:, :2], T) is None


@pytest.mark.parametrize("jit", [None, False])
def test_step_and_rollout_follow_parameter_values_changed_in_place(jit):
    # the compiled cycle folds the parameter values in: a value changed after the first batch
    # must give the cycle of a model built with it (it used to keep the old one, silently)
    X, T = np.array([[0.0, 0.0, 0.3], [1.0, -1.0, 2.0]]), np.array([[2.0, 1.0], [0.0, 0.0]])
    m = models.get("unicycle", jit=jit)
    first = m.step(X, T)
    m.rollout(X, T, 4)
    m.values["k_alpha"] = 2.5
    m.dt = 0.05
    fresh = models.get("unicycle", jit=jit, k_alpha=2.5, dt=0.05)
    assert np.array_equal(m.step(X, T), fresh.step(X, T))
    assert np.array_equal(m.rollout(X, T, 4), fresh.rollout(X, T, 4))
    assert not np.array_equal(m.step(X, T), first)


@pytest.mark.parametrize("jit", [None, False])
@pytest.mark.parametrize("used", [False, True])
@pytest.mark.parametrize("key, value, message", [
    ("k_alpha", "abc", "model unicycle: k_alpha: expected a number, got 'abc'"),
    ("k_alpha", float("nan"), "model unicycle: k_alpha: expected a finite number, got nan"),
    ("controller", "bogus", "model unicycle: controller: expected one of go_to_point, heading, "
                            "got 'bogus'")])
def test_a_bad_value_set_in_place_gets_the_constructors_error(jit, used, key, value, message):
    X, T = np.array([[0.0, 0.0, 0.3]]), np.array([[2.0, 1.0]])
    m = models.get("unicycle", jit=jit)
    if used:
        m.step(X, T)
    (m.values if key in m.values else m.options)[key] = value
    with pytest.raises(HybridnavError, match=re.escape(message)):
        m.step(X, T)
