"""One deprecation policy: every old name still works until 0.4.0 and warns, naming its
replacement and the removal version; the project itself uses none of them."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import hybridnav
from hybridnav.errors import HybridnavError
from hybridnav.deprecation import MOVED_MODULES, REMOVAL, HybridnavDeprecationWarning

ROOT = Path(__file__).resolve().parents[1]


def _fresh_import(name: str):
    """``import name`` as a statement in this file (not importlib's function)."""
    sys.modules.pop(name, None)
    exec(compile(f"import {name}", __file__, "exec"), {})
    return sys.modules[name]


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_an_old_module_name_warns_and_serves_the_new_module(old):
    new = MOVED_MODULES[old]
    with pytest.warns(HybridnavDeprecationWarning) as caught:
        alias = _fresh_import(old)
    message = str(caught[0].message)
    assert message == f"{old} is deprecated since 0.3.0 and will be removed in {REMOVAL}: use {new}"
    assert caught[0].filename == __file__           # attributed to the import, not to importlib
    target = importlib.import_module(new)
    for name in getattr(target, "__all__", []):
        assert getattr(alias, name) is getattr(target, name), name


def test_from_import_of_an_old_module_gives_the_same_objects():
    sys.modules.pop("hybridnav.grid", None)
    with pytest.warns(HybridnavDeprecationWarning, match=r"hybridnav\.grid .* use hybridnav\.world\.grid"):
        from hybridnav.grid import OccupancyGrid
    from hybridnav.world.grid import OccupancyGrid as new

    assert OccupancyGrid is new


def test_patching_through_an_old_module_name_patches_the_module():
    """Until 0.3 the old name was the module itself: ``mock.patch`` through it, or setting an
    attribute on it, reached the module; the alias forwards both."""
    from unittest import mock

    from hybridnav.planners.path import gridsearch as real

    with pytest.warns(HybridnavDeprecationWarning):
        gs = _fresh_import("hybridnav.planners.gridsearch")
    with mock.patch("hybridnav.planners.gridsearch.search_world", side_effect=RuntimeError):
        assert isinstance(real.search_world, mock.Mock)
    assert not isinstance(real.search_world, mock.Mock)
    gs.custom_attribute = 1
    assert real.custom_attribute == 1
    del gs.custom_attribute
    assert not hasattr(real, "custom_attribute")
    assert gs.__name__ == "hybridnav.planners.gridsearch" and real.__name__.endswith("path.gridsearch")


def test_running_an_old_module_name_is_a_clean_error():
    out = subprocess.run([sys.executable, "-m", "hybridnav.grid"], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode != 0 and "Traceback" not in out.stderr
    assert "No code object available for hybridnav.grid" in out.stderr


def test_import_linearize_as_module_works_and_keeps_the_function():
    """``import hybridnav.analysis.linearize as lin`` binds the package attribute, the function
    since 0.3.0: it carries the old module's names, and stays the function."""
    script = textwrap.dedent("""
        import warnings
        warnings.simplefilter("error")
        from hybridnav.analysis import linearize, summarize
        assert callable(linearize) and linearize.__module__ == "hybridnav.analysis.linearization"
        warnings.simplefilter("always")
        with warnings.catch_warnings(record=True) as w:
            import hybridnav.analysis.linearize as lin
        assert [str(x.message) for x in w] == [
            "hybridnav.analysis.linearize is deprecated since 0.3.0 and will be removed in "
            "0.4.0: use hybridnav.analysis.linearization"], w
        assert lin is linearize and lin.summarize is summarize
        import hybridnav.analysis
        assert hybridnav.analysis.linearize is linearize
        from hybridnav.analysis.linearize import LinearizationReport
        from hybridnav.analysis.linearization import LinearizationReport as new
        assert LinearizationReport is new
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_renamed_attributes_warn_and_work():
    from hybridnav import planners
    from hybridnav.models import get as get_model

    m = get_model("unicycle")
    with pytest.warns(HybridnavDeprecationWarning, match=r"Unicycle\.params .* use Unicycle\.values"):
        assert m.params == m.values
    apf = planners.get("apf")
    with pytest.warns(HybridnavDeprecationWarning, match=r"APF\.params .* use APF\.parameters"):
        assert type(apf).params is type(apf).parameters
    with pytest.warns(HybridnavDeprecationWarning, match=r"hybridnav\.planners\.MOVED .* 0\.4\.0"):
        assert planners.MOVED["apf"] == "field.apf"


def test_a_planner_declared_with_the_old_name_warns_and_is_declared_under_the_new():
    from hybridnav.params import Param
    from hybridnav.planners.base import Planner

    with pytest.warns(HybridnavDeprecationWarning, match=r"Old\.params .* use Old\.parameters") \
            as caught:
        class Old(Planner):
            name = "old-style"
            params = {"k": Param(1.0, "a gain")}

            def run(self, scenario, seed=0):
                raise NotImplementedError

    assert caught[0].filename == __file__         # the class statement: shown by default there
    assert Old.parameters["k"].default == 1.0
    assert Old(k=2.0).values["k"] == 2.0
    with pytest.raises(HybridnavError, match=r"^planner Both: expected its settings under "
                                             r"parameters only, got params \(their old name\)"):
        class Both(Planner):
            parameters = {"a": Param(1.0, "a")}
            params = {"b": Param(2.0, "b")}

            def run(self, scenario, seed=0):
                raise NotImplementedError


def test_a_planners_own_params_attribute_is_left_alone():
    """Only a dict of declarations is the old name; a property or an instance attribute named
    params is a planner's own (as before the rename)."""
    import warnings

    from hybridnav.params import Param
    from hybridnav.planners.base import Planner

    with warnings.catch_warnings():
        warnings.simplefilter("error")

        class Prop(Planner):
            parameters = {"a": Param(1.0, "a")}

            @property
            def params(self):
                return "mine"

            def run(self, scenario, seed=0):
                raise NotImplementedError

        class Inst(Planner):
            parameters = {"a": Param(1.0, "a")}

            def __init__(self, **kw):
                super().__init__(**kw)
                self.params = {"cache": 1}

            def run(self, scenario, seed=0):
                raise NotImplementedError

        assert Prop().params == "mine" and Prop(a=3.0).values["a"] == 3.0
        inst = Inst()
        assert inst.params == {"cache": 1} and set(Inst.parameters) == {"a"}


def test_the_old_name_read_on_a_class_without_the_new_is_the_descriptor():
    """``help(Unicycle)`` and ``inspect.getmembers`` read every class attribute: no warning, no
    AttributeError for ``values``, which only instances have."""
    import inspect
    import warnings

    from hybridnav.deprecation import RenamedAttribute
    from hybridnav.models import Unicycle

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert isinstance(Unicycle.params, RenamedAttribute)
        inspect.getmembers(Unicycle)


def test_the_jobs_old_heldout_key_warns_naming_the_file(tmp_path):
    from hybridnav.tuner import load_job

    job = tmp_path / "job.toml"
    job.write_text('[scenarios]\ntrain = ["effc-env-a"]\nheldout = ["effc-env-b"]\n')
    with pytest.warns(HybridnavDeprecationWarning) as caught:
        j = load_job(job)
    assert str(caught[0].message) == (f"{job}: scenarios.heldout is deprecated since 0.3.0 and "
                                      "will be removed in 0.4.0: use scenarios.test")
    assert caught[0].filename == __file__          # the caller's line, not hybridnav's
    assert [s.name for s in j.scenarios("test")] == ["effc-env-b"]


def test_the_command_line_shows_an_old_key_as_one_line(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('[scenarios]\ntrain = ["no-such-world"]\nheldout = ["effc-env-b"]\n')
    out = subprocess.run([sys.executable, "-m", "hybridnav", "tune", str(job), "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    assert lines[0] == (f"hybridnav: warning: {job}: scenarios.heldout is deprecated since 0.3.0 "
                        "and will be removed in 0.4.0: use scenarios.test")
    assert lines[1].startswith(f"hybridnav: error: {job}: scenarios.train[0]: ")


def test_the_command_line_keeps_quiet_when_the_user_silences_warnings(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('[scenarios]\ntrain = ["no-such-world"]\nheldout = ["effc-env-b"]\n')
    out = subprocess.run([sys.executable, "-W", "ignore", "-m", "hybridnav", "tune", str(job),
                          "--out", str(tmp_path / "out")], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 2 and "warning" not in out.stderr, out.stderr


def test_the_version_and_the_changelog_name_every_old_name():
    assert hybridnav.__version__ == "0.3.0"
    text = (ROOT / "CHANGELOG.md").read_text()
    assert re.search(r"^## 0\.3\.0\b", text, re.M)
    entry = text.split("## 0.3.0", 1)[1].split("\n## ", 1)[0]
    for old in [*MOVED_MODULES, "Model.params", "Planner.params", "scenarios.heldout",
                "hybridnav.planners.MOVED"]:
        assert f"`{old}`" in entry, old
    assert "0.4.0" in entry


def test_the_project_uses_no_old_name():
    """README, notebooks, examples, benchmarks and docs: the old module names appear only where
    the deprecation is explained (CHANGELOG, the deprecation module and this test)."""
    pattern = re.compile("|".join(re.escape(old) + r"\b(?!\.)" for old in MOVED_MODULES
                                  if old != "hybridnav.analysis.linearize")
                         + r"|hybridnav\.analysis\.linearize import")
    hits = []
    for folder, suffixes in ((ROOT / "hybridnav", {".py"}), (ROOT / "tests", {".py"}),
                             (ROOT / "benchmarks", {".py"}), (ROOT / "examples", {".py"}),
                             (ROOT / "notebooks", {".ipynb"}), (ROOT / "docs", {".py", ".rst", ".md"})):
        for path in folder.rglob("*"):
            if path.suffix not in suffixes or "_build" in path.parts or "gallery" in path.parts \
                    or path.name in ("deprecation.py", "test_deprecation.py") or "api" in path.parts:
                continue
            for i, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line) and "deprecat" not in line.lower():
                    hits.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    for name in ("README.md", "CONTRIBUTING.md"):
        for i, line in enumerate((ROOT / name).read_text().splitlines(), 1):
            if pattern.search(line) and "deprecat" not in line.lower():
                hits.append(f"{name}:{i}: {line.strip()}")
    assert not hits, "\n".join(hits)
