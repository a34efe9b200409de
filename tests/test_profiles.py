"""Planner profiles (issue 16): ``profile=paper`` selects the paper's settings, ``hybridnav`` (the
default) this package's; explicit parameters win; every run records its profile."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav import HybridnavError, planners
from hybridnav.cli import main
from hybridnav.planners.path.geometry import pull_tight, sample_along
from hybridnav.planners.path.planners import obstacle_world
from hybridnav.results import path_length
from hybridnav.world import load_scenario

WITH_PROFILES = {name: cls for name, cls in planners.PLANNERS.items() if cls.profiles}


def test_the_reproduced_planners_have_both_profiles():
    assert {"fastep-kinematic", "aco-kinematic", "rfd", "pso", "rfd-pso"} <= set(WITH_PROFILES)
    for name, cls in WITH_PROFILES.items():
        assert set(cls.profiles) == {"hybridnav", "paper"}, name
        assert cls.profiles["hybridnav"] == {}
        assert cls.parameters["profile"].default == "hybridnav"
        assert cls.paper_notes.startswith("paper")


@pytest.mark.parametrize("name", sorted(WITH_PROFILES))
def test_profile_paper_sets_its_values_and_explicit_ones_win(name):
    cls = WITH_PROFILES[name]
    paper = cls.profiles["paper"]
    p = planners.get(name, profile="paper")
    assert p.values["profile"] == "paper" and p.describe()["profile"] == "paper"
    for key, value in paper.items():
        assert p.values[key] == value
    default = planners.get(name)
    assert default.values["profile"] == "hybridnav"
    for key in paper:
        assert default.values[key] == cls.parameters[key].default
    key = next(iter(paper))
    mine = cls.parameters[key].default
    assert planners.get(name, profile="paper", **{key: mine}).values[key] == mine
    with pytest.raises(HybridnavError,
                       match=rf"planner {name}: profile: expected one of hybridnav, paper, "
                             r"got 'papers'"):
        planners.get(name, profile="papers")


def test_paper_profiles_say_what_the_papers_do():
    assert planners.get("fastep-kinematic", profile="paper").values["distance"] == "euclidean"
    assert planners.get("aco-kinematic", profile="paper").values["distance"] == "euclidean"
    assert planners.get("rfd", profile="paper").values["slope"] == 0.0
    rp = planners.get("rfd-pso", profile="paper").values
    assert (rp["slope"], rp["iterations"], rp["shorten"]) == (0.0, 50, False)
    assert (rp["grid"], rp["waypoints"]) == (20, 28)
    assert planners.get("rfd", profile="paper").values["grid"] == 20
    pp = planners.get("pso", profile="paper").values
    assert (pp["iterations"], pp["waypoints"]) == (50, 28)


def test_rfd_pso_paper_seeds_the_rfd_path_itself_not_its_shortened_form():
    """No shortening: the seed particle is the RFD path sampled at K points along its length;
    the hybridnav profile pulls the path tight first (the seed's corners are RFD vertices)."""
    s = load_scenario("rfd-pso-700")
    name = s.robots[0].name
    out = {}
    for profile in ("paper", "hybridnav"):
        # the same RFD terrain and grid in both, so that only the seeding differs
        plan = planners.get("rfd-pso", profile=profile, slope=0.01, grid=20).plans(s, seed=2)[0]
        out[profile] = plan
    rfd = out["paper"].info["rfd_points"]
    np.testing.assert_array_equal(rfd, out["hybridnav"].info["rfd_points"])
    seed_paper = out["paper"].info["seed_points"]
    np.testing.assert_allclose(seed_paper[1:-1], sample_along(rfd, 28), rtol=0, atol=1e-12)
    tight = pull_tight(rfd, obstacle_world(s), 12.5)
    assert path_length(out["hybridnav"].info["seed_points"]) == pytest.approx(
        path_length(tight), rel=1e-12)
    assert path_length(tight) < path_length(rfd)
    assert name


def test_sample_along_is_evenly_spaced_on_the_polyline():
    P = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    Q = sample_along(P, 6)
    np.testing.assert_allclose(Q, [[1, 0], [2, 0], [3, 0], [4, 0], [4, 1], [4, 2]], atol=1e-12)


def test_shorten_pulls_the_astar_path_tight():
    s = load_scenario("rfd-pso-700")
    plain = planners.get("astar").plans(s)[0]
    tight = planners.get("astar", shorten=True).plans(s)[0]
    assert tight.length < plain.length
    np.testing.assert_array_equal(tight.points, pull_tight(plain.points, obstacle_world(s),
                                                           12.5))


def test_profile_from_the_cli_is_listed_and_recorded(tmp_path, capsys):
    assert main(["planners"]) == 0
    text = capsys.readouterr().out
    assert ("profile 'paper': slope = 0.0, iterations = 50, shorten = False, grid = 20, "
            "waypoints = 28") in text
    assert main(["run", "rfd-pso-700", "--planner", "rfd", "--set", "profile=paper",
                 "--out", str(tmp_path / "run")]) == 0
    from hybridnav.results import read_result

    back = read_result(tmp_path / "run")
    assert back.params["profile"] == "paper" and back.params["slope"] == 0.0


def test_lbcs_stalls_in_the_papers_scenario_4():
    """The ACO-Kinematic paper's scenario 4 (start (5,5), goal (45,45), our reconstruction of
    its cup): LbCS is trapped, as the paper reports."""
    r = planners.get("lbcs").run(load_scenario("aco-scenario-4"))
    assert r.robots[0].outcome == "stuck"


def test_aco_kinematic_paper_profile_is_stuck_in_the_local_minimum_trap():
    """With the paper's straight-line distance, no goal candidate and one archive, ACO-Kinematic
    walks into the cup of aco-local-minimum and stays there; the geodesic distance leads it round
    (seed 0 of both)."""
    s = load_scenario("aco-local-minimum")
    paper = planners.get("aco-kinematic", profile="paper").run(s, seed=0).robots[0]
    ours = planners.get("aco-kinematic").run(s, seed=0).robots[0]
    assert paper.outcome == "stuck" and ours.outcome == "reached"
    # stuck inside the cup: within the arc of radius 6 round (27, 25)
    assert np.hypot(*(paper.states[-1, :2] - (27.0, 25.0))) < 6.0


@pytest.mark.long
def test_pso_ba_paper_profile_has_eq_9s_pso_and_the_swarm_barely_matters():
    """eq. 9 has no inertia factor; the PSO tunes the bats, but the best bat is a full step
    towards the goal whatever they are: two seeds give paths 5e-4 (of 50) apart."""
    assert planners.get("pso-ba", profile="paper").values["pso_w"] == 1.0
    s = load_scenario("pso-ba-dynamic")
    a = planners.get("pso-ba", profile="paper").run(s, seed=0)
    b = planners.get("pso-ba", profile="paper").run(s, seed=1)
    for ra, rb in zip(a.robots, b.robots):
        assert ra.outcome == rb.outcome == "reached"
        assert ra.states.shape == rb.states.shape
        assert 0 < np.abs(ra.states - rb.states).max() < 1e-2
