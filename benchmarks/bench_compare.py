"""``compare`` with one and with two worker processes: wall time and speed-up, measured in one run.

``hybridnav.analysis.compare.compare`` of ``--planners`` x ``--scenarios`` x ``--runs`` (by
default the four field planners on the EFFC paper's four worlds, 2 runs each: 32 short runs)
with ``workers = 1`` (in this process) and ``workers = 2`` (a local process pool), alternately,
best of ``--repeat``; the tables must be equal (results do not depend on the workers). Each
repeat starts cold (new worker processes; in-process caches of this process cleared is not
possible, so the one-worker figure has the advantage of a warm process after the first repeat).
The machine's load is printed with the figures.

Target (issue 25): ``--workers 2`` >= 1.8x ``--workers 1`` on a quiet two-core machine.

Run: ``python benchmarks/bench_compare.py [--repeat 3] [--runs 2] [--planners apf,effc]
[--scenarios effc-env-a,effc-env-b]``.
"""

from __future__ import annotations

import argparse
import os
import time

import pandas as pd

from hybridnav.analysis.compare import compare


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--planners", default="apf,effc,hapf,fuzzy-steer")
    ap.add_argument("--scenarios", default="effc-env-a,effc-env-b,effc-train-1,effc-train-2")
    args = ap.parse_args()
    planners, scenarios = args.planners.split(","), args.scenarios.split(",")
    compare(planners, scenarios[:1], 1)            # imports, compiled functions on disk
    best = {1: float("inf"), 2: float("inf")}
    tables = {}
    load = os.getloadavg()[0]
    for _ in range(args.repeat):
        for w in (2, 1):
            tic = time.perf_counter()
            tables[w], _ = compare(planners, scenarios, args.runs, workers=w)
            best[w] = min(best[w], time.perf_counter() - tic)
    cols = ["planner", "scenario", "run", "robot", "outcome", "path_length"]
    pd.testing.assert_frame_equal(tables[1][cols], tables[2][cols])
    n = len(tables[1])
    print(f"load {load:.2f} -> {os.getloadavg()[0]:.2f}; compare {len(planners)} planners x "
          f"{len(scenarios)} scenarios x {args.runs} runs ({n} runs): 1 worker {best[1]:.2f} s, "
          f"2 workers {best[2]:.2f} s; speed-up {best[1] / best[2]:.2f}x (target >= 1.8x); "
          "tables equal")


if __name__ == "__main__":
    main()
