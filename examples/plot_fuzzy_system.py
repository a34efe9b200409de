"""
A Mamdani fuzzy system: memberships and its output surface
==========================================================

The EFFC paper's force-weight system (scikit-fuzzy's semantics), its membership functions and
the output over both inputs.
"""

import matplotlib.pyplot as plt
import numpy as np

from hybridnav import fuzzy
from hybridnav.fuzzy import plots

fis = fuzzy.builtin("effc-5rule")
for i, rule in enumerate(fis.rules):
    print(f"rule {i}: {rule.sentence(fis.output.name)}")

# %%
# The membership functions of every input and the output.
fig = plt.figure(figsize=(8, 6), layout="constrained")
plots.plot_memberships(fis, fig=fig)

# %%
# The output on a grid of both inputs, evaluated in one batched call.
(a_name, a_rng), (b_name, b_rng) = [(v.name, v.range) for v in fis.inputs]
A, B = np.meshgrid(np.linspace(*a_rng, 121), np.linspace(*b_rng, 121))
W = fis.evaluate(**{a_name: A.ravel(), b_name: B.ravel()}).reshape(A.shape)
fig, ax = plt.subplots(figsize=(5.5, 4), layout="constrained")
im = ax.pcolormesh(A, B, W, shading="auto", cmap="viridis")
ax.contour(A, B, W, levels=8, colors="white", linewidths=0.6)
fig.colorbar(im, ax=ax, label=fis.output.name)
ax.set_xlabel(a_name)
ax.set_ylabel(b_name)
