"""Suite-wide collection order: the tests marked ``slow`` run first.

The suite runs on every core (``-n auto --dist worksteal`` in pyproject.toml). A test of half a
minute that starts last keeps its worker busy while the other one has nothing left to take: the
run lasts as long as that test after everything else is done. Started early, the long tests share
the cores from the beginning and the many quick ones fill the gaps at the end (the longest
processing time first rule of scheduling). Mark a test ``slow`` when it takes more than about
ten seconds.

A module's tests stay together (its slow ones first): a module-scoped fixture is torn down
when the next test belongs to another module, so pulling a module's slow tests away from its
other tests would build that fixture twice.
"""

from __future__ import annotations

import os
from pathlib import Path

# Bytecode: where PYTHONDONTWRITEBYTECODE is set (as on our CI machines), every process the suite
# starts (the xdist workers, command-line runs, pool and dask workers, notebook kernels, the docs
# build) compiled every module it imports again: 0.3-0.5 s each for hybridnav alone. The suite's
# processes keep bytecode in the user's own cache folder instead (PYTHONPYCACHEPREFIX: `pycache`
# beside hybridnav's compiled kernels, ~/.cache/hybridnav/pycache by default; created private,
# used only when the user owns it), never beside the sources. It holds every imported package's bytecode (about 60 MB)
# and is reused by later sessions; delete it at will. Set before xdist starts its workers.


def _private_pycache() -> Path | None:
    from hybridnav.native import cache_dir

    folder = cache_dir().parent / "pycache"
    try:
        folder.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = folder.stat()
    except OSError:
        return None
    if hasattr(os, "getuid") and (st.st_uid != os.getuid() or st.st_mode & 0o022):
        return None                         # another user's, or writable by others: not used
    return folder


if os.environ.get("PYTHONDONTWRITEBYTECODE") and not os.environ.get("PYTHONPYCACHEPREFIX"):
    _cache = _private_pycache()
    if _cache is not None:
        os.environ["PYTHONPYCACHEPREFIX"] = str(_cache)
        del os.environ["PYTHONDONTWRITEBYTECODE"]


def _slow(item) -> bool:
    return item.get_closest_marker("slow") is not None


def pytest_collection_modifyitems(session, config, items):
    """Modules holding ``slow`` tests first, and within every module its ``slow`` tests first;
    otherwise the collection order."""
    modules: dict[object, list] = {}
    for item in items:
        modules.setdefault(item.module if hasattr(item, "module") else None, []).append(item)
    groups = [sorted(group, key=lambda it: not _slow(it)) for group in modules.values()]
    groups.sort(key=lambda group: not _slow(group[0]))      # (stable: both keep their order)
    items[:] = [item for group in groups for item in group]
