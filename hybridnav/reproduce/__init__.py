"""``hybridnav reproduce NAME``: run a paper's protocol in both profiles and report beside it.

:func:`reproduce` runs :data:`PROTOCOLS` ``[name]`` through :func:`hybridnav.experiments.compare`
(every planner with profiles as ``NAME/paper`` with ``profile=paper`` and as ``NAME`` with the
default ``hybridnav`` profile; planners without profiles once; the protocol's ablations with the
default profile), writes the comparison's tables and figures, and ``report.md``
(:mod:`hybridnav.reproduce.report`): the paper's numbers beside ours for each profile, the
paper's derived figures recomputed, and for each of the paper's claims whether it holds in the
paper's own table and here.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from hybridnav.errors import HybridnavError
from hybridnav.backends import load_average
from hybridnav.reproduce.checks import check_count
from hybridnav.fileio import locked_folder
from hybridnav.reproduce.layouts import LAYOUT_RUNS, LAYOUTS, MAX_LAYOUTS
from hybridnav.reproduce.protocols import PROTOCOLS, Claim, Protocol, Row, Value
from hybridnav.reproduce.variants import PROFILES, label_for, variants

__all__ = ["PROFILES", "PROTOCOLS", "Claim", "Protocol", "Row", "Value", "label_for", "reproduce",
           "variants"]


def reproduce(name: str, out: str | Path, *, runs: int | None = None, seed: int = 0,
              workers: int = 1, dask: str | Any | None = None,
              progress: Callable[[int, int], None] | None = None,
              scenarios: Sequence[str] | None = None, layouts: int | None = None,
              phase: Callable[[str], None] | None = None, fmt: str = "png",
              dpi: int = 120) -> dict[str, Any]:
    """Run protocol ``name`` and write its report into ``out``.

    Parameters
    ----------
    name : str
        A key of :data:`PROTOCOLS`, or of :data:`hybridnav.reproduce.tuning.EXPERIMENTS` (a
        target that tunes before it judges: ``effc-ga``; ``runs`` is then its GA seeds per
        profile and ``scenarios``/``layouts`` do not apply).
    out : str or Path
        The output folder (``report.md``, ``runs.csv``, ``summary.csv``, figures,
        ``comparison.json``).
    runs : int, optional
        Runs per planner and scenario (default: the paper's number).
    seed : int
        Base seed of the comparison.
    workers : int
        Local worker processes.
    dask : str or distributed.Client, optional
        A Dask scheduler (as for ``compare``).
    progress : callable, optional
        ``progress(done, total)``.
    scenarios : sequence of str, optional
        Run only these of the protocol's scenarios (its rows; default all).
    layouts : int, optional
        Perturbed layouts per row where a claim does not hold in our runs
        (:mod:`hybridnav.reproduce.layouts`; default :data:`LAYOUTS`; ``min(runs,
        LAYOUT_RUNS)`` runs per planner and layout; 0: no layout sensitivity). They are written to ``out/layouts/``, their verdicts
        to ``layouts.csv`` and their runs' summary to ``layouts_summary.csv``.
    phase : callable, optional
        ``phase(message)`` as each phase after the runs starts (tables and figures, the
        report; for ``effc-ga``, as its experiment names them).
    fmt : str
        The figures' format: ``png``, ``pdf`` or ``svg`` (their names, and the report's links,
        carry it).
    dpi : int
        The figures' resolution in dots per inch.

    Returns
    -------
    dict
        ``claims``: per claim, ``{"text", "paper", "paper profile", "hybridnav profile"}`` with
        True, False or None (not checkable); ``files``: what was written.

    Raises
    ------
    HybridnavError
        An unknown protocol or a bad ``runs``; another job writing ``out`` (the folder is
        locked while a reproduction runs).
    """
    from hybridnav.experiments.compare import PlannerSpec

    from hybridnav.reproduce.tuning import EXPERIMENTS, run_experiment

    from hybridnav.params import check_dpi, check_figure_format

    if name not in PROTOCOLS and name not in EXPERIMENTS:
        raise HybridnavError(f"reproduce: unknown protocol {name!r}; expected one of: "
                             + ", ".join(sorted([*PROTOCOLS, *EXPERIMENTS])))
    figures = {"fmt": check_figure_format(fmt, "fmt"), "dpi": check_dpi(dpi)}
    if name in EXPERIMENTS:
        if scenarios:
            raise HybridnavError(f"reproduce {name}: --scenarios: this target tunes before it "
                                 "compares and judges fixed world sets; expected none")
        if layouts is not None:
            raise HybridnavError(f"reproduce {name}: --layouts: this target judges generated "
                                 "world sets, not reconstructed layouts; expected none")
        if runs is not None:
            check_count("--runs", runs, 1)
        with locked_folder(out, f"reproduce {name}"):
            return run_experiment(name, out, runs=runs, seed=seed, workers=workers, dask=dask,
                                  progress=progress, phase=phase, **figures)
    protocol = PROTOCOLS[name]
    if scenarios:
        known = [row.scenario for row in protocol.rows]
        bad = [sc for sc in scenarios if sc not in known]
        if bad:
            raise HybridnavError(f"reproduce {name}: --scenarios: expected some of "
                                 f"{', '.join(known)}, got {bad[0]!r}")
        protocol = dataclasses.replace(protocol, rows=tuple(
            row for row in protocol.rows if row.scenario in scenarios))
    n = protocol.runs if runs is None else check_count("--runs", runs, 1)
    layouts = LAYOUTS if layouts is None else check_count("--layouts", layouts, 0, MAX_LAYOUTS)
    specs = [PlannerSpec(label, planner, params) for label, planner, params in variants(protocol)]
    scenarios = [row.scenario for row in protocol.rows]
    with locked_folder(out, f"reproduce {name}"):       # one job writes a folder at a time
        return _reproduce(name, protocol, specs, scenarios, int(n), Path(out), seed, workers,
                          dask, progress, int(layouts), phase or (lambda msg: None), figures)




def _reproduce(name, protocol, specs, scenarios, n, out, seed, workers, dask, progress, layouts,
               say, figures=None):
    from hybridnav.experiments.compare import compare, write_comparison
    from hybridnav.fileio import atomic_write_text
    from hybridnav.reproduce.layouts import layout_sensitivity
    from hybridnav.reproduce.report import check_claims, write_report

    tic = time.perf_counter()
    table, summary = compare(specs, scenarios, int(n), seed=seed, workers=workers, dask=dask,
                             progress=progress)
    layout_runs = min(n, LAYOUT_RUNS)
    first = len(table.groupby(["planner", "scenario", "run"]))     # the main runs, done

    def later(done, total):                  # the layout runs continue the count
        if progress is not None:
            progress(first + done, first + total)

    verdicts, lsummary = layout_sensitivity(protocol, summary, count=layouts, runs=layout_runs,
                                            seed=seed, workers=workers, dask=dask,
                                            folder=out / "layouts", progress=later)
    elapsed = time.perf_counter() - tic
    from hybridnav import __version__

    settings = {"protocol": name, "paper": protocol.paper, "runs": int(n),
                "paper_runs": protocol.runs, "seed": seed, "profiles": list(PROFILES),
                "planners": [s.format() for s in specs], "scenarios": scenarios,
                "workers": workers if dask is None else f"dask {dask}",
                "elapsed_s": round(elapsed, 1), "load": load_average(), "layouts": layouts,
                "layout_runs": layout_runs}
    say("tables and figures")
    files = write_comparison(out, table, summary, settings=settings, **(figures or {}))
    if not verdicts.empty:
        atomic_write_text(out / "layouts.csv", verdicts.to_csv(index=False))
        atomic_write_text(out / "layouts_summary.csv", lsummary.to_csv(index=False))
        files += ["layouts.csv", "layouts_summary.csv", "layouts/"]
    else:                                    # an earlier run's verdicts are not this run's
        for stale in ("layouts.csv", "layouts_summary.csv"):
            (out / stale).unlink(missing_ok=True)
        from hybridnav.reproduce.layouts import LAYOUT_FILE

        if (out / "layouts").is_dir():       # nor its layouts (only names we write)
            for old in (out / "layouts").glob("*.toml"):
                if LAYOUT_FILE.fullmatch(old.name) and old.name.split(".")[0] in scenarios:
                    old.unlink()
    say("claims and report")
    claims = check_claims(protocol, summary)
    write_report(Path(out) / "report.md", protocol, summary, claims, runs=int(n), seed=seed,
                 version=__version__, files=files, layouts=verdicts, layout_runs=layout_runs)
    return {"claims": claims, "files": ["report.md", *files]}


