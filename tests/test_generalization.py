"""The main job's tuned controller on worlds it never saw.

``effc-tuned`` is the system the README's main job (``hybridnav tune --workers 2 --out tuned``,
built-in defaults, seed 0) returns: trained on generated worlds of seed 1, chosen on seed 2,
reported on seed 3. Here it is judged on 40 worlds of seed 2027 — disjoint from all three — against
the system it started from (``effc-5rule``) and plain ``apf``, with the issue's acceptance
conditions. The rows come from the lockstep simulation; a sample is replayed with the planners.
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
from hybridnav.worldgen import WorldGenerator

FRESH_SEED = 2027


def test_fresh_seed_is_disjoint_from_the_jobs_sets():
    job = load_job(None)
    seeds = {item["seed"] for k in ("train", "validation", "test")
             for item in job["scenarios"][k] if isinstance(item, dict)}
    assert FRESH_SEED not in seeds
    fresh = {tuple(w.robots[0].start) for w in WorldGenerator().generate(40, FRESH_SEED)}
    used = {tuple(s.robots[0].start) for k in ("train", "validation", "test")
            for s in job.scenarios(k)}
    assert not fresh & used


@pytest.fixture(scope="module")
def table():
    worlds = WorldGenerator().generate(40, FRESH_SEED)
    systems = {"start": fuzzy.builtin("effc-5rule"), "tuned": fuzzy.builtin("effc-tuned")}
    return worlds, systems, run_systems(systems, worlds)


def test_rows_are_what_the_planners_do(table):
    worlds, systems, t = table
    for w in worlds[::8]:
        for label, system in systems.items():
            r = planners.get("effc", fis=system).run(w).robots[0]
            row = t[(t.scenario == w.name) & (t.system == label)].iloc[0]
            assert row.outcome == r.outcome
            assert row.path_length == pytest.approx(r.path_length, rel=1e-12)
            assert row.min_clearance == pytest.approx(r.min_clearance, rel=1e-12)


def test_tuned_reaches_more_than_start_and_apf_on_unseen_worlds_and_the_verdict_weighs_safety(
        table):
    _, _, t = table
    s = summarize(t)
    v = verdict(s, "test", 0.1, table=t)
    by = s.set_index("system")
    # success: more than its start and than apf; collisions: none (its start 2, apf 0)
    assert by.loc["tuned", "reached"] > by.loc["start", "reached"]
    assert by.loc["tuned", "reached"] > by.loc["apf", "reached"]
    assert by.loc["tuned", "collided"] == 0 == by.loc["apf", "collided"]
    assert by.loc["start", "collided"] > 0
    # but it passes closer to obstacles than apf: the verdict must not call it ready
    assert by.loc["tuned", "common_min_clearance"] < by.loc["apf", "common_min_clearance"]
    assert not v["better"] and not v["safe"]
    assert "less safe than apf (clearance)" in v["headline"]
    # and it does not get there by hugging obstacles: clearance on every reached world >= r / 2
    assert by.loc["tuned", "min_clearance_reached"] >= 0.05
    assert by.loc["tuned", "common_length"] < by.loc["start", "common_length"]


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
    assert "test: tuned is better than its start" in done.stdout
