"""Software in the loop (issue 15): the exported C controller, compiled and run in a child process
(issue 27), drives the EFFC closed loop exactly as the Python evaluator does."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from hybridnav import HybridnavError, fuzzy, planners
from hybridnav.fuzzy.export.closedloop import verify
from hybridnav.cli import main
from hybridnav.fuzzy.export import export
from hybridnav.fuzzy.export.sil import CompiledFIS
from hybridnav.world import load_scenario

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                                reason="no C compiler")
WORLDS = ["effc-train-1", "effc-train-2", "effc-env-a", "effc-env-b"]


@pytest.mark.parametrize("name", [pytest.param("effc-2rule", marks=pytest.mark.long),
                                  pytest.param("effc-5rule", marks=pytest.mark.long), "effc-tuned"])
def test_compiled_c_trajectories_equal_python_to_1e9(tmp_path, name):
    fs = fuzzy.builtin(name)
    export(fs, "c", tmp_path / "effc")
    compiled = CompiledFIS(tmp_path / "effc.c")
    assert compiled.input_names == fs.input_names
    # effc-tuned is deployed with the safety filter it was tuned with (its description says so)
    margin = 0.05 if name == "effc-tuned" else 0.0
    rows = verify(fs, compiled, [load_scenario(w) for w in WORLDS], safety_margin=margin)
    assert len(rows) == 4
    for r in rows:
        assert r["samples"] > 50 and r["same_inputs_w_diff"] <= 1e-12, r   # the export is exact
        if margin:          # the filter's decisions at its margin can part the loops on rounding
            assert r["same_outcome"] or r["outcome"] not in ("collided", "out_of_bounds")
            continue
        assert r["same_outcome"]
        assert r["max_state_diff"] <= 1e-9 and r["max_w_diff"] <= 1e-9, r


def test_the_compiled_evaluator_equals_evaluate_on_a_grid(tmp_path):
    fs = fuzzy.builtin("effc-5rule")
    export(fs, "c", tmp_path / "fis")
    compiled = CompiledFIS(tmp_path / "fis.c")
    d, a = np.meshgrid(np.linspace(-0.5, 3.5, 41), np.linspace(-0.2, 2.0, 37))
    np.testing.assert_allclose(compiled.evaluate(dtheta=d, alpha=a),
                               fs.evaluate(dtheta=d, alpha=a), rtol=0, atol=1e-12)
    assert np.isnan(compiled.evaluate(dtheta=np.nan, alpha=0.3))
    with pytest.raises(TypeError, match="takes the inputs dtheta, alpha"):
        compiled.evaluate(dtheta=0.1)


def test_run_with_the_c_file_and_verify_from_the_cli(tmp_path, capsys):
    fs = fuzzy.builtin("effc-tuned")
    export(fs, "c", tmp_path / "effc")
    c = str(tmp_path / "effc.c")
    assert main(["run", "effc-env-b", "--planner", "effc", "--fis", c,
                 "--out", str(tmp_path / "run")]) == 0
    py = planners.get("effc", fis=fs).run(load_scenario("effc-env-b"))
    from hybridnav.results import read_result

    back = read_result(tmp_path / "run")
    np.testing.assert_allclose(back.robots[0].states, py.robots[0].states, rtol=0, atol=1e-9)
    assert back.params["fis"] == c
    capsys.readouterr()
    assert main(["verify", "effc-tuned", c, "--scenarios", "effc-env-a,effc-env-b"]) == 0
    assert "verified: every trajectory and w signal within 1e-09" in capsys.readouterr().out
    # a float build is the deployment artifact too, and it is not the same system to 1e-9
    export(fs, "c", tmp_path / "single", real="float")
    assert main(["verify", "effc-tuned", str(tmp_path / "single.c"), "--scenarios",
                 "effc-env-b"]) == 1
    assert "NOT verified" in capsys.readouterr().out


def test_bad_c_files_are_refused_with_the_file(tmp_path, monkeypatch):
    with pytest.raises(HybridnavError, match=r"nope\.c: no such file"):
        CompiledFIS(tmp_path / "nope.c")
    (tmp_path / "x.c").write_text("int x;\n")
    (tmp_path / "x.h").write_text("/* nothing */\n")
    with pytest.raises(HybridnavError, match=r"x\.h: not a hybridnav C export"):
        CompiledFIS(tmp_path / "x.c")
    export(fuzzy.builtin("effc-2rule"), "c", tmp_path / "e")
    text = (tmp_path / "e.c").read_text()
    (tmp_path / "e.c").write_text(text + "\nthis is not C\n")
    lines = text.count("\n")
    with pytest.raises(HybridnavError, match=rf"e\.c: expected the file hybridnav exports for the "
                                             rf"system embedded in e\.c, unmodified, got one that "
                                             rf"differs from it at line {lines + 2}; .* --trust"):
        CompiledFIS(tmp_path / "e.c")
    # trusted, it is compiled: the first error's location and kind, nothing it quotes
    with pytest.raises(HybridnavError, match=rf"e\.c: does not compile: .*e\.c:{lines + 2}:1: "
                                             r"unknown type name '\.\.\.'\Z"):
        CompiledFIS(tmp_path / "e.c", trust=True)
    monkeypatch.setenv("CC", "/no/such/compiler")
    with pytest.raises(HybridnavError, match=r"no C compiler"):
        CompiledFIS(tmp_path / "e.c", trust=True)


def test_an_export_with_a_huge_input_index_is_refused_by_name(tmp_path):
    """A header edited to declare an input index past Python's int-string limit (4300 digits)
    is not a hybridnav export: a HybridnavError naming the header, not a ValueError (found by
    test_verify_untrusted's property test)."""
    from hybridnav.fuzzy import builtin
    from hybridnav.fuzzy.export.c import to_c
    from hybridnav.fuzzy.export.sil import CompiledFIS

    code = to_c(builtin("effc-5rule"), "effc")
    header = code.header
    (tmp_path / "effc.c").write_text(code.source)
    for line, big in (("#define EFFC_IN_ALPHA 1", "#define EFFC_IN_ALPHA " + "9" * 4301),
                      ("#define EFFC_N_INPUTS 2", "#define EFFC_N_INPUTS " + "9" * 4301)):
        (tmp_path / "effc.h").write_text(header.replace(line, big))
        with pytest.raises(HybridnavError, match=r"effc\.h: not a hybridnav C export \(inputs "
                                                 r"not declared\)"):
            CompiledFIS(tmp_path / "effc.c")
