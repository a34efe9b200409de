"""The robot control cycle of the tuner's lockstep loop: compiled (one C call per run) vs NumPy.

The built-in job's training cost (its 32 training worlds, ``effc-5rule``'s shape) simulates a
chunk of candidates — a training chunk of 50 random genomes and a validation-sized batch of 3 —
once with the compiled control cycle (:mod:`hybridnav.native`) and once with the NumPy cycle
(``HYBRIDNAV_NATIVE=0``), in this one process, best of ``--repeat``. A robot-cycle is one robot
in one control cycle while it runs (counted from each run's end time), so early collisions do not
flatter either path. Also printed: how many of the runs end the same way in both (rounding
differences can grow through a closed loop) and the machine's load.

Target (issue 25): <= 0.3 us per robot-cycle.

Run: ``python benchmarks/bench_lockstep.py [--repeat 3] [--chunk 50]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from hybridnav.native.lockstep import available
from hybridnav.tuner.costs.base import Candidates
from hybridnav.tuner.job import load_job


def run(cost, cands, keys, native: bool, repeat: int):
    os.environ["HYBRIDNAV_NATIVE"] = "1" if native else "0"
    best, res = np.inf, None
    for _ in range(repeat):
        tic = time.perf_counter()
        res, _ = cost.simulate(cands.family, cands.tables, keys, seed=0)
        best = min(best, time.perf_counter() - tic)
    return best, res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--chunk", type=int, default=50)
    args = ap.parse_args()
    if not available():
        raise SystemExit("no C compiler here: the compiled control cycle is unavailable")
    job = load_job(None)
    cost, space = job.cost("train"), job.tunable()
    dt = cost.scenarios[0].dt
    print(f"load {os.getloadavg()[0]:.2f}; {len(cost.scenarios)} training worlds, dt {dt} s")
    for label, n in (("training chunk", args.chunk), ("validation batch", 3)):
        X = np.vstack([space.to_vector()[None],
                       space.random(n - 1, np.random.default_rng(1))])
        cands = Candidates(space, X)
        keys = [(1, i) for i in range(n)]
        run(cost, cands, keys, True, 1)                      # build / load the library
        t_c, r_c = run(cost, cands, keys, True, args.repeat)
        t_n, r_n = run(cost, cands, keys, False, args.repeat)
        cycles = float(np.sum(np.round(r_n.time / dt)))
        same = float(np.mean(r_c.outcome == r_n.outcome))
        print(f"{label} ({n} candidates x {len(cost.scenarios)} worlds, {cycles:.0f} "
              f"robot-cycles): compiled {t_c / cycles * 1e6:.3f} us, NumPy "
              f"{t_n / cycles * 1e6:.3f} us per robot-cycle; speed-up {t_n / t_c:.1f}x; "
              f"same outcome {same:.1%} of runs   (target <= 0.3 us)")
    os.environ.pop("HYBRIDNAV_NATIVE", None)


if __name__ == "__main__":
    main()
