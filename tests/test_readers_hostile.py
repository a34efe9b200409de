"""The scenario and job readers on hostile files (issue 15): never a traceback, always a
HybridnavError that names the file and the key, before any work starts.

``tests/hostile/`` keeps the corpus (binary, UTF-16, NUL bytes, nesting tomllib cannot parse,
integers past Python's 4300-digit limit, workspaces, steps and grids beyond
:mod:`hybridnav.limits`, ...) and ``EXPECTED.json`` what each must say. The hypothesis tests
damage valid scenario and job files as the fuzzy readers' fuzz test does.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export_fuzz import mutated

from hybridnav import HybridnavError
from hybridnav.cli import main
from hybridnav.tuner import load_job
from hybridnav.world import Scenario, load_scenario
from hybridnav.world.builtin import _builtin_dir

CORPUS = Path(__file__).parent / "hostile"
EXPECTED = json.loads((CORPUS / "EXPECTED.json").read_text(encoding="utf-8"))


def test_every_corpus_file_has_an_expectation():
    files = {p.name for p in CORPUS.iterdir() if p.suffix == ".toml"}
    assert files == set(EXPECTED)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_a_hostile_file_fails_with_its_file_and_key(name):
    path = CORPUS / name
    read = load_scenario if name.startswith("scenario-") else load_job
    with pytest.raises(HybridnavError) as err:
        read(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: "), msg
    assert re.search(EXPECTED[name], msg[len(str(path)) + 2:]), msg
    assert len(msg) < 600, msg                       # long values are cut


@pytest.mark.parametrize("name", sorted(n for n in EXPECTED if n.startswith("scenario-")))
def test_the_cli_exits_2_without_a_traceback(name, capsys):
    assert main(["show", str(CORPUS / name), "-o", "/dev/null"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hybridnav: error: ") and "Traceback" not in err


def test_a_job_beyond_the_limits_fails_in_the_cli_before_any_work(tmp_path, capsys):
    out = tmp_path / "tuned"
    assert main(["tune", str(CORPUS / "job-huge-generate.toml"), "--out", str(out)]) == 2
    assert "generate: expected an integer in [1, 10000]" in capsys.readouterr().err
    assert not out.exists()


# ---- damaged valid files ------------------------------------------------------------------------

SCENARIOS = [(_builtin_dir() / f"{n}.toml").read_text(encoding="utf-8")
             for n in ("fastep-s2", "effc-env-b", "tractor-trailer-1", "pso-ba-dynamic")]
JOBS = [
    '[ga]\npopulation = 4\ngenerations = 1\n[scenarios]\ntrain = ["effc-train-1"]\n'
    'test = ["effc-env-a"]\n[reward]\nkind = "deploy"\ncollision = 20.0\n[planner]\n'
    'speed = 0.1\nmax_turn = 0.7853981633974483\n[backend]\nworkers = 1\nchunk = 50\n',
    'name = "j"\nseed = 3\n[free]\nmf = ["alpha", "w"]\nmargin = 0.25\n[coverage]\ngrid = 11\n'
    '[scenarios]\ntrain = ["effc-train-2"]\ntest = []\n[validation]\ntop = 2\npatience = 3\n',
]


def _check(read, path: Path) -> None:
    try:
        out = read(path)
    except HybridnavError as exc:
        assert str(exc).startswith(f"{path}: "), str(exc)
        return
    assert out is not None


@settings(deadline=None, max_examples=150, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_scenario_files(tmp_path, data):
    path = tmp_path / "s.toml"
    path.write_text(data.draw(mutated(SCENARIOS)), encoding="utf-8")
    _check(load_scenario, path)


@settings(deadline=None, max_examples=100, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_job_files(tmp_path, data):
    path = tmp_path / "job.toml"
    path.write_text(data.draw(mutated(JOBS)), encoding="utf-8")
    _check(load_job, path)


@settings(deadline=None, max_examples=100, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(blob=st.binary(max_size=300), which=st.sampled_from(["scenario", "job"]))
def test_arbitrary_bytes(tmp_path, blob, which):
    path = tmp_path / f"{which}.toml"
    path.write_bytes(blob)
    _check(load_scenario if which == "scenario" else load_job, path)


def test_the_sources_are_valid(tmp_path):
    for k, text in enumerate(SCENARIOS):
        (tmp_path / f"{k}.toml").write_text(text, encoding="utf-8")
        assert isinstance(load_scenario(tmp_path / f"{k}.toml"), Scenario)
    for k, text in enumerate(JOBS):
        (tmp_path / f"j{k}.toml").write_text(text, encoding="utf-8")
        load_job(tmp_path / f"j{k}.toml")
