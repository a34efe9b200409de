"""The GA tuner: batched population evaluation, genomes, jobs, backends, checkpoints."""

from __future__ import annotations

import fnmatch
import json
import os
import signal
import subprocess
import types
import sys
import time

import numpy as np
import pytest

from hybridnav import HybridnavError, fuzzy, planners
from hybridnav.fileio import LOCK_NAME, locked_folder
from hybridnav.fuzzy.family import SystemFamily
from hybridnav.backends import DaskBackend, ProcessBackend, SerialBackend
from hybridnav.tuner import tune as tune_objects
from hybridnav.tuner.costs.base import Candidates, Context, evaluate_chunk
from hybridnav.tuner.genome import GenomeSpace
from hybridnav.tuner.job import load_job, validate_job
from hybridnav.tuner.run import OUTPUT_FILES, OUTPUT_FOLDERS

SMALL = """
name = "small"
seed = 3
[ga]
population = 6
generations = 2
elite = 1
tournament = 2
[backend]
chunk = 2
[scenarios]
train = ["effc-train-1", "effc-train-2"]
validation = [{generate = 3, seed = 2, circles = [1, 3]}]
[falsify]
budget = 60
population = 20
"""


def small_job(tmp_path, extra=""):
    p = tmp_path / "job.toml"
    p.write_text(SMALL + extra)
    return load_job(p)


def assess(job, X, generation=0, indices=None, which="train"):
    """One chunk of a job's cost, as the tuner evaluates it."""
    ctx = Context(job.seed, "train" if which == "train" else "validation", generation,
                  None if indices is None else tuple(indices))
    return evaluate_chunk(job.cost(which), job.tunable(), np.atleast_2d(X), ctx)


def tune(job, out, **kw):
    """The tuning a job means (without its outputs), checkpointing into ``out``."""
    return tune_objects(job.start_system(), job.cost("train"), checkpoint=out, judge=False,
                        **{**job.tune_kwargs(), **kw})


def variants(template, n, rng):
    out = []
    for _ in range(n):
        d = template.to_dict()
        for v in d["inputs"] + [d["output"]]:
            lo, hi = v["range"]
            for t in v["terms"]:
                t["params"] = sorted(float(x) for x in rng.uniform(lo, hi, len(t["params"])))
        for r in d["rules"]:
            r["weight"] = float(rng.choice([0.0, rng.uniform(), 1.0]))
            r["then"] = str(rng.choice([t["name"] for t in d["output"]["terms"]]))
        out.append(fuzzy.FuzzySystem.from_dict(d))
    return out


@pytest.mark.parametrize("name", ["effc-2rule", "effc-5rule"])
def test_family_evaluation_matches_each_system(name):
    rng = np.random.default_rng(1)
    tpl = fuzzy.builtin(name)
    systems = variants(tpl, 15, rng)
    fam = SystemFamily(tpl)
    tables = fam.tables_of(systems)
    B = 3000
    member = rng.integers(0, len(systems), B)
    d = rng.uniform(-0.3, 1.9, B)
    a = rng.uniform(-0.2, 2.3, B)
    got = fam.evaluate(tables, member, {"dtheta": d, "alpha": a})
    ref = np.array([systems[m].evaluate(dtheta=x, alpha=y) for m, x, y in zip(member, d, a)])
    assert np.abs(got - ref).max() <= 1e-9


def test_family_handles_other_shapes_and_nested_rules():
    rng = np.random.default_rng(2)
    tpl = fuzzy.FuzzySystem.from_dict({
        "format": "hybridnav-fis/1", "name": "shapes",
        "inputs": [
            {"name": "u", "range": [-1.0, 1.0], "points": 41,
             "terms": [{"name": "n", "mf": "trapmf", "params": [-1, -1, -0.4, 0.1]},
                       {"name": "p", "mf": "gaussmf", "params": [0.5, 0.3]}]},
            {"name": "v", "range": [0.0, 5.0], "points": 77,
             "terms": [{"name": "s", "mf": "trimf", "params": [0, 1, 3]},
                       {"name": "b", "mf": "sigmf", "params": [2.5, 3.0]}]},
            {"name": "z", "range": [0.0, 1.0], "points": 11,
             "terms": [{"name": "lo", "mf": "gbellmf", "params": [0.2, 2.0, 0.1]}]}],
        "output": {"name": "y", "range": [-2.0, 2.0], "points": 61,
                   "terms": [{"name": "a", "mf": "trimf", "params": [-2, -1, 0.5]},
                             {"name": "b", "mf": "gaussmf", "params": [0.5, 0.4]},
                             {"name": "c", "mf": "smf", "params": [0.0, 1.8]}],
                   "defuzz": "centroid", "default": 0.25},
        "rules": [
            {"if": {"and": [["u", "n"], {"not": ["v", "b"]}]}, "then": "a"},
            {"if": {"or": [["u", "p"], {"and": [["v", "s"], ["z", "lo"]]}]}, "then": "c",
             "weight": 0.7},
            {"if": {"not": {"or": [["u", "n"], ["z", "lo"]]}}, "then": "b"}]})
    fam = SystemFamily(tpl)
    systems = [tpl]
    for k in range(6):          # weights and consequents vary; MF shapes as in the template
        d = tpl.to_dict()
        for r in d["rules"]:
            r["weight"] = float(rng.choice([0.0, rng.uniform(), 1.0]))
            r["then"] = str(rng.choice(["a", "b", "c"]))
        systems.append(fuzzy.FuzzySystem.from_dict(d))
    tables = fam.tables_of(systems)
    B = 2000
    member = rng.integers(0, len(systems), B)
    X = {"u": rng.uniform(-1.2, 1.2, B), "v": rng.uniform(-0.5, 5.5, B), "z": rng.random(B)}
    got = fam.evaluate(tables, member, X)
    ref = np.array([systems[m].evaluate(u=X["u"][i], v=X["v"][i], z=X["z"][i])
                    for i, m in enumerate(member)])
    assert np.abs(got - ref).max() <= 1e-9


def test_genome_round_trip_repair_and_switches():
    tpl = fuzzy.builtin("effc-5rule")
    space = GenomeSpace(tpl, {"mf": ["dtheta", "alpha", "w"], "rule_switches": True,
                              "rule_weights": True, "rule_consequents": True, "bounds": {}})
    x = space.encode()
    assert space.system(x).to_dict()["rules"] == tpl.to_dict()["rules"]
    assert space.system(x).inputs == tpl.inputs and space.system(x).output == tpl.output
    bad = x.copy()
    i, j = space.labels.index("dtheta.low.zmf[0]"), space.labels.index("dtheta.low.zmf[1]")
    bad[i], bad[j] = 1.0, 0.3                       # a > b: repair swaps
    fixed = space.repair(bad[None])[0]
    assert fixed[i] < fixed[j]
    off = x.copy()
    for k, lab in enumerate(space.labels):
        if lab.endswith(".on"):
            off[k] = 0.1 if lab != "rule3.on" else 0.2
    kept = space.system(off)
    assert len(kept.rules) == 1 and kept.rules[0].description == tpl.rules[2].description
    rng = np.random.default_rng(0)
    X = space.random(50, rng)
    assert np.all(X >= space.lower) and np.all(X <= space.upper)
    for row in X[:10]:
        space.system(row)             # every repaired genome decodes to a valid system


def _uncovered_reference(system, grid):
    """Fraction of the input grid where no rule fires, from scikit-fuzzy's sampled membership
    functions and interp_membership (min for AND, max for OR, times the weight; every output
    term has a positive area)."""
    import skfuzzy

    names = system.input_names
    axes = [np.linspace(v.range[0], v.range[1], grid) for v in system.inputs]
    D, A = np.meshgrid(*axes, indexing="ij")
    X = {names[0]: D.ravel(), names[1]: A.ravel()}
    mf = {}
    for v in system.inputs:
        u = np.linspace(v.range[0], v.range[1], v.points)
        mf[v.name] = {t.name: skfuzzy.interp_membership(u, getattr(skfuzzy, t.mf)(u, *t.params),
                                                        X[v.name]) for t in v.terms}

    def fire(a):
        if isinstance(a, list):
            return mf[a[0]][a[1]]
        op, items = next(iter(a.items()))
        if op == "not":
            return 1.0 - fire(items)
        parts = [fire(x) for x in items]
        return np.minimum.reduce(parts) if op == "and" else np.maximum.reduce(parts)

    fired = np.zeros(D.size, dtype=bool)
    for r in system.to_dict()["rules"]:
        fired |= fire(r["if"]) * r.get("weight", 1.0) > 0
    return 1.0 - fired.mean()


def test_chunk_reward_equals_the_planner_run(tmp_path):
    job = small_job(tmp_path)
    start = job.start_system()
    space = job.tunable()
    ev = assess(job, space.to_vector())
    costs = []
    for s, env in zip(job.scenarios(), ev.details[0]):
        r = planners.get("effc", fis=start).run(s).robots[0]
        assert env["outcome"] == r.outcome
        assert env["length"] == pytest.approx(r.path_length, rel=1e-9)
        robot = s.robots[0]
        D = np.hypot(*np.subtract(robot.goal, robot.start)) - robot.goal_radius
        assert r.outcome == "reached"
        short = max(0.0, 1.0 - r.min_clearance / robot.radius)    # safety: one robot radius
        costs.append(r.path_length / D + 2.0 * short)
        assert env["reward"] == pytest.approx(costs[-1], rel=1e-9)
    unc = _uncovered_reference(start, 41)
    assert unc == pytest.approx(0.11, abs=0.01)      # alpha high and dtheta low: no rule fires
    assert ev.info[0]["uncovered"] == pytest.approx(unc, abs=1e-12)
    assert ev.info[0]["reward"] == pytest.approx(np.mean(costs), rel=1e-9)
    assert ev.objectives[0, 0] == pytest.approx(np.mean(costs) + 100.0 * unc, rel=1e-9)
    assert not ev.feasible[0]                    # 11 % uncovered > the allowed 0


def test_coverage_matches_scikit_fuzzy_on_random_genomes(tmp_path):
    job = small_job(tmp_path)
    space = job.tunable()
    X = space.random(12, np.random.default_rng(3))
    got = Candidates(space, X).uncovered(41)
    ref = [_uncovered_reference(space.to_system(x), 41) for x in X]
    assert np.allclose(got, ref, atol=1e-12)
    assert 0 < sum(np.asarray(ref) == 0) < len(ref)    # some cover everything, some do not


def test_deploy_cost_orders_outcomes(tmp_path):
    from hybridnav.planners.field.lockstep import LockstepResult
    from hybridnav.tuner.evaluate import run_costs

    job = small_job(tmp_path)
    scen = job.scenarios()[:1]
    out = np.array([["reached", "reached", "reached", "stuck", "timeout", "collided",
                     "out_of_bounds"]], dtype=object)
    n = out.shape[1]
    res = LockstepResult(outcome=out, path_length=np.array([[4.0, 4.0, 12.0, 3, 3, 1, 1]]),
                         time=np.full((1, n), 40.0),
                         min_clearance=np.array([[0.5, 0.02, 0.0, 0.3, 0.3, -0.01, 0.1]]),
                         final_distance=np.array([[0.05, 0.05, 0.05, 0.0, 5.0, 2, 2]]))
    c = run_costs(job["reward"], job["planner"]["speed"], scen, res)[0]
    D = np.hypot(3, 3) - 0.1
    assert c[0] == pytest.approx(4.0 / D)
    assert c[1] == pytest.approx(4.0 / D + 2.0 * 0.8)          # 2 cm from a 10 cm robot
    # the longest possible detour (the whole time budget at full speed), touching an obstacle,
    # still costs less than getting stuck next to the goal, which costs less than a collision
    assert c[2] < c[3] < c[4] < c[5] == c[6] == 20.0
    assert c[3] == pytest.approx(10.0) and c[4] == pytest.approx(15.0)


def test_penalty_and_the_maximize_convention(tmp_path):
    job = small_job(tmp_path, '[reward]\nsense = "maximize"\npenalty = 7.0\n')
    space = job.tunable()
    x = space.to_vector()
    x[space.labels.index("w.high.smf[0]")] = 0.0          # always repel: the robot backs off
    x[space.labels.index("w.high.smf[1]")] = 0.01
    x[space.labels.index("w.low.zmf[0]")] = 0.99
    x[space.labels.index("w.low.zmf[1]")] = 1.0
    ev = assess(job, space.repair(x[None]))
    for env in ev.details[0]:
        assert env["reward"] == (env["length"] if env["outcome"] == "reached" else -7.0)
    assert job["reward"]["kind"] == "paper"         # an old job file's sense chooses the kind
    unc = ev.info[0]["uncovered"]
    total = sum(e["reward"] for e in ev.details[0])
    assert ev.info[0]["fitness"] == pytest.approx(total - 100.0 * unc)
    assert ev.objectives[0, 0] == pytest.approx(-(total - 100.0 * unc))    # minimized


def test_noise_does_not_depend_on_the_chunking(tmp_path):
    job = small_job(tmp_path, "[reward]\nheading_noise = 0.05\nrepeats = 2\n")
    X = job.tunable().random(4, np.random.default_rng(5))
    whole = assess(job, X, 2, [0, 1, 2, 3]).objectives[:, 0].tolist()
    parts = (assess(job, X[:1], 2, [0]).objectives[:, 0].tolist()
             + assess(job, X[1:], 2, [1, 2, 3]).objectives[:, 0].tolist())
    assert whole == parts
    quiet = assess(small_job(tmp_path), X, 2, [0, 1, 2, 3]).objectives[:, 0].tolist()
    assert whole != quiet


@pytest.mark.parametrize("extra, key, text", [
    ("[ga]\npopulation = 2\nelite = 2\n", "ga.elite", "expected fewer elites"),
    ("[ga]\ncrossover = \"uniform\"\n", "ga.crossover", "expected one of sbx, blend"),
    ("[gaa]\n", "gaa", "unknown key"),
    ("[free]\nmf = [\"speed\"]\n", "free", "expected a variable of 'effc-5rule'"),
    ("[free.bounds]\nalpha = [1.0, 0.5]\n", "free", "bounds.alpha: expected [lo, hi]"),
    ("[system]\nstart = \"missing.json\"\n", "system.start", "cannot read"),
    ("[scenarios]\ntrain = [\"aco-three-robots\"]\n", "scenarios.train[0]", "exactly one"),
    ("[reward]\nrepeats = 3\n", "reward.repeats", "alpha_noise > 0"),
    ("[reward]\nkind = \"fast\"\n", "reward.kind", "expected one of deploy, length, paper"),
    ("[reward]\nkind = \"deploy\"\nsense = \"maximize\"\n", "reward.sense",
     "expected minimize"),
    ("[scenarios]\ntrain = [{generate = 0}]\n", "scenarios.train[0].generate",
     "expected an integer in [1, 10000]"),
    ("[scenarios]\ntrain = [{seed = 1}]\n", "scenarios.train[0].generate", "missing"),
    ("[scenarios]\ntrain = [{generate = 2, circle = [1, 2]}]\n",
     "scenarios.train[0].circle", "unknown key"),
    ("[scenarios]\ntrain = [{generate = 2, radius = [0.5, 0.2]}]\n",
     "scenarios.train[0].radius", "low <= high"),
    ("[scenarios]\ntrain = [{generate = 2, layout = \"ring\"}]\n",
     "scenarios.train[0].layout", "expected one of diagonal, random"),
    ("[scenarios]\ntrain = [\"effc-train-1\"]\nvalidation = [3]\n",
     "scenarios.validation[0]", "expected a scenario name or path"),
    ("[scenarios]\ntrain = [{generate = 2, circles = [40, 40], radius = [0.9, 1.0], min_gap = 0, "
     "max_tries = 2}]\n", "scenarios.train[0]", "no solvable world"),
    ("[scenarios]\ntrain = [\"effc-train-1\", {generate = 1, dt = 0.05}]\n",
     "scenarios.train", "expected one robot model for the whole set"),
    ("[scenarios]\ntrain = [\"effc-train-1\", \"effc-train-1\"]\n", "scenarios.train",
     "expected distinct scenario names"),
    ("[coverage]\nmax_uncovered = 1.5\n", "coverage.max_uncovered", "expected a number in [0, 1], got 1.5"),
    ("[validation]\ntop = 0\n", "validation.top", "expected an integer in [1, 1000], got 0"),
    ("[free]\nmargin = -0.1\n", "free.margin", "expected a number in [0, 1], got -0.1"),
    ("[reward]\npenalty = \"big\"\n", "reward.penalty", "expected a number, got 'big'"),
])
def test_bad_jobs_fail_before_any_work(tmp_path, extra, key, text):
    p = tmp_path / "bad.toml"
    p.write_text(extra)
    with pytest.raises(HybridnavError) as info:
        load_job(p)
    msg = str(info.value)
    assert "bad.toml" in msg and f": {key}: " in msg and text in msg


def _strip(logbook):
    return logbook.drop(columns="wall_time").to_dict("records")


def test_checkpoint_resume_equals_an_uninterrupted_run(tmp_path):
    job = small_job(tmp_path)
    full = tune(job, tmp_path / "full")
    tune(job, tmp_path / "part", stop_after=1)
    state = json.loads((tmp_path / "part" / "checkpoint.json").read_text())
    assert state["optimizer"]["generation"] == 2     # the next generation, not the saved one
    resumed = tune(job, tmp_path / "part", resume=True)
    assert list(resumed.x) == list(full.x)
    assert _strip(resumed.logbook) == _strip(full.logbook)
    assert resumed.records.equals(full.records)
    other = job.with_seed(4)
    with pytest.raises(HybridnavError, match="config_hash: this checkpoint was written by a "
                                             "different configuration"):
        tune(other, tmp_path / "part", resume=True)


def test_two_local_processes_give_the_same_run(tmp_path):
    job = small_job(tmp_path)
    serial = tune(job, tmp_path / "s", backend=SerialBackend())
    with ProcessBackend(2) as be:
        par = tune(job, tmp_path / "p", backend=be)
    assert list(par.x) == list(serial.x) and _strip(par.logbook) == _strip(serial.logbook)


@pytest.mark.slow
def test_dask_local_cluster_and_a_killed_worker_give_the_same_run(tmp_path):
    job = small_job(tmp_path)
    serial = tune(job, tmp_path / "s")
    with DaskBackend("", workers=2) as be:
        assert _strip(tune(job, tmp_path / "d", backend=be).logbook) == _strip(serial.logbook)
        pids = be.client.run(os.getpid)
        victim = next(iter(pids.values()))

        def kill_now(row):
            # a generation takes milliseconds with the compiled control cycle: the worker dies
            # right after generation 0, so generation 1's chunks meet a dead or restarting one
            if row["gen"] == 0:
                os.kill(victim, signal.SIGKILL)

        again = tune(job, tmp_path / "k", backend=be, progress=kill_now)
        be.client.wait_for_workers(2, timeout=120)
        assert victim not in be.client.run(os.getpid).values()   # that worker really died
    assert list(again.x) == list(serial.x)
    assert _strip(again.logbook) == _strip(serial.logbook)


@pytest.mark.slow
def test_sigkill_and_resume_from_the_command_line(tmp_path):
    """A killed ``hybridnav tune`` process resumes to the run it would have made. The reference
    run is made in this process (the same ``main``); the killed, the refused and the resumed
    runs are true processes. The falsification search after tuning is off: it runs once the GA
    is done, after any kill, and its own outputs are tested in
    test_tune_cli_quick_writes_every_output."""
    from hybridnav.cli import main

    job_file = tmp_path / "job.toml"
    job_file.write_text(SMALL.replace("generations = 2", "generations = 4")
                        .replace("[falsify]\nbudget = 60", "[falsify]\nbudget = 0"))
    cmd = [sys.executable, "-m", "hybridnav.cli", "tune", str(job_file), "--out"]
    assert main(["tune", str(job_file), "--out", str(tmp_path / "ref")]) == 0
    out = tmp_path / "run"
    proc = subprocess.Popen(cmd + [str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    ckpt = out / "checkpoint.json"
    deadline = time.time() + 120
    while time.time() < deadline:
        if ckpt.exists() and json.loads(ckpt.read_text())["optimizer"]["generation"] >= 2:
            break
        time.sleep(0.05)
    # a second job into the folder while the first writes it is refused (the folder is locked)
    second = subprocess.run(cmd + [str(out), "--force"], capture_output=True, text=True,
                            timeout=300)
    assert second.returncode == 2 and "another hybridnav job is writing this folder (pid " \
        f"{proc.pid} on" in second.stderr, second.stderr
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert (out / LOCK_NAME).exists()           # the killed job's lock: stale, taken over below
    gen = json.loads(ckpt.read_text())["optimizer"]["generation"]
    assert 2 <= gen <= 5
    (out / ".paths.png.x1y2z3w4.tmp.png").write_bytes(b"half a png")   # a killed writer's leftover
    done = subprocess.run(cmd + [str(out), "--resume"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert not (out / ".paths.png.x1y2z3w4.tmp.png").exists() and not (out / LOCK_NAME).exists()
    a = json.loads((out / "fis.json").read_text())
    b = json.loads((tmp_path / "ref" / "fis.json").read_text())
    b["name"] = a["name"]
    assert a == b
    import pandas as pd
    la = pd.read_csv(out / "logbook.csv").drop(columns="wall_time")
    lb = pd.read_csv(tmp_path / "ref" / "logbook.csv").drop(columns="wall_time")
    pd.testing.assert_frame_equal(la, lb)


@pytest.mark.slow
def test_tune_cli_quick_writes_every_output(tmp_path, capsys):
    from hybridnav.cli import main

    job_file = tmp_path / "job.toml"
    job_file.write_text(SMALL)
    import pandas as pd

    o = tmp_path / "o"
    assert main(["tune", str(job_file), "--out", str(o)]) == 0
    # every phase after the GA is named, with its time, as plain lines (not a terminal)
    phases = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("  ")]
    assert phases[0] == "  judging start and tuned on the validation and test data ..."
    assert phases[1].startswith("  judging start and tuned on the validation and test data: ")
    assert phases[1].endswith(" s") and len(phases) >= 4 and len(phases) % 2 == 0
    # a second run into the same folder neither overwrites it nor starts silently
    capsys.readouterr()
    assert main(["tune", str(job_file), "--out", str(o)]) == 2
    assert "holds a tuning run (checkpoint.json); --resume continues it" in capsys.readouterr().err
    # nor while another job writes it (here: this process holds the folder's lock)
    with locked_folder(o, "tune other.toml"):
        assert main(["tune", str(job_file), "--out", str(o), "--force"]) == 2
        err = capsys.readouterr().err
        assert f"{o}: another hybridnav job is writing this folder (pid {os.getpid()}" in err
        assert "'tune other.toml'" in err
    assert not (o / LOCK_NAME).exists()
    # --force leaves no file of the old run: not an old falsified world, not a temporary file
    old = [o / "falsified" / "falsified-9999.toml", o / ".fis.json.abc_1234.tmp.json",
           o / "robust-7" / "checkpoint.json"]
    for f in old:
        f.parent.mkdir(exist_ok=True)
        f.write_text("old run")
    (o / "notes.txt").write_text("the user's own file stays")
    mine = [o / "robust-notes" / "ideas.txt", o / "falsified" / "my-world.toml",
            o / ".env.tmpl", o / "front" / "cover.txt"]       # the user's: kept by --force
    for f in mine:
        f.parent.mkdir(exist_ok=True)
        f.write_text("mine")
    assert main(["tune", str(job_file), "--out", str(o), "--force"]) == 0
    assert not any(f.exists() for f in old) and not (o / "robust-7").exists()
    assert (o / "notes.txt").exists() and all(f.exists() for f in mine)
    # everything a run writes is declared (what --force removes)
    for entry in o.iterdir():
        if entry.name in ("notes.txt", ".env.tmpl", "robust-notes", "front"):
            continue
        assert entry.name in OUTPUT_FILES or any(
            entry.is_dir() and fnmatch.fnmatch(entry.name, g) for g in OUTPUT_FOLDERS), entry
    for name in ("fis.json", "start.json", "logbook.csv", "evaluations.csv", "validation.csv",
                 "heldout.csv", "heldout_summary.csv", "convergence.png", "mfs.png",
                 "surface.png", "coverage.png", "paths.png", "report.md", "checkpoint.json",
                 "deployment.json", "effc_safety.c", "effc_safety.h"):
        assert (tmp_path / "o" / name).exists(), name
    tuned = fuzzy.load(str(tmp_path / "o" / "fis.json"))
    assert tuned.input_names == ("dtheta", "alpha")
    report = (tmp_path / "o" / "report.md").read_text()
    assert "Training objective (deploy reward, minimized): start" in report
    assert "**Verdict: on the test set (2 worlds) tuned reaches" in report
    assert "Safety first (the tuned system against apf and its start):" in report
    # the falsification searched start, tuned and apf with the same budget: one row each
    fals = pd.read_csv(tmp_path / "o" / "falsification.csv")
    assert list(fals.system) == ["tuned", "start", "apf"] and set(fals.tried) == {60}
    assert "| apf | 60 |" in report
    assert "Returned system: the best on **validation**" in report
    summary = pd.read_csv(tmp_path / "o" / "heldout_summary.csv")
    assert set(summary.system) == {"start", "tuned", "apf"}
    assert set(summary.set) == {"validation", "test"}
    held = pd.read_csv(tmp_path / "o" / "heldout.csv")
    assert set(held[held.set == "test"].scenario) == {"effc-env-a", "effc-env-b"}
    # the start's row comes from the same lockstep code as tuning; check one against the planner
    row = held[(held.set == "test") & (held.system == "start")
               & (held.scenario == "effc-env-b")].iloc[0]
    ref = planners.get("effc", fis="effc-5rule", safety_margin=0.05).run(
        __import__("hybridnav.world", fromlist=["x"]).load_scenario("effc-env-b")).robots[0]
    assert row.outcome == ref.outcome and row.path_length == pytest.approx(ref.path_length)
    import pandas as pd
    ev = pd.read_csv(tmp_path / "o" / "evaluations.csv")
    assert set(ev.columns) >= {"generation", "individual", "scenario", "outcome", "length",
                               "time", "clearance", "reward", "uncovered"}
    assert main(["tune", str(job_file), "--out", str(tmp_path / "x"), "--resume"]) == 2


def test_validate_job_defaults_are_the_papers():
    job = validate_job({}, None, __import__("pathlib").Path.cwd())
    assert job["ga"]["population"] == 100 and job["ga"]["generations"] == 25
    sets = job["scenarios"]
    assert sets["train"][:2] == ["effc-train-1", "effc-train-2"]       # the paper's two
    assert sets["train"][2]["generate"] > 0 and sets["validation"][0]["generate"] > 0
    assert sets["test"][:2] == ["effc-env-a", "effc-env-b"]
    seeds = {sets[k][-1]["seed"] for k in ("train", "validation", "test")}
    assert len(seeds) == 3                                 # three disjoint generated sets
    names = {k: {s.name for s in job.scenarios(k)} for k in ("train", "validation", "test")}
    assert not names["train"] & names["validation"] and not names["test"] & (
        names["train"] | names["validation"])


def test_wilson_interval_matches_scipy():
    from scipy.stats import binomtest

    from hybridnav.tuner.heldout import wilson

    for k, n in [(0, 5), (3, 10), (29, 30), (30, 30), (11, 30)]:
        ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
        assert wilson(k, n) == pytest.approx((ref.low, ref.high), abs=1e-12)


def test_summary_and_verdict_on_a_known_table():
    import pandas as pd

    from hybridnav.tuner.heldout import summarize, verdict

    rows = []
    for w, (st, tu, ap) in enumerate([("reached", "reached", "reached"),
                                      ("collided", "reached", "stuck"),
                                      ("reached", "reached", "reached")]):
        for sys_, out, L, c in (("start", st, 5.0 + w, 0.03), ("tuned", tu, 4.8 + w, 0.07),
                                ("apf", ap, 5.5 + w, 0.2)):
            rows.append({"set": "test", "scenario": f"w{w}", "system": sys_, "outcome": out,
                         "path_length": L, "time": 1.0, "min_clearance": c})
    summ = summarize(pd.DataFrame(rows))
    t = summ.set_index("system").loc["tuned"]
    assert t.reached == 3 and t.common_worlds == 2                  # w0 and w2: all reached
    assert t.common_length == pytest.approx((4.8 + 6.8) / 2)
    assert summ.set_index("system").loc["start"].collided == 1
    # tuned keeps 0.07 m where apf keeps 0.2 m: a safety figure worse than apf's
    v = verdict(summ, "test", 0.1)
    assert not v["better"] and not v["safe"] and v["better_than_start"]
    assert [ok for _, ok in v["checks"]] == [True, True, False, True, True, True, True, True]
    assert v["checks"][2][0].startswith("smallest clearance on the 2 worlds every system "
                                        "reached 0.070 m; apf 0.200 m")
    assert "NOT ready to deploy: less safe than apf (clearance)" in v["headline"]
    for r in rows:                                   # apf as close as tuned: nothing worse
        if r["system"] == "apf":
            r["min_clearance"] = 0.07
    v = verdict(summarize(pd.DataFrame(rows)), "test", 0.1)
    assert v["better"] and all(ok for _, ok in v["checks"]) and "ready to deploy" in v["headline"]
    rows[4]["min_clearance"] = 0.04                                  # tuned grazes w1
    v = verdict(summarize(pd.DataFrame(rows)), "test", 0.1)
    assert not v["better"] and [text for text, ok in v["checks"] if not ok] == [
        "keeps at least half the robot radius (0.05 m) from obstacles on every world it "
        "reaches (smallest 0.040 m)"]


def _three(outcomes, clear=(0.1, 0.1, 0.1)):
    """A judged table of start, tuned and apf on len(outcomes) worlds."""
    import pandas as pd

    rows = []
    for w, trio in enumerate(outcomes):
        for sys_, out, c, L in zip(("start", "tuned", "apf"), trio, clear, (5.0, 4.8, 5.2)):
            rows.append({"set": "test", "scenario": f"w{w}", "system": sys_, "outcome": out,
                         "path_length": L, "time": 1.0, "min_clearance": c})
    return pd.DataFrame(rows)


def test_a_tuned_system_that_collides_where_apf_does_not_is_not_called_better():
    from hybridnav.tuner.heldout import summarize, verdict

    # better than its start (fewer collisions, more reached) but one collision apf avoids
    t = _three([("collided", "reached", "reached")] * 2 + [("collided", "collided", "stuck")]
               + [("reached", "reached", "reached")] * 5)
    v = verdict(summarize(t), "test", 0.1, table=t)
    assert not v["better"] and not v["safe"]
    assert v["headline"].startswith("on the test set (8 worlds) tuned reaches 7, collides 1")
    assert "apf reaches 7, collides 0" in v["headline"]
    assert v["headline"].endswith("NOT ready to deploy: less safe than apf (collisions)")
    failed = [text for text, ok in v["checks"] if not ok]
    assert failed == ["collides or leaves the workspace in 1 of 8 (2-47 %) test worlds; apf "
                      "in 0 of 8 (0-32 %)"]
    # the wrong comparator is gone: it IS better than its start on every figure
    assert v["better_than_start"]


def test_falsification_rates_enter_the_verdict():
    import pandas as pd

    from hybridnav.tuner.heldout import summarize, verdict

    t = _three([("reached", "reached", "reached")] * 4)
    fals = pd.DataFrame([
        {"system": s, "tried": 100, "valid": v, "failures": f, "collisions": c,
         "failures_rate": f / v, "collisions_rate": c / v}
        for s, v, f, c in (("tuned", 80, 6, 3), ("start", 70, 9, 5), ("apf", 75, 4, 0))])
    v = verdict(summarize(t), "test", 0.1, fals, t)
    assert not v["better"] and not v["safe"] and v["better_than_start"]
    bad = [text for text, ok in v["checks"] if not ok]
    assert bad[0] == ("an adversarial search (100 worlds each, the same seed) makes it collide "
                      "in 3 of 80 (1-10 %) valid worlds; apf in 0 of 75 (0-5 %)")
    assert "(collisions under falsification)" in v["headline"]
    fals.loc[0, ["collisions", "collisions_rate"]] = [0, 0.0]
    v = verdict(summarize(t), "test", 0.1, fals, t)
    assert v["safe"]


EARLY = SMALL.replace("generations = 2", "generations = 6") + """
[validation]
patience = 1
"""


def test_early_stop_returns_the_best_on_validation_and_resume_is_a_no_op(tmp_path):
    job_file = tmp_path / "job.toml"
    job_file.write_text(EARLY)
    job = load_job(job_file)
    res = tune(job, tmp_path / "e")
    stopped = res.stopped
    assert stopped is not None and stopped < 6                  # stopped before the end
    assert len(res.logbook) == stopped + 1
    cands = res.validation
    best = cands.loc[cands.score.idxmin()]
    assert res.best_generation == best.generation and res.validation_score == best.score
    again = tune(job, tmp_path / "e", resume=True)
    before = (tmp_path / "e" / "checkpoint.json").read_text()
    assert list(again.x) == list(res.x) and _strip(again.logbook) == _strip(res.logbook)
    assert json.loads(before)["stopped"] == stopped


KFOLD = SMALL.replace("generations = 2", "generations = 1").replace(
    "budget = 60", "budget = 0").replace(
    'train = ["effc-train-1", "effc-train-2"]',
    'train = ["effc-train-1", "effc-train-2", {generate = 2, seed = 5, circles = [1, 2]}]') + """
[validation]
kfold = 2
patience = 0
"""


def test_kfold_runs_one_stage_per_fold_and_resumes_exactly(tmp_path):
    job_file = tmp_path / "job.toml"
    job_file.write_text(KFOLD)
    job = load_job(job_file)
    from hybridnav.tuner.costs.base import fold_of

    folds = list(fold_of(len(job.scenarios("train")), 2, job.seed))
    assert sorted(folds) == [0, 0, 1, 1]
    full = tune(job, tmp_path / "full")
    assert list(full.logbook.stage) == [0, 0, 1, 1]
    assert [f["fold"] for f in full.folds] == [0, 1]
    ev = full.records
    names = {s.name for s in job.scenarios("train")}
    for stage in (0, 1):          # each stage trains on the worlds outside its fold only
        trained = set(ev[ev.stage == stage].scenario)
        held = {s.name for f, s in zip(folds, job.scenarios("train")) if f == stage}
        assert trained == names - held
    tune(job, tmp_path / "part", stop_after=2)                 # inside stage 1
    resumed = tune(job, tmp_path / "part", resume=True)
    assert list(resumed.x) == list(full.x)
    assert _strip(resumed.logbook) == _strip(full.logbook)


@pytest.mark.slow
def test_kfold_job_without_validation_set_writes_its_report(tmp_path):
    from hybridnav.cli import main

    job_file = tmp_path / "job.toml"
    job_file.write_text(KFOLD.replace('validation = [{generate = 3, seed = 2, circles = [1, 3]}]',
                                      'validation = []'))
    assert main(["tune", str(job_file), "--out", str(tmp_path / "o")]) == 0
    report = (tmp_path / "o" / "report.md").read_text()
    assert "k-fold over the training data (2 folds" in report
    assert "Mean of the fold scores" in report
    assert "the last k-fold stage's best on its own fold (fold 1" in report
    job_file.write_text(KFOLD)
    assert main(["tune", str(job_file), "--out", str(tmp_path / "v")]) == 0
    report = (tmp_path / "v" / "report.md").read_text()
    assert "of k-fold stage" in report and "Mean of the fold scores" in report


def test_backends_report_each_finished_task_and_keep_the_order():
    """The one parallel mechanism (tune and compare): results in submission order, on_done once
    per task, whatever the backend."""
    from hybridnav.backends import make_backend

    args = [(i,) for i in range(7)]
    for workers in (1, 2):
        seen: list[int] = []
        with make_backend(workers=workers) as backend:
            out = backend.map(abs, [(-a,) for (a,) in args], on_done=seen.append)
        assert out == list(range(7)) and sorted(seen) == list(range(7))


def test_the_verdict_does_not_read_better_than_missing_or_hidden_data():
    import pandas as pd

    from hybridnav.tuner.heldout import summarize, verdict

    t = _three([("reached", "reached", "reached")] * 4)
    # no apf at all: never "ready"
    no_apf = t[t.system != "apf"]
    v = verdict(summarize(no_apf), "test", 0.1, table=no_apf)
    assert not v["better"] and "no apf run to compare with" in v["headline"]
    # a graze on a world only the tuned system reached is a safety failure against apf
    g = pd.concat([t, pd.DataFrame([{"set": "test", "scenario": "w9", "system": s,
                                     "outcome": o, "path_length": 5.0, "time": 1.0,
                                     "min_clearance": c}
                                    for s, o, c in (("start", "stuck", 0.3),
                                                    ("tuned", "reached", 0.01),
                                                    ("apf", "stuck", 0.3))])])
    v = verdict(summarize(g), "test", 0.1, table=g)
    assert not v["safe"] and "(0.010 m on a world not every system reached)" in v["headline"]
    # a falsification with no valid world, or without the comparators' rows, is no pass
    def fals(rows):
        return pd.DataFrame([{"system": s, "tried": 50, "valid": n, "failures": 0,
                              "collisions": 0, "failures_rate": 0.0, "collisions_rate": 0.0}
                             for s, n in rows])
    v = verdict(summarize(t), "test", 0.1, fals([("tuned", 0), ("start", 9), ("apf", 9)]), t)
    assert not v["safe"] and not v["better"]
    v = verdict(summarize(t), "test", 0.1, fals([("tuned", 30)]), t)
    assert not v["better"] and any("no rows for apf" in c for c, ok in v["checks"] if not ok)
    v = verdict(summarize(t), "test", 0.1, fals([("tuned", 30), ("start", 9), ("apf", 9)]), t)
    assert v["safe"]


def test_an_empty_table_or_an_unknown_clearance_is_no_verdict_to_act_on():
    import math

    import pandas as pd

    from hybridnav.tuner.heldout import COLUMNS, summarize, verdict

    v = verdict(summarize(pd.DataFrame(columns=COLUMNS)), "test", 0.1)
    assert v["checks"] == [] and not v["better"]
    t = _three([("reached", "reached", "reached")] * 3)
    t.loc[(t.system == "tuned") & (t.scenario == "w1"), "min_clearance"] = math.nan
    s = summarize(t).set_index("system")
    assert math.isnan(s.loc["tuned", "min_clearance_reached"])
    assert not verdict(summarize(t), "test", 0.1, table=t)["safe"]


@pytest.mark.long
def test_falsification_in_the_training_loop_adds_finds_to_training_only(tmp_path):
    """A round adds the worst finds (every failure here) to the training worlds and tunes on;
    validation and test stay the job's; a rerun resumes to the same system."""
    import pandas as pd

    from hybridnav.cli import main

    job_file = tmp_path / "job.toml"
    # (the search after tuning is off: the rounds' own searches are what this test is about;
    # the one after tuning is tested in test_tune_cli_quick_writes_every_output)
    job_file.write_text(SMALL.replace("[falsify]\nbudget = 60", "[falsify]\nbudget = 0")
                        + "\n[robust]\nrounds = 2\nbudget = 20\ncap = 2\nfailures = "
                        '"all"\n')
    assert main(["tune", str(job_file), "--out", str(tmp_path / "o")]) == 0
    res = json.loads((tmp_path / "o" / "result.json").read_text())
    rows = res["robust"]
    assert 1 <= len(rows) <= 2 and all(r["searched"] == 20 for r in rows)
    assert all(r["added"] <= 2 for r in rows) and rows[0]["added"] > 0
    held = pd.read_csv(tmp_path / "o" / "heldout.csv")
    assert not held.scenario.str.startswith("robust-").any()       # validation/test untouched
    assert (tmp_path / "o" / "robust-1" / "checkpoint.json").exists()
    report = (tmp_path / "o" / "report.md").read_text()
    assert "## Falsification in the training loop" in report
    first = json.loads((tmp_path / "o" / "fis.json").read_text())
    assert main(["tune", str(job_file), "--out", str(tmp_path / "o"), "--resume"]) == 0
    assert json.loads((tmp_path / "o" / "fis.json").read_text()) == first


def test_robust_rounds_are_refused_where_they_cannot_apply(tmp_path):
    from hybridnav.tuner.job import load_job

    p = tmp_path / "job.toml"
    p.write_text('[robust]\nrounds = 1\n[validation]\nkfold = 3\n')
    with pytest.raises(HybridnavError, match=r"job.toml: robust.rounds: expected 0 with rule "
                                             r"learning, k-fold"):
        load_job(p)
    p.write_text('[validation]\nkfold = 3\n')               # the default quietly does not apply
    assert load_job(p)["robust"]["rounds"] == 0


def test_multi_robot_test_worlds_count_every_robot_of_every_system():
    from hybridnav.tuner import NavigationCost
    from hybridnav.world import scenario_from_dict

    two = scenario_from_dict({
        "name": "two", "units": "m", "dt": 0.1, "max_time": 40.0,
        "workspace": {"xmin": 0, "xmax": 4, "ymin": 0, "ymax": 4},
        "obstacles": [{"type": "circle", "center": [2.0, 2.0], "radius": 0.3}],
        "robots": [{"name": n, "model": "unicycle", "start": s, "goal": g, "radius": 0.1,
                    "goal_radius": 0.1} for n, s, g in (("a", [0.5, 0.5], [3.5, 3.5]),
                                                       ("b", [0.5, 3.5], [3.5, 0.5]))]})
    cost = NavigationCost([two], name="test", strict=False)
    t = cost.judge({"start": fuzzy.builtin("effc-5rule"), "tuned": fuzzy.builtin("effc-tuned")},
                   "test")
    assert t.groupby("system").size().to_dict() == {"apf": 2, "start": 2, "tuned": 2}


def test_one_and_two_workers_judge_and_falsify_alike(tmp_path):
    """Same seed, serial and two processes: round-robin chunks, the two held-out sets judged
    one per worker and the three falsification searches one per worker give the same tables."""
    from hybridnav.tuner.falsify import falsify_systems, rates

    text = SMALL.replace("[scenarios]\n", "[scenarios]\ntest = [{generate = 2, seed = 5, "
                                          "circles = [1, 3]}]\n").replace("chunk = 2", "chunk = 4")
    (tmp_path / "job.toml").write_text(text)
    job = load_job(tmp_path / "job.toml")
    kw = job.tune_kwargs()
    out = {}
    for label, be in (("serial", SerialBackend()), ("two", ProcessBackend(2))):
        with be:
            res = tune_objects(job.start_system(), job.cost("train"), backend=be, **kw)
            found = falsify_systems(job.cost("train"), {"tuned": res.system, "start":
                                                        res.start, "apf": "apf"},
                                    budget=8, population=4, seed=2, backend=be)
        out[label] = (res, found)
    (a, fa), (b, fb) = out["serial"], out["two"]
    assert list(a.x) == list(b.x) and _strip(a.logbook) == _strip(b.logbook)
    assert a.records.equals(b.records)
    assert set(a.heldout.set) == {"validation", "test"} and a.heldout.equals(b.heldout)
    assert rates(fa).equals(rates(fb))
    assert [w.name for w in fa["tuned"].worlds] == [w.name for w in fb["tuned"].worlds]


@pytest.mark.long
def test_one_and_two_workers_give_the_same_job_outputs(tmp_path):
    """Same seed, one worker and two: the round-robin chunks, the held-out sets judged one per
    worker and the falsification searches one per worker give the same tables, bit for bit.
    (``long``: two whole jobs with their figures; the test above checks the same mechanisms
    in seconds on every run.)"""
    from hybridnav.tuner.run import run_job

    text = SMALL.replace("[scenarios]\n", "[scenarios]\ntest = [{generate = 2, seed = 5, "
                                          "circles = [1, 3]}]\n").replace("chunk = 2", "chunk = 4")
    assert "test = " in text and "chunk = 4" in text
    (tmp_path / "job.toml").write_text(text)
    job = load_job(tmp_path / "job.toml")
    outs = {}
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        res = run_job(job.with_backend(workers=workers), out)
        outs[workers] = (res, out)
    (a, da), (b, db) = outs[1], outs[2]
    assert list(a.x) == list(b.x) and _strip(a.logbook) == _strip(b.logbook)
    assert set(a.heldout.set) == {"validation", "test"}
    for name in ("heldout.csv", "falsification.csv", "evaluations.csv"):
        assert (da / name).read_text() == (db / name).read_text(), name


def test_the_path_figure_draws_the_held_out_runs():
    """``paths.png`` draws lockstep batches (the held-out table's simulation): the same outcome,
    length, end time and final state as the batch run that judged each system, and the
    planner's own run where the worlds cannot be batched."""
    from hybridnav.planners.field.apf import apf_lockstep
    from hybridnav.fuzzy.family import SystemFamily
    from hybridnav.tuner.evaluate import lockstep_effc, scenario_set
    from hybridnav.tuner.heldout import baseline
    from hybridnav.tuner.run import _lockstep_traces
    from hybridnav.world import load_scenario
    from hybridnav.world.generator import WorldGenerator

    scen = [load_scenario("effc-env-a"), load_scenario("effc-env-b")] \
        + WorldGenerator().generate(3, seed=4)
    fis = fuzzy.builtin("effc-5rule")
    settings = {"speed": 0.1, "max_turn": np.pi / 4, "stuck_window": 10.0, "stuck_radius": 2.0,
                "safety_margin": 0.05}
    runs = (("start", "effc", {"fis": fis, **settings}), ("apf", "apf", baseline(settings)))
    traces = _lockstep_traces(scen, runs)
    st = scenario_set(scen)
    fam = SystemFamily(fis)
    ref = [lockstep_effc(st, fam, fam.tables_of([fis]), 1, settings, record_paths=True),
           apf_lockstep(st, baseline(settings), record_paths=True)]
    assert len(traces) == len(scen) * 2
    for e in range(len(scen)):
        for j, res in enumerate(ref):
            (tr,) = traces[e * 2 + j]
            assert tr.outcome == res.outcome[e, 0] and tr.path_length == res.path_length[e, 0]
            assert tr.t_end == res.time[e, 0]
            assert len(tr.xy) == round(res.time[e, 0] / 0.1) + 1
            assert np.array_equal(tr.xy[-1], res.final_states[e, 0, :2])
    # worlds of two control cycles cannot be batched together: the planners run instead
    import dataclasses

    assert _lockstep_traces(scen + [dataclasses.replace(scen[0], dt=0.05)], runs) is None


def test_the_convergence_figure_ticks_whole_generations():
    """Generations are whole numbers: the convergence figure has no fractional ticks, even for a
    short run (matplotlib's default locator puts 0.5 steps on a 3-generation axis)."""
    import pandas as pd

    from hybridnav.tuner.run import _convergence

    log = pd.DataFrame({"gen": [0, 1, 2, 3], "min": [3.0, 2.5, 2.2, 2.1],
                        "mean": [9.0, 5.0, 3.0, 2.5], "val_gen": [3.2, 2.7, 2.6, 2.4],
                        "val_best": [3.2, 2.7, 2.6, 2.4]})
    result = types.SimpleNamespace(logbook=log, best_generation=3, objective_names=("rmse",),
                                   system=types.SimpleNamespace(name="x"))
    fig = _convergence(result)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig).draw()
    ticks = fig.axes[0].get_xticks()
    lo, hi = fig.axes[0].get_xlim()
    shown = [t for t in ticks if lo <= t <= hi]
    assert shown and all(float(t).is_integer() for t in shown), shown


def test_path_legends_give_the_length_unit():
    """``plot_traces`` / ``plot_result`` legends carry the scenario's length unit, and the
    outcome marker at the path's end."""
    from hybridnav.plotting import Trace, plot_traces
    from hybridnav.world import load_scenario

    s = load_scenario("effc-env-b")
    fig = plot_traces(s, [Trace("robot", np.array([[0.0, 0.0], [1.0, 1.0]]), "reached", 1.414,
                                None, 14.1)])
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts == [f"robot: reached, length 1.41 {s.units}", "end: reached"]
