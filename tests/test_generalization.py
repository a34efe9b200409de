"""The main job's tuned controller on worlds it never saw.

``effc-tuned`` is the system the README's main job (``hybridnav tune --workers 2 --out tuned``,
built-in defaults, seed 0) returns: trained on generated worlds of seeds 1 and 11 (trap
structures), chosen on seeds 2 and 12, reported on seeds 3 and 13, with its escape-circle safety
filter at 5 cm. Here it is judged, with that filter, on 40 generated and 16 trap worlds of seed
2027 — disjoint from all of them — against the system it started from (``effc-5rule``, the same
filter) and plain ``apf``. The rows come from the lockstep simulation; a sample is replayed with
the planners.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from hybridnav import fuzzy, planners
from hybridnav.tuner.heldout import run_systems, summarize, verdict
from hybridnav.tuner.job import load_job
from hybridnav.world.generator import WorldGenerator

FRESH_SEED = 2027


def test_fresh_seed_is_disjoint_from_the_jobs_sets():
    job = load_job(None)
    seeds = {item["seed"] for k in ("train", "validation", "test")
             for item in job["scenarios"][k] if isinstance(item, dict)}
    assert FRESH_SEED not in seeds
    fresh = {tuple(w.robots[0].start) for w in _fresh()}
    used = {tuple(s.robots[0].start) for k in ("train", "validation", "test")
            for s in job.scenarios(k)}
    assert not fresh & used


#: the deployment setting the main job tunes and judges with (its [planner] safety_margin)
MARGIN = 0.05


def _fresh():
    from hybridnav.tuner.job import TRAPS

    traps = {k: tuple(v) if isinstance(v, list) else v for k, v in TRAPS.items()}
    return WorldGenerator().generate(40, FRESH_SEED) + WorldGenerator(**traps).generate(
        16, FRESH_SEED)


@pytest.fixture(scope="module")
def table():
    worlds = _fresh()
    systems = {"start": fuzzy.builtin("effc-5rule"), "tuned": fuzzy.builtin("effc-tuned")}
    return worlds, systems, run_systems(systems, worlds, safety_margin=MARGIN)


def test_rows_are_what_the_planners_do(table):
    worlds, systems, t = table
    for w in worlds[::8]:
        for label, system in systems.items():
            r = planners.get("effc", fis=system, safety_margin=MARGIN).run(w).robots[0]
            row = t[(t.scenario == w.name) & (t.system == label)].iloc[0]
            assert row.outcome == r.outcome
            assert row.path_length == pytest.approx(r.path_length, rel=1e-9)
            assert row.min_clearance == pytest.approx(r.min_clearance, rel=1e-9)
        a = planners.get("apf").run(w).robots[0]          # the baseline: plain apf
        assert t[(t.scenario == w.name) & (t.system == "apf")].iloc[0].outcome == a.outcome


def test_tuned_reaches_more_than_start_and_apf_on_unseen_worlds_and_the_verdict_weighs_safety(
        table):
    worlds, systems, t = table
    s = summarize(t)
    v = verdict(s, "test", 0.1, table=t)
    by = s.set_index("system")
    # success: more than its start and than apf, on 40 generated and 16 trap worlds
    assert by.loc["tuned", "reached"] > by.loc["start", "reached"] > by.loc["apf", "reached"]
    trap = t[t.scenario.str.startswith("trap")]
    ok = trap[trap.outcome == "reached"].groupby("system").size()
    assert ok["tuned"] >= ok["start"] and ok["tuned"] > ok["apf"]
    # safety: no collision, and the filter keeps half the robot radius (to a micrometre)
    assert by.loc["tuned", "collided"] == 0 == by.loc["tuned", "out_of_bounds"]
    assert t[t.system == "tuned"].min_clearance.min() >= MARGIN - 1e-6
    # but it passes closer to obstacles than apf: the verdict must not call it ready
    assert by.loc["tuned", "common_min_clearance"] < by.loc["apf", "common_min_clearance"]
    assert not v["better"] and not v["safe"]
    assert "less safe than apf (clearance)" in v["headline"]


def test_the_safety_filter_is_part_of_the_tuned_controller(table):
    """Tuned with the filter on, the system relies on it: without it, it collides (so every
    deployment must run it: the exports and the report say so)."""
    worlds, systems, _ = table
    bare = run_systems({"tuned": systems["tuned"]}, worlds, apf=False)
    assert (bare.outcome == "collided").sum() > 0
    assert "safety_margin = 0.05" in systems["tuned"].description


def test_tuned_system_covers_its_input_space():
    from hybridnav.fuzzy.family import SystemFamily

    tuned = fuzzy.builtin("effc-tuned")
    fam = SystemFamily(tuned)
    assert fam.uncovered(fam.tables_of([tuned]), 101)[0] == 0.0      # never the default
    start = fuzzy.builtin("effc-5rule")
    fam = SystemFamily(start)
    assert fam.uncovered(fam.tables_of([start]), 101)[0] > 0.1


@pytest.mark.long
def test_the_main_job_reproduces_the_shipped_system(tmp_path):
    """``hybridnav tune --workers 2`` on the built-in defaults returns ``effc-tuned`` exactly."""
    out = tmp_path / "tuned"
    done = subprocess.run([sys.executable, "-m", "hybridnav.cli", "tune", "--workers", "2",
                           "--out", str(out)], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    got = json.loads((out / "fis.json").read_text())
    ref = fuzzy.builtin("effc-tuned").to_dict()
    assert got["rules"] == ref["rules"]
    for a, b in zip(got["inputs"] + [got["output"]], ref["inputs"] + [ref["output"]]):
        for ta, tb in zip(a["terms"], b["terms"]):
            assert np.array_equal(ta["params"], tb["params"])
    assert "test: on the test set (40 worlds) tuned reaches" in done.stdout
