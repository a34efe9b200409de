"""The documentation builds with warnings as errors, its gallery runs, and its API reference has
pages for the public functions (CI builds it here, with the suite)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytest.importorskip("sphinx")
pytest.importorskip("sphinx_gallery")
pytest.importorskip("myst_parser")


@pytest.mark.slow
def test_the_docs_build_with_warnings_as_errors(tmp_path):
    out = tmp_path / "html"
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                          "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(out)],
                         capture_output=True, text=True, cwd=ROOT, timeout=1800)
    assert run.returncode == 0, run.stderr[-4000:]
    for name, params in (("hybridnav.tuner.tune", ("system", "cost", "optimizer", "validation")),
                         ("hybridnav.analysis.check_lyapunov", ("target", "region", "level"))):
        page = out / "api" / "generated" / f"{name}.html"
        text = page.read_text(encoding="utf-8")
        assert "Parameters" in text and "Returns" in text, name
        for p in params:
            assert re.search(rf">{p}<", text), (name, p)
    # the gallery ran: every example has its page with at least one figure
    examples = sorted(p.stem for p in (ROOT / "examples").glob("plot_*.py"))
    assert len(examples) >= 4
    for ex in examples:
        page = (out / "gallery" / f"{ex}.html").read_text(encoding="utf-8")
        assert re.search(r'<img[^>]+sphx_glr_' + ex, page), ex
    # the user guide carries the README's sections
    guide = (out / "guide" / "tuning.html").read_text(encoding="utf-8")
    assert "Tuning any fuzzy system" in guide
