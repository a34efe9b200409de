"""Command-line values and run folders on hostile input (issue 27): every bad value ends in
``hybridnav: error:`` naming the option or key and what was expected (exit 2), never a traceback;
backends bounded by the work and the cores; a Dask run without workers fails instead of waiting
forever."""

from __future__ import annotations

import os
import time

import pytest

from hybridnav import HybridnavError, planners
from hybridnav.backends import DASK_ADDRESS, ProcessBackend, cores, make_backend
from hybridnav.cli import main
from hybridnav.fileio import LOCK_NAME, atomic_write_text, clean_temporaries, locked_folder
from hybridnav.params import check_seed
from hybridnav.world import load_scenario


def _pid(_):
    return os.getpid()


@pytest.mark.parametrize("argv", [
    ["run", "fastep-s1", "--planner", "apf", "--seed", "-1", "-o", "X"],
    ["compare", "--planners", "apf", "--scenarios", "fastep-s1", "--runs", "1", "--seed", "-1",
     "-o", "X"],
    ["tune", "--quick", "--seed", "-1", "--out", "X"],
    ["generate", "--seed", "-1", "-o", "X"],
    ["run", "fastep-s1", "--planner", "apf", "--seed", "1" + "0" * 50, "-o", "X"],
])
def test_a_negative_or_huge_seed_is_refused_by_every_command(argv, tmp_path, capsys):
    argv = [str(tmp_path / "out") if a == "X" else a for a in argv]
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "hybridnav: error: argument --seed: expected a non-negative integer below 2**128, " \
           "got '" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("option, value, expected", [
    ("--workers", "0", "an integer in [1, 256]"), ("--workers", "16000", "an integer in [1, 256]"),
    ("--runs", "-3", "an integer in [1, 100000]"), ("--runs", "1e9", "an integer in [1, 100000]"),
])
def test_counts_on_the_command_line_are_bounded(option, value, expected, tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["compare", "--planners", "apf", "--scenarios", "fastep-s1", option, value,
              "-o", str(tmp_path / "o")])
    assert f"argument {option}: expected {expected}, got '{value}'" in capsys.readouterr().err


def test_the_python_api_refuses_the_same_seeds():
    scens = [load_scenario(n) for n in ("fastep-s1", "pso-ba-dynamic", "rfd-pso-700",
                                         "tractor-trailer-1")]
    checked = set()
    for name in sorted(planners.PLANNERS):
        planner = planners.get(name)
        for scen in scens:
            try:
                planner.check_scenario(scen)
            except HybridnavError:
                continue
            with pytest.raises(HybridnavError, match=r"^seed: expected a non-negative integer "
                                                     r"below 2\*\*128 or None, got -1$"):
                planner.run(scen, seed=-1)
            checked.add(name)
            break
    assert checked == set(planners.PLANNERS)
    for bad in (True, 1.5, "3", 2**128):
        with pytest.raises(HybridnavError, match="^seed: expected"):
            check_seed(bad)
    assert check_seed(2**128 - 1) == 2**128 - 1 and check_seed(None) is None


@pytest.mark.parametrize("argv, expected", [
    (["show", "fastep-s1", "-o", "{tmp}/picture"],
     "{tmp}/picture: expected a picture file name ending in one of .avif, .eps"),
    (["show", "fastep-s1", "-o", "{tmp}/picture.txt"], "got .txt"),
    (["show", "pso-ba-dynamic", "--time", "1e308", "-o", "{tmp}/p.png"],
     "t: expected a time in [0, 600] s (the scenario's max_time), got 1e+308"),
    (["show", "pso-ba-dynamic", "--time", "nan", "-o", "{tmp}/p.png"],
     "argument --time: expected a finite time >= 0 (seconds), got 'nan'"),
])
def test_show_refuses_what_it_cannot_draw(argv, expected, tmp_path, capsys):
    argv = [a.format(tmp=tmp_path) for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith("hybridnav: error: ")
    assert expected.format(tmp=tmp_path) in err, err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("address", ["not a url", "tcp://", "host", "tcp://h:port", "x" * 5000])
def test_a_dask_address_is_checked_before_anything_starts(address):
    with pytest.raises(HybridnavError, match=r"^--dask: expected 'local' or a scheduler address "
                                             r"such as tcp://host:8786, got"):
        make_backend(2, address)
    assert len(str(pytest.raises(HybridnavError, make_backend, 2, address).value)) < 300


@pytest.mark.parametrize("address", ["local", "tcp://127.0.0.1:8786", "scheduler:8786",
                                     "tls://[::1]:8786"])
def test_real_dask_addresses_pass_the_check(address):
    assert DASK_ADDRESS.check("--dask", address) == address


def test_local_workers_are_bounded_by_the_tasks_and_the_cores():
    with ProcessBackend(16) as be:
        assert be.limit == min(16, cores())
        assert len(set(be.map(_pid, [(i,) for i in range(1)]))) == 1 and be.size == 1
        pids = be.map(_pid, [(i,) for i in range(8)])
        assert be.size == min(16, cores(), 8) and len(set(pids)) <= be.size
        assert os.getpid() not in pids


def test_write_failures_name_the_file_not_its_temporary(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):                      # root ignores the mode bits
            pytest.skip("running as root: a read-only folder is writable")
        with pytest.raises(HybridnavError, match=rf"^{ro}/a.txt: cannot write \(Permission "
                                                 r"denied\); nothing was replaced$"):
            atomic_write_text(ro / "a.txt", "x")
        with pytest.raises(HybridnavError, match=rf"^{ro}/run: cannot make the output folder"):
            with locked_folder(ro / "run", "test"):
                pass
    finally:
        ro.chmod(0o755)


def test_a_full_disk_names_the_file(tmp_path, monkeypatch):
    import hybridnav.fileio as fileio

    real = fileio.os.replace

    def full(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(fileio.os, "replace", full)
    with pytest.raises(HybridnavError, match=rf"^{tmp_path}/r.json: cannot write \(No space "
                                             r"left on device\); nothing was replaced$"):
        atomic_write_text(tmp_path / "r.json", "{}")
    monkeypatch.setattr(fileio.os, "replace", real)
    assert list(tmp_path.iterdir()) == []               # the temporary file went too


def test_a_stale_lock_is_taken_over_and_temporaries_are_cleaned(tmp_path):
    import json

    # a killed job's lock file: nobody holds its flock any more
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": 2**40, "host": "x", "command": "tune",
                                                  "started": "2026-01-01T00:00:00"}))
    (tmp_path / ".report.md.k3j_9abc.tmp.md").write_text("half")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / ".a.png.x1234567.tmp.png").write_text("not ours to clean: a sub-folder")
    (tmp_path / "keep.tmp").write_text("a user's file")
    (tmp_path / ".env.tmpl").write_text("a user's file")
    with locked_folder(tmp_path, "tune new"):
        held = json.loads((tmp_path / LOCK_NAME).read_text())
        assert held["pid"] == os.getpid() and held["command"] == "tune new"
        assert [p.name for p in clean_temporaries(tmp_path)] == [".report.md.k3j_9abc.tmp.md"]
    assert sorted(p.name for p in tmp_path.rglob("*")) == [
        ".a.png.x1234567.tmp.png", ".env.tmpl", "keep.tmp", "sub"]


def _hold(folder, barrier, out):
    barrier.wait()
    try:
        with locked_folder(folder, "race"):
            out.put(("in", os.getpid(), time.time()))
            time.sleep(0.3)
            out.put(("out", os.getpid(), time.time()))
    except HybridnavError:
        out.put(("refused", os.getpid(), time.time()))


def test_racing_jobs_never_hold_one_folder_together(tmp_path):
    """Found by a review: taking over a stale lock by check-then-unlink let two of three racing
    jobs in at once (12 of 60 trials). flock leaves one holder."""
    import json
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    for trial in range(8):
        folder = tmp_path / f"t{trial}"
        folder.mkdir()
        (folder / LOCK_NAME).write_text(json.dumps({"pid": 999999, "host": "h"}))   # stale
        barrier, out = ctx.Barrier(3), ctx.Queue()
        procs = [ctx.Process(target=_hold, args=(folder, barrier, out)) for _ in range(3)]
        for pr in procs:
            pr.start()
        for pr in procs:
            pr.join(30)
        events = []
        while not out.empty():
            events.append(out.get())
        events.sort(key=lambda e: e[2])
        inside = 0
        for kind, _, _ in events:
            inside += {"in": 1, "out": -1}.get(kind, 0)
            assert inside <= 1, events
        assert sum(k == "in" for k, _, _ in events) >= 1


def test_a_lock_that_is_not_a_file_is_refused_without_waiting(tmp_path):
    os.mkfifo(tmp_path / LOCK_NAME)
    with pytest.raises(HybridnavError, match=r"expected the lock file of a hybridnav job \(a "
                                             r"regular file\); remove it"):
        with locked_folder(tmp_path, "x"):
            pass


def test_a_fifo_as_input_file_is_refused_without_waiting(tmp_path):
    from hybridnav.fuzzy import load_any
    from hybridnav.tuner import load_job

    for name, read in (("s.toml", load_scenario), ("j.toml", load_job), ("f.json", load_any),
                       ("f.fll", load_any)):
        os.mkfifo(tmp_path / name)
        t0 = time.monotonic()
        with pytest.raises(HybridnavError, match="expected a regular .*, got a pipe, device or "
                                                 "socket"):
            read(tmp_path / name)
        assert time.monotonic() - t0 < 5


@pytest.mark.slow
def test_a_dask_run_whose_workers_are_all_gone_fails_after_its_timeout():
    from distributed import Client, LocalCluster

    from hybridnav.backends import DaskBackend

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        be = DaskBackend(client, no_workers_timeout=3.0)
        assert be.map(_pid, [(0,)])                      # works while a worker is there
        cluster.scale(0)
        deadline = time.time() + 30
        while client.scheduler_info()["workers"] and time.time() < deadline:
            time.sleep(0.1)
        t0 = time.monotonic()
        with pytest.raises(HybridnavError, match=r"^backend: the Dask scheduler has had no worker "
                                                 r"for 3 s; 2 of 2 task\(s\) unfinished"):
            be.map(time.sleep, [(0.1,), (0.1,)])
        assert 3.0 <= time.monotonic() - t0 < 20


# ---- stored reproductions (reproduce --update-readme) ---------------------------------------

@pytest.fixture(scope="module")
def store(tmp_path_factory):
    import shutil
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    base = tmp_path_factory.mktemp("store")
    shutil.copytree(root / "docs" / "reproductions" / "fastep-table2", base / "fastep-table2")
    return base


def _damaged(store, tmp_path, mutate):
    import shutil

    d = tmp_path / "store"
    shutil.copytree(store, d)
    readme = tmp_path / "README.md"
    readme.write_text("intro\n<!-- reproduce:fastep-table2 -->\nold\n"
                      "<!-- /reproduce:fastep-table2 -->\n")
    mutate(d / "fastep-table2", readme)
    return d, readme


def _columns_only(folder, readme):
    header = (folder / "summary.csv").read_text().splitlines()[0]
    (folder / "summary.csv").write_text(header + "\n")


def _all_nan(folder, readme):
    import pandas as pd

    df = pd.read_csv(folder / "summary.csv")
    for c in df.columns:
        if c not in ("planner", "scenario", "units"):
            df[c] = float("nan")
    df.to_csv(folder / "summary.csv", index=False)


def _text(folder, readme):
    import pandas as pd

    df = pd.read_csv(folder / "summary.csv")
    df["path_length_mean"] = "long"
    df.to_csv(folder / "summary.csv", index=False)


@pytest.mark.parametrize("mutate, expected", [
    (lambda f, r: r.write_bytes(r.read_bytes() + "caf\xe9".encode("latin-1")),
     r"README.md: not UTF-8 text: byte \d+ \(0xe9\) of the README cannot be decoded"),
    (lambda f, r: (f / "summary.csv").write_text("a,b\n1,2\n"),
     r"fastep-table2/summary.csv: planner: missing column \(expected the columns planner, "
     r"scenario, robots, success_rate"),
    (_columns_only, r"fastep-table2/summary.csv: expected a row per planner and scenario, got "
                    r"only the header"),
    (_all_nan, r"fastep-table2/summary.csv: success_rate: expected a share in \[0, 1\], got nan "
               r"in row 2"),
    (_text, r"fastep-table2/summary.csv: path_length_mean: expected numbers, got 'long' in row 2"),
    (lambda f, r: (f / "summary.csv").write_bytes(b"\x00\xff" * 8),
     r"fastep-table2/summary.csv: not UTF-8 text"),
    (lambda f, r: (f / "comparison.json").write_text('{"runs": ' + "9" * 5000 + "}"),
     r"fastep-table2/comparison.json: expected the comparison.json of a reproduction "
     r"\('Exceeds the limit"),
])
def test_update_readme_refuses_a_damaged_store_and_keeps_the_readme(store, tmp_path, capsys,
                                                                   mutate, expected):
    d, readme = _damaged(store, tmp_path, mutate)
    before = readme.read_bytes()
    assert main(["reproduce", "--update-readme", "--readme", str(readme), "--reports",
                 str(d)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hybridnav: error: ") and "Traceback" not in err
    assert __import__("re").search(expected, err), err
    assert len(err) < 700
    assert readme.read_bytes() == before


def test_update_readme_renders_an_intact_store(store, tmp_path):
    d, readme = _damaged(store, tmp_path, lambda f, r: None)
    assert main(["reproduce", "--update-readme", "--readme", str(readme), "--reports",
                 str(d)]) == 0
    text = readme.read_text()
    assert "old\n" not in text and "hybridnav reproduce fastep-table2" in text


@pytest.mark.parametrize("argv", [
    ["run", "fastep-s1", "--planner", "apf", "-o", "{o}"],
    ["compare", "--planners", "apf", "--scenarios", "fastep-s1", "--runs", "1", "-o", "{o}"],
    ["reproduce", "fastep-table2", "--runs", "1", "-o", "{o}"],
])
def test_run_compare_and_reproduce_refuse_a_folder_another_job_writes(argv, tmp_path, capsys):
    o = tmp_path / "o"
    with locked_folder(o, "tune other.toml"):
        assert main([a.format(o=o) for a in argv]) == 2
    err = capsys.readouterr().err
    assert f"hybridnav: error: {o}: another hybridnav job is writing this folder (pid " \
           f"{os.getpid()} on" in err
    assert not o.exists()                      # made for the lock, nothing written: removed


def test_a_5000_digit_value_gets_a_short_message_and_leaves_nothing(tmp_path, capsys):
    big = "9" * 5000
    for argv in (["compare", "--planners", f"apf@x:speed={big}", "--scenarios", "fastep-s1",
                  "--runs", "1", "-o", str(tmp_path / "c")],
                 ["generate", "--set", f"circles=[1,{big}]", "-o", str(tmp_path / "g")],
                 ["run", "fastep-s1", "--planner", "apf", "--set", f"speed={big}",
                  "-o", str(tmp_path / "r")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.splitlines()[-1]
        assert err.startswith("hybridnav: error: ") and len(err) < 400, err
    assert list(tmp_path.iterdir()) == []          # no folder, no stale lock


def test_an_unwritable_output_folder_fails_before_any_work(tmp_path, monkeypatch, capsys):
    """(A read-only folder cannot be made as root; the lock file's creation is refused instead,
    as the kernel refuses it in a read-only folder.)"""
    import hybridnav.fileio as fileio
    import hybridnav.tuner.run as tuner_run

    real_open = fileio.os.open

    def refuse(path, *a, **k):
        if str(path).endswith(LOCK_NAME):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr(fileio.os, "open", refuse)
    monkeypatch.setattr(tuner_run, "_run_job", lambda *a, **k: pytest.fail("work started"))
    t0 = time.monotonic()
    assert main(["tune", "--quick", "--out", str(tmp_path / "o")]) == 2
    assert time.monotonic() - t0 < 30
    err = capsys.readouterr().err
    assert f"hybridnav: error: {tmp_path / 'o'}: cannot write in the output folder (Permission " \
           "denied)" in err


@pytest.mark.parametrize("load", [
    lambda n: load_scenario(n), lambda n: __import__("hybridnav.fuzzy", fromlist=["x"]).load(n),
    lambda n: __import__("hybridnav.fuzzy", fromlist=["x"]).load_any(n),
    lambda n: __import__("hybridnav.world.grid", fromlist=["x"]).load_movingai_map(
        "movingai:" + n),
    lambda n: load_scenario("/no/such/" + n + ".toml"),
])
def test_a_name_longer_than_a_file_name_is_an_error_not_an_oserror(load):
    """Built-in names are looked up in the list of built-ins, never as arbitrary file names
    (a 5,000-character name raised 'File name too long'); long names and paths are cut."""
    with pytest.raises(HybridnavError) as info:
        load("effc-train" + "9" * 5000)
    assert len(str(info.value)) < 600


def test_a_file_that_is_not_a_table_or_a_fuzzy_system_is_not_echoed(tmp_path, capsys):
    """Found by a review: a trajectory linked to a secret, and .fll/.fis files that are not,
    showed their first line in the message."""
    secret = "API_KEY=sk-very-secret-0123456789abcdef"
    (tmp_path / "sec.fll").write_text(secret + "\n")
    (tmp_path / "sec.fis").write_text(secret + "\n")
    for name in ("sec.fll", "sec.fis"):
        assert main(["export", str(tmp_path / name), "--format", "json",
                     "-o", str(tmp_path / "o.json")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"hybridnav: error: {tmp_path / name}: line 1: ") and \
            "secret" not in err and "API_KEY" not in err, err
    out = tmp_path / "r"
    assert main(["run", "fastep-s1", "--planner", "apf", "-o", str(out)]) == 0
    traj = next(out.glob("trajectory_*.csv"))
    traj.unlink()
    (tmp_path / "secret.env").write_text(secret + "\n")
    traj.symlink_to(tmp_path / "secret.env")
    capsys.readouterr()
    assert main(["plot", str(out)]) == 2
    err = capsys.readouterr().err
    assert "line 1: expected the header t,x,y,..., got a first line of 1 field(s)" in err
    assert "secret" not in err.replace("secret.env", "") or "API_KEY" not in err


def test_a_robot_name_too_long_for_a_file_name_is_refused_before_the_run(tmp_path):
    from hybridnav.world import scenario_from_dict

    data = {"name": "s", "dt": 0.1, "max_time": 10,
            "workspace": {"xmin": 0, "xmax": 10, "ymin": 0, "ymax": 10},
            "robots": [{"name": "r" * 101, "model": "point_mass", "start": [1, 1],
                        "goal": [9, 9]}]}
    with pytest.raises(HybridnavError, match=r"robots\[0\]\.name: expected a name of at most "
                                             r"100 letters"):
        scenario_from_dict(data, "s.toml")
    data["robots"][0]["name"] = "r" * 100
    assert scenario_from_dict(data, "s.toml").robots[0].name == "r" * 100


def test_review_findings_of_small_hostile_inputs(tmp_path, capsys):
    """A 170 kB fuzzy file asking for 24 GB of memberships, a job's objectives of lists, a
    stored run's protocol of a list, an infinite verify timeout: each a named error."""
    import json

    from hybridnav.fuzzy import loads
    from hybridnav.fuzzy.spec import MAX_SAMPLES

    d = json.loads((__import__("pathlib").Path(__import__("hybridnav").__file__).parent
                    / "fuzzy" / "systems" / "effc-5rule.json").read_text())
    d["inputs"][0]["points"] = 1_000_000
    d["inputs"][0]["terms"] += [{"name": f"t{i}", "mf": "trimf", "params": [0, 0.5, 1]}
                                for i in range(3000)]
    with pytest.raises(HybridnavError, match=rf"^m.json: inputs\[0\]\.points: expected points x "
                                             rf"terms of at most {MAX_SAMPLES}"):
        loads(json.dumps(d), "m.json")
    job = tmp_path / "j.toml"
    job.write_text("[cost]\nobjectives = [[1, 2]]\n")
    assert main(["tune", str(job), "--out", str(tmp_path / "o")]) == 2
    assert "cost.objectives: expected a list of distinct names" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["verify", "effc-5rule", "x.c", "--timeout", "inf"])
    assert "argument --timeout: expected a time in (0, 86400] seconds" in \
        capsys.readouterr().err


def test_an_output_path_that_is_a_file_is_exit_2(tmp_path, capsys):
    res = tmp_path / "r"
    assert main(["run", "fastep-s1", "--planner", "apf", "-o", str(res)]) == 0
    (tmp_path / "afile").write_text("x")
    capsys.readouterr()
    assert main(["plot", str(res), "-o", str(tmp_path / "afile")]) == 2
    assert f"hybridnav: error: {tmp_path / 'afile'}: cannot use it (File exists)" in \
        capsys.readouterr().err
