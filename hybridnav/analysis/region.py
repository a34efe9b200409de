"""State-space regions for the analysis tools: a box on the states, optionally cut by a level set."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from hybridnav.errors import HybridnavError

__all__ = ["Box", "as_box"]


@dataclass(frozen=True)
class Box:
    """Axis-aligned bounds on every state, in the model's state order."""

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` states drawn uniformly from the box, shape ``(n, nx)``."""
        return self.lower + (self.upper - self.lower) * rng.random((n, len(self.names)))

    def contains(self, X: np.ndarray) -> np.ndarray:
        """Whether each row of ``X`` lies in the box."""
        X = np.asarray(X, dtype=float)
        return np.all((X >= self.lower) & (X <= self.upper), axis=-1)

    def to_dict(self) -> dict[str, list[float]]:
        """``{state: [lo, hi]}``."""
        return {n: [float(lo), float(hi)] for n, lo, hi in zip(self.names, self.lower, self.upper)}


def as_box(model, region: Mapping[str, Sequence[float]] | Box) -> Box:
    """Turn ``{state name: (lo, hi)}`` into a :class:`Box` over all of ``model``'s states.

    Parameters
    ----------
    model : Model
    region : dict or Box
        ``{state name: (lo, hi)}`` for every state (a Box is returned as it is).

    Raises
    ------
    HybridnavError
        A state without bounds, an unknown state, or bounds that are not ``lo <= hi`` numbers.
    """
    if isinstance(region, Box):
        if region.names != tuple(model.state_names):
            raise HybridnavError(
                f"region: expected bounds for the states {', '.join(model.state_names)}, got "
                f"{', '.join(region.names)}"
            )
        return region
    if not isinstance(region, Mapping):
        raise HybridnavError(
            f"region: expected a mapping {{state: (lo, hi)}} over {', '.join(model.state_names)},"
            f" got {type(region).__name__}"
        )
    unknown = sorted(set(region) - set(model.state_names))
    if unknown:
        raise HybridnavError(
            f"region.{unknown[0]}: not a state of {model.name}; expected one of: "
            + ", ".join(model.state_names)
        )
    lower, upper = [], []
    for name in model.state_names:
        if name not in region:
            raise HybridnavError(
                f"region.{name}: missing; expected (lo, hi) bounds for every state of "
                f"{model.name} ({', '.join(model.state_names)})"
            )
        try:
            lo, hi = (float(v) for v in region[name])
        except (TypeError, ValueError):
            raise HybridnavError(
                f"region.{name}: expected two numbers (lo, hi), got {region[name]!r}"
            ) from None
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise HybridnavError(f"region.{name}: expected finite lo <= hi, got ({lo}, {hi})")
        lower.append(lo)
        upper.append(hi)
    return Box(tuple(model.state_names), np.array(lower), np.array(upper))
