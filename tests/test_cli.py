"""The hybridnav command: listing, drawing, and clean errors (exit 2, no traceback)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from hybridnav import __version__
from hybridnav.cli import main
from hybridnav.world import list_scenarios


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hybridnav.cli", *args], capture_output=True,
                          text=True, timeout=120)


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"hybridnav {__version__}"


def test_scenarios_lists_every_builtin_with_its_description(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out.splitlines()
    names = [name for name, _ in list_scenarios()]
    assert [line.split()[0] for line in out] == names
    for expected in ("fastep-s1", "fastep-s2", "fastep-s3", "aco-three-robots", "aco-local-minimum",
                     "tractor-trailer-1", "tractor-trailer-3", "effc-train-1", "effc-train-2",
                     "effc-env-a", "effc-env-b", "rfd-pso-700", "pso-ba-dynamic", "arena",
                     "turtlebot-office"):
        assert expected in names


@pytest.mark.parametrize("scenario", ["fastep-s3", "tractor-trailer-3", "pso-ba-dynamic", "arena"])
def test_show_writes_a_png(tmp_path, capsys, scenario):
    out = tmp_path / "pics" / f"{scenario}.png"
    assert main(["show", scenario, "-o", str(out)]) == 0
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    assert scenario in capsys.readouterr().out
    assert [p.name for p in out.parent.iterdir()] == [out.name]   # no temporary files left


def test_models_lists_parameters(capsys):
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    for text in ("point_mass:", "tractor_trailer:", "unicycle:", "alpha1 = 0.1", "xi_law = 'filter'"):
        assert text in out


def test_unknown_scenario_exits_2_without_traceback():
    proc = run("show", "no-such-scenario", "-o", "x.png")
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.startswith("hybridnav: error: ")
    assert "no-such-scenario" in proc.stderr


def test_bad_scenario_file_names_file_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        'name = "bad"\ndt = 0.1\nmax_time = 10.0\n'
        "[workspace]\nxmin = 0.0\nxmax = 10.0\nymin = 0.0\nymax = 10.0\n"
        '[[robots]]\nname = "R1"\nmodel = "point_mass"\nstart = [1.0, 1.0]\ngoal = [20.0, 5.0]\n'
    )
    proc = run("show", str(bad), "-o", str(tmp_path / "bad.png"))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "bad.toml" in proc.stderr and "robots[0].goal" in proc.stderr
    assert not (tmp_path / "bad.png").exists()


def test_analyze_with_a_bad_scenario_exits_2(tmp_path):
    proc = run("analyze", "lbcs", "--scenario", "fastep-s3", "--out", str(tmp_path / "a"))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "fastep-s3.toml: obstacles[0]: the LbCS model takes circle obstacles only" in proc.stderr


def test_export_every_format_and_back(tmp_path, capsys):
    src = tmp_path / "sys.json"
    assert main(["export", "effc-5rule", "--format", "json", "-o", str(src)]) == 0
    for fmt in ("fll", "fis", "fcl"):
        out = tmp_path / f"sys.{fmt}"
        assert main(["export", str(src), "--format", fmt, "-o", str(out)]) == 0
        assert out.read_text().strip()
    assert main(["export", str(src), "--format", "c", "-o", str(tmp_path / "c" / "effc")]) == 0
    assert (tmp_path / "c" / "effc.h").exists() and (tmp_path / "c" / "effc.c").exists()
    back = tmp_path / "back.json"
    assert main(["export", str(tmp_path / "sys.fll"), "--format", "json", "-o", str(back)]) == 0
    import json as _json
    a, b = _json.loads(back.read_text()), _json.loads(src.read_text())
    assert a["inputs"] == b["inputs"] and a["output"] == b["output"]


def test_export_bad_file_exits_2(tmp_path):
    bad = tmp_path / "bad.fis"
    bad.write_text("[System]\nName='x'\nType='sugeno'\n")
    proc = run("export", str(bad), "--format", "json")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and "bad.fis" in proc.stderr


def test_plot_redraws_the_diagnostics_from_a_result_folder(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["run", "effc-train-1", "--planner", "hapf", "--out", str(run)]) == 0
    drawn = sorted(p.name for p in run.glob("*.png"))
    assert drawn == ["harmonic_field.png", "path.png"]
    # the extras the figures are drawn from are files beside result.json
    names = [p.name for p in run.iterdir()]
    assert any(n.startswith("harmonic_potential_") and n.endswith(".npy") for n in names)
    assert any(n.startswith("harmonic_grid_") and n.endswith(".csv") for n in names)
    capsys.readouterr()
    assert main(["plot", str(run), "--out", str(tmp_path / "again")]) == 0
    assert sorted(p.name for p in (tmp_path / "again").glob("*.png")) == drawn
    assert "wrote" in capsys.readouterr().out
    assert main(["plot", str(run), "--scenario", "effc-train-2"]) == 2
    assert "is of scenario 'effc-train-1', not 'effc-train-2'" in capsys.readouterr().err
    assert main(["plot", str(tmp_path / "nothing")]) == 2
    assert "no such file" in capsys.readouterr().err
    # a file that shares the result's scenario name but not its robots' starts is refused
    from hybridnav.world import load_scenario, save_scenario, scenario_from_dict, scenario_to_dict

    d = scenario_to_dict(load_scenario("effc-train-1"))
    d["robots"][0]["start"] = [d["robots"][0]["start"][0] + 0.1, d["robots"][0]["start"][1]]
    other = tmp_path / "same-name.toml"
    save_scenario(scenario_from_dict(d), other)
    assert main(["plot", str(run), "--scenario", str(other)]) == 2
    assert "do not start where the result's" in capsys.readouterr().err


def test_export_measures_the_formula_form_and_says_what_it_wrote(tmp_path, capsys):
    """effc-5rule's narrow Z/S split is not resolved by its 101 samples: the formula form would
    differ by 0.15 of the output range, so FLL gets the sampled terms unless --formula; .fis has
    no sampled form and leaves 11.2 % of the inputs to the engine's own default."""
    from hybridnav import fuzzy
    from hybridnav.fuzzy.export.fidelity import formula_difference, uncovered_fraction

    fs = fuzzy.builtin("effc-5rule")
    worst, _ = formula_difference(fs)
    assert worst > 0.1 and uncovered_fraction(fs) > 0.1
    assert main(["export", "effc-5rule", "--format", "fll", "-o", str(tmp_path / "a.fll")]) == 0
    err = capsys.readouterr().err
    assert "wrote the sampled terms instead" in err and "0.15 of the output range" in err
    assert "Discrete" in (tmp_path / "a.fll").read_text()
    assert main(["export", "effc-5rule", "--format", "fll", "--formula",
                 "-o", str(tmp_path / "b.fll")]) == 0
    assert "--sampled (FLL, FCL) writes the exact terms" in capsys.readouterr().err
    assert "Discrete" not in (tmp_path / "b.fll").read_text()
    assert main(["export", "effc-5rule", "--format", "fis", "-o", str(tmp_path / "c.fis")]) == 0
    assert "no rule fires on 11.2% of the input ranges" in capsys.readouterr().err
    assert main(["export", "effc-tuned", "--format", "fll", "-o", str(tmp_path / "d.fll")]) == 0
    assert "agrees with hybridnav's evaluate within" in capsys.readouterr().err
    assert main(["export", "effc-5rule", "--format", "fll", "--formula", "--sampled"]) == 2


def test_planners_lists_what_the_paper_profiles_still_do_differently(capsys):
    from hybridnav.cli import main

    assert main(["planners"]) == 0
    out = "\n" + capsys.readouterr().out
    block = out.split("\naco-kinematic:")[1].split("\napf:")[0]
    assert "still different from the paper in profile 'paper':" in block
    for word in ("step switching", "feasibility", "stop rules", "xi_law"):
        assert word in block, word
    assert "search window" in out.split("\nfastep-kinematic:")[1].split("\nfuzzy-steer:")[0]
    assert "waypoints: K = 28" in out.split("\nrfd-pso:")[1]


def test_python_dash_m_runs_the_command():
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "hybridnav", "--help"], capture_output=True,
                         text=True, check=False)
    assert out.returncode == 0 and "usage: hybridnav" in out.stdout


def test_dask_without_the_extra_names_it(monkeypatch, capsys, tmp_path):
    """``--dask`` where Dask's distributed is not installed (an optional extra) fails with a
    message naming the extra, no traceback."""
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)       # import fails
    code = main(["compare", "--scenarios", "fastep-s1", "--planners", "apf", "--runs", "1",
                 "--dask", "tcp://127.0.0.1:8786", "-o", str(tmp_path / "c")])
    err = capsys.readouterr().err
    assert code == 2 and 'pip install "hybridnav[dask]"' in err and "Traceback" not in err


def test_progress_is_plain_lines_when_not_a_terminal():
    """In a log file the progress is whole lines (no carriage returns): one per tenth of the
    work and the last, with the postfix."""
    import io

    from hybridnav.progress import PlainProgress, bar

    buf = io.StringIO()
    b = bar(25, "gen", "tune x", file=buf)
    assert isinstance(b, PlainProgress)
    for i in range(25):
        b.set_postfix(gen=i)
        b.update(1)
    b.close()
    text = buf.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert 9 <= len(lines) <= 11 and lines[-1].startswith("tune x: 25/25 gen")
    assert lines[-1].endswith("gen=24")


def test_plain_progress_past_its_total_without_one_and_closed():
    """Past the total a line per tenth of it (was one per update: 200 lines for 300 of 100);
    without a total one at each doubling (was one per update); nothing after close() and the
    last count once, as tqdm; set_postfix takes tqdm's dict and refresh."""
    import io

    from hybridnav.progress import PlainProgress

    def lines(total, updates, close=2):
        buf = io.StringIO()
        p = PlainProgress(total, "run", "x", file=buf)
        for _ in range(updates):
            p.update()
        for _ in range(close):
            p.close()
        p.update(5)
        return buf.getvalue().splitlines()

    assert len(lines(100, 300)) == 31 and lines(100, 300)[-1].startswith("x: 300/100 run")
    assert [ln.split()[1] for ln in lines(0, 25)] == ["1", "2", "4", "8", "16", "25"]
    assert [ln.split()[1] for ln in lines(None, 5)] == ["1", "2", "4", "5"]
    assert lines(7, 0) == [] and len(lines(3, 3)) == 3
    buf = io.StringIO()
    p = PlainProgress(2, "gen", "t", file=buf)
    p.set_postfix({"best": 1}, refresh=False, gen=3)
    p.update(2)
    assert buf.getvalue().rstrip().endswith("; best=1, gen=3")


def test_phase_log_names_each_phase_and_its_time():
    """Plain lines in a log (a start line, an end line with the seconds); on a terminal one
    line per phase, rewritten with carriage returns as its clock ticks, ended by its time."""
    import io
    import re
    import time

    from hybridnav.progress import PhaseLog

    buf = io.StringIO()
    with PhaseLog(buf) as say:
        say("first")
        say("second")
    assert re.fullmatch(r"  first \.\.\.\n  first: \d+\.\d s\n  second \.\.\.\n  second: \d+\.\d s\n",
                        buf.getvalue()), buf.getvalue()
    assert [m for m, _ in say.done] == ["first", "second"]

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    term = Terminal()
    say = PhaseLog(term, interval=0.01)
    say("slow")
    time.sleep(0.1)
    say.close()
    say.close()                                          # once only
    text = term.getvalue()
    assert text.startswith("\r  slow ...") and text.count("\n") == 1 and text.endswith(" s\n")
    assert text.count("\r") >= 3                          # the clock ticked
    assert "slow ... " in text.rsplit("\r", 1)[1]


@pytest.mark.long
def test_analyze_names_its_phases_with_their_times(tmp_path, capsys):
    from hybridnav.cli import main

    assert main(["analyze", "point_mass", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "  Lyapunov check ..." and out[1].startswith("  Lyapunov check: ")
    assert any(line.startswith("  closed-loop sweep: ") and line.endswith(" s") for line in out)


def test_a_phase_left_by_an_error_or_ctrl_c_does_not_read_as_done():
    import io

    from hybridnav.progress import PhaseLog

    for error, word in ((RuntimeError("boom"), "failed"), (KeyboardInterrupt(), "interrupted")):
        buf = io.StringIO()
        with pytest.raises(type(error)):
            with PhaseLog(buf) as say:
                say("work")
                raise error
        assert buf.getvalue().splitlines()[-1].endswith(f" s ({word})"), buf.getvalue()
