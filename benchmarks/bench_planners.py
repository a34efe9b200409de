"""Step planners: planning time per step against the targets, its share in the compiled rollout,
compare throughput.

1. FAStep-Kinematic (``fastep``: 50 fireflies, 30 generations) and ACO-Kinematic (``acor``: archive
   300, sample 10000, 1 generation), paper defaults, seed 0, on fastep-s1..s3 and
   tractor-trailer-1: planning time per planned step (the robots' ``planning_time`` /
   ``planning_calls`` metrics, wall clock; ``cpu``: the process's CPU time in the same calls,
   which a busy machine inflates less), measured on a second run of each case after an identical
   warm-up run (so JIT compilation of the rollout batch sizes is not counted), and its ratio to
   the target of the planner and robot (:data:`TARGETS`, ms per step; below 1 meets it). With
   ``--before REV`` the same table is measured for the commit ``REV`` (its ``hybridnav`` package
   from ``git archive``, in a fresh interpreter) and printed beside it: the speed-up and whether
   the run is the same (the final states of every robot bit for bit, outcome and steps).
2. The share of that time spent in ``Model.rollout`` (the batched feasibility rollout to every
   candidate; timed by wrapping it in this process), in the compiled CasADi call inside it, and in
   the rest of ``feasible_steps`` (the swept-footprint check). What is left is the step fitness,
   the optimizer and the bookkeeping. Rollouts outside planning (re-checking the current move) are
   reported apart.
3. ``hybridnav.experiments.compare.compare`` on both planners x fastep-s1, fastep-s3 x ``--runs`` runs
   with 1 and 2 worker processes, each in a fresh interpreter (cold caches, as the CLI starts):
   runs per second, the speedup, and the CPU seconds used (the processes' own plus the
   pool's; CPU/wall near 2 with 2 workers means both cores were ours -- on a shared machine the
   wall-clock speedup is only as good as the idle cores, so a trivial CPU-bound 2-process job is
   timed next to it as the reference).

It prints, it does not assert. It imports the ``hybridnav`` of the tree it is in. Run:
``python benchmarks/bench_planners.py [--runs 4] [--scenarios ...] [--skip-compare]
[--before REV]``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from _reference import burn  # this folder: the reference job every parallel benchmark times

PLANNERS = {"fastep-kinematic": "fastep", "aco-kinematic": "acor"}
SCENARIOS = ["fastep-s1", "fastep-s2", "fastep-s3", "tractor-trailer-1"]
COMPARE_SCENARIOS = ["fastep-s1", "fastep-s3"]
#: ms per planned step to reach, per planner and robot model
TARGETS = {("fastep-kinematic", "point_mass"): 30.0, ("fastep-kinematic", "tractor_trailer"): 100.0,
           ("aco-kinematic", "point_mass"): 100.0, ("aco-kinematic", "tractor_trailer"): 500.0}
ROOT = Path(__file__).resolve().parents[1]


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

        def rollout(model, X0, targets, steps, **kwargs):
            tic = time.perf_counter()
            try:
                return orig_rollout(model, X0, targets, steps, **kwargs)
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
        """Count what happens inside ``planner.optimize`` (most of a planned step) as planning
        (and its CPU time)."""
        orig = planner.optimize

        def optimize(*args, **kwargs):
            self.in_plan = True
            cpu = time.process_time()
            try:
                return orig(*args, **kwargs)
            finally:
                self.in_plan = False
                self.t["cpu_plan"] += time.process_time() - cpu

        planner.optimize = optimize

    def reset(self) -> None:
        self.t.clear()
        self.rows.clear()


def measure_table(scenarios: list[str]) -> list[dict]:
    """Part 1 and 2 for every planner x scenario: one row each."""
    from hybridnav import planners
    from hybridnav.world import load_scenario

    timers = Timers()
    rows = []
    for pname in PLANNERS:
        for sname in scenarios:
            scenario = load_scenario(sname)
            tic = time.perf_counter()
            planners.get(pname).run(scenario, seed=0)          # warm-up: JIT-compiles batch sizes
            warm = time.perf_counter() - tic
            planner = planners.get(pname)
            timers.instrument(planner)
            timers.reset()
            result = planner.run(scenario, seed=0)
            final = hashlib.sha256(b"".join(r.states.tobytes() for r in result.robots))
            rows.append({
                "planner": pname, "scenario": sname,
                "model": ",".join(sorted({r.model for r in scenario.robots})),
                "outcome": ",".join(sorted({r.outcome for r in result.robots})),
                "steps": sum(r.metrics["planning_calls"] for r in result.robots),
                "seconds": sum(r.metrics["planning_time"] for r in result.robots),
                "cpu": timers.t["cpu_plan"], "rows": timers.rows["plan"], "warm": warm,
                "run": f"{final.hexdigest()[:12]} {[r.outcome for r in result.robots]} "
                       f"{[len(r.states) for r in result.robots]}",
                **{k: timers.t[k] for k in ("rollout_plan", "compiled_plan", "feasible_plan",
                                            "rollout_other")}})
    return rows


def planning_table(scenarios: list[str], before: str | None) -> None:
    from hybridnav import models

    old = None
    if before:
        old = {(r["planner"], r["scenario"]): r for r in table_at(before, scenarios)}
    rows = measure_table(scenarios)
    print(f"1+2. planning time per step, seed 0 (JIT available: {models.jit_available()}); "
          f"shares of planning time; load average {os.getloadavg()[0]:.2f}")
    head = (f"{'planner':<18}{'scenario':<19}{'outcome':<9}{'steps':>6}{'ms/step':>9}"
            f"{'cpu ms':>8}{'target':>8}{'ratio':>7}{'cand/step':>10}{'rollout':>9}"
            f"{'compiled':>9}{'sweep':>7}{'other':>7}{'recheck s':>10}")
    if old:
        head += f"  | {'before ms/step':>14}{'speed-up':>9}  same run"
    print(head)
    print("-" * len(head))
    for pname in PLANNERS:
        tot = defaultdict(float)
        for r in (r for r in rows if r["planner"] == pname):
            target = TARGETS.get((pname, r["model"]))
            line = f"{pname:<18}{r['scenario']:<19}{r['outcome']:<9}{r['steps']:>6}"
            if r["steps"]:
                pt, n = r["seconds"], r["steps"]
                for k in ("seconds", "cpu", "steps", "rows", "rollout_plan", "compiled_plan",
                          "feasible_plan"):
                    tot[k] += r[k]
                ms = 1e3 * pt / n
                line += (f"{ms:>9.1f}{1e3 * r['cpu'] / n:>8.1f}"
                         f"{target if target else float('nan'):>8.0f}"
                         f"{ms / target if target else float('nan'):>7.2f}{r['rows'] / n:>10.0f}"
                         f"{r['rollout_plan'] / pt:>9.0%}{r['compiled_plan'] / pt:>9.0%}"
                         f"{(r['feasible_plan'] - r['rollout_plan']) / pt:>7.0%}"
                         f"{1 - r['feasible_plan'] / pt:>7.0%}{r['rollout_other']:>10.3f}")
            else:
                line += (f"{'-':>9}{'-':>8}{target or float('nan'):>8.0f}{'-':>7}{'-':>10}"
                         f"{'-':>9}{'-':>9}{'-':>7}{'-':>7}{r['rollout_other']:>10.3f}")
            if old:
                o = old.get((pname, r["scenario"]))
                if o and o["steps"] and r["steps"]:
                    before_ms = 1e3 * o["seconds"] / o["steps"]
                    line += (f"  | {before_ms:>14.1f}"
                             f"{before_ms / (1e3 * r['seconds'] / r['steps']):>8.1f}x")
                else:
                    line += f"  | {'-':>14}{'-':>9}"
                line += f"  {'yes' if o and o['run'] == r['run'] else 'NO'}"
            if not r["steps"]:
                line += "   (no step planned: the straight line is free)"
            print(line)
        if tot["steps"]:
            pt, n = tot["seconds"], tot["steps"]
            print(f"{pname:<18}{'all':<19}{'':<9}{n:>6.0f}{1e3 * pt / n:>9.1f}"
                  f"{1e3 * tot['cpu'] / n:>8.1f}{'':>8}{'':>7}{tot['rows'] / n:>10.0f}"
                  f"{tot['rollout_plan'] / pt:>9.0%}{tot['compiled_plan'] / pt:>9.0%}"
                  f"{(tot['feasible_plan'] - tot['rollout_plan']) / pt:>7.0%}"
                  f"{1 - tot['feasible_plan'] / pt:>7.0%}")
        print()
    print("steps: planned steps (planning_calls); ms/step: wall clock, cpu ms: CPU time; target: "
          "ms/step to reach,\nratio: ms/step / target; cand/step: candidates checked per step; "
          "rollout: Model.rollout (compiled:\nthe CasADi call inside it); sweep: swept-footprint "
          "check of feasible_steps; other: fitness, optimizer,\nbookkeeping; recheck s: rollout "
          "seconds outside planning (checking the current move)" +
          (f"; before: commit {before},\nsame run: every robot's states bit for bit, outcome and "
           "number of states." if old else "."))


def table_at(rev: str, scenarios: list[str]) -> list[dict]:
    """:func:`measure_table` for the ``hybridnav`` package of commit ``rev``, in a fresh
    interpreter."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_before_"))
    try:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "hybridnav"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
        proc = subprocess.run([sys.executable, __file__, "--table-json", "--root", str(tmp),
                               "--scenarios", *scenarios], capture_output=True, text=True,
                              cwd=tempfile.gettempdir())
        if proc.returncode:
            raise SystemExit(f"the table failed at {rev}:\n{proc.stderr[-3000:]}")
        return json.loads(proc.stdout.strip().splitlines()[-1])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def compare_child(workers: int, runs: int) -> None:
    """Run in a fresh interpreter: time one compare() call, print JSON."""
    import resource

    from hybridnav.experiments.compare import compare

    tic, cpu0 = time.perf_counter(), time.process_time()
    from hybridnav.backends import close_shared

    table, _ = compare(list(PLANNERS), COMPARE_SCENARIOS, runs, seed=0, workers=workers)
    seconds = time.perf_counter() - tic
    close_shared()                        # compare keeps its pool: reap it to count its CPU
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)       # the pool's processes, reaped
    cpu = time.process_time() - cpu0 + kids.ru_utime + kids.ru_stime
    same = table.drop(columns=["compute_time"]).to_csv(index=False)
    print(json.dumps({"seconds": seconds, "cpu": cpu,
                      "tasks": len(PLANNERS) * len(COMPARE_SCENARIOS) * runs,
                      "table": hashlib.sha256(same.encode()).hexdigest(),
                      "reached": int((table["outcome"] == "reached").sum()), "rows": len(table)}))



def free_parallelism(n: int = 10_000_000) -> float:
    """Speedup of 2 processes over 1 on pure CPU-bound work: what the machine offers right now."""
    from concurrent.futures import ProcessPoolExecutor

    tic = time.perf_counter()
    burn(n), burn(n)
    serial = time.perf_counter() - tic
    with ProcessPoolExecutor(2) as pool:
        list(pool.map(burn, [1, 1]))                  # start the workers outside the timing
        tic = time.perf_counter()
        list(pool.map(burn, [n, n]))
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
    ap.add_argument("--before", help="a git revision whose planning times to print beside")
    ap.add_argument("--compare-child", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--table-json", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--root", default=str(ROOT), help=argparse.SUPPRESS)
    args = ap.parse_args()
    sys.path.insert(0, args.root)           # this tree's hybridnav, not an installed one
    if args.compare_child:
        compare_child(args.compare_child, args.runs)
        return
    if args.table_json:
        print(json.dumps(measure_table(args.scenarios)))
        return
    tic = time.perf_counter()
    print(f"uptime: {subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}")
    planning_table(args.scenarios, args.before)
    if not args.skip_compare:
        throughput(args.runs)
    print(f"\ntotal {time.perf_counter() - tic:.0f} s; uptime: "
          f"{subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}")


if __name__ == "__main__":
    main()
