"""``report.md`` of a reproduction: the paper's numbers beside ours, per profile, and its claims.

Our figures are means over the runs that reached the goal (the success count beside them). A
claim about two planners is judged row by row: in the paper's numbers as printed (one value per
method; one that never arrives is not shorter or faster); in ours it holds on a row only when
both planners reached in most of their runs and the two-sided Mann-Whitney U test of the reached
runs (``summary.csv``) gives p < :data:`ALPHA` with ``a`` ahead — the opposite with p < ALPHA
is "does not hold", so is ``a`` reaching in no run where ``b`` reaches, and anything else "not
shown". A ``faster`` claim uses the time its paper means (:attr:`Claim.time`: the simulated
travel time, or travel plus planning computation), and the report says which.

Two more kinds, judged without a significance test (see :data:`CLAIM_RULES`):

``collision-free`` (one planner, ``a``)
    In ours it holds on a row when every robot of every run reached its goal and none collided
    (``success_rate == 1``, ``collided == 0`` and ``robot_contacts == 0``: no robot's clearance
    to another robot, ``min_robot_clearance``, went below 0); anything else does not hold. The
    detail gives the closest two robots came (``min_robot_clearance_min``). In the paper's
    numbers it holds where the paper's value is an arrival (a figure showing the robots reach).
``worst-case`` (``a`` against ``b``)
    Each planner's worst run is its longest reached path, with that run's own simulated time
    (``worst_path_length``, ``worst_time_to_goal`` in ``summary.csv``), as papers pair "the
    worst-case path length and time". It holds on a row when ``a``'s worst run is both shorter
    and faster than ``b``'s; a run that did not reach is worse than any that did, so when only
    ``b`` has one it holds, when only ``a`` has one it does not, and when both have one it is
    not shown. In the paper's numbers ``a``'s worst run is :attr:`Row.extremes`, ``b``'s the
    same or, where the paper gives none (a planner it ran once), its printed value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.params import FIGURE_FORMATS
from hybridnav.reproduce.protocols import JITTER, Claim, Protocol, Row, Value
from hybridnav.reproduce.variants import label_for, levels

__all__ = ["ALPHA", "ASTAR_SLACK", "CLAIM_RULES", "MOST_REACHED", "astar_bound", "bounds_section",
           "check_claims", "claims_section", "conflicts_section", "extremes_section",
           "has_profiles", "impossible_lengths", "length_bounds", "literature_line", "ours",
           "profile_sections", "row_verdict", "sensitivity_section", "separation_section", "straight_line_bound",
           "variants_section", "write_report"]

VIEWS = ("paper", "paper profile", "hybridnav profile")


def ours(summary: pd.DataFrame, label: str, scenario: str) -> dict[str, Any] | None:
    """Our summary row of one variant on one scenario.

    Parameters
    ----------
    summary : DataFrame
        ``summarize_runs`` of the reproduction.
    label : str
        The variant's label.
    scenario : str
        The scenario's name.

    Returns
    -------
    dict or None
        The row (None if that variant did not run on that scenario).
    """
    sel = summary[(summary["planner"] == label) & (summary["scenario"] == scenario)]
    return None if sel.empty else sel.iloc[0].to_dict()


def straight_line_bound(scenario) -> float:
    """The shortest any path of the scenario's first robot can be: start to goal in a straight
    line, less the goal radius (reaching the goal disk ends the run)."""
    r = scenario.robots[0]
    return max(0.0, math.dist(r.start, r.goal) - r.goal_radius)


def astar_bound(scenario) -> float | None:
    """The shortened A* path of the scenario's first robot, less the goal radius: the shortest
    path our grid search finds with the robot's radius as clearance (no margin), pulled tight.
    Near the true shortest path of the layout, not a proof of it (None: A* finds no path, or
    the robot is not a disk the grid search plans for)."""
    from hybridnav import planners

    astar = planners.get("astar", shorten=True, margin=0.0)
    try:
        astar.check_scenario(scenario)
    except HybridnavError:
        return None                     # a grid path is a disk's: no bound for a trailer
    plan = astar.plans(scenario)[0]
    if not plan.found:
        return None
    return max(0.0, float(plan.length) - scenario.robots[0].goal_radius)


#: a paper length this much below our shortened A* path is flagged (the grid's own slack)
ASTAR_SLACK = 0.01


def length_bounds(protocol: Protocol) -> dict[str, tuple[float, float | None]]:
    """``{row label: (straight-line bound, shortened A* bound)}`` of every single-robot row."""
    from hybridnav.world import load_scenario

    out = {}
    for row in protocol.rows:
        scenario = load_scenario(row.scenario)
        if len(scenario.robots) == 1:
            out[row.label] = (straight_line_bound(scenario), astar_bound(scenario))
    return out


def impossible_lengths(protocol: Protocol, bounds: dict[str, tuple[float, float | None]]
                       | None = None) -> list[tuple[str, str, float, str, float]]:
    """The paper's lengths that our layout contradicts: ``(row, planner, paper length, what,
    bound)``, ``what`` being ``"straight line"`` where the length is below
    :func:`straight_line_bound` (no path can have it) or ``"A*"`` where it is more than
    :data:`ASTAR_SLACK` below :func:`astar_bound` (no path our search knows has it).

    Parameters
    ----------
    protocol : Protocol
    bounds : dict, optional
        :func:`length_bounds` of the protocol, if already computed.
    """
    bounds = length_bounds(protocol) if bounds is None else bounds
    out = []
    for row in protocol.rows:
        if row.label not in bounds:
            continue
        straight, astar = bounds[row.label]
        for planner, v in row.paper.items():
            if v.length is None:
                continue
            if v.length < straight:
                out.append((row.label, planner, v.length, "straight line", straight))
            elif astar is not None and v.length < (1 - ASTAR_SLACK) * astar:
                out.append((row.label, planner, v.length, "A*", astar))
    return out


def _label(protocol: Protocol, planner: str, view: str) -> str:
    return label_for(protocol, planner, "paper" if view == "paper profile" else "hybridnav")


def _levels(protocol: Protocol, planner: str, view: str) -> list[tuple[Any, str]]:
    """``(sweep value, label)`` of ``planner``'s variants in ``view`` (one, value None, unless
    the protocol sweeps a parameter the planner has)."""
    return levels(protocol, planner, _label(protocol, planner, view))


def _at_level(protocol: Protocol, planner: str, view: str, level: Any) -> str:
    """The label of ``planner``'s variant in ``view`` at sweep value ``level`` (its only one
    when it is not swept)."""
    return next(lb for v, lb in _levels(protocol, planner, view) if v is None or v == level)


def _where(protocol: Protocol, row: Row, level: Any) -> str:
    """A row's label, with the sweep value when there is one."""
    return row.label if level is None else f"{row.label}, {protocol.sweep[0]} = {level:g}"


def _rows(protocol: Protocol, claim: Claim) -> list[Row]:
    return [r for r in protocol.rows if not claim.rows or r.label in claim.rows]


def _metric(value: Value | dict[str, Any] | None, column: str) -> float | None:
    """A paper value's length or time, or the mean of ``column`` in one of our summary rows
    (None: none reached, or the summary has no such column)."""
    if value is None:
        return None
    if isinstance(value, Value):
        v = value.length if column == "path_length" else value.time
        return v if value.outcome == "reached" else None
    if not value["success_rate"] > 0:
        return None
    v = value.get(f"{column}_mean")
    return None if v is None or not math.isfinite(v) else float(v)


def _reached(value: Value | dict[str, Any] | None) -> float | None:
    """Share of reached runs (paper: 1 or 0 by its outcome)."""
    if value is None:
        return None
    if isinstance(value, Value):
        return 1.0 if value.outcome == "reached" else 0.0
    return float(value["success_rate"])


#: a claim about two planners holds in our runs only with this significance (two-sided
#: Mann-Whitney U test of the reached runs) and with both reaching in more than
#: :data:`MOST_REACHED` of their runs; otherwise it is "not shown"
ALPHA = 0.05
MOST_REACHED = 0.5


def _column(claim: Claim) -> str:
    """The summary metric a ``shorter`` / ``faster`` claim compares."""
    if claim.kind == "shorter":
        return "path_length"
    return "time_with_planning" if claim.time == "with planning" else "time_to_goal"


def row_verdict(protocol: Protocol, claim: Claim, summary: pd.DataFrame | None, view: str,
                row: Row, single: bool = False) -> tuple[bool | None, str]:
    """One row's verdict on a claim and the numbers it rests on (for a protocol with a
    :attr:`Protocol.sweep`, every swept value of ``a`` against ``b`` at the same value, or its
    only one: the row holds when every value holds and fails when one fails).

    Parameters
    ----------
    protocol : Protocol
    claim : Claim
    summary : DataFrame or None
        Our ``summarize_runs`` (unused, may be None, for the ``paper`` view).
    view : {"paper", "paper profile", "hybridnav profile"}
    row : Row
        A row of the claim; its ``scenario`` names the summary's rows (a perturbed layout's
        name in :mod:`hybridnav.reproduce.layouts`).

    single : bool
        Where both planners gave one result in every run (deterministic: the runs are copies,
        not samples, and a test on them would count one observation many times), judge the one
        comparison by its sign (a perturbed layout of :mod:`hybridnav.reproduce.layouts` is one
        observation) instead of "not shown".

    Returns
    -------
    (bool or None, str)
        holds / does not hold / not shown, and the detail (``<row>: <numbers>`` per value).
    """
    if view == "paper":
        cases = [(row.label, row.paper.get(claim.a), row.paper.get(claim.b), "")]
    else:                       # per sweep value of a (b at the same value, or its only one)
        levels_a = _levels(protocol, claim.a, view)
        levels_b = _levels(protocol, claim.b, view) if claim.b else [(None, "")]
        if levels_a[0][0] is None and levels_b[0][0] is not None:
            pairs = [(level, levels_a[0][1], lb) for level, lb in levels_b]   # only b swept
        else:
            pairs = [(level, la, _at_level(protocol, claim.b, view, level) if claim.b else "")
                     for level, la in levels_a]
        cases = []
        for level, la, lb in pairs:
            cases.append((_where(protocol, row, level), ours(summary, la, row.scenario),
                          ours(summary, lb, row.scenario) if claim.b else None, lb))
    verdicts, parts = [], []
    for where, va, vb, lb in cases:
        if claim.kind in ("shorter", "faster"):
            verdict, part = _compare_row(protocol, claim, view, va, vb, lb, single)
        elif claim.kind == "collision-free":
            verdict, part = _collision_free_row(va)
        elif claim.kind == "worst-case":
            verdict, part = _worst_case_row(claim, row, view, va, vb)
        elif claim.kind == "stuck":
            verdict, part = _stuck_row(va)
        else:
            share = _reached(va)
            verdict, part = ((None, "no number") if share is None else
                             (share == 1.0, f"reached {share:.0%}"))
            if view == "paper" and share is not None:      # a statement, not a measured share
                part = f"the paper states it ({va.outcome}; no runs counted)"
        verdicts.append(verdict)
        parts.append(f"{where}: {part}")
    return _combined(verdicts), "; ".join(parts)


def _combined(verdicts: list[bool | None]) -> bool | None:
    """Does not hold if one part does not, holds if every part holds, else not shown."""
    if any(v is False for v in verdicts):
        return False
    return True if verdicts and all(v is True for v in verdicts) else None


def _check(protocol: Protocol, claim: Claim, summary: pd.DataFrame, view: str
           ) -> tuple[bool | None, str]:
    parts, verdicts = [], []
    for row in _rows(protocol, claim):
        verdict, part = row_verdict(protocol, claim, summary, view, row)
        verdicts.append(verdict)
        parts.append(part)
    return _combined(verdicts), "; ".join(parts)


def _constant(value: dict[str, Any], col: str) -> bool:
    """Whether every reached run of a summary row gave the same ``col`` (a deterministic
    planner's copies): its minimum is its maximum."""
    lo, hi = value.get(f"{col}_min"), value.get(f"{col}_max")
    return lo is not None and hi is not None and math.isfinite(float(lo)) and \
        float(lo) == float(hi)


def _compare_row(protocol: Protocol, claim: Claim, view: str, va, vb, label_b: str = "",
                 single: bool = False) -> tuple[bool | None, str]:
    """One row of a ``shorter`` / ``faster`` claim. The paper's numbers (one value per method)
    are compared as printed; ours need significance and runs that reached (see :data:`ALPHA`),
    and at least one side whose runs differ (two deterministic planners give one comparison,
    however many runs: "not shown", or its sign with ``single``); ``label_b``: the variant of
    ``b`` compared (its p-value column)."""
    col = _column(claim)
    a, b = _metric(va, col), _metric(vb, col)
    if view == "paper":
        if a is None and b is not None and _reached(va) == 0.0:
            return False, f"{claim.a} reached none, {claim.b} {b:.4g}"
        if b is None and a is not None and _reached(vb) == 0.0:
            return True, f"{claim.a} {a:.4g}, {claim.b} reached none"
        if a is None or b is None:
            return None, "no number"
        return a < b, f"{a:.4g} vs {b:.4g}"
    if va is None or vb is None:
        return None, "no number"
    ra, rb = _reached(va), _reached(vb)
    na, nb = int(va["robots"]), int(vb["robots"])
    reach = f"reached {round(ra * na)}/{na} vs {round(rb * nb)}/{nb}"
    if ra == 0.0 and rb > 0.0:
        shown = _fmt(b) if b is not None else "-"      # a summary without the column
        return False, f"{claim.a} reached none, {claim.b} {shown} ({reach})"
    if ra <= MOST_REACHED or rb <= MOST_REACHED:
        nums = f"{_fmt(a) if a is not None else '-'} vs {_fmt(b) if b is not None else '-'}"
        return None, f"{nums}, {reach}: not most runs on both sides"
    if a is not None and b is not None and _constant(va, col) and _constant(vb, col):
        one = f"{a:.4g} vs {b:.4g}: every run of each gave the same result"
        if single:
            return (None, f"{one} (a tie)") if a == b else (a < b, f"{one} (one comparison)")
        return None, (f"{one}, so the runs are copies, not samples: one comparison, no test "
                      "(see the layout sensitivity)")
    key = f"{col}_p_vs_{label_b or _label(protocol, claim.b, view)}"
    p = va.get(key, math.nan)
    p = math.nan if p is None else float(p)
    if a is None or b is None or not math.isfinite(p):
        return None, f"no {col} in this summary (stored before it was recorded: run it again)"
    if p >= ALPHA:
        return None, f"{a:.4g} vs {b:.4g}, p = {p:.2g} >= {ALPHA:g}"
    return a < b, f"{a:.4g} vs {b:.4g}, p = {p:.2g}"


#: how the claims judged without a significance test are judged (the claims table says so)
CLAIM_RULES = {
    "collision-free": ("A \"no collision\" claim holds in ours only when every robot of every run "
                       "reached its goal and none touched an obstacle or another robot; "
                       "anything else does not hold."),
    "stuck": ("A \"trapped\" claim holds in ours only when every run ended stuck or at the "
              "time limit short of the goal; a run that reached, collided or left the workspace "
              "was not trapped."),
    "worst-case": ("A worst-case claim compares each planner's worst run (its longest reached "
                   "path, with that run's own time): it holds when the first planner's is both "
                   "shorter and faster; a run that did not reach is worse than any that did "
                   "(only the second planner has one: holds; only the first: does not hold; "
                   "both: not shown)."),
}


def _finite(x: Any) -> float | None:
    """``x`` as a float, None if missing or not finite."""
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _collision_free_row(value: Value | dict[str, Any] | None) -> tuple[bool | None, str]:
    """One row of a ``collision-free`` claim (see the module docstring)."""
    if value is None:
        return None, "no number"
    if isinstance(value, Value):
        ok = value.outcome == "reached"
        return ok, "every robot reached, no collision" if ok else value.outcome
    n = int(value["robots"])
    k = int(round(float(value["success_rate"]) * n))
    collided = int(_finite(value.get("collided")) or 0)
    contacts = _finite(value.get("robot_contacts"))
    gap = _finite(value.get("min_robot_clearance_min"))
    units = value.get("units") if isinstance(value.get("units"), str) else ""
    others = [f"{o} {int(_finite(value.get(o)) or 0)}" for o in ("stuck", "timeout",
                                                                 "out_of_bounds")
              if _finite(value.get(o))]
    part = f"reached {k}/{n}" + (f" ({', '.join(others)})" if others else "") + \
        f", collided {collided}"
    if contacts is not None and (contacts or gap is not None):
        part += f" ({int(contacts)} with a robot)"
    if gap is not None:
        part += f", closest robots {_fmt(gap)} {units}".rstrip()
    return k == n and collided == 0 and not contacts, part


def _stuck_row(value: Value | dict[str, Any] | None) -> tuple[bool | None, str]:
    """One row of a ``stuck`` claim: in ours it holds when every run ended trapped, ``stuck``
    or still short of the goal at the time limit (``timeout``); a run that reached, collided or
    left the workspace was not trapped, so the claim does not hold (not reaching is not being
    stuck). In the paper's numbers it holds where the paper's outcome is ``stuck``."""
    if value is None:
        return None, "no number"
    if isinstance(value, Value):
        return (value.outcome == "stuck",
                f"the paper states it ({value.outcome}; no runs counted)")
    n = int(value["robots"])
    k = int(round(float(value["success_rate"]) * n))
    counts = {o: _finite(value.get(o)) for o in ("stuck", "timeout", "collided",
                                                 "out_of_bounds")}
    if counts["stuck"] is None:
        return None, "no stuck count in this summary (run it again)"
    counts = {o: int(c or 0) for o, c in counts.items()}
    part = f"stuck {counts['stuck']}/{n}, reached {k}" + "".join(
        f", {o} {c}" for o, c in counts.items() if o != "stuck" and c)
    return counts["stuck"] + counts["timeout"] == n and k == 0, part


def _worst_case_row(claim: Claim, row: Row, view: str, va, vb) -> tuple[bool | None, str]:
    """One row of a ``worst-case`` claim (see the module docstring)."""
    if view == "paper":
        ea, eb = row.extremes.get(claim.a), row.extremes.get(claim.b)
        wa = ea[1] if ea else None
        wb = eb[1] if eb else vb
        if wa is None or wb is None or None in (wa.length, wa.time) \
                or (wb.outcome == "reached" and None in (wb.length, wb.time)):
            return None, "no number"
        if wb.outcome != "reached":
            return True, f"{claim.a} worst {wa.time:g} s / {wa.length:g}, {claim.b} {wb.outcome}"
        what = "worst" if eb else "its one value"
        return (wa.length < wb.length and wa.time < wb.time,
                f"{claim.a} worst {wa.time:g} s / {wa.length:g} vs {claim.b} ({what}) "
                f"{wb.time:g} s / {wb.length:g}")
    if va is None or vb is None:
        return None, "no number"
    na, nb = int(va["robots"]), int(vb["robots"])
    ka = int(round(float(va["success_rate"]) * na))
    kb = int(round(float(vb["success_rate"]) * nb))
    reach = f"reached {ka}/{na} vs {kb}/{nb}"
    if ka < na and kb < nb:
        return None, f"both have runs that did not reach ({reach})"
    if ka < na:
        return False, f"{claim.a} has runs that did not reach ({reach})"
    if kb < nb:
        return True, f"{claim.b} has runs that did not reach ({reach})"
    la, ta = _finite(va.get("worst_path_length")), _finite(va.get("worst_time_to_goal"))
    lb, tb = _finite(vb.get("worst_path_length")), _finite(vb.get("worst_time_to_goal"))
    if None in (la, ta, lb, tb):
        return None, "no worst run in this summary (run it again)"
    return (la < lb and ta < tb,
            f"worst {ta:.4g} s / {la:.4g} vs {tb:.4g} s / {lb:.4g}")


def check_claims(protocol: Protocol, summary: pd.DataFrame) -> list[dict[str, Any]]:
    """Each claim's verdict in the paper's own numbers and in ours for both profiles.

    Parameters
    ----------
    protocol : Protocol
    summary : DataFrame
        ``summarize_runs`` of the reproduction.

    Returns
    -------
    list of dict
        ``text``, and per view (``paper``, ``paper profile``, ``hybridnav profile``) the verdict
        (True, False or None) and ``<view> detail`` (the numbers it rests on).
    """
    out = []
    for claim in protocol.claims:
        item: dict[str, Any] = {"text": claim.text, "measure": _measure(claim),
                                "kind": claim.kind}
        for view in VIEWS:
            item[view], item[f"{view} detail"] = _check(protocol, claim, summary, view)
        out.append(item)
    return out


def _measure(claim: Claim) -> str:
    """What a claim compares, in words (the report's "measured" column)."""
    if claim.kind == "shorter":
        return "mean path length of the reached runs"
    if claim.kind == "faster":
        what = ("travel time plus the planner's computation" if claim.time == "with planning"
                else "simulated travel time")
        return f"mean {what} of the reached runs" + (
            f" (the paper's time: {claim.time_source})" if claim.time_source else "")
    if claim.kind == "collision-free":
        return ("robots x runs that reached, collisions (with an obstacle or another robot) and "
                "the closest two robots came")
    if claim.kind == "worst-case":
        return ("each planner's worst run: its longest reached path and that run's simulated "
                "travel time")
    return ("share of runs that reached" if claim.kind == "reaches" else
            "runs that ended stuck (or at the time limit) short of the goal")


def _word(v: bool | None) -> str:
    return {True: "holds", False: "does not hold", None: "not shown"}[v]


def _cell(row: dict[str, Any] | None, units: str) -> str:
    if row is None:
        return "-"
    n = int(row["robots"])
    k = int(round(row["success_rate"] * n))
    if k == 0:
        fails = [o for o in ("stuck", "collided", "timeout", "out_of_bounds") if row.get(o)]
        return f"none reached ({', '.join(f'{o} {int(row[o])}' for o in fails)})"
    return (f"{row['time_to_goal_mean']:.1f} s / {row['path_length_mean']:.4g} {units} "
            f"({k}/{n})")


def _paper_cell(v: Value | None, units: str) -> str:
    if v is None:
        return "-"
    if v.outcome != "reached":
        return v.outcome
    parts = [f"{v.time:g} s" if v.time is not None else "", f"{v.length:g} {units}"
             if v.length is not None else ""]
    return " / ".join(p for p in parts if p) or "reached"


def _units(summary: pd.DataFrame) -> dict[str, str]:
    """``{scenario: its units}`` of a summary."""
    return dict(zip(summary["scenario"], summary["units"]))


def _fmt(x: float) -> str:
    """A number to 4 significant digits, NaN as ``-``."""
    return "-" if x != x else f"{x:.4g}"


def bounds_section(protocol: Protocol, units_of: dict[str, str]) -> list[str]:
    """The layouts' length bounds per row and the paper lengths they contradict (markdown lines)."""
    lines: list[str] = []
    bounds = length_bounds(protocol)
    if bounds:
        lines += ["How short a path can be in our layouts (first robot, to its goal disk): the "
                  "straight line, and the shortened A* path with the robot's radius as "
                  "clearance.", "", "| row | scenario | straight line | shortened A* |",
                  "|---|---|---|---|"]
        for row in protocol.rows:
            if row.label in bounds:
                straight, astar = bounds[row.label]
                u = units_of.get(row.scenario, "")
                lines.append(f"| {row.label} | `{row.scenario}` | {straight:.4g} {u} | "
                             + (f"{astar:.4g} {u}" if astar is not None else "-") + " |")
        lines.append("")
    bad = impossible_lengths(protocol, bounds)
    if bad:
        lines += ["Paper lengths that our reconstruction contradicts: " + "; ".join(
                      f"{row}, {p}: {length:g} below the {what} ({bound:.4g})"
                      for row, p, length, what, bound in bad)
                  + ". Those rows compare layouts, not planners.", ""]
    return lines


def profile_sections(protocol: Protocol, summary: pd.DataFrame, level: int = 2) -> list[str]:
    """Per profile: the paper's values beside ours, and the enhancement percentages (markdown;
    ``level``: of the headings)."""
    lines: list[str] = []
    units_of = _units(summary)
    both = has_profiles(protocol)
    for view in ("paper profile", "hybridnav profile") if both else ("hybridnav profile",):
        lines += [f"{'#' * level} Our runs, {view}" if both else
                  f"{'#' * level} Our runs (no compared planner has profiles: one run each)", ""]
        head = ["row", "scenario"]
        for p in protocol.planners:
            head += [f"paper: {p}", f"ours: `{_label(protocol, p, view)}`"]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for row in protocol.rows:
            u = units_of.get(row.scenario, "")
            for value in _sweep_values(protocol):
                cells = [_where(protocol, row, value), f"`{row.scenario}`"]
                for p in protocol.planners:
                    cells += [_paper_cell(row.paper.get(p), u),
                              _cell(ours(summary, _at_level(protocol, p, view, value),
                                         row.scenario), u)]
                lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        if protocol.enhancement:
            a, b = protocol.enhancement
            lines += [f"Enhancement of `{a}` over `{b}`, `100 (b - a) / b` (the paper's derived "
                      "figures, recomputed from its table and from ours):", "",
                      "| row | paper: length | ours: length | paper: time | ours: time |",
                      "|---|---|---|---|---|"]
            for row in protocol.rows:
                cells = [row.label]
                for what in ("length", "time"):
                    for side in ("paper", "ours"):
                        if side == "paper":
                            va, vb = row.paper.get(a), row.paper.get(b)
                        else:
                            va = ours(summary, _label(protocol, a, view), row.scenario)
                            vb = ours(summary, _label(protocol, b, view), row.scenario)
                        col = "path_length" if what == "length" else "time_to_goal"
                        x, y = _metric(va, col), _metric(vb, col)
                        cells.append(f"{100 * (y - x) / y:.2f} %" if x is not None and y else "-")
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
    return lines


def _sweep_values(protocol: Protocol) -> tuple:
    """The protocol's sweep values (``(None,)`` without a sweep)."""
    return protocol.sweep[1] if protocol.sweep else (None,)


def _num(row: dict[str, Any], column: str, unit: str = "") -> str:
    """A summary number to 4 significant digits (``-`` where the summary has none)."""
    v = row.get(column)
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(v):
        return "-"
    return f"{v:.4g}{unit}"


def safety_section(protocol: Protocol, summary: pd.DataFrame, level: int = 2) -> list[str]:
    """Every variant's safety figures first, then its effort and convenience figures (markdown
    lines; ``level``: of the heading): reached and failed runs by outcome, the smallest
    footprint clearance of any run and its mean over the runs, the mean control effort and mean
    time / length of the reached runs."""
    units_of = _units(summary)
    lines = [f"{'#' * level} Safety, effort, then time and length", "",
             "Per variant: runs that reached, collided or failed otherwise; the footprint's "
             "clearance to the nearest obstacle (smallest of any run, and the mean over the runs "
             "of each run's smallest; negative: overlap); the control effort, sum of (v^2 + "
             "omega^2) dt of the commanded linear speed and turn rate, mean over the reached "
             "runs (`-`: a model without body rates, or a summary stored before it was "
             "recorded); then mean time / length over the reached runs.", "",
             "| variant | scenario | reached | collided | other failures | clearance: worst | "
             "clearance: mean | control effort | time / length (reached) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for label in dict.fromkeys(summary["planner"]):
        for row in protocol.rows:
            r = ours(summary, label, row.scenario)
            if r is None:
                continue
            u = units_of.get(row.scenario, "")
            n = int(r["robots"])
            k = int(round(r["success_rate"] * n))
            others = [f"{o} {int(r[o])}" for o in ("out_of_bounds", "stuck", "timeout")
                      if r.get(o)]
            conv = (f"{r['time_to_goal_mean']:.1f} s / {r['path_length_mean']:.4g} {u}" if k
                    else "-")
            lines.append(f"| `{label}` | `{row.scenario}` | {k}/{n} | {int(r.get('collided', 0))}"
                         f" | {', '.join(others) or '-'} | {_num(r, 'min_clearance_min', ' ' + u)}"
                         f" | {_num(r, 'min_clearance_mean', ' ' + u)} | "
                         f"{_num(r, 'control_effort_mean')} | {conv} |")
    return lines + [""]


def has_profiles(protocol: Protocol) -> bool:
    """Whether any compared planner has profiles (else one run serves both views)."""
    from hybridnav import planners

    return any(planners.PLANNERS[p].profiles for p in protocol.planners)


def claims_section(claims: Sequence[dict[str, Any]], level: int = 2,
                   profiles: bool = True) -> list[str]:
    """The paper's claims with their verdicts in its numbers and in ours (markdown lines;
    ``level``: of the heading; ``profiles``: a column per profile, else one for ours)."""
    views = VIEWS if profiles else VIEWS[::2]
    head = ("| claim | measured | in the paper's numbers | ours, `profile=paper` | ours, "
            "`profile=hybridnav` |" if profiles else
            "| claim | measured | in the paper's numbers | ours |")
    rule = (f"In the paper's numbers a claim is judged as printed. In ours it holds on a row only "
            f"when both planners reached in more than {MOST_REACHED:.0%} of their runs and the "
            f"two-sided Mann-Whitney U test of the reached runs gives p < {ALPHA:g} in its "
            "favour; significant the other way, or the first planner reaching in no run where "
            "the second does, is \"does not hold\"; anything else is \"not shown\". Two "
            "planners that each gave the same result in every run (deterministic) give one "
            "comparison, not a sample: \"not shown\" here, and the layout sensitivity below "
            "counts them layout by layout.")
    kinds = list(dict.fromkeys(c.get("kind") for c in claims))
    if all(k in CLAIM_RULES for k in kinds):     # no claim the significance rule judges
        rule = "In the paper's numbers a claim is judged as printed."
    rule += "".join(f" {CLAIM_RULES[k]}" for k in kinds if k in CLAIM_RULES)
    return [f"{'#' * level} The paper's claims", "", rule, "", head,
            "|---" * (len(views) + 2) + "|"] + [
        f"| {c['text']} | {c.get('measure', '')} | "
        + " | ".join(f"{_word(c[v])} ({c[f'{v} detail']})" for v in views)
        + " |" for c in claims] + [""]


def variants_section(protocol: Protocol, summary: pd.DataFrame, level: int = 2,
                     only: Sequence[str] | None = None) -> list[str]:
    """Every variant (or those in ``only``) with median, 95 % interval and best run (markdown
    lines; ``level``: of the heading)."""
    units_of = _units(summary)
    names = [lb for lb in dict.fromkeys(summary["planner"]) if only is None or lb in only]
    lines = [f"{'#' * level} Every variant" if only is None else f"{'#' * level} Ablations", "",
             "Mean time / length over the reached runs, median length, 95 % interval of the "
             "mean length, best run (length, its time); the default profile unless the label "
             "says `/paper`.", "",
             "| variant | scenario | time / length (reached) | median | 95 % interval | best |",
             "|---|---|---|---|---|---|"]
    for label in names:
        for row in protocol.rows:
            r = ours(summary, label, row.scenario)
            if r is None:
                continue
            u = units_of.get(row.scenario, "")
            lines.append(f"| `{label}` | `{row.scenario}` | {_cell(r, u)} | "
                         f"{_fmt(r['path_length_median'])} | [{_fmt(r['path_length_ci95_lo'])}, "
                         f"{_fmt(r['path_length_ci95_hi'])}] | {_fmt(r['best_path_length'])} {u}"
                         f", {_fmt(r['best_time_to_goal'])} s |")
    return lines + [""]


def _run_cell(row: dict[str, Any] | None, side: str, units: str) -> str:
    """Our best or worst run (``side``) of a summary row: its time and length."""
    if row is None:
        return "-"
    length, t = _finite(row.get(f"{side}_path_length")), _finite(row.get(f"{side}_time_to_goal"))
    if length is None or t is None:
        return "none reached" if not row["success_rate"] > 0 else "-"
    return f"{t:.1f} s / {length:.4g} {units}"


def _scenario_units(name: str) -> str:
    """The length unit of a scenario (for a row our summary does not have)."""
    from hybridnav.world import load_scenario

    return load_scenario(name).units


def extremes_section(protocol: Protocol, summary: pd.DataFrame, level: int = 2) -> list[str]:
    """The paper's best and worst runs (:attr:`Row.extremes`) beside ours, in every profile
    (markdown lines; none if the paper quotes none; ``level``: of the heading). Ours: the
    shortest and the longest reached path, each with its own time."""
    rows = [row for row in protocol.rows if row.extremes]
    if not rows:
        return []
    units_of = _units(summary)
    views = ("paper profile", "hybridnav profile") if has_profiles(protocol) else \
        ("hybridnav profile",)
    head = ["row", "planner", "paper: best", "paper: worst"]
    for view in views:
        name = "ours" if len(views) == 1 else f"ours, `profile={view.split()[0]}`"
        head += [f"{name}: best", f"{name}: worst"]
    lines = [f"{'#' * level} Best and worst runs", "",
             "The paper's best and worst runs (time / length) beside ours: the shortest and the "
             "longest reached path, each with its own time.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        u = units_of.get(row.scenario) or _scenario_units(row.scenario)
        for p in protocol.planners:
            best, worst = row.extremes.get(p, (None, None))
            cells = [row.label, f"`{p}`", _paper_cell(best, u), _paper_cell(worst, u)]
            for view in views:
                r = ours(summary, _label(protocol, p, view), row.scenario)
                cells += [_run_cell(r, "best", u), _run_cell(r, "worst", u)]
            lines.append("| " + " | ".join(cells) + " |")
    return lines + [""]


def separation_section(protocol: Protocol, summary: pd.DataFrame, level: int = 2) -> list[str]:
    """How the robots of the multi-robot rows kept apart: per variant, the robots that reached,
    collided (with a robot among them) and the closest any two came (markdown lines; none
    without a multi-robot row or a summary that recorded it; ``level``: of the heading)."""
    if "min_robot_clearance_min" not in summary:
        return []
    units_of = _units(summary)
    lines: list[str] = []
    for row in protocol.rows:
        sel = summary[summary["scenario"] == row.scenario]
        for _, r in sel.iterrows():
            gap = _finite(r.get("min_robot_clearance_min"))
            if gap is None:
                continue
            u = units_of.get(row.scenario, "")
            n = int(r["robots"])
            k = int(round(float(r["success_rate"]) * n))
            contacts = int(_finite(r.get("robot_contacts")) or 0)
            lines.append(f"| {row.label} | `{r['planner']}` | {k}/{n} | "
                         f"{int(_finite(r.get('collided')) or 0)} ({contacts} with a robot) | "
                         f"{_fmt(gap)} {u} | {_fmt(float(r['min_robot_clearance_mean']))} {u} | "
                         f"{_fmt(float(r['min_clearance_min']))} {u} |")
    if not lines:
        return []
    return [f"{'#' * level} Robots avoiding each other", "",
            "Per variant over every robot of every run: how many reached, how many collided "
            "(and of those, how many touched another robot), the closest two robots' footprints "
            "came (clearance, below 0 a contact), each robot's closest approach to another "
            "robot on average, and the smallest clearance to anything (obstacles too).", "",
            "| row | variant | reached | collided | closest robots | mean closest | "
            "closest to anything |", "|---|---|---|---|---|---|---|"] + lines + [""]


def conflicts_section(protocol: Protocol, level: int = 2) -> list[str]:
    """The paper's internal conflicts and which version we use (markdown lines; none if the
    protocol lists none; ``level``: of the heading)."""
    if not protocol.conflicts:
        return []
    return [f"{'#' * level} Where the paper contradicts itself", ""] + [
        f"- {c}" for c in protocol.conflicts] + [""]


def sensitivity_section(protocol: Protocol, verdicts: pd.DataFrame, summary: pd.DataFrame,
                        *, runs: int, level: int = 2, profiles: bool = True) -> list[str]:
    """The layout-sensitivity table (markdown lines; none if no claim failed).

    Parameters
    ----------
    protocol : Protocol
    verdicts : DataFrame
        :func:`layout_sensitivity`'s first table.
    summary : DataFrame
        The reproduction's own summary (the unperturbed verdicts).
    runs : int
        Runs per planner and layout.
    level : int
        Of the heading.
    profiles : bool
        A column per profile (else one: planners without profiles ran once).
    """
    if verdicts is None or verdicts.empty:
        return []
    views = VIEWS[1:] if profiles else VIEWS[2:]
    rows = {row.label: row for row in protocol.rows}
    n_layouts = verdicts.groupby(["claim", "row"])["layout"].nunique()
    lines = [f"{'#' * level} Layout sensitivity", "",
             f"Every row where a claim does not hold in our runs (or two deterministic planners "
             f"give one comparison), rerun on perturbed copies of "
             f"our reconstructed layout ({runs} run(s) per planner and layout): the whole world "
             f"mirrored, every start moved sideways by {JITTER:.0%} of its start-goal distance, "
             f"and every free-standing obstacle moved by up to {JITTER:.0%} of it, walls staying "
             "where they are (how exactly a layout read "
             "off a figure can be placed). Each cell: the verdict on our layout, then in how "
             "many perturbed layouts the claim holds / does not hold / is not shown, by the "
             "same rule as above, except that where both planners gave one result in every run "
             "(deterministic) a layout counts as one comparison, judged by its sign. Rows where "
             "such planners could not be tested on our layout are rerun too.", "",
             "| claim | row | layouts | " + " | ".join(
                 f"ours, `profile={v.split()[0]}`" if profiles else "ours" for v in views) + " |",
             "|---|---|---|" + "---|" * len(views)]
    for (i, label), group in verdicts.groupby(["claim", "row"], sort=False):
        claim = protocol.claims[int(i)]
        cells = []
        for view in views:
            v = group[group["view"] == view]["verdict"]
            own = row_verdict(protocol, claim, summary, view, rows[label])[0]
            words = {True: "holds", False: "does not hold", None: "not shown"}
            cells.append(f"{words[own]} here; {int((v == True).sum())} / "        # noqa: E712
                         f"{int((v == False).sum())} / {int(v.isna().sum())} of {len(v)}")  # noqa: E712
        tags = ", ".join(dict.fromkeys(group["layout"]))
        lines.append(f"| {claim.text} | {label} | {int(n_layouts[(i, label)])} ({tags}) | "
                     + " | ".join(cells) + " |")
    return lines + [""]


def literature_line(protocol: Protocol) -> list[str]:
    """The values the paper quotes from other work (markdown lines; none if it quotes none)."""
    if not protocol.literature:
        return []
    return ["Values the paper quotes from other work (not run here): " + "; ".join(
        f"{row}: " + ", ".join(f"{m} {v:g}" for m, v in vals.items())
        for row, vals in protocol.literature.items()) + ".", ""]


def write_report(path: Path, protocol: Protocol, summary: pd.DataFrame,
                 claims: Sequence[dict[str, Any]], *, runs: int, seed: int, version: str,
                 files: Sequence[str], layouts: pd.DataFrame | None = None,
                 layout_runs: int = 0) -> None:
    """Write ``report.md``.

    Parameters
    ----------
    path : Path
    protocol : Protocol
    summary : DataFrame
    claims : sequence of dict
        :func:`check_claims` of the same summary.
    runs, seed : int
        What the comparison ran with.
    version : str
        The package version.
    files : sequence of str
        The comparison's files in the same folder (figures are linked).
    layouts : DataFrame, optional
        :func:`hybridnav.reproduce.layouts.layout_sensitivity`'s verdicts (none: no section).
    layout_runs : int
        Runs per planner and perturbed layout.
    """

    units_of = _units(summary)
    lines = [f"# `{protocol.name}`: {protocol.paper}", "",
             f"Reproduces {protocol.source}. hybridnav {version}; {runs} run(s) per planner and "
             f"scenario (the paper: {protocol.paper_runs or protocol.runs}), seed {seed}. " + (
                 "Every planner with profiles ran twice: `profile=paper` (the paper's settings "
                 "and rules, see `hybridnav planners`) and the default `profile=hybridnav`."
                 if has_profiles(protocol) else
                 "No compared planner has a paper profile: each ran once, with the settings "
                 "below."), ""]
    if protocol.settings:
        lines += ["Settings from the paper: " + "; ".join(
            f"{p}: " + ", ".join(f"{k} = {v}" for k, v in s.items())
            for p, s in protocol.settings.items()) + ".", ""]
    if protocol.notes:
        lines += [protocol.notes, ""]
    lines += conflicts_section(protocol)
    lines += safety_section(protocol, summary)
    lines += ["Ours: mean time to goal / mean path length over the robots' runs that reached "
              "the goal (reached / robots x runs).", ""]
    lines += bounds_section(protocol, units_of)
    lines += profile_sections(protocol, summary)
    lines += extremes_section(protocol, summary)
    lines += separation_section(protocol, summary)
    lines += claims_section(claims, profiles=has_profiles(protocol))
    lines += sensitivity_section(protocol, layouts, summary, runs=layout_runs,
                                 profiles=has_profiles(protocol))
    lines += variants_section(protocol, summary)
    lines += literature_line(protocol)
    # the same order however found; in the format they were written in (--format)
    figures = sorted(f for f in files if f.rpartition(".")[2] in FIGURE_FORMATS)
    if figures:
        lines += ["## Figures", ""] + [f"![{f}]({f})" for f in figures] + [""]
    atomic_write_text(path, "\n".join(lines))
