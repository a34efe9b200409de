"""Does the main job's tuned controller generalize? The built-in job, judged on worlds it never saw.

Runs the README's main job (``hybridnav tune --workers N``, built-in defaults) into a temporary
folder and prints, from its ``heldout_summary.csv``, start (``effc-5rule``) vs tuned vs ``apf``
on the validation set and on the test set (the paper's ``effc-env-a``/``effc-env-b`` and 30
generated worlds whose seed differs from the training and validation seeds): worlds reached with
a 95 % interval, collisions, other failures, mean length and clearance on the worlds all three
reached, and the smallest clearance on the worlds each reached — then the acceptance checks one
by one, the falsification finds, and the job's wall time with the machine's load.

Run: ``python benchmarks/bench_generalization.py [--workers 2] [--seed 0] [--keep DIR]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import pandas as pd

from hybridnav.tuner.heldout import verdict
from hybridnav.tuner.job import load_job
from hybridnav.tuner.run import run_job


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--keep", metavar="DIR", help="keep the job's outputs here")
    args = ap.parse_args()
    job = load_job(None).with_seed(args.seed).with_backend(workers=args.workers)
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp()) / "tuned"
    load0 = os.getloadavg()[0]
    tic = time.perf_counter()
    result = run_job(job, out)
    wall = time.perf_counter() - tic
    summary = pd.read_csv(out / "heldout_summary.csv")
    radius = job.scenarios("train")[0].robots[0].radius
    n = {k: len(job.scenarios(k)) for k in ("train", "validation", "test")}
    print(f"built-in job, seed {job.seed}: {n['train']} training, {n['validation']} validation, "
          f"{n['test']} test worlds; returned system from generation {result.best_generation} "
          f"(chosen on {result.selected_by})")
    cols = ["set", "system", "reached", "worlds", "ci_low", "ci_high", "collided", "stuck",
            "timeout", "out_of_bounds", "common_worlds", "common_length", "common_clearance",
            "min_clearance_reached"]
    print(summary[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    for which in ("validation", "test"):
        v = verdict(summary, which, radius)
        print(f"\n{which}: tuned is {'better' if v['better'] else 'NOT better'} than its start")
        for text, ok in v["checks"]:
            print(f"  {'pass' if ok else 'FAIL'}: {text}")
        s = summary[summary.set == which].set_index("system")
        ratio = s.loc["tuned", "common_length"] / s.loc["start", "common_length"]
        print(f"  length ratio tuned / start on common worlds: {ratio:.3f}")
    fpath = out / "falsified.csv"
    if fpath.exists():
        f = pd.read_csv(fpath)
        print(f"\nfalsification: {len(f)} failure worlds kept")
        print(f.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    else:
        print("\nfalsification: no failure found within the budget")
    load1 = os.getloadavg()[0]
    print(f"\nwall time of the whole job (tuning, held-out runs, falsification, plots, exports): "
          f"{wall:.1f} s on {args.workers} workers; tuning alone "
          f"{result.wall_time:.1f} s; load average {load0:.2f} -> {load1:.2f}")
    if not args.keep:
        shutil.rmtree(out.parent, ignore_errors=True)


if __name__ == "__main__":
    main()
