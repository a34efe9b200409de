"""
Running and comparing planners on a scenario
============================================

One EFFC run and one plain potential-field run on the paper's environment (b), drawn with
their outcomes.
"""

import matplotlib.pyplot as plt

from hybridnav import planners
from hybridnav.plotting import plot_result
from hybridnav.world import load_scenario

scenario = load_scenario("effc-env-b")
fig, axes = plt.subplots(1, 2, figsize=(10, 4.5), layout="constrained")
for ax, name in zip(axes, ("effc", "apf")):
    result = planners.get(name).run(scenario)
    robot = result.robots[0]
    print(f"{name}: {robot.outcome}, path {robot.path_length:.2f} m")
    plot_result(scenario, result, ax=ax)
