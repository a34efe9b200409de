"""``hybridnav animate``: GIFs and MP4s of runs and of tuning jobs.

The frames are checked against the scenario, not against the drawing code: the data-to-pixel map
comes from the workspace border found in the frame itself, and each moving circle's fill colour
must be centred where ``MovingCircle.center_at`` puts it at the frame's time.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import os
import shutil
import stat
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from hybridnav import HybridnavError, planners
from hybridnav.cli import main
from hybridnav.plotting import animate
from hybridnav.results import read_result
from hybridnav.world import MovingCircle, load_scenario

#: the fill of a moving circle: tab:red at alpha 0.75 over white
FILL = np.array([0.75 * 214 + 0.25 * 255, 0.75 * 39 + 0.25 * 255, 0.75 * 40 + 0.25 * 255])
SMALL_PSOBA = {"particles": 2, "pso_iterations": 2, "bats": 4, "bat_iterations": 4}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """pso-ba-dynamic, 25 s of it, with a small swarm: a result folder as 'run' writes it."""
    folder = tmp_path_factory.mktemp("animate") / "psoba"
    scenario = dataclasses.replace(load_scenario("pso-ba-dynamic"), max_time=25.0)
    planners.get("pso-ba", **SMALL_PSOBA).run(scenario, seed=1).write(folder)
    return folder


def cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["animate", *map(str, args)])
    return rc, out.getvalue(), err.getvalue()


def frames(path: Path) -> list[np.ndarray]:
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB")).astype(float))
    return out


def border(img: np.ndarray) -> tuple[float, float, float, float]:
    """Pixel columns of the workspace's left and right sides and rows of its top and bottom:
    the darkest lines that run across most of the frame (the axes' frame is lighter)."""
    dark = img.sum(axis=2) < 300

    def lines(count: np.ndarray) -> tuple[float, float]:
        idx = np.flatnonzero(count > 0.4 * len(count))
        groups = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        assert len(groups) == 2, groups
        return tuple(float(np.average(g, weights=count[g])) for g in groups)

    left, right = lines(dark.sum(axis=0))
    top, bottom = lines(dark.sum(axis=1))
    return left, right, top, bottom


def fill_centroid(img: np.ndarray, at: np.ndarray, radius: float) -> tuple[np.ndarray, int]:
    """Centroid (column, row) and count of the moving-circle fill pixels within ``radius``."""
    rows, cols = np.mgrid[:img.shape[0], :img.shape[1]]
    near = np.hypot(cols - at[0], rows - at[1]) <= radius
    fill = np.all(np.abs(img - FILL) < 30, axis=2) & near
    if not fill.any():
        return np.array([np.nan, np.nan]), 0
    return np.array([cols[fill].mean(), rows[fill].mean()]), int(fill.sum())


def test_the_gif_shows_the_moving_obstacles_where_they_are(run_dir, tmp_path):
    out = tmp_path / "run.gif"
    rc, stdout, err = cli(run_dir, "--out", out, "--max-frames", 6, "--dpi", 40)
    assert rc == 0, err
    result = read_result(run_dir)
    t_end = max(float(r.t[-1]) for r in result.robots)
    assert t_end == pytest.approx(25.0, abs=0.11)       # the budget (or both reached before)
    assert stdout == f"wrote {out}: 6 frames at 10 fps, 256 x 256 pixels (t = 0 to {t_end:.1f} s)\n"
    imgs = frames(out)
    assert len(imgs) == 6 and imgs[0].shape == (256, 256, 3)
    times = np.linspace(0.0, t_end, 6)
    scenario = load_scenario("pso-ba-dynamic")
    xmin, xmax, ymin, ymax = scenario.world.workspace
    static = scenario.world.static()
    moving = [o for o in scenario.world.obstacles if isinstance(o, MovingCircle)]
    assert len(moving) == 4
    def pixels(img):
        """The frame's data -> pixel map, from its workspace border; and its scale."""
        left, right, top, bottom = border(img)
        sx, sy = (right - left) / (xmax - xmin), (bottom - top) / (ymax - ymin)
        assert sx == pytest.approx(sy, rel=0.02)          # equal aspect
        return (lambda p: np.array([left + (p[0] - xmin) * sx, bottom - (p[1] - ymin) * sy])), \
            sx, sy

    checked = 0
    for img, t in zip(imgs, times):
        pixel, sx, sy = pixels(img)
        for o in moving:
            c = o.center_at(t)
            # only where the circle is over empty floor (its fill colour is the one tested)
            others = [m.center_at(t) for m in moving if m is not o]
            if static.clearance(c)[0] <= o.radius + 1.0 or any(
                    np.hypot(*(c - q)) <= 2 * o.radius + 2.0 for q in others):
                continue
            r_px = o.radius * sx
            got, count = fill_centroid(img, pixel(c), r_px + 2.0)
            assert count >= 0.5 * np.pi * r_px**2, (t, o)
            assert np.hypot(*(got - pixel(c))) < 1.5, (t, o, got, pixel(c))
            checked += 1
    assert checked >= 16
    # the circle moving down from (100, 170) at 2 cm/s: its fill moved by 2 t_end cm, and none is
    # left where it started
    o = moving[0]
    pixel, sx, sy = pixels(imgs[0])
    first, _ = fill_centroid(imgs[0], pixel(o.center_at(0.0)), o.radius * sx + 2.0)
    pixel, sx, sy = pixels(imgs[-1])
    last, _ = fill_centroid(imgs[-1], pixel(o.center_at(t_end)), o.radius * sx + 2.0)
    assert last[1] - first[1] == pytest.approx(2.0 * t_end * sy, abs=1.5)
    assert fill_centroid(imgs[-1], first, o.radius * sx)[1] == 0


def test_python_api_writes_frames_at_the_run_times_and_the_candidates(run_dir, tmp_path):
    result = read_result(run_dir)
    # the swarm's candidates are recorded per search, at most MAX_CANDIDATES each
    cand = result.extras["candidates_robot1"]
    steps = result.extras["swarm_best_robot1"]
    assert set(np.unique(cand["plan"])) == set(np.unique(steps["plan"]))
    # one best bat per bat run: the PSO scores its first swarm and each iteration's
    assert np.all(np.bincount(cand["plan"].astype(int)) == 2 * (2 + 1))
    step = 3.0 * 3.0                                                # 3 robot radii of 3 cm
    pts = {row[0]: row for row in zip(*(result.extras["path_points_robot1"][c]
                                        for c in ("t", "x", "y")))}
    traj = result.robots[0]
    for plan in np.unique(cand["plan"]):
        sel = cand["plan"] == plan
        t = cand["t"][sel][0]
        p = traj.states[np.searchsorted(traj.t, t), :2]
        # every candidate lies in the step disk around where the robot was when it searched
        assert np.all(np.hypot(cand["x"][sel] - p[0], cand["y"][sel] - p[1]) <= step + 1e-9)
    assert pts                                                      # points were placed
    done = animate(result, tmp_path / "api.gif", scenario="pso-ba-dynamic", max_frames=4,
                   dpi=30, fps=5)
    assert done.frames == 4 and done.fps == 5 and done.size == (192, 192)
    t_end = max(float(r.t[-1]) for r in result.robots)
    assert done.times == pytest.approx(tuple(np.linspace(0.0, t_end, 4)))
    assert done.labels[1] == f"pso-ba-dynamic: pso-ba, t = {t_end / 3:.1f} s"
    # few samples: a frame at each (the GIF writer would merge frames that look the same)
    short = dataclasses.replace(result, robots=[dataclasses.replace(
        r, t=r.t[:4], states=r.states[:4]) for r in result.robots])
    few = animate(short, tmp_path / "few.gif", scenario="pso-ba-dynamic", dpi=20)
    assert few.times == pytest.approx((0.0, 0.1, 0.2, 0.3))
    with Image.open(few.path) as im:
        assert im.n_frames == 4
    with Image.open(done.path) as im:
        assert im.n_frames == 4 and im.info["duration"] == 200 and im.info["loop"] == 0


def test_step_planner_candidates_and_a_trailer_outline(tmp_path):
    scenario = dataclasses.replace(load_scenario("tractor-trailer-1"), max_time=8.0)
    res = planners.get("fastep-kinematic", n=6, iterations=3).run(scenario, seed=0)
    name = res.robots[0].name
    cand = res.extras[f"candidates_{name}"]
    assert len(cand["plan"]) == sum(min(6, n) if n > 1 else 1 for n in np.bincount(
        cand["plan"].astype(int)))
    assert set(np.unique(cand["plan"])) == set(np.unique(res.extras[f"swarm_best_{name}"]["plan"]))
    done = animate(res, tmp_path / "tt.gif", scenario=scenario, max_frames=3, dpi=30)
    assert done.frames == 3
    model = scenario.model(scenario.robots[0], jit=False)
    tractor, trailer = model.outline(res.robots[0].states[-1:])
    centers, _ = model.footprint(res.robots[0].states[-1:])
    # the outline's rectangles hold the covering disks' centres (tractor first, then trailer)
    from matplotlib.path import Path as MPath

    inside = [MPath(tractor[0]).contains_point(c) or MPath(trailer[0]).contains_point(c)
              for c in centers[0]]
    assert all(inside)
    L, b = model.values["L"], model.values["b"]
    assert np.hypot(*(tractor[0][1] - tractor[0][0])) == pytest.approx(L)
    assert np.hypot(*(tractor[0][2] - tractor[0][1])) == pytest.approx(b)


def test_a_failed_animation_leaves_no_file(run_dir, tmp_path, monkeypatch):
    from hybridnav.plotting import animation

    out = tmp_path / "keep.gif"
    out.write_bytes(b"old")
    calls = {"n": 0}
    real = animation._Stage.render

    def render(self):
        calls["n"] += 1
        if calls["n"] == 3:
            raise HybridnavError("disk full (simulated)")
        return real(self)

    monkeypatch.setattr(animation._Stage, "render", render)
    rc, _, err = cli(run_dir, "--out", out, "--max-frames", 5, "--dpi", 20)
    assert rc == 2 and err == "hybridnav: error: disk full (simulated)\n"
    assert out.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == [
        "keep.gif"]


def test_mp4_without_ffmpeg_is_a_clear_error(run_dir, tmp_path, monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name, *a, **k: None)
    out = tmp_path / "run.mp4"
    rc, _, err = cli(run_dir, "--out", out)
    assert rc == 2
    assert err == (f"hybridnav: error: {out}: writing an MP4 needs ffmpeg, and 'ffmpeg' is not "
                   "on PATH; install ffmpeg or write a GIF (a .gif file name)\n")
    assert not out.exists() and list(tmp_path.iterdir()) == []


def _fake_ffmpeg(folder: Path, code: int) -> None:
    """An ``ffmpeg`` that writes how many bytes it was piped (or fails like a missing encoder)."""
    script = folder / "ffmpeg"
    body = ("data = sys.stdin.buffer.read()\n"
            "open(sys.argv[-1], 'w').write(f'{len(data)} {\" \".join(sys.argv[1:-1])}')\n"
            if code == 0 else
            "sys.stdin.buffer.read()\nsys.stderr.write(\"Unknown encoder 'h264'\\n\")\n")
    script.write_text(f"#!{sys.executable}\nimport sys\n{body}sys.exit({code})\n")
    script.chmod(script.stat().st_mode | stat.S_IXUSR)


@pytest.mark.skipif(os.name != "posix", reason="a fake ffmpeg script")
def test_mp4_frames_are_piped_to_ffmpeg_whole(run_dir, tmp_path, monkeypatch):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _fake_ffmpeg(bin_dir, 0)
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ['PATH']}")
    done = animate(run_dir, tmp_path / "run.mp4", max_frames=3, dpi=25, fps=12)
    w, h = done.size
    assert (w, h) == (160, 160)
    size, args = (tmp_path / "run.mp4").read_text().split(" ", 1)
    assert int(size) == 3 * w * h * 4                          # three RGBA frames
    assert f"-s {w}x{h} -pix_fmt rgba -framerate 12 -i pipe:" in args
    assert "-vcodec h264" in args and "-pix_fmt yuv420p" in args
    # an ffmpeg that fails: its message, and no file
    _fake_ffmpeg(bin_dir, 1)
    with pytest.raises(HybridnavError) as err:
        animate(run_dir, tmp_path / "bad.mp4", max_frames=2, dpi=20)
    assert str(err.value) == (f"{tmp_path / 'bad.mp4'}: ffmpeg failed (\"Unknown encoder "
                              "'h264'\"); write a GIF instead (a .gif file name)")
    assert not (tmp_path / "bad.mp4").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".bad.mp4")]


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="ffmpeg is not installed")
def test_a_real_mp4(run_dir, tmp_path):
    rc, _, err = cli(run_dir, "--out", tmp_path / "run.mp4", "--max-frames", 4, "--dpi", 41)
    assert rc == 0, err
    assert (tmp_path / "run.mp4").read_bytes()[4:8] == b"ftyp"
    if shutil.which("ffprobe"):                     # an independent reader: every frame is there
        import subprocess

        out = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                              "-show_entries", "stream=nb_read_frames,width,height", "-of",
                              "csv=p=0", str(tmp_path / "run.mp4")], capture_output=True,
                             text=True, timeout=60)
        width, height, frames = (int(v) for v in out.stdout.strip().split(","))
        assert frames == 4 and width > 100 and height > 100, out.stdout


def test_bad_input_is_one_line_naming_the_file(run_dir, tmp_path):
    missing = tmp_path / "nowhere"
    empty = tmp_path / "empty"
    empty.mkdir()
    broken = tmp_path / "broken"
    shutil.copytree(run_dir, broken)
    (broken / "result.json").write_text('{"scenario": ')
    other = tmp_path / "other"
    shutil.copytree(run_dir, other)
    data = json.loads((other / "result.json").read_text())
    data["scenario"] = "my-world"
    (other / "result.json").write_text(json.dumps(data))
    cases = [
        ((missing,), f"{missing}: no such folder (expected a folder written by 'hybridnav run' "
                     "or 'hybridnav tune')"),
        ((empty,), f"{empty / 'result.json'}: no such file (expected a hybridnav result folder)"),
        ((broken,), f"{broken / 'result.json'}: not valid JSON: Expecting value: line 1 column "
                    "14 (char 13)"),
        ((other,), f"{other / 'result.json'}: scenario: 'my-world' is not a built-in scenario; "
                   "pass the scenario file the result was run on with --scenario"),
        ((run_dir, "--out", tmp_path / "x.png"),
         f"{tmp_path / 'x.png'}: expected an animation file name ending in .gif or .mp4, got "
         ".png"),
        ((run_dir, "--out", tmp_path / "x"),
         f"{tmp_path / 'x'}: expected an animation file name ending in .gif or .mp4, got no "
         "suffix"),
        ((run_dir, "--world", "effc-env-a"),
         f"{run_dir}: --world: only for a tuning job's folder (this is not one: a run's scenario "
         "is its result's)"),
        ((run_dir, "--scenario", "arena"),
         f"{run_dir / 'result.json'}: scenario: the result is of scenario 'pso-ba-dynamic', not "
         "'arena' (--scenario arena)"),
    ]
    for args, message in cases:
        rc, out, err = cli(*args)
        assert (rc, out, err) == (2, "", f"hybridnav: error: {message}\n"), args
    for option, value, what in (("--fps", "0", "a number of frames per second in [0.01, 100]"),
                                ("--fps", "nan", "a number of frames per second in [0.01, 100]"),
                                # below ~0.0016 a GIF frame outlasts its 16-bit duration field
                                # (Pillow raised OverflowError)
                                ("--fps", "0.001", "a number of frames per second in [0.01, 100]"),
                                ("--fps", "1e400", "a number of frames per second in [0.01, 100]"),
                                ("--dpi", "5", "an integer in [10, 600]"),
                                ("--max-frames", "0", "an integer in [1, 10000]")):
        with pytest.raises(SystemExit) as exit_, contextlib.redirect_stderr(io.StringIO()) as e:
            main(["animate", str(run_dir), option, value])
        assert exit_.value.code == 2
        assert e.getvalue().splitlines()[-1] == (
            f"hybridnav: error: argument {option}: expected {what}, got '{value}' (see "
            "'hybridnav animate --help')")
    assert not list(run_dir.glob("*.gif"))
    for fps in (True, 0.001, 10**400, float("inf")):
        with pytest.raises(HybridnavError, match=r"^fps: expected a number of frames per second in"
                                                 r" \[0\.01, 100\], got "):
            animate(run_dir, tmp_path / "a.gif", fps=fps)
    with pytest.raises(HybridnavError, match=r"^animate: scenario: expected the scenario the "):
        animate(read_result(run_dir), tmp_path / "a.gif")
    # the slowest rate is written: a frame of 100 s
    slow = animate(run_dir, tmp_path / "slow.gif", fps=0.01, max_frames=2, dpi=10)
    with Image.open(slow.path) as im:
        assert (slow.fps, im.n_frames, im.info["duration"]) == (0.01, 2, 100_000)


def test_the_help_has_an_example():
    with pytest.raises(SystemExit), contextlib.redirect_stdout(io.StringIO()) as out:
        main(["animate", "--help"])
    text = out.getvalue()
    assert "hybridnav animate runs/psoba" in text and "--max-frames N" in text


# ---- tuning jobs --------------------------------------------------------------------------------


def test_a_tuning_job_animates_its_best_system_per_generation(tmp_path):
    sys.path.insert(0, str(Path(__file__).parent))
    from test_tuner import small_job, tune

    from hybridnav.tuner import animate_tuning
    from hybridnav.tuner.run import OUTPUT_FILES, write_generations

    job = small_job(tmp_path)
    folder = tmp_path / "tuned"
    result = tune(job, folder)
    # one per generation: the carried population's best, the logbook's min
    assert [g["generation"] for g in result.generations] == list(result.logbook["gen"])
    assert [g["score"] for g in result.generations] == list(result.logbook["min"])
    assert write_generations(job, result, folder) == ["generations.json"]
    assert "generations.json" in OUTPUT_FILES
    data = json.loads((folder / "generations.json").read_text())
    assert data["planner"] == "effc" and data["worlds"]["train"] == ["effc-train-1",
                                                                     "effc-train-2"]
    # a resumed run ends with the same generations (they are in the checkpoint)
    tune(job, tmp_path / "part", stop_after=1)
    again = tune(job, tmp_path / "part", resume=True)
    assert [(g["generation"], g["score"], g["system"]) for g in again.generations] == \
        [(g["generation"], g["score"], g["system"]) for g in result.generations]

    rc, out, err = cli(folder, "--max-frames", 6, "--dpi", 30, "--world", "effc-train-2")
    assert rc == 0, err
    assert out == (f"wrote {folder / 'animation.gif'}: 6 frames at 4 fps, 192 x 192 pixels "
                   "(generation 0 to generation 2)\n")
    done = animate_tuning(folder, tmp_path / "t.gif", max_frames=6, dpi=30, world="effc-train-2")
    assert [lab.split(", t = ")[0] for lab in done.labels] == [
        f"generation {g}: score {s:.4g}" for g, s in zip((0, 0, 1, 1, 2, 2),
                                                         np.repeat(result.logbook["min"], 2))]
    assert [float(lab.split(", t = ")[1][:-2]) for lab in done.labels] == pytest.approx(
        done.times, abs=0.051)
    # each generation's last frame is the end of its system's run on that world
    scenario = load_scenario("effc-train-2")
    for j, g in enumerate(result.generations):
        run = planners.get("effc", fis=g["system"], **job["planner"]).run(scenario)
        assert done.times[2 * j + 1] == pytest.approx(float(run.robots[0].t[-1]))
    # the default world: the job's first test world
    assert animate_tuning(folder, tmp_path / "d.gif", max_frames=3, dpi=20).frames == 3
    with pytest.raises(HybridnavError, match="a tuning job's folder, not a run's: hybridnav.tuner"
                                             ".animate_tuning animates it"):
        animate(folder, tmp_path / "e.gif")
    rc, _, err = cli(folder, "--world", "nowhere", "--max-frames", 2)
    assert rc == 2 and err.startswith(f"hybridnav: error: {folder / 'generations.json'}: world: "
                                      "expected the name of one of the job's worlds "
                                      "(['effc-env-a', 'effc-env-b', ")
    assert err.endswith("got 'nowhere'\n")
    # one frame: the last generation's run at its end (it was generation 0 at t = 0)
    one = animate_tuning(folder, tmp_path / "one.gif", max_frames=1, dpi=20,
                         world="effc-train-2")
    last = planners.get("effc", fis=result.generations[-1]["system"],
                        **job["planner"]).run(scenario)
    assert one.labels[0].startswith(f"generation {result.generations[-1]['generation']}: ")
    assert one.times == pytest.approx((float(last.robots[0].t[-1]),))


def test_a_tuning_folder_without_generations(tmp_path):
    folder = tmp_path / "old"
    folder.mkdir()
    (folder / "logbook.csv").write_text("gen,min\n0,1.0\n")
    (folder / "checkpoint.json").write_text("{}")
    rc, _, err = cli(folder)
    assert rc == 2 and err == (
        f"hybridnav: error: {folder / 'generations.json'}: no such file: a navigation tuning job "
        "run by hybridnav 0.3.0 or later writes it (its best system per generation); run the "
        "job again to animate it\n")
    (folder / "generations.json").write_text(json.dumps({"format": "hybridnav-generations/1",
                                                         "planner": "effc",
                                                         "planner_params": {}}))
    rc, _, err = cli(folder)
    assert rc == 2 and err == (f"hybridnav: error: {folder / 'generations.json'}: worlds: "
                               "expected an object of train, validation and test lists, got "
                               "None\n")


def small_generations(folder: Path, **change) -> Path:
    """A tuning folder whose generations.json is written by hand: effc-2rule on effc-train-1,
    three generations (``change`` replaces top-level keys)."""
    from hybridnav import fuzzy

    folder.mkdir(parents=True, exist_ok=True)
    data = {"format": "hybridnav-generations/1", "planner": "effc", "planner_params": {},
            "worlds": {"train": ["effc-train-1"], "validation": [], "test": []},
            "systems": [fuzzy.load("effc-2rule").to_dict()],
            "generations": [{"stage": 0, "generation": g, "score": 1.0 - g / 10, "system": 0}
                            for g in range(3)]}
    data.update(change)
    (folder / "generations.json").write_text(json.dumps(data))
    return folder / "generations.json"


@pytest.mark.parametrize("edit, message", [
    # Python's int-string limit: json.loads raised ValueError (a traceback)
    (lambda t: t.replace('"generation": 1', '"generation": ' + "7" * 5000, 1),
     "generations[1].generation: expected a number as hybridnav writes them (finite, at most "
     "4300 digits), got an integer of 5000 digits"),
    # an int beyond floats: formatting the score raised OverflowError
    (lambda t: t.replace('"score": 0.9', '"score": 1' + "0" * 400, 1),
     "generations[1].score: expected a finite number or null, got 1000000000000000000000000000000"
     "000000000...0000000000 (401 characters)"),
    # NaN and Infinity were taken silently
    (lambda t: t.replace('"score": 0.9', '"score": NaN', 1),
     "generations[1].score: expected a number as hybridnav writes them (finite, at most 4300 "
     "digits), got NaN"),
    (lambda t: t.replace('"score": 0.8', '"score": -Infinity', 1),
     "generations[2].score: expected a number as hybridnav writes them (finite, at most 4300 "
     "digits), got -Infinity"),
    (lambda t: t.replace('"score": 0.8', '"score": 1e999', 1),
     "generations[2].score: expected a number as hybridnav writes them (finite, at most 4300 "
     "digits), got '1e999' (beyond the float range)"),
    (lambda t: t.replace('"score": 0.8', '"score": true', 1),
     "generations[2].score: expected a finite number or null, got True"),
    (lambda t: t.replace('"generation": 2', '"generation": -2', 1),
     "generations[2].generation: expected a whole number from 0 to 2**63 - 1, got -2"),
    (lambda t: t.replace('"system": 0}]', '"system": 1}]', 1),
     "generations[2].system: expected an index into systems (an integer in [0, 0]), got 1"),
    (lambda t: t.replace('"planner": "effc"', '"planner": "effc", "planner": "apf"', 1),
     "(top level): duplicate key 'planner'"),
])
def test_hostile_numbers_in_generations_json(tmp_path, edit, message, monkeypatch):
    gens = small_generations(tmp_path / "tuned")
    gens.write_text(edit(gens.read_text()))
    monkeypatch.setattr(planners, "get", None)        # refused before any run
    rc, out, err = cli(gens.parent)
    assert (rc, out, err) == (2, "", f"hybridnav: error: {gens}: {message}\n")
    assert sorted(p.name for p in gens.parent.iterdir()) == ["generations.json"]


def test_a_world_generations_json_cannot_load_is_named_by_its_place(tmp_path, monkeypatch):
    """Worlds are loaded one at a time (no more generated than needed): the message names the
    item's place in its set, worlds.test[1] (it said worlds.test[1][0])."""
    gens = small_generations(tmp_path / "tuned", worlds={
        "train": ["effc-train-1"], "validation": [], "test": ["effc-env-b", "no-such-world"]})
    monkeypatch.setattr(planners, "get", None)        # refused before any run
    rc, out, err = cli(gens.parent, "--world", "effc-train-1")
    assert (rc, out) == (2, "")
    assert err.startswith(f"hybridnav: error: {gens}: worlds.test[1]: ")
    assert "[1][0]" not in err


@pytest.mark.parametrize("change, message", [
    ({"planner_params": {"speed": "fast"}},
     "planner_params (planner 'effc', fis systems[0]): planner effc: speed: expected a number, "
     "got 'fast'"),
    ({"planner": "apf"},
     "planner_params (planner 'apf', fis systems[0]): planner apf: unknown parameter 'fis'"),
])
def test_planner_settings_refused_are_named_by_generations_json(tmp_path, change, message,
                                                                monkeypatch):
    """The planner's settings come from generations.json: a refused one was a bare 'planner
    effc: speed: ...' that named neither the file nor its key; and no run starts before."""
    from hybridnav.planners.base import Planner

    gens = small_generations(tmp_path / "tuned", **change)
    monkeypatch.setattr(Planner, "run", None)          # refused before any run
    rc, out, err = cli(gens.parent)
    assert (rc, out) == (2, "")
    assert err.startswith(f"hybridnav: error: {gens}: {message}")


def test_a_tuning_animation_checks_its_file_before_it_runs(tmp_path, monkeypatch):
    gens = small_generations(tmp_path / "tuned")
    monkeypatch.setattr(planners, "get", None)        # no planner runs before these errors
    (tmp_path / "file").write_text("")
    for out, message in (
            (tmp_path / "x.png", f"{tmp_path / 'x.png'}: expected an animation file name ending "
                                 "in .gif or .mp4, got .png"),
            (tmp_path / "file" / "a.gif", f"{tmp_path / 'file' / 'a.gif'}: cannot write "
                                          f"({tmp_path / 'file'} is not a folder)"),
            (tmp_path / "d.gif", f"{tmp_path / 'd.gif'}: cannot write (it is a folder; expected "
                                 "a file name)")):
        if out.name == "d.gif":
            out.mkdir()
        rc, _, err = cli(gens.parent, "--out", out)
        assert (rc, err) == (2, f"hybridnav: error: {message}\n")
    from hybridnav.tuner import animate_tuning

    with pytest.raises(HybridnavError, match=r"^fps: expected a number of frames per second in "
                                             r"\[0\.01, 100\], got 0\.001$"):
        animate_tuning(gens.parent, fps=0.001)
    assert sorted(p.name for p in gens.parent.iterdir()) == ["generations.json"]


def test_one_frame_is_the_end_and_a_failure_leaves_no_folder(run_dir, tmp_path, monkeypatch):
    result = read_result(run_dir)
    end = max(float(rr.t[-1]) for rr in result.robots)
    rc, out, err = cli(run_dir, "--out", tmp_path / "one.gif", "--max-frames", 1, "--dpi", 20)
    assert rc == 0, err
    assert out == f"wrote {tmp_path / 'one.gif'}: 1 frame at 10 fps, 128 x 128 pixels " \
                  f"(t = {end:.1f} s)\n"
    assert animate(run_dir, tmp_path / "b.gif", max_frames=1, dpi=20).times == (end,)
    # the folders the file would go in are made only to write it, and removed on a failure
    from hybridnav.plotting import animation

    def fail(self):
        raise HybridnavError("disk full (simulated)")

    monkeypatch.setattr(animation._Stage, "render", fail)
    rc, _, err = cli(run_dir, "--out", tmp_path / "new" / "sub" / "a.gif", "--max-frames", 2,
                     "--dpi", 20)
    assert (rc, err) == (2, "hybridnav: error: disk full (simulated)\n")
    assert not (tmp_path / "new").exists()
