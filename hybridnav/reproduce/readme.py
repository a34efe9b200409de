"""README sections generated from stored reproductions, so that no number in them is copied
by hand.

A full run of ``hybridnav reproduce NAME`` kept under ``docs/reproductions/NAME/`` (its
``summary.csv`` and ``comparison.json``) is what README's section on that protocol shows: the
text between ``<!-- reproduce:NAME -->`` and ``<!-- /reproduce:NAME -->`` is :func:`render` of
that folder, and ``hybridnav reproduce --update-readme`` rewrites every such block. A test
renders each block again from the stored files and compares it with README.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd

from hybridnav.errors import HybridnavError
from hybridnav.fileio import atomic_write_text
from hybridnav.reproduce.protocols import PROTOCOLS

__all__ = ["STORE", "blocks", "load_stored", "render", "update_readme"]

#: where the full runs are kept, relative to the repository's root
STORE = Path("docs") / "reproductions"

_BLOCK = re.compile(r"<!-- reproduce:(?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /reproduce:(?P=name) -->",
                    re.S)


def load_stored(folder: str | Path) -> tuple[str, pd.DataFrame, dict]:
    """``(protocol name, summary, settings)`` of a stored reproduction.

    Raises
    ------
    HybridnavError
        A missing or unreadable ``summary.csv``/``comparison.json``, or a protocol that no
        longer exists (naming the file and key).
    """
    folder = Path(folder)
    meta_path = folder / "comparison.json"
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError) as exc:
        raise HybridnavError(f"{meta_path}: expected the comparison.json of a reproduction "
                             f"({exc})") from None
    name = meta.get("protocol") if isinstance(meta, dict) else None
    if name not in PROTOCOLS:
        raise HybridnavError(f"{meta_path}: protocol: expected one of "
                             f"{', '.join(sorted(PROTOCOLS))}, got {name!r}")
    try:
        summary = pd.read_csv(folder / "summary.csv")
    except (OSError, ValueError) as exc:
        raise HybridnavError(f"{folder / 'summary.csv'}: expected the summary of a "
                             f"reproduction ({exc})") from None
    return name, summary, meta


def render(folder: str | Path) -> str:
    """The README block of the stored reproduction in ``folder``: how it was run, the paper's
    numbers beside ours per profile, and the paper's claims checked (as in its ``report.md``).
    """
    import dataclasses

    from hybridnav.reproduce.report import (check_claims, claims_section, has_profiles,
                                            literature_line, profile_sections,
                                            variants_section)

    name, summary, meta = load_stored(folder)
    protocol = PROTOCOLS[name]
    scenarios = meta.get("scenarios") or [row.scenario for row in protocol.rows]
    protocol = dataclasses.replace(protocol, rows=tuple(
        row for row in protocol.rows if row.scenario in scenarios))
    how = (f"Measured by `hybridnav reproduce {name}` with hybridnav {meta.get('version')}: "
           f"{meta.get('runs')} run(s) per planner and scenario (the paper: {protocol.runs}), "
           f"seed {meta.get('seed')}")
    if meta.get("elapsed_s") is not None:
        how += (f", {meta['elapsed_s'] / 60:.1f} min with {meta.get('workers', 1)} worker(s) "
                f"(load {meta.get('load', '?')})")
    how += (f". The whole report, with every variant, the bounds of our layouts and the "
            f"figures: [`{STORE.as_posix()}/{name}/report.md`]({STORE.as_posix()}/{name}/"
            "report.md).")
    lines = [how, ""]
    lines += profile_sections(protocol, summary, level=4)
    if protocol.ablations:
        lines += variants_section(protocol, summary, level=4,
                                  only=[label for label, _, _ in protocol.ablations])
    lines += literature_line(protocol)
    lines += claims_section(check_claims(protocol, summary), level=4,
                            profiles=has_profiles(protocol))
    return "\n".join(lines)


def blocks(text: str) -> dict[str, str]:
    """The reproduce blocks of a README: ``{protocol name: body}``."""
    return {m["name"]: m["body"] for m in _BLOCK.finditer(text)}


def update_readme(readme: str | Path, store: str | Path) -> list[str]:
    """Rewrite every reproduce block of ``readme`` from ``store/NAME``; returns the names.

    Raises
    ------
    HybridnavError
        A block whose protocol has no stored run (naming the folder), or no block at all.
    """
    readme = Path(readme)
    text = readme.read_text()
    found = blocks(text)
    if not found:
        raise HybridnavError(f"{readme}: expected <!-- reproduce:NAME --> blocks, found none")
    for name in found:
        if not (Path(store) / name / "summary.csv").exists():
            raise HybridnavError(f"{Path(store) / name}: expected a stored run of "
                                 f"`hybridnav reproduce {name}` for README's block")

    def sub(m: re.Match) -> str:
        body = render(Path(store) / m["name"])
        return f"<!-- reproduce:{m['name']} -->\n{body}\n<!-- /reproduce:{m['name']} -->"

    atomic_write_text(readme, _BLOCK.sub(sub, text))
    return list(found)
