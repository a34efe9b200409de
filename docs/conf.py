"""Sphinx configuration of hybridnav's documentation.

Build it (warnings are errors, as CI builds it)::

    python -m pip install ".[docs]"
    python -m sphinx -W --keep-going -b html docs docs/_build/html

The user guide pages include the README's sections (one text, two places); the API reference is
generated from the package's numpydoc docstrings; the gallery runs ``examples/*.py``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("MPLBACKEND", "Agg")

import hybridnav  # noqa: E402

project = "hybridnav"
author = "The hybridnav developers"
copyright = "2026, The hybridnav developers"
release = hybridnav.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
# the stored reproductions' own reports are pages; the GA runs' and layouts' folders inside are not
exclude_patterns = ["_build", "**/.ipynb_checkpoints", "reproductions/*/*/**"]
# the README's blocks (included by the guide pages) step from H1 to H3 or H4 where a page starts
# inside a section; that is layout only
suppress_warnings = ["myst.header"]
root_doc = "index"

# API reference: one page per public object, from the numpydoc docstrings
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "inherited-members": False}
autodoc_typehints = "none"              # numpydoc's Parameters sections say the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False


def _share_numpydoc_template() -> None:
    """numpydoc 1.x builds a new jinja environment for every docstring it renders and compiles
    its template again each time (2,600 docstrings: about 20 s of a 70 s build); every
    environment it builds here shares the template compiled first (the same file and loader
    settings throughout a build)."""
    import numpydoc.docscrape_sphinx as ds

    base = ds.SandboxedEnvironment
    if getattr(base, "_hybridnav_shared", False):
        return

    class SharedTemplate(base):
        _hybridnav_shared = True
        _compiled: dict = {}

        def get_template(self, name, *args, **kwargs):
            if name not in self._compiled:
                self._compiled[name] = super().get_template(name, *args, **kwargs)
            return self._compiled[name]

    ds.SandboxedEnvironment = SharedTemplate


_share_numpydoc_template()

myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "image_scrapers": ("matplotlib",),
    "reset_modules": (),
    # no docs/sg_execution_times.rst: a build must not rewrite a file of the source tree
    "write_computation_times": False,
}

html_theme = "pydata_sphinx_theme"
html_title = f"hybridnav {release}"
html_theme_options = {"show_toc_level": 2, "navigation_with_keys": False}
html_static_path: list[str] = []

# ---- the API reference: one page per public package, listing its ``__all__`` -----------------
#: the packages users import from (their ``__all__`` is the public API)
API = {
    "hybridnav": "Top level: errors and the version",
    "hybridnav.models": "Kinematic models (CasADi)",
    "hybridnav.world": "Worlds, obstacles, scenarios and their files",
    "hybridnav.world.grid": "Occupancy grids and MovingAI maps",
    "hybridnav.world.generator": "Generated worlds",
    "hybridnav.analysis": "Stability analysis",
    "hybridnav.fuzzy": "Mamdani fuzzy systems, their files and exports",
    "hybridnav.tuner": "Tuning fuzzy systems",
    "hybridnav.planners": "Planners",
    "hybridnav.planners.swarm": "Swarm optimizers",
    "hybridnav.results": "Run results and their files",
    "hybridnav.plotting": "Figures",
    "hybridnav.params": "Settings and their checks",
    "hybridnav.backends": "Parallel backends",
    "hybridnav.experiments.compare": "Planner comparisons",
    "hybridnav.experiments.convergence": "Convergence of the swarm searches",
    "hybridnav.reproduce": "Reproductions of the papers",
    "hybridnav.fuzzy.export.sil": "Software in the loop: the C export compiled and called",
    "hybridnav.fuzzy.export.closedloop": "Software in the loop: the C export in closed loop",
    "hybridnav.deprecation": "Deprecated names and when they go",
}


def _write_api_pages() -> None:
    import importlib

    api = Path(__file__).parent / "api"
    api.mkdir(exist_ok=True)
    index = ["API reference", "=============", "",
             "Every public name, by the package it is imported from (its ``__all__``); each page",
             "is generated from the numpydoc docstrings.", "", ".. toctree::", "   :maxdepth: 1",
             ""]
    for name, title in API.items():
        module = importlib.import_module(name)
        names = sorted(getattr(module, "__all__", []))
        head = f"``{name}``: {title}"
        lines = [head, "=" * len(head), "", f".. automodule:: {name}", "   :no-members:", "",
                 f".. currentmodule:: {name}", "", ".. autosummary::", "   :toctree: generated",
                 "   :nosignatures:", ""]
        lines += [f"   {n}" for n in names]
        text = "\n".join(lines) + "\n"
        page = api / f"{name}.rst"
        if not page.exists() or page.read_text() != text:
            page.write_text(text)
        index.append(f"   {name}")
    text = "\n".join(index) + "\n"
    if not (api / "index.rst").exists() or (api / "index.rst").read_text() != text:
        (api / "index.rst").write_text(text)


_write_api_pages()
