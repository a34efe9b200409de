"""The comparison harness: tables, seeds, and identical results on any backend."""

from __future__ import annotations

import pandas as pd
import pytest

from hybridnav import HybridnavError
from hybridnav.experiments.compare import RUN_COLUMNS, compare, run_seed, write_comparison

ARGS = (["apf", "pbpf"], ["effc-train-1", "effc-train-2"], 2)
PARAMS = {"pbpf": {"population": 3, "generations": 1}}


@pytest.fixture(scope="module")
def serial():
    return compare(*ARGS, seed=5, params=PARAMS)


def _same(a: pd.DataFrame, b: pd.DataFrame):
    cols = [c for c in a.columns if not c.startswith(("compute_time", "time_with_planning"))]
    pd.testing.assert_frame_equal(a[cols], b[cols])


def test_tables_have_the_contract_columns(serial, tmp_path):
    table, summary = serial
    assert list(table.columns) == RUN_COLUMNS
    assert len(table) == 2 * 2 * 2
    assert set(table["seed"]) == {run_seed(5, 0), run_seed(5, 1)}
    assert {"success_rate", "path_length_mean", "path_length_std", "path_length_min",
            "path_length_max", "time_to_goal_mean", "min_clearance_mean",
            "compute_time_mean"} <= set(summary.columns)
    ok = table[(table.planner == "apf") & (table.scenario == "effc-train-1")]
    row = summary[(summary.planner == "apf") & (summary.scenario == "effc-train-1")].iloc[0]
    assert row.success_rate == (ok.outcome == "reached").mean()
    assert row.path_length_mean == pytest.approx(ok[ok.outcome == "reached"].path_length.mean())
    files = write_comparison(tmp_path, table, summary)
    assert (tmp_path / "runs.csv").exists() and "compare_success_rate.png" in files
    back = pd.read_csv(tmp_path / "runs.csv")
    assert list(back.columns) == RUN_COLUMNS and len(back) == len(table)


def test_two_local_workers_give_the_same_tables(serial):
    table, summary = compare(*ARGS, seed=5, params=PARAMS, workers=2)
    _same(table, serial[0])
    _same(summary, serial[1])


def test_workers_are_kept_between_calls_and_need_not_share_the_working_directory(
        serial, tmp_path, monkeypatch):
    """The local pool outlives a call (workers start once), its units go out longest expected
    first, and a scenario named by a path relative to the caller's directory reaches workers
    forked elsewhere (the loaded scenario travels, not its name)."""
    import os

    from hybridnav.experiments import compare as module
    from hybridnav.backends import shared_backend
    from hybridnav.world import load_scenario, save_scenario

    compare(*ARGS, seed=5, params=PARAMS, workers=2)                  # the pool exists now
    pool = shared_backend(2).backend._pool
    assert pool is not None
    save_scenario(load_scenario("effc-train-2"), tmp_path / "here.toml")
    monkeypatch.chdir(tmp_path)
    again, _ = compare(["apf", "pbpf"], ["effc-train-1", "here.toml"], 2, seed=5,
                       params=PARAMS, workers=2)
    assert shared_backend(2).backend._pool is pool                    # the same processes
    assert os.getcwd() == str(tmp_path)
    _same(again.drop(columns="scenario"), serial[0].drop(columns="scenario"))
    tasks = [module._Task("a", "apf", (), str(k), 0, 0) for k in range(8)]
    monkeypatch.setattr(module, "_SECONDS", {("a", "apf", (), str(k)): float(k)
                                              for k in range(8)})
    units = module._units(tasks, 8, 1, 2)
    assert [u[0].scenario for u in units] == [str(k) for k in range(7, -1, -1)]
    assert module._units(tasks, 8, 1, 1) == [[t] for t in tasks]    # one worker: in order


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_tables(serial):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        table, summary = compare(*ARGS, seed=5, params=PARAMS, dask=client)
    _same(table, serial[0])
    _same(summary, serial[1])


def test_bad_requests_fail_before_any_work():
    with pytest.raises(HybridnavError, match="unknown planner 'nope'"):
        compare(["nope"], ["effc-train-1"], 1)
    with pytest.raises(HybridnavError, match="fixed goals only|does not handle moving targets"):
        compare(["hapf"], ["pso-ba-dynamic"], 1)
    with pytest.raises(HybridnavError, match="runs: expected a positive number"):
        compare(["apf"], ["effc-train-1"], 0)
    with pytest.raises(HybridnavError, match="'hapf' is not one of the compared planners"):
        compare(["apf"], ["effc-train-1"], 1, params={"hapf": {"margin": 0.1}})


# --- labelled planner variants ----------------------------------------------------------------

def test_variants_of_one_planner_match_running_it_directly(tmp_path):
    from hybridnav import planners
    from hybridnav.world import load_scenario

    variants = {"effc": {}, "fast": {"speed": 0.2}, "slow": {"speed": 0.05, "max_turn": 0.5}}
    table, summary = compare(["effc", "effc@fast:speed=0.2", ("slow", "effc", variants["slow"])],
                             ["effc-train-1"], 2, seed=3)
    assert list(table.columns) == RUN_COLUMNS and RUN_COLUMNS[11:] == [
        "planner_name", "control_effort", "min_robot_clearance"]
    assert list(dict.fromkeys(table.planner)) == ["effc", "fast", "slow"]
    assert set(table.planner_name) == {"effc"}
    assert list(summary.planner) == ["effc", "fast", "slow"]
    scenario = load_scenario("effc-train-1")
    for label, params in variants.items():
        rows = table[table.planner == label]
        assert list(rows.run) == [0, 1]
        for r in range(2):
            res = planners.get("effc", **params).run(scenario, seed=run_seed(3, r)).robots[0]
            row = rows[rows.run == r].iloc[0]
            assert row.outcome == res.outcome
            assert row.path_length == res.path_length
    lengths = table[table.run == 0].set_index("planner").path_length
    assert len(set(lengths)) == 3               # the parameters made a difference
    write_comparison(tmp_path, table, summary)
    back = pd.read_csv(tmp_path / "runs.csv")
    assert list(back.columns) == RUN_COLUMNS and set(back.planner) == {"effc", "fast", "slow"}


def test_set_applies_by_label_and_the_variant_wins():
    table, _ = compare(["effc", "effc@fast:speed=0.2"], ["effc-train-1"], 1,
                       params={"fast": {"speed": 0.05, "max_turn": 0.5}, "effc": {"speed": 0.2}})
    direct, _ = compare([("a", "effc", {"speed": 0.2}), ("b", "effc", {"speed": 0.2,
                                                                      "max_turn": 0.5})],
                        ["effc-train-1"], 1)
    assert list(table.path_length) == list(direct.path_length)
    with pytest.raises(HybridnavError, match=r"'effc' is not one of the compared planners "
                                             r"\(a, b\)"):
        compare(["effc@a", "effc@b"], ["effc-train-1"], 1, params={"effc": {"speed": 0.2}})


def test_relative_fis_paths_survive_a_worker_in_another_directory(tmp_path, monkeypatch):
    import os

    from hybridnav import fuzzy
    from hybridnav.experiments import compare as module

    (tmp_path / "tuned").mkdir()
    fuzzy.builtin("effc-5rule").save(tmp_path / "tuned" / "fis.json")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    real = module._execute

    def in_another_directory(task):            # what a Dask worker with another cwd would see
        here = os.getcwd()
        os.chdir(elsewhere)
        try:
            return real(task)
        finally:
            os.chdir(here)

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(module, "_execute", in_another_directory)
    table, _ = compare(["effc@five:fis=tuned/fis.json", "effc@builtin:fis=effc-5rule"],
                       ["effc-train-1"], 1)
    assert list(table.planner) == ["five", "builtin"]
    assert table.path_length[0] == table.path_length[1]


@pytest.mark.parametrize("planners, message", [
    (["effc", "apf", "effc"], r"--planners effc: duplicate label 'effc' \(items 1 and 3\)"),
    (["effc@x", "apf@x"], r"--planners apf@x: duplicate label 'x'"),
    (["effc@apf"], r"--planners effc@apf: the label 'apf' is the name of another planner"),
    (["effc:speed=0.2"], r"--planners effc:speed=0.2: a variant with parameters needs a label"),
    (["effc@"], r"--planners effc@: expected a label after '@'"),
    (["effc@a:speed"], r"--planners effc@a:speed: 'speed': expected key=value"),
    (["effc@a:speed=1:speed=2"], r"speed: set twice"),
    (["nope@a"], r"--planners nope@a: planner: unknown planner 'nope'"),
    (["effc@a:nope=1"], r"--planners effc@a:nope=1: planner effc: unknown parameter 'nope'"),
    (["effc@a:speed=fast"], r"--planners effc@a:speed=fast: .*speed: expected a number"),
    (["effc@a:fis=missing.json"], r"--planners effc@a:fis=missing.json: missing.json: cannot read"),
    ([("a", "effc", {"speed": -1.0})], r"--planners effc@a:speed=-1.0: .*expected a positive number"),
    ([], r"--planners: expected at least one planner"),
    ([3], r"planners\[0\]: expected NAME"),
])
def test_bad_planner_items_fail_before_any_run(planners, message, monkeypatch):
    from hybridnav.experiments import compare as module

    def no_runs(task):
        raise AssertionError("a run started")

    monkeypatch.setattr(module, "_execute", no_runs)
    with pytest.raises(HybridnavError, match=message):
        compare(planners, ["effc-train-1"], 1)


def test_cli_compares_two_variants_of_effc(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "cmp"
    proc = subprocess.run([sys.executable, "-m", "hybridnav.cli", "compare", "--planners",
                           "effc,effc@five:fis=effc-5rule", "--scenarios", "effc-train-1",
                           "--runs", "1", "--set", "five.speed=0.12", "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    import json

    from hybridnav import __version__

    settings = json.loads((out / "comparison.json").read_text())   # what was compared
    assert settings["version"] == __version__ and settings["runs"] == 1
    assert settings["planners"] == ["effc", "effc@five:fis=effc-5rule"]
    assert settings["set"] == {"five": {"speed": "0.12"}}
    runs = pd.read_csv(out / "runs.csv")
    assert list(runs.columns) == RUN_COLUMNS
    assert list(runs.planner) == ["effc", "five"] and list(runs.planner_name) == ["effc", "effc"]
    assert list(pd.read_csv(out / "summary.csv").planner) == ["effc", "five"]
    bad = subprocess.run([sys.executable, "-m", "hybridnav.cli", "compare", "--planners",
                          "effc,effc", "--scenarios", "effc-train-1", "--runs", "1", "--out",
                          str(tmp_path / "bad")], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert "hybridnav: error: --planners effc: duplicate label 'effc'" in bad.stderr
    assert not (tmp_path / "bad").exists()


@pytest.mark.long
def test_cli_dask_local_keeps_the_cluster_chatter_out_of_the_progress_bar(tmp_path):
    """``--dask local`` used to print distributed's INFO lines (scheduler, nanny, connections)
    into the progress bar: without -vvv only warnings of other libraries reach stderr."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")}
    proc = subprocess.run([sys.executable, "-m", "hybridnav.cli", "compare", "--planners", "apf",
                           "--scenarios", "effc-train-1", "--runs", "2", "--dask", "local",
                           "-o", str(tmp_path / "out")], capture_output=True, text=True,
                          env=env, timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "INFO" not in proc.stderr and "distributed" not in proc.stderr
    assert (tmp_path / "out" / "summary.csv").exists()


def test_summary_statistics_against_scipy(serial, tmp_path):
    """Medians, 95 % intervals of the mean (Student's t), best and worst runs with their own
    times, and the pairwise Mann-Whitney U p-values, recomputed from runs.csv with scipy."""
    import numpy as np
    from scipy import stats

    table, summary = serial
    for _, row in summary.iterrows():
        g = table[(table.planner == row.planner) & (table.scenario == row.scenario)]
        ok = g[g.outcome == "reached"]
        v = ok.path_length.astype(float).to_numpy()
        if len(v) >= 2:
            lo, hi = ((v.mean(), v.mean()) if np.all(v == v[0]) else   # scipy: nan at sem 0
                      stats.t.interval(0.95, len(v) - 1, loc=v.mean(), scale=stats.sem(v)))
            assert row.path_length_ci95_lo == pytest.approx(lo, rel=1e-12, abs=1e-12)
            assert row.path_length_ci95_hi == pytest.approx(hi, rel=1e-12, abs=1e-12)
        if len(v):
            assert row.path_length_median == np.median(v)
            best = ok.loc[ok.path_length.astype(float).idxmin()]
            assert (row.best_path_length, row.best_time_to_goal) == (best.path_length,
                                                                     best.time_to_goal)
        assert row.units == "m"
        other = "pbpf" if row.planner == "apf" else "apf"
        w = table[(table.planner == other) & (table.scenario == row.scenario)
                  & (table.outcome == "reached")].path_length.astype(float).to_numpy()
        p = row[f"path_length_p_vs_{other}"]
        if len(v) and len(w):
            assert p == stats.mannwhitneyu(v, w, alternative="two-sided").pvalue
        else:
            assert np.isnan(p)
    files = write_comparison(tmp_path, table, summary)
    assert {"paths_effc-train-1.png", "paths_effc-train-2.png",
            "compare_compute_time.png"} <= set(files)


@pytest.mark.slow
def test_convergence_of_the_swarm_searches_is_recorded_per_run_and_plotted(tmp_path):
    """Every run's searches land in ``convergence.csv``: PSO's one search per run (its best
    never rises, and its last value is the cost the planner reports), a step planner's one
    search per plan call, PBPF's gain search; A* searches with no swarm and has no rows."""
    from hybridnav import planners
    from hybridnav.world import load_scenario

    specs = ["pso@pso:iterations=15:particles=10", "fastep-kinematic",
             "pbpf@pbpf:population=3:generations=2", "astar"]
    table, summary = compare(specs, ["fastep-s3"], 2, seed=3)
    files = write_comparison(tmp_path, table, summary)
    assert "convergence.csv" in files and "convergence_fastep-s3.png" in files
    conv = pd.read_csv(tmp_path / "convergence.csv")
    assert set(conv["planner"]) == {"pso", "fastep-kinematic", "pbpf"}
    for (label, run, plan), g in conv.groupby(["planner", "run", "plan"]):
        best = g.sort_values("iteration")["best"].dropna().to_numpy()
        assert (best[1:] <= best[:-1]).all(), (label, run, plan)      # elitist
        assert list(g["iteration"]) == list(range(len(g)))
    s = load_scenario("fastep-s3")
    found = 0
    for run in (0, 1):
        seed = int(table[(table.planner == "pso") & (table.run == run)]["seed"].iloc[0])
        res = planners.get("pso", iterations=15, particles=10).run(s, seed=seed)
        mine = conv[(conv.planner == "pso") & (conv.run == run)]
        assert set(mine["plan"]) == {0} and len(mine) == 16
        planned = res.robots[0].metrics["planned_length"]       # None: no collision-free path
        assert planned is None or mine["best"].iloc[-1] == pytest.approx(planned)
        found += planned is not None
        fa = planners.get("fastep-kinematic").run(s, seed=seed).robots[0]
        steps = conv[(conv.planner == "fastep-kinematic") & (conv.run == run)]
        assert steps["plan"].nunique() == fa.metrics["planning_calls"]
    assert found                                  # the search's last best is the path's length


def test_bars_are_honest():
    """compare's bar figures: a planner that never reached is marked ``n = 0``, a success rate
    carries its Wilson interval, and no interval leaves its metric's range (lengths and times
    are not negative; a rate stays in [0, 1])."""
    import numpy as np
    import pandas as pd

    from hybridnav.experiments.compare import _bars
    from hybridnav.tuner.heldout import wilson

    summary = pd.DataFrame({
        "planner": ["a", "b"], "scenario": ["s", "s"], "robots": [10, 10],
        "success_rate": [0.9, 0.0], "units": ["m", "m"],
        "compute_time_mean": [0.05, 0.3], "compute_time_ci95_lo": [-0.27, 0.1],
        "compute_time_ci95_hi": [0.37, 0.5],
        "path_length_mean": [5.0, np.nan], "path_length_ci95_lo": [4.0, np.nan],
        "path_length_ci95_hi": [6.0, np.nan]})
    fig = _bars(summary, "path_length", "path length [{units}] (reached)")
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.texts] == ["n = 0"]
    assert ax.get_title() != ax.get_ylabel()
    fig = _bars(summary, "compute_time", "compute time [s]")
    segs = [c for c in fig.axes[0].collections]
    lows = [min(seg[0][1], seg[1][1]) for col in segs for seg in col.get_segments()]
    assert lows and min(lows) >= 0.0
    fig = _bars(summary, "success_rate", "success rate")
    segs = [seg for col in fig.axes[0].collections for seg in col.get_segments()]
    spans = sorted((round(min(a[1], b[1]), 9), round(max(a[1], b[1]), 9)) for a, b in segs)
    want = sorted(tuple(round(v, 9) for v in wilson(k, 10)) for k in (9, 0))
    assert spans == want and all(0.0 <= lo <= hi <= 1.0 for lo, hi in spans)
