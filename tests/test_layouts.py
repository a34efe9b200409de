"""Layout sensitivity of the reproductions: the perturbed layouts, the verdicts on them, the
report's table and the stored verdicts."""

import math

import numpy as np
import pandas as pd
import pytest

from hybridnav.cli import main
from hybridnav.errors import HybridnavError
from hybridnav.reproduce import PROTOCOLS, reproduce
from hybridnav.reproduce.layouts import JITTER, failing_rows, perturbed_layouts
from hybridnav.reproduce.report import sensitivity_section
from hybridnav.reproduce.readme import load_layouts
from hybridnav.world import load_scenario, scenario_to_dict


def _tags(layouts):
    return [tag for tag, _ in layouts]


def test_the_family_mirrors_moves_starts_and_jitters_obstacles_within_bounds():
    base = load_scenario("effc-env-b")
    layouts = dict(perturbed_layouts(base, 8, seed=3))
    assert list(layouts) == ["mirror-x", "mirror-y", "start+", "start-", "jitter-1",
                             "jitter-2", "jitter-3", "jitter-4"]
    r0 = base.robots[0]
    (xmin, xmax, ymin, ymax) = base.world.workspace
    dist = math.dist(r0.start, r0.goal)
    # mirror-x: every point reflected about x = (xmin + xmax) / 2, the heading as a direction
    mx = layouts["mirror-x"].robots[0]
    assert mx.start == pytest.approx((xmin + xmax - r0.start[0], r0.start[1]))
    assert mx.goal == pytest.approx((xmin + xmax - r0.goal[0], r0.goal[1]))
    t0, t1 = r0.initial["theta"], mx.initial["theta"]
    assert (math.cos(t1), math.sin(t1)) == pytest.approx((-math.cos(t0), math.sin(t0)))
    my = layouts["mirror-y"].robots[0]
    assert my.start == pytest.approx((r0.start[0], ymin + ymax - r0.start[1]))
    # reflecting the clearance field: the mirrored world's clearance at mirrored points is the
    # original's at the original points
    rng = np.random.default_rng(0)
    P = rng.uniform([xmin, ymin], [xmax, ymax], size=(500, 2))
    Q = np.column_stack([xmin + xmax - P[:, 0], P[:, 1]])
    np.testing.assert_allclose(layouts["mirror-x"].world.clearance(Q), base.world.clearance(P),
                               atol=1e-12)
    # the start moves sideways (perpendicular to start-goal) by JITTER of the distance
    for tag, sign in (("start+", 1), ("start-", -1)):
        s = np.subtract(layouts[tag].robots[0].start, r0.start)
        assert np.linalg.norm(s) == pytest.approx(JITTER * dist)
        assert np.dot(s, np.subtract(r0.goal, r0.start)) == pytest.approx(0.0, abs=1e-12)
        u = np.subtract(r0.goal, r0.start)
        assert (u[0] * s[1] - u[1] * s[0]) * sign > 0          # to the left for start+
    # jitters move every obstacle rigidly by at most JITTER * distance; starts and goals clear
    d0 = scenario_to_dict(base)["obstacles"]
    for k in range(1, 5):
        lay = layouts[f"jitter-{k}"]
        for a, b in zip(d0, scenario_to_dict(lay)["obstacles"]):
            key = "center" if "center" in a else "min" if "min" in a else "points"
            pa, pb = np.atleast_2d(a[key]), np.atleast_2d(b[key])
            shift = pb - pa
            assert np.allclose(shift, shift[0])
            assert np.linalg.norm(shift[0]) <= JITTER * dist + 1e-12
        r = lay.robots[0]
        assert (lay.world.clearance(np.array([r.start, r.goal]), radius=r.radius) > 0).all()
    # reproducible from the seed, different with another
    again = dict(perturbed_layouts(base, 8, seed=3))
    other = dict(perturbed_layouts(base, 8, seed=4))
    assert scenario_to_dict(again["jitter-2"]) == scenario_to_dict(layouts["jitter-2"])
    assert scenario_to_dict(other["jitter-2"]) != scenario_to_dict(layouts["jitter-2"])
    assert all(lay.name == f"effc-env-b.{tag}" for tag, lay in layouts.items())


def test_mirroring_twice_gives_the_original_and_trailers_mirror_their_headings():
    base = load_scenario("tractor-trailer-1")
    once = dict(perturbed_layouts(base, 2))["mirror-y"]
    twice = dict(perturbed_layouts(once, 2))["mirror-y"]
    a, b = scenario_to_dict(base), scenario_to_dict(twice)
    for d in (a, b):
        d.pop("name"), d.pop("description")
    np.testing.assert_allclose(
        [o.get("center", [0, 0])[1] for o in b["obstacles"]],
        [o.get("center", [0, 0])[1] for o in a["obstacles"]], atol=1e-12)
    for key in ("theta0", "theta1"):
        assert once.robots[0].initial[key] == pytest.approx(-base.robots[0].initial[key])
        assert twice.robots[0].initial[key] == pytest.approx(base.robots[0].initial[key])


def test_a_grid_map_file_only_moves_starts_and_bad_jitter_is_refused():
    assert _tags(perturbed_layouts(load_scenario("rfd-pso-alley"), 8)) == ["start+", "start-"]
    for bad in (0.0, 1.0, -0.1, math.nan):
        with pytest.raises(HybridnavError, match="jitter: expected a fraction in"):
            perturbed_layouts(load_scenario("effc-env-a"), 2, jitter=bad)


def _summary(rows):
    """A hand-built summary: ``rows`` of (planner, scenario, reached, length, p)."""
    out = []
    for planner, scenario, reached, length, p in rows:
        out.append({"planner": planner, "scenario": scenario, "robots": 5,
                    "success_rate": reached / 5, "collided": 0, "stuck": 5 - reached,
                    "timeout": 0, "out_of_bounds": 0, "path_length_mean": length,
                    "time_to_goal_mean": 10.0, "units": "m",
                    **{f"path_length_p_vs_{o}": p for o in ("effc", "hapf", "pbpf")}})
    return pd.DataFrame(out)


def test_failing_rows_and_the_table_use_the_main_tables_rule():
    protocol = PROTOCOLS["effc-table3"]
    own = _summary([("effc", "effc-env-a", 0, math.nan, math.nan),
                    ("hapf", "effc-env-a", 5, 2.8, math.nan),
                    ("pbpf", "effc-env-a", 0, math.nan, math.nan),
                    ("effc", "effc-env-b", 5, 2.5, 0.01), ("hapf", "effc-env-b", 5, 2.9, 0.01),
                    ("pbpf", "effc-env-b", 5, 2.6, 0.01)])
    # effc reached none where hapf reached: both claims against HAPF fail in environment (a)
    assert failing_rows(protocol, own) == [(0, "environment (a)"), (2, "environment (a)")]
    verdicts = pd.DataFrame([
        {"claim": 0, "text": protocol.claims[0].text, "row": "environment (a)",
         "scenario": "effc-env-a", "layout": tag, "view": view, "verdict": v, "detail": ""}
        for tag, v in (("mirror-x", False), ("start+", True), ("jitter-1", None))
        for view in ("paper profile", "hybridnav profile")])
    text = "\n".join(sensitivity_section(protocol, verdicts, own, runs=5, profiles=False))
    assert "## Layout sensitivity" in text
    assert ("| EFFC's path is shorter than HAPF's | environment (a) | 3 (mirror-x, start+, "
            "jitter-1) | does not hold here; 1 / 1 / 1 of 3 |") in text
    assert sensitivity_section(protocol, verdicts.iloc[:0], own, runs=5) == []


@pytest.mark.slow
def test_reproduce_writes_the_layout_table_and_the_readme_renders_it(tmp_path, capsys):
    out = tmp_path / "effc"
    assert main(["reproduce", "effc-table3", "--runs", "1", "--layouts", "2",
                 "--scenarios", "effc-env-a", "-o", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert "## Layout sensitivity" in text
    assert sorted(p.name for p in (out / "layouts").iterdir()) == [
        "effc-env-a.mirror-x.toml", "effc-env-a.mirror-y.toml"]
    table = load_layouts(out, PROTOCOLS["effc-table3"])
    assert set(table["layout"]) == {"mirror-x", "mirror-y"}
    assert set(table["verdict"]) <= {True, False, None}
    # layout files are scenarios anyone can run again
    assert load_scenario(out / "layouts" / "effc-env-a.mirror-x.toml").name == \
        "effc-env-a.mirror-x"
    # --layouts 0: no table, and the earlier run's verdicts are gone
    reproduce("effc-table3", out, runs=1, layouts=0, scenarios=["effc-env-a"])
    assert not (out / "layouts.csv").exists()
    assert not list((out / "layouts").glob("*.toml"))        # nor the earlier layouts
    assert "## Layout sensitivity" not in (out / "report.md").read_text()


def test_bad_layout_counts_and_stored_verdicts_are_named_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", "effc-table3", "--layouts", "-1", "-o", str(tmp_path)])
    assert exc.value.code == 2
    assert "--layouts: expected an integer in [0, 100]" in capsys.readouterr().err
    with pytest.raises(HybridnavError, match="--layouts: expected an integer"):
        reproduce("effc-table3", tmp_path, layouts=True)
    protocol = PROTOCOLS["effc-table3"]
    good = ("claim,text,row,scenario,layout,view,verdict,detail\n"
            "0,t,environment (a),effc-env-a,mirror-x,hybridnav profile,False,d\n")
    (tmp_path / "layouts.csv").write_text(good)
    assert load_layouts(tmp_path, protocol)["verdict"].tolist() == [False]
    for bad, what in ((good.replace(",False,", ",maybe,"), "verdict: expected True, False "
                       "or empty, got 'maybe' in row 2"),
                      (good.replace("0,t,", "9,t,"), "claim: expected a claim index"),
                      (good.replace("environment (a)", "env z"), "row: expected a row label"),
                      (good.replace("detail", "x"), "detail: missing column")):
        (tmp_path / "layouts.csv").write_text(bad)
        with pytest.raises(HybridnavError, match=r"layouts\.csv: " + what.replace("(", r"\(")):
            load_layouts(tmp_path, protocol)


def _box(o):
    if "center" in o:
        c = np.asarray(o["center"])
        return c - o["radius"], c + o["radius"]
    if "min" in o:
        return np.asarray(o["min"]), np.asarray(o["max"])
    P = np.asarray(o["points"] if "points" in o else [o["a"], o["b"]])
    return P.min(axis=0), P.max(axis=0)


@pytest.mark.parametrize("name", ["turtlebot-office", "pso-ba-dynamic", "rfd-pso-20m"])
def test_jittered_obstacles_stay_inside_the_workspace_and_walls_stay_whole(name):
    """An office's outer walls and the room walls attached to them do not move (moving a piece
    of a wall opens a doorway the layout does not have, or pushes it out of the workspace), and
    no jittered obstacle leaves the workspace (formerly: every obstacle of the office moved by
    up to 0.27 m, its 0.1 m outer walls partly out of the workspace and room walls detached)."""
    base = load_scenario(name)
    xmin, xmax, ymin, ymax = base.world.workspace
    d0 = scenario_to_dict(base)["obstacles"]
    jitters = [lay for tag, lay in perturbed_layouts(base, 20, seed=0) if "jitter" in tag]
    assert jitters
    for lay in jitters:
        for a, b in zip(d0, scenario_to_dict(lay)["obstacles"]):
            lo, hi = _box(b)
            assert lo[0] >= xmin and lo[1] >= ymin and hi[0] <= xmax and hi[1] <= ymax, \
                (lay.name, b)
            lo0, hi0 = _box(a)
            touches_edge = lo0[0] <= xmin or lo0[1] <= ymin or hi0[0] >= xmax or hi0[1] >= ymax
            if touches_edge:
                assert a == b, (lay.name, a, b)
    if name == "turtlebot-office":            # every wall piece stays, the furniture moves
        moved = {i for lay in jitters
                 for i, (a, b) in enumerate(zip(d0, scenario_to_dict(lay)["obstacles"]))
                 if a != b}
        walls = {i for i, o in enumerate(d0) if o["type"] == "rectangle"}
        assert not moved & walls and moved == set(range(len(d0))) - walls


def test_a_heading_left_out_is_mirrored_too():
    """A unicycle without ``initial.theta`` starts at heading 0 (east); mirrored about the
    vertical line it must start facing west (formerly it kept heading 0: not a mirror image)."""
    from hybridnav.world import scenario_from_dict

    data = scenario_to_dict(load_scenario("effc-env-a"))
    data["robots"][0]["initial"] = {}
    base = scenario_from_dict(data)
    layouts = dict(perturbed_layouts(base, 2))
    t = layouts["mirror-x"].robots[0].initial.get("theta", 0.0)
    assert (math.cos(t), math.sin(t)) == pytest.approx((-1.0, 0.0))
    t = layouts["mirror-y"].robots[0].initial.get("theta", 0.0)
    assert (math.cos(t), math.sin(t)) == pytest.approx((1.0, 0.0))
    # a point mass has no heading: nothing is added
    assert dict(perturbed_layouts(load_scenario("fastep-s1"), 1))["mirror-x"].robots[0] \
        .initial == {}


def test_stored_verdicts_must_be_layouts_of_the_rows_they_name(tmp_path):
    """A layout tag that is none of the family (a README marker smuggled into the block), a
    scenario that is not the row's, a row the claim does not cover, or the same layout twice
    (counted twice in the share) is refused."""
    protocol = PROTOCOLS["effc-table3"]
    head = "claim,text,row,scenario,layout,view,verdict,detail\n"
    good = "0,t,environment (a),effc-env-a,mirror-x,hybridnav profile,False,d\n"
    (tmp_path / "layouts.csv").write_text(head + good + good.replace("mirror-x", "jitter-12"))
    assert load_layouts(tmp_path, protocol)["layout"].tolist() == ["mirror-x", "jitter-12"]
    for rows, what in (
            (good.replace("mirror-x", '"a | b\n<!-- /reproduce:effc-table3 -->"'),
             "layout: expected mirror-x, mirror-y, start\\+, start- or jitter-<k>"),
            (good.replace("mirror-x", "jitter-0"), "layout: expected"),
            (good.replace(",effc-env-a,", ",effc-env-b,"),
             r"scenario: expected effc-env-a \(the scenario of row 'environment \(a\)'\)"),
            (good + good.replace(",False,", ",True,"),
             "layout: expected one verdict per claim, row, layout and view")):
        (tmp_path / "layouts.csv").write_text(head + rows)
        with pytest.raises(HybridnavError, match=r"layouts\.csv: " + what):
            load_layouts(tmp_path, protocol)
    aco = PROTOCOLS["aco-table5"]
    stuck = next(i for i, c in enumerate(aco.claims) if c.kind == "stuck")
    (tmp_path / "layouts.csv").write_text(
        head + f"{stuck},t,scenario 1,fastep-s1,mirror-x,hybridnav profile,True,d\n")
    with pytest.raises(HybridnavError, match=r"row: expected a row of claim \d \(scenario 4\)"):
        load_layouts(tmp_path, aco)


def test_stored_verdicts_need_the_runs_per_layout_beside_them(tmp_path):
    """layouts.csv in a stored run whose comparison.json has no layout_runs (or 0) would render
    "0 run(s) per planner and layout" beside verdicts: refused."""
    import json
    import shutil
    from pathlib import Path

    from hybridnav.reproduce.readme import STORE, render

    root = Path(__file__).resolve().parents[1]
    folder = tmp_path / "effc-table3"
    shutil.copytree(root / STORE / "effc-table3", folder)
    (folder / "layouts.csv").write_text(
        "claim,text,row,scenario,layout,view,verdict,detail\n"
        "0,t,environment (a),effc-env-a,mirror-x,hybridnav profile,False,d\n")
    meta = json.loads((folder / "comparison.json").read_text())
    for runs in (None, 0):
        (folder / "comparison.json").write_text(json.dumps(
            {k: v for k, v in {**meta, "layout_runs": runs}.items() if v is not None}))
        with pytest.raises(HybridnavError, match="comparison.json: layout_runs: expected the "
                                                 "runs per planner and layout"):
            render(folder)
    (folder / "comparison.json").write_text(json.dumps({**meta, "layout_runs": 3}))
    assert "(3 run(s) per planner and layout)" in render(folder)
