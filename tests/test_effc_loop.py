"""EFFC closed around the unicycle as CasADi expressions: the planner's field, exactly."""

from __future__ import annotations

import casadi as cs
import numpy as np
import pytest

from hybridnav import fuzzy, models
from hybridnav.analysis import linearize
from hybridnav.errors import HybridnavError
from hybridnav.planners.field.effc import effc_force, effc_inputs_from
from hybridnav.planners.field.effc_loop import effc_closed_loop

GOAL = np.array([4.0, 0.0])
CIRCLE = (2.0, 0.1, 0.5)


@pytest.mark.parametrize("name", ["effc-tuned", "effc-2rule", "effc-5rule"])
def test_the_closed_loop_field_is_the_planners(name):
    uni = models.get("unicycle", controller="heading")
    fis = fuzzy.builtin(name)
    sys = effc_closed_loop(uni, fis, GOAL, CIRCLE)
    x = sys.sym.x
    F = cs.Function("F", [x], [cs.vertcat(sys.parts["w"], sys.parts["dtheta"],
                                          sys.parts["alpha"])])
    rng = np.random.default_rng(3)
    P = rng.uniform([-1, -2], [5, 2], (3000, 2))
    c = np.array(CIRCLE[:2])
    d = np.hypot(*(P - c).T)
    P, d = P[d > CIRCLE[2] + 1e-3], d[d > CIRCLE[2] + 1e-3]
    near = c + CIRCLE[2] * (P - c) / d[:, None]
    dth, al, fa, fr = effc_inputs_from(P, np.tile(GOAL, (len(P), 1)), d - CIRCLE[2], near,
                                       uni.radius)
    w = fis.evaluate(dtheta=dth, alpha=al)
    got = np.asarray(F.map(len(P))(np.c_[P, np.zeros(len(P))].T))
    np.testing.assert_allclose(got, np.vstack([w, dth, al]), atol=1e-12)
    # the closed loop's heading rate turns towards the planner's force direction
    force = effc_force(w, fa, fr)
    rhs = cs.Function("rhs", [x], [sys._rhs])
    th = rng.uniform(-np.pi, np.pi, len(P))
    out = np.asarray(rhs.map(len(P))(np.c_[P, th].T))
    err = np.arctan2(np.sin(np.arctan2(force[:, 1], force[:, 0]) - th),
                     np.cos(np.arctan2(force[:, 1], force[:, 0]) - th))
    expect = np.clip(err, -uni.values["max_turn"], uni.values["max_turn"]) / uni.dt
    np.testing.assert_allclose(out[2], expect, atol=1e-9)


def test_the_loop_is_simulated_and_linearized():
    uni = models.get("unicycle", controller="heading", jit=False)   # (no compile: one robot)
    sys = effc_closed_loop(uni, fuzzy.builtin("effc-tuned"), GOAL, CIRCLE)
    traj = sys.rollout(np.array([[0.0, 0.0, 0.0]]), np.zeros((1, 3)), 800)[0]
    clearance = np.hypot(traj[:, 0] - 2.0, traj[:, 1] - 0.1) - 0.5 - uni.radius
    assert clearance.min() > 0                       # sampled: this start keeps clear
    assert np.hypot(*(traj[:, :2] - GOAL).T).min() < 0.05
    lin = linearize(sys, [0.8, 0.6, 0.1])           # (a smooth point of this system)
    assert lin.A.shape == (3, 3) and np.all(np.isfinite(lin.A))
    with pytest.raises(HybridnavError, match="inputs dtheta and alpha"):
        effc_closed_loop(uni, fuzzy.builtin("steer-7rule"), GOAL, CIRCLE)
