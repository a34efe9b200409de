"""The ``hybridnav`` command: a thin layer over the library.

User errors (:class:`hybridnav.HybridnavError`) are printed as one line, ``hybridnav: error: ...``,
and the command exits with status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

from hybridnav import HybridnavError, __version__

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
    path = save_scenario_png(scenario, args.output, t=args.time)
    robots = ", ".join(r.name for r in scenario.robots)
    print(f"{scenario.name}: {len(scenario.world.obstacles)} obstacles, robots {robots} -> {path}")
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    from hybridnav.models import MODELS

    for name, cls in sorted(MODELS.items()):
        states = ", ".join(cls.plant_state_names + cls.controller_state_names)
        print(f"{name}: {cls.description}")
        print(f"  states: {states}; inputs: {', '.join(cls.input_names)}")
        for key, value in cls.defaults.items():
            print(f"  {key} = {value:g}    {cls.param_docs.get(key, '')}")
        for key, value in cls.option_defaults.items():
            choices = " | ".join(cls.option_choices.get(key, ()))
            print(f"  {key} = {value!r}    one of: {choices}")
    return 0


def _cmd_analyze(args: argparse.Namespace) -> int:
    from hybridnav.analysis.report import analyze

    result = analyze(args.model, scenario=args.scenario, out=args.out, seed=args.seed,
                     progress=lambda msg: print(f"  {msg} ...", flush=True))
    width = max(len(c["name"]) for c in result["checks"])
    print(f"{result['model']} on {result['scenario']}, target {result['target']}:")
    for c in result["checks"]:
        print(f"  {c['name']:<{width}}  {c['status']}")
    print(f"wrote {args.out}/analysis.json, report.md and {len(result['plots'])} plots")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``hybridnav`` command."""
    parser = argparse.ArgumentParser(
        prog="hybridnav",
        description="Hybrid mobile-robot navigation: kinematic models, planners, analysis, "
                    "fuzzy tuning.",
    )
    parser.add_argument("--version", action="version", version=f"hybridnav {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="log more (repeat for debug output)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("scenarios", help="list the built-in scenarios")
    p.set_defaults(func=_cmd_scenarios)

    p = sub.add_parser("show", help="draw a scenario (workspace, obstacles, robots) to a PNG")
    p.add_argument("scenario", help="built-in scenario name or path to a scenario .toml file")
    p.add_argument("-o", "--output", required=True, metavar="FILE.png", help="picture to write")
    p.add_argument("--time", type=float, default=0.0, metavar="T",
                   help="draw moving obstacles at time T (seconds, default 0)")
    p.set_defaults(func=_cmd_show)

    p = sub.add_parser("analyze", help="stability analysis of a model: Lyapunov, linearization, "
                                       "region of attraction, sweeps")
    p.add_argument("model", choices=["point_mass", "unicycle", "tractor_trailer", "lbcs"])
    p.add_argument("--scenario", help="scenario giving target, region and obstacles (default: "
                                      "one per model)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for analysis.json, "
                                                              "report.md and plots")
    p.add_argument("--seed", type=int, default=0, help="seed of the sampling (default 0)")
    p.set_defaults(func=_cmd_analyze)

    p = sub.add_parser("models", help="list the kinematic models and their parameters")
    p.set_defaults(func=_cmd_models)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hybridnav`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=(logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)],
                        format="%(levelname)s %(name)s: %(message)s")
    try:
        return args.func(args)
    except HybridnavError as exc:
        print(f"hybridnav: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # unwritable output folder, disk full, ...
        print(f"hybridnav: error: {exc.filename or ''}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hybridnav: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
