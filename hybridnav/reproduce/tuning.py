"""``hybridnav reproduce effc-ga``: the EFFC paper's own GA run, judged on worlds it never saw.

The paper tunes its fuzzy force weight with a GA (population 100, 25 generations) on two
training environments (``effc-train-1``, ``effc-train-2``: the robot from the origin at heading
pi/4 to (3, 3) past one circle) at 0.1 m/s, with its eq. 11 reward: the travelled distance
when the robot reaches the target safely, -100 otherwise, summed over the environments and
*maximized*. It then claims that this learning "enhances generalization" (Sec. 3.2). This
target runs that GA (:data:`EXPERIMENTS`), in two profiles:

* ``paper``: eq. 11 as printed (maximized: longer successful paths score higher);
* ``intended``: what the text says the reward is for ("we aim to minimize path length"): the
  distance on success, 100 on failure, minimized.

Neither has a validation set or a safety filter (the paper has none): the returned system is
the GA's best on the two training environments. Each profile is run with ``runs`` GA seeds
(the paper ran one). Every tuned system, its start (``effc-5rule``), our ``deploy`` job's
system (built-in ``effc-tuned``, tuned on 40 generated worlds with a validation set and
deployed with its safety filter, ``safety_margin = 0.05``) and plain ``apf`` are then
simulated on the training environments, the paper's comparison environments and a set of
generated worlds no tuning run used (:data:`HELDOUT`), and judged as ``hybridnav tune``
judges its own result (:func:`hybridnav.tuner.heldout.verdict`: collisions and clearance
first, then success). The paper's generalization claim holds for a GA run only if its system
reaches significantly more held-out worlds than its start (exact McNemar test of the paired
outcomes, p < :data:`hybridnav.reproduce.report.ALPHA`) without colliding more.
"""

from __future__ import annotations

import copy
import json
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError

__all__ = ["EXPERIMENTS", "HELDOUT", "Experiment", "heldout_verdicts", "load_experiment",
           "mcnemar", "render_experiment", "run_experiment", "write_experiment_report"]

#: the generated worlds no tuning run used (the deploy job draws its sets from seeds 1-13;
#: ``seed`` of a reproduction adds ``1000 * seed`` to these)
HELDOUT = ({"generate": 40, "seed": 101},
           {"generate": 10, "seed": 111, "cups": [0, 1], "corridors": [0, 1], "gaps": [0, 1],
            "walls": [0, 1], "circles": [0, 3], "name": "trap"})


@dataclass(frozen=True)
class Experiment:
    """A reproduction that tunes before it compares (``hybridnav reproduce NAME``)."""

    name: str
    paper: str
    source: str
    runs: int
    #: profile -> the tuning job's settings (over hybridnav's built-in job)
    profiles: dict[str, dict[str, Any]]
    #: the systems judged beside the tuned ones: label -> (fuzzy system, safety margin)
    beside: dict[str, tuple[str, float]]
    #: world sets: label -> job scenario-set items
    sets: dict[str, list[Any]]
    claims: tuple[str, ...]
    notes: str = ""
    settings: dict[str, Any] = field(default_factory=dict)


_PAPER_JOB = {"system": {"start": "effc-5rule"},
              "scenarios": {"train": ["effc-train-1", "effc-train-2"], "validation": [],
                            "test": []},
              "ga": {"population": 100, "generations": 25},
              "planner": {"speed": 0.1, "safety_margin": 0.0},
              "robust": {"rounds": 0}, "falsify": {"budget": 0},
              "validation": {"patience": 0}}

EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment(
        name="effc-ga",
        paper="Golkhatib, Shahmansoorian & Davoudi, IJEEE 2025 (EFFC)",
        source="Sec. 3.2 (eq. 11, Algorithm 1) and Sec. 4 (GA: population 100, 25 "
               "generations, two training environments, 0.1 m/s)",
        runs=3,
        profiles={"paper": {**_PAPER_JOB, "reward": {"kind": "paper"}},
                  "intended": {**_PAPER_JOB, "reward": {"kind": "length", "penalty": 100.0}}},
        beside={"start": ("effc-5rule", 0.0), "deploy": ("effc-tuned", 0.05)},
        sets={"training": ["effc-train-1", "effc-train-2"],
              "comparison": ["effc-env-a", "effc-env-b"],
              "held-out": list(HELDOUT)},
        claims=("The GA-tuned EFFC reaches the target in both training environments "
                "(Fig. 14)",
                "The GA's learning gives the fuzzy system enhanced generalization (Sec. 3.2): "
                "on worlds it never saw it reaches more than its start without colliding more"),
        notes=("The training environments are reconstructions of Fig. 14 (the paper gives the "
               "start, heading and target; the circle positions are ours). The paper's GA "
               "ran once; here each profile runs with several seeds. The paper does not say "
               "what '10 simulation iterations' per task means; each candidate is simulated "
               "once per environment (the simulation is deterministic)."),
    ),
)}


def mcnemar(a: list[bool], b: list[bool]) -> tuple[int, int, float]:
    """Exact McNemar test of paired outcomes: ``(a only, b only, two-sided p)``.

    Parameters
    ----------
    a, b : list of bool
        Whether each system reached each world (same worlds, same order).

    Returns
    -------
    (int, int, float)
        Worlds only ``a`` reached, worlds only ``b`` reached, and the two-sided binomial
        p-value of the discordant pairs (1.0 when there are none).
    """
    if len(a) != len(b):
        raise ValueError("mcnemar: expected paired outcomes of the same length")
    only_a = sum(1 for x, y in zip(a, b) if x and not y)
    only_b = sum(1 for x, y in zip(a, b) if y and not x)
    return only_a, only_b, _mcnemar_p(only_a, only_b)


def _job(experiment: Experiment, profile: str, seed: int, workers: int, dask):
    from hybridnav.tuner.job import validate_job

    raw = copy.deepcopy(experiment.profiles[profile])
    raw.update(name=f"{experiment.name}-{profile}", seed=int(seed))
    job = validate_job(raw, f"{experiment.name} ({profile} profile)", Path.cwd())
    return job.with_backend(workers=workers, dask=dask if isinstance(dask, str) else None)


def _worlds(experiment: Experiment, seed: int) -> dict[str, list]:
    """The judged world sets, loaded (generated sets shifted by ``1000 * seed``)."""
    from hybridnav.tuner.job import validate_job

    out = {}
    for label, items in experiment.sets.items():
        items = [dict(it, seed=it["seed"] + 1000 * seed) if isinstance(it, dict) else it
                 for it in items]
        job = validate_job({"scenarios": {"test": items}}, f"{experiment.name}: {label}",
                           Path.cwd())
        out[label] = job.scenarios("test")
    return out


def run_experiment(name: str, out: str | Path, *, runs: int | None = None, seed: int = 0,
                   workers: int = 1, dask: Any = None,
                   progress: Callable[[int, int], None] | None = None,
                   phase: Callable[[str], None] | None = None, fmt: str = "png",
                   dpi: int = 120) -> dict[str, Any]:
    """Tune in every profile with ``runs`` seeds, judge every system, write ``report.md``.

    Parameters
    ----------
    name : str
        A key of :data:`EXPERIMENTS`.
    out : str or Path
        The output folder: ``tuning/<profile>-seed<k>/`` (each GA run's own outputs, as
        ``hybridnav tune`` writes them), ``heldout.csv`` (every system on every world),
        ``heldout_summary.csv``, ``verdicts.csv``, ``experiment.json``, ``report.md``.
    runs : int, optional
        GA seeds per profile (default :attr:`Experiment.runs`); run ``k`` uses ``seed + k``.
    seed, workers, dask, progress
        As for :func:`hybridnav.reproduce.reproduce` (``progress(done, total)`` per GA run).
    phase : callable, optional
        ``phase(message)`` as each phase after the GA runs starts (judging every system on
        each world set, the report).
    fmt, dpi
        The GA runs' figures: format (``png``, ``pdf``, ``svg``) and dots per inch.

    Returns
    -------
    dict
        ``claims`` (text and verdict per view) and ``files``.
    """
    import pandas as pd

    from hybridnav import __version__
    from hybridnav.fileio import atomic_write_text
    from hybridnav.fuzzy import load_any
    from hybridnav.backends import load_average
    from hybridnav.tuner.heldout import run_systems, summarize
    from hybridnav.tuner.run import run_job

    experiment = EXPERIMENTS[name]
    from hybridnav.reproduce.checks import check_count

    n = experiment.runs if runs is None else check_count("--runs", runs, 1)
    out = Path(out)
    tic = time.perf_counter()
    worlds = _worlds(experiment, seed)       # fail on a bad set before any tuning
    tuned: dict[str, Any] = {}
    total, done = len(experiment.profiles) * int(n), 0
    for profile in experiment.profiles:
        for k in range(int(n)):
            job = _job(experiment, profile, seed + k, workers, dask)
            folder = out / "tuning" / f"{profile}-seed{seed + k}"
            run_job(job, folder, force=True, fmt=fmt, dpi=dpi)
            tuned[f"{profile}/seed{seed + k}"] = load_any(str(folder / "fis.json"))
            done += 1
            if progress is not None:
                progress(done, total)
    systems = {label: load_any(fis) for label, (fis, margin) in experiment.beside.items()
               if margin == 0.0}
    systems.update(tuned)
    filtered = {label: (load_any(fis), margin) for label, (fis, margin)
                in experiment.beside.items() if margin != 0.0}
    speed = experiment.profiles[next(iter(experiment.profiles))]["planner"]["speed"]
    say = phase or (lambda msg: None)
    parts = []
    for label, scen in worlds.items():
        say(f"every system on the {label} worlds ({len(scen)})")
        parts.append(run_systems(systems, scen, speed=speed, set_name=label))
        for flabel, (system, margin) in filtered.items():
            parts.append(run_systems({flabel: system}, scen, speed=speed, set_name=label,
                                     apf=False, safety_margin=margin))
    say("verdicts and report")
    table = pd.concat(parts, ignore_index=True)
    summary = summarize(table)
    radius = worlds["held-out"][0].robots[0].radius
    verdicts = heldout_verdicts(experiment, table, summary, list(tuned), radius)
    elapsed = time.perf_counter() - tic
    meta = {"experiment": name, "paper": experiment.paper, "version": __version__,
            "runs": int(n), "paper_runs": 1, "seed": seed, "profiles": list(experiment.profiles),
            "workers": workers if dask is None else f"dask {dask}",
            "elapsed_s": round(elapsed, 1), "load": load_average(),
            "sets": {k: len(v) for k, v in worlds.items()}}
    atomic_write_text(out / "heldout.csv", table.to_csv(index=False))
    atomic_write_text(out / "heldout_summary.csv", summary.to_csv(index=False))
    atomic_write_text(out / "verdicts.csv", verdicts.to_csv(index=False))
    atomic_write_text(out / "experiment.json", json.dumps(meta, indent=1))
    claims = experiment_claims(experiment, verdicts)
    write_experiment_report(out / "report.md", experiment, summary, verdicts, claims, meta)
    return {"claims": claims, "files": ["report.md", "experiment.json", "heldout.csv",
                                        "heldout_summary.csv", "verdicts.csv", "tuning/"]}


def heldout_verdicts(experiment: Experiment, table, summary, tuned: list[str],
                     radius: float):
    """Per tuned system: the training claim, the generalization test against its start, and
    ``hybridnav tune``'s safety-first verdict against its start and ``apf`` on the held-out
    set (a DataFrame, one row per tuned system)."""
    import pandas as pd

    from hybridnav.tuner.heldout import verdict

    rows = []
    for label in tuned:
        train = table[(table["set"] == "training") & (table["system"] == label)]
        held = table[table["set"] == "held-out"].pivot_table(
            index="scenario", columns="system", values="outcome", aggfunc="first")
        a = (held[label] == "reached").tolist()
        b = (held["start"] == "reached").tolist()
        only_a, only_b, p = mcnemar(a, b)
        crash = {s: int(held[s].isin(["collided", "out_of_bounds"]).sum())
                 for s in (label, "start")}
        sub = summary[summary["system"].isin([label, "start", "apf"])].replace(
            {"system": {label: "tuned"}})
        judged = verdict(sub, "held-out", radius, table=table[table["system"].isin(
            [label, "start", "apf"])].replace({"system": {label: "tuned"}}))
        rows.append({"system": label, "profile": label.split("/")[0],
                     "training_reached": int((train["outcome"] == "reached").sum()),
                     "training_worlds": len(train),
                     "heldout_reached": int(sum(a)), "start_reached": int(sum(b)),
                     "worlds": len(a), "only_tuned": only_a, "only_start": only_b,
                     "p_vs_start": p, "collisions": crash[label],
                     "start_collisions": crash["start"], "ready": bool(judged["better"]),
                     "headline": judged["headline"]})
    return pd.DataFrame(rows)


def _generalizes(r) -> bool | None:
    from hybridnav.reproduce.report import ALPHA

    if r["collisions"] > r["start_collisions"]:
        return False
    if r["p_vs_start"] >= ALPHA:
        return None
    return bool(r["only_tuned"] > r["only_start"])


def experiment_claims(experiment: Experiment, verdicts) -> list[dict[str, Any]]:
    """Each claim's verdict per profile (``<profile> profile``: holds when it holds for every GA
    run, does not hold when it fails for every GA run, else not shown; ``<profile> profile
    detail``: the per-run figures); ``paper``: True (the paper states it)."""
    out = []
    checks = (lambda r: r["training_reached"] == r["training_worlds"], _generalizes)
    for text, check in zip(experiment.claims, checks):
        item: dict[str, Any] = {"text": text, "paper": True}
        for profile in experiment.profiles:
            rs = verdicts[verdicts["profile"] == profile]
            v = [check(r) for _, r in rs.iterrows()]
            item[f"{profile} profile"] = (True if v and all(x is True for x in v) else
                                          False if v and all(x is False for x in v) else None)
            item[f"{profile} profile detail"] = "; ".join(
                f"{r['system'].split('/')[1]}: " + (
                    f"reached {r['training_reached']}/{r['training_worlds']}"
                    if check is checks[0] else
                    f"{r['heldout_reached']} vs start {r['start_reached']} of {r['worlds']} "
                    f"(only tuned {r['only_tuned']}, only start {r['only_start']}, "
                    f"p = {r['p_vs_start']:.2g}; collided or left the workspace "
                    f"{r['collisions']} vs {r['start_collisions']})")
                for _, r in rs.iterrows())
        out.append(item)
    return out


def _word(v) -> str:
    return {True: "holds", False: "does not hold", None: "not shown"}[v]


def experiment_sections(experiment: Experiment, summary, verdicts, claims, meta,
                        level: int = 2) -> list[str]:
    """The results as markdown lines: safety and success per set and system, the verdict per
    GA run, the claims (``level``: of the headings)."""
    h = "#" * level
    lines = [f"{h} Every system on every set", "",
             "Collisions (and leaving the workspace) first, then the smallest clearance on the "
             "worlds the system reached, then success with its 95 % Wilson interval, then the "
             "mean length on the worlds every system of the set reached. `start` is "
             "`effc-5rule`, `deploy` our deploy job's `effc-tuned` (with its safety filter), "
             "`<profile>/seed<k>` the GA runs.", "",
             "| set | system | collided or left the workspace | smallest clearance (m) | "
             "reached | mean length on common worlds (m) |", "|---|---|---|---|---|---|"]
    for _, r in summary.iterrows():
        clear = r["min_clearance_reached"]
        length = r["common_length"]
        lines.append(
            f"| {r['set']} | `{r['system']}` | {int(r['collided']) + int(r['out_of_bounds'])} "
            f"| {'-' if clear != clear else f'{clear:.3f}'} | {int(r['reached'])}/"
            f"{int(r['worlds'])} ({100 * r['ci_low']:.0f}-{100 * r['ci_high']:.0f} %) | "
            f"{'-' if length != length else f'{length:.2f}'} |")
    lines += ["", f"{h} Each GA run on the held-out worlds", "",
              "Against its start: worlds only it reached / only the start reached, exact "
              "McNemar p; and `hybridnav tune`'s verdict against its start and `apf` "
              "(safety first).", "",
              "| GA run | training reached | held-out reached (start) | only tuned / only "
              "start, p | collided or left the workspace (start) | ready to deploy |", "|---|---|---|---|---|---|"]
    for _, r in verdicts.iterrows():
        lines.append(f"| `{r['system']}` | {r['training_reached']}/{r['training_worlds']} | "
                     f"{r['heldout_reached']}/{r['worlds']} ({r['start_reached']}) | "
                     f"{r['only_tuned']} / {r['only_start']}, p = {r['p_vs_start']:.2g} | "
                     f"{r['collisions']} ({r['start_collisions']}) | "
                     f"{'yes' if r['ready'] else 'no'}: {r['headline']} |")
    profiles = list(experiment.profiles)
    lines += ["", f"{h} The paper's claims", "",
              "A claim holds for a profile when it holds for every GA run of it, does not hold "
              "when it fails for every run, else it is not shown. Generalization needs "
              "p < 0.05 in the tuned system's favour and no more collisions than its start.",
              "", "| claim | in the paper | " + " | ".join(
                  f"ours, `{p}` profile" for p in profiles) + " |",
              "|---|---|" + "---|" * len(profiles)]
    for c in claims:
        lines.append(f"| {c['text']} | stated | " + " | ".join(
            f"{_word(c[f'{p} profile'])} ({c[f'{p} profile detail']})" for p in profiles)
                     + " |")
    return lines + [""]


def write_experiment_report(path: Path, experiment: Experiment, summary, verdicts, claims,
                            meta) -> None:
    """Write ``report.md`` of an experiment."""
    from hybridnav.fileio import atomic_write_text

    lines = [f"# `{experiment.name}`: {experiment.paper}", "",
             f"Reproduces {experiment.source}. hybridnav {meta['version']}; {meta['runs']} GA "
             f"run(s) per profile (the paper: 1), seed {meta['seed']}; world sets: "
             + ", ".join(f"{k} {v}" for k, v in meta["sets"].items()) + ".", "",
             "Profiles: `paper` maximizes eq. 11 as printed (the distance travelled on "
             "success, -100 on failure: longer successful paths score higher); `intended` "
             "minimizes the distance with 100 per failure, what the text says the reward is "
             "for. Both: population 100, 25 generations, the two training environments only, "
             "no validation set, no safety filter, 0.1 m/s.", "", experiment.notes, ""]
    lines += experiment_sections(experiment, summary, verdicts, claims, meta)
    lines += ["Each GA run's own outputs (tuned system, convergence, its report) are in "
              "`tuning/<profile>-seed<k>/`.", ""]
    atomic_write_text(path, "\n".join(lines))


#: what ``render_experiment`` reads of a stored run's ``experiment.json``
_META = {"version": ("", "package version"), "runs": (1, "GA runs per profile"),
         "seed": (0, "base seed"), "elapsed_s": (0.0, "wall time (s)")}
#: the columns of a stored ``heldout_summary.csv`` the report reads (the rest may be absent)
_SUMMARY_TEXT = ("set", "system")
_SUMMARY_COUNTS = ("worlds", "reached", "collided", "out_of_bounds")
_SUMMARY_REALS = ("ci_low", "ci_high", "min_clearance_reached", "common_length")
#: text a stored table may put into a README table cell: one line, no cell bar, no markup
_PLAIN = re.compile(r"[^|<>`\n\r]*")
#: the columns of a stored ``verdicts.csv``
_VERDICT_COUNTS = ("training_reached", "training_worlds", "heldout_reached", "start_reached",
                   "worlds", "only_tuned", "only_start", "collisions", "start_collisions")


def _csv(path: Path, what: str):
    """A stored CSV table as text cells (a named error where it is not one)."""
    from hybridnav.reproduce.checks import read_stored_csv

    table = read_stored_csv(path, what, f"the {what} of `hybridnav reproduce`",
                            text_cells=True)
    if table.empty:
        raise HybridnavError(f"{path}: expected a row per system, got only the header")
    return table


def _columns(path: Path, table, text=(), counts=(), reals=(), *, required=()) -> None:
    """Check and convert ``table``'s columns in place: names (non-empty text), counts
    (integers >= 0), reals (numbers, empty: NaN)."""
    import math

    from hybridnav.params import short_repr

    for col in (*text, *counts, *reals, *required):
        if col not in table.columns:
            raise HybridnavError(f"{path}: {col}: missing column")

    def bad(col, what, i):
        raise HybridnavError(f"{path}: {col}: expected {what}, got "
                             f"{short_repr(table[col].iloc[i])} in row {i + 2}")

    for col in text:
        for i, v in enumerate(table[col]):
            if not v.strip():
                bad(col, "a name", i)
    for col in counts:
        out = []
        for i, v in enumerate(table[col]):
            try:
                x = float(v)
            except ValueError:
                bad(col, "a count", i)
            if not (math.isfinite(x) and x >= 0 and x == int(x)):
                bad(col, "a count", i)
            out.append(int(x))
        table[col] = out
    for col in reals:
        out = []
        for i, v in enumerate(table[col]):
            try:
                out.append(float(v) if v.strip() else math.nan)
            except ValueError:
                bad(col, "a number (or empty)", i)
        table[col] = out


def load_experiment(folder: str | Path):
    """``(experiment, summary, verdicts, meta)`` of a stored experiment, checked: its
    ``experiment.json``, ``heldout_summary.csv`` and ``verdicts.csv`` as
    :func:`run_experiment` writes them.

    Raises
    ------
    HybridnavError
        A missing or unreadable file, a bad key or column, a count that is not one, a GA run
        of a profile the experiment does not have, or a p-value that is not the exact McNemar
        test of the run's own counts (naming the file, key or column and row).
    """
    import math

    from hybridnav.params import Param, short_repr
    from hybridnav.reproduce.checks import check_shown, read_stored_json

    folder = Path(folder)
    path = folder / "experiment.json"
    meta = read_stored_json(path, "the experiment.json of `hybridnav reproduce`")
    name = meta.get("experiment")
    if not isinstance(name, str) or name not in EXPERIMENTS:
        raise HybridnavError(f"{path}: experiment: expected one of {', '.join(EXPERIMENTS)}, "
                             f"got {short_repr(name)}")
    experiment = EXPERIMENTS[name]
    for key, (default, doc) in _META.items():
        if key == "elapsed_s" and key not in meta:
            continue                            # optional: the timing is then left out
        lo = 1 if key == "runs" else 0 if key != "version" else None
        extra = {"pattern": r"[\w.+-]{1,64}", "expected": "a version number"} \
            if key == "version" else {}
        meta[key] = Param(default, doc, lo=lo, **extra).check(key, meta.get(key), f"{path}: ")
    sets = meta.get("sets")
    if not isinstance(sets, dict) or not sets or not all(
            isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) and v >= 0
            for k, v in sets.items()):
        raise HybridnavError(f"{path}: sets: expected a table of world counts by set, got "
                             f"{short_repr(sets)}")
    check_shown(path, meta)

    spath = folder / "heldout_summary.csv"
    summary = _csv(spath, "held-out summary")
    _columns(spath, summary, _SUMMARY_TEXT, _SUMMARY_COUNTS, _SUMMARY_REALS)
    systems = re.compile("|".join([*map(re.escape, experiment.beside), "apf",
                                   *(rf"{re.escape(p)}/seed\d+" for p in experiment.profiles)]))
    for col, ok, what in (("set", lambda v: v in experiment.sets,
                           f"one of the sets {', '.join(experiment.sets)}"),
                          ("system", lambda v: systems.fullmatch(v) is not None,
                           "start, deploy, apf or <profile>/seed<k>")):
        for i, v in enumerate(summary[col]):
            if not ok(v):
                raise HybridnavError(f"{spath}: {col}: expected {what}, got {short_repr(v)} in "
                                     f"row {i + 2}")
    for i, (k, n) in enumerate(zip(summary["reached"], summary["worlds"])):
        if k > n:
            raise HybridnavError(f"{spath}: reached: expected at most worlds ({n}), got {k} in "
                                 f"row {i + 2}")

    vpath = folder / "verdicts.csv"
    verdicts = _csv(vpath, "GA runs' verdicts")
    _columns(vpath, verdicts, ("system", "profile"), _VERDICT_COUNTS, ("p_vs_start",),
             required=("ready", "headline"))
    for i, r in verdicts.iterrows():
        row = f"in row {i + 2}"
        system = r["system"].split("/")
        if len(system) != 2 or system[0] != r["profile"] or not system[1].startswith("seed"):
            raise HybridnavError(f"{vpath}: system: expected <profile>/seed<k> of the row's "
                                 f"profile, got {short_repr(r['system'])} {row}")
        if r["profile"] not in experiment.profiles:
            raise HybridnavError(f"{vpath}: profile: expected one of "
                                 f"{', '.join(experiment.profiles)}, got "
                                 f"{short_repr(r['profile'])} {row}")
        for k, n in (("training_reached", "training_worlds"), ("heldout_reached", "worlds"),
                     ("start_reached", "worlds")):
            if r[k] > r[n]:
                raise HybridnavError(f"{vpath}: {k}: expected at most {n} ({r[n]}), got "
                                     f"{r[k]} {row}")
        if r["only_tuned"] + r["only_start"] > r["worlds"] or \
                r["heldout_reached"] - r["start_reached"] != r["only_tuned"] - r["only_start"]:
            raise HybridnavError(f"{vpath}: only_tuned: expected the worlds only the tuned "
                                 f"system reached (with only_start, the paired counts of "
                                 f"heldout_reached and start_reached), got {r['only_tuned']} "
                                 f"and {r['only_start']} {row}")
        p = _mcnemar_p(r["only_tuned"], r["only_start"])
        if not math.isclose(r["p_vs_start"], p, rel_tol=1e-6, abs_tol=1e-12):
            raise HybridnavError(f"{vpath}: p_vs_start: expected the exact McNemar p of "
                                 f"only_tuned and only_start ({p:.6g}), got "
                                 f"{short_repr(r['p_vs_start'])} {row}")
        if not _PLAIN.fullmatch(r["headline"]):     # shown in a table row of README
            raise HybridnavError(f"{vpath}: headline: expected one line of text without '|' "
                                 f"or markup, got {short_repr(r['headline'])} {row}")
        if r["ready"] not in ("True", "False"):
            raise HybridnavError(f"{vpath}: ready: expected True or False, got "
                                 f"{short_repr(r['ready'])} {row}")
    verdicts["ready"] = verdicts["ready"] == "True"
    return experiment, summary, verdicts, meta


def _mcnemar_p(only_a: int, only_b: int) -> float:
    """The two-sided exact McNemar p of the discordant counts (1.0 with none)."""
    from scipy import stats

    n = only_a + only_b
    return 1.0 if n == 0 else float(stats.binomtest(only_a, n, 0.5).pvalue)


def render_experiment(folder: str | Path) -> str:
    """The README block of a stored experiment (from its CSV files and ``experiment.json``,
    checked by :func:`load_experiment`)."""
    from hybridnav.reproduce.protocols import STORE

    experiment, summary, verdicts, meta = load_experiment(folder)
    name = experiment.name
    claims = experiment_claims(experiment, verdicts)
    timing = (f", {meta['elapsed_s'] / 60:.1f} min with {meta.get('workers', 1)} worker(s) "
              f"(load {meta.get('load', '?')})" if "elapsed_s" in meta else "")
    how = (f"Measured by `hybridnav reproduce {name}` with hybridnav {meta['version']}: "
           f"{meta['runs']} GA run(s) per profile (the paper: 1), seed {meta['seed']}"
           f"{timing}. The whole report: [`{STORE.as_posix()}/{name}/"
           f"report.md`]({STORE.as_posix()}/{name}/report.md).")
    return "\n".join([how, ""] + experiment_sections(experiment, summary, verdicts, claims,
                                                      meta, level=4))


def rewrite_experiment_report(folder: str | Path) -> Path:
    """Write a stored experiment's ``report.md`` again from its stored tables (checked by
    :func:`load_experiment`)."""
    folder = Path(folder)
    experiment, summary, verdicts, meta = load_experiment(folder)
    write_experiment_report(folder / "report.md", experiment, summary, verdicts,
                            experiment_claims(experiment, verdicts), meta)
    return folder / "report.md"
