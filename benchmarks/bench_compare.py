"""``compare`` with one and with two worker processes: wall time and speed-up, measured in one run.

``hybridnav.experiments.compare.compare`` of ``--planners`` x ``--scenarios`` x ``--runs`` (by
default the four field planners on the EFFC paper's four worlds, 2 runs each: 32 short runs)
with ``workers = 1`` (in this process) and ``workers = 2`` (the local process pool ``compare``
keeps for the life of the process, as ``reproduce`` uses it: the first repeat starts it),
alternately, best of ``--repeat``; the tables must be equal (results do not depend on the workers). Next to
it, in the same repeats and timed the same way (best of, interleaved), a trivially parallel
reference job: two equal pure-Python CPU loops in this process and on two worker processes. On a
shared machine the reference ratio is what two workers can get right now; ``compare``'s ratio is
to be read against it. ``uptime`` is printed before and after.

Target (issue 25): ``--workers 2`` >= 1.8x ``--workers 1`` on a quiet two-core machine.

Run: ``PYTHONPATH=$PWD python benchmarks/bench_compare.py [--repeat 3] [--runs 2]
[--planners apf,effc] [--scenarios effc-env-a,effc-env-b]`` (``PYTHONPATH``: this tree's package,
not an installed one).
"""

from __future__ import annotations

import argparse
import os
import time
from concurrent.futures import ProcessPoolExecutor

import pandas as pd

from hybridnav.experiments.compare import compare

from _reference import burn, uptime  # this folder: the reference job every parallel benchmark times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--planners", default="apf,effc,hapf,fuzzy-steer")
    ap.add_argument("--scenarios", default="effc-env-a,effc-env-b,effc-train-1,effc-train-2")
    ap.add_argument("--burn", type=int, default=15_000_000,
                    help="loop length of the trivially parallel reference (per process)")
    args = ap.parse_args()
    print(f"uptime: {uptime()}")
    planners, scenarios = args.planners.split(","), args.scenarios.split(",")
    compare(planners, scenarios[:1], 1)            # imports, compiled functions on disk
    best = {1: float("inf"), 2: float("inf")}
    tables = {}
    load = os.getloadavg()[0]
    ref = {1: float("inf"), 2: float("inf")}
    pool = ProcessPoolExecutor(2)
    list(pool.map(burn, [1, 1]))                      # the reference's workers, started
    for _ in range(args.repeat):
        for w in (2, 1):
            tic = time.perf_counter()
            tables[w], _ = compare(planners, scenarios, args.runs, workers=w)
            best[w] = min(best[w], time.perf_counter() - tic)
            tic = time.perf_counter()
            if w == 1:
                burn(args.burn), burn(args.burn)
            else:
                list(pool.map(burn, [args.burn, args.burn]))
            ref[w] = min(ref[w], time.perf_counter() - tic)
    pool.shutdown()
    cols = ["planner", "scenario", "run", "robot", "outcome", "path_length"]
    pd.testing.assert_frame_equal(tables[1][cols], tables[2][cols])
    n = len(tables[1])
    print(f"load {load:.2f} -> {os.getloadavg()[0]:.2f}; compare {len(planners)} planners x "
          f"{len(scenarios)} scenarios x {args.runs} runs ({n} runs): 1 worker {best[1]:.2f} s, "
          f"2 workers {best[2]:.2f} s; speed-up {best[1] / best[2]:.2f}x (target >= 1.8x); "
          "tables equal")
    print(f"reference (2 equal CPU loops, same repeats): 1 process {ref[1]:.2f} s, 2 processes "
          f"{ref[2]:.2f} s; speed-up {ref[1] / ref[2]:.2f}x (what 2 workers can get now)")
    print(f"uptime: {uptime()}")


if __name__ == "__main__":
    main()
