"""What the ``hybridnav`` command says besides its options: examples per command and the shell
completion scripts.

:data:`EXAMPLES` holds each command's examples (``hybridnav COMMAND --help`` prints them; a test
parses every one with the real parser). :func:`completion_script` writes a bash, zsh or tcsh
completion script generated from the parser itself (``shtab``), so it completes every command,
option and choice the installed version has, files where a command takes a file, and (bash,
zsh) the built-in scenario and planner names where it takes those.
"""

from __future__ import annotations

import argparse

__all__ = ["EXAMPLES", "SHELLS", "completion_script", "epilog"]

#: command -> ((command line, what it does), ...)
EXAMPLES: dict[str, tuple[tuple[str, str], ...]] = {
    "": (
        ("hybridnav tune -o out/tune", "tune the built-in EFFC controller (about a minute)"),
        ("hybridnav run effc-env-b --planner effc -o out/run", "one run, its files and figures"),
        ("hybridnav analyze unicycle -o out/analysis", "stability analysis of a model"),
        ("hybridnav COMMAND --help", "a command's options and examples"),
    ),
    "scenarios": (("hybridnav scenarios", "names, models and descriptions"),),
    "show": (
        ("hybridnav show pso-ba-dynamic -o scene.png --time 5", "the scene at t = 5 s"),
    ),
    "analyze": (
        ("hybridnav analyze unicycle -o out/analysis", "the default target and region"),
        ("hybridnav analyze tractor_trailer --scenario tractor-trailer-1 -o out/tt",
         "target, region and obstacles from a scenario"),
    ),
    "planners": (("hybridnav planners", "every planner, its parameters and profiles"),),
    "run": (
        ("hybridnav run effc-env-b --planner effc -o out/run", "EFFC with its built-in system"),
        ("hybridnav run fastep-s1 --planner fastep-kinematic --set profile=paper -o out/fs",
         "a planner in its paper's settings"),
        ("hybridnav run effc-env-b --planner effc --fis out/tune/fis.json "
         "--set safety_margin=0.05 -o out/tuned",
         "a tuned system with the safety filter it was tuned with (its deployment.json)"),
    ),
    "verify": (
        ("hybridnav verify out/tune/fis.json out/tune/effc.c", "the exported C in closed loop"),
    ),
    "plot": (("hybridnav plot out/run", "redraw a run's figures"),
             ("hybridnav plot out/run -o out/svg --format svg", "the same as SVG files"),),
    "compare": (
        ("hybridnav compare --planners apf,effc --scenarios effc-env-a,effc-env-b --runs 5 "
         "-o out/cmp --workers 2", "two planners, two scenarios, five runs each"),
        ("hybridnav compare --planners effc,effc@tuned:fis=out/tune/fis.json:safety_margin=0.05 "
         "--scenarios effc-env-a -o out/cmp2", "one planner against itself, retuned"),
    ),
    "reproduce": (
        ("hybridnav reproduce --list", "the papers' protocols"),
        ("hybridnav reproduce effc-table3 -o out/effc-table3 --workers 2",
         "a table of a paper, both profiles, beside the paper's numbers"),
    ),
    "fis": (
        ("hybridnav fis effc-5rule -o out/fis", "describe a system, draw its terms and surface"),
        ("hybridnav fis my_system.fll", "a fuzzylite file"),
        ("hybridnav fis effc-5rule -o out/fis --format pdf", "the figures as PDF, for a paper"),
    ),
    "tune": (
        ("hybridnav tune -o out/tune --workers 2", "the built-in EFFC job"),
        ("hybridnav tune --quick -o out/quick", "a small smoke run"),
        ("hybridnav tune job.toml -o out/job --resume", "a job file, continuing a checkpoint"),
    ),
    "export": (
        ("hybridnav export out/tune/fis.json --format c -o build/effc", "build/effc.h and .c"),
        ("hybridnav export effc-5rule --format fll", "fuzzylite's language"),
    ),
    "generate": (
        ("hybridnav generate --count 5 --seed 3 --set 'circles=[4,8]' -o worlds",
         "five solvable worlds as scenario files"),
    ),
    "models": (("hybridnav models", "every kinematic model and its parameters"),),
    "animate": (
        ("hybridnav run pso-ba-dynamic --planner pso-ba -o runs/psoba", "a run to watch"),
        ("hybridnav animate runs/psoba", "runs/psoba/animation.gif"),
        ("hybridnav animate runs/psoba --out psoba.mp4 --fps 20", "an MP4 (needs ffmpeg)"),
        ("hybridnav animate out/tune --world effc-env-b --out tuning.gif",
         "a tuning job's best system, generation by generation"),
    ),
    "completion": (
        ('eval "$(hybridnav completion bash)"', "completion in this bash session"),
        ("hybridnav completion zsh > ~/.zfunc/_hybridnav", "install it for zsh"),
    ),
}

#: the shells :func:`completion_script` writes for
SHELLS = ("bash", "zsh", "tcsh")


def epilog(command: str) -> str | None:
    """The examples of ``command`` (``""``: the top level) as help text.

    Parameters
    ----------
    command : str
        A key of :data:`EXAMPLES`.

    Returns
    -------
    str or None
        None when the command has no examples.
    """
    items = EXAMPLES.get(command)
    if not items:
        return None
    width = max(len(c) for c, _ in items)
    lines = ["examples:"]
    for cmd, what in items:
        if len(cmd) + len(what) + 4 > 100 or width > 60:
            lines += [f"  {cmd}", f"      {what}"]
        else:
            lines.append(f"  {cmd.ljust(width)}  # {what}")
    return "\n".join(lines)


_PREAMBLE = {
    "bash": """
_shtab_hybridnav_scenarios() {{
  compopt -o filenames 2>/dev/null
  compgen -W "{scenarios}" -- "$1"
  compgen -f -X '!*.toml' -- "$1"
  compgen -d -- "$1"
}}
_shtab_hybridnav_planners() {{
  compgen -W "{planners}" -- "$1"
}}
""",
    "zsh": """
_shtab_hybridnav_scenarios() {{
  _alternative 'scenarios:built-in scenario:({scenarios})' 'files:scenario file:_files -g "*.toml"'
}}
_shtab_hybridnav_planners() {{
  _values 'planner' {planners}
}}
""",
}


def _mark(parser: argparse.ArgumentParser) -> None:
    """Tell shtab what each argument takes: files, scenario names, planner names."""
    import shtab

    kinds = {"scenario": "scenarios", "planner": "planners"}
    files = {"job", "fis", "c_file", "result", "out", "output", "readme", "reports", "scenarios"}
    for action in parser._actions:                       # noqa: SLF001 - argparse has no API
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for sub in action.choices.values():
                _mark(sub)
            continue
        if action.choices is not None:
            continue
        if action.dest in kinds:
            name = kinds[action.dest]
            action.complete = {"bash": f"_shtab_hybridnav_{name}",
                               "zsh": f"_shtab_hybridnav_{name}"}
        elif action.dest in files:
            action.complete = shtab.DIRECTORY if action.metavar == "DIR" else shtab.FILE


def completion_script(shell: str, parser: argparse.ArgumentParser) -> str:
    """A completion script for ``shell``, generated from the ``hybridnav`` parser.

    Parameters
    ----------
    shell : {"bash", "zsh", "tcsh"}
    parser : argparse.ArgumentParser
        :func:`hybridnav.cli.build_parser` ``()`` (marked with what each argument takes; build a
        new one for other uses).

    Returns
    -------
    str
        The script: ``eval "$(hybridnav completion bash)"`` loads it into bash; zsh takes it as a
        ``_hybridnav`` file on ``fpath``.

    Raises
    ------
    HybridnavError
        An unknown shell.
    """
    import shtab

    from hybridnav.errors import HybridnavError
    from hybridnav.planners import PLANNERS
    from hybridnav.world import list_scenarios

    if shell not in SHELLS:
        raise HybridnavError(f"completion: shell: expected one of {', '.join(SHELLS)}, got {shell!r}")
    _mark(parser)
    names = {"scenarios": " ".join(sorted(n for n, _ in list_scenarios())),
             "planners": " ".join(sorted(PLANNERS))}
    preamble = _PREAMBLE.get(shell, "").format(**names) or None
    return shtab.complete(parser, shell=shell, preamble=preamble)
