"""The result contract every planner fills: :class:`Result`, :class:`RobotResult`, the writer.

A planner run that writes to a folder leaves there

* ``result.json``: ``scenario``, ``planner``, ``params``, ``seed``, ``version`` and ``robots``, a
  list of objects with ``name``, ``outcome`` (one of :data:`OUTCOMES`), ``path_length``,
  ``smoothness`` (see :func:`smoothness`), ``time_to_goal`` (null unless reached),
  ``min_clearance`` (null when there was nothing to be near), ``compute_time`` and any extra
  per-robot metrics a planner adds;
* ``trajectory_<robot name>.csv`` per robot, header ``t,x,y`` then the model's other state names;
* one file per entry of :attr:`Result.extras`, what a planner records for its diagnostics: a
  *table* (a mapping of column names to equal-length 1-D arrays, numbers or strings) is written as
  ``<name>.csv`` with a header row, an *array* (any ``numpy.ndarray``) as ``<name>.npy``
  (``numpy.save``, no pickles); ``result.json`` lists them under ``extras`` (name -> file).

All are written atomically. :func:`read_result` reads a folder back, extras included, so a
planner's ``diagnostics(scenario, result)`` works on a result read from disk.

What a robot's metrics and each planner's extras hold is declared once, in
:mod:`hybridnav.resultspec`: :class:`Result` and :func:`write_result` refuse to write anything
else, and :func:`read_result` refuses to read anything else (naming the file and the key), so a
figure drawn from a result folder never meets a missing column or a NaN it cannot draw.
"""

from __future__ import annotations

import csv
import io
import tokenize
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fileio import (
    atomic_write_bytes,
    atomic_write_text,
    dumps_json,
    json_ready,
    read_json,
    read_text_file,
)
from hybridnav.limits import MAX_GRID_CELLS
from hybridnav.params import short_repr
from hybridnav.resultspec import (
    OUTCOMES,
    SAFE_NAME,
    Array,
    Table,
    check_column,
    check_entry,
    check_extra,
    show_key,
    spec_of,
)

__all__ = [
    "OUTCOMES",
    "Result",
    "RobotResult",
    "check_extras",
    "path_length",
    "read_result",
    "read_run",
    "smoothness",
    "write_result",
]

#: Longest text value of an extra table's text column.
MAX_TEXT = 1000


def path_length(xy: np.ndarray) -> float:
    """Length of a polyline given as an ``(T, 2)`` array of points."""
    xy = np.asarray(xy, dtype=float)
    if len(xy) < 2:
        return 0.0
    return float(np.hypot(*np.diff(xy, axis=0).T).sum())


def smoothness(xy: np.ndarray) -> float:
    """Total turning of a polyline: the sum of absolute heading changes, in radians.

    Headings are taken between consecutive *distinct* points (repeated points, e.g. a robot
    standing still, are skipped); each change between consecutive headings is wrapped to
    ``(-pi, pi]`` before its absolute value is summed. A straight line gives 0, a right-angle
    corner ``pi / 2``, a reversal ``pi``; inserting points along a straight piece changes nothing.

    Parameters
    ----------
    xy : array_like, shape (T, 2)
        The points of the path, in order.

    Returns
    -------
    float
        0 for fewer than three distinct points.

    Examples
    --------
    >>> round(smoothness([[0, 0], [1, 0], [1, 0], [1, 1], [2, 1]]), 12) == round(np.pi, 12)
    True
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    d = np.diff(xy, axis=0)
    d = d[np.any(d != 0.0, axis=1)]
    if len(d) < 2:
        return 0.0
    turn = np.diff(np.arctan2(d[:, 1], d[:, 0]))
    turn = np.mod(turn + np.pi, 2.0 * np.pi) - np.pi      # [-pi, pi)
    turn = np.where(turn <= -np.pi, turn + 2.0 * np.pi, turn)  # (-pi, pi]
    return float(np.abs(turn).sum())


@dataclass
class RobotResult:
    """Outcome, metrics and trajectory of one robot in one run.

    Parameters
    ----------
    name : str
        Robot name (also used in the trajectory file name).
    outcome : str
        One of :data:`OUTCOMES`.
    t : ndarray, shape (T,)
        Sample times in seconds.
    states : ndarray, shape (T, nx)
        States at those times; the first two columns are ``x`` and ``y``.
    state_names : sequence of str
        ``("x", "y", ...)``, the model's state names.
    time_to_goal : float or None
        Time at which the goal was reached; must be given exactly when ``outcome == "reached"``.
    min_clearance : float or None
        Smallest clearance between the robot's footprint and any obstacle or other robot.
    compute_time : float
        Wall-clock seconds the planner spent on this robot.
    metrics : dict
        Further per-robot metrics (written into ``result.json`` beside the standard ones).
    """

    name: str
    outcome: str
    t: np.ndarray
    states: np.ndarray
    state_names: Sequence[str]
    time_to_goal: float | None = None
    min_clearance: float | None = None
    compute_time: float = 0.0
    metrics: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise HybridnavError(
                f"robot {self.name}: outcome: expected one of {', '.join(OUTCOMES)}, got "
                f"{self.outcome!r}"
            )
        if not isinstance(self.name, str) or not SAFE_NAME.fullmatch(self.name):
            raise HybridnavError(
                f"robot name: expected letters, digits, '_', '-' or '.', got {self.name!r}"
            )
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        self.states = np.asarray(self.states, dtype=float).reshape(len(self.t), -1)
        self.state_names = tuple(self.state_names)
        if self.state_names[:2] != ("x", "y") or len(self.state_names) != self.states.shape[1]:
            raise HybridnavError(
                f"robot {self.name}: state_names: expected ('x', 'y', ...) with one name per state"
                f" column ({self.states.shape[1]}), got {self.state_names}"
            )
        if (self.outcome == "reached") != (self.time_to_goal is not None):
            raise HybridnavError(
                f"robot {self.name}: time_to_goal: expected a time exactly when the outcome is "
                f"'reached' (outcome {self.outcome!r}, time_to_goal {self.time_to_goal!r})"
            )

    @property
    def path_length(self) -> float:
        """Length of the travelled ``(x, y)`` polyline."""
        return path_length(self.states[:, :2])

    @property
    def smoothness(self) -> float:
        """Sum of absolute heading changes along the travelled path (:func:`smoothness`)."""
        return smoothness(self.states[:, :2])

    def summary(self) -> dict[str, Any]:
        """The robot's entry in ``result.json``."""
        out = {
            "name": self.name,
            "outcome": self.outcome,
            "path_length": self.path_length,
            "smoothness": self.smoothness,
            "time_to_goal": self.time_to_goal,
            "min_clearance": self.min_clearance,
            "compute_time": self.compute_time,
        }
        out.update(self.metrics)
        return json_ready(out)

    def trajectory_csv(self) -> str:
        """The trajectory file's text: header ``t,x,y,...`` and one row per sample."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(("t",) + self.state_names)
        for ti, row in zip(self.t, self.states):
            w.writerow([repr(float(ti))] + [repr(float(v)) for v in row])
        return buf.getvalue()


@dataclass
class Result:
    """One planner run on one scenario: what was run, every robot's outcome, and the extras.

    ``extras`` holds what the planner recorded for its diagnostics (per-cycle signals, planned
    paths, search histories, fields): name -> table (mapping of column -> 1-D array, all of one
    length) or ``numpy.ndarray``. They are written beside ``result.json`` and read back with it
    (see the module docstring), so nothing a diagnostic needs stays on the planner object.
    """

    scenario: str
    planner: str
    params: Mapping[str, Any]
    seed: int | None
    robots: list[RobotResult]
    version: str = ""
    extras: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.version:
            from hybridnav import __version__

            self.version = __version__
        names = [r.name for r in self.robots]
        if len(set(names)) != len(names):
            raise HybridnavError(f"result: robots: duplicate robot names in {names}")
        self.extras = check_extras(self.extras, names)

    def extra_files(self) -> dict[str, str]:
        """Extra name -> the file it is written to (``<name>.csv`` or ``<name>.npy``)."""
        return {k: f"{k}.npy" if isinstance(v, np.ndarray) else f"{k}.csv"
                for k, v in self.extras.items()}

    def _extras_entry(self) -> dict[str, Any]:
        """``result.json``'s ``extras``: name -> ``{"file": ..., "text": [text columns]}``."""
        out: dict[str, Any] = {}
        for k, file in self.extra_files().items():
            v = self.extras[k]
            out[k] = {"file": file} if isinstance(v, np.ndarray) else \
                {"file": file, "text": [c for c, a in v.items() if a.dtype.kind == "U"]}
        return out

    def to_dict(self) -> dict[str, Any]:
        """The content of ``result.json``."""
        return {
            "scenario": self.scenario,
            "planner": self.planner,
            "params": dict(self.params),
            "seed": self.seed,
            "version": self.version,
            "robots": [r.summary() for r in self.robots],
            "extras": self._extras_entry(),
        }

    def write(self, folder: str | Path) -> Path:
        """Write ``result.json`` and the trajectory CSVs into ``folder`` (created if needed)."""
        return write_result(self, folder)


def write_result(result: Result, folder: str | Path) -> Path:
    """Write a :class:`Result` to ``folder``; returns the path of ``result.json``.

    Trajectories are written first and ``result.json`` last, so a folder with a ``result.json``
    is complete.

    Parameters
    ----------
    result : Result
    folder : str or Path
        Created if needed.

    Raises
    ------
    HybridnavError
        A robot's metric is not as :data:`hybridnav.resultspec.METRICS` declares it (e.g. a
        metric that may not be null is infinite: JSON writes null for it); nothing is written.
    """
    content = result.to_dict()
    for i, entry in enumerate(content["robots"]):
        check_entry(entry, f"result: robots[{i}]")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for r in result.robots:
        atomic_write_text(folder / f"trajectory_{r.name}.csv", r.trajectory_csv())
    for name, file in result.extra_files().items():
        value = result.extras[name]
        if isinstance(value, np.ndarray):
            buf = io.BytesIO()
            np.save(buf, value, allow_pickle=False)
            atomic_write_bytes(folder / file, buf.getvalue())
        else:
            atomic_write_text(folder / file, _table_csv(value))
    path = folder / "result.json"
    atomic_write_text(path, dumps_json(content))
    return path


#: The keys of ``result.json`` (``extras`` may be missing: results written before extras).
_TOP_KEYS = ("scenario", "planner", "params", "seed", "version", "robots", "extras")


def read_result(folder: str | Path) -> Result:
    """Read a folder written by :func:`write_result` back into a :class:`Result`.

    Everything is checked before it is used: ``result.json`` is JSON as the writer writes it
    (no NaN or Infinity, no number beyond the float range or Python's integer digit limit, no
    duplicate keys), its keys have their types, every robot's entry is as
    :func:`hybridnav.resultspec.check_entry` requires (outcome, metrics of the declared types),
    every trajectory holds finite numbers at strictly increasing times, and every extra a figure
    reads is as :data:`hybridnav.resultspec.EXTRAS` declares it.

    Parameters
    ----------
    folder : str or Path
        The folder :func:`write_result` wrote.

    Returns
    -------
    Result

    Raises
    ------
    HybridnavError
        Naming the file and the key, for anything that is not a result folder as
        :func:`write_result` writes it (missing or unreadable files, wrong types, rows of the
        wrong length, non-finite or huge numbers where the writer writes none, missing or
        renamed columns of a declared extra, extras that name files outside the folder or
        arrays beyond the limits).
    """
    folder = Path(folder)
    path = folder / "result.json"
    if not path.is_file():
        raise HybridnavError(f"{path}: no such file (expected a hybridnav result folder)")
    data = read_json(path, "result file")
    if not isinstance(data, dict):
        raise HybridnavError(f"{path}: expected a JSON object at the top level, got "
                             f"{type(data).__name__}")
    for key in data:
        if key not in _TOP_KEYS:
            raise HybridnavError(f"{path}: {show_key(key)}: not a key of result.json "
                                 f"(expected {', '.join(_TOP_KEYS)})")
    for key in _TOP_KEYS[:-1]:
        if key not in data:
            raise HybridnavError(f"{path}: {key}: missing (expected a hybridnav result.json)")
    for key, kind, what in (("scenario", str, "a name"), ("planner", str, "a name"),
                            ("version", str, "a string"), ("params", dict, "an object"),
                            ("robots", list, "an array"),
                            ("extras", dict, "an object of name -> file")):
        value = data.get(key, {})
        if not isinstance(value, kind) or (what == "a name" and not value.strip()):
            raise HybridnavError(f"{path}: {key}: expected {what}, got {short_repr(value)}")
    seed = data["seed"]
    if seed is not None and (type(seed) is not int or seed < 0):
        raise HybridnavError(f"{path}: seed: expected a non-negative integer or null, got "
                             f"{short_repr(seed)}")
    for i, entry in enumerate(data["robots"]):
        check_entry(entry, f"{path}: robots[{i}]")
    robots = []
    standard = {"name", "outcome", "path_length", "smoothness", "time_to_goal", "min_clearance",
                "compute_time"}
    for i, entry in enumerate(data["robots"]):
        t, states, names = _read_trajectory(folder / f"trajectory_{entry['name']}.csv")
        try:
            robots.append(RobotResult(
                name=entry["name"], outcome=entry["outcome"], t=t, states=states,
                state_names=names, time_to_goal=entry.get("time_to_goal"),
                min_clearance=entry.get("min_clearance"),
                compute_time=entry.get("compute_time", 0.0),
                metrics={k: v for k, v in entry.items() if k not in standard},
            ))
        except HybridnavError as exc:
            raise HybridnavError(f"{path}: robots[{i}]: {exc}") from None
    names = [r.name for r in robots]
    if len(set(names)) != len(names):
        raise HybridnavError(f"{path}: robots: expected distinct names, got {short_repr(names)}")
    extras = {name: _read_extra(folder, path, name, entry, names)
              for name, entry in data.get("extras", {}).items()}
    try:
        return Result(scenario=data["scenario"], planner=data["planner"], params=data["params"],
                      seed=seed, robots=robots, version=data["version"], extras=extras)
    except HybridnavError as exc:
        raise HybridnavError(f"{path}: {exc}") from None


def read_run(folder: str | Path, scenario: str | Path | None = None) -> tuple[Result, Any]:
    """A result folder with the scenario it was run on (what ``hybridnav plot`` and
    ``hybridnav animate`` draw).

    Parameters
    ----------
    folder : str or Path
        The folder :func:`write_result` wrote.
    scenario : str or Path, optional
        The scenario the result is of (a built-in name or a ``.toml`` file); default: the
        built-in scenario of the name ``result.json`` gives (``result.json`` never chooses a file
        to read).

    Returns
    -------
    (Result, Scenario)

    Raises
    ------
    HybridnavError
        As :func:`read_result`; a scenario name that is not built in (without ``scenario``); a
        scenario of another name, other robots or other starts than the result's.
    """
    from hybridnav.world import list_scenarios, load_scenario

    result = read_result(folder)
    listing = Path(folder) / "result.json"
    scen = short_repr(result.scenario)
    if scenario is None:
        # only a built-in by its name: result.json does not choose a file to read
        if result.scenario not in {n for n, _ in list_scenarios()}:
            raise HybridnavError(f"{listing}: scenario: {scen} is not a built-in scenario; pass "
                                 "the scenario file the result was run on with --scenario")
        loaded = load_scenario(result.scenario)
    else:
        loaded = load_scenario(scenario)
    where = f"--scenario {scenario}" if scenario else f"scenario {scen}"
    if loaded.name != result.scenario:
        raise HybridnavError(f"{listing}: scenario: the result is of scenario {scen}, not "
                             f"{short_repr(loaded.name)} ({where})")
    # a file scenario may share a built-in's name: the robots must be the result's
    names = [r.name for r in loaded.robots]
    if names != [r.name for r in result.robots]:
        got = [r.name for r in result.robots]
        raise HybridnavError(f"{listing}: robots: expected the robots of {where} "
                             f"{short_repr(names)}, got {short_repr(got)}; pass the scenario "
                             "the result was run on with --scenario")
    for rr, r in zip(result.robots, loaded.robots):
        if not np.allclose(rr.states[0, :2], r.start):
            raise HybridnavError(
                f"{Path(folder) / f'trajectory_{rr.name}.csv'}: line 2: robot {rr.name} "
                f"starts at {tuple(float(v) for v in rr.states[0, :2])}, in {where} at "
                f"{tuple(float(v) for v in r.start)}: its robots do not start where the "
                "result's do; pass the scenario the result was run on with --scenario")
    return result, loaded


# --------------------------------------------------------------------------------------------
# extras: tables and arrays


def check_extras(extras: Mapping[str, Any], robots: Sequence[str] = ()) -> dict[str, Any]:
    """Validate and normalize the extras of a result (tables become dicts of 1-D arrays: numbers
    and booleans as ``float64``, text as ``str``).

    Parameters
    ----------
    extras : mapping
        Name -> table (column -> 1-D array) or ``numpy.ndarray``.
    robots : sequence of str
        The result's robot names: an extra ``<prefix>_<robot>`` of a prefix that
        :data:`hybridnav.resultspec.EXTRAS` declares must be as declared.

    Returns
    -------
    dict
        The normalized extras.

    Raises
    ------
    HybridnavError
        A name that is not a safe file name or collides with the result's own files; a table
        whose columns are not named, 1-D and of one length, or hold text that is not one line of
        at most :data:`MAX_TEXT` printable characters; an array that is not numbers or has more
        than :data:`hybridnav.limits.MAX_GRID_CELLS` entries; a declared extra that is not as
        declared (a missing column, ``nan`` in a column of finite numbers, ...).
    """
    if not isinstance(extras, Mapping):
        raise HybridnavError(f"result: extras: expected a mapping, got {type(extras).__name__}")
    out: dict[str, Any] = {}
    for name, value in extras.items():
        if not _extra_name_ok(name):
            raise HybridnavError(f"result: extras: expected names of letters, digits, '_', '-' "
                                 f"or '.' other than result and trajectory_*, got {name!r}")
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf" or value.size > MAX_GRID_CELLS:
                raise HybridnavError(f"result: extras.{name}: expected an array of numbers with "
                                     f"at most {MAX_GRID_CELLS} entries, got {value.dtype} "
                                     f"{value.shape}")
            out[name] = value
            continue
        if not isinstance(value, Mapping) or not value:
            raise HybridnavError(f"result: extras.{name}: expected a table (column -> 1-D array)"
                                 f" or a numpy array, got {type(value).__name__}")
        table = {}
        for col, v in value.items():
            if not isinstance(col, str) or not SAFE_NAME.fullmatch(col):
                raise HybridnavError(f"result: extras.{name}: expected column names of letters, "
                                     f"digits, '_', '-' or '.', got {col!r}")
            arr = np.asarray(v)
            if arr.ndim != 1:
                raise HybridnavError(f"result: extras.{name}.{col}: expected a named 1-D column")
            if arr.dtype.kind in "biuf":
                arr = arr.astype(float)
            elif arr.dtype.kind in "US" or (arr.dtype.kind == "O" and all(
                    isinstance(x, str) for x in arr)):
                arr = arr.astype(str)
                bad = [x for x in arr if len(x) > MAX_TEXT or not x.isprintable()]
                if bad:
                    raise HybridnavError(f"result: extras.{name}.{col}: expected one-line "
                                         f"printable text of at most {MAX_TEXT} characters, got "
                                         f"{short_repr(bad[0])}")
            else:
                raise HybridnavError(f"result: extras.{name}.{col}: expected numbers or text, "
                                     f"got {arr.dtype}")
            table[col] = arr
        if len({len(a) for a in table.values()}) != 1:
            raise HybridnavError(f"result: extras.{name}: expected columns of one length, got "
                                 f"{ {k: len(a) for k, a in table.items()} }")
        out[name] = table
    for name, value in out.items():
        spec = spec_of(name, robots)
        if spec is not None:
            check_extra(value, spec, f"result: extras.{name}")
    return out


def _extra_name_ok(name: Any) -> bool:
    return (isinstance(name, str) and bool(SAFE_NAME.fullmatch(name)) and name != "result"
            and not name.startswith("trajectory_") and name not in (".", ".."))


def _table_csv(table: Mapping[str, np.ndarray]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(table))
    cols = [[repr(float(x)) for x in a] if a.dtype.kind == "f" else [str(x) for x in a]
            for a in table.values()]
    w.writerows(zip(*cols))
    return buf.getvalue()


def _read_extra(folder: Path, listing: Path, name: Any, entry: Any, robots: list[str]) -> Any:
    if not _extra_name_ok(name):                       # before any file is opened
        raise HybridnavError(f"{listing}: extras: expected names of letters, digits, '_', '-' "
                             f"or '.', got {short_repr(name)}")
    if not isinstance(entry, dict) or entry.get("file") not in (f"{name}.csv", f"{name}.npy"):
        raise HybridnavError(f"{listing}: extras.{name}: expected {{\"file\": \"{name}.csv\" or "
                             f"\"{name}.npy\"}}, got {short_repr(entry)}")
    spec = spec_of(name, robots)
    if spec is not None:
        ext, what = ("npy", "an array") if isinstance(spec, Array) else ("csv", "a table")
        if entry["file"] != f"{name}.{ext}":
            raise HybridnavError(f"{listing}: extras.{name}.file: expected {name}.{ext} ({what}),"
                                 f" got {short_repr(entry['file'])}")
    path = folder / entry["file"]
    if not path.is_file():
        raise HybridnavError(f"{path}: no such file (listed in result.json extras)")
    if entry["file"].endswith(".npy"):
        value = _read_npy(path)
        if spec is not None:
            check_extra(value, spec, str(path))
        return value
    text_cols = entry.get("text", [])
    if not isinstance(text_cols, list) or not all(isinstance(c, str) for c in text_cols):
        raise HybridnavError(f"{listing}: extras.{name}.text: expected a list of column names, "
                             f"got {short_repr(text_cols)}")
    rows = _csv_rows(path, "extra table")
    header = rows[0]
    if len(set(header)) != len(header) or not all(SAFE_NAME.fullmatch(c) for c in header):
        raise HybridnavError(f"{path}: line 1: expected distinct column names of letters, "
                             f"digits, '_', '-' or '.', got {_header_text(header)}")
    if isinstance(spec, Table):                        # before any value is read
        spec.check_names(header, str(path))
    table = {}
    for j, col in enumerate(header):
        values = [r[j] for r in rows[1:]]
        if col in text_cols:
            table[col] = np.array(values, dtype=str)
            bad = [v for v in values if len(v) > MAX_TEXT or not v.isprintable()]
            if bad:
                raise HybridnavError(f"{path}: column {col}: expected one-line printable text "
                                     f"of at most {MAX_TEXT} characters, got {short_repr(bad[0])}")
        else:
            table[col] = _floats(values, path, f"column {col}")
    if spec is not None:
        check_extra(table, spec, str(path), first_line=2)
    return table


def _floats(values: list[str], path: Path, key: str) -> np.ndarray:
    """CSV fields as floats; the message names the line (the header is line 1)."""
    out = []
    for k, v in enumerate(values):
        try:
            out.append(float(v))
        except ValueError:
            raise HybridnavError(f"{path}: {key}: expected numbers, got {short_repr(v)} at line "
                                 f"{k + 2}") from None
    return np.array(out, dtype=float)


def _read_npy(path: Path) -> np.ndarray:
    """A ``.npy`` array of numbers, its header checked before any data is read."""
    try:
        with open(path, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                np.lib.format.read_array_header_2_0
            shape, _, dtype = read(fh)
            count = int(np.prod(shape, dtype=object))
            if dtype.kind not in "biuf" or count > MAX_GRID_CELLS:
                raise HybridnavError(f"{path}: expected an array of numbers with at most "
                                     f"{MAX_GRID_CELLS} entries, got {dtype} {shape}")
            fh.seek(0)
            return np.load(fh, allow_pickle=False)
    except HybridnavError:
        raise
    # what numpy's header parser (tokenize, ast.literal_eval) raises on damaged bytes
    except (OSError, ValueError, EOFError, SyntaxError, TypeError, OverflowError,
            RecursionError, tokenize.TokenError) as exc:
        why = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise HybridnavError(f"{path}: not a numpy .npy array of numbers: {why}") from None


def _csv_rows(path: Path, what: str) -> list[list[str]]:
    """The rows of a CSV file with a header, all as long as the header."""
    text = read_text_file(path, what)
    try:
        rows = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise HybridnavError(f"{path}: not a CSV file: {exc}") from None
    if not rows or not rows[0]:
        raise HybridnavError(f"{path}: line 1: expected a header row")
    for k, r in enumerate(rows[1:], start=2):
        if len(r) != len(rows[0]):
            raise HybridnavError(f"{path}: line {k}: expected {len(rows[0])} fields (as the "
                                 f"header), got {len(r)}")
    return rows


def _read_trajectory(path: Path) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Times and states of a trajectory CSV: finite numbers (of magnitude at most
    :data:`hybridnav.resultspec.MAX_MAGNITUDE`; ``x`` and ``y`` at most
    :data:`hybridnav.limits.MAX_POSITION`), at strictly increasing times."""
    if not path.is_file():
        raise HybridnavError(f"{path}: no such file (every robot has a trajectory CSV)")
    rows = _csv_rows(path, "trajectory")
    if rows[0][:3] != ["t", "x", "y"]:
        raise HybridnavError(f"{path}: line 1: expected the header t,x,y,..., got "
                             f"{_header_text(rows[0])}")
    if len(rows) < 2:
        raise HybridnavError(f"{path}: expected at least one sample after the header")
    cols = [_floats([r[j] for r in rows[1:]], path, f"column {show_key(name)}")
            for j, name in enumerate(rows[0])]
    for j, (name, col) in enumerate(zip(rows[0], cols)):   # x and y: what the figures draw
        check_column(col, "position" if j in (1, 2) else "finite",
                     f"{path}: column {show_key(name)}", first_line=2)
    back = np.flatnonzero(np.diff(cols[0]) <= 0)
    if len(back):
        k = int(back[0]) + 1
        raise HybridnavError(f"{path}: column t: expected strictly increasing times, got "
                             f"{float(cols[0][k])!r} after {float(cols[0][k - 1])!r} at line "
                             f"{k + 2}")
    data = np.column_stack(cols)
    return data[:, 0], data[:, 1:], tuple(rows[0][1:])


def _header_text(header: list[str]) -> str:
    """A CSV header for a message: shown when it is a row of names, else only described (a file
    that is not a hybridnav table, e.g. a link to a secret, is never echoed)."""
    if header and all(SAFE_NAME.fullmatch(c) for c in header) and sum(map(len, header)) < 200:
        return short_repr(",".join(header))
    return f"a first line of {len(header)} field(s) that are not all column names"
