"""The built-in scenarios and data files shipped in ``hybridnav/scenarios``."""

from __future__ import annotations

from importlib import resources

__all__ = ["builtin_data_path"]

_SCENARIO_PACKAGE = "hybridnav.scenarios"


def _builtin_dir():
    return resources.files(_SCENARIO_PACKAGE)


def builtin_data_path(name: str):
    """A file shipped in ``hybridnav/scenarios/data`` (an importlib.resources Traversable).

    Parameters
    ----------
    name : str
        File name, e.g. ``"arena.map"``.
    """
    return _builtin_dir().joinpath("data", name)
