"""The software-in-the-loop check of a tuning job with local workers runs in a process of its own
while the path figure is drawn (``hybridnav.tuner.run._SideTask``); one worker, or Dask, keeps
it in this process. A side process that dies leaves the check to this process."""

from __future__ import annotations

import os

import pytest

import hybridnav.tuner.run as run
from hybridnav.cli import main

from tests.test_tuner import SMALL

PARENT = os.getpid()


def _pid() -> int:
    return os.getpid()


def _dies_elsewhere() -> str:
    if os.getpid() != PARENT:
        os._exit(3)                      # the side process dies without a word
    return "here"


def test_the_side_process_runs_the_task_elsewhere_and_only_when_asked():
    with run._SideTask(_pid, elsewhere=True) as side:
        assert side.elsewhere
        assert side.result() != os.getpid()
    with run._SideTask(_pid, elsewhere=False) as side:
        assert not side.elsewhere and side._future is None
        assert side.result() == os.getpid()


def test_a_side_process_that_dies_leaves_the_task_to_this_one(caplog):
    with run._SideTask(_dies_elsewhere, elsewhere=True) as side:
        assert side.result() == "here"
    assert "the process of _dies_elsewhere died; running it here" in caplog.text


def _sil_where(system, c_file, worlds, planner):
    assert c_file.name == "effc.c" and c_file.exists() and len(worlds) == 3
    return ["", f"SIL ran in process {os.getpid()}"]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_job_checks_its_c_export_beside_the_path_figure_with_local_workers(
        tmp_path, monkeypatch, capsys, workers):
    monkeypatch.setattr(run, "_sil_lines", _sil_where)
    monkeypatch.setattr(run, "_paths", lambda *a, **k: [])      # (what the check overlaps)
    job = tmp_path / "job.toml"
    job.write_text(SMALL.replace("[falsify]\nbudget = 60", "[falsify]\nbudget = 0"))
    out = tmp_path / "out"
    assert main(["tune", str(job), "--out", str(out), "--workers", str(workers)]) == 0
    where = int((out / "report.md").read_text().split("SIL ran in process ")[1].split()[0])
    assert (where != os.getpid()) == (workers == 2)
    said = capsys.readouterr().out
    assert ("against evaluate (run meanwhile)" in said) == (workers == 2)
