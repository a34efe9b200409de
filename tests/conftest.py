"""Suite-wide collection order: the tests marked ``slow`` run first.

The suite runs on every core (``-n auto --dist worksteal`` in pyproject.toml). A test of half a
minute that starts last keeps its worker busy while the other one has nothing left to take: the
run lasts as long as that test after everything else is done. Started first, the long tests share
the cores from the beginning and the many quick ones fill the gaps at the end (the longest
processing time first rule of scheduling). Mark a test ``slow`` when it takes more than about
ten seconds; the order changes nothing else (each test sets up what it needs).
"""

from __future__ import annotations


def pytest_collection_modifyitems(session, config, items):
    """Move the ``slow`` tests to the front, keeping the order within both groups."""
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    if slow:
        rest = [item for item in items if item.get_closest_marker("slow") is None]
        items[:] = slow + rest
