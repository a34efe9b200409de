"""Contracts every registered planner, model and optimizer keeps (parametrized over the
registries, so a new one is checked without writing a test for it)."""

from __future__ import annotations

import numpy as np
import pytest

from hybridnav import HybridnavError, models, planners
from hybridnav.planners.swarm import OPTIMIZERS
from hybridnav.results import OUTCOMES, read_result
from hybridnav.world import MODEL_NAMES, scenario_from_dict

SMALL = {
    "name": "contract", "dt": 0.1, "max_time": 80.0,
    "workspace": {"xmin": 0.0, "xmax": 10.0, "ymin": 0.0, "ymax": 10.0},
    "obstacles": [{"type": "circle", "center": [5.0, 7.5], "radius": 1.0}],
    "robots": [{"name": "R", "model": "point_mass", "start": [1.0, 1.0], "goal": [9.0, 9.0],
                "goal_radius": 0.3, "radius": 0.2}],
}


@pytest.fixture(scope="module")
def small():
    return scenario_from_dict(SMALL)


def driven(name, small):
    """The contract scenario with a robot model the planner drives (the point mass if it can)."""
    cls = planners.PLANNERS[name]
    if "point_mass" in cls.models:
        return small
    d = {**SMALL, "robots": [{**SMALL["robots"][0], "model": cls.models[0]}]}
    return scenario_from_dict(d)


@pytest.mark.parametrize("name", sorted(planners.PLANNERS))
def test_planner_refuses_an_unknown_parameter(name):
    cls = planners.PLANNERS[name]
    expected = ", ".join(sorted(cls.parameters)) or "(none)"
    with pytest.raises(HybridnavError) as err:
        planners.get(name, no_such_parameter=1)
    assert str(err.value) == (f"planner {name}: unknown parameter 'no_such_parameter'; "
                              f"expected one of: {expected}")


@pytest.mark.parametrize("name", sorted(planners.PLANNERS))
def test_planner_declares_the_robots_it_drives_by_capability(name):
    cls = planners.PLANNERS[name]
    assert cls.models and set(cls.models) <= set(MODEL_NAMES)
    for model in cls.models:
        caps = models.MODELS[model].capabilities
        assert any(req <= caps for req in cls.drives)


@pytest.mark.parametrize("name", sorted(planners.PLANNERS))
def test_planner_outcome_seed_and_result_round_trip(name, small, tmp_path):
    small = driven(name, small)
    first = planners.get(name).run(small, seed=3)
    again = planners.get(name).run(small, seed=3)
    assert [r.name for r in first.robots] == ["R"]
    for a, b in zip(first.robots, again.robots):
        assert a.outcome in OUTCOMES
        assert a.outcome == b.outcome                      # the same seed, the same run
        np.testing.assert_array_equal(a.states, b.states)
        assert a.t[0] == 0.0 and np.all(np.diff(a.t) > 0)
        assert a.state_names[:2] == ("x", "y")               # the trajectory CSV contract
    back = read_result(first.write(tmp_path / name).parent)
    assert back.planner == first.planner and back.seed == 3
    for a, b in zip(first.robots, back.robots):
        assert b.outcome == a.outcome
        np.testing.assert_allclose(b.states, a.states, rtol=1e-12, atol=1e-12)
    assert back.extras.keys() == first.extras.keys()
    for key, value in first.extras.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(back.extras[key], value)
        else:
            assert back.extras[key].keys() == value.keys()
            for col in value:
                np.testing.assert_array_equal(back.extras[key][col], value[col])


@pytest.mark.parametrize("name", sorted(planners.PLANNERS))
def test_planner_is_stateless_and_diagnoses_a_result_read_from_disk(name, small, tmp_path):
    from matplotlib.figure import Figure

    small = driven(name, small)
    import pickle

    planner = planners.get(name)
    before = dict(vars(planner))
    frozen = pickle.dumps(before)
    first = planner.run(small, seed=3)
    assert vars(planner).keys() == before.keys()            # a run leaves nothing on the object
    assert all(vars(planner)[k] is v for k, v in before.items())
    assert pickle.dumps(dict(vars(planner))) == frozen      # and changes nothing inside it
    second = planner.run(small, seed=3)                     # so one instance runs again alike
    for a, b in zip(first.robots, second.robots):
        np.testing.assert_array_equal(a.states, b.states)
    figures = planners.get(name).diagnostics(small, first)   # another instance: from the result
    back = read_result(first.write(tmp_path / name).parent)
    again = planners.get(name).diagnostics(small, back)
    assert again.keys() == figures.keys()
    assert all(isinstance(f, Figure) for f in again.values())
    for key in figures:
        assert len(again[key].axes) == len(figures[key].axes)


@pytest.mark.parametrize("name", sorted(models.MODELS))
def test_model_refuses_unknown_parameters_and_declares_what_others_ask(name):
    cls = models.MODELS[name]
    with pytest.raises(HybridnavError, match="no_such_parameter"):
        models.get(name, no_such_parameter=1.0)
    assert isinstance(cls.capabilities, frozenset)
    assert set(cls.angle_state_names) <= set(cls.plant_state_names + cls.controller_state_names)
    if cls.analysis_scenario is not None:
        from hybridnav.world import load_scenario

        load_scenario(cls.analysis_scenario)             # the scenario analyze uses exists


@pytest.mark.parametrize("name", sorted(OPTIMIZERS))
def test_optimizer_refuses_an_unknown_parameter_and_reproduces_its_seed(name):
    from hybridnav.planners import swarm

    def f(X):
        return np.sum((np.asarray(X) - 0.25) ** 2, axis=1)

    box = ([0.0, 0.0], [1.0, 1.0])
    with pytest.raises(HybridnavError, match=rf"^no_such_parameter: unknown parameter of {name}"):
        swarm.minimize(name, f, box, no_such_parameter=1)
    a = swarm.minimize(name, f, box, iterations=5, seed=3)
    b = swarm.minimize(name, f, box, iterations=5, seed=3)
    np.testing.assert_array_equal(a.population, b.population)
    assert a.fun == b.fun and np.all((a.population >= 0) & (a.population <= 1))
