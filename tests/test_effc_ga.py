"""``hybridnav reproduce effc-ga``: the EFFC paper's GA run judged on worlds it never saw."""

import dataclasses
import json
import math
import re

import pandas as pd
import pytest
from scipy import stats

from hybridnav.cli import main
from hybridnav.errors import HybridnavError
from hybridnav.reproduce import reproduce, tuning
from hybridnav.reproduce.tuning import EXPERIMENTS, experiment_claims, mcnemar


def test_mcnemar_is_the_exact_binomial_test_of_the_discordant_pairs():
    a = [True] * 10 + [False] * 6 + [True] * 2
    b = [True] * 10 + [True] * 6 + [False] * 2
    only_a, only_b, p = mcnemar(a, b)
    assert (only_a, only_b) == (2, 6)
    assert p == pytest.approx(stats.binomtest(2, 8, 0.5).pvalue)
    assert mcnemar(b, a)[2] == pytest.approx(p)              # symmetric
    assert mcnemar([False] * 6, [True] * 6)[2] == pytest.approx(2 * 0.5 ** 6)
    assert mcnemar([True, False], [True, False]) == (0, 0, 1.0)   # no discordant pair
    with pytest.raises(ValueError, match="same length"):
        mcnemar([True], [True, False])


def _verdicts(rows):
    cols = ["system", "profile", "training_reached", "training_worlds", "heldout_reached",
            "start_reached", "worlds", "only_tuned", "only_start", "p_vs_start", "collisions",
            "start_collisions", "ready", "headline"]
    return pd.DataFrame([dict(zip(cols, r)) for r in rows])


def test_claims_hold_only_when_every_ga_run_shows_them():
    e = EXPERIMENTS["effc-ga"]
    v = _verdicts([
        # paper profile: both runs reach training, one generalizes significantly, one is
        # significantly worse -> training holds, generalization not shown
        ("paper/seed0", "paper", 2, 2, 40, 30, 50, 12, 2, 0.01, 1, 1, False, ""),
        ("paper/seed1", "paper", 2, 2, 20, 30, 50, 1, 11, 0.006, 1, 1, False, ""),
        # intended: one run misses a training world; both generalize but one collides more
        ("intended/seed0", "intended", 1, 2, 45, 30, 50, 16, 1, 0.0001, 0, 1, True, ""),
        ("intended/seed1", "intended", 2, 2, 45, 30, 50, 16, 1, 0.0001, 3, 1, False, ""),
    ])
    train, general = experiment_claims(e, v)
    assert train["paper"] is True
    assert train["paper profile"] is True and train["intended profile"] is None
    assert general["paper profile"] is None
    assert general["intended profile"] is None
    assert "seed1: 20 vs start 30 of 50 (only tuned 1, only start 11, p = 0.006" in \
        general["paper profile detail"]
    # every run worse (or colliding more): does not hold; every run better: holds
    worse = v.assign(only_tuned=1, only_start=11, p_vs_start=0.006)
    assert experiment_claims(e, worse)[1]["paper profile"] is False
    better = v.assign(only_tuned=12, only_start=1, p_vs_start=0.003, collisions=0)
    assert experiment_claims(e, better)[1]["intended profile"] is True
    not_sig = better.assign(p_vs_start=0.2)
    assert experiment_claims(e, not_sig)[1]["paper profile"] is None


def test_the_profiles_are_the_papers_ga_and_the_reward_as_its_text_means_it():
    e = EXPERIMENTS["effc-ga"]
    for profile, kind in (("paper", "paper"), ("intended", "length")):
        job = tuning._job(e, profile, 0, 1, None)
        assert job["ga"]["population"] == 100 and job["ga"]["generations"] == 25
        assert job["reward"]["kind"] == kind and job["reward"]["penalty"] == 100.0
        assert job["scenarios"]["train"] == ["effc-train-1", "effc-train-2"]
        assert job["scenarios"]["validation"] == [] and job["planner"]["speed"] == 0.1
        assert job["planner"]["safety_margin"] == 0.0
    assert tuning._job(e, "paper", 0, 1, None)["reward"]["sense"] == "maximize"
    # the held-out worlds are none of the deploy job's (its sets use seeds 1-13)
    from hybridnav.tuner.job import DEFAULT_JOB
    used = {it["seed"] for sets in DEFAULT_JOB["scenarios"].values() for it in sets
            if isinstance(it, dict)}
    assert not used & {it["seed"] for it in tuning.HELDOUT}


def test_bad_requests_are_refused(tmp_path):
    with pytest.raises(HybridnavError, match="--scenarios: this target tunes"):
        reproduce("effc-ga", tmp_path, scenarios=["effc-env-a"])
    with pytest.raises(HybridnavError, match="--runs: expected a positive integer"):
        reproduce("effc-ga", tmp_path, runs=0)


@pytest.mark.slow
def test_effc_ga_runs_end_to_end_with_one_run(tmp_path, capsys, monkeypatch):
    """The whole target with --runs 1 and a small GA (the full run is stored)."""
    e = EXPERIMENTS["effc-ga"]
    small = {k: {**v, "ga": {"population": 8, "generations": 1}} for k, v in e.profiles.items()}
    monkeypatch.setitem(EXPERIMENTS, "effc-ga", dataclasses.replace(e, profiles=small))
    out = tmp_path / "ga"
    assert main(["reproduce", "effc-ga", "--runs", "1", "--seed", "4", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    for claim in e.claims:
        line = next(ln for ln in printed.splitlines() if ln.startswith(claim))
        assert "profile=paper" in line and "profile=intended" in line
    meta = json.loads((out / "experiment.json").read_text())
    assert meta["sets"] == {"training": 2, "comparison": 2, "held-out": 50}
    table = pd.read_csv(out / "heldout.csv")
    systems = {"start", "deploy", "apf", "paper/seed4", "intended/seed4"}
    assert set(table["system"]) == systems
    # every system on every world of every set, once
    assert (table.groupby(["set", "system"]).size() == table.groupby("set").scenario.nunique()
            .reindex(table.groupby(["set", "system"]).size().index.get_level_values(0))
            .to_numpy()).all()
    verdicts = pd.read_csv(out / "verdicts.csv")
    assert list(verdicts["system"]) == ["paper/seed4", "intended/seed4"]
    held = table[table["set"] == "held-out"]
    for _, r in verdicts.iterrows():        # the counts are the table's
        mine = held[held.system == r["system"]].set_index("scenario").outcome
        start = held[held.system == "start"].set_index("scenario").outcome.loc[mine.index]
        assert r["heldout_reached"] == int((mine == "reached").sum())
        assert r["only_tuned"] == int(((mine == "reached") & (start != "reached")).sum())
        assert math.isfinite(r["p_vs_start"])
    report = (out / "report.md").read_text()
    assert "## Every system on every set" in report and "## The paper's claims" in report
    # safety before convenience in the systems table
    head = next(ln for ln in report.splitlines() if ln.startswith("| set | system"))
    assert head.index("collided") < head.index("reached") < head.index("length")
    for profile in ("paper", "intended"):
        assert (out / "tuning" / f"{profile}-seed4" / "fis.json").exists()
    # what run_experiment writes is what load_experiment accepts (the README block renders)
    assert "#### The paper's claims" in tuning.render_experiment(out)


def _stored_copy(tmp_path):
    """A copy of the stored effc-ga run (without its GA runs' folders) and a README block."""
    import shutil
    from pathlib import Path

    from hybridnav.reproduce.readme import STORE

    root = Path(__file__).resolve().parents[1]
    store = tmp_path / "store"
    shutil.copytree(root / STORE / "effc-ga", store / "effc-ga",
                    ignore=shutil.ignore_patterns("tuning"))
    readme = tmp_path / "README.md"
    readme.write_text("<!-- reproduce:effc-ga -->\nold\n<!-- /reproduce:effc-ga -->\n")
    return store / "effc-ga", readme


def _json_edit(**changes):
    def edit(text):
        meta = json.loads(text)
        for k, v in changes.items():
            if v is None:
                meta.pop(k, None)
            else:
                meta[k] = v
        return json.dumps(meta)
    return edit


@pytest.mark.parametrize("file, edit, message", [
    ("experiment.json", lambda t: "{not json", "experiment.json: expected the experiment.json"),
    ("experiment.json", lambda t: "[]", "experiment.json: expected a JSON object, got list"),
    ("experiment.json", _json_edit(version=None), "experiment.json: version: expected a version number, got None"),
    ("experiment.json", _json_edit(elapsed_s="x"), "experiment.json: elapsed_s: expected"),
    ("experiment.json", _json_edit(runs=0), "experiment.json: runs: expected"),
    ("experiment.json", _json_edit(sets=5), "experiment.json: sets: expected a table"),
    ("experiment.json", _json_edit(workers=[1]), "experiment.json: workers: expected"),
    ("experiment.json", _json_edit(load="1\n<!-- /reproduce:effc-ga -->"),
     "experiment.json: load: expected a worker count or one line of plain text"),
    ("experiment.json", _json_edit(version="1 <!-- x -->"),
     "experiment.json: version: expected a version number"),
    ("verdicts.csv", lambda t: "", "verdicts.csv: expected the GA runs' verdicts"),
    ("verdicts.csv", lambda t: t.splitlines()[0] + "\n", "verdicts.csv: expected a row per"),
    ("verdicts.csv", lambda t: t.replace("p_vs_start", "pv"), "verdicts.csv: p_vs_start: "
                                                              "missing column"),
    ("verdicts.csv", lambda t: t.replace(",0.076812744140625,", ",abc,"),
     "verdicts.csv: p_vs_start: expected a number"),
    # a p-value that is not its own counts' McNemar p would make a claim hold on its own say
    ("verdicts.csv", lambda t: t.replace(",0.076812744140625,", ",0.001,"),
     r"verdicts.csv: p_vs_start: expected the exact McNemar p"),
    ("verdicts.csv", lambda t: t.replace(",4,12,0.0768", ",40,12,0.0768"),
     "verdicts.csv: only_tuned: expected the worlds only the tuned system reached"),
    ("verdicts.csv", lambda t: t.replace("paper/seed0,paper", "paperseed0,paper"),
     "verdicts.csv: system: expected <profile>/seed<k>"),
    ("verdicts.csv", lambda t: t.replace("paper/seed0,paper", "other/seed0,other"),
     "verdicts.csv: profile: expected one of paper, intended"),
    ("verdicts.csv", lambda t: t.replace(",2,2,28,", ",2,2,2.5,"),
     "verdicts.csv: heldout_reached: expected a count, got '2.5' in row 2"),
    ("verdicts.csv", lambda t: t.replace(",False,", ",maybe,", 1),
     "verdicts.csv: ready: expected True or False"),
    ("heldout_summary.csv", lambda t: t.splitlines()[0] + "\n",
     "heldout_summary.csv: expected a row per system"),
    ("heldout_summary.csv", lambda t: t.replace("ci_low", "x"),
     "heldout_summary.csv: ci_low: missing column"),
    ("heldout_summary.csv", lambda t: t.replace("training,start,2,2,", "training,start,2,x,"),
     "heldout_summary.csv: reached: expected a count, got 'x' in row 2"),
    # text shown in README's tables: no closing marker smuggled into the block
    ("verdicts.csv", lambda t: t.replace("NOT ready", "| <!-- /reproduce:effc-ga -->", 1),
     "verdicts.csv: headline: expected one line of text without '\\|' or markup"),
    ("heldout_summary.csv", lambda t: t.replace("training,start", "training,<!-- x -->", 1),
     "heldout_summary.csv: system: expected start, deploy, apf or <profile>/seed<k>"),
    ("heldout_summary.csv", lambda t: t.replace("training,start", "trainin,start", 1),
     "heldout_summary.csv: set: expected one of the sets training, comparison, held-out"),
])
def test_a_damaged_stored_experiment_is_a_named_error(tmp_path, capsys, file, edit, message):
    folder, readme = _stored_copy(tmp_path)
    path = folder / file
    path.write_text(edit(path.read_text()))
    assert main(["reproduce", "--update-readme", "--reports", str(folder.parent),
                 "--readme", str(readme)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hybridnav: error: ") and "Traceback" not in err
    assert re.search(message, err), err
    assert "old" in readme.read_text()                        # nothing rewritten


def test_the_stored_experiment_renders_and_without_its_timing(tmp_path):
    folder, readme = _stored_copy(tmp_path)
    assert tuning.render_experiment(folder).startswith(
        "Measured by `hybridnav reproduce effc-ga` with hybridnav")
    (folder / "experiment.json").write_text(_json_edit(elapsed_s=None)(
        (folder / "experiment.json").read_text()))
    assert " min with " not in tuning.render_experiment(folder).splitlines()[0]


@pytest.mark.parametrize("name", ["effc-ga", "effc-table3"])
@pytest.mark.parametrize("runs", [math.nan, math.inf, -math.inf, 2.5, True, "3", 0])
def test_hostile_runs_are_named_errors_before_any_work(tmp_path, name, runs):
    """NaN and inf used to escape as ValueError / OverflowError from int()."""
    with pytest.raises(HybridnavError, match="--runs: expected a positive integer"):
        reproduce(name, tmp_path, runs=runs)
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("layouts", [math.nan, math.inf, -1, 101, 1.5, True])
def test_hostile_layout_counts_are_named_errors(tmp_path, layouts):
    with pytest.raises(HybridnavError, match=r"--layouts: expected an integer in \[0, 100\]"):
        reproduce("effc-table3", tmp_path, layouts=layouts)


def test_layouts_with_effc_ga_are_refused_not_ignored(tmp_path, capsys):
    with pytest.raises(HybridnavError, match="effc-ga: --layouts: this target judges"):
        reproduce("effc-ga", tmp_path, layouts=2)
    assert main(["reproduce", "effc-ga", "--layouts", "0", "-o", str(tmp_path)]) == 2
    assert "--layouts: this target judges generated world sets" in capsys.readouterr().err
