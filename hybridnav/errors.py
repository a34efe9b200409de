"""The one exception type for bad user input."""

from __future__ import annotations

__all__ = ["HybridnavError", "where"]


class HybridnavError(ValueError):
    """Bad input: a file, key or value that is not what hybridnav expects.

    The message names the file (when there is one), the key and what was expected. The CLI prints it
    and exits with status 2, without a traceback.
    """


def where(source: str | None, key: str) -> str:
    """Return the ``"file: key"`` prefix used by error messages.

    Parameters
    ----------
    source : str or None
        File name (or other origin such as ``"<string>"``); omitted when None.
    key : str
        Dotted key path, e.g. ``"robots[1].start"``.
    """
    return f"{source}: {key}" if source else key
