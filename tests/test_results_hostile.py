"""Result folders on hostile edits (issue 27): ``read_result`` and ``hybridnav plot`` either work
or fail with a HybridnavError (exit 2, ``hybridnav: error: ...``) that names the file in the folder
and the key -- never a traceback, never a wrong value taken silently.

The folders are real: the planners that write each kind of extra run once per module on a small
scenario. One test per class of damage found by hand (a renamed or missing column of every
declared extra, a 5000-digit integer, NaN / inf where the writer writes none, a header-only CSV,
arrays of the wrong dimension, metrics of the wrong type), then a hypothesis fuzz test that damages
one file of a folder (text mutations as the fuzzy readers' fuzz test, and structured ones: columns
dropped or renamed, cells set to NaN / huge / text, JSON values of the wrong type, .npy headers
truncated or altered). ``HYBRIDNAV_FUZZ_EXAMPLES=10000`` runs that many mutants instead of the
default few.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import shutil
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_fuzzy_export_fuzz import examples, mutated

from hybridnav import HybridnavError, planners
from hybridnav.cli import main
from hybridnav.results import Result, RobotResult, read_result, write_result
from hybridnav.resultspec import EXTRAS, METRICS, Array, Table
from hybridnav.world import save_scenario, scenario_from_dict


SMALL = {
    "name": "hostile-results", "dt": 0.1, "max_time": 40.0,
    "workspace": {"xmin": 0.0, "xmax": 10.0, "ymin": 0.0, "ymax": 10.0},
    "obstacles": [{"type": "circle", "center": [5.0, 6.5], "radius": 1.0}],
    "robots": [{"name": "R", "model": "point_mass", "start": [1.0, 1.0], "goal": [9.0, 9.0],
                "goal_radius": 0.3, "radius": 0.2},
               {"name": "Q", "model": "point_mass", "start": [9.0, 1.0], "goal": [1.0, 9.0],
                "goal_radius": 0.3, "radius": 0.2}],
}
#: planners that between them write every declared extra
PLANNERS = ("hapf", "effc", "rfd-pso", "fastep-kinematic", "pso-ba")


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The small scenario's file and one result folder per planner of PLANNERS."""
    root = tmp_path_factory.mktemp("results")
    scenario = scenario_from_dict(SMALL)
    save_scenario(scenario, root / "small.toml")
    for name in PLANNERS:
        planners.get(name).run(scenario, seed=3).write(root / name)
    return root


def copy_of(written: Path, planner: str, tmp_path: Path) -> Path:
    folder = tmp_path / "run"
    shutil.copytree(written / planner, folder)
    return folder


def plot(folder: Path, written: Path, tmp_path: Path) -> tuple[int, str]:
    """``hybridnav plot`` on the folder: exit status and standard error."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), \
            mock.patch("hybridnav.plotting.save_figure", _quick_save):
        rc = main(["plot", str(folder), "--scenario", str(written / "small.toml"),
                   "--out", str(tmp_path / "figures")])
    return rc, err.getvalue()


def _quick_save(fig, path, dpi=120, bbox_inches="tight"):
    """save_figure, drawn at a tenth of the resolution into memory: the same drawing, faster."""
    fig.savefig(io.BytesIO(), format="png", dpi=12, bbox_inches=bbox_inches)
    return Path(path)


def fails(folder: Path, written: Path, tmp_path: Path, file: str, message: str) -> None:
    """read_result and the plot command both refuse the folder with ``file: message``."""
    with pytest.raises(HybridnavError) as err:
        read_result(folder)
    assert str(err.value) == f"{folder / file}: {message}"
    assert len(str(err.value)) < 600
    rc, stderr = plot(folder, written, tmp_path)
    assert rc == 2 and stderr == f"hybridnav: error: {folder / file}: {message}\n"


def edit_json(folder: Path, change) -> None:
    data = json.loads((folder / "result.json").read_text())
    change(data)
    (folder / "result.json").write_text(json.dumps(data))


def edit_table(path: Path, change) -> None:
    """Apply ``change`` to the rows (header first) of a CSV file."""
    rows = [line.split(",") for line in path.read_text().splitlines()]
    path.write_text("".join(",".join(r) + "\n" for r in change(rows)))


@pytest.mark.slow
def test_the_folders_hold_every_declared_extra_and_plot(written, tmp_path):
    prefixes = set()
    for name in PLANNERS:
        back = read_result(written / name)
        for key in back.extras:
            prefixes |= {p for p in EXTRAS for r in back.robots if key == f"{p}_{r.name}"}
        rc, err = plot(written / name, written, tmp_path)
        assert rc == 0, err
    assert prefixes == set(EXTRAS)


# ---- one test per class ------------------------------------------------------------------------

def _table_cases():
    """(planner, extra prefix, column) for every declared column of every declared table."""
    writer = {"signals": "effc", "harmonic_grid": "hapf", "swarm_best": "rfd-pso",
              "planned": "rfd-pso", "rfd_path": "rfd-pso", "rfd_seed": "rfd-pso",
              "steps": "fastep-kinematic", "waypoints": "fastep-kinematic",
              "path_points": "pso-ba", "candidates": "pso-ba"}
    assert set(writer) == {p for p, s in EXTRAS.items() if isinstance(s, Table)}
    return [(writer[p], p, c) for p, s in EXTRAS.items() if isinstance(s, Table)
            for c in s.columns]


@pytest.mark.parametrize("how", ["renamed", "dropped"])
@pytest.mark.parametrize("planner, prefix, column", _table_cases())
def test_a_missing_or_renamed_column_names_the_file_and_column(written, tmp_path, planner,
                                                               prefix, column, how):
    folder = copy_of(written, planner, tmp_path)
    file = f"{prefix}_R.csv"

    def change(rows):
        j = rows[0].index(column)
        if how == "renamed":
            rows[0][j] = column + "_old"
            return rows
        return [r[:j] + r[j + 1:] for r in rows]

    edit_table(folder / file, change)
    fails(folder, written, tmp_path, file,
          f"column {column}: missing (expected {EXTRAS[prefix].expected()})")


def test_an_undeclared_column_is_refused(written, tmp_path):
    folder = copy_of(written, "fastep-kinematic", tmp_path)
    edit_table(folder / "waypoints_R.csv", lambda rows: [r + [r[0] if k else "speed"]
                                                         for k, r in enumerate(rows)])
    fails(folder, written, tmp_path, "waypoints_R.csv",
          f"column speed: not expected (expected {EXTRAS['waypoints'].expected()})")


@pytest.mark.parametrize("where", ["seed", "params", "metric"])
def test_an_integer_of_5000_digits_in_result_json(written, tmp_path, where):
    folder = copy_of(written, "effc", tmp_path)
    text = (folder / "result.json").read_text()
    huge = "7" * 5000
    key = {"seed": '"seed": 3', "params": '"speed": ', "metric": '"path_length": '}[where]
    assert key in text
    text = text.replace(key, '"seed": ' + huge if where == "seed" else key + huge + ", \"x\": ", 1)
    (folder / "result.json").write_text(text)
    keys = {"seed": "seed", "params": "params.speed", "metric": "robots[0].path_length"}
    fails(folder, written, tmp_path, "result.json",
          f"{keys[where]}: expected a number as hybridnav writes them (finite, at most 4300 "
          "digits), got an integer of 5000 digits")


@pytest.mark.parametrize("literal, shown", [("NaN", "NaN"), ("Infinity", "Infinity"),
                                            ("-Infinity", "-Infinity"),
                                            ("1e999", "'1e999' (beyond the float range)")])
def test_nan_and_infinity_in_result_json(written, tmp_path, literal, shown):
    folder = copy_of(written, "effc", tmp_path)
    text = (folder / "result.json").read_text()
    (folder / "result.json").write_text(text.replace('"compute_time": ',
                                                     f'"compute_time": {literal}, "x": ', 1))
    fails(folder, written, tmp_path, "result.json",
          "robots[0].compute_time: expected a number as hybridnav writes them (finite, at most "
          f"4300 digits), got {shown}")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e308", "2e151"])
def test_nan_or_inf_in_the_grid_csv(written, tmp_path, value):
    folder = copy_of(written, "hapf", tmp_path)

    def change(rows):
        rows[1][0] = value
        return rows

    edit_table(folder / "harmonic_grid_R.csv", change)
    fails(folder, written, tmp_path, "harmonic_grid_R.csv",
          f"column x0: expected finite coordinates of magnitude at most 1e+150, got "
          f"{float(value)!r} at line 2")


def test_a_degenerate_grid_extent(written, tmp_path):
    folder = copy_of(written, "hapf", tmp_path)

    def change(rows):
        rows[1][1] = rows[1][0]
        return rows

    edit_table(folder / "harmonic_grid_R.csv", change)
    fails(folder, written, tmp_path, "harmonic_grid_R.csv",
          "column x1: expected more than x0 (0.0), got 0.0 at line 2")


@pytest.mark.parametrize("value, shown", [(np.nan, "nan"), (np.inf, "inf"), (-1e301, "-1e+301")])
def test_nan_or_inf_in_the_potential_npy(written, tmp_path, value, shown):
    folder = copy_of(written, "hapf", tmp_path)
    phi = np.load(folder / "harmonic_potential_R.npy")
    phi[3, 4] = value
    np.save(folder / "harmonic_potential_R.npy", phi)
    fails(folder, written, tmp_path, "harmonic_potential_R.npy",
          "expected a 2-D array of finite floats (magnitude at most 1e+300), no dimension empty, "
          f"got {shown} at index (3, 4)")


@pytest.mark.parametrize("array, got", [
    (np.float64(0.5), "shape ()"), (np.zeros(7), "shape (7,)"), (np.zeros((2, 3, 4)),
                                                                 "shape (2, 3, 4)"),
    (np.zeros((0, 5)), "shape (0, 5)"), (np.zeros((4, 4), dtype=int), "dtype int64"),
    (np.zeros((4, 4), dtype=bool), "dtype bool"), (np.zeros((4, 4), dtype=complex),
                                                   "dtype complex128"),
    (np.zeros((4, 4), dtype=np.longdouble), f"dtype {np.dtype(np.longdouble)}"),
])
def test_an_array_of_the_wrong_shape_or_type(written, tmp_path, array, got):
    folder = copy_of(written, "hapf", tmp_path)
    np.save(folder / "harmonic_potential_R.npy", array)
    if array.dtype == np.longdouble and np.dtype(np.longdouble).itemsize <= 8:
        pytest.skip("long double is double here")
    if array.dtype.kind == "c":                # not a number the reader takes at all
        with pytest.raises(HybridnavError, match=r"harmonic_potential_R.npy: expected an array "
                                                 r"of numbers"):
            read_result(folder)
        return
    fails(folder, written, tmp_path, "harmonic_potential_R.npy",
          "expected a 2-D array of finite floats (magnitude at most 1e+300), no dimension empty, "
          f"got {got}")


@pytest.mark.parametrize("planner, file, rows, message", [
    ("hapf", "harmonic_grid_R.csv", "x0,x1,y0,y1\n", "expected 1 row of x0, x1, y0, y1, got 0"),
    ("effc", "trajectory_R.csv", "t,x,y\n", "expected at least one sample after the header"),
    ("effc", "signals_R.csv", "", "line 1: expected a header row"),
])
def test_a_header_only_csv(written, tmp_path, planner, file, rows, message):
    folder = copy_of(written, planner, tmp_path)
    assert (folder / file).read_text().startswith(rows)
    (folder / file).write_text(rows)
    fails(folder, written, tmp_path, file, message)


@pytest.mark.parametrize("planner, prefix", [("fastep-kinematic", "steps"),
                                             ("fastep-kinematic", "waypoints"),
                                             ("rfd-pso", "swarm_best"), ("rfd-pso", "planned"),
                                             ("pso-ba", "path_points"), ("pso-ba", "candidates"),
                                             ("effc", "signals")])
def test_a_header_only_table_the_writer_writes_too_plots(written, tmp_path, planner, prefix):
    """Tables of no rows are written (no step planned, no path found): they read and plot."""
    folder = copy_of(written, planner, tmp_path)
    edit_table(folder / f"{prefix}_R.csv", lambda rows: rows[:1])
    assert all(len(v) == 0 for v in read_result(folder).extras[f"{prefix}_R"].values())
    rc, err = plot(folder, written, tmp_path)
    assert rc == 0, err


@pytest.mark.parametrize("planner, key, value, message", [
    ("rfd-pso", "planning_time", None, "expected a finite number >= 0, got None"),
    ("rfd-pso", "planning_time", "0.1", "expected a finite number >= 0, got '0.1'"),
    ("rfd-pso", "planning_time", -1.0, "expected a finite number >= 0, got -1.0"),
    ("rfd-pso", "planning_time", 10**400,
     ("expected a finite number >= 0, got 1000000000000000000000000000000000000000...0000000000 "
      "(401 characters)")),
    ("effc", "path_length", "long", "expected a finite number >= 0, got 'long'"),
    ("effc", "smoothness", [1.0], "expected a finite number >= 0, got [1.0]"),
    ("effc", "compute_time", None, "expected a finite number >= 0, got None"),
    ("effc", "min_clearance", True, "expected a finite number or null, got True"),
    ("effc", "time_to_goal", {"t": 1}, "expected a finite number >= 0 or null, got {'t': 1}"),
    ("rfd-pso", "waypoints", 8.0, "expected a whole number from 0 to 2**63 - 1 or null, got 8.0"),
    ("rfd-pso", "pso_runs", None, "expected a whole number from 0 to 2**63 - 1, got None"),
    ("fastep-kinematic", "steps_planned", -1,
     "expected a whole number from 0 to 2**63 - 1, got -1"),
    ("pso-ba", "ls_repairs", 2**63,
     "expected a whole number from 0 to 2**63 - 1, got 9223372036854775808"),
    ("effc", "anything_else", "text", "expected a finite number or null, got 'text'"),
    ("effc", "outcome", "won",
     "expected one of reached, collided, out_of_bounds, stuck, timeout, got 'won'"),
    ("effc", "outcome", None,
     "expected one of reached, collided, out_of_bounds, stuck, timeout, got None"),
    ("effc", "name", "../R", "expected at most 100 letters, digits, '_', '-' or '.', got '../R'"),
    ("effc", "name", "R\n", "expected at most 100 letters, digits, '_', '-' or '.', got 'R\\n'"),
])
def test_a_metric_of_the_wrong_type(written, tmp_path, planner, key, value, message):
    folder = copy_of(written, planner, tmp_path)
    edit_json(folder, lambda d: d["robots"][0].update({key: value}))
    fails(folder, written, tmp_path, "result.json", f"robots[0].{key}: {message}")


def test_read_result_refuses_a_path_length_of_text(written, tmp_path):
    folder = copy_of(written, "effc", tmp_path)
    edit_json(folder, lambda d: d["robots"][1].update(path_length="long"))
    with pytest.raises(HybridnavError) as err:
        read_result(folder)
    assert str(err.value) == (f"{folder / 'result.json'}: robots[1].path_length: expected a "
                              "finite number >= 0, got 'long'")


def test_every_metric_a_planner_writes_is_declared(written):
    """A planner adding a metric declares it (undeclared ones are a number or null)."""
    for name in PLANNERS:
        data = json.loads((written / name / "result.json").read_text())
        for entry in data["robots"]:
            assert set(entry) - {"name", "outcome"} <= set(METRICS), name


@pytest.mark.parametrize("change, file, message", [
    (lambda d: d.update(extra={}), "result.json",
     ("extra: not a key of result.json (expected scenario, planner, params, seed, version, "
      "robots, extras)")),
    (lambda d: d.update(seed=-1), "result.json",
     "seed: expected a non-negative integer or null, got -1"),
    (lambda d: d.update(seed=1.5), "result.json",
     "seed: expected a non-negative integer or null, got 1.5"),
    (lambda d: d.update(scenario=""), "result.json", "scenario: expected a name, got ''"),
    (lambda d: d.update(planner=7), "result.json", "planner: expected a name, got 7"),
    (lambda d: d.update(extras=[]), "result.json",
     "extras: expected an object of name -> file, got []"),
    (lambda d: d["robots"].append(d["robots"][0]), "result.json",
     "robots: expected distinct names, got ['R', 'Q', 'R']"),
    (lambda d: d["extras"].update(steps_R={"file": "steps_R.npy"}), "result.json",
     "extras.steps_R.file: expected steps_R.csv (a table), got 'steps_R.npy'"),
    (lambda d: d["extras"]["steps_R"].update(text=[]), "steps_R.csv",
     "column mode: expected numbers, got 'goal' at line 2"),
    (lambda d: d["extras"]["steps_R"].update(text=["mode", "cost"]), "steps_R.csv",
     "column cost: expected finite numbers of magnitude at most 1e+300, got text"),
])
def test_result_json_of_the_wrong_shape(written, tmp_path, change, file, message):
    folder = copy_of(written, "fastep-kinematic", tmp_path)
    edit_json(folder, change)
    fails(folder, written, tmp_path, file, message)


def test_a_duplicate_key_in_result_json(written, tmp_path):
    folder = copy_of(written, "effc", tmp_path)
    text = (folder / "result.json").read_text()
    (folder / "result.json").write_text(text.replace('"path_length": ', '"path_length": 1.0, '
                                                     '"path_length": ', 1))
    fails(folder, written, tmp_path, "result.json", "robots[0]: duplicate key 'path_length'")


@pytest.mark.parametrize("line, value, message", [
    (3, "nan", "column t: expected finite numbers of magnitude at most 1e+300, got nan at line 3"),
    (4, "0.05", "column t: expected strictly increasing times, got 0.05 after 0.1 at line 4"),
    (2, "x", "column t: expected numbers, got 'x' at line 2"),
])
def test_a_damaged_trajectory(written, tmp_path, line, value, message):
    folder = copy_of(written, "effc", tmp_path)

    def change(rows):
        rows[line - 1][0] = value
        return rows

    edit_table(folder / "trajectory_R.csv", change)
    fails(folder, written, tmp_path, "trajectory_R.csv", message)


@pytest.mark.parametrize("column, value", [(1, "1e200"), (2, "-2e151"), (1, "inf")])
def test_a_trajectory_far_outside_any_world(written, tmp_path, column, value):
    """Coordinates near 1e200 crashed Matplotlib's Agg renderer (OverflowError) in 'plot' and
    'animate': x and y are bounded by limits.MAX_POSITION (1e150)."""
    folder = copy_of(written, "effc", tmp_path)

    def change(rows):
        rows[3][column] = value
        return rows

    edit_table(folder / "trajectory_R.csv", change)
    fails(folder, written, tmp_path, "trajectory_R.csv",
          f"column {'xy'[column - 1]}: expected finite coordinates of magnitude at most 1e+150, "
          f"got {float(value)!r} at line 4")


def test_a_diverged_run_still_reads_and_plots(written, tmp_path):
    """A model that diverges leaves its workspace by far in one step (x = -8.1e40 was seen with
    legal unicycle gains): the run's folder is what the run wrote, and it reads and plots."""
    folder = copy_of(written, "effc", tmp_path)

    def change(rows):
        rows[-1][1] = "-8.1e40"
        return rows

    edit_table(folder / "trajectory_R.csv", change)
    assert read_result(folder).robots[0].states[-1, 0] == -8.1e40
    rc, stderr = plot(folder, written, tmp_path)
    assert rc == 0, stderr


def test_candidates_out_of_order(written, tmp_path):
    """The writer records the searches in the order they ran (the animation bisects their
    times): a shuffled candidates table is refused, not drawn at the wrong times."""
    folder = copy_of(written, "pso-ba", tmp_path)
    path = folder / "candidates_R.csv"
    rows = [line.split(",") for line in path.read_text().splitlines()]
    late = max(range(1, len(rows)), key=lambda k: float(rows[k][0]))
    assert float(rows[late][0]) > 0
    edit_table(path, lambda rows: [rows[0], rows[late]] + rows[1:late] + rows[late + 1:])
    fails(folder, written, tmp_path, "candidates_R.csv",
          f"column plan: expected rows in the order they were recorded (plan never decreasing), "
          f"got {float(rows[1][0])!r} after {float(rows[late][0])!r} at line 3")


def test_steps_with_an_unknown_mode(written, tmp_path):
    folder = copy_of(written, "fastep-kinematic", tmp_path)

    def change(rows):
        rows[1][4] = "fly"
        return rows

    edit_table(folder / "steps_R.csv", change)
    fails(folder, written, tmp_path, "steps_R.csv",
          "column mode: expected one of hold, goal, step, got 'fly' at line 2")


def test_plot_reads_only_a_built_in_scenario_by_the_name_in_result_json(written, tmp_path,
                                                                        capsys):
    folder = copy_of(written, "effc", tmp_path)
    for name in ("../../etc/secret.toml", "hostile-results", "x" * 5000):
        edit_json(folder, lambda d, name=name: d.update(scenario=name))
        assert main(["plot", str(folder)]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"hybridnav: error: {folder / 'result.json'}: scenario: ")
        assert "is not a built-in scenario; pass the scenario file the result was run on with " \
               "--scenario" in err and len(err) < 600


def test_a_trajectory_that_does_not_start_where_the_scenario_does(written, tmp_path):
    folder = copy_of(written, "effc", tmp_path)

    def change(rows):
        rows[1][1] = "2.0"
        return rows

    edit_table(folder / "trajectory_Q.csv", change)
    read_result(folder)                                   # a valid folder, of another scenario
    rc, err = plot(folder, written, tmp_path)
    assert rc == 2 and err.startswith(f"hybridnav: error: {folder / 'trajectory_Q.csv'}: line 2: "
                                      "robot Q starts at (2.0, 1.0), in --scenario ")
    assert "do not start where the result's do" in err


# ---- the writer checks the same declarations ---------------------------------------------------

def _robots():
    return [RobotResult("R", "timeout", [0.0, 1.0], [[0, 0], [1, 1]], ("x", "y"))]


@pytest.mark.parametrize("extras, message", [
    ({"steps_R": {"t": [0.0]}}, "result: extras.steps_R: column target_x: missing"),
    ({"harmonic_potential_R": np.zeros(4)}, "result: extras.harmonic_potential_R: expected a 2-D"),
    ({"harmonic_potential_R": {"x": [0.0]}},
     r"result: extras.harmonic_potential_R: expected an array \(.npy\), got a table"),
    ({"planned_R": {"x": [np.nan], "y": [0.0]}},
     "result: extras.planned_R: column x: expected finite coordinates .* got nan at row 0"),
    ({"swarm_best_R": {"plan": [0], "iteration": [0], "best": [np.nan]}},
     r"column best: expected numbers or \+-inf \(no nan\), got nan at row 0"),
    # the reader refuses both: the writer never writes them
    ({"planned_R": {"x": [2e151], "y": [0.0]}},
     r"column x: expected finite coordinates of magnitude at most 1e\+150, got 2e\+151 at "
     "row 0"),
    ({"candidates_R": {"plan": [1, 0], "t": [0.0, 0.0], "x": [0.0, 0.0], "y": [0.0, 0.0],
                       "cost": [1.0, 1.0]}},
     r"extras.candidates_R: column plan: expected rows in the order they were recorded \(plan "
     r"never decreasing\), got 0.0 after 1.0 at row 1"),
])
def test_the_writer_refuses_an_extra_that_is_not_as_declared(extras, message):
    with pytest.raises(HybridnavError, match=message):
        Result("s", "p", {}, 0, _robots(), extras=extras)


def test_extras_of_other_names_or_robots_are_free():
    Result("s", "p", {}, 0, _robots(), extras={"steps_Z": {"t": [0.0]}, "mine": {"a": [1.0]}})


def test_the_writer_refuses_a_metric_json_would_write_as_null(tmp_path):
    robots = _robots()
    robots[0].metrics["planning_time"] = math.inf
    with pytest.raises(HybridnavError, match=r"result: robots\[0\].planning_time: expected a "
                                             "finite number >= 0, got None"):
        write_result(Result("s", "p", {}, 0, robots), tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_every_declaration_is_a_table_or_an_array():
    for spec in EXTRAS.values():
        assert isinstance(spec, (Table, Array))


# ---- fuzz: damage one file of a real folder ------------------------------------------------------

WEIRD_CELLS = ["nan", "inf", "-inf", "1e308", "-1e308", "1e999", "", "x", "1_0", " 1", "0x10",
               "-0.0", "1e-320", "9" * 400, "goal", "hold", "wall"]
WEIRD_JSON = [None, True, False, "long", "", -1, 0, 1.5, 1e308, -1e308, 2**63, 10**400, [], {},
              [1.0], {"a": 1}, "../x", "R\n", "nan"]
JSON_LITERALS = ["NaN", "Infinity", "-Infinity", "1e999", "9" * 5000, "-" + "9" * 5000, "1e-400"]


def _paths(value, key=()):
    """Every key path of a JSON value (dict keys and list indices)."""
    yield key
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _paths(v, (*key, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _paths(v, (*key, i))


@st.composite
def damage(draw, folder: Path) -> None:
    """Damage one file of ``folder`` (text, structure, or a .npy header)."""
    files = sorted(p.name for p in folder.iterdir())
    # result.json and the arrays as often as all the CSV files together
    kinds = [["result.json"], [f for f in files if f.endswith(".npy")],
             [f for f in files if f.endswith(".csv")]]
    file = draw(st.sampled_from(draw(st.sampled_from([k for k in kinds if k]))))
    path = folder / file
    if file.endswith(".npy"):
        data = path.read_bytes()
        kind = draw(st.sampled_from(["truncate", "byte", "header", "array"]))
        if kind == "truncate":
            path.write_bytes(data[:draw(st.integers(0, len(data) - 1))])
        elif kind == "byte":
            pos = draw(st.integers(0, min(len(data), 200) - 1))
            path.write_bytes(data[:pos] + bytes([draw(st.integers(0, 255))]) + data[pos + 1:])
        elif kind == "header":                    # the dict of the header, as text
            end = data.index(b"\n") + 1
            header = data[:end].decode("latin1")
            text = draw(mutated([header]))
            path.write_bytes(text.encode("latin1", "replace") + data[end:])
        else:
            arr = draw(st.sampled_from([np.float64(1.0), np.zeros(3), np.zeros((2, 2, 2)),
                                        np.zeros((0, 3)), np.full((3, 3), np.nan),
                                        np.zeros((3, 3), int), np.ones((3, 3), bool),
                                        np.zeros((3, 3), complex), np.full((3, 3), 1e308),
                                        np.zeros(3, dtype=[("a", "f8")]),
                                        np.array([1, None], dtype=object)]))
            with open(path, "wb") as fh:
                np.save(fh, arr, allow_pickle=arr.dtype.kind == "O")
        return
    text = path.read_text()
    kind = draw(st.sampled_from(["text", "structure"]))
    if kind == "text":
        path.write_text(draw(mutated([text])))
        return
    if file == "result.json":
        data = json.loads(text)
        keys = [k for k in _paths(data) if k]
        key = draw(st.sampled_from(keys))
        parent = data
        for k in key[:-1]:
            parent = parent[k]
        how = draw(st.sampled_from(["value", "delete", "rename", "literal"]))
        if how == "value":
            parent[key[-1]] = draw(st.sampled_from(WEIRD_JSON))
        elif how == "delete":
            del parent[key[-1]]
        elif how == "rename" and isinstance(parent, dict):
            parent[str(key[-1]) + "_x"] = parent.pop(key[-1])
        out = json.dumps(data)
        if how == "literal":                   # a number JSON cannot hold, or too long to read
            nums = list(re.finditer(r"(?<![\w.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?", out))
            if nums:
                m = nums[draw(st.integers(0, len(nums) - 1))]
                out = out[:m.start()] + draw(st.sampled_from(JSON_LITERALS)) + out[m.end():]
        path.write_text(out)
        return
    rows = [line.split(",") for line in text.splitlines()]
    how = draw(st.sampled_from(["drop", "rename", "cell", "header_only", "swap_rows"]))
    width = len(rows[0])
    j = draw(st.integers(0, width - 1))
    if how == "drop":
        rows = [r[:j] + r[j + 1:] for r in rows]
    elif how == "rename":
        rows[0][j] = draw(st.sampled_from([rows[0][j] + "2", rows[0][j].upper(), "t", "x",
                                           "mode", "best", ""]))
    elif how == "cell" and len(rows) > 1:
        rows[draw(st.integers(1, len(rows) - 1))][j] = draw(st.sampled_from(WEIRD_CELLS))
    elif how == "header_only":
        rows = rows[:1]
    elif how == "swap_rows" and len(rows) > 2:
        i, k = draw(st.integers(1, len(rows) - 1)), draw(st.integers(1, len(rows) - 1))
        rows[i], rows[k] = rows[k], rows[i]
    path.write_text("".join(",".join(r) + "\n" for r in rows))


def _names_a_file_of(folder: Path, message: str) -> bool:
    return re.match(re.escape(str(folder)) + r"/[\w.\-]+: ", message) is not None


@pytest.mark.slow
@settings(deadline=None, max_examples=examples(25), suppress_health_check=[
    HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large])
@given(data=st.data(), planner=st.sampled_from(PLANNERS))
def test_damaged_result_folders(written, tmp_path, data, planner):
    folder = tmp_path / "fuzz"
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(written / planner, folder)
    data.draw(damage(folder))
    try:
        read_result(folder)
    except HybridnavError as exc:
        assert _names_a_file_of(folder, str(exc)), str(exc)
        assert len(str(exc)) < 1000, str(exc)
        return
    rc, err = plot(folder, written, tmp_path)
    assert rc == 0 or (rc == 2 and _names_a_file_of(folder, err.removeprefix(
        "hybridnav: error: "))), err


@pytest.mark.parametrize("value", [math.inf, math.nan, 1e200, -1e151])
def test_a_step_that_diverges_ends_the_run_at_its_last_state_and_the_run_saves(value, tmp_path,
                                                                               monkeypatch):
    """A model whose step diverges (a user's model with a singularity: inf, NaN, or a position
    no result folder holds) ends that robot out_of_bounds at its last state; the run is written
    and read back (it once failed to save: "path_length: expected a finite number")."""
    from hybridnav.models.base import Model
    from hybridnav.world import load_scenario

    real, calls = Model.step, []

    def step(self, X, T):
        calls.append(1)
        out = real(self, X, T)
        if len(calls) == 20:
            out = out.copy()
            out[:, 0] = value
        return out

    monkeypatch.setattr(Model, "step", step)
    r = planners.get("apf").run(load_scenario("effc-env-b"), seed=0)
    robot = r.robots[0]
    assert robot.outcome == "out_of_bounds" and len(robot.states) == 20
    assert np.isfinite(robot.states).all() and math.isfinite(robot.path_length)
    write_result(r, tmp_path / "run")
    back = read_result(tmp_path / "run").robots[0]
    np.testing.assert_array_equal(back.states, robot.states)
