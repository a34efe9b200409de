"""Tuning speed: the paper-scale job's wall time, and the lockstep reward vs the straightforward one.

1. The GA of the built-in EFFC job (population 100, 25 generations, the paper's 2 training
   environments plus 30 generated worlds, validation on 24 more, early stopping) on this machine
   with ``--workers`` local processes (default 2) and with one, in this one run (best of
   ``--repeat`` interleaved runs each: this shared machine's load swings): wall times,
   their ratio and whether both return the same system. Next to it, in the same interleaved
   repeats and timed the same way, a trivially parallel reference (two equal pure-Python CPU
   loops in one process and on two): on a shared machine its ratio is what two workers can get
   at that moment; ``uptime`` is printed before and after. Targets (issue 25): <= 20 s on two
   workers, >= 1.8x one worker (``bench_generalization.py`` times the whole job: <= 45 s).
2. The paper's reward (length if reached, else the penalty; ``reward.kind = "length"``, no
   coverage penalty, no safety filter) on the paper's two environments computed the
   straightforward way — a
   scikit-fuzzy ``ControlSystemSimulation`` per individual, one robot stepped at a time — on a
   reduced job, against the lockstep chunk evaluation of the same genomes: seconds per
   (individual, environment) evaluation and their ratio. Target: >= 100x. The two rewards are
   also compared (they must agree).

Run: ``PYTHONPATH=$PWD python benchmarks/bench_tuning.py [--workers 2] [--repeat 2] [--reduced 6]
[--skip-full] [--skip-reward]`` (``PYTHONPATH``: this tree's package, not an installed one).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time

import numpy as np

from hybridnav.backends import make_backend
from hybridnav.planners.field.effc import effc_force, effc_inputs
from hybridnav.tuner import tune
from hybridnav.tuner.costs.base import Context, evaluate_chunk
from hybridnav.tuner.job import load_job, validate_job

from _reference import burn, uptime  # this folder: the reference job every parallel benchmark times


def straightforward_reward(job, system, scenarios) -> float:
    """One ControlSystemSimulation, one robot at a time, one step at a time."""
    from skfuzzy import control as ctrl

    sim = ctrl.ControlSystemSimulation(system.to_skfuzzy(), cache=False)
    pl, rw = job["planner"], job["reward"]
    total = 0.0
    for s in scenarios:
        r = s.robots[0]
        m = s.model(r, controller="heading", speed=pl["speed"], max_turn=pl["max_turn"])
        x = m.initial_state(r.start, r.goal, r.initial)
        goal = np.asarray(r.goal, dtype=float)
        length, outcome = 0.0, "timeout"
        V = np.zeros(2)
        hist = [x[:2].copy()]
        window = int(round(pl["stuck_window"] / s.dt))
        for k in range(int(math.ceil(s.max_time / s.dt))):
            t = k * s.dt
            d, a, fa, fr = effc_inputs(s.world, x[None, :2], goal[None], m.radius, t)
            sim.input["dtheta"], sim.input["alpha"] = float(d[0]), float(a[0])
            try:
                sim.compute()
                w = sim.output.get("w", system.output.default)
            except Exception:           # scikit-fuzzy raises where no rule fires
                w = system.output.default
            F = effc_force(np.array([w]), fa, fr)[0]
            if np.hypot(*F) > 0:          # balanced forces keep the previous command
                V = F / np.hypot(*F) * pl["speed"]
            xn = m.step(x[None], m.carrot(x[None], V[None]))[0]
            length += float(np.hypot(*(xn[:2] - x[:2])))
            x = xn
            hist.append(x[:2].copy())
            centers, radii = m.footprint(x[None])
            if np.any(s.world.clearance(centers[0], t=t + s.dt) < radii):
                outcome = "collided"
                break
            if not np.all(s.world.inside_workspace(centers[0], radii.max())):
                outcome = "out_of_bounds"
                break
            if np.hypot(*(x[:2] - goal)) <= r.goal_radius:
                outcome = "reached"
                break
            if len(hist) > window:
                w_ = np.array(hist[-window - 1:])
                if np.max(np.hypot(*(w_ - w_.mean(axis=0)).T)) < pl["stuck_radius"] * r.goal_radius:
                    outcome = "stuck"
                    break
        total += length if outcome == "reached" else rw["penalty"]
    return total




def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--reduced", type=int, default=6, help="individuals in the reduced job")
    ap.add_argument("--skip-full", action="store_true")
    ap.add_argument("--skip-reward", action="store_true", help="skip part 2")
    ap.add_argument("--burn", type=int, default=30_000_000,
                    help="loop length of the trivially parallel reference (per process)")
    ap.add_argument("--repeat", type=int, default=2,
                    help="GA runs per worker count, interleaved; the best wall time counts")
    args = ap.parse_args()
    job = load_job()
    print(f"uptime: {uptime()}")
    if not args.skip_full:
        import os
        from concurrent.futures import ProcessPoolExecutor

        walls: dict[int, float] = {}
        ref: dict[int, float] = {}
        results = {}
        load = os.getloadavg()[0]
        pool = ProcessPoolExecutor(args.workers)
        list(pool.map(burn, [1] * args.workers))       # the reference's workers, started
        for _ in range(max(1, args.repeat)):
            for w in sorted({1, args.workers}, reverse=True):
                job2 = job.with_backend(workers=w)
                with tempfile.TemporaryDirectory() as out, make_backend(w) as be:
                    tic = time.perf_counter()
                    res = tune(job2.start_system(), job2.cost("train"), backend=be,
                               checkpoint=out, judge=False, **job2.tune_kwargs())
                    wall = time.perf_counter() - tic
                walls[w] = min(walls.get(w, math.inf), wall)
                results[w] = res
                tic = time.perf_counter()
                if w == 1:
                    for _ in range(args.workers):
                        burn(args.burn)
                else:
                    list(pool.map(burn, [args.burn] * args.workers))
                ref[w] = min(ref.get(w, math.inf), time.perf_counter() - tic)
        pool.shutdown()
        res, wall = results[args.workers], walls[args.workers]
        evals = res.evaluations
        E = len(job.scenarios("train"))
        print(f"built-in job's GA: population {job['ga']['population']}, "
              f"{len(res.logbook) - 1} of {job['ga']['generations']} generations (early stop), "
              f"{E} training worlds, {args.workers} workers: {wall:.1f} s wall for {evals} "
              f"individuals ({evals * E / wall:.0f} (individual, world) evaluations/s, validation "
              f"included); best training objective {res.logbook['min'].iloc[-1]:.4f}   (target: "
              "<= 20 s on 2 workers)")
        if args.workers != 1:
            same = list(results[1].x) == list(res.x)
            print(f"1 worker {walls[1]:.1f} s, {args.workers} workers {wall:.1f} s: "
                  f"{walls[1] / wall:.2f}x (target >= 1.8x; best of {max(1, args.repeat)} each, "
                  f"interleaved); the same tuned system: {same}; "
                  f"load {load:.2f} -> {os.getloadavg()[0]:.2f}")
            print(f"reference ({args.workers} equal CPU loops, same repeats): 1 process "
                  f"{ref[1]:.2f} s, {args.workers} processes {ref[args.workers]:.2f} s: "
                  f"{ref[1] / ref[args.workers]:.2f}x (what {args.workers} workers can get now)")
        print(f"uptime: {uptime()}")
    if args.skip_reward:
        return
    import pathlib

    # (no safety filter: the paper has none, and the straightforward loop does not apply one)
    job = validate_job({"scenarios": {"train": ["effc-train-1", "effc-train-2"]},
                        "reward": {"kind": "length"}, "coverage": {"penalty": 0.0},
                        "planner": {"safety_margin": 0.0}}, None, pathlib.Path.cwd())
    space = job.tunable()
    X = np.vstack([space.to_vector()[None], space.random(args.reduced - 1,
                                                         np.random.default_rng(0))])
    cost = job.cost("train")
    # the lockstep path evaluates a whole generation's chunk at once: time a full population
    # (the reduced job's genomes first) and take the time per (individual, environment)
    P = np.vstack([X, space.random(job["ga"]["population"] - len(X),
                                   np.random.default_rng(1))])
    evaluate_chunk(cost, space, P[:1], Context(job.seed))       # build and compile once
    tic = time.perf_counter()
    fast_all = evaluate_chunk(cost, space, P, Context(job.seed, "train", 0,
                                                      tuple(range(len(P)))))
    t_fast = (time.perf_counter() - tic) / (len(P) * 2)
    fast = fast_all.objectives[:len(X), 0].tolist()
    scenarios = job.scenarios()
    tic = time.perf_counter()
    slow = [straightforward_reward(job, space.to_system(x), scenarios) for x in X]
    t_slow = (time.perf_counter() - tic) / (len(X) * 2)
    print(f"per (individual, environment) evaluation: lockstep (a generation of {len(P)} in one "
          f"chunk) {t_fast * 1e3:.2f} ms, straightforward (reduced job, {len(X)} individuals) "
          f"{t_slow * 1e3:.1f} ms; "
          f"ratio {t_slow / t_fast:.0f}x (target >= 100x); max reward difference "
          f"{max(abs(a - b) for a, b in zip(fast, slow)):.2e}")
    # the same rewards to rounding, or the ratio compares two different computations
    if not np.allclose(fast, slow, rtol=1e-6, atol=1e-9):
        print(f"REWARDS DIFFER: lockstep {fast}, straightforward {slow}")


if __name__ == "__main__":
    main()
