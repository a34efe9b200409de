"""The command's help: examples that parse, help text on every argument, shell completion that
completes what the installed version has."""

from __future__ import annotations

import argparse
import shlex
import shutil
import subprocess

import pytest

from hybridnav.cli import build_parser, main
from hybridnav.cli_help import EXAMPLES, SHELLS, completion_script
from hybridnav.errors import HybridnavError


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_command_has_examples_and_every_example_parses():
    commands = _commands()
    assert set(EXAMPLES) == {""} | set(commands)
    parser = build_parser()
    checked = 0
    for command, items in EXAMPLES.items():
        assert items, command
        for line, what in items:
            assert what and line.startswith(("hybridnav", "eval")), line
            if "COMMAND" in line or line.startswith("eval"):
                continue
            words = shlex.split(line.split(" > ")[0])[1:]
            assert not command or command in words[:1] or words[0] in commands, line
            parser.parse_args(words)                  # exits (SystemExit) when it does not parse
            checked += 1
    assert checked >= 20


def test_every_argument_has_help_text():
    missing = []
    for name, p in _commands().items():
        assert p.description or p.epilog, name
        for action in p._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            if not (action.help or "").strip():
                missing.append(f"{name}: {'/'.join(action.option_strings) or action.dest}")
    assert not missing, missing


def test_help_shows_the_examples(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["tune", "--help"])
    assert exit_.value.code == 0
    out = capsys.readouterr().out
    assert "examples:\n  hybridnav tune -o out/tune --workers 2" in out


def _complete(script: str, words: list[str]) -> list[str]:
    """What bash completes for ``words`` (the last one being typed) with ``script`` loaded."""
    line = " ".join(words)
    program = (f"source {shlex.quote(script)}\n"
               f"COMP_WORDS=({' '.join(shlex.quote(w) for w in words)})\n"
               f"COMP_CWORD={len(words) - 1}\nCOMP_LINE={shlex.quote(line)}\n"
               f"COMP_POINT={len(line)}\n"
               f"_shtab_hybridnav hybridnav {shlex.quote(words[-1])} {shlex.quote(words[-2])}\n"
               'printf "%s\\n" "${COMPREPLY[@]}"\n')
    out = subprocess.run(["bash", "-c", program], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return [w for w in out.stdout.splitlines() if w]


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_bash_completion_completes_commands_options_scenarios_and_planners(tmp_path):
    script = tmp_path / "hybridnav.bash"
    script.write_text(completion_script("bash", build_parser()))
    assert _complete(str(script), ["hybridnav", "ge"]) == ["generate"]
    assert set(_complete(str(script), ["hybridnav", "run", "effc-env"])) == {"effc-env-a", "effc-env-b"}
    # a scenario file in a folder with a space: escaped and completed as a path (cwd = tmp_path)
    (tmp_path / "my worlds").mkdir()
    (tmp_path / "my worlds" / "a b.toml").write_text("")
    program = (f"cd {shlex.quote(str(tmp_path))}; source {shlex.quote(str(script))}; "
               "_shtab_hybridnav_scenarios 'my worlds/'")
    out = subprocess.run(["bash", "-c", program], capture_output=True, text=True, timeout=60)
    assert out.stdout.split("\n")[0] == "my worlds/a b.toml"
    assert set(_complete(str(script), ["hybridnav", "run", "x", "--planner", "fa"])) == {"fastep-kinematic"}
    assert "--workers" in _complete(str(script), ["hybridnav", "tune", "--w"])
    assert set(_complete(str(script), ["hybridnav", "export", "x", "--format", ""])) == \
        {"json", "fll", "fis", "fcl", "c"}


@pytest.mark.parametrize("shell", SHELLS)
def test_completion_scripts_for_each_shell(shell, capsys):
    assert main(["completion", shell]) == 0
    text = capsys.readouterr().out
    assert "hybridnav" in text and "effc-env-a" in text if shell != "tcsh" else "hybridnav" in text
    if shell == "bash" and shutil.which("bash"):
        assert subprocess.run(["bash", "-n"], input=text, text=True).returncode == 0
    if shell == "zsh" and shutil.which("zsh"):
        assert subprocess.run(["zsh", "-n"], input=text, text=True).returncode == 0


def test_an_unknown_shell_is_an_error(capsys):
    with pytest.raises(HybridnavError, match=r"^completion: shell: expected one of bash, zsh, tcsh, got 'fish'$"):
        completion_script("fish", build_parser())
    with pytest.raises(SystemExit) as exit_:
        main(["completion", "fish"])
    assert exit_.value.code == 2
    assert "invalid choice: 'fish'" in capsys.readouterr().err
