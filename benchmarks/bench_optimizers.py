"""GA vs CMA-ES vs PSO vs NSGA-II at an equal evaluation budget, and the workers' start-up cost.

Two problems, each optimizer with its default settings except the population (the budget is
the same number of training evaluations for all, ``tune(max_evals=...)``):

* **navigation**: the built-in EFFC job's starting system, free settings, training worlds
  (2 paper + 30 generated) and validation worlds (24 generated); the deploy reward; scored by
  the returned system's validation reward (lower is better) and its test-set success;
* **data**: ``effc-5rule`` with every MF parameter perturbed by up to 8 % of its range, tuned to
  500 samples of the unperturbed system; scored by the RMSE on 2,000 held-out samples (as a
  fraction of the output range).

NSGA-II runs on the single objective here (it then reduces to an elitist GA with crowding); its
several-objective use is in the README. Prints wall time and evaluations per second of each
run, measured in one run on this machine (ratios, not absolute times, are what to compare), and
the start-up cost of a worker: the old design rebuilt the job from its JSON text in every worker
(validating it and generating all its worlds, the test set included); the new one unpickles the
cost object it is sent.

Run: ``python benchmarks/bench_optimizers.py [--budget-nav 800] [--budget-data 3000]``.
"""

from __future__ import annotations

import argparse
import os
import pickle
import subprocess
import sys
import time

import numpy as np

from hybridnav import fuzzy
from hybridnav.tuner import CMAES, GA, NSGA2, PSO, DataCost, tune
from hybridnav.tuner.heldout import summarize
from hybridnav.tuner.job import load_job


def optimizers():
    return {"GA": GA(population=40, generations=10_000),
            "CMA-ES": CMAES(generations=10_000),
            "PSO": PSO(n=30, generations=10_000),
            "NSGA-II": NSGA2(population=40, generations=10_000)}


def navigation(budget: int) -> None:
    job = load_job(None)
    start, train = job.start_system(), job.cost("train")
    val, test = job.cost("validation"), job.cost("test")
    print(f"\nnavigation: {len(train.scenarios)} training worlds, {len(val.scenarios)} validation, "
          f"{len(test.scenarios)} test; budget {budget} training evaluations")
    print(f"{'optimizer':10s} {'evals':>6s} {'wall s':>7s} {'evals/s':>8s} {'val reward':>11s} "
          f"{'test reached':>13s} {'test collided':>14s}")
    for name, opt in optimizers().items():
        tic = time.perf_counter()
        res = tune(start, train, settings=job.tunable(), optimizer=opt, validation=val,
                   test=test, seed=0, max_evals=budget, patience=0)
        wall = time.perf_counter() - tic
        s = summarize(res.heldout[res.heldout.set == "test"]).set_index("system")
        print(f"{name:10s} {res.evaluations:6d} {res.wall_time:7.1f} "
              f"{res.evaluations / res.wall_time:8.1f} {res.validation_score:11.4f} "
              f"{int(s.loc['tuned', 'reached']):>6d}/{int(s.loc['tuned', 'worlds']):<6d} "
              f"{int(s.loc['tuned', 'collided']):>14d}   (with judging {wall:.1f} s)")
    s = summarize(res.heldout[res.heldout.set == "test"]).set_index("system")
    print(f"{'start':10s} {'':6s} {'':7s} {'':8s} {res.start_validation_score:11.4f} "
          f"{int(s.loc['start', 'reached']):>6d}/{int(s.loc['start', 'worlds']):<6d} "
          f"{int(s.loc['start', 'collided']):>14d}")


def data(budget: int) -> None:
    target = fuzzy.builtin("effc-5rule")
    rng = np.random.default_rng(1)
    d = target.to_dict()
    for v in d["inputs"] + [d["output"]]:
        w = v["range"][1] - v["range"][0]
        for t in v["terms"]:
            t["params"] = sorted((np.array(t["params"]) + rng.uniform(-0.08, 0.08, 2) * w)
                                 .tolist())
    start = fuzzy.FuzzySystem.from_dict(d)

    def samples(n, seed):
        r = np.random.default_rng(seed)
        X = r.uniform([0, 0], [np.pi / 2, 2], (n, 2))
        return X, target.evaluate(dtheta=X[:, 0], alpha=X[:, 1])

    X, y = samples(500, 2)
    Xt, yt = samples(2000, 3)
    test = DataCost(Xt, yt)
    print(f"\ndata: 500 samples (20 % for validation), 2,000 held out; budget {budget} "
          "training evaluations")
    print(f"{'optimizer':10s} {'evals':>6s} {'wall s':>7s} {'evals/s':>8s} "
          f"{'held-out RMSE':>14s} {'(start)':>8s}")
    for name, opt in optimizers().items():
        res = tune(start, DataCost(X, y), optimizer=opt, validation=0.2, test=test, seed=0,
                   max_evals=budget, patience=0)
        h = res.heldout[res.heldout.set == "test"].set_index("system")
        print(f"{name:10s} {res.evaluations:6d} {res.wall_time:7.2f} "
              f"{res.evaluations / res.wall_time:8.0f} {h.loc['tuned', 'objective_0']:14.5f} "
              f"{h.loc['start', 'objective_0']:8.4f}")


OLD_WORKER = """
import json, time
tic = time.perf_counter()
from hybridnav.tuner.job import load_job, validate_job
from pathlib import Path
job = load_job(None)
raw = json.loads(json.dumps({"data": job.data, "source": None, "base": "."}))
t0 = time.perf_counter()
job = validate_job(raw["data"], raw["source"], Path(raw["base"]))     # what every worker did
for k in ("train", "validation", "test"):
    job.scenarios(k)
print(time.perf_counter() - t0)
"""

NEW_WORKER = """
import pickle, sys, time
data = open(sys.argv[1], "rb").read()
import hybridnav.tuner
t0 = time.perf_counter()
cost = pickle.loads(data)                                            # what a worker does now
cost.packed
print(time.perf_counter() - t0)
"""


def startup(repeats: int = 3) -> None:
    job = load_job(None)
    path = "/tmp/hybridnav_bench_cost.pkl"
    with open(path, "wb") as fh:
        pickle.dump(job.cost("train"), fh)
    size = os.path.getsize(path)

    def best(code, *args):
        return min(float(subprocess.run([sys.executable, "-c", code, *args], check=True,
                                        capture_output=True, text=True).stdout)
                   for _ in range(repeats))

    old, new = best(OLD_WORKER), best(NEW_WORKER, path)
    print(f"\nworker start-up (best of {repeats}, after imports): old design (rebuild the job "
          f"from JSON, generate every set) {old:.3f} s; new (unpickle the {size / 1024:.0f} KiB "
          f"cost, pack its worlds) {new:.4f} s: {old / new:.0f}x less")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget-nav", type=int, default=800)
    ap.add_argument("--budget-data", type=int, default=3000)
    ap.add_argument("--skip-navigation", action="store_true")
    a = ap.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} (1 min), {os.cpu_count()} cores")
    startup()
    data(a.budget_data)
    if not a.skip_navigation:
        navigation(a.budget_nav)


if __name__ == "__main__":
    main()
