"""The compared variants of a protocol: each planner with profiles in both, ablations once."""

from __future__ import annotations

from typing import Any

from hybridnav.reproduce.protocols import Protocol

__all__ = ["PROFILES", "label_for", "variants"]

PROFILES = ("paper", "hybridnav")


def variants(protocol: Protocol) -> list[tuple[str, str, dict[str, Any]]]:
    """The compared ``(label, planner, params)``: both profiles where the planner has them."""
    from hybridnav import planners

    out = []
    for name in protocol.planners:
        base = dict(protocol.settings.get(name, {}))
        if planners.PLANNERS[name].profiles:
            out.append((f"{name}/paper", name, {**base, "profile": "paper"}))
        out.append((name, name, base))
    for label, name, params in protocol.ablations:
        out.append((label, name, {**protocol.settings.get(name, {}), **params}))
    return out


def label_for(protocol: Protocol, planner: str, profile: str) -> str:
    """The label of ``planner``'s variant in ``profile``.

    Parameters
    ----------
    protocol : Protocol
    planner : str
        A planner of the protocol.
    profile : {"paper", "hybridnav"}

    Returns
    -------
    str
        ``NAME/paper`` for the paper profile of a planner with profiles, else ``NAME`` (a
        planner without profiles runs once, for both).
    """
    from hybridnav import planners

    return f"{planner}/paper" if profile == "paper" and planners.PLANNERS[planner].profiles \
        else planner
