"""The result contract: result.json + one trajectory CSV per robot, written atomically."""

from __future__ import annotations

import csv
import itertools
import json
import math

import numpy as np
import pytest

from hybridnav import HybridnavError, __version__
from hybridnav.results import (
    OUTCOMES,
    Result,
    RobotResult,
    path_length,
    read_result,
    smoothness,
)


def make_result():
    t = np.arange(4) * 0.5
    a = RobotResult("R1", "reached", t, np.array([[0, 0], [3, 4], [3, 8], [6, 12]]), ("x", "y"),
                    time_to_goal=1.5, min_clearance=0.25, compute_time=0.01)
    b = RobotResult("tt-2", "collided", t[:2], np.array([[1, 1, 0.1, 0.2, 0.0],
                                                         [2, 1, 0.1, 0.2, 0.3]]),
                    ("x", "y", "theta0", "theta1", "xi"), min_clearance=math.inf,
                    compute_time=0.5, metrics={"planned_length": 0.25})
    return Result("fastep-s1", "demo", {"a": 0.18, "n": 50}, 7, [a, b])


def test_write_and_read_back(tmp_path):
    res = make_result()
    path = res.write(tmp_path / "out")
    data = json.loads(path.read_text())
    assert set(data) == {"scenario", "planner", "params", "seed", "version", "robots", "extras"}
    assert data["version"] == __version__
    r1, r2 = data["robots"]
    # R1 turns from atan2(4, 3) to +y and back: twice the angle between (3, 4) and (0, 1)
    turn = 2 * math.acos(4 / 5)
    assert r1 == {"name": "R1", "outcome": "reached", "path_length": 14.0,
                  "smoothness": pytest.approx(turn, abs=1e-15), "time_to_goal": 1.5,
                  "min_clearance": 0.25, "compute_time": 0.01}
    assert r2["time_to_goal"] is None and r2["min_clearance"] is None  # inf is not JSON
    assert r2["planned_length"] == 0.25 and r2["smoothness"] == 0.0
    with open(tmp_path / "out" / "trajectory_tt-2.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", "x", "y", "theta0", "theta1", "xi"]
    assert [float(v) for v in rows[2]] == [0.5, 2.0, 1.0, 0.1, 0.2, 0.3]
    back = read_result(tmp_path / "out")
    assert back.to_dict() == data
    np.testing.assert_array_equal(back.robots[0].states, res.robots[0].states)
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]


def test_path_length_is_polyline_length():
    assert path_length(np.array([[0, 0], [3, 4], [3, 8]])) == 9.0
    assert path_length(np.zeros((1, 2))) == 0.0


def _turning_reference(xy):
    """Independent reference: turning angles from dot and cross products (no heading wrap)."""
    pts = [np.asarray(p, dtype=float) for p in xy]
    pts = [p for i, p in enumerate(pts) if i == 0 or not np.array_equal(p, pts[i - 1])]
    total = 0.0
    for a, b, c in zip(pts, pts[1:], pts[2:]):
        u, v = b - a, c - b
        total += abs(math.atan2(u[0] * v[1] - u[1] * v[0], u @ v))
    return total


def test_smoothness_straight_line_is_zero():
    assert smoothness(np.column_stack([np.linspace(-3, 5, 17), np.linspace(2, -1, 17)])) == 0.0
    assert smoothness(np.zeros((1, 2))) == 0.0 and smoothness(np.zeros((0, 2))) == 0.0
    assert smoothness([[0, 0], [1, 1]]) == 0.0


def test_smoothness_right_angle_and_reversal():
    assert smoothness([[0, 0], [2, 0], [2, 3]]) == pytest.approx(math.pi / 2, abs=1e-15)
    assert smoothness([[0, 0], [2, 0], [2, -3]]) == pytest.approx(math.pi / 2, abs=1e-15)
    # a reversal is a change of exactly pi (the wrap is to (-pi, pi], either sign is pi)
    assert smoothness([[0, 0], [1, 0], [0, 0]]) == pytest.approx(math.pi, abs=1e-15)
    # headings on both sides of the -x axis: +179 deg to -179 deg is a 2 deg change, not 358
    a = math.radians(1.0)
    xy = [[0, 0], [-math.cos(a), math.sin(a)], [-2 * math.cos(a), 0.0]]
    assert smoothness(xy) == pytest.approx(2 * a, rel=1e-12)


def test_smoothness_zig_zag():
    # n teeth of +-45 degrees: the first corner turns 90 degrees, and so does every other one
    xy = np.array([[i, i % 2] for i in range(9)], dtype=float)
    assert smoothness(xy) == pytest.approx(7 * math.pi / 2, rel=1e-14)
    rng = np.random.default_rng(3)
    for _ in range(20):
        P = rng.normal(size=(12, 2))
        assert smoothness(P) == pytest.approx(_turning_reference(P), rel=1e-12, abs=1e-12)


def test_smoothness_ignores_resampling_of_straight_pieces_and_repeats():
    corners = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [1.0, 7.0], [6.0, 9.0]])
    dense = [corners[0]]
    for a, b in itertools.pairwise(corners):
        for s in np.linspace(0, 1, 7)[1:]:
            dense.append(a + s * (b - a))
    dense = np.array(dense)
    ref = smoothness(corners)
    assert ref == pytest.approx(_turning_reference(corners), rel=1e-14)
    assert smoothness(dense) == pytest.approx(ref, rel=1e-12)
    # a robot standing still repeats its point: no heading, no change
    stalled = np.repeat(dense, 3, axis=0)
    assert smoothness(stalled) == pytest.approx(ref, rel=1e-12)
    r = RobotResult("R", "timeout", np.arange(len(stalled)), stalled, ("x", "y"))
    assert r.summary()["smoothness"] == pytest.approx(ref, rel=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"outcome": "lost"}, "outcome: expected one of reached, collided"),
        ({"outcome": "reached"}, "time_to_goal: expected a time exactly when the outcome is"),
        ({"time_to_goal": 1.0}, "time_to_goal: expected a time exactly when the outcome is"),
        ({"name": "a/b"}, "robot name: expected letters"),
        ({"state_names": ("y", "x")}, "state_names: expected ('x', 'y', ...)"),
    ],
)
def test_bad_robot_results(kwargs, message):
    args = dict(name="R1", outcome="timeout", t=[0.0, 1.0], states=[[0, 0], [1, 1]],
                state_names=("x", "y"))
    args.update(kwargs)
    with pytest.raises(HybridnavError, match=None) as info:
        RobotResult(**args)
    assert message in str(info.value)


def test_outcomes_are_the_contract():
    assert OUTCOMES == ("reached", "collided", "out_of_bounds", "stuck", "timeout")


def test_read_result_errors_name_the_file(tmp_path):
    with pytest.raises(HybridnavError, match="result.json: no such file"):
        read_result(tmp_path)
    (tmp_path / "result.json").write_text("{not json")
    with pytest.raises(HybridnavError, match="result.json: not valid JSON"):
        read_result(tmp_path)
    (tmp_path / "result.json").write_text('{"scenario": "x"}')
    with pytest.raises(HybridnavError, match="result.json: planner: missing"):
        read_result(tmp_path)


# ---- extras: what a planner records for its diagnostics --------------------------------------

def test_extras_are_written_as_documented_files_and_read_back(tmp_path):
    import dataclasses

    # points_R1 is no planner's extra: its columns are free (a declared one's are not)
    res = dataclasses.replace(make_result(), extras={
        "signals_R1": {"t": [0.0, 0.1, 0.2], "w": [0.5, 0.25, 1e-300]},
        "points_R1": {"t": [0.0, 1.0], "mode": ["goal", "wall"],
                           "fitness": [1.5, math.nan]},
        "potential": np.arange(12.0).reshape(3, 4) / 7.0,
        "empty": {"x": [], "y": []},
    })
    res.write(tmp_path)
    data = json.loads((tmp_path / "result.json").read_text())
    assert data["extras"] == {
        "signals_R1": {"file": "signals_R1.csv", "text": []},
        "points_R1": {"file": "points_R1.csv", "text": ["mode"]},
        "potential": {"file": "potential.npy"}, "empty": {"file": "empty.csv", "text": []}}
    assert (tmp_path / "signals_R1.csv").read_text().splitlines() == [
        "t,w", "0.0,0.5", "0.1,0.25", "0.2,1e-300"]
    assert (tmp_path / "points_R1.csv").read_text().splitlines()[2] == "1.0,wall,nan"
    np.testing.assert_array_equal(np.load(tmp_path / "potential.npy"), res.extras["potential"])
    back = read_result(tmp_path)
    assert back.extras.keys() == res.extras.keys()
    for name, value in res.extras.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(back.extras[name], value)     # bit for bit
        else:
            for col in value:
                np.testing.assert_array_equal(back.extras[name][col], value[col])
    assert back.extras["points_R1"]["mode"].dtype.kind == "U"


def test_old_result_folders_without_extras_still_read(tmp_path):
    make_result().write(tmp_path)
    data = json.loads((tmp_path / "result.json").read_text())
    del data["extras"]
    (tmp_path / "result.json").write_text(json.dumps(data))
    assert read_result(tmp_path).extras == {}


def test_text_that_looks_like_numbers_stays_text(tmp_path):
    import dataclasses

    cols = {"a": ["1", "2"], "b": [" 1", "2 "], "c": ["nan", "inf"], "d": ["1_000", "x"]}
    dataclasses.replace(make_result(), extras={"s": cols, "e": {"t": np.zeros(0),
                                                               "m": np.array([], str)}}
                        ).write(tmp_path)
    back = read_result(tmp_path).extras
    for k, v in cols.items():
        assert back["s"][k].dtype.kind == "U" and list(back["s"][k]) == v
    assert back["e"]["m"].dtype.kind == "U" and back["e"]["t"].dtype.kind == "f"


@pytest.mark.parametrize("extras, message", [
    ({"trajectory_R1": {"t": [0.0]}}, r"result: extras: expected names .* got 'trajectory_R1'"),
    ({"s": {"m": ["a\rb"]}}, r"result: extras.s.m: expected one-line printable text"),
    ({"s": {"m": ["a\nb"]}}, r"result: extras.s.m: expected one-line printable text"),
    ({"s": {"m": ["x" * 1001]}}, r"result: extras.s.m: expected one-line printable text"),
    ({"s": {"a,b": [1.0]}}, r"result: extras.s: expected column names"),
    ({"s": {"a\nb": [1.0]}}, r"result: extras.s: expected column names"),
    ({"s": np.array([1, None], dtype=object)}, r"result: extras.s: expected an array of numbers"),
    ({"s": {"o": np.array([1, None], dtype=object)}}, r"result: extras.s.o: expected numbers or"),
    ({"result": {"t": [0.0]}}, r"result: extras: expected names .* got 'result'"),
    ({"../up": {"t": [0.0]}}, r"result: extras: expected names .* got '../up'"),
    ({"s": {"t": [0.0, 1.0], "w": [1.0]}}, r"result: extras.s: expected columns of one length"),
    ({"s": {"t": [[0.0, 1.0]]}}, r"result: extras.s.t: expected a named 1-D column"),
    ({"s": [1.0, 2.0]}, r"result: extras.s: expected a table .* got list"),
])
def test_bad_extras_are_refused_with_the_key(extras, message):
    r = make_result()
    with pytest.raises(HybridnavError, match=message):
        Result(r.scenario, r.planner, r.params, r.seed, r.robots, extras=extras)


def test_a_listed_extra_that_is_missing_names_the_file(tmp_path):
    import dataclasses

    dataclasses.replace(make_result(), extras={"s": {"t": [0.0]}}).write(tmp_path)
    (tmp_path / "s.csv").unlink()
    with pytest.raises(HybridnavError, match=r"s\.csv: no such file \(listed in result.json"):
        read_result(tmp_path)


def _folder(tmp_path):
    import dataclasses

    dataclasses.replace(make_result(), extras={"s": {"t": [0.0, 1.0], "m": ["a", "b"]},
                                               "p": np.eye(2)}).write(tmp_path)
    return tmp_path


def _edit(path, fn):
    data = json.loads(path.read_text())
    fn(data)
    path.write_text(json.dumps(data))


@pytest.mark.parametrize("change, message", [
    (lambda f: _edit(f / "result.json", lambda d: d.update(robots=5)),
     r"result.json: robots: expected an array, got 5"),
    (lambda f: _edit(f / "result.json", lambda d: d.update(robots=None)),
     r"result.json: robots: expected an array, got None"),
    (lambda f: _edit(f / "result.json", lambda d: d.update(seed="x")),
     r"result.json: seed: expected a non-negative integer or null, got 'x'"),
    (lambda f: _edit(f / "result.json", lambda d: d["robots"][0].update(name="../R1")),
     r"result.json: robots\[0\].name: expected at most 100 letters, digits"),
    (lambda f: _edit(f / "result.json", lambda d: d["robots"][0].update(outcome="won")),
     r"result.json: robots\[0\].outcome: expected one of reached, .* got 'won'"),
    (lambda f: (f / "trajectory_R1.csv").write_text("t,x,y\n"),
     r"trajectory_R1.csv: expected at least one sample"),
    (lambda f: (f / "trajectory_R1.csv").write_text("t,x,y\n0,1\n"),
     r"trajectory_R1.csv: line 2: expected 3 fields"),
    (lambda f: (f / "trajectory_R1.csv").write_bytes(b"t,x,y\n\xff\xfe,1,2\n"),
     r"trajectory_R1.csv: not UTF-8 text"),
    (lambda f: ((f / "trajectory_R1.csv").unlink(), (f / "trajectory_R1.csv").mkdir()),
     r"trajectory_R1.csv: no such file"),
    (lambda f: (f / "s.csv").write_text("t,m\n" + "x" * 200_000 + ",a\n"),
     r"s.csv: not a CSV file"),
    (lambda f: _edit(f / "result.json", lambda d: d["extras"].update({"../up": "../up.csv"})),
     r"result.json: extras: expected names .* got '../up'"),
    (lambda f: _edit(f / "result.json", lambda d: d["extras"].update(s={"file": "/etc/passwd"})),
     r"result.json: extras.s: expected"),
    (lambda f: (f / "p.npy").write_bytes(b"PK\x03\x04 not an array"),
     r"p.npy: not a numpy .npy array of numbers"),
    (lambda f: _huge_npy(f / "p.npy"),
     r"p.npy: expected an array of numbers with at most 20000000 entries"),
    (lambda f: (f / "p.npy").write_bytes(open(_object_npy(f), "rb").read()),
     r"p.npy: expected an array of numbers"),
])
def test_an_edited_result_folder_fails_with_the_file_and_key(tmp_path, change, message):
    folder = _folder(tmp_path)
    change(folder)
    with pytest.raises(HybridnavError, match=message):
        read_result(folder)


def _object_npy(folder):
    path = folder / "object.npy"
    np.save(path, np.array([1, None], dtype=object), allow_pickle=True)
    return path


def _huge_npy(path):
    """A .npy header claiming 10**11 doubles (800 GB), followed by no data."""
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (10**11,)})
