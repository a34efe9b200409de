"""The general tuner: any fuzzy system, any cost (data, navigation, a user's function), any
optimizer (GA, CMA-ES, PSO, NSGA-II), through ``tune(system, cost, ...)`` and job files."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest

from hybridnav import HybridnavError, fuzzy
from hybridnav.backends import DaskBackend, ProcessBackend
from hybridnav.fuzzy.export._common import normalize
from hybridnav.tuner import (
    CMAES,
    Candidates,
    GA,
    NSGA2,
    PSO,
    DataCost,
    FunctionCost,
    KFold,
    NavigationCost,
    TunableSettings,
    TuningResult,
    learn,
    load_job,
    tune,
)
from hybridnav.tuner.optimizers import non_dominated

TIPPER = """[System]
Name='tipper'
Type='mamdani'
Version=2.0
NumInputs=2
NumOutputs=1
NumRules=3
AndMethod='min'
OrMethod='max'
ImpMethod='min'
AggMethod='max'
DefuzzMethod='centroid'

[Input1]
Name='service'
Range=[0 10]
NumMFs=3
MF1='poor':'gaussmf',[1.5 0]
MF2='good':'gaussmf',[1.5 5]
MF3='excellent':'gaussmf',[1.5 10]

[Input2]
Name='food'
Range=[0 10]
NumMFs=2
MF1='rancid':'trapmf',[0 0 1 3]
MF2='delicious':'trapmf',[7 9 10 10]

[Output1]
Name='tip'
Range=[0 30]
NumMFs=3
MF1='cheap':'trimf',[0 5 10]
MF2='average':'trimf',[10 15 20]
MF3='generous':'trimf',[20 25 30]

[Rules]
1 1, 1 (1) : 2
2 0, 2 (1) : 1
3 2, 3 (1) : 2
"""


def perturbed(system, frac, rng):
    """``system`` with every MF parameter moved by up to ``frac`` of its variable's range."""
    d = system.to_dict()
    for v in d["inputs"] + [d["output"]]:
        w = v["range"][1] - v["range"][0]
        for t in v["terms"]:
            p = np.array(t["params"]) + rng.uniform(-frac, frac, len(t["params"])) * w
            if t["mf"] in ("trimf", "trapmf", "zmf", "smf"):
                p = np.sort(p)
            if t["mf"] == "gaussmf":
                p[1] = abs(p[1]) + 0.05 * w
            t["params"] = p.tolist()
    return fuzzy.FuzzySystem.from_dict(d)


def samples(system, n, seed):
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(*v.range, n) for v in system.inputs])
    y = system.evaluate(**{v.name: X[:, i] for i, v in enumerate(system.inputs)})
    return X, y


@pytest.fixture(scope="module")
def target():
    return fuzzy.builtin("effc-5rule")


def test_data_tuning_recovers_a_known_system_on_held_out_samples(target):
    """500 samples of a known system; the start has every MF parameter perturbed; the tuned
    system's RMSE on 2,000 other samples is below 1 % of the output range."""
    start = perturbed(target, 0.08, np.random.default_rng(1))
    X, y = samples(target, 500, 2)
    Xt, yt = samples(target, 2000, 3)
    test = DataCost(Xt, yt)
    res = tune(start, DataCost(X, y), optimizer=PSO(), validation=0.2, test=test, seed=3)
    assert isinstance(res, TuningResult) and res.selected_by == "validation"
    width = target.output.range[1] - target.output.range[0]
    err = test.judge({"tuned": res.system, "start": start})
    rmse = dict(zip(err.system, err.objective_0))
    assert rmse["start"] > 0.05 * width                 # the start is far off
    assert rmse["tuned"] < 0.01 * width                  # the acceptance bound
    # the judged table and verdict in the result are the same numbers
    held = res.heldout[res.heldout.set == "test"].set_index("system")
    assert held.loc["tuned", "objective_0"] == pytest.approx(rmse["tuned"], rel=1e-12)
    assert res.verdicts["test"]["better"]
    # the logbook's best never gets worse for an elitist search and matches the records
    assert list(res.logbook.columns[:3]) == ["gen", "evals", "min"]
    assert res.evaluations == int(res.logbook.evals.sum())


def test_tipper_fis_round_trip_through_data_tuning(tmp_path):
    """A MATLAB .fis read, tuned on data, written as .fis and read back equals the tuned
    system."""
    tipper = fuzzy.read_fis(TIPPER, "tipper.fis")
    rng = np.random.default_rng(5)
    X, y = samples(perturbed(tipper, 0.05, rng), 300, 6)
    settings = TunableSettings(tipper).fix("tip")          # tune the inputs' terms only
    assert settings.size == 3 * 2 + 2 * 4
    res = tune(tipper, DataCost(pd.DataFrame({"food": X[:, 1], "service": X[:, 0]}), y),
               settings=settings, optimizer=CMAES(generations=30), seed=2)
    assert res.objectives[0] < res.start_objectives[0]
    for t0, t1 in zip(tipper.output.terms, res.system.output.terms):
        assert t0.params == t1.params                       # fixed stays fixed
    path = tmp_path / "tuned.fis"
    fuzzy.export_to_file(res.system, "fis", path)
    back = fuzzy.load_any(str(path))
    assert back == normalize(res.system, flat=True)
    Xg, _ = samples(tipper, 200, 9)
    a = back.evaluate(service=Xg[:, 0], food=Xg[:, 1])
    b = res.system.evaluate(service=Xg[:, 0], food=Xg[:, 1])
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


@pytest.mark.parametrize("optimizer, tol", [
    (GA(population=30, generations=40), 2e-3),
    (CMAES(generations=60), 1e-4),
    (PSO(n=20, generations=60), 1e-4),
])
def test_each_optimizer_reaches_a_known_optimum(target, optimizer, tol):
    """Two free numbers (effc-5rule's dtheta term 'high' moved off): the optimum is the target's
    own parameters, RMSE 0."""
    d = target.to_dict()
    d["inputs"][0]["terms"][1]["params"] = [0.6, 1.5]
    start = fuzzy.FuzzySystem.from_dict(d)
    settings = TunableSettings(start, mf=["dtheta.high"])
    X, y = samples(target, 200, 4)
    res = tune(start, DataCost(X, y), settings=settings, optimizer=optimizer, seed=1,
               patience=0)
    assert res.start_objectives[0] > 0.02 and res.objectives[0] < tol
    assert np.all((settings.lower <= res.x) & (res.x <= settings.upper))


def _two_objectives(candidates, context):
    """(a, (1 - a)^2) of the first free number a: the front is a in [0, 1]."""
    a = candidates.X[:, 0]
    return np.column_stack([a, (1.0 - a) ** 2])


def test_nsga2_front_is_non_dominated_and_covers_the_trade_off(target):
    settings = TunableSettings(target, mf=["w.high.smf[1]"])      # b of smf(0.3, b)
    cost = FunctionCost(_two_objectives, batch=True, objectives=["a", "b"])
    res = tune(target, cost, settings=settings, optimizer=NSGA2(population=40, generations=30),
               seed=2)
    F = res.front[["objective_0", "objective_1"]].to_numpy()
    assert non_dominated(F).all() and len(F) >= 10
    a = F[:, 0]
    assert a.min() < 0.35 and a.max() > 0.95              # the whole trade-off b in (0.3, 1]
    np.testing.assert_allclose(F[:, 1], (1 - a) ** 2, atol=1e-12)
    assert res.front.returned.sum() == 1 and len(res.members) == len(F)
    for m, row in zip(res.members, F):
        assert m.system.output.terms[1].params[1] == pytest.approx(row[0], abs=1e-12)


def test_nsga2_front_has_one_member_per_distinct_system(target):
    """Vectors that differ only in genes the system does not use (a switched-off rule slot's
    terms) are one member of the front (the front was once 40 rows of one system); different
    systems with equal objectives stay apart (validation may tell them apart)."""
    settings = TunableSettings.learning(target, 4, keep_rules=False)

    def rules_on(candidates, context):
        on = candidates.settings.arrays(candidates.X)[4].sum(axis=1).astype(float)
        return np.column_stack([on, -on])

    res = tune(settings.template, FunctionCost(rules_on, batch=True, objectives=["on", "minus"]),
               settings=settings, optimizer=NSGA2(population=40, generations=3), seed=1)
    systems = [json.dumps(m.system.to_dict(), sort_keys=True) for m in res.members]
    assert len(set(systems)) == len(systems) == len(res.front)
    # the population's non-dominated rows (the logbook counts them) held repeats of a system
    assert len(res.front) < res.logbook["front"].iloc[-1]
    assert non_dominated(res.front[["objective_0", "objective_1"]].to_numpy()).all()


def test_a_checkpoint_write_that_fails_stops_the_run_with_its_error(tmp_path, target,
                                                                     monkeypatch):
    """Checkpoints are written in the background: a failed write (a full disk) still ends the
    run with that error, and what was written before it stays a valid checkpoint."""
    import hybridnav.tuner.core as core

    X, y = samples(target, 100, 8)
    real, calls = core.atomic_write_text, []

    def failing(path, text):
        calls.append(path)
        if len(calls) == 3:
            raise HybridnavError(f"{path}: cannot write (No space left on device)")
        return real(path, text)

    monkeypatch.setattr(core, "atomic_write_text", failing)
    with pytest.raises(HybridnavError, match="No space left on device"):
        tune(target, DataCost(X, y), optimizer=GA(population=6, generations=6),
             checkpoint=tmp_path, seed=1)
    monkeypatch.setattr(core, "atomic_write_text", real)
    done = tune(target, DataCost(X, y), optimizer=GA(population=6, generations=6),
                checkpoint=tmp_path, resume=True, seed=1)
    fresh = tune(target, DataCost(X, y), optimizer=GA(population=6, generations=6), seed=1)
    assert np.array_equal(done.x, fresh.x)


def test_results_do_not_depend_on_the_backend_and_resume_exactly(tmp_path, target):
    start = perturbed(target, 0.05, np.random.default_rng(7))
    X, y = samples(target, 200, 8)
    cost = DataCost(X, y)
    kw = dict(optimizer=CMAES(generations=6), validation=KFold(2), seed=4, chunk=3)
    serial = tune(start, cost, **kw)
    with ProcessBackend(2) as be:
        par = tune(start, cost, backend=be, **kw)
    assert np.array_equal(par.x, serial.x)
    pd.testing.assert_frame_equal(par.logbook.drop(columns="wall_time"),
                                  serial.logbook.drop(columns="wall_time"))
    tune(start, cost, checkpoint=tmp_path, stop_after=9, **kw)      # inside stage 1
    resumed = tune(start, cost, checkpoint=tmp_path, resume=True, **kw)
    assert np.array_equal(resumed.x, serial.x)
    pd.testing.assert_frame_equal(resumed.logbook.drop(columns="wall_time"),
                                  serial.logbook.drop(columns="wall_time"))
    pd.testing.assert_frame_equal(resumed.records, serial.records)
    with pytest.raises(HybridnavError, match="different configuration"):
        tune(start, cost, checkpoint=tmp_path, resume=True, **{**kw, "seed": 5})


MODULE = '''
import numpy as np

def cost(system):
    """Squared distance of the output at three points from 0.25."""
    w = system.evaluate(dtheta=[0.1, 0.8, 1.4], alpha=[0.1, 1.0, 1.9])
    return float(np.sum((w - 0.25) ** 2))
'''


@pytest.mark.slow
def test_function_cost_from_a_module_runs_on_local_workers_and_dask(tmp_path, target):
    (tmp_path / "mycost.py").write_text(MODULE)
    cost = FunctionCost("mycost:cost", path=tmp_path)
    kw = dict(optimizer=PSO(n=8, generations=3), seed=6, chunk=3)
    serial = tune(target, cost, **kw)
    assert serial.objectives[0] < serial.start_objectives[0]
    with ProcessBackend(2) as be:
        par = tune(target, cost, backend=be, **kw)
    with DaskBackend("", workers=2) as be:
        dask = tune(target, cost, backend=be, **kw)
    assert np.array_equal(par.x, serial.x) and np.array_equal(dask.x, serial.x)


def test_navigation_cost_needs_the_planners_inputs():
    tipper = fuzzy.read_fis(TIPPER, "tipper.fis")
    from hybridnav.world import load_scenario

    cost = NavigationCost([load_scenario("effc-train-1")])
    with pytest.raises(HybridnavError, match="the effc planner provides the fuzzy inputs "
                                             "dtheta, alpha \\(and optionally clearance\\); 'tipper' has "
                                             "service, food"):
        tune(tipper, cost)
    with pytest.raises(HybridnavError, match="planner: expected a planner that takes a fuzzy "
                                             "system"):
        NavigationCost([load_scenario("effc-train-1")], planner="apf")


@pytest.mark.parametrize("call, text", [
    (lambda t: GA(population=1), "ga: population: expected an integer in [2, 100000], got 1"),
    (lambda t: GA(crossover="uniform"), "ga: crossover: expected a crossover operator"),
    (lambda t: NSGA2(population=10), "expected a multiple of 4"),
    (lambda t: CMAES(sigma=0), "cmaes: sigma: expected a number in (0, 10]"),
    (lambda t: PSO(speed=1), "pso: speed: unknown setting"),
    (lambda t: tune(t, DataCost(np.ones((3, 3)), np.ones(3))),
     "inputs: expected 2 columns (the system's inputs dtheta, alpha), got 3"),
    (lambda t: tune(t, DataCost(pd.DataFrame({"dtheta": [1.0], "beta": [1.0]}), [0.5])),
     "alpha: expected a column for every input"),
    (lambda t: DataCost([[1, np.nan]], [1.0]), "row 0: expected finite numbers"),
    (lambda t: tune(t, FunctionCost(lambda s: 1.0), optimizer=GA(), seed=-1),
     "seed: expected a non-negative integer"),
    (lambda t: tune(t, FunctionCost(lambda s: [1.0, 2.0]), optimizer=GA(population=4,
                                                                        generations=0)),
     "expected objectives of shape (4, 1), got (4, 2)"),
    (lambda t: tune(t, FunctionCost(lambda s: [1.0, 2.0], objectives=2), optimizer=GA()),
     "the cost has 2 objectives; expected one (use NSGA2 for several)"),
    (lambda t: FunctionCost("nosuchmodule:f"), "cannot import module 'nosuchmodule'"),
    (lambda t: TunableSettings(t).fix("w.middle"), "w has no term 'middle'"),
    (lambda t: TunableSettings(t, mf=False).rules(), "nothing"),
])
def test_bad_calls_fail_with_the_exact_error(target, call, text):
    with pytest.raises(HybridnavError) as info:
        r = call(target)
        if isinstance(r, TunableSettings):
            tune(target, FunctionCost(lambda s: 0.0), settings=r)
    assert text in str(info.value)


def test_settings_map_a_system_to_a_bounded_vector_and_back(target):
    s = TunableSettings(target).rules(switches=True, weights=True, which=[0, 2])
    assert s.size == 12 + 4
    x = s.to_vector()
    assert np.all((s.lower <= x) & (x <= s.upper))
    back = s.to_system(x)
    assert back.to_dict()["inputs"] == target.to_dict()["inputs"]
    table = s.table()
    assert list(table.gene[-4:]) == ["rule1.on", "rule1.weight", "rule3.on", "rule3.weight"]
    assert "TunableSettings of 'effc-5rule': 16 free numbers" in str(s)
    # repair restores order and clips; fixed neighbours bound a partly free term
    part = TunableSettings(target, mf=["w.high.smf[0]"])
    b = target.output.terms[1].params[1]
    assert b - 1e-5 < part.repair([[5.0]])[0, 0] < b           # a < b kept strictly


DATA_JOB = """
name = "tipper-data"
seed = 2
[system]
start = "tipper.fis"
[cost]
kind = "data"
data = "samples.csv"
validation = 0.25
test = "test.csv"
[optimizer]
kind = "cmaes"
generations = 25
[settings]
free = ["service", "food"]
rule_switches = false
"""


@pytest.mark.slow
def test_a_data_job_file_tunes_from_the_command_line(tmp_path):
    (tmp_path / "tipper.fis").write_text(TIPPER)
    tipper = fuzzy.read_fis(TIPPER, "tipper.fis")
    truth = perturbed(tipper, 0.05, np.random.default_rng(11))
    for name, n, seed in (("samples.csv", 300, 1), ("test.csv", 300, 2)):
        X, y = samples(truth, n, seed)
        pd.DataFrame({"service": X[:, 0], "food": X[:, 1], "tip": y}).to_csv(
            tmp_path / name, index=False)
    (tmp_path / "job.toml").write_text(DATA_JOB)
    job = load_job(tmp_path / "job.toml")
    assert job.optimizer().name == "cmaes" and job.validation_arg() == 0.25
    done = subprocess.run([sys.executable, "-m", "hybridnav.cli", "tune",
                           str(tmp_path / "job.toml"), "--out", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "test: on the test data the tuned system is better than its start" in done.stdout
    out = tmp_path / "o"
    summary = json.loads((out / "result.json").read_text())
    assert summary["selected_by"] == "validation" and summary["verdicts"]["test"]["better"]
    assert (out / "fis.fis").exists() and (out / "report.md").exists()
    tuned = fuzzy.load(str(out / "fis.json"))
    assert tuned.input_names == ("service", "food")


@pytest.mark.parametrize("extra, key, text", [
    ('[optimizer]\nkind = "annealing"\n', "optimizer.kind", "expected one of ga, cmaes, pso"),
    ('[optimizer]\nkind = "pso"\npopulation = 4\n', "optimizer.population",
     "unknown setting"),
    ('[optimizer]\nkind = ["ga"]\n', "optimizer.kind", "expected one of ga, cmaes"),
    ('[optimizer]\nkind = "ga"\ncrossover = {kind = "sbx", eta = -1}\n',
     "optimizer.crossover.eta", "expected a non-negative number, got -1"),
    ('[cost]\nkind = "data"\n', "cost.data", "expected a CSV file of samples"),
    ('[cost]\nkind = "data"\ndata = "missing.csv"\n', "cost.data", "missing.csv"),
    ('[cost]\nkind = "python"\nfunction = "nowhere:f"\n', "cost.function",
     "cannot import module 'nowhere'"),
    ('[settings]\nfree = ["dtheta.tiny"]\n', "settings", "dtheta has no term 'tiny'"),
    ('[settings]\nfree = []\nrule_switches = false\n', "settings", "nothing is free"),
    ('[free]\nmf = ["dtheta"]\n[settings]\nfree = ["alpha"]\n', "settings",
     "expected either [settings] or its old name [free]"),
    ('[falsify]\nbudget = 5\npopulation = 30\n', "falsify.budget",
     "expected 0 (off) or at least falsify.population (30 worlds"),
    ('[system]\nstart = "tipper.fis"\n', "system.start",
     "the effc planner provides the fuzzy inputs dtheta, alpha (and optionally clearance); "
     "'tipper' has service, food"),
])
def test_bad_job_files_fail_before_any_work(tmp_path, extra, key, text):
    (tmp_path / "tipper.fis").write_text(TIPPER)
    p = tmp_path / "bad.toml"
    p.write_text(textwrap.dedent(extra))
    with pytest.raises(HybridnavError) as info:
        load_job(p)
    msg = str(info.value)
    assert "bad.toml" in msg and f": {key}" in msg and text in msg, msg


# ---- rule learning ----------------------------------------------------------------------------

def test_learned_rule_bases_evaluate_as_the_systems_they_decode_to(target):
    """A population of learned rule bases (per slot: term, NOT term or don't care per input) in
    one batched family evaluation equals each decoded FuzzySystem's own evaluation."""
    s = TunableSettings.learning(target, 7, rule_weights=True)
    assert s.learns_rules and s.size == 7 * (1 + 2 + 1 + 1)
    rng = np.random.default_rng(4)
    X = s.random(40, rng)
    P, _ = samples(target, 300, 5)
    out = Candidates(s, X).evaluate({"dtheta": P[:, 0], "alpha": P[:, 1]})
    for k in range(len(X)):
        sk = s.to_system(X[k])
        assert 1 <= len(sk.rules) <= 7
        ref = sk.evaluate(dtheta=P[:, 0], alpha=P[:, 1])
        np.testing.assert_allclose(out[k], ref, rtol=0, atol=1e-12)
    # and a decoded system agrees with scikit-fuzzy's own Mamdani engine where a rule fires
    from skfuzzy import control as ctrl

    sk = s.to_system(X[0])
    sim = ctrl.ControlSystemSimulation(sk.to_skfuzzy(), cache=False)
    used = {a.label for a in sk.to_skfuzzy().antecedents}
    fired = Candidates(s, X[:1]).family.fired(Candidates(s, X[:1]).tables,
                                              np.zeros(20, dtype=int),
                                              {"dtheta": P[:20, 0], "alpha": P[:20, 1]})
    for k in np.flatnonzero(fired):
        for i, name in enumerate(("dtheta", "alpha")):
            if name in used:
                sim.input[name] = float(P[k, i])
        sim.compute()
        assert sim.output["w"] == pytest.approx(out[0, k], abs=1e-9)


def test_learning_starts_from_the_systems_rules_or_from_none(target):
    s = TunableSettings.learning(target, 8)
    start = s.to_system(s.to_vector())

    def parts(a):
        return frozenset(getattr(a, "items", (a,)))

    assert [parts(r.antecedent) for r in start.rules] == [parts(r.antecedent)
                                                           for r in target.rules]
    assert [r.then for r in start.rules] == [r.then for r in target.rules]
    P, _ = samples(target, 200, 3)
    np.testing.assert_allclose(start.evaluate(dtheta=P[:, 0], alpha=P[:, 1]),
                               target.evaluate(dtheta=P[:, 0], alpha=P[:, 1]), atol=1e-12)
    empty = TunableSettings.learning(target, 8, keep_rules=False)
    one = empty.to_system(empty.to_vector())
    assert len(one.rules) == 1                        # at least one rule stays on
    X, y = samples(target, 300, 6)
    res = learn(target, DataCost(X, y), max_rules=6, keep_rules=False,
                rule_optimizer=GA(population=24, generations=8), optimizer=CMAES(generations=8),
                seed=1, validation=0.25)
    assert res.learning is not None and res.learning.finished
    assert res.objectives[0] <= res.learning.objectives[0] + 1e-12     # stage 2 from stage 1
    empty_start = res.learning.start_objectives[0]                  # the empty rule base's
    assert res.objectives[0] < 0.5 * empty_start
    assert res.start is target                                      # judged against the start
    assert res.start_objectives[0] < 1e-12      # and scored as itself: the data are its own
    assert not res.start_is_candidate


# ---- a second planner that takes a fuzzy system ------------------------------------------------

def test_worldstack_nearest_each_is_the_worlds():
    from hybridnav.planners.field.worldstack import WorldStack
    from hybridnav.world import load_scenario

    worlds = [load_scenario(n).world for n in ("effc-env-a", "effc-env-b", "fastep-s2",
                                                "effc-train-1")]
    stack = WorldStack(worlds)
    rng = np.random.default_rng(2)
    for e, w in enumerate(worlds):
        x0, x1, y0, y1 = w.workspace
        P = rng.uniform([x0, y0], [x1, y1], (50, 2))
        D, near = stack.nearest_each(P, np.full(50, e), 0.7)
        Dw, nw = w.nearest_each(P, 0.7)
        k = len(w.obstacles)
        np.testing.assert_allclose(D[:, :k], Dw, atol=1e-12)
        np.testing.assert_allclose(near[:, :k], nw, atol=1e-12)
        assert np.all(np.isinf(D[:, k:]))


@pytest.mark.long
def test_fuzzy_steer_lockstep_is_the_planner_and_tunes_on_the_same_worlds(tmp_path):
    from hybridnav import planners
    from hybridnav.world.generator import WorldGenerator

    worlds = WorldGenerator().generate(6, 2027)
    start = fuzzy.builtin("steer-7rule")
    cost = NavigationCost(worlds, planner="fuzzy-steer", name="fresh")
    table = cost.judge({"start": start}, "fresh", apf=False)
    for w in worlds:
        r = planners.get("fuzzy-steer", fis=start, **cost.planner_params).run(w).robots[0]
        row = table[table.scenario == w.name].iloc[0]
        assert row.outcome == r.outcome
        assert row.path_length == pytest.approx(r.path_length, rel=1e-9)
        assert row.min_clearance == pytest.approx(r.min_clearance, rel=1e-9, abs=1e-12)
    # the same job machinery tunes it (a short run: the objective can only improve)
    res = tune(start, cost, optimizer=GA(population=8, generations=2), seed=0, judge=False)
    assert res.objectives[0] <= res.start_objectives[0]
    assert res.system.input_names == ("left", "front", "right", "bearing")


def test_navigation_objectives_for_nsga2_and_an_evaluation_budget():
    """(failure, length, clearance) on worlds: each objective is what the runs measure."""
    from hybridnav.world import load_scenario

    worlds = [load_scenario(n) for n in ("effc-train-1", "effc-train-2")]
    start = fuzzy.builtin("effc-5rule")
    cost = NavigationCost(worlds, objectives=("failure", "collision", "length", "clearance"),
                          coverage={"penalty": 0.0})
    table = cost.judge({"start": start}, "t", apf=False)
    ev = cost.assess(Candidates(TunableSettings(start, mf=False), np.zeros((1, 0))),
                     __import__("hybridnav.tuner", fromlist=["Context"]).Context())
    f = ev.objectives[0]
    reached = table.outcome == "reached"
    assert f[0] == pytest.approx(1 - reached.mean())
    assert f[1] == pytest.approx(table.outcome.isin(["collided", "out_of_bounds"]).mean())
    D = np.array([np.hypot(*np.subtract(w.robots[0].goal, w.robots[0].start))
                  - w.robots[0].goal_radius for w in worlds])
    assert f[2] == pytest.approx(np.mean((table.path_length / D)[reached]))
    assert f[3] == pytest.approx(-table.min_clearance.min())
    res = tune(start, cost, optimizer=NSGA2(population=8, generations=50), max_evals=20,
               seed=1, judge=False)
    assert 20 <= res.evaluations <= 28 and len(res.logbook) == 3      # 8 + 8 + 8, then stop
    assert res.front.shape[1] >= 5 and non_dominated(
        res.front[[f"objective_{i}" for i in range(4)]].to_numpy()).all()


# ---- found in review ---------------------------------------------------------------------------

def test_resumes_are_exact_for_cma_es_and_finished_k_fold_runs(tmp_path, target):
    X, y = samples(target, 120, 1)
    cost = DataCost(X, y)
    start = perturbed(target, 0.05, np.random.default_rng(3))
    for seed in (4, 5, 6):
        kw = dict(settings=TunableSettings(start).rules(switches=True), seed=seed,
                  optimizer=CMAES(generations=4))
        full = tune(start, cost, **kw)
        tune(start, cost, checkpoint=tmp_path / f"c{seed}", stop_after=1, **kw)
        again = tune(start, cost, checkpoint=tmp_path / f"c{seed}", resume=True, **kw)
        assert np.array_equal(again.x, full.x) and again.objectives[0] == full.objectives[0]
    kw = dict(optimizer=PSO(n=6, generations=2), validation=KFold(2), seed=1)
    done = tune(start, cost, checkpoint=tmp_path / "k", **kw)
    again = tune(start, cost, checkpoint=tmp_path / "k", resume=True, **kw)   # finished: as is
    assert np.array_equal(again.x, done.x) and len(again.logbook) == len(done.logbook)


def test_verdicts_never_read_better_than_the_data(target):
    X, y = samples(target, 60, 2)
    same = tune(target, FunctionCost(lambda s: 1.0), optimizer=GA(population=4, generations=1),
                settings=TunableSettings(target, mf=["alpha"]), test=DataCost(X, y))
    v = same.verdicts["test"]
    assert not v["better"] and "NOT better" in v["headline"]        # a tie is not better
    val = tune(target, DataCost(X, y), optimizer=GA(population=4, generations=1),
               validation=DataCost(X, y))
    assert "not an independent test" in val.verdicts["validation"]["headline"]


def test_a_start_outside_the_default_bounds_is_kept_exactly():
    tipper = fuzzy.read_fis(TIPPER.replace("[1.5 5]", "[40 5]"), "wide.fis")  # sigma 40 > 10
    X, y = samples(tipper, 80, 3)
    s = TunableSettings(tipper)
    assert np.array_equal(s.to_system(s.to_vector()).to_dict()["inputs"],
                          tipper.to_dict()["inputs"])
    res = tune(tipper, DataCost(X, y), optimizer=GA(population=4, generations=1), settings=s)
    assert res.start_objectives[0] < 1e-12                  # the real start, scored as it is


@pytest.mark.parametrize("f, text", [
    (lambda s: "abc", "expected 1 real number(s) per system, got 'abc'"),
    (lambda s: 1 / 0, "raised ZeroDivisionError: division by zero"),
    (lambda s: -np.inf, "finite or +inf"),
    (lambda s: 1 + 2j, "expected 1 real number(s)"),
])
def test_a_users_cost_function_fails_with_its_name(target, f, text):
    with pytest.raises(HybridnavError, match="cost") as info:
        tune(target, FunctionCost(f), optimizer=GA(population=4, generations=0))
    assert text in str(info.value)


def test_lambdas_are_refused_before_a_process_pool_and_damaged_checkpoints_are_named(
        tmp_path, target):
    with ProcessBackend(2) as be, pytest.raises(HybridnavError,
                                                match="cannot be sent to worker processes"):
        tune(target, FunctionCost(lambda s: 1.0), backend=be)
    X, y = samples(target, 60, 2)
    kw = dict(optimizer=GA(population=4, generations=3), seed=0, checkpoint=tmp_path)
    tune(target, DataCost(X, y), stop_after=1, **kw)
    ck = tmp_path / "checkpoint.json"
    good = ck.read_text()
    state = json.loads(good)
    del state["optimizer"]["population"]
    ck.write_text(json.dumps(state))
    with pytest.raises(HybridnavError, match="checkpoint.json: damaged checkpoint"):
        tune(target, DataCost(X, y), resume=True, **kw)
    ck.write_text(good)
    rows = (tmp_path / "evaluations.jsonl").read_text().splitlines()
    (tmp_path / "evaluations.jsonl").write_text("\n".join(rows[:2] + ["garbage"] + rows[2:]))
    with pytest.raises(HybridnavError, match="evaluations.jsonl: line 3: expected a JSON row"):
        tune(target, DataCost(X, y), resume=True, **kw)


def test_csv_headers_are_checked_and_the_output_column_found_by_name(tmp_path):
    p = tmp_path / "d.csv"
    p.write_text("service,food,food,tip\n1,2,3,4\n")
    with pytest.raises(HybridnavError, match="food: expected distinct column names"):
        DataCost.from_csv(p)
    p.write_text("service,food,tip,extra\n1,2,3,4\n2,3,4,5\n")
    c = DataCost.from_csv(p, prefer="tip")
    assert c.y.tolist() == [3.0, 4.0] and c.columns == ["service", "food", "extra"]


@pytest.mark.parametrize("extra, key, text", [
    ('[cost]\nkind = "python"\nfunction = "os:getcwd"\n[validation]\nkfold = 2\n',
     "validation.kfold", "cannot be split into folds"),
    ('[cost]\nkind = "python"\nfunction = "os:getcwd"\nvalidation = 0.3\n', "cost.validation",
     "for cost.kind = 'data'"),
    ('[cost]\nkind = "python"\nfunction = "os:getcwd"\n[scenarios]\ntrain = ["x"]\n',
     "scenarios", "expected no worlds"),
    ('[cost]\nkind = "python"\nfunction = "os:getcwd"\nobjectives = 0\n', "cost.objectives",
     "expected an integer in [1, 10]"),
    ('[cost]\nobjectives = ["failure", "speed"]\n', "cost.objectives",
     "expected a list of distinct names"),
])
def test_job_cost_combinations_that_cannot_work_fail_before_any_work(tmp_path, extra, key,
                                                                      text):
    p = tmp_path / "bad.toml"
    p.write_text(extra)
    with pytest.raises(HybridnavError) as info:
        load_job(p)
    assert f"bad.toml: {key}" in str(info.value) and text in str(info.value), str(info.value)


@pytest.mark.long
def test_rules_learned_from_an_empty_base_reach_as_often_as_the_5_rule_start(tmp_path):
    """The built-in job with ``[learning] max_rules = 8, keep_rules = false``: on its held-out
    worlds (24 validation, 32 test) the learned-then-tuned controller reaches at least as many
    as the paper's 5-rule start."""
    job = tmp_path / "learn.toml"
    job.write_text("name = \"learn\"\n[learning]\nmax_rules = 8\nkeep_rules = false\n"
                   "[falsify]\nbudget = 0\n[backend]\nworkers = 2\n")
    done = subprocess.run([sys.executable, "-m", "hybridnav.cli", "tune", str(job), "--out",
                           str(tmp_path / "o")], capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr
    s = pd.read_csv(tmp_path / "o" / "heldout_summary.csv").set_index(["set", "system"])
    for which in ("validation", "test"):
        assert s.loc[(which, "tuned"), "reached"] >= s.loc[(which, "start"), "reached"]
        assert s.loc[(which, "tuned"), "collided"] <= s.loc[(which, "start"), "collided"]


def test_min_overlap_is_kept_by_the_repair_and_rules_can_be_chosen(target):
    s = TunableSettings(target, min_overlap=0.3)
    X = s.random(300, np.random.default_rng(0))
    for x in X:
        sk = s.to_system(x)
        for v in (*sk.inputs, sk.output):
            width = v.range[1] - v.range[0]
            low, high = v.terms                     # zmf, smf: their supports' ends
            assert high.params[0] <= low.params[1] - 0.3 * width + 1e-9 * width
    s2 = TunableSettings.from_table(target, {"free": ["w"], "rule_weights": True,
                                             "rules": [2, 4]})
    assert s2.labels[-2:] == ["rule2.weight", "rule4.weight"]
    with pytest.raises(HybridnavError, match=r"rules: expected rule numbers in \[1, 5\]"):
        TunableSettings.from_table(target, {"rules": [0]})


# ---- found in the second review ----------------------------------------------------------------

def test_a_repaired_start_is_scored_as_itself_and_k_fold_stops_at_the_budget(target):
    X, y = samples(target, 100, 4)
    res = tune(target, DataCost(X, y), settings=TunableSettings(target, min_overlap=0.3),
               optimizer=GA(population=4, generations=1), seed=0)
    assert res.start_objectives[0] < 1e-12 and not res.start_is_candidate
    a = TunableSettings(target, min_overlap=0.3).key()
    assert a != TunableSettings(target).key()                     # part of the resume hash
    r = tune(target, DataCost(X, y), optimizer=GA(population=8, generations=3),
             validation=KFold(3), max_evals=10, seed=0)
    assert r.evaluations < 20 and len(r.folds) <= 1


def test_the_clearance_objective_is_finite_without_obstacles():
    from hybridnav.world import scenario_from_dict

    w = scenario_from_dict({
        "name": "empty", "dt": 0.1, "max_time": 60.0,
        "workspace": {"xmin": 0.0, "xmax": 5.0, "ymin": 0.0, "ymax": 5.0}, "obstacles": [],
        "robots": [{"name": "r", "model": "unicycle", "start": [1, 1], "goal": [4, 4],
                    "goal_radius": 0.1, "radius": 0.1}]})
    cost = NavigationCost([w], planner="fuzzy-steer", objectives=("failure", "clearance"))
    ev = cost.assess(Candidates(TunableSettings(fuzzy.builtin("steer-7rule"), mf=False),
                                np.zeros((1, 0))), __import__(
        "hybridnav.tuner", fromlist=["Context"]).Context())
    assert np.isfinite(ev.objectives).all()
    with pytest.raises(HybridnavError, match="takes heading_noise only"):
        NavigationCost([w], planner="fuzzy-steer", reward={"alpha_noise": 0.1})
