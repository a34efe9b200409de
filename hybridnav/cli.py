"""The ``hybridnav`` command: a thin layer over the library.

User errors (:class:`hybridnav.HybridnavError`) are printed as one line, ``hybridnav: error: ...``,
and the command exits with status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from hybridnav import HybridnavError, __version__
from hybridnav.fileio import locked_folder
from hybridnav.params import (
    DEFAULT_DPI,
    FIGURE_FORMATS,
    FPS_RANGE,
    MAX_DPI,
    MIN_DPI,
    check_dpi,
    check_figure_format,
    check_fps,
    check_seed,
    describe_params,
    short_repr,
)
from hybridnav.reproduce.layouts import LAYOUTS, MAX_LAYOUTS

__all__ = ["main"]

log = logging.getLogger("hybridnav")


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from hybridnav.world import list_scenarios

    rows = list_scenarios()
    width = max(len(name) for name, _ in rows)
    for name, description in rows:
        print(f"{name:<{width}}  {description}")
    return 0


def _cmd_show(args: argparse.Namespace) -> int:
    from hybridnav.plotting import save_scenario_png
    from hybridnav.world import load_scenario

    scenario = load_scenario(args.scenario)
    path = save_scenario_png(scenario, args.output, t=args.time, dpi=args.dpi)
    robots = ", ".join(r.name for r in scenario.robots)
    print(f"{scenario.name}: {len(scenario.world.obstacles)} obstacles, robots {robots} -> {path}")
    return 0


def _cmd_completion(args: argparse.Namespace) -> int:
    from hybridnav.cli_help import completion_script

    print(completion_script(args.shell, build_parser()), end="")
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    from hybridnav.models import MODELS

    for name, cls in sorted(MODELS.items()):
        states = ", ".join(cls.plant_state_names + cls.controller_state_names)
        print(f"{name}: {cls.description}")
        print(f"  states: {states}; inputs: {', '.join(cls.input_names)}")
        for line in describe_params(cls.parameters):
            print(line)
    return 0


def _cmd_analyze(args: argparse.Namespace) -> int:
    from hybridnav.analysis.report import analyze
    from hybridnav.progress import PhaseLog

    with PhaseLog() as say:
        result = analyze(args.model, scenario=args.scenario, out=args.out, seed=args.seed,
                         progress=say, fmt=args.format, dpi=args.dpi)
    width = max(len(c["name"]) for c in result["checks"])
    print(f"{result['model']} on {result['scenario']}, target {result['target']}:")
    for c in result["checks"]:
        print(f"  {c['name']:<{width}}  {c['status']}")
    print(f"wrote {args.out}/analysis.json, report.md and {len(result['plots'])} plots")
    return 0


def _cmd_planners(args: argparse.Namespace) -> int:
    from hybridnav.planners import PLANNERS

    for name, cls in sorted(PLANNERS.items()):
        extra = []
        if not cls.moving_obstacles:
            extra.append("static obstacles only")
        if not cls.moving_targets:
            extra.append("fixed goals only")
        note = f" ({'; '.join(extra)})" if extra else ""
        print(f"{name}: {cls.description}{note}")
        print(f"  robots: {', '.join(cls.models)}")
        for line in describe_params(cls.parameters):
            print(line)
        for profile, values in cls.profiles.items():
            if values:
                print(f"  profile {profile!r}: "
                      + ", ".join(f"{k} = {short_repr(v)}" for k, v in values.items()))
        if cls.paper_notes:
            print(f"    {cls.paper_notes}")
        if cls.paper_deviations:
            print("  still different from the paper in profile 'paper':")
            for item in cls.paper_deviations:
                print(f"    - {item}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hybridnav import planners
    from hybridnav.plotting import figure_name, plot_result, save_figure
    from hybridnav.world import load_scenario

    scenario = load_scenario(args.scenario)
    settings = planners.parse_assignments(args.set or [])
    if args.fis is not None:
        cls = planners.PLANNERS.get(args.planner)
        if cls is None or "fis" not in cls.parameters:
            takes = ", ".join(k for k, c in planners.PLANNERS.items() if "fis" in c.parameters)
            raise HybridnavError(f"--fis: only the planners that take a fuzzy system ({takes}) "
                                 f"do, not {args.planner}")
        settings["fis"] = args.fis
    planner = planners.get(args.planner, **settings)
    out = Path(args.out)
    with locked_folder(out, f"run {args.scenario} --planner {args.planner}"):
        result = planner.run(scenario, seed=args.seed)
        result.write(out)
        path_name = figure_name("path", args.format)
        save_figure(plot_result(scenario, result), out / path_name, dpi=args.dpi)
        # figures drawn from the result alone, named in the chosen format
        extra = _save_all(planner.diagnostics(scenario, result), out, args)
    print(f"{scenario.name} with {planner.name} (seed {args.seed}):")
    print(f"  {'robot':<10} {'outcome':<14} {'length':>10} {'time':>9} {'clearance':>10} "
          f"{'compute':>9}")
    for r in result.robots:
        t = "-" if r.time_to_goal is None else f"{r.time_to_goal:.1f}"
        c = "-" if r.min_clearance is None or r.min_clearance == float("inf") else \
            f"{r.min_clearance:.3g}"
        print(f"  {r.name:<10} {r.outcome:<14} {r.path_length:>10.4g} {t:>9} {c:>10} "
              f"{r.compute_time:>8.2f}s")
    files = ["result.json", *(f"trajectory_{r.name}.csv" for r in result.robots),
             *result.extra_files().values(), path_name, *extra]
    print(f"wrote {out}/: {', '.join(files)}")
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hybridnav import planners
    from hybridnav.params import short_repr
    from hybridnav.plotting import figure_name, plot_result, save_figure
    from hybridnav.results import read_run

    result, scenario = read_run(args.result, args.scenario)
    listing = Path(args.result) / "result.json"
    if result.planner not in planners.PLANNERS:
        raise HybridnavError(f"{listing}: planner: expected one of "
                             f"{', '.join(sorted(planners.PLANNERS))}, got "
                             f"{short_repr(result.planner)}")
    out = Path(args.out or args.result)
    out.mkdir(parents=True, exist_ok=True)
    path_name = figure_name("path", args.format)
    save_figure(plot_result(scenario, result), out / path_name, dpi=args.dpi)
    # any instance draws from the result alone (its extras), not from a run of its own
    figures = _save_all(planners.get(result.planner).diagnostics(scenario, result), out, args)
    note = "" if figures else f" (the result has no extras {result.planner} draws from)"
    print(f"wrote {out}/: {', '.join([path_name, *figures])}{note}")
    return 0


def _save_all(figures, out, args: argparse.Namespace) -> list[str]:
    """Write ``{name: figure}`` (a planner's diagnostics, named ``<stem>.png``) into ``out`` in
    the format and resolution of ``--format`` and ``--dpi``; returns the names written."""
    from hybridnav.plotting import figure_name, save_figure

    names = []
    for name, fig in figures.items():
        name = figure_name(name, args.format)
        save_figure(fig, out / name, dpi=args.dpi)
        names.append(name)
    return names


def _cmd_animate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hybridnav.plotting import animate
    from hybridnav.tuner.animation import animate_tuning, is_tuning_folder

    folder = Path(args.folder)
    if folder.is_dir() and is_tuning_folder(folder):
        if args.scenario is not None:
            raise HybridnavError(f"{folder}: --scenario: a tuning job's folder drives on one of "
                                 "the job's worlds: choose it with --world")
        done = animate_tuning(folder, args.out, world=args.world,
                              fps=4.0 if args.fps is None else args.fps, dpi=args.dpi,
                              max_frames=args.max_frames)
    else:
        if args.world is not None:
            raise HybridnavError(f"{folder}: --world: only for a tuning job's folder (this is "
                                 "not one: a run's scenario is its result's)")
        done = animate(folder, args.out, scenario=args.scenario,
                       fps=10.0 if args.fps is None else args.fps, dpi=args.dpi,
                       max_frames=args.max_frames)
    w, h = done.size
    if not done.labels[0].startswith("generation"):
        what = f"t = {done.times[-1]:.1f} s" if done.frames == 1 else \
            f"t = 0 to {done.times[-1]:.1f} s"
    else:                                    # one frame: the last generation's end
        first, last = (lab.split(":")[0] for lab in (done.labels[0], done.labels[-1]))
        what = last if done.frames == 1 else f"{first} to {last}"
    print(f"wrote {done.path}: {done.frames} frame{'s' * (done.frames != 1)} at {done.fps:g} "
          f"fps, {w} x {h} pixels "
          f"({what})")
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    from hybridnav import fuzzy
    from hybridnav.fuzzy.export.sil import CompiledFIS
    from hybridnav.world import load_scenario

    from hybridnav import planners

    system = fuzzy.load_any(args.fis)
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    scenarios = [load_scenario(n) for n in names]
    settings = planners.parse_assignments(args.set or [])
    if "fis" in settings:
        raise HybridnavError("--set fis: the system is the FIS argument")
    effc = planners.get("effc", fis=system, **settings)    # checks names and values
    params = {k: effc.values[k] for k in settings}
    # compiled and run in a child process with limits; other than an unmodified export only
    # with --trust
    with CompiledFIS(args.c_file, trust=args.trust, timeout=args.timeout) as compiled:
        if set(compiled.input_names) != set(system.input_names):
            raise HybridnavError(f"{args.c_file}: its inputs {', '.join(compiled.input_names)} "
                                 f"are not those of {args.fis} ({', '.join(system.input_names)})")
        from hybridnav.fuzzy.export.closedloop import verify   # seconds to import: after the C's checks

        rows = verify(system, compiled, scenarios, seed=args.seed, **params)
    shown = "".join(f", {k}={v}" for k, v in params.items())
    print(f"{args.c_file} (compiled) against {args.fis} (Python), planner effc{shown}, seed "
          f"{args.seed}:")
    print(f"  {'scenario':<16} {'robot':<8} {'outcome':<14} {'samples':>7} {'max |dx|':>10} "
          f"{'max |dw|':>10} {'same inputs':>11}")
    ok = True
    for r in rows:
        good = r["same_outcome"] and r["max_state_diff"] <= args.tolerance \
            and r["max_w_diff"] <= args.tolerance and r["same_inputs_w_diff"] <= args.tolerance
        ok &= good
        print(f"  {r['scenario']:<16} {r['robot']:<8} {r['outcome']:<14} {r['samples']:>7} "
              f"{r['max_state_diff']:>10.2e} {r['max_w_diff']:>10.2e} "
              f"{r['same_inputs_w_diff']:>11.2e}{'' if good else '  DIFFERS'}")
    print(f"{'verified' if ok else 'NOT verified'}: every trajectory and w signal "
          f"{'within' if ok else 'must be within'} {args.tolerance:g}")
    exact = max(r["same_inputs_w_diff"] for r in rows)
    parted = [r for r in rows if not (r["max_state_diff"] <= args.tolerance)]
    if not ok and exact <= args.tolerance and parted:
        print(f"  (on the same inputs the compiled w equals Python's within {exact:.2e}: the "
              f"closed loops of {', '.join(r['scenario'] for r in parted)} part on rounding at a "
              "discontinuity of the loop, e.g. a graze or the safety filter's decision at its margin)")
    return 0 if ok else 1


def _cmd_compare(args: argparse.Namespace) -> int:
    from hybridnav.progress import bar as progress_bar

    from hybridnav.experiments.compare import compare, write_comparison
    from hybridnav.planners import parse_assignments

    plans = [p.strip() for p in args.planners.split(",") if p.strip()]
    scens = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    params: dict[str, dict[str, str]] = {}
    for key, value in parse_assignments(args.set or []).items():
        planner, dot, name = key.rpartition(".")    # labels may contain dots, keys do not
        if not dot or not planner or not name:
            raise HybridnavError(f"--set {key}={value}: expected label.parameter=value")
        params.setdefault(planner, {})[name] = value
    bar = progress_bar(len(plans) * len(scens) * args.runs, "run", "compare")

    def progress(done, total):
        bar.update(done - bar.n)

    with locked_folder(args.out, f"compare --planners {args.planners}"):
        try:
            table, summary = compare(plans, scens, args.runs, seed=args.seed, params=params,
                                     workers=args.workers, dask=args.dask, progress=progress)
        finally:
            bar.close()
        files = write_comparison(args.out, table, summary, settings={
            "planners": plans, "scenarios": scens, "runs": args.runs, "seed": args.seed,
            "set": params, "workers": args.workers, "dask": args.dask or ""},
            fmt=args.format, dpi=args.dpi)
    cols = ["planner", "scenario", "success_rate", "path_length_mean", "path_length_std",
            "time_to_goal_mean", "time_to_goal_std"]
    print(summary[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"wrote {args.out}/: {', '.join(files)}")
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from hybridnav.progress import PhaseLog
    from hybridnav.progress import bar as progress_bar
    from hybridnav.reproduce import PROTOCOLS, reproduce, variants

    if args.update_readme:
        from hybridnav.reproduce.readme import STORE, update_readme

        names = update_readme(args.readme, args.reports or STORE)
        print(f"{args.readme}: rewrote the blocks of {', '.join(names)} from "
              f"{args.reports or STORE}/")
        return 0
    from hybridnav.reproduce.tuning import EXPERIMENTS

    if args.list or not args.name:
        for name, protocol in PROTOCOLS.items():
            print(f"{name}: {protocol.paper}, {protocol.source}; {protocol.runs} runs; "
                  f"scenarios {', '.join(r.scenario for r in protocol.rows)}")
        for name, exp in EXPERIMENTS.items():
            print(f"{name}: {exp.paper}, {exp.source}; {exp.runs} GA runs per profile "
                  f"({', '.join(exp.profiles)}); world sets {', '.join(exp.sets)}")
        return 0
    if args.out is None:
        raise HybridnavError("reproduce: -o/--out: expected the output folder")
    if args.name not in PROTOCOLS and args.name not in EXPERIMENTS:
        raise HybridnavError(f"reproduce: unknown protocol {args.name!r}; expected one of: "
                             + ", ".join(sorted([*PROTOCOLS, *EXPERIMENTS])))
    scens = [s.strip() for s in (args.scenarios or "").split(",") if s.strip()]
    if args.name in EXPERIMENTS:
        exp = EXPERIMENTS[args.name]
        total = len(exp.profiles) * (exp.runs if args.runs is None else args.runs)
        views = [f"{p} profile" for p in exp.profiles]
        unit = "GA run"
    else:
        protocol = PROTOCOLS[args.name]
        runs = protocol.runs if args.runs is None else args.runs
        rows = len(scens) if scens else len(protocol.rows)
        total = len(variants(protocol)) * rows * max(runs, 0)
        views = ["paper profile", "hybridnav profile"]
        unit = "run"
    bar = progress_bar(total, unit, args.name)

    def progress(done, total):
        if total != bar.total:               # the layout-sensitivity runs join the count
            bar.total = total
            bar.refresh()
        bar.update(done - bar.n)

    with PhaseLog() as phases:               # a phase an error leaves ends "(failed)"
        try:
            result = reproduce(args.name, args.out, runs=args.runs, seed=args.seed,
                               workers=args.workers, dask=args.dask, progress=progress,
                               scenarios=scens, layouts=args.layouts,
                               phase=lambda msg: (bar.close(), phases(msg)),
                               fmt=args.format, dpi=args.dpi)
        finally:
            bar.close()
    words = {True: "holds", False: "does not hold", None: "not shown"}
    for c in result["claims"]:
        print(f"{c['text']}: paper's numbers {words[c['paper']]}; ours, " + "; ".join(
            f"profile={v.split()[0]} {words[c[v]]}" for v in views))
    print(f"wrote {args.out}/: {', '.join(result['files'])}")
    return 0


def _cmd_fis(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hybridnav import fuzzy
    from hybridnav.fuzzy import plots

    system = fuzzy.load_any(args.fis)
    print(f"{system.name}: {len(system.inputs)} inputs, {len(system.rules)} rules, output "
          f"{system.output.name} in {list(system.output.range)} (default {system.output.default})")
    for v in system.inputs:
        terms = ", ".join(f"{t.name} {t.mf}{list(t.params)}" for t in v.terms)
        print(f"  input {v.name} in {list(v.range)}: {terms}")
    terms = ", ".join(f"{t.name} {t.mf}{list(t.params)}" for t in system.output.terms)
    print(f"  output {system.output.name}: {terms}")
    for i, r in enumerate(system.rules, 1):
        print(f"  rule {i}: {r.sentence(system.output.name)}")
    if args.out:
        from hybridnav.plotting import figure_name

        out = Path(args.out)
        names = [figure_name("mfs", args.format), figure_name("surface", args.format)]
        plots.save_memberships_png(system, out / names[0], dpi=args.dpi)
        plots.save_surface_png(system, out / names[1], dpi=args.dpi)
        print(f"wrote {out}/: {', '.join(names)}")
    return 0


def _cmd_tune(args: argparse.Namespace) -> int:
    from hybridnav.progress import PhaseLog
    from hybridnav.progress import bar as progress_bar
    from hybridnav.tuner.job import load_job, quick
    from hybridnav.tuner.run import run_job

    job = load_job(args.job).with_seed(args.seed)
    if args.quick:
        job = quick(job)
    job = job.with_backend(workers=args.workers, dask=args.dask)
    total = (job.optimizer().generations + 1) * max(1, job["validation"]["kfold"]) \
        * (2 if job["learning"]["max_rules"] else 1)
    bar = progress_bar(total, "gen", f"tune {job.name}")
    evals = {"n": 0, "t": 0.0}

    def progress(row):
        evals["n"] += row["evals"]
        rate = evals["n"] / row["wall_time"] if row["wall_time"] > 0 else 0.0
        extra = {"val": f"{row['val_best']:.4g}"} if row.get("val_best") is not None else {}
        bar.set_postfix(gen=row["gen"], best=f"{row['min']:.4g}", mean=f"{row['mean']:.4g}",
                        **extra, evals_s=f"{rate:.0f}")
        bar.update(1)

    with PhaseLog() as phases:               # a phase an error leaves ends "(failed)"
        try:
            result = run_job(job, args.out, resume=args.resume, force=args.force,
                             progress=progress, phase=lambda msg: (bar.close(), phases(msg)),
                             fmt=args.format, dpi=args.dpi)
        finally:
            bar.close()
    print(f"{job.name}: training objective ({result.objective_names[0]}) start "
          f"{result.start_objectives[0]:.4f} -> returned {result.objectives[0]:.4f} "
          f"({len(result.system.rules)} rules kept; chosen on {result.selected_by}, generation "
          f"{result.best_generation})")
    for which in ("validation", "test"):
        v = result.verdicts.get(which)
        if v and v["checks"]:
            print(f"{which}: {v['headline']} (see report.md)")
    print(f"wrote {args.out}/: {', '.join(result.files)}")
    return 0


def _cmd_generate(args: argparse.Namespace) -> int:
    import tomllib
    from pathlib import Path

    from hybridnav.planners import parse_assignments
    from hybridnav.world import save_scenario
    from hybridnav.world.generator import generator_from_table

    table: dict[str, object] = {"generate": args.count, "seed": args.seed}
    for key, text in parse_assignments(args.set or []).items():
        try:                                # TOML values: numbers, [low, high], "strings"
            table[key] = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            table[key] = text.strip()       # a bare word such as random
        except (ValueError, RecursionError):   # e.g. past Python's 4300-digit integer limit
            raise HybridnavError(f"--set {key}: expected a number, [low, high] or a word, got "
                                 f"{short_repr(text)} (a number Python cannot read)") from None
    gen, count, seed = generator_from_table(table, "hybridnav generate: ", "")
    out = Path(args.out)
    with locked_folder(out, "generate"):
        for s in gen.generate(count, seed):
            save_scenario(s, out / f"{s.name}.toml")
    print(f"wrote {count} solvable worlds (seed {seed}) to {out}/: {gen.name}-{seed}-000.toml"
          + (f" ... {gen.name}-{seed}-{count - 1:03d}.toml" if count > 1 else ""))
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from hybridnav import fuzzy
    from hybridnav.fuzzy.export.fidelity import (
        FORMULA_TOLERANCE,
        formula_difference,
        uncovered_fraction,
    )

    system = fuzzy.load_any(args.fis, points=args.points)
    if args.sampled and args.formula:
        raise HybridnavError("--sampled and --formula: expected one of them")
    opts: dict[str, object] = {}
    notes = []
    if args.format in ("fll", "fcl", "fis") and not args.sampled:
        worst, at = formula_difference(system)
        where = ", ".join(f"{k} = {v:.4g}" for k, v in at.items())
        if worst > FORMULA_TOLERANCE and args.format != "fis" and not args.formula:
            opts["sampled"] = True
            notes.append(f"the formula form would differ from hybridnav's evaluate by up to "
                         f"{worst:.3g} of the output range (at {where}; tolerance "
                         f"{FORMULA_TOLERANCE:g}): wrote the sampled terms instead (--formula "
                         "writes the formulas)")
        elif worst > FORMULA_TOLERANCE:
            notes.append(f"engines that evaluate the formulas differ from hybridnav's evaluate "
                         f"by up to {worst:.3g} of the output range (at {where})"
                         + ("; --sampled (FLL, FCL) writes the exact terms" if args.format != "fis"
                            else "; the FLL and FCL exports can carry the exact sampled terms"))
        else:
            notes.append(f"the formula form agrees with hybridnav's evaluate within {worst:.2g} of "
                         "the output range")
    if args.format == "fis":
        frac = uncovered_fraction(system)
        if frac > 0:
            o = system.output
            notes.append(f"no rule fires on {frac:.1%} of the input ranges: there hybridnav "
                         f"returns the default {o.default:g}, MATLAB the middle of the output "
                         f"range ({(o.range[0] + o.range[1]) / 2:g}) and fuzzylite NaN; the FLL "
                         "and FCL exports carry the default, or add a rule that fires there")
    if args.sampled:
        opts["sampled"] = True
    if args.float:
        opts["real"] = "float"
    for path in fuzzy.export_to_file(system, args.format, args.out, **opts):
        print(path)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with the one error style: ``hybridnav: error: ...``, exit status 2."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        self.print_usage(sys.stderr)
        self.exit(2, f"hybridnav: error: {message} (see '{self.prog} --help')\n")


def _typed(name: str, convert, check):
    """An argparse ``type``: ``convert`` the text, then ``check`` it (a HybridnavError becomes
    argparse's message naming the option)."""
    def parse(text: str):
        try:
            value = convert(text)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError(f"expected {name}, got {short_repr(text)}") from None
        try:
            return check(value)
        except HybridnavError:
            raise argparse.ArgumentTypeError(f"expected {name}, got {short_repr(text)}") from None
    parse.__name__ = name
    return parse


def _between(lo: float, hi: float = float("inf"), lo_open: bool = False):
    """A check of ``lo <= v <= hi`` (``lo < v`` when ``lo_open``; never NaN or infinite)."""
    import math

    def check(v: float) -> float:
        if not math.isfinite(v) or v < lo or (lo_open and v == lo) or v > hi:
            raise HybridnavError("out of range")
        return v
    return check


#: ``--seed``: what numpy's SeedSequence takes
_SEED = _typed("a non-negative integer below 2**128", int,
               lambda v: check_seed(v, optional=False))
#: ``--workers``: processes on this machine (a job is also bounded by its chunks)
_WORKERS = _typed("an integer in [1, 256]", int, _between(1, 256))
_COUNT = _typed("an integer in [1, 100000]", int, _between(1, 100000))
_LAYOUTS = _typed(f"an integer in [0, {MAX_LAYOUTS}]", int, _between(0, MAX_LAYOUTS))
_TIME = _typed("a finite time >= 0 (seconds)", float, _between(0.0))
_TOLERANCE = _typed("a finite number >= 0", float, _between(0.0))


#: ``--format`` and ``--dpi`` of the commands that draw (hybridnav.plotting.output writes them)
_FIGURE_FORMAT = _typed(f"one of {', '.join(FIGURE_FORMATS)}", str, check_figure_format)
_DPI = _typed(f"an integer in [{MIN_DPI}, {MAX_DPI}] (dots per inch)", int, check_dpi)


def _figure_options() -> argparse.ArgumentParser:
    """``--format`` and ``--dpi``: one parent parser for every command that draws."""
    parent = _Parser(add_help=False)
    parent.add_argument("--format", dest="format", default=FIGURE_FORMATS[0], type=_FIGURE_FORMAT,
                        metavar="{" + ",".join(FIGURE_FORMATS) + "}",
                        help="format of the figures (default png; pdf and svg are vector)")
    parent.add_argument("--dpi", type=_DPI, default=DEFAULT_DPI, metavar="N",
                        help=f"resolution of the figures in dots per inch (default {DEFAULT_DPI})")
    return parent


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``hybridnav`` command."""
    from hybridnav.cli_help import epilog

    parser = _Parser(
        prog="hybridnav",
        description="Hybrid mobile-robot navigation: kinematic models, planners, analysis, "
                    "fuzzy tuning.",
        epilog=epilog(""), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"hybridnav {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="log more (repeat for debug output)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    # -v also after the command (hybridnav tune -v): every command takes it
    common = _Parser(add_help=False)
    common.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                        help="log more (repeat for debug output)")

    figures = _figure_options()

    def add_command(name: str, draws: bool = False, **kwargs: Any) -> argparse.ArgumentParser:
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        return sub.add_parser(name, parents=[common, figures] if draws else [common],
                              epilog=epilog(name), **kwargs)

    p = add_command("scenarios", help="list the built-in scenarios")
    p.set_defaults(func=_cmd_scenarios)

    p = add_command("show", help="draw a scenario (workspace, obstacles, robots) to a PNG")
    p.add_argument("scenario", help="built-in scenario name or path to a scenario .toml file")
    p.add_argument("-o", "--out", "--output", dest="output", required=True, metavar="FILE.png",
                   help="picture to write")
    p.add_argument("--time", type=_TIME, default=0.0, metavar="T",
                   help="draw moving obstacles at time T (seconds, default 0)")
    p.add_argument("--dpi", type=_DPI, default=DEFAULT_DPI, metavar="N",
                   help=f"resolution in dots per inch (default {DEFAULT_DPI}; the format is "
                        "FILE's suffix)")
    p.set_defaults(func=_cmd_show)

    p = add_command("analyze", draws=True, help="stability analysis of a model: Lyapunov, linearization, "
                                       "region of attraction, sweeps")
    from hybridnav import models
    from hybridnav.fuzzy.export import FORMATS

    p.add_argument("model", choices=sorted(models.analyzable()),
                   help="the kinematic model to analyse (see 'hybridnav models')")
    p.add_argument("--scenario", help="scenario giving target, region and obstacles (default: "
                                      "one per model)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder for analysis.json, "
                                                              "report.md and plots")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the sampling (default 0)")
    p.set_defaults(func=_cmd_analyze)

    p = add_command("planners", help="list the planners and their parameters with defaults")
    p.set_defaults(func=_cmd_planners)

    p = add_command("run", draws=True, help="run a planner on a scenario and write the result files")
    p.add_argument("scenario", help="built-in scenario name or path to a scenario .toml file")
    p.add_argument("--planner", required=True, help="planner name (see 'hybridnav planners')")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the planner's randomness")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="set a planner parameter (repeatable)")
    p.add_argument("--fis", metavar="FIS", help="effc, fuzzy-steer: the fuzzy system (a built-in "
                                                "name, a .json, .fll or .fis file, or "
                                                "file.py:NAME / module:NAME naming a "
                                                "FuzzySystem or a scikit-fuzzy ControlSystem)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder for result.json, "
                                                              "trajectories and plots")
    p.set_defaults(func=_cmd_run)

    p = add_command("verify", help="software in the loop: the exported C controller, "
                                      "compiled, against the Python evaluator in closed loop")
    p.add_argument("fis", help="the system the C was exported from (built-in name, .json, .fll, "
                               ".fis)")
    p.add_argument("c_file", metavar="C_FILE", help="the exported .c file (its .h beside it)")
    p.add_argument("--scenarios", default="effc-train-1,effc-train-2,effc-env-a,effc-env-b",
                   help="comma-separated scenarios (default: the EFFC paper's four)")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the runs (default 0)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="an effc parameter for both runs, e.g. safety_margin=0.05 (what a tuned "
                        "system's deployment.json says; repeatable)")
    p.add_argument("--tolerance", type=_TOLERANCE, default=1e-9,
                   help="largest allowed difference of states and w (default 1e-9)")
    p.add_argument("--trust", action="store_true",
                   help="compile C that is not an unmodified hybridnav export (it still runs "
                        "only in a child process with limits)")
    p.add_argument("--timeout", type=_typed("a time in (0, 86400] seconds", float,
                                            _between(0.0, 86400.0, lo_open=True)),
                   default=10.0, metavar="SECONDS",
                   help="time limit of each call into the compiled C (default 10)")
    p.set_defaults(func=_cmd_verify)

    p = add_command("plot", draws=True, help="redraw path.png and the planner's diagnostics from a result "
                                    "folder written by 'run'")
    p.add_argument("result", metavar="DIR", help="a folder with result.json")
    p.add_argument("--scenario", help="the scenario the result is of, when it is not built in "
                                      "(default: the result's scenario name)")
    p.add_argument("-o", "--out", metavar="DIR", help="folder for the figures (default: DIR)")
    p.set_defaults(func=_cmd_plot)

    p = add_command("animate", help="write a GIF or MP4 of a run (a folder written by 'run') "
                                    "or of a tuning job's best system per generation",
                    formatter_class=argparse.RawDescriptionHelpFormatter,
                    description="Animate a run: the robots' trails and poses (footprints), the\n"
                                "moving obstacles and targets where they are, and for swarm\n"
                                "planners (pso-ba, fastep-kinematic, aco-kinematic) the\n"
                                "candidates of each planning step. On a tuning job's folder:\n"
                                "generation by generation, the best system of that generation\n"
                                "driving on one of the job's worlds.")
    p.add_argument("folder", metavar="DIR", help="a folder written by 'hybridnav run' "
                                                  "(result.json) or 'hybridnav tune'")
    p.add_argument("-o", "--out", metavar="FILE",
                   help="the .gif or .mp4 to write (.mp4 needs ffmpeg on PATH; default "
                        "DIR/animation.gif)")
    p.add_argument("--scenario", help="a run's scenario when it is not built in (a .toml file; "
                                      "default: the result's scenario name)")
    p.add_argument("--world", metavar="NAME", help="tuning job: which of the job's worlds "
                                                    "(default: its first test world, else "
                                                    "validation)")
    p.add_argument("--fps", type=_typed(FPS_RANGE, float, check_fps),
                   default=None, metavar="N", help="frames per second, 0.01 to 100 (default 10; "
                                                   "4 for a tuning job)")
    p.add_argument("--dpi", type=_typed("an integer in [10, 600]", int, _between(10, 600)),
                   default=80, metavar="N", help="resolution: a frame is 6.4 x 6.4 inches "
                                                 "(default 80: 512 x 512 pixels)")
    p.add_argument("--max-frames", type=_typed("an integer in [1, 10000]", int,
                                               _between(1, 10000)),
                   default=150, metavar="N", help="most frames (default 150)")
    p.set_defaults(func=_cmd_animate)

    p = add_command("compare", draws=True, help="run planners x scenarios x runs; runs.csv, summary.csv, "
                                       "plots")
    p.add_argument("--planners", required=True,
                   help="comma-separated planners: NAME, NAME@LABEL or NAME@LABEL:key=value"
                        "[:key=value...] (a labelled variant; its parameters win over --set)")
    p.add_argument("--scenarios", required=True, help="comma-separated scenario names or paths")
    p.add_argument("--runs", type=_COUNT, default=10, help="runs per combination (default 10)")
    p.add_argument("--seed", type=_SEED, default=0, help="seed from which every run's seed derives")
    p.add_argument("--set", action="append", metavar="LABEL.KEY=VALUE",
                   help="set a parameter of the planner with that label or plain name "
                        "(repeatable)")
    backend = p.add_mutually_exclusive_group()
    backend.add_argument("--workers", type=_WORKERS, default=1, help="local worker processes")
    backend.add_argument("--dask", metavar="ADDRESS", help="Dask scheduler address")
    p.add_argument("-o", "--out", required=True, metavar="DIR",
                   help="folder for the tables and plots")
    p.set_defaults(func=_cmd_compare)

    p = add_command("reproduce", draws=True, help="run a paper's protocol in both profiles; report.md with "
                                      "the paper's numbers and claims beside ours")
    p.add_argument("name", nargs="?", help="protocol (see --list)")
    p.add_argument("--list", action="store_true", help="list the protocols")
    p.add_argument("--runs", type=_COUNT, default=None,
                   help="runs per planner and scenario (default: the paper's number)")
    p.add_argument("--scenarios", help="comma-separated: only these of the protocol's scenarios")
    p.add_argument("--seed", type=_SEED, default=0, help="seed from which every run's seed derives")
    p.add_argument("--layouts", type=_LAYOUTS, default=None,
                   help="perturbed layouts per row where a claim does not hold in our runs "
                        f"(layout sensitivity; default {LAYOUTS}, 0: none)")
    backend = p.add_mutually_exclusive_group()
    backend.add_argument("--workers", type=_WORKERS, default=1, help="local worker processes")
    backend.add_argument("--dask", metavar="ADDRESS", help="Dask scheduler address")
    p.add_argument("-o", "--out", metavar="DIR", help="folder for the report, tables and plots")
    p.add_argument("--update-readme", action="store_true",
                   help="rewrite README's reproduce blocks from the stored full runs")
    p.add_argument("--readme", default="README.md", help="with --update-readme: the README")
    p.add_argument("--reports", metavar="DIR",
                   help="with --update-readme: the stored runs (default docs/reproductions)")
    p.set_defaults(func=_cmd_reproduce)

    p = add_command("fis", draws=True, help="describe a fuzzy system; plot its membership functions and "
                                   "control surface")
    p.add_argument("fis", help="built-in name (effc-2rule, effc-5rule, effc-tuned, ...), a "
                                  ".json, .fll or .fis file, or file.py:NAME / module:NAME "
                                  "naming a FuzzySystem or a scikit-fuzzy ControlSystem")
    p.add_argument("-o", "--out", metavar="DIR", help="folder for mfs.png and surface.png (or "
                                                      ".pdf, .svg: --format)")
    p.set_defaults(func=_cmd_fis)

    p = add_command("tune", draws=True, help="tune a fuzzy system: a navigation controller, a system fitted to "
                                    "data or to your own cost; GA, CMA-ES, PSO or NSGA-II "
                                    "(default: the built-in EFFC job)")
    p.add_argument("job", nargs="?", help="job file (TOML); omitted: the built-in EFFC job")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder for the tuned system, "
                                                              "report, plots and checkpoint")
    p.add_argument("--seed", type=_SEED, help="override the job's seed")
    p.add_argument("--quick", action="store_true", help="small smoke run (population 12, "
                                                        "3 generations)")
    backend = p.add_mutually_exclusive_group()
    backend.add_argument("--workers", type=_WORKERS, help="local worker processes")
    backend.add_argument("--dask", metavar="ADDRESS", help="Dask scheduler address ('local': a "
                                                           "LocalCluster)")
    p.add_argument("--resume", action="store_true", help="continue from DIR/checkpoint.json")
    p.add_argument("--force", action="store_true", help="start over in a DIR that holds a "
                                                        "tuning run (its outputs are removed)")
    p.set_defaults(func=_cmd_tune)

    p = add_command("export", help="write a fuzzy system as JSON, fuzzylite FLL, MATLAB .fis, "
                                      "IEC 61131-7 FCL or standalone C")
    p.add_argument("fis", metavar="FIS", help="built-in name, a .json/.fll/.fis file, or "
                                              "file.py:NAME / module:NAME (a FuzzySystem or "
                                              "a scikit-fuzzy ControlSystem)")
    p.add_argument("--format", required=True, choices=list(FORMATS),
                   help="json: hybridnav's own file; fll: fuzzylite; fis: MATLAB Fuzzy Logic "
                        "Toolbox; fcl: IEC 61131-7; c: a standalone C evaluator (.h and .c)")
    p.add_argument("-o", "--out", metavar="PATH", help="output file; for c a prefix (PATH.h, "
                                                       "PATH.c); default <name>.<ext>")
    p.add_argument("--sampled", action="store_true", help="fll/fcl: terms as their sampled "
                                                          "polylines (exactly hybridnav's "
                                                          "membership; the default when the "
                                                          "formulas would differ by > 1e-3)")
    p.add_argument("--formula", action="store_true", help="fll/fcl: the membership formulas "
                                                          "even where they differ")
    p.add_argument("--float", action="store_true", help="c: single precision by default")
    p.add_argument("--points", type=int, default=101, help="universe points for .fll/.fis files "
                                                           "without hybridnav metadata")
    p.set_defaults(func=_cmd_export)

    p = add_command("generate", help="write random solvable EFFC-scale worlds as scenario "
                                        "TOML files")
    p.add_argument("--count", type=_COUNT, default=10, help="number of worlds (default 10)")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the set (default 0)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="generator setting, e.g. circles=[2,6], radius=[0.2,0.4], "
                        "layout=random (repeatable; see the README)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder for the .toml files")
    p.set_defaults(func=_cmd_generate)

    p = add_command("models", help="list the kinematic models and their parameters")
    p.set_defaults(func=_cmd_models)

    from hybridnav.cli_help import SHELLS

    p = add_command("completion", help="print a shell completion script (bash, zsh, tcsh)")
    p.add_argument("shell", choices=SHELLS, help="the shell the script is for")
    p.set_defaults(func=_cmd_completion)
    return parser


def _show_deprecations() -> None:
    """Show old names used by the files and code a command loads, one line each: Python hides
    ``DeprecationWarning`` outside ``__main__`` unless a filter (``-W``, pytest's settings) says
    otherwise. Call inside ``warnings.catch_warnings()``, which restores both."""
    from hybridnav.deprecation import HybridnavDeprecationWarning

    default = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, HybridnavDeprecationWarning):
            print(f"hybridnav: warning: {message}", file=file or sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    if sys.warnoptions:                      # the user chose (-W, PYTHONWARNINGS): as they say
        return
    for action, msg, category, module, _ in warnings.filters:   # the filter that would apply
        if isinstance(module, str):                 # a filter as Python's defaults store it
            module = re.compile(re.escape(module) + r"\Z")
        if msg is None and issubclass(HybridnavDeprecationWarning, category) and (
                module is None or module.match("hybridnav.cli")):
            if action == "ignore":
                warnings.filterwarnings("default", category=HybridnavDeprecationWarning)
            return


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hybridnav`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    level = (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    # -v / -vv are hybridnav's own log; other libraries (matplotlib's font search, Dask's
    # cluster chatter in the progress bar) stay at warnings unless -vvv
    logging.basicConfig(level=level if args.verbose >= 3 else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("hybridnav").setLevel(level)
    if args.verbose < 3:
        for name in ("distributed", "matplotlib", "PIL", "asyncio", "tornado", "bokeh"):
            logging.getLogger(name).setLevel(logging.WARNING)
        # distributed sets its loggers from Dask's config when it is imported (later, by --dask),
        # in this process and in its worker processes: the config says warnings too
        os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "warning")
    try:
        with warnings.catch_warnings():
            _show_deprecations()
            return args.func(args)
    except HybridnavError as exc:
        print(f"hybridnav: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head or less that quit early
        return 0
    except OSError as exc:  # an output path that is a file, a dangling link, ...
        from hybridnav.fileio import shown_path

        where_ = shown_path(exc.filename) if exc.filename else "output"
        print(f"hybridnav: error: {where_}: cannot use it ({exc.strerror or exc})",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hybridnav: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
