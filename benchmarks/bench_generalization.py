"""Does the main job's tuned controller generalize, and can it be deployed? The built-in job,
judged on worlds it never saw.

Runs the README's main job (``hybridnav tune --workers N``, built-in defaults) into a temporary
folder and prints, from its ``heldout_summary.csv``, start (``effc-5rule``) vs tuned vs plain
``apf`` on the validation set and on the test set (the paper's ``effc-env-a``/``effc-env-b``, 30
generated worlds and 8 with trap structures, of seeds no other set uses): worlds reached with a
95 % interval, collisions, other failures, mean length and clearance on the worlds all three
reached, and the smallest clearance on the worlds each reached; then the job's deployment
verdicts (safety first, falsification included) check by check, the falsification table of
start, tuned and apf (the same budget and seed), and the job's wall time with the machine's
load. Last, the returned system on further worlds no set of the job uses (``--fresh`` generated
and ``--fresh-traps`` trap worlds of seed 2027), with the job's safety filter, against its start
and plain ``apf``: the acceptance figures of the deployable-controller issue.

Run: ``python benchmarks/bench_generalization.py [--workers 2] [--seed 0] [--keep DIR]
[--fresh 40] [--fresh-traps 16]``.
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


def fresh(job, result, count: int, traps: int) -> None:
    """The returned system on worlds no set of the job uses, with the job's planner settings."""
    from hybridnav.tuner.heldout import run_systems, summarize
    from hybridnav.tuner.job import TRAPS
    from hybridnav.world.generator import WorldGenerator

    seed = 2027
    kinds = {k: tuple(v) if isinstance(v, list) else v for k, v in TRAPS.items()}
    worlds = WorldGenerator().generate(count, seed) + (
        WorldGenerator(**kinds).generate(traps, seed) if traps else [])
    pl = dict(job["planner"])
    table = run_systems({"start": result.start, "tuned": result.system}, worlds,
                        speed=pl["speed"], max_turn=pl["max_turn"],
                        stuck_window=pl["stuck_window"], stuck_radius=pl["stuck_radius"],
                        safety_margin=pl["safety_margin"])
    s = summarize(table)
    print(f"\nfurther worlds no set uses ({count} generated + {traps} trap, seed {seed}; safety "
          f"margin {pl['safety_margin']:g} for start and tuned, plain apf):")
    print(s[["system", "reached", "worlds", "collided", "out_of_bounds", "stuck", "timeout",
             "common_length", "common_min_clearance", "min_clearance_reached"]].to_string(
        index=False, float_format=lambda v: f"{v:.3f}"))
    v = verdict(s, "test", float(worlds[0].robots[0].radius), table=table)
    print(f"  verdict: {v['headline']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--keep", metavar="DIR", help="keep the job's outputs here")
    ap.add_argument("--fresh", type=int, default=40, help="further generated worlds")
    ap.add_argument("--fresh-traps", type=int, default=16, help="further trap worlds")
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
    held = pd.read_csv(out / "heldout.csv")
    t = held[(held.set == "test") & ~held.scenario.str.startswith("trap")]
    ok = t[t.outcome == "reached"].groupby("system").size().to_dict()
    print(f"test worlds without trap structures ({t.scenario.nunique()}): reached {ok}")
    for which in ("validation", "test"):
        v = result.verdicts.get(which)
        if not v:
            continue
        print(f"\n{which}: {v['headline']}")
        for text, passed in v["checks"]:
            print(f"  {'pass' if passed else 'FAIL'}: {text}")
    fpath = out / "falsification.csv"
    if fpath.exists():
        f = pd.read_csv(fpath)
        print("\nfalsification (the same budget and seed for each system):")
        print(f[["system", "tried", "valid", "failures", "failures_rate", "collisions",
                 "collisions_rate", "collisions_ci_high"]].to_string(
            index=False, float_format=lambda v: f"{v:.3f}"))
    else:
        print("\nfalsification: off")
    fresh(job, result, args.fresh, args.fresh_traps)
    load1 = os.getloadavg()[0]
    print(f"\nwall time of the whole job (tuning, held-out runs, falsification, plots, exports): "
          f"{wall:.1f} s on {args.workers} workers; tuning alone "
          f"{result.wall_time:.1f} s; load average {load0:.2f} -> {load1:.2f}")
    if not args.keep:
        shutil.rmtree(out.parent, ignore_errors=True)


if __name__ == "__main__":
    main()
