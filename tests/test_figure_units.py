"""Every figure of ``run``, ``compare``, ``fis``, ``analyze`` and ``tune`` read back as matplotlib
objects: labelled axes with units, labelled colour bars, legends of drawn artists only,
intervals inside their metric's range; and ``--format`` / ``--dpi`` on the files.

The expected units come from a table below that states the physics independently (time in s,
headings in rad, positions in the scenario's length unit) and is checked against the models'
and planners' declarations (``state_units``, ``fuzzy_units``, ``signal_units``); the labels are
then checked against the declarations, never against themselves.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import Collection, LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from hybridnav import HybridnavError, fuzzy, models, planners
from hybridnav.world import load_scenario

#: what each quantity is measured in, stated here (``length``: the scenario's unit)
PHYSICS = {"t": "s", "x": "length", "y": "length", "theta": "rad", "theta0": "rad",
           "theta1": "rad", "xi": "rad", "dtheta": "rad", "bearing": "rad", "turn": "rad",
           "alpha": "", "w": "", "xdot": "length/s", "ydot": "length/s", "speed": "length/s",
           "Re λ": "1/s", "Im λ": "1/s"}
#: labels deliberately without a unit: counts, scores and objectives with no physical unit
UNITLESS = re.compile(r"^(generation|iteration|step|scenario|best cost: the search's objective"
                      r"|fitness of the path point|V = L|log10 L|dV/dt$|[a-z_ ]+, minimized$"
                      r"|control effort)")
LABEL = re.compile(r"^(?P<head>.+?) \((?P<unit>[^()]+)\)$")


def declared_units() -> dict[str, str]:
    """The units the models and planners declare (every name the figures may show)."""
    out: dict[str, str] = {}
    for cls in models.MODELS.values():
        out.update(cls.state_units)
    for cls in planners.PLANNERS.values():
        out.update(getattr(cls, "fuzzy_units", {}))
    return out


def test_the_declarations_agree_with_the_physics():
    declared = declared_units()
    for cls in models.MODELS.values():
        assert set(cls.state_units) == set(cls.plant_state_names + cls.controller_state_names)
    for name, unit in declared.items():
        if name in PHYSICS:
            # fuzzy ranges are in metres where the scenario's length is meant
            assert unit == PHYSICS[name] or (PHYSICS[name] == "length" and unit == "m"), name
    for cls in planners.PLANNERS.values():
        for name, unit in getattr(cls, "signal_units", {}).items():
            assert name not in PHYSICS or unit == PHYSICS[name], (cls.name, name)


def expected(head: str, length: str | None) -> str | None:
    unit = PHYSICS.get(head)
    if unit is None:
        return None
    if unit == "":
        return "dimensionless"
    return unit.replace("length", length) if "length" in unit and length else unit


def drawn_labels(ax) -> set[str]:
    """Labels of the artists drawn in ``ax`` (visible, with data)."""
    out = set()
    for a in [*ax.get_children(), *ax.containers]:
        label = a.get_label() if hasattr(a, "get_label") else None
        if not isinstance(label, str) or not label or label.startswith("_"):
            continue
        if hasattr(a, "get_visible") and not a.get_visible():
            continue
        if isinstance(a, Line2D) and len(a.get_xdata()) == 0:
            continue
        if isinstance(a, Collection) and not (len(a.get_paths()) or len(a.get_offsets())):
            continue
        out.add(label)
    return out


def colorbars(fig: Figure):
    return [ax._colorbar for ax in fig.axes if getattr(ax, "_colorbar", None) is not None]


def check_figure(fig: Figure, length: str | None, where: str) -> None:
    """Labels, units, colour bars and legends of one figure."""
    bars = colorbars(fig)
    bar_axes = {id(cb.ax) for cb in bars}
    for cb in bars:
        label = cb.ax.get_ylabel() if cb.orientation == "vertical" else cb.ax.get_xlabel()
        assert label, f"{where}: a colour bar without a label"
        check_label(label, length, where)
    for ax in fig.axes:
        if id(ax) in bar_axes or not ax.get_visible():
            continue
        shows = any(isinstance(a, (Line2D, Collection, Patch)) for a in ax.get_children()
                    if a is not ax.patch and a.get_visible()
                    and not isinstance(a, type(ax.spines.get("left"))))
        if not shows:
            continue
        # panels sharing an x axis name it once (under the bottom panel)
        xlabel = ax.get_xlabel() or next(
            (s.get_xlabel() for s in ax.get_shared_x_axes().get_siblings(ax) if s.get_xlabel()),
            "")
        for label in (xlabel, ax.get_ylabel()):
            assert label, f"{where}: axes {ax.get_title()!r} has an empty axis label"
            check_label(label, length, where)
        legend = ax.get_legend()
        if legend is not None:
            texts = {t.get_text() for t in legend.get_texts()}
            missing = texts - drawn_labels(ax)
            assert not missing, f"{where}: legend lists what is not drawn: {missing}"
    for legend in fig.legends:
        texts = {t.get_text() for t in legend.get_texts()}
        every = set().union(*(drawn_labels(ax) for ax in fig.axes))
        assert texts <= every, f"{where}: figure legend lists what is not drawn"


def check_label(label: str, length: str | None, where: str) -> None:
    """A label with a unit carries the declared one; one without is deliberately unitless."""
    m = LABEL.match(label)
    head = m["head"] if m else label
    want = expected(head, length)
    if want is not None:
        assert m and m["unit"] == want, f"{where}: {label!r} should carry ({want})"
    elif m is None:
        assert UNITLESS.match(label), f"{where}: {label!r} has no unit and is not known unitless"


def check_intervals(fig: Figure, where: str) -> None:
    """Error bars and bands lie within their metric's range: rates in [0, 1], times, lengths
    and costs >= 0."""
    for ax in fig.axes:
        ylabel = ax.get_ylabel()
        rate = ylabel.startswith("success rate")
        nonneg = rate or re.search(r"\((s|m|cm|cells)\)$", ylabel) is not None \
            or ylabel.startswith("best cost")
        if not nonneg or ylabel.startswith("smallest clearance"):
            continue
        for col in ax.collections:
            if isinstance(col, LineCollection):          # error bars
                ys = np.concatenate([np.asarray(s)[:, 1] for s in col.get_segments()] or [[]])
            elif isinstance(col, PolyCollection):        # fill_between bands
                ys = np.concatenate([p.vertices[:, 1] for p in col.get_paths()] or [[]])
            else:
                continue
            ys = ys[np.isfinite(ys)]
            assert (ys >= 0).all(), f"{where}: an interval below 0 ({ylabel})"
            if rate:
                assert (ys <= 1).all(), f"{where}: a rate interval above 1"


@pytest.fixture
def captured(monkeypatch):
    """Every figure written (through save_figure or any other savefig), not drawn: the
    tests read the objects, and skipping the rendering keeps them quick."""
    seen: list[tuple[Figure, str]] = []

    def record(self, fname, *args, **kwargs):
        seen.append((self, str(fname)))
        Path(fname).write_bytes(b"")

    monkeypatch.setattr(Figure, "savefig", record)
    return seen


def test_run_figures(tmp_path):
    """``path.png`` and every diagnostic figure of the planners, on small settings."""
    from hybridnav.plotting import plot_result

    cases = [("apf", "effc-train-1", {}), ("effc", "effc-train-1", {}),
             ("fuzzy-steer", "effc-train-1", {}), ("hapf", "effc-train-1", {}),
             ("pbpf", "effc-train-1", {"population": 3, "generations": 1}),
             ("pso", "fastep-s3", {"iterations": 5, "particles": 5}),
             ("rfd-pso", "fastep-s3", {"iterations": 3, "particles": 4}),
             ("fastep-kinematic", "fastep-s3", {})]
    drawn = set()
    for name, scen, kw in cases:
        s = load_scenario(scen)
        planner = planners.get(name, **kw)
        result = planner.run(s, seed=1)
        figs = {"path.png": plot_result(s, result), **planner.diagnostics(s, result)}
        for fname, fig in figs.items():
            check_figure(fig, s.units, f"{name}: {fname}")
            drawn.add(fname)
        # the path's end carries its outcome, in the legend
        legend = {t.get_text() for t in figs["path.png"].axes[0].get_legend().get_texts()}
        assert {f"end: {r.outcome}" for r in result.robots} <= legend
        assert f"{result.robots[0].name}: {result.robots[0].outcome}, length " \
               f"{result.robots[0].path_length:.3g} {s.units}" in legend
    assert drawn == {"path.png", "signals.png", "harmonic_field.png", "pbpf_search.png",
                     "planned_paths.png", "waypoints.png"}


def test_pso_ba_figure():
    from hybridnav.world import scenario_from_dict

    s = scenario_from_dict({
        "name": "small", "dt": 0.1, "max_time": 60.0, "units": "m",
        "workspace": {"xmin": 0.0, "xmax": 10.0, "ymin": 0.0, "ymax": 10.0},
        "obstacles": [{"type": "rectangle", "min": [4.0, 3.0], "max": [5.0, 7.0]}],
        "robots": [{"name": "r", "model": "point_mass", "start": [1.0, 5.0], "goal": [9.0, 5.0],
                    "goal_radius": 0.3, "radius": 0.3}]})
    planner = planners.get("pso-ba", particles=5, pso_iterations=3, bats=5, bat_iterations=5)
    figs = planner.diagnostics(s, planner.run(s, seed=0))
    assert list(figs) == ["pso_ba.png"]
    check_figure(figs["pso_ba.png"], "m", "pso-ba")


def test_waypoints_figure_only_with_waypoints():
    """Without a planned step ``waypoints.png`` would repeat ``path.png``: it is not drawn."""
    import dataclasses

    s = load_scenario("fastep-s3")
    planner = planners.get("fastep-kinematic")
    result = planner.run(s, seed=1)
    assert "waypoints.png" in planner.diagnostics(s, result)
    none = {k: ({c: v[:0] for c, v in t.items()} if k.startswith("waypoints_") else t)
            for k, t in result.extras.items()}
    figs = planner.diagnostics(s, dataclasses.replace(result, extras=none))
    assert list(figs) == ["signals.png"]


@pytest.mark.parametrize("name", ["effc-2rule", "effc-safe", "steer-7rule"])
def test_fis_figures(name):
    from hybridnav.fuzzy import plots

    system = fuzzy.builtin(name)
    for fig in (plots.plot_memberships(system), plots.plot_surface(system, resolution=21)):
        check_figure(fig, None, name)
    mfs = plots.plot_memberships(system)
    # dtheta (rad) and the others as the planner declares them
    units = planners.fuzzy_units(system)
    assert set(units) >= set(system.input_names)
    for ax, v in zip(mfs.axes, [*system.inputs, system.output]):
        want = expected(v.name, "m") or ("dimensionless" if units.get(v.name) == "" else
                                         units.get(v.name))
        assert ax.get_xlabel() == f"{v.name} ({want})"


def test_compare_figures(tmp_path, captured):
    from hybridnav.experiments.compare import compare, write_comparison

    # apf reaches on the one, is stuck in the cup of the other: two outcome markers
    table, summary = compare(["apf", "pbpf@pbpf:population=3:generations=1"],
                             ["effc-train-1", "effc-env-a"], 2, seed=5)
    files = write_comparison(tmp_path, table, summary)
    assert len(captured) == sum(n.endswith(".png") for n in files)
    units = {"effc-train-1": "m", "effc-env-a": "m"}
    for fig, path in captured:
        scen = next((s for s in units if s in path), None)
        check_figure(fig, units.get(scen), path)
        check_intervals(fig, path)
    # run 0 of every planner ends in its outcome's marker
    for fig, path in captured:
        if "paths_" not in path:
            continue
        scen = next(s for s in units if s in path)
        ax = fig.axes[0]
        rows = table[(table.run == 0) & (table.scenario == scen)]
        marks = [ln for ln in ax.lines if ln.get_linestyle() == "None"
                 and ln.get_marker() in ("*", "X", "s", "D")
                 and ln.get_markersize() == 9]
        assert len(marks) == len(rows)
        legend = {t.get_text() for t in ax.get_legend().get_texts()}
        assert {f"end: {o}" for o in rows.outcome} <= legend


def test_analyze_figures(tmp_path, captured):
    """Every figure ``analyze`` writes for the point mass (vdot map, eigenvalues, basin, phase
    portrait, sweep, V(t))."""
    from hybridnav.analysis.report import analyze

    data = analyze("point_mass", out=tmp_path)
    assert len(captured) == len(data["plots"]) == 6
    length = load_scenario(models.MODELS["point_mass"].analysis_scenario).units
    for fig, path in captured:
        check_figure(fig, length, path)
    figs = {Path(p).name: f for f, p in captured}
    eig = next(f for n, f in figs.items() if "eigenvalues" in n)
    # the closed loop's double eigenvalue -alpha is marked as such
    assert "×2" in [t.get_text() for t in eig.axes[0].texts]
    vt = next(f for n, f in figs.items() if "V_time" in n)
    (bar,) = colorbars(vt)                    # a family of curves: a colour bar, no legend
    assert vt.axes[0].get_legend() is None and len(vt.axes[0].lines) > 1


@pytest.mark.long
def test_analysis_figures_of_the_other_models():
    """The slices of models with headings (their held states in rad) and the LbCS field, drawn
    directly on coarse grids (``analyze`` itself takes tens of seconds on these)."""
    import math

    from hybridnav.analysis.plots import plot_lbcs_field, plot_phase_portrait, plot_vdot_map

    for name in ("unicycle", "tractor_trailer"):
        s = load_scenario(models.MODELS[name].analysis_scenario)
        model = models.get(name, dt=s.dt, **s.robots[0].params)
        xmin, xmax, ymin, ymax = s.world.workspace
        region = {"x": (xmin, xmax), "y": (ymin, ymax),
                  **{k: (-math.pi, math.pi) for k in model.state_names[2:]}}
        target = s.robots[0].goal
        fixed = dict(model.analysis_slice)
        for fig in (plot_phase_portrait(model, target=target, region=region, fixed=fixed, n=11,
                                        length=s.units),
                    plot_vdot_map(model, target=target, region=region, fixed=fixed, n=21,
                                  length=s.units)):
            check_figure(fig, s.units, name)
            assert f"{model.state_names[2]} = 0 rad" in fig.axes[0].get_title()
    s = load_scenario("aco-local-minimum")
    lb = models.MODELS["lbcs"].from_scenario(s, s.robots[0].name)
    xmin, xmax, ymin, ymax = s.world.workspace
    fig = plot_lbcs_field(lb, target=s.robots[0].goal, region={"x": (xmin, xmax),
                                                               "y": (ymin, ymax)}, n=41,
                          length=s.units)
    check_figure(fig, s.units, "lbcs_field")


def test_tune_figures(tmp_path, captured):
    from test_tuner import SMALL

    from hybridnav.tuner.job import load_job
    from hybridnav.tuner.run import FIGURES, OUTPUT_FILES, run_job

    (tmp_path / "job.toml").write_text(SMALL.replace("budget = 60", "budget = 20"))
    result = run_job(load_job(tmp_path / "job.toml"), tmp_path / "o", fmt="svg")
    figures = [f for f in result.files if f.endswith(".svg")]
    assert len(captured) == len(figures) and not any(f.endswith(".png") for f in result.files)
    assert {f.split(".")[0] for f in figures} <= set(FIGURES)
    for f in (tmp_path / "o").iterdir():                # --force knows what it would remove
        assert f.is_dir() or f.name in OUTPUT_FILES, f.name
    # what 'hybridnav tune' lists is every file the job left, checkpoint.json and
    # evaluations.jsonl included (they were missing from its "wrote ..." line)
    left = sorted(p.relative_to(tmp_path / "o").as_posix()
                  for p in (tmp_path / "o").rglob("*") if p.is_file())
    assert sorted(result.files) == left and len(set(result.files)) == len(result.files)
    assert {"checkpoint.json", "evaluations.jsonl"} <= set(result.files)
    assert "coverage.svg" in (tmp_path / "o" / "report.md").read_text()
    for fig, path in captured:
        check_figure(fig, "m", path)
    conv = next(f for f, p in captured if "convergence" in p)
    texts = " ".join(t.get_text() for t in conv.axes[0].get_legend().get_texts())
    assert "not trained on" in texts


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


@pytest.mark.long
def test_format_and_dpi_on_the_command_line(tmp_path, capsys):
    from hybridnav.cli import main

    for fmt, magic in (("svg", b"<?xml"), ("pdf", b"%PDF")):
        out = tmp_path / fmt
        assert main(["fis", "effc-2rule", "-o", str(out), "--format", fmt]) == 0
        assert sorted(p.name for p in out.iterdir()) == [f"mfs.{fmt}", f"surface.{fmt}"]
        assert f"wrote {out}/: mfs.{fmt}, surface.{fmt}" in capsys.readouterr().out
        for p in out.iterdir():
            assert p.read_bytes()[:len(magic)] == magic
    out = tmp_path / "run"
    assert main(["run", "effc-train-1", "--planner", "effc", "-o", str(out),
                 "--format", "svg"]) == 0
    listed = capsys.readouterr().out.splitlines()[-1]
    assert "path.svg" in listed and "signals.svg" in listed and ".png" not in listed
    assert (out / "path.svg").read_bytes()[:5] == b"<?xml" and not list(out.glob("*.png"))
    # 'plot' on the folder writes the requested format only, in place or elsewhere
    before = {p.name for p in out.iterdir()}
    assert main(["plot", str(out), "--format", "pdf"]) == 0
    assert capsys.readouterr().out == f"wrote {out}/: path.pdf, signals.pdf\n"
    assert {p.name for p in out.iterdir()} - before == {"path.pdf", "signals.pdf"}
    assert main(["plot", str(out), "--format", "svg", "-o", str(tmp_path / "again")]) == 0
    assert sorted(p.name for p in (tmp_path / "again").iterdir()) == ["path.svg", "signals.svg"]
    capsys.readouterr()
    # --dpi scales the pixels (surface.png: a constrained 6.4 x 5.2 inch figure)
    for dpi in (50, 120):
        assert main(["fis", "effc-2rule", "-o", str(tmp_path / f"d{dpi}"), "--dpi",
                     str(dpi)]) == 0
    w50, h50 = png_size(tmp_path / "d50" / "surface.png")
    w120, h120 = png_size(tmp_path / "d120" / "surface.png")
    assert (w50, h50) == (round(6.4 * 50), round(5.2 * 50))
    assert (w120, h120) == (round(6.4 * 120), round(5.2 * 120))


@pytest.mark.parametrize("argv, message", [
    (["fis", "effc-2rule", "-o", "{tmp}", "--format", "jpg"],
     "argument --format: expected one of png, pdf, svg, got 'jpg'"),
    (["fis", "effc-2rule", "-o", "{tmp}", "--dpi", "0"],
     "argument --dpi: expected an integer in [10, 1200] (dots per inch), got '0'"),
    # below 10 dpi FreeType raised RuntimeError (invalid ppem value) while drawing the text
    (["fis", "effc-2rule", "-o", "{tmp}", "--dpi", "5"],
     "argument --dpi: expected an integer in [10, 1200] (dots per inch), got '5'"),
    (["run", "effc-train-1", "--planner", "apf", "-o", "{tmp}", "--dpi", "1201"],
     "argument --dpi: expected an integer in [10, 1200] (dots per inch), got '1201'"),
    (["compare", "--planners", "apf", "--scenarios", "effc-train-1", "-o", "{tmp}",
      "--dpi", "2.5"], "argument --dpi: expected an integer in [10, 1200] (dots per inch)"),
])
def test_bad_format_or_dpi_is_one_line_and_status_2(argv, message, tmp_path, capsys):
    from hybridnav.cli import main

    with pytest.raises(SystemExit) as exc:
        main([a.format(tmp=tmp_path / "o") for a in argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"hybridnav: error: {message}")
    assert "Traceback" not in "".join(err) and not (tmp_path / "o").exists()


def test_the_python_api_checks_format_and_dpi(tmp_path):
    from hybridnav.analysis.report import analyze
    from hybridnav.plotting import check_dpi, check_format, figure_name, save_figure

    with pytest.raises(HybridnavError, match=r"^fmt: expected one of png, pdf, svg, got 'gif'$"):
        analyze("point_mass", out=tmp_path / "a", fmt="gif")
    with pytest.raises(HybridnavError, match=r"^dpi: expected an integer in \[10, 1200\]"):
        analyze("point_mass", out=tmp_path / "a", dpi=0)
    assert not (tmp_path / "a").exists()
    for bad in (0, -3, 1, 9, 1201, 2.5, True, "120"):
        with pytest.raises(HybridnavError, match="^dpi: expected an integer"):
            check_dpi(bad)
    assert check_dpi(10) == 10 and check_dpi(1200) == 1200
    assert check_format(".SVG") == "svg" and figure_name("signals.png", "pdf") == "signals.pdf"
    with pytest.raises(HybridnavError, match="^format: expected one of png, pdf, svg"):
        check_format("eps")
    with pytest.raises(HybridnavError, match="^dpi: expected an integer"):
        save_figure(Figure(), tmp_path / "x.png", dpi=5000)
