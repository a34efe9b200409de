"""The comparison harness: tables, seeds, and identical results on any backend."""

from __future__ import annotations

import pandas as pd
import pytest

from hybridnav import HybridnavError
from hybridnav.analysis.compare import RUN_COLUMNS, compare, run_seed, write_comparison

ARGS = (["apf", "pbpf"], ["effc-train-1", "effc-train-2"], 2)
PARAMS = {"pbpf": {"population": 3, "generations": 1}}


@pytest.fixture(scope="module")
def serial():
    return compare(*ARGS, seed=5, params=PARAMS)


def _same(a: pd.DataFrame, b: pd.DataFrame):
    cols = [c for c in a.columns if c != "compute_time" and not c.startswith("compute_time")]
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
