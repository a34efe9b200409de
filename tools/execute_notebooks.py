"""Execute the notebooks in ``notebooks/`` and store them with their outputs.

The repository keeps the notebooks executed, so that they read with their tables and figures on
any notebook viewer; ``tests/test_notebooks.py`` executes them again and checks that the stored
text outputs are what the code prints now (on the same kind of CPU: :func:`machine`, recorded in
each notebook's metadata). Run after changing a notebook or what it shows::

    python tools/execute_notebooks.py            # all of them
    python tools/execute_notebooks.py 02_fuzzy_tuning.ipynb
"""

from __future__ import annotations

import platform
import sys
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient

FOLDER = Path(__file__).resolve().parent.parent / "notebooks"


#: the CPU features that change the last bits NumPy computes (its SIMD kernels for
#: transcendental functions; BLAS picks kernels by the same generations): AVX2 + FMA, AVX-512;
#: ARM's ASIMD, SVE (names every NumPy version has)
_SIMD = ("AVX2", "FMA3", "AVX512F", "AVX512_SKX", "ASIMD", "SVE")


def machine() -> str:
    """The kind of machine the outputs depend on: the architecture, NumPy's version and the
    SIMD features it dispatches to.

    Optimizers and trajectories amplify last-bit differences, so a notebook executed on an
    AVX-512 machine prints other tuned numbers (and learns other rules) than on an AVX2 one;
    :mod:`tests.test_notebooks` compares the stored text outputs only on the kind of machine
    that stored them (``metadata.hybridnav.machine``) and the outputs' structure everywhere."""
    import numpy as np

    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:                                     # NumPy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    arch = {"arm64": "aarch64", "amd64": "x86_64"}.get(platform.machine().lower(),
                                                        platform.machine().lower())
    numpy_version = ".".join(np.__version__.split(".")[:2])
    return " ".join([arch, f"numpy-{numpy_version}"] + [f for f in _SIMD if features.get(f)])


def execute(path: Path) -> nbformat.NotebookNode:
    """The notebook at ``path`` executed in a temporary folder (what it writes goes there)."""
    nb = nbformat.read(path, as_version=4)
    with tempfile.TemporaryDirectory() as tmp:
        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": tmp}}).execute()
    nb.metadata["hybridnav"] = {"machine": machine()}
    return nb


def main(names: list[str]) -> int:
    paths = [FOLDER / n for n in names] if names else sorted(FOLDER.glob("*.ipynb"))
    for path in paths:
        nb = execute(path)
        nbformat.write(nb, path)
        print(f"{path.name}: executed and stored ({path.stat().st_size / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
