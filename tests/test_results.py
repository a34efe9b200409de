"""The result contract: result.json + one trajectory CSV per robot, written atomically."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from hybridnav import HybridnavError, __version__
from hybridnav.results import OUTCOMES, Result, RobotResult, path_length, read_result


def make_result():
    t = np.arange(4) * 0.5
    a = RobotResult("R1", "reached", t, np.array([[0, 0], [3, 4], [3, 8], [6, 12]]), ("x", "y"),
                    time_to_goal=1.5, min_clearance=0.25, compute_time=0.01)
    b = RobotResult("tt-2", "collided", t[:2], np.array([[1, 1, 0.1, 0.2, 0.0],
                                                         [2, 1, 0.1, 0.2, 0.3]]),
                    ("x", "y", "theta0", "theta1", "xi"), min_clearance=math.inf,
                    compute_time=0.5, metrics={"smoothness": 0.25})
    return Result("fastep-s1", "demo", {"a": 0.18, "n": 50}, 7, [a, b])


def test_write_and_read_back(tmp_path):
    res = make_result()
    path = res.write(tmp_path / "out")
    data = json.loads(path.read_text())
    assert set(data) == {"scenario", "planner", "params", "seed", "version", "robots"}
    assert data["version"] == __version__
    r1, r2 = data["robots"]
    assert r1 == {"name": "R1", "outcome": "reached", "path_length": 14.0, "time_to_goal": 1.5,
                  "min_clearance": 0.25, "compute_time": 0.01}
    assert r2["time_to_goal"] is None and r2["min_clearance"] is None  # inf is not JSON
    assert r2["smoothness"] == 0.25
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
