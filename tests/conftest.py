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
