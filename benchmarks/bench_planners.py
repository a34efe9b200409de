"""Step planners: planning time per step, its share in the compiled rollout, compare throughput.

1. FAStep-Kinematic (``fastep``: 50 fireflies, 30 generations) and ACO-Kinematic (``acor``: archive
   300, sample 10000, 1 generation), paper defaults, seed 0, on fastep-s1..s3 and
   tractor-trailer-1: planning time per planned step (the robots' ``planning_time`` /
   ``planning_calls`` metrics), measured on a second run of each case after an identical warm-up
   run (so JIT compilation of the padded rollout batch sizes is not counted).
2. The share of that time spent in ``Model.rollout`` (the batched feasibility rollout to every
   candidate; timed by wrapping it in this process), in the compiled CasADi call inside it, and in
   the rest of ``feasible_steps`` (the swept-footprint check). What is left is the step fitness,
   the optimizer and the bookkeeping. Rollouts outside planning (re-checking the current move) are
   reported apart.
3. ``hybridnav.analysis.compare.compare`` on both planners x fastep-s1, fastep-s3 x ``--runs`` runs
   with 1 and 2 worker processes, each in a fresh interpreter (cold caches, as the CLI starts):
   runs per second, the speedup, and the CPU seconds used (the processes' own plus the
   pool's; CPU/wall near 2 with 2 workers means both cores were ours -- on a shared machine the
   wall-clock speedup is only as good as the idle cores, so a trivial CPU-bound 2-process job is
   timed next to it as the reference).

It prints, it does not assert. Run: ``python benchmarks/bench_planners.py [--runs 4]
[--scenarios ...] [--skip-compare]``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from collections import defaultdict

PLANNERS = {"fastep-kinematic": "fastep", "aco-kinematic": "acor"}
SCENARIOS = ["fastep-s1", "fastep-s2", "fastep-s3", "tractor-trailer-1"]
COMPARE_SCENARIOS = ["fastep-s1", "fastep-s3"]


class Timers:
    """Wraps Model.rollout, the compiled call and feasible_steps; splits in-plan and other time."""

    def __init__(self) -> None:
        from hybridnav.models import base, compile as compiled
        from hybridnav.planners.step import base as stepping

        self.t: dict[str, float] = defaultdict(float)
        self.rows: dict[str, int] = defaultdict(int)
        self.in_plan = False
        timers = self
        orig_rollout, orig_call = base.Model.rollout, compiled._Buffered.__call__
        orig_feasible = stepping.feasible_steps

        def where() -> str:
            return "plan" if timers.in_plan else "other"

        def rollout(model, X0, targets, steps):
            tic = time.perf_counter()
            try:
                return orig_rollout(model, X0, targets, steps)
            finally:
                timers.t["rollout_" + where()] += time.perf_counter() - tic

        def call(buffered):
            tic = time.perf_counter()
            try:
                return orig_call(buffered)
            finally:
                timers.t["compiled_" + where()] += time.perf_counter() - tic

        def feasible(model, x0, P, *args, **kwargs):
            tic = time.perf_counter()
            try:
                return orig_feasible(model, x0, P, *args, **kwargs)
            finally:
                timers.t["feasible_" + where()] += time.perf_counter() - tic
                # candidates checked (the rollout integrates them in blocks, each a call)
                timers.rows[where()] += len(P)

        base.Model.rollout = rollout
        compiled._Buffered.__call__ = call
        stepping.feasible_steps = feasible   # looked up at call time by the planning closures

    def instrument(self, planner) -> None:
        """Count what happens inside ``planner.optimize`` (most of a planned step) as planning."""
        orig = planner.optimize

        def optimize(*args, **kwargs):
            self.in_plan = True
            try:
                return orig(*args, **kwargs)
            finally:
                self.in_plan = False

        planner.optimize = optimize

    def reset(self) -> None:
        self.t.clear()
        self.rows.clear()


def planning_table(scenarios: list[str]) -> None:
    from hybridnav import models, planners
    from hybridnav.world import load_scenario

    timers = Timers()
    print(f"1+2. planning time per step, seed 0 (JIT available: {models.jit_available()}); "
          f"shares of planning time")
    head = (f"{'planner':<18}{'scenario':<19}{'outcome':<9}{'steps':>6}{'ms/step':>9}"
            f"{'cand/step':>10}{'rollout':>9}{'compiled':>9}{'sweep':>7}{'other':>7}"
            f"{'recheck s':>10}")
    print(head)
    print("-" * len(head))
    for pname in PLANNERS:
        tot_time = tot_calls = 0.0
        tot = defaultdict(float)
        for sname in scenarios:
            scenario = load_scenario(sname)
            tic = time.perf_counter()
            planners.get(pname).run(scenario, seed=0)          # warm-up: JIT-compiles batch sizes
            warm = time.perf_counter() - tic
            planner = planners.get(pname)
            timers.instrument(planner)
            timers.reset()
            result = planner.run(scenario, seed=0)
            pt = sum(r.metrics["planning_time"] for r in result.robots)
            calls = sum(r.metrics["planning_calls"] for r in result.robots)
            outcome = ",".join(sorted({r.outcome for r in result.robots}))
            t = timers.t
            tot_time += pt
            tot_calls += calls
            for k in ("rollout_plan", "compiled_plan", "feasible_plan"):
                tot[k] += t[k]
            tot["rows"] += timers.rows["plan"]
            if calls:
                sweep = t["feasible_plan"] - t["rollout_plan"]
                print(f"{pname:<18}{sname:<19}{outcome:<9}{calls:>6}{1e3 * pt / calls:>9.1f}"
                      f"{timers.rows['plan'] / calls:>10.0f}{t['rollout_plan'] / pt:>9.0%}"
                      f"{t['compiled_plan'] / pt:>9.0%}{sweep / pt:>7.0%}"
                      f"{1 - t['feasible_plan'] / pt:>7.0%}{t['rollout_other']:>10.3f}"
                      f"   (warm-up run {warm:.1f} s)")
            else:
                print(f"{pname:<18}{sname:<19}{outcome:<9}{0:>6}{'-':>9}{'-':>10}{'-':>9}{'-':>9}"
                      f"{'-':>7}{'-':>7}{t['rollout_other']:>10.3f}   (no step planned: the "
                      f"straight line is free)")
        if tot_calls:
            sweep = tot["feasible_plan"] - tot["rollout_plan"]
            print(f"{pname:<18}{'all':<19}{'':<9}{tot_calls:>6.0f}"
                  f"{1e3 * tot_time / tot_calls:>9.1f}{tot['rows'] / tot_calls:>10.0f}"
                  f"{tot['rollout_plan'] / tot_time:>9.0%}{tot['compiled_plan'] / tot_time:>9.0%}"
                  f"{sweep / tot_time:>7.0%}{1 - tot['feasible_plan'] / tot_time:>7.0%}")
        print()
    print("steps: planned steps (planning_calls); cand/step: candidates checked per step; "
          "rollout: Model.rollout\n(compiled: the CasADi call inside it); sweep: swept-footprint "
          "check of feasible_steps; other: fitness,\noptimizer, bookkeeping; recheck s: rollout "
          "seconds outside planning (checking the current move).")


def compare_child(workers: int, runs: int) -> None:
    """Run in a fresh interpreter: time one compare() call, print JSON."""
    import resource

    from hybridnav.analysis.compare import compare

    tic, cpu0 = time.perf_counter(), time.process_time()
    table, _ = compare(list(PLANNERS), COMPARE_SCENARIOS, runs, seed=0, workers=workers)
    seconds = time.perf_counter() - tic
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)       # the pool's processes, reaped
    cpu = time.process_time() - cpu0 + kids.ru_utime + kids.ru_stime
    same = table.drop(columns=["compute_time"]).to_csv(index=False)
    print(json.dumps({"seconds": seconds, "cpu": cpu,
                      "tasks": len(PLANNERS) * len(COMPARE_SCENARIOS) * runs,
                      "table": hashlib.sha256(same.encode()).hexdigest(),
                      "reached": int((table["outcome"] == "reached").sum()), "rows": len(table)}))


def _burn(n: int) -> int:
    s = 0
    for i in range(n):
        s += i * i
    return s


def free_parallelism(n: int = 10_000_000) -> float:
    """Speedup of 2 processes over 1 on pure CPU-bound work: what the machine offers right now."""
    from concurrent.futures import ProcessPoolExecutor

    tic = time.perf_counter()
    _burn(n), _burn(n)
    serial = time.perf_counter() - tic
    with ProcessPoolExecutor(2) as pool:
        list(pool.map(_burn, [1, 1]))                  # start the workers outside the timing
        tic = time.perf_counter()
        list(pool.map(_burn, [n, n]))
        return serial / (time.perf_counter() - tic)


def throughput(runs: int) -> None:
    print(f"\n3. compare(): {' + '.join(PLANNERS)} x {', '.join(COMPARE_SCENARIOS)} x {runs} runs, "
          f"each in a fresh interpreter; {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.2f}")
    out = {}
    for w in (1, 2):
        proc = subprocess.run([sys.executable, __file__, "--compare-child", str(w),
                               "--runs", str(runs)], capture_output=True, text=True, check=True)
        out[w] = json.loads(proc.stdout.strip().splitlines()[-1])
        o = out[w]
        print(f"  workers {w}: {o['tasks']} runs in {o['seconds']:6.1f} s = "
              f"{o['tasks'] / o['seconds']:.2f} runs/s, CPU {o['cpu']:6.1f} s "
              f"(CPU/wall {o['cpu'] / o['seconds']:.2f}; reached {o['reached']}/{o['rows']})")
    print(f"  speedup 2 vs 1 workers: {out[1]['seconds'] / out[2]['seconds']:.2f}x (a trivial "
          f"CPU-bound job gets {free_parallelism():.2f}x on this machine now)\n  run tables "
          f"identical (compute_time aside): {out[1]['table'] == out[2]['table']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="+", default=SCENARIOS)
    ap.add_argument("--runs", type=int, default=4, help="runs per planner x scenario in part 3")
    ap.add_argument("--skip-compare", action="store_true")
    ap.add_argument("--compare-child", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.compare_child:
        compare_child(args.compare_child, args.runs)
        return
    tic = time.perf_counter()
    planning_table(args.scenarios)
    if not args.skip_compare:
        throughput(args.runs)
    print(f"\ntotal {time.perf_counter() - tic:.0f} s")


if __name__ == "__main__":
    main()
