"""
Tuning a fuzzy system on your own data, then exporting it
=========================================================

The tuning core takes any fuzzy system and any cost. Here a two-input system is fitted to
samples of a target function (a data cost, root-mean-square error), judged on samples it did not
see, and exported to C.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hybridnav import fuzzy
from hybridnav.fuzzy.export import to_c
from hybridnav.tuner import GA, DataCost, tune

start = fuzzy.builtin("effc-5rule")
(a, ra), (b, rb) = [(v.name, v.range) for v in start.inputs]
rng = np.random.default_rng(0)


def samples(n):
    X = np.column_stack([rng.uniform(*ra, n), rng.uniform(*rb, n)])
    y = 0.5 + 0.4 * np.tanh(2 * (X[:, 1] - X[:, 0] / 4))
    return X, y


X, y = samples(300)
Xt, yt = samples(300)
cost = DataCost(X, y)                  # columns in the system's input order
result = tune(start, cost, optimizer=GA(population=30, generations=8), seed=0)
tuned = result.system
rmse = lambda s, X, y: float(np.sqrt(np.mean((s.evaluate(**{a: X[:, 0], b: X[:, 1]}) - y) ** 2)))
print(f"held-out RMSE: start {rmse(start, Xt, yt):.3f}, tuned {rmse(tuned, Xt, yt):.3f}")

# %%
# The C export: one header and one source, table-driven, no dependencies but libm.
out = Path(tempfile.mkdtemp())
code = to_c(tuned, "weight")
(out / "weight.h").write_text(code.header)
(out / "weight.c").write_text(code.source)
print(code.header.splitlines()[:12])

# %%
fig, ax = plt.subplots(figsize=(5, 3.5), layout="constrained")
ax.plot(result.logbook["gen"], result.logbook["min"], marker="o")
ax.set_xlabel("generation")
ax.set_ylabel("training RMSE (best)")
ax.xaxis.get_major_locator().set_params(integer=True)
