"""
Stability of a robot model and a pendulum
=========================================

Linearize a model (exact CasADi Jacobians, as a ``control.StateSpace``), check a Lyapunov
function on a region (``"proved"`` only when an interval certificate closes), and estimate a
region of attraction.
"""

import control as ct
import matplotlib.pyplot as plt
import numpy as np

from hybridnav import models
from hybridnav.analysis import (check_lyapunov, estimate_roa, linearize,
                                lyapunov_equation_candidate, summarize)

# %%
# The tractor-trailer linearized about a straight run: controllable.
sys = linearize(models.get("tractor_trailer"), [0, 0, 0, 0], [1.0, 0.0])
print(summarize(sys).controllability_rank)

# %%
# The point mass under its Lyapunov-based controller: V and its derivative are quadratic forms,
# so the check proves it.
report = check_lyapunov(models.get("point_mass"), target=(45, 5),
                        region={"x": (0, 50), "y": (0, 50)})
print(report.status)

# %%
# Any python-control system: a damped pendulum, a quadratic Lyapunov candidate from the
# linearization, and the largest sublevel set of it the check finds decreasing.
pend = ct.nlsys(lambda t, x, u, p: [x[1], -9.81 * np.sin(x[0]) - 0.5 * x[1] + u[0]],
                None, states=["theta", "omega"], inputs=["tau"], name="pendulum")
V, P = lyapunov_equation_candidate(pend, equilibrium=[0, 0])
print(check_lyapunov(pend, V, equilibrium=[0, 0],
                     region={"theta": (-0.3, 0.3), "omega": (-0.3, 0.3)}).status)
roa = estimate_roa(pend, V, equilibrium=[0, 0], region={"theta": (-3, 3), "omega": (-6, 6)})
print(roa.status, f"level {roa.level:.3f}")

# %%
# The level set, drawn with the quadratic form P.
th, om = np.meshgrid(np.linspace(-3, 3, 201), np.linspace(-6, 6, 201))
X = np.stack([th, om], axis=-1)
vals = np.einsum("...i,ij,...j->...", X, np.asarray(P), X)
fig, ax = plt.subplots(figsize=(5, 4), layout="constrained")
cs = ax.contour(th, om, vals, levels=12, cmap="viridis")
fig.colorbar(cs, ax=ax, label="V (quadratic candidate)")
ax.set_xlabel("theta [rad]")
ax.set_ylabel("omega [rad/s]")
ax.set_title("Pendulum: level sets of the Lyapunov candidate")
