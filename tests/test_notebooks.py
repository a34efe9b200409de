"""The notebooks run top to bottom; their cells assert what they show; the repository stores
them executed (`python tools/execute_notebooks.py`), with the outputs the code gives now."""

from __future__ import annotations

import copy
import importlib.util
import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
_spec = importlib.util.spec_from_file_location("execute_notebooks",
                                               ROOT / "tools" / "execute_notebooks.py")
execute_notebooks = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(execute_notebooks)


_NUMBER = re.compile(r"-?\d+\.\d*(?:e[-+]?\d+)?|-?\d+e[-+]?\d+", re.I)


def _six_digits(text: str) -> str:
    """Numbers to 6 significant digits: the last digits of a float depend on the BLAS kernel
    and the CPU (an eigen-solver's 1.5 prints 1.4999999999999998 on another machine)."""
    return _NUMBER.sub(lambda m: f"{float(m.group()):.6g}", text)


def _printed(cell) -> list[str]:
    """What a cell printed and returned as text (stderr left out: warnings name local paths).
    Consecutive prints are one text, as a notebook shows them: how the kernel splits them into
    stream messages depends on timing."""
    out: list[str] = []
    joined = False                          # the last item is printed text: join what follows
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream":
            if o.get("name") == "stdout":
                if joined:
                    out[-1] += o["text"]
                else:
                    out.append(o["text"])
                    joined = True
            continue                        # (stderr does not separate prints either)
        joined = False
        if "text/plain" in o.get("data", {}) and not re.fullmatch(
                r"<(Figure|matplotlib\.\w+).*>", o["data"]["text/plain"].strip(), re.S):
            out.append(o["data"]["text/plain"])
    return [_six_digits(t) for t in out]


@pytest.mark.slow
# the default run executes the stability analysis notebook; the tuning and comparison notebooks
# (whose workflows the tuner's and compare's command-line tests run) with -m long
@pytest.mark.parametrize("path", [p if p.name.startswith("01_") else
                                  pytest.param(p, marks=pytest.mark.long) for p in NOTEBOOKS],
                         ids=[p.name for p in NOTEBOOKS])
def test_notebook_executes_and_is_stored_executed(path, tmp_path):
    stored = nbformat.read(path, as_version=4)
    code = [c for c in stored.cells if c.cell_type == "code"]
    assert [c.execution_count for c in code] == list(range(1, len(code) + 1)), \
        f"{path.name}: store it executed, in order (python tools/execute_notebooks.py)"
    stored_on = stored.metadata.get("hybridnav", {}).get("machine")
    here = execute_notebooks.machine()
    assert stored_on, f"{path.name}: store it with python tools/execute_notebooks.py (its " \
        "metadata names the kind of machine its outputs come from)"
    nb = copy.deepcopy(stored)
    client = NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}})
    client.execute()     # raises CellExecutionError, with the failing cell, if an assert fails
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if o.get("output_type") == "error"]
    assert not errors
    stderr = "".join(o["text"] for c in nb.cells if c.cell_type == "code"
                     for o in c.get("outputs", []) if o.get("name") == "stderr")
    assert "HybridnavDeprecationWarning" not in stderr       # the notebooks use current names
    fresh = [c for c in nb.cells if c.cell_type == "code"]
    images = lambda c: sum("image/png" in o.get("data", {}) for o in c.get("outputs", []))  # noqa: E731
    for i, (old, new) in enumerate(zip(code, fresh)):
        assert images(old) == images(new), f"{path.name}, code cell {i + 1}: figures"
    if stored_on != here:
        # a tuner's numbers (and the rules it learns) follow last-bit differences of NumPy's
        # SIMD kernels and BLAS: across kinds of machine only the cells' own asserts and their
        # figures are checked
        pytest.skip(f"{path.name}: stored on {stored_on!r}, executed on {here!r}: the stored "
                    "text outputs are compared only on the kind of machine that stored them")
    for i, (old, new) in enumerate(zip(code, fresh)):
        assert _printed(old) == _printed(new), \
            f"{path.name}, code cell {i + 1}: the stored output is not what it prints now " \
            "(python tools/execute_notebooks.py)"
