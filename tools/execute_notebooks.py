"""Execute the notebooks in ``notebooks/`` and store them with their outputs.

The repository keeps the notebooks executed, so that they read with their tables and figures on
any notebook viewer; ``tests/test_notebooks.py`` executes them again and checks that the stored
text outputs are what the code prints now. Run after changing a notebook or what it shows::

    python tools/execute_notebooks.py            # all of them
    python tools/execute_notebooks.py 02_fuzzy_tuning.ipynb
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient

FOLDER = Path(__file__).resolve().parent.parent / "notebooks"


def execute(path: Path) -> nbformat.NotebookNode:
    """The notebook at ``path`` executed in a temporary folder (what it writes goes there)."""
    nb = nbformat.read(path, as_version=4)
    with tempfile.TemporaryDirectory() as tmp:
        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": tmp}}).execute()
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
