"""How figures are written: one save function, the formats and resolutions it takes.

Every figure hybridnav writes (``run``, ``plot``, ``show``, ``compare``, ``fis``, ``analyze``,
``tune``, ``reproduce`` and their Python functions) goes through :func:`save_figure`; the
commands' ``--format png|pdf|svg`` and ``--dpi N`` are checked by :func:`check_format` and
:func:`check_dpi` (declared in :mod:`hybridnav.params`, which the command line reads without
loading matplotlib) and name their files with :func:`figure_name`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_path
from hybridnav.params import DEFAULT_DPI, FIGURE_FORMATS, MAX_DPI, check_dpi, check_figure_format

__all__ = ["DEFAULT_DPI", "FORMATS", "MAX_DPI", "check_dpi", "check_format", "figure_name",
           "is_figure_name", "save_figure"]

if TYPE_CHECKING:
    from matplotlib.figure import Figure

log = logging.getLogger(__name__)

#: the formats the commands write
FORMATS = FIGURE_FORMATS


def check_format(fmt: object, name: str = "format") -> str:
    """``fmt`` as one of :data:`FORMATS` (lower case), else a HybridnavError naming ``name``
    (:func:`hybridnav.params.check_figure_format`).

    Parameters
    ----------
    fmt : str
        ``"png"``, ``"pdf"`` or ``"svg"`` (any case, a leading dot allowed).
    name : str
        The option or parameter the value came from (e.g. ``"--format"``).
    """
    return check_figure_format(fmt, name)


def figure_name(stem: str, fmt: str = "png") -> str:
    """The file name of figure ``stem`` in format ``fmt``: ``figure_name("path", "svg")`` is
    ``"path.svg"``; a name that already has a figure suffix gets ``fmt``'s instead.

    Parameters
    ----------
    stem : str
        ``"path"`` or ``"path.png"``.
    fmt : str
        One of :data:`FORMATS`.
    """
    fmt = check_format(fmt)
    base, dot, suffix = stem.rpartition(".")
    if dot and suffix.lower() in FORMATS:
        stem = base
    return f"{stem}.{fmt}"


def is_figure_name(name: str) -> bool:
    """Whether the file name ``name`` ends in a figure suffix of :data:`FORMATS`.

    Parameters
    ----------
    name : str
    """
    return Path(name).suffix.lower().lstrip(".") in FORMATS


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = DEFAULT_DPI,
                bbox_inches: str | None = "tight") -> Path:
    """Write a figure to ``path`` atomically, in the format its suffix names; returns the path.

    PDF and SVG are written without a creation date, so the same figure gives the same file.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or path-like
        Ends in ``.png``, ``.pdf`` or ``.svg`` (what the commands write), or another suffix
        matplotlib writes (``.jpg``, ``.eps``, ...: ``hybridnav show -o``).
    dpi : int
        Dots per inch, in ``[MIN_DPI, MAX_DPI]`` (10 to 1200).
    bbox_inches : str or None
        As for :meth:`matplotlib.figure.Figure.savefig`.

    Raises
    ------
    HybridnavError
        A suffix matplotlib does not write, or a ``dpi`` out of range.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(path)
    formats = FigureCanvasAgg.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in formats:
        raise HybridnavError(f"{path}: expected a picture file name ending in one of "
                             f"{', '.join('.' + f for f in sorted(formats))}, got "
                             f"{'.' + suffix if suffix else 'no suffix'}")
    dpi = check_dpi(dpi)
    metadata = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}.get(suffix)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, bbox_inches=bbox_inches, format=suffix, metadata=metadata)
    log.debug("wrote %s", path)
    return path
