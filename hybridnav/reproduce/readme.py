"""README sections generated from stored reproductions, so that no number in them is copied
by hand.

A full run of ``hybridnav reproduce NAME`` kept under ``docs/reproductions/NAME/`` (its
``summary.csv`` and ``comparison.json``) is what README's section on that protocol shows: the
text between ``<!-- reproduce:NAME -->`` and ``<!-- /reproduce:NAME -->`` is :func:`render` of
that folder, and ``hybridnav reproduce --update-readme`` rewrites every such block (and each
stored ``report.md``, so that the two agree). A test
renders each block again from the stored files and compares it with README.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text, read_text_file
from hybridnav.params import Param, short_repr
from hybridnav.reproduce.checks import check_shown, read_stored_csv, read_stored_json
from hybridnav.reproduce.protocols import PROTOCOLS, STORE

__all__ = ["STORE", "blocks", "check_shown", "load_layouts", "load_stored", "render", "rewrite_report",
           "update_readme"]


_BLOCK = re.compile(r"<!-- reproduce:(?P<name>[\w-]+) -->\r?\n(?P<body>.*?)"
                    r"<!-- /reproduce:(?P=name) -->", re.S)
_OPEN = re.compile(r"<!-- reproduce:([\w-]+) -->")

#: the keys of a stored run's comparison.json that the README and the report read
_STORED = {"version": Param("", "package version", pattern=r"[\w.+-]{1,64}",
                           expected="a version number"), "runs": Param(1, "runs", lo=1),
           "seed": Param(0, "base seed"), "elapsed_s": Param(0.0, "wall time (s)", lo=0.0),
           "scenarios": Param([], "the protocol's scenarios"),
           "layout_runs": Param(0, "runs per planner and perturbed layout", lo=0)}
_OPTIONAL = ("elapsed_s", "layout_runs")


def load_stored(folder: str | Path) -> tuple[str, pd.DataFrame, dict]:
    """``(protocol name, summary, settings)`` of a stored reproduction.

    Raises
    ------
    HybridnavError
        A missing or unreadable ``summary.csv``/``comparison.json``, a protocol that no longer
        exists, a bad key, or scenarios other than the protocol's rows now (naming the file and
        key).
    """
    folder = Path(folder)
    meta_path = folder / "comparison.json"
    meta = read_stored_json(meta_path, "the comparison.json of a reproduction")
    name = meta.get("protocol")
    if not isinstance(name, str) or name not in PROTOCOLS:
        raise HybridnavError(f"{meta_path}: protocol: expected one of "
                             f"{', '.join(sorted(PROTOCOLS))}, got {short_repr(name)}")
    for key, param in _STORED.items():
        if key in meta or key not in _OPTIONAL:
            meta[key] = param.check(key, meta.get(key), f"{meta_path}: ")
    check_shown(meta_path, meta)
    rows = [row.scenario for row in PROTOCOLS[name].rows]
    if meta["scenarios"] != rows:
        raise HybridnavError(f"{meta_path}: scenarios: expected the protocol's "
                             f"{', '.join(rows)} (run it again), got "
                             f"{', '.join(map(str, meta['scenarios']))}")
    path = folder / "summary.csv"
    summary = read_stored_csv(path, "summary", "the summary of a reproduction")
    return name, _check_summary(path, summary, PROTOCOLS[name]), meta




_VERDICTS = {"True": True, "False": False, "": None}
_LAYOUT_COLUMNS = ("claim", "text", "row", "scenario", "layout", "view", "verdict", "detail")


def load_layouts(folder: str | Path, protocol) -> pd.DataFrame | None:
    """The stored layout-sensitivity verdicts of a reproduction (``layouts.csv``; None where
    the run has none), checked against the protocol.

    Raises
    ------
    HybridnavError
        A missing column, a claim index or row the protocol does not have, a view or verdict
        that is not one of the known words (naming the file, column and row).
    """
    path = Path(folder) / "layouts.csv"
    if not path.exists():
        return None
    table = read_stored_csv(path, "layouts", "the layout verdicts of a reproduction",
                            text_cells=True)
    for col in _LAYOUT_COLUMNS:
        if col not in table.columns:
            raise HybridnavError(f"{path}: {col}: missing column (expected "
                                 f"{', '.join(_LAYOUT_COLUMNS)})")
    labels = {row.label for row in protocol.rows}
    claims = {str(i) for i in range(len(protocol.claims))}
    checks = (("claim", claims, "a claim index of the protocol"),
              ("row", labels, "a row label of the protocol"),
              ("view", {"paper profile", "hybridnav profile"}, "a profile view"),
              ("verdict", set(_VERDICTS), "True, False or empty"))
    for col, allowed, what in checks:
        bad = ~table[col].isin(allowed)
        if bad.any():
            i = int(bad.to_numpy().nonzero()[0][0])
            raise HybridnavError(f"{path}: {col}: expected {what}, got "
                                 f"{short_repr(table[col].iloc[i])} in row {i + 2}")
    from hybridnav.reproduce.layouts import LAYOUT_TAG

    scenario_of = {row.label: row.scenario for row in protocol.rows}
    seen: set[tuple[str, ...]] = set()
    for i, r in enumerate(table.itertuples(index=False)):
        where = f"in row {i + 2}"
        if not LAYOUT_TAG.fullmatch(r.layout):
            raise HybridnavError(f"{path}: layout: expected mirror-x, mirror-y, start+, start- "
                                 f"or jitter-<k>, got {short_repr(r.layout)} {where}")
        if r.scenario != scenario_of[r.row]:
            raise HybridnavError(f"{path}: scenario: expected {scenario_of[r.row]} (the scenario "
                                 f"of row {r.row!r}), got {short_repr(r.scenario)} {where}")
        claim = protocol.claims[int(r.claim)]
        if claim.rows and r.row not in claim.rows:
            raise HybridnavError(f"{path}: row: expected a row of claim {r.claim} "
                                 f"({', '.join(claim.rows)}), got {short_repr(r.row)} {where}")
        key = (r.claim, r.row, r.layout, r.view)
        if key in seen:                     # counted twice, the share of layouts would be off
            raise HybridnavError(f"{path}: layout: expected one verdict per claim, row, layout "
                                 f"and view, got {r.layout!r} of claim {r.claim}, {r.row!r}, "
                                 f"{r.view!r} again {where}")
        seen.add(key)
    table["claim"] = table["claim"].astype(int)
    table["verdict"] = table["verdict"].map(_VERDICTS).astype(object)
    return table


#: the metric columns the README block and the report read (``summarize_runs`` writes them all)
_READ_COLUMNS = ("units", "collided", "stuck", "timeout", "out_of_bounds", "path_length_mean", "time_to_goal_mean", "path_length_median",
                 "path_length_ci95_lo", "path_length_ci95_hi", "best_path_length",
                 "best_time_to_goal", "min_clearance_min", "min_clearance_mean")

#: outcome counts of a stored summary (robots x runs; ``robot_contacts`` where recorded)
_COUNT_COLUMNS = ("collided", "stuck", "timeout", "out_of_bounds", "robot_contacts")

#: a stored summary's length unit (text the README shows: no markup)
_UNITS = re.compile(r"[^\W\d_]{0,16}")

#: Columns of a stored summary that hold text; every other column holds numbers (or is empty)
_TEXT_COLUMNS = ("planner", "scenario", "units")


def _check_summary(path: Path, summary: pd.DataFrame, protocol) -> pd.DataFrame:
    """A stored ``summary.csv`` as :func:`hybridnav.experiments.compare.summarize` writes it: the
    key columns, numbers where numbers belong, a row for every scenario of the protocol."""
    need = ("planner", "scenario", "robots", "success_rate")
    for col in need + _READ_COLUMNS + (("min_robot_clearance_mean",)
                                       if "min_robot_clearance_min" in summary.columns else ()):
        if col not in summary.columns:
            raise HybridnavError(f"{path}: {col}: missing column (expected the columns "
                                 f"{', '.join(need)} and the metrics of a reproduction's "
                                 "summary)")
    if summary.empty:
        raise HybridnavError(f"{path}: expected a row per planner and scenario, got only the "
                             "header")
    for col in summary.columns:
        if col in _TEXT_COLUMNS:
            values = summary[col]
            if col != "units" and values.isna().any():
                raise HybridnavError(f"{path}: {col}: expected a name in every row, got an "
                                     f"empty cell in row {int(values.isna().argmax()) + 2}")
            summary[col] = values.astype(str)
            continue
        try:
            numbers = pd.to_numeric(summary[col], errors="coerce")
        except OverflowError:                  # an integer beyond any float (pandas raises)
            raise HybridnavError(f"{path}: {col}: expected numbers, got an integer beyond the "
                                 "float range") from None
        bad = numbers.isna() & summary[col].notna()
        if bad.any():
            row = int(bad.argmax())
            raise HybridnavError(f"{path}: {col}: expected numbers, got "
                                 f"{short_repr(summary[col].iloc[row])} in row {row + 2}")
        summary[col] = numbers.astype(float)
    rate = summary["success_rate"]
    if not rate.between(0.0, 1.0).all():
        row = int((~rate.between(0.0, 1.0)).argmax())
        raise HybridnavError(f"{path}: success_rate: expected a share in [0, 1], got "
                             f"{short_repr(float(rate.iloc[row]))} in row {row + 2}")
    robots = summary["robots"]
    if not (np.isfinite(robots) & (robots >= 0) & (robots == np.round(robots))).all():
        row = int((~(np.isfinite(robots) & (robots >= 0) & (robots == np.round(robots))))
                  .argmax())
        raise HybridnavError(f"{path}: robots: expected a count, got "
                             f"{short_repr(float(robots.iloc[row]))} in row {row + 2}")
    for col in _COUNT_COLUMNS:               # outcome counts: of the row's robots
        if col not in summary.columns:
            continue
        v = summary[col]
        ok = np.isfinite(v) & (v >= 0) & (v == np.round(v)) & (v <= robots)
        if not ok.all():
            row = int((~ok).argmax())
            raise HybridnavError(f"{path}: {col}: expected a count of at most the row's robots "
                                 f"({int(robots.iloc[row])}), got "
                                 f"{short_repr(float(v.iloc[row]))} in row {row + 2}")
    from hybridnav.reproduce.variants import variants

    labels = [label for label, _, _ in variants(protocol)]
    for col, ok, what in (
            ("planner", lambda v: v in labels,
             f"one of the protocol's variants ({', '.join(labels)})"),
            ("units", lambda v: v != v or v == "nan" or (
                isinstance(v, str) and _UNITS.fullmatch(v) is not None),
             "a length unit (letters, at most 16)")):
        bad = ~summary[col].map(ok)
        if bad.any():
            row = int(bad.argmax())
            raise HybridnavError(f"{path}: {col}: expected {what}, got "
                                 f"{short_repr(summary[col].iloc[row])} in row {row + 2}")
    missing = [r.scenario for r in protocol.rows if r.scenario not in set(summary["scenario"])]
    if missing:
        raise HybridnavError(f"{path}: scenario: expected rows for the protocol's "
                             f"{', '.join(missing)} (run it again)")
    return summary


def _stored_layouts(folder: Path, protocol, meta: dict) -> pd.DataFrame | None:
    """:func:`load_layouts`, with the runs per layout its table states: a stored run with
    layout verdicts has ``layout_runs >= 1`` in its ``comparison.json``."""
    table = load_layouts(folder, protocol)
    if table is not None and not meta.get("layout_runs", 0) >= 1:
        raise HybridnavError(f"{Path(folder) / 'comparison.json'}: layout_runs: expected the "
                             "runs per planner and layout (at least 1) beside layouts.csv, got "
                             f"{short_repr(meta.get('layout_runs'))}")
    return table


def render(folder: str | Path) -> str:
    """The README block of the stored reproduction in ``folder``: how it was run, the paper's
    numbers beside ours per profile, and the paper's claims checked (as in its ``report.md``).
    """
    from hybridnav.reproduce.report import (check_claims, claims_section, conflicts_section,
                                            sensitivity_section,
                                            extremes_section, has_profiles, literature_line,
                                            profile_sections, safety_section,
                                            separation_section, variants_section)
    from hybridnav.reproduce.variants import levels

    name, summary, meta = load_stored(folder)
    protocol = PROTOCOLS[name]
    how = (f"Measured by `hybridnav reproduce {name}` with hybridnav {meta['version']}: "
           f"{meta['runs']} run(s) per planner and scenario (the paper: {protocol.paper_runs or protocol.runs}), "
           f"seed {meta['seed']}")
    if meta.get("elapsed_s") is not None:
        how += (f", {meta['elapsed_s'] / 60:.1f} min with {meta.get('workers', 1)} worker(s) "
                f"(load {meta.get('load', '?')})")
    how += (f". The whole report, with every variant, the bounds of our layouts and the "
            f"figures: [`{STORE.as_posix()}/{name}/report.md`]({STORE.as_posix()}/{name}/"
            "report.md).")
    lines = [how, ""]
    lines += conflicts_section(protocol, level=4)
    lines += safety_section(protocol, summary, level=4)
    lines += profile_sections(protocol, summary, level=4)
    lines += extremes_section(protocol, summary, level=4)
    lines += separation_section(protocol, summary, level=4)
    if protocol.ablations:
        lines += variants_section(protocol, summary, level=4,
                                  only=[lb for label, _, _ in protocol.ablations
                                        for _, lb in levels(protocol, label, label)])
    lines += literature_line(protocol)
    lines += claims_section(check_claims(protocol, summary), level=4,
                            profiles=has_profiles(protocol))
    lines += sensitivity_section(protocol, _stored_layouts(folder, protocol, meta), summary,
                                 runs=meta.get("layout_runs", 0), level=4,
                                 profiles=has_profiles(protocol))
    return "\n".join(lines)


def rewrite_report(folder: str | Path) -> Path:
    """Write the ``report.md`` of a stored reproduction again from its ``summary.csv`` and
    ``comparison.json`` (after a change to how reports are written or claims are checked, no
    run is needed); returns its path."""
    from hybridnav.reproduce.report import check_claims, write_report

    folder = Path(folder)
    name, summary, meta = load_stored(folder)
    protocol = PROTOCOLS[name]
    write_report(folder / "report.md", protocol, summary, check_claims(protocol, summary),
                 runs=meta["runs"], seed=meta["seed"], version=meta["version"],
                 files=[f.name for f in folder.iterdir()],
                 layouts=_stored_layouts(folder, protocol, meta),
                 layout_runs=meta.get("layout_runs", 0))
    return folder / "report.md"


def blocks(text: str, source: str = "README") -> dict[str, str]:
    """The reproduce blocks of a README: ``{protocol name: body}``.

    Raises
    ------
    HybridnavError
        An opening marker without its closing one, or a protocol's block twice.
    """
    found = [(m["name"], m["body"]) for m in _BLOCK.finditer(text)]
    names = [n for n, _ in found]
    opened = _OPEN.findall(text)
    if sorted(opened) != sorted(names):
        bad = next(n for n in opened if opened.count(n) != names.count(n))
        raise HybridnavError(f"{source}: reproduce:{bad}: expected one block closed by "
                             f"<!-- /reproduce:{bad} -->")
    if len(set(names)) != len(names):
        bad = next(n for n in names if names.count(n) > 1)
        raise HybridnavError(f"{source}: reproduce:{bad}: expected one block, found "
                             f"{names.count(bad)}")
    return dict(found)


def update_readme(readme: str | Path, store: str | Path) -> list[str]:
    """Rewrite every reproduce block of ``readme`` from ``store/NAME`` (and that run's
    ``report.md``, with :func:`rewrite_report`); returns the names.

    Raises
    ------
    HybridnavError
        A block whose protocol has no stored run (naming the folder), or no block at all.
    """
    readme = Path(readme)
    text = read_text_file(readme, "README")
    found = blocks(text, str(readme))
    if not found:
        raise HybridnavError(f"{readme}: expected <!-- reproduce:NAME --> blocks, found none")
    from hybridnav.reproduce.tuning import (EXPERIMENTS, load_experiment, render_experiment,
                                            rewrite_experiment_report)

    for name in found:                       # every stored run checked before anything is written
        need = "experiment.json" if name in EXPERIMENTS else "summary.csv"
        if not (Path(store) / name / need).exists():
            raise HybridnavError(f"{Path(store) / name}: {need}: expected a stored run of "
                                 f"`hybridnav reproduce {name}` for README's block")
        stored = (load_experiment(Path(store) / name)[0].name if name in EXPERIMENTS
                  else load_stored(Path(store) / name)[0])
        if stored != name:                   # another target's run in this block's folder
            key = "experiment.json: experiment" if name in EXPERIMENTS else \
                "comparison.json: protocol"
            raise HybridnavError(f"{Path(store) / name}/{key}: expected {name} (README's "
                                 f"block), got {stored}")

    for name in found:
        (rewrite_experiment_report if name in EXPERIMENTS else rewrite_report)(
            Path(store) / name)

    def sub(m: re.Match) -> str:
        body = (render_experiment if m["name"] in EXPERIMENTS else render)(
            Path(store) / m["name"])
        return f"<!-- reproduce:{m['name']} -->\n{body}\n<!-- /reproduce:{m['name']} -->"

    atomic_write_text(readme, _BLOCK.sub(sub, text))
    return list(found)
