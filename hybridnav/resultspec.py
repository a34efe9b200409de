"""What a result folder may hold, declared once: robot metrics and the planners' extras.

:data:`METRICS` declares the metrics of a robot's entry in ``result.json``: the standard ones of
:class:`~hybridnav.results.RobotResult` and those planners add (any other metric is a number or
null, :data:`OTHER_METRIC`). :data:`EXTRAS` declares every extra a planner records for its
diagnostics, by the prefix of its name ``<prefix>_<robot>``: the columns of a table and what each
holds (:class:`Table`), or the dimensions of an array (:class:`Array`).

The writer (:class:`~hybridnav.results.Result`, :func:`~hybridnav.results.write_result`) and the
reader (:func:`~hybridnav.results.read_result`) check against these declarations, and the figures
of :mod:`hybridnav.plotting` read only the declared columns (:func:`declared`), so what a planner
writes, what a result folder may hold and what a figure draws cannot drift apart.

What a column holds (its *kind*):

============  ======================================================================
kind          values
============  ======================================================================
``finite``    finite numbers of magnitude at most :data:`MAX_MAGNITUDE`
``position``  finite numbers of magnitude at most :data:`hybridnav.limits.MAX_POSITION`
              (coordinates in the plane, what the figures draw)
``index``     whole numbers from 0 to 2**53
``extended``  as ``finite``, or ``inf`` / ``-inf`` (no ``nan``)
``any``       as ``finite``, ``nan``, ``inf`` or ``-inf``
``text``      one-line text
a tuple       one of these words
============  ======================================================================
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fileio import MAX_ROBOT_NAME, SAFE_NAME, show_key
from hybridnav.limits import MAX_POSITION
from hybridnav.params import short_repr

__all__ = ["EXTRAS", "MAX_MAGNITUDE", "METRICS", "OTHER_METRIC", "OUTCOMES", "SAFE_NAME", "Array",
           "Metric", "Table", "check_column", "check_entry", "check_extra", "declared", "show_key",
           "spec_of"]

#: The outcome of each robot. A planner that runs out of its step or time budget reports
#: ``timeout``; it never loops forever and never raises for it.
OUTCOMES = ("reached", "collided", "out_of_bounds", "stuck", "timeout")


#: Largest magnitude of a finite number in a result (no measurement comes near it; matplotlib
#: cannot scale an axis to numbers near the float maximum, 1.8e308).
MAX_MAGNITUDE = 1e300

_KINDS = {
    "finite": f"finite numbers of magnitude at most {MAX_MAGNITUDE:g}",
    "position": f"finite coordinates of magnitude at most {MAX_POSITION:g}",
    "index": "whole numbers from 0 to 2**53",
    "extended": "numbers or +-inf (no nan)",
    "any": "numbers, nan or +-inf",
    "text": "one-line text",
}


@dataclass(frozen=True)
class Metric:
    """What one metric of a robot's entry in ``result.json`` holds.

    Parameters
    ----------
    kind : {"number", "count"}
        A finite number of magnitude at most :data:`MAX_MAGNITUDE`, or a whole number in
        ``[0, 2**63)`` written as a JSON integer.
    null : bool
        Whether the writer may write ``null`` (no value, or a non-finite one: JSON has neither).
    lo : float or None
        Smallest value (numbers only).
    """

    kind: str
    null: bool = False
    lo: float | None = None

    def problem(self, value: Any) -> str | None:
        """What is wrong with ``value`` as this metric (``"expected ..., got ..."``), or None.

        Parameters
        ----------
        value : any
            The metric's value as JSON holds it.
        """
        if value is None and self.null:
            return None
        what = ("a whole number from 0 to 2**63 - 1" if self.kind == "count" else
                "a finite number" + (f" >= {self.lo:g}" if self.lo is not None else ""))
        what += " or null" if self.null else ""
        if self.kind == "count":
            ok = type(value) is int and 0 <= value < 2**63
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and \
                abs(value) <= MAX_MAGNITUDE and (self.lo is None or value >= self.lo)
        return None if ok else f"expected {what}, got {short_repr(value)}"


_NUMBER0 = Metric("number", lo=0.0)
_COUNT = Metric("count")

#: The metrics of a robot's entry in ``result.json`` (besides ``name`` and ``outcome``): the
#: standard ones every planner writes and those planners add.
METRICS: dict[str, Metric] = {
    # RobotResult's own (time_to_goal is null unless the robot reached its goal; min_clearance
    # is null when there was nothing to be near: infinite)
    "path_length": _NUMBER0, "smoothness": _NUMBER0, "compute_time": _NUMBER0,
    "time_to_goal": Metric("number", null=True, lo=0.0),
    "min_clearance": Metric("number", null=True),
    # the closed loop's (hybridnav.planners.simulate): sum over control cycles of
    # (v^2 + omega^2) dt, the commanded linear speed and turn rate held each cycle; models that
    # give their body rates only (the unicycle)
    "control_effort": _NUMBER0,
    # the shared simulation, with more than one robot: the clearance to the other robots alone
    "min_robot_clearance": Metric("number", null=True),
    # planners that plan before they move (step, path, pso-ba)
    "planning_time": _NUMBER0,
    # step planners
    "steps_planned": _COUNT, "planning_calls": _COUNT,
    # path planners (null or infinite when no path was found)
    "planned_length": Metric("number", null=True, lo=0.0), "waypoints": Metric("count", null=True),
    "grid_length": Metric("number", null=True, lo=0.0), "expanded": _COUNT,
    "rfd_iterations": _COUNT, "pso_runs": _COUNT, "rfd_length": Metric("number", null=True, lo=0.0),
    # pso-ba
    "path_points": _COUNT, "pso_ba_runs": _COUNT, "ls_repairs": _COUNT, "wall_episodes": _COUNT,
    "direction_changes": _COUNT, "memory_refusals": _COUNT,
}

#: Any metric :data:`METRICS` does not list.
OTHER_METRIC = Metric("number", null=True)


@dataclass(frozen=True)
class Table:
    """A table extra (``<name>.csv``): its columns, in order, and what each holds.

    Parameters
    ----------
    columns : mapping
        Column name -> kind (see the module docstring).
    others : str or None
        The kind of any further column (None: no further columns).
    rows : int or None
        The exact number of rows, if fixed.
    less : tuple of (str, str)
        Pairs of columns ``(a, b)`` with ``a < b`` in every row (an extent's bounds).
    ascending : tuple of str
        Columns whose values never decrease from row to row (rows in the order they were
        recorded, what a reader that looks a time up by bisection needs).
    """

    columns: Mapping[str, Any]
    others: str | None = None
    rows: int | None = None
    less: tuple[tuple[str, str], ...] = ()
    ascending: tuple[str, ...] = ()

    def expected(self) -> str:
        """The columns, as the messages list them."""
        more = f", and any further columns of {_KINDS[self.others]}" if self.others else ""
        return f"the columns {', '.join(self.columns)}{more}"

    def check_names(self, names: list[str], source: str) -> None:
        """Raise a :class:`HybridnavError` unless ``names`` (a header) holds every declared
        column and no other (unless further columns are declared).

        Parameters
        ----------
        names : list of str
        source : str
            What the messages start with: the file, or ``result: extras.<name>``.
        """
        for col in self.columns:
            if col not in names:
                raise HybridnavError(f"{source}: column {col}: missing (expected "
                                     f"{self.expected()})")
        if self.others is None:
            for col in names:
                if col not in self.columns:
                    raise HybridnavError(f"{source}: column {show_key(col)}: not expected "
                                         f"(expected {self.expected()})")

    def check(self, table: Mapping[str, np.ndarray], source: str,
              first_line: int | None = None) -> None:
        """Raise a :class:`HybridnavError` unless ``table`` is as declared.

        Parameters
        ----------
        table : mapping
            Column name -> 1-D array (numbers as floats, text as ``str``), all of one length.
        source : str
            What the messages start with: the file, or ``result: extras.<name>``.
        first_line : int or None
            Line of the first row in the file (rows are named by line then), else None.
        """
        self.check_names(list(table), source)
        for col, values in table.items():
            kind = self.columns.get(col, self.others)
            check_column(np.asarray(values), kind, f"{source}: column {col}", first_line)
        n = len(next(iter(table.values()))) if table else 0
        if self.rows is not None and n != self.rows:
            raise HybridnavError(f"{source}: expected {self.rows} row{'s' * (self.rows != 1)}"
                                 f" of {', '.join(self.columns)}, got {n}")
        for col in self.ascending:
            values = np.asarray(table[col])
            back = np.flatnonzero(np.diff(values) < 0)
            if len(back):
                k = int(back[0]) + 1
                raise HybridnavError(f"{source}: column {col}: expected rows in the order they "
                                     f"were recorded ({col} never decreasing), got "
                                     f"{float(values[k])!r} after {float(values[k - 1])!r} at "
                                     f"{_at(k, first_line)}")
        for a, b in self.less:
            bad = ~(np.asarray(table[a]) < np.asarray(table[b]))
            if bad.any():
                k = int(np.argmax(bad))
                raise HybridnavError(f"{source}: column {b}: expected more than {a} "
                                     f"({float(table[a][k])!r}), got {float(table[b][k])!r} at "
                                     f"{_at(k, first_line)}")


@dataclass(frozen=True)
class Array:
    """An array extra (``<name>.npy``): floats (at most 64-bit), finite, of magnitude at most
    :data:`MAX_MAGNITUDE`, with ``ndim`` dimensions, none of them empty.

    Parameters
    ----------
    ndim : int
    """

    ndim: int

    def check(self, array: np.ndarray, source: str) -> None:
        """Raise a :class:`HybridnavError` unless ``array`` is as declared.

        Parameters
        ----------
        array : ndarray
        source : str
            What the messages start with: the file, or ``result: extras.<name>``.
        """
        what = (f"a {self.ndim}-D array of finite floats (magnitude at most "
                f"{MAX_MAGNITUDE:g}), no dimension empty")
        if array.dtype.kind != "f" or array.dtype.itemsize > 8:
            raise HybridnavError(f"{source}: expected {what}, got dtype {array.dtype}")
        if array.ndim != self.ndim or 0 in array.shape:
            raise HybridnavError(f"{source}: expected {what}, got shape {array.shape}")
        bad = ~(np.abs(array) <= MAX_MAGNITUDE)
        if bad.any():
            at = tuple(int(i) for i in np.unravel_index(int(np.argmax(bad)), array.shape))
            raise HybridnavError(f"{source}: expected {what}, got {float(array[at])!r} at "
                                 f"index {at}")


_XY = Table({"x": "position", "y": "position"})

#: The extras planners record, by the prefix of their names (``<prefix>_<robot>``).
EXTRAS: dict[str, Table | Array] = {
    # field planners: FieldPlanner.trace, one column per traced signal
    "signals": Table({"t": "finite"}, others="any"),
    # hapf: the harmonic potential on its grid and the grid's extent
    "harmonic_potential": Array(ndim=2),
    "harmonic_grid": Table({"x0": "position", "x1": "position", "y0": "position",
                            "y1": "position"},
                           rows=1, less=(("x0", "x1"), ("y0", "y1"))),
    # every swarm search (pbpf, path planners, step planners, pso-ba): best cost per iteration
    "swarm_best": Table({"plan": "index", "iteration": "index", "best": "extended"}),
    # step planners, pso-ba: the final candidates of each search (at most MAX_CANDIDATES of
    # hybridnav.planners.base each; cost inf where infeasible), for the animations
    # (in the order the searches ran: the animation finds a time's search by bisection)
    "candidates": Table({"plan": "index", "t": "finite", "x": "position", "y": "position",
                         "cost": "extended"}, ascending=("plan", "t")),
    # path planners
    "planned": _XY, "rfd_path": _XY, "rfd_seed": _XY,
    # step planners
    "steps": Table({"t": "finite", "target_x": "position", "target_y": "position",
                    "cost": "finite", "mode": ("hold", "goal", "step"), "xdot": "finite",
                    "ydot": "finite"}),
    "waypoints": Table({"t": "finite", "x": "position", "y": "position", "cost": "finite"}),
    # pso-ba (fitness and the bat parameters are nan where no PSO-BA run placed the point)
    "path_points": Table({"t": "finite", "x": "position", "y": "position",
                          "mode": ("goal", "repaired", "wall", "track"), "fitness": "any",
                          "alpha": "any", "gamma": "any"}),
}


def spec_of(name: str, robots: Iterable[str]) -> Table | Array | None:
    """The declaration of the extra ``name`` if it is ``<prefix>_<robot>`` for a declared prefix
    and one of ``robots``, else None (an extra no figure reads).

    Parameters
    ----------
    name : str
    robots : iterable of str
        The result's robot names.
    """
    for robot in robots:
        if name.endswith(f"_{robot}") and name[:-len(robot) - 1] in EXTRAS:
            return EXTRAS[name[:-len(robot) - 1]]
    return None


def check_extra(value: Any, spec: Table | Array, source: str,
                first_line: int | None = None) -> None:
    """Raise a :class:`HybridnavError` unless the extra ``value`` is as ``spec`` declares.

    Parameters
    ----------
    value : mapping or ndarray
        A table (column -> 1-D array) or an array.
    spec : Table or Array
    source : str
        What the messages start with: the file, or ``result: extras.<name>``.
    first_line : int or None
        For a table read from a file, the line of its first row.
    """
    if isinstance(spec, Array) != isinstance(value, np.ndarray):
        raise HybridnavError(f"{source}: expected "
                             f"{'an array (.npy)' if isinstance(spec, Array) else 'a table (.csv)'}"
                             f", got {'an array' if isinstance(value, np.ndarray) else 'a table'}")
    if isinstance(spec, Array):
        spec.check(value, source)
    else:
        spec.check(value, source, first_line)


def declared(spec: Table, table: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The declared columns of ``table`` (the further columns too when ``spec`` allows them):
    what a figure may read, so reading an undeclared column fails in every test that draws it.

    Parameters
    ----------
    spec : Table
    table : mapping
    """
    return {c: v for c, v in table.items() if c in spec.columns or spec.others is not None}


def check_entry(entry: Any, source: str) -> None:
    """Raise a :class:`HybridnavError` unless ``entry`` is a robot's entry of ``result.json`` as
    the writer writes it: a safe ``name``, an ``outcome`` of
    :data:`OUTCOMES`, and metrics as :data:`METRICS` declares them.

    Parameters
    ----------
    entry : any
        The entry as JSON holds it.
    source : str
        What the messages start with, e.g. ``"result.json: robots[0]"``.
    """
    if not isinstance(entry, dict):
        raise HybridnavError(f"{source}: expected an object (name, outcome, metrics), got "
                             f"{type(entry).__name__}")
    for key in ("name", "outcome"):
        if key not in entry:
            raise HybridnavError(f"{source}: {key}: missing")
    if not isinstance(entry["name"], str) or not SAFE_NAME.fullmatch(entry["name"]) \
            or len(entry["name"]) > MAX_ROBOT_NAME:
        raise HybridnavError(f"{source}.name: expected at most 100 letters, digits, '_', '-' or "
                             "'.', got "
                             f"{short_repr(entry['name'])}")
    if not isinstance(entry["outcome"], str) or entry["outcome"] not in OUTCOMES:
        raise HybridnavError(f"{source}.outcome: expected one of {', '.join(OUTCOMES)}, got "
                             f"{short_repr(entry['outcome'])}")
    for key, value in entry.items():
        if key in ("name", "outcome"):
            continue
        problem = METRICS.get(key, OTHER_METRIC).problem(value)
        if problem:
            raise HybridnavError(f"{source}.{show_key(key)}: {problem}")


def _at(k: int, first_line: int | None) -> str:
    """Row ``k`` of a table, as a line of its file or a row index."""
    return f"line {k + first_line}" if first_line is not None else f"row {k}"


def check_column(values: np.ndarray, kind: Any, key: str, first_line: int | None = None) -> None:
    """Raise a :class:`HybridnavError` unless ``values`` hold what ``kind`` declares (see the
    module docstring), naming ``key`` and the first bad row.

    Parameters
    ----------
    values : ndarray
        A 1-D column (numbers as floats, text as ``str``).
    kind : str or tuple
    key : str
        What the messages start with (``<file>: column x``).
    first_line : int or None
        Line of the first row in the file (rows are named by line then), else None.
    """
    if kind == "text" or isinstance(kind, tuple):
        what = _KINDS["text"] if kind == "text" else f"one of {', '.join(kind)}"
        if values.dtype.kind != "U":
            raise HybridnavError(f"{key}: expected {what}, got numbers")
        if isinstance(kind, tuple):
            bad = ~np.isin(values, kind)
            if bad.any():
                k = int(np.argmax(bad))
                raise HybridnavError(f"{key}: expected {what}, got {short_repr(str(values[k]))}"
                                     f" at {_at(k, first_line)}")
        return
    if values.dtype.kind != "f":
        raise HybridnavError(f"{key}: expected {_KINDS[kind]}, got text")
    with np.errstate(invalid="ignore"):
        big = np.isfinite(values) & (np.abs(values) > MAX_MAGNITUDE)
        bad = {"finite": ~np.isfinite(values) | big,
               "index": ~((values >= 0) & (values <= 2.0**53) & (values == np.floor(values))),
               "position": ~(np.abs(values) <= MAX_POSITION),
               "extended": np.isnan(values) | big,
               "any": big}[kind]
    if bad.any():
        k = int(np.argmax(bad))
        raise HybridnavError(f"{key}: expected {_KINDS[kind]}, got {float(values[k])!r} at "
                             f"{_at(k, first_line)}")

