"""The package's import structure: no cycles (local imports included), every module imports alone,
and the old import paths kept as aliases still work."""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import networkx as nx
import pytest

import hybridnav

PACKAGE = Path(hybridnav.__file__).parent


def import_graph(root: Path) -> nx.DiGraph:
    """Modules of the package under ``root`` and the package modules each one imports (anywhere in
    the file, function-local imports included)."""
    mods = {}
    for p in root.rglob("*.py"):
        parts = list(p.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        mods[".".join(parts)] = p
    graph = nx.DiGraph()
    for name, path in mods.items():
        graph.add_node(name)
        pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    head = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    base = ".".join(head + ([base] if base else []))
                targets = [base] + [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            graph.add_edges_from((name, t) for t in targets if t in mods and t != name)
    return graph


def test_the_package_has_no_import_cycle():
    cycles = list(nx.simple_cycles(import_graph(PACKAGE)))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles[:5])


def test_the_cycle_check_finds_a_cycle(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from pkg.sub.b import f\n")
    (pkg / "a.py").write_text("def g():\n    from pkg.sub import f\n")
    (pkg / "sub" / "b.py").write_text("from pkg import a\n")
    cycles = list(nx.simple_cycles(import_graph(pkg)))
    assert sorted(map(sorted, cycles)) == [["pkg.a", "pkg.sub", "pkg.sub.b"]]


@pytest.mark.slow
def test_every_module_imports_alone():
    """Each module imported first, in a process where no other hybridnav module is loaded yet."""
    names = sorted(import_graph(PACKAGE).nodes)
    script = textwrap.dedent(f"""
        import importlib, sys
        failed = []
        for name in {names!r}:
            for loaded in [m for m in sys.modules if m == "hybridnav" or m.startswith("hybridnav.")]:
                del sys.modules[loaded]
            try:
                importlib.import_module(name)
            except Exception as exc:
                failed.append(f"{{name}}: {{type(exc).__name__}}: {{exc}}")
        print("\\n".join(failed))
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "", out.stdout


def test_every_module_declares_its_public_names_and_documents_them():
    """``__all__`` everywhere: each name it lists exists, and functions and classes have
    docstrings (the python-control convention the design follows)."""
    import importlib
    import inspect
    import pkgutil

    problems = []
    for info in pkgutil.walk_packages(hybridnav.__path__, "hybridnav."):
        mod = importlib.import_module(info.name)
        names = getattr(mod, "__all__", None)
        if names is None:
            problems.append(f"{info.name}: no __all__")
            continue
        for name in names:
            if not hasattr(mod, name):
                problems.append(f"{info.name}.{name}: listed in __all__, not defined")
                continue
            obj = getattr(mod, name)
            if (inspect.isfunction(obj) or inspect.isclass(obj)) and not (obj.__doc__ or "").strip():
                problems.append(f"{info.name}.{name}: no docstring")
    assert not problems, problems
