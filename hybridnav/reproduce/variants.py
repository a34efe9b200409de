"""The compared variants of a protocol: each planner with profiles in both, ablations once, and
each of them once per value of the protocol's sweep where its planner has the swept parameter."""

from __future__ import annotations

from typing import Any

from hybridnav.reproduce.protocols import Protocol

__all__ = ["PROFILES", "label_for", "levels", "sweep_label", "variants"]

PROFILES = ("paper", "hybridnav")


def sweep_label(label: str, key: str, value: Any) -> str:
    """The label of variant ``label`` at the sweep value ``key = value``."""
    return f"{label}/{key}={value:g}" if isinstance(value, (int, float)) else \
        f"{label}/{key}={value}"


def _swept(protocol: Protocol, name: str) -> bool:
    """Whether planner ``name``'s variants run once per value of the protocol's sweep."""
    from hybridnav import planners

    return protocol.sweep is not None and protocol.sweep[0] in planners.PLANNERS[name].parameters


def variants(protocol: Protocol) -> list[tuple[str, str, dict[str, Any]]]:
    """The compared ``(label, planner, params)``: both profiles where the planner has them, the
    ablations, each once per sweep value where the planner has the swept parameter."""
    from hybridnav import planners

    base = []
    for name in protocol.planners:
        settings = dict(protocol.settings.get(name, {}))
        if planners.PLANNERS[name].profiles:
            base.append((f"{name}/paper", name, {**settings, "profile": "paper"}))
        base.append((name, name, settings))
    for label, name, params in protocol.ablations:
        base.append((label, name, {**protocol.settings.get(name, {}), **params}))
    out = []
    for label, name, params in base:
        if _swept(protocol, name):
            key, values = protocol.sweep
            out += [(sweep_label(label, key, v), name, {**params, key: v}) for v in values]
        else:
            out.append((label, name, params))
    return out


def label_for(protocol: Protocol, planner: str, profile: str) -> str:
    """The label of ``planner``'s variant in ``profile`` (before any sweep).

    Parameters
    ----------
    protocol : Protocol
    planner : str
        A planner of the protocol, or the label of one of its ablations (its own label in both
        profiles).
    profile : {"paper", "hybridnav"}

    Returns
    -------
    str
        ``NAME/paper`` for the paper profile of a planner with profiles, else ``NAME`` (a
        planner without profiles runs once, for both).
    """
    from hybridnav import planners

    if planner not in planners.PLANNERS:
        return planner                             # an ablation's label
    return f"{planner}/paper" if profile == "paper" and planners.PLANNERS[planner].profiles \
        else planner


def levels(protocol: Protocol, planner: str, label: str) -> list[tuple[Any, str]]:
    """``(sweep value, label)`` of the variant ``label`` of ``planner`` (a planner of the
    protocol or an ablation's label) at every sweep value; ``[(None, label)]`` when it is not
    swept."""
    name = dict((lb, n) for lb, n, _ in protocol.ablations).get(planner, planner)
    if not _swept(protocol, name):
        return [(None, label)]
    key, values = protocol.sweep
    return [(v, sweep_label(label, key, v)) for v in values]
