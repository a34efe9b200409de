"""Runs you can watch: a GIF (Pillow) or an MP4 (ffmpeg) of a result folder or a tuning job.

:func:`animate` draws one frame per moment of a run (evenly spaced over it, at most
``max_frames``): the scenario as :func:`~hybridnav.plotting.draw_scenario` draws it (drawn once),
and per frame every robot's trail up to that time and its current pose (its footprint's disks,
its body's outline where the model has one, :meth:`hybridnav.models.Model.outline`, and its
heading), the moving circles where they are then
(:func:`~hybridnav.plotting.scenes.draw_moving_obstacles`), a moving target (``goal_follow``)
where the followed robot is, and for the swarm planners (``pso-ba``, ``fastep-kinematic``,
``aco-kinematic``) the candidates of the robot's latest planning step (the result's
``candidates_<robot>`` extra). The title gives the time.

:func:`animate_runs` draws several runs on one scenario one after the other, the earlier paths
faint: :func:`hybridnav.tuner.animate_tuning` draws a tuning job's best system per generation
with it, titled ``generation g: score s``.

The file is written atomically: a failed or interrupted run leaves no half-written file.
"""

from __future__ import annotations

import logging
import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle as CirclePatch
from matplotlib.patches import Polygon as PolygonPatch

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_path, check_writable
from hybridnav.params import check_fps, short_repr
from hybridnav.plotting.diagnostics import extras_of
from hybridnav.plotting.scenes import draw_moving_obstacles, draw_scenario
from hybridnav.results import Result, read_run

__all__ = ["ANIMATION_FORMATS", "Animated", "animate", "animate_result", "animate_runs"]

log = logging.getLogger(__name__)

#: The file suffixes :func:`animate` writes: a GIF (Pillow) or an MP4 (ffmpeg on PATH).
ANIMATION_FORMATS = ("gif", "mp4")

#: The file a tuning job's folder holds for its animation (``hybridnav.tuner.write_generations``).
GENERATIONS_FILE = "generations.json"

#: Most pixels of all a GIF's frames together (they are collected in memory, 1 byte a pixel)
_MAX_GIF_PIXELS = 2e9

#: Frames per run at most in :func:`animate_runs` (a tuning job's generation driving its run).
_PER_RUN = 8

_OUTCOME_MARK = {"reached": ("*", "green"), "collided": ("X", "red"),
                 "out_of_bounds": ("X", "purple"), "stuck": ("s", "orange"),
                 "timeout": ("D", "gray")}


@dataclass(frozen=True)
class Animated:
    """What :func:`animate` wrote: the file, its frames and the time (or generation) each shows.

    Attributes
    ----------
    path : pathlib.Path
    times : tuple of float
        Per frame, the time of the run it shows (seconds).
    labels : tuple of str
        Per frame, its title.
    size : (int, int)
        Width and height of a frame in pixels.
    fps : float
        Frames per second.
    """

    path: Path
    times: tuple[float, ...]
    labels: tuple[str, ...]
    size: tuple[int, int]
    fps: float

    @property
    def frames(self) -> int:
        """Number of frames."""
        return len(self.times)


def animate(source: str | os.PathLike[str] | Result, path: str | os.PathLike[str] | None = None,
            *, scenario: Any = None, fps: float = 10.0, dpi: int = 80, max_frames: int = 150,
            fmt: str | None = None) -> Animated:
    """Write an animation of a run (a result folder or a :class:`~hybridnav.results.Result`) as
    a GIF or an MP4 (:func:`animate_result`; a tuning job's folder:
    :func:`hybridnav.tuner.animate_tuning`).

    Parameters
    ----------
    source : str, path-like or Result
        A folder ``hybridnav run`` wrote (``result.json``), or a result (then ``scenario`` is
        required).
    path : str or path-like, optional
        The file to write; default ``animation.gif`` in the folder.
    scenario : Scenario, str or path-like, optional
        The scenario the result is of: for a folder, a built-in name or a ``.toml`` file
        (default: the built-in scenario the result names); for a result, a Scenario too.
    fps : float
        Frames per second, in [0.01, 100] (:func:`hybridnav.params.check_fps`: a GIF cannot
        show a frame longer than 655.35 s).
    dpi : int
        Resolution, in [10, 600] (a frame is 6.4 x 6.4 inches: 512 x 512 pixels at 80).
    max_frames : int
        Most frames, in [1, 10000] (one frame shows the end of the run).
    fmt : {"gif", "mp4"}, optional
        Default: from the suffix of ``path``.

    Returns
    -------
    Animated

    Raises
    ------
    HybridnavError
        Naming the file and what was expected: a folder that is not a result's, a damaged
        result, a scenario it was not run on, an unknown format or suffix, an MP4 without ffmpeg
        on PATH, settings out of range.
    """
    _check_settings(fps, dpi, max_frames)
    if isinstance(source, Result):
        if path is None:
            raise HybridnavError("animate: path: expected the file to write for a Result "
                                 "(a folder's default is <folder>/animation.gif)")
        return animate_result(source, _scenario_of(source, scenario), path, fps=fps, dpi=dpi,
                              max_frames=max_frames, fmt=fmt)
    folder = Path(source)
    if not folder.is_dir():
        raise HybridnavError(f"{folder}: no such folder (expected a folder written by "
                             "'hybridnav run' or 'hybridnav tune')")
    if _is_tuning(folder):
        raise HybridnavError(f"{folder}: a tuning job's folder, not a run's: "
                             "hybridnav.tuner.animate_tuning animates it (hybridnav animate "
                             "does)")
    out = Path(path) if path is not None else folder / "animation.gif"
    fmt = _format(out, fmt)                        # before any file is read
    check_writable(out)
    result, scen = read_run(folder, scenario)
    return animate_result(result, scen, out, fps=fps, dpi=dpi, max_frames=max_frames, fmt=fmt)


def animate_result(result: Result, scenario: Any, path: str | os.PathLike[str], *,
                   fps: float = 10.0, dpi: int = 80, max_frames: int = 150,
                   fmt: str | None = None) -> Animated:
    """Write an animation of one run: frames at evenly spaced times from 0 to the end of the
    longest robot's run (at every sample time when there are at most ``max_frames``; a single
    frame shows the end).

    Parameters
    ----------
    result : Result
    scenario : Scenario
        The scenario the result is of.
    path : str or path-like
        The ``.gif`` or ``.mp4`` to write.
    fps, dpi, max_frames, fmt :
        As for :func:`animate`.

    Returns
    -------
    Animated
    """
    fps, dpi, max_frames = _check_settings(fps, dpi, max_frames)
    path = Path(path)
    fmt = _format(path, fmt)
    t_end = max(float(rr.t[-1]) for rr in result.robots) if result.robots else 0.0
    samples = np.unique(np.concatenate([rr.t for rr in result.robots])) if result.robots \
        else np.zeros(1)
    # every sample when there are few, else evenly spaced times (farther apart than samples)
    times = samples if len(samples) <= max_frames else _spread(0.0, t_end, max_frames)
    stage = _Stage(scenario, dpi)
    runs = [_Track.of(rr) for rr in result.robots]
    candidates = extras_of(result, "candidates")
    stage.legend(runs, result.planner)
    digits = _digits(times)
    labels = [f"{scenario.name}: {result.planner}, t = {t:.{digits}f} s" for t in times]

    def frame(k: int) -> None:
        t = float(times[k])
        stage.moment(t, runs, candidates)
        stage.title(labels[k])

    _write(stage, path, fmt, fps, dpi, len(times), frame)
    return Animated(path, tuple(float(t) for t in times), tuple(labels), stage.size(dpi), fps)


def animate_runs(scenario: Any, runs: Sequence[tuple[str, Any]],
                 path: str | os.PathLike[str], *, fps: float = 4.0, dpi: int = 80,
                 max_frames: int = 150, fmt: str | None = None) -> Animated:
    """Write an animation of several runs on one scenario, one after the other (e.g. a tuning
    job's best system per generation): each run gets up to a few frames (fewer when there are
    many runs; with more runs than ``max_frames``, evenly chosen runs, the last among them),
    its last frame showing its whole path; earlier runs' paths stay, faint. A frame's title is
    its run's, then the time.

    Parameters
    ----------
    scenario : Scenario
    runs : sequence of (str, Result)
        Each run's title and result (its robots those of ``scenario``).
    path : str or path-like
        The ``.gif`` or ``.mp4`` to write.
    fps, dpi, max_frames, fmt :
        As for :func:`animate`.

    Returns
    -------
    Animated
    """
    fps, dpi, max_frames = _check_settings(fps, dpi, max_frames)
    path = Path(path)
    fmt = _format(path, fmt)
    if not runs:
        raise HybridnavError("animate_runs: runs: expected at least one (title, result)")
    runs = list(runs)
    if len(runs) > max_frames:                     # evenly chosen runs, the last kept
        pick = np.unique(_spread(0, len(runs) - 1, max_frames).round().astype(int))
        runs = [runs[i] for i in pick]
    tracks = [[_Track.of(rr) for rr in res.robots] for _, res in runs]
    per = max(1, min(_PER_RUN, max_frames // len(runs)))
    plan: list[tuple[int, float]] = []                 # (run, time) per frame
    for j, tr in enumerate(tracks):
        t_end = max(x.t[-1] for x in tr)
        ts = np.linspace(0.0, t_end, per + 1)[1:] if per > 1 else np.array([t_end])
        plan += [(j, float(t)) for t in ts]
    digits = _digits(np.array([t for _, t in plan]))
    labels = [f"{runs[j][0]}, t = {t:.{digits}f} s" for j, t in plan]
    stage = _Stage(scenario, dpi)
    shown = {"run": -1}

    def frame(k: int) -> None:
        j, t = plan[k]
        if j != shown["run"]:
            if shown["run"] >= 0:                     # the previous run's path stays
                for tr in tracks[shown["run"]]:
                    stage.ax.plot(tr.xy[:, 0], tr.xy[:, 1], color="0.55", linewidth=0.8,
                                  alpha=0.6, zorder=6)
                stage.still()
            shown["run"] = j
            stage.legend(tracks[j], runs[j][1].planner)
        stage.moment(t, tracks[j], {})
        stage.title(labels[k])

    _write(stage, path, fmt, fps, dpi, len(plan), frame)
    return Animated(path, tuple(t for _, t in plan), tuple(labels), stage.size(dpi), fps)


# ---- the frames ---------------------------------------------------------------------------------


@dataclass
class _Track:
    """One robot's run: its times and states (the first two columns x, y), outcome."""

    name: str
    t: np.ndarray
    states: np.ndarray
    outcome: str

    @classmethod
    def of(cls, rr) -> _Track:
        return cls(rr.name, np.asarray(rr.t, dtype=float), np.asarray(rr.states, dtype=float),
                   rr.outcome)

    @property
    def xy(self) -> np.ndarray:
        return self.states[:, :2]

    def index(self, t: float) -> int:
        """The last sample at or before ``t`` (the robot stays at its last state after it)."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))


@dataclass
class _Stage:
    """A figure with the scenario drawn once; :meth:`moment` redraws what moves."""

    scenario: Any
    dpi: int
    fig: Figure = field(init=False)
    ax: Any = field(init=False)
    models: dict[str, Any] = field(init=False)
    trails: dict[str, Line2D] = field(init=False)
    moving: list[Artist] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        s = self.scenario
        self.fig = Figure(figsize=(6.4, 6.4), dpi=self.dpi)
        FigureCanvasAgg(self.fig)
        # a fixed layout: frames of one size whatever the title says
        self.ax = self.fig.add_axes((0.11, 0.08, 0.86, 0.84))
        draw_scenario(s, ax=self.ax, t=0.0, moving=False)
        self.ax.set_xlabel(f"x ({s.units})")
        self.ax.set_ylabel(f"y ({s.units})")
        self.models = {r.name: s.model(r, jit=False) for r in s.robots}
        self.trails = {}
        for i, r in enumerate(s.robots):
            (line,) = self.ax.plot([], [], color=f"C{i % 10}", linewidth=1.6, zorder=7)
            self.trails[r.name] = line

    def size(self, dpi: int) -> tuple[int, int]:
        w, h = self.fig.canvas.get_width_height()
        return int(w), int(h)

    def title(self, text: str) -> None:
        self.ax.title.set_text(text)
        self.ax.title.set_fontsize(10)

    def still(self) -> None:
        """Something that stays changed (a legend, a faded path): draw the background again."""
        self._background = None

    def render(self) -> np.ndarray:
        """The frame as an ``(h, w, 4)`` RGBA array: the background drawn once (everything but
        the trails, what :meth:`moment` drew and the title), then those on it."""
        canvas = self.fig.canvas
        ax = self.ax
        dynamic = [*self.trails.values(), *self.moving]
        if getattr(self, "_background", None) is None:
            text = ax.title.get_text()
            ax.title.set_text("")
            for a in dynamic:
                a.set_visible(False)
            canvas.draw()
            self._background = canvas.copy_from_bbox(self.fig.bbox)
            for a in dynamic:
                a.set_visible(True)
            ax.title.set_text(text)
        canvas.restore_region(self._background)
        for a in sorted(dynamic, key=lambda a: a.get_zorder()):
            ax.draw_artist(a)
        ax.draw_artist(ax.title)
        return np.asarray(canvas.buffer_rgba()).copy()

    def legend(self, runs: list[_Track], planner: str) -> None:
        handles = [Line2D([], [], color=self.trails[tr.name].get_color(), linewidth=1.6,
                          label=f"{tr.name}: {tr.outcome}") for tr in runs
                   if tr.name in self.trails]
        old = self.ax.get_legend()
        if old is not None:
            old.remove()
        self.still()
        if handles:
            self.ax.legend(handles=handles, loc="upper left", fontsize=7, title=planner,
                           title_fontsize=7, framealpha=0.8)

    def moment(self, t: float, runs: list[_Track], candidates: dict[str, Any]) -> None:
        """Everything that moves, at time ``t``."""
        for a in self.moving:
            a.remove()
        ax = self.ax
        added = draw_moving_obstacles(self.scenario, ax, t)
        col = {r.name: f"C{i % 10}" for i, r in enumerate(self.scenario.robots)}
        where: dict[str, np.ndarray] = {}
        for tr in runs:
            k = tr.index(t)
            state = tr.states[k]
            where[tr.name] = state
            c = col.get(tr.name, "black")
            trail = self.trails.get(tr.name)
            if trail is not None:
                trail.set_data(tr.xy[:k + 1, 0], tr.xy[:k + 1, 1])
            added += self._pose(tr.name, state, c)
            if t >= tr.t[-1] and len(tr.t) > 1:
                mark, mcol = _OUTCOME_MARK.get(tr.outcome, ("o", "black"))
                added += ax.plot(*state[:2], marker=mark, color=mcol, markersize=11,
                                 markeredgecolor="black", zorder=9)
            cand = candidates.get(tr.name)
            if cand is not None and t <= tr.t[-1]:
                added += self._candidates(cand, t, c)
        for r in self.scenario.robots:                 # a moving target: the followed robot
            if r.goal is None and r.goal_follow in where and r.name in where:
                g = where[r.goal_follow][:2]
                added.append(ax.add_artist(CirclePatch(tuple(g), r.goal_radius, fill=False,
                                                      edgecolor=col[r.name], linestyle="--",
                                                      linewidth=1.0, zorder=8)))
                added += ax.plot(*g, marker="*", color=col[r.name], markersize=12,
                                 markeredgecolor="black", zorder=9)
                added += ax.plot([where[r.name][0], g[0]], [where[r.name][1], g[1]],
                                 color=col[r.name], linestyle=":", linewidth=1.0, zorder=6)
        self.moving = added

    def _pose(self, name: str, state: np.ndarray, color: str) -> list[Artist]:
        ax = self.ax
        model = self.models.get(name)
        out: list[Artist] = []
        if model is None or len(state) != model.nx:
            out += ax.plot(*state[:2], marker="o", color=color, markersize=6,
                           markeredgecolor="black", zorder=8)
            return out
        centers, radii = model.footprint(state[None])
        for c, rad in zip(centers[0], radii):
            out.append(ax.add_artist(CirclePatch(tuple(c), rad, facecolor=color, edgecolor="black",
                                                alpha=0.45, linewidth=0.6, zorder=8)))
        for body in model.outline(state[None]) or ():
            out.append(ax.add_artist(PolygonPatch(body[0], closed=True, fill=False,
                                                 edgecolor="black", linewidth=1.0, zorder=8)))
        names = tuple(model.state_names)
        th = next((state[names.index(k)] for k in ("theta", "theta0") if k in names), None)
        if th is not None:
            r = model.radius
            out += ax.plot([state[0], state[0] + 1.6 * r * math.cos(th)],
                           [state[1], state[1] + 1.6 * r * math.sin(th)], color="black",
                           linewidth=1.2, zorder=8)
        return out

    def _candidates(self, cand: dict[str, np.ndarray], t: float, color: str) -> list[Artist]:
        """The candidates of the latest search at or before ``t``, the best one crossed."""
        ts = cand["t"]
        if not len(ts) or ts[0] > t:
            return []
        plan = cand["plan"][np.searchsorted(ts, t, side="right") - 1]
        sel = cand["plan"] == plan
        X, Y, cost = cand["x"][sel], cand["y"][sel], cand["cost"][sel]
        ok = np.isfinite(cost)
        out: list[Artist] = []
        if (~ok).any():
            out += self.ax.plot(X[~ok], Y[~ok], linestyle="none", marker="x", color="0.5",
                                markersize=3, zorder=7)
        if ok.any():
            out += self.ax.plot(X[ok], Y[ok], linestyle="none", marker="o", markersize=3,
                                markerfacecolor="none", markeredgecolor=color, zorder=7)
            b = int(np.flatnonzero(ok)[np.argmin(cost[ok])])
            out += self.ax.plot(X[b], Y[b], linestyle="none", marker="P", markersize=7,
                                color=color, markeredgecolor="black", zorder=9)
        return out


# ---- files --------------------------------------------------------------------------------------


def _write(stage: _Stage, path: Path, fmt: str, fps: float, dpi: int, n: int, frame) -> None:
    """Draw the ``n`` frames (``frame(k)`` sets frame ``k`` up) into ``path`` atomically."""
    with atomic_path(path) as tmp:
        if fmt == "mp4":
            _write_mp4(stage, tmp, path, fps, n, frame)
        else:
            from PIL import Image

            w, h = stage.size(dpi)
            if n * w * h > _MAX_GIF_PIXELS:
                raise HybridnavError(f"{path}: {n} frames of {w} x {h} pixels: a GIF is "
                                     f"collected in memory, at most {_MAX_GIF_PIXELS:.0e} "
                                     "pixels in all; lower dpi or max_frames, or write an MP4")
            images = []
            for k in range(n):
                frame(k)
                # one palette per frame, as GIF keeps them (1 byte per pixel while collecting)
                images.append(Image.fromarray(stage.render()[..., :3]).quantize(
                    255, method=Image.Quantize.FASTOCTREE))
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                           duration=max(10, round(1000.0 / fps)), loop=0, disposal=1)
    log.debug("wrote %s: %d frames", path, n)


def _write_mp4(stage: _Stage, tmp: Path, path: Path, fps: float, n: int, frame) -> None:
    """The frames piped into ffmpeg (H.264, yuv420p: what players play), one at a time."""
    import subprocess

    import matplotlib

    w, h = stage.size(stage.dpi)
    exe = shutil.which(matplotlib.rcParams["animation.ffmpeg_path"])
    if exe is None:                                  # gone since _format looked
        raise HybridnavError(f"{path}: writing an MP4 needs ffmpeg on PATH; write a GIF "
                             "instead (a .gif file name)")
    cmd = [exe, "-y", "-loglevel", "error", "-f", "rawvideo", "-vcodec", "rawvideo",
           "-s", f"{w}x{h}", "-pix_fmt", "rgba", "-framerate", f"{fps:g}", "-i", "pipe:",
           "-vcodec", "h264", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p",
           "-f", "mp4", str(tmp)]
    with subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
        try:
            for k in range(n):
                frame(k)
                proc.stdin.write(stage.render().tobytes())
            proc.stdin.close()
        except BrokenPipeError:
            pass                                     # ffmpeg quit: its message follows
        except BaseException:
            proc.kill()
            raise
        err = proc.stderr.read().decode(errors="replace").strip()
        code = proc.wait()
    if code != 0:
        last = err.splitlines()[-1] if err else f"exit status {code}"
        raise HybridnavError(f"{path}: ffmpeg failed ({short_repr(last, 200)}); write a GIF "
                             "instead (a .gif file name)")


def _format(path: Path, fmt: str | None) -> str:
    """The format of ``path``: ``fmt``, else its suffix; MP4 only with ffmpeg on PATH."""
    suffix = path.suffix.lower().lstrip(".")
    if fmt is None:
        if suffix not in ANIMATION_FORMATS:
            raise HybridnavError(f"{path}: expected an animation file name ending in .gif or "
                                 f".mp4, got {'.' + suffix if suffix else 'no suffix'}")
        fmt = suffix
    if fmt not in ANIMATION_FORMATS:
        raise HybridnavError(f"fmt: expected one of {', '.join(ANIMATION_FORMATS)}, got "
                             f"{short_repr(fmt)}")
    if fmt == "mp4":
        import matplotlib

        exe = matplotlib.rcParams["animation.ffmpeg_path"]
        if shutil.which(exe) is None:
            raise HybridnavError(f"{path}: writing an MP4 needs ffmpeg, and {exe!r} is not on "
                                 "PATH; install ffmpeg or write a GIF (a .gif file name)")
    return fmt


def _spread(first: float, last: float, n: int) -> np.ndarray:
    """``n`` evenly spaced values from ``first`` to ``last``; one frame is ``last`` (a run's end,
    the last run: what the animation has come to), not ``first`` as ``np.linspace`` gives."""
    return np.linspace(first, last, n) if n > 1 else np.array([last], dtype=float)


def _digits(times: np.ndarray) -> int:
    """Decimals that tell the frames' times apart (at least 1): a GIF writer merges frames that
    are the same picture, titles included."""
    gaps = np.diff(np.unique(times))
    if not len(gaps):
        return 1
    return int(min(6, max(1, math.ceil(-math.log10(float(gaps.min())) - 1e-9))))


def _check_settings(fps: Any, dpi: Any, max_frames: Any) -> tuple[float, int, int]:
    def number(v: Any) -> bool:
        return not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))

    fps = check_fps(fps)
    for key, v, lo, hi in (("dpi", dpi, 10, 600), ("max_frames", max_frames, 1, 10000)):
        if not number(v) or v != int(v) or not lo <= v <= hi:
            raise HybridnavError(f"{key}: expected an integer in [{lo}, {hi}], got "
                                 f"{short_repr(v)}")
    return fps, int(dpi), int(max_frames)


def _scenario_of(result: Result, scenario: Any) -> Any:
    from hybridnav.world import Scenario, load_scenario

    if scenario is None:
        raise HybridnavError("animate: scenario: expected the scenario the result is of (a "
                             "Scenario, a built-in name or a .toml file)")
    scen = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if [r.name for r in scen.robots] != [r.name for r in result.robots]:
        raise HybridnavError(f"animate: scenario: expected the robots of the result "
                             f"{short_repr([r.name for r in result.robots])}, got those of "
                             f"{scen.name} {short_repr([r.name for r in scen.robots])}")
    return scen


def _is_tuning(folder: Path) -> bool:
    """A folder ``hybridnav tune`` wrote (``generations.json``, or its checkpoint and logbook)."""
    return (folder / GENERATIONS_FILE).is_file() or (
        (folder / "logbook.csv").is_file() and (folder / "checkpoint.json").is_file())
