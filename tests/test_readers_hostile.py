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
from test_fuzzy_export_fuzz import examples, mutated

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


@settings(deadline=None, max_examples=examples(150), suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_scenario_files(tmp_path, data):
    path = tmp_path / "s.toml"
    path.write_text(data.draw(mutated(SCENARIOS)), encoding="utf-8")
    _check(load_scenario, path)


@settings(deadline=None, max_examples=examples(100), suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_job_files(tmp_path, data):
    path = tmp_path / "job.toml"
    path.write_text(data.draw(mutated(JOBS)), encoding="utf-8")
    _check(load_job, path)


@pytest.mark.slow
@settings(deadline=None, max_examples=examples(100), suppress_health_check=[HealthCheck.function_scoped_fixture])
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


# ---- maps, stored reproductions and command-line values (issue 27) ----------------------------

MAPS = ["type octile\nheight 3\nwidth 4\nmap\n....\n.@T.\n....\n",
        "type octile\nheight 2\nwidth 2\nmap\n.G\nS.\n"]


@settings(deadline=None, max_examples=examples(100),
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_map_files(tmp_path, data):
    from hybridnav.world.grid import load_movingai_map

    path = tmp_path / "m.map"
    path.write_text(data.draw(mutated(MAPS)), encoding="utf-8")
    _check(load_movingai_map, path)


STORE = Path(__file__).resolve().parents[1] / "docs" / "reproductions" / "fastep-table2"
STORED = {name: (STORE / name).read_text(encoding="utf-8")
          for name in ("summary.csv", "comparison.json")}


@settings(deadline=None, max_examples=examples(60),
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data(), which=st.sampled_from(sorted(STORED)))
def test_damaged_stored_reproductions(tmp_path, data, which):
    import shutil

    from hybridnav.reproduce.readme import load_stored

    folder = tmp_path / "fastep-table2"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    for name, text in STORED.items():
        (folder / name).write_text(text, encoding="utf-8")
    (folder / which).write_text(data.draw(mutated([STORED[which]])), encoding="utf-8")
    try:
        load_stored(folder)
    except HybridnavError as exc:
        assert str(exc).startswith(str(folder)), str(exc)


OPTIONS = [("show", "--time", ["show", "fastep-s1", "-o", "x.png"]),
           ("run", "--seed", ["run", "fastep-s1", "--planner", "apf", "-o", "x"]),
           ("compare", "--runs", ["compare", "--planners", "apf", "--scenarios", "s", "-o", "x"]),
           ("compare", "--workers", ["compare", "--planners", "apf", "--scenarios", "s",
                                     "-o", "x"]),
           ("verify", "--tolerance", ["verify", "effc-5rule", "x.c"]),
           ("generate", "--count", ["generate", "-o", "x"])]


@settings(deadline=None, max_examples=examples(200))
@given(option=st.sampled_from(OPTIONS),
       value=st.one_of(st.text(max_size=30), st.integers().map(str),
                       st.floats(allow_nan=True).map(repr),
                       st.sampled_from(["-1", "0", "1e308", "inf", "nan", "9" * 5000, "2**128",
                                        "340282366920938463463374607431768211456"])))
def test_command_line_values(option, value):
    """A typed option either parses into its documented range or exits 2 with the one style."""
    import contextlib
    import io
    import math

    from hybridnav.cli import build_parser

    _, flag, argv = option
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = build_parser().parse_args([*argv, f"{flag}={value}"])
    except SystemExit as exc:
        assert exc.code == 2
        assert "hybridnav: error: " in err.getvalue(), err.getvalue()
        assert len(err.getvalue()) < 1500
        return
    got = getattr(args, flag.lstrip("-"))
    if flag == "--seed":
        assert isinstance(got, int) and 0 <= got < 2**128
    elif flag in ("--runs", "--count"):
        assert isinstance(got, int) and 1 <= got <= 100_000
    elif flag == "--workers":
        assert isinstance(got, int) and 1 <= got <= 256
    else:
        assert math.isfinite(got) and got >= 0


@pytest.mark.parametrize("width, expected", [
    ("99999999999999999999999", "expected a map of at most 20000000 cells"),
    ("9" * 5000, "expected integer height and width, got '3', '9999"),
])
def test_a_map_header_beyond_the_limits(width, expected):
    """Found by the long fuzz run: numpy refused to allocate a 3 x 1e23 map (ValueError)."""
    from hybridnav.world.grid import parse_movingai_map

    with pytest.raises(HybridnavError, match=re.escape(expected)) as info:
        parse_movingai_map(f"type octile\nheight 3\nwidth {width}\nmap\n....\n", "m.map")
    assert str(info.value).startswith("m.map: header: ") and len(str(info.value)) < 300


def test_a_stored_summary_with_an_integer_beyond_floats(tmp_path):
    """Found by a long fuzz run: pandas' to_numeric raised OverflowError."""
    import shutil

    from hybridnav.reproduce.readme import load_stored

    folder = tmp_path / "fastep-table2"
    folder.mkdir()
    shutil.copy(STORE / "comparison.json", folder)
    lines = STORED["summary.csv"].splitlines()
    head, first = lines[0].split(","), lines[1].split(",")
    first[head.index("robots")] = "9" * 400
    (folder / "summary.csv").write_text("\n".join([lines[0], ",".join(first), *lines[2:]]) + "\n")
    with pytest.raises(HybridnavError, match=r"summary.csv: robots: expected numbers, got an "
                                             r"integer beyond the float range"):
        load_stored(folder)
