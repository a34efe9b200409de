"""Real-coded variation operators (DEAP's), as objects passed to :class:`GA` and :class:`NSGA2`.

``GA(crossover=SBX(eta=10), mutation=Polynomial(eta=20, gene_prob=0.1))``. Each operator acts
in place on DEAP individuals (lists of floats) and draws from Python's ``random`` module, which
the optimizers point at their own seeded ``random.Random`` for the duration of a step
(:func:`deap_random`), so nothing else in the process shifts their stream.
"""

from __future__ import annotations

import contextlib
import random
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from deap import base, tools

from hybridnav.errors import HybridnavError
from hybridnav.params import Param

__all__ = ["SBX", "Blend", "Gaussian", "Individual", "Polynomial", "crossover_from",
           "deap_random", "mutation_from"]


class Individual(list):
    """A vector (list of floats) with a DEAP ``fitness`` (every objective minimized)."""

    def __init__(self, genes=(), n_obj: int = 1) -> None:
        super().__init__(float(g) for g in genes)
        self.fitness = _fitness(n_obj)()


_FITNESS: dict[int, type] = {}


def _fitness(n_obj: int) -> type:
    """A ``deap.base.Fitness`` subclass minimizing ``n_obj`` objectives (defined once per m,
    at module level, so that it pickles)."""
    if n_obj not in _FITNESS:
        cls = type(f"FitnessMin{n_obj}", (base.Fitness,), {"weights": (-1.0,) * n_obj,
                                                            "__module__": __name__})
        globals()[cls.__name__] = cls
        _FITNESS[n_obj] = cls
    return _FITNESS[n_obj]


@contextlib.contextmanager
def deap_random(rnd: random.Random):
    """Make DEAP's selection, crossover and mutation operators draw from ``rnd``."""
    from deap.tools import crossover, emo, mutation, selection

    modules = (selection, crossover, mutation, emo)
    saved = [m.random for m in modules]
    for m in modules:
        m.random = rnd
    try:
        yield
    finally:
        for m, r in zip(modules, saved):
            m.random = r


def _check(op: str, spec: dict[str, Param], values: dict[str, Any]) -> None:
    for k, p in spec.items():
        p.check(k, values[k], f"{op}(): ")


@dataclass(frozen=True)
class SBX:
    """Bounded simulated binary crossover (Deb & Agrawal 1995); ``eta``: distribution index."""

    eta: float = 15.0
    name = "sbx"

    def __post_init__(self) -> None:
        _check("SBX", {"eta": Param(15.0, lo=0.0)}, asdict(self))

    def __call__(self, a, b, lower, upper) -> None:
        tools.cxSimulatedBinaryBounded(a, b, self.eta, lower, upper)


@dataclass(frozen=True)
class Blend:
    """Blend crossover BLX-alpha (Eshelman & Schaffer 1993); children are repaired afterwards."""

    alpha: float = 0.3
    name = "blend"

    def __post_init__(self) -> None:
        _check("Blend", {"alpha": Param(0.3, lo=0.0)}, asdict(self))

    def __call__(self, a, b, lower, upper) -> None:
        tools.cxBlend(a, b, self.alpha)


@dataclass(frozen=True)
class Polynomial:
    """Bounded polynomial mutation (Deb); each gene mutates with ``gene_prob``."""

    eta: float = 20.0
    gene_prob: float = 0.2
    name = "polynomial"

    def __post_init__(self) -> None:
        _check("Polynomial", {"eta": Param(20.0, lo=0.0),
                              "gene_prob": Param(0.2, lo=0.0, hi=1.0)}, asdict(self))

    def __call__(self, ind, lower, upper) -> None:
        tools.mutPolynomialBounded(ind, self.eta, lower, upper, self.gene_prob)


@dataclass(frozen=True)
class Gaussian:
    """Gaussian mutation, std ``sigma`` times each gene's range; each gene with ``gene_prob``."""

    sigma: float = 0.1
    gene_prob: float = 0.2
    name = "gaussian"

    def __post_init__(self) -> None:
        _check("Gaussian", {"sigma": Param(0.1, lo=0.0),
                            "gene_prob": Param(0.2, lo=0.0, hi=1.0)}, asdict(self))

    def __call__(self, ind, lower, upper) -> None:
        sigma = (self.sigma * (np.asarray(upper) - np.asarray(lower))).tolist()
        tools.mutGaussian(ind, 0.0, sigma, self.gene_prob)


CROSSOVERS = {"sbx": SBX, "blend": Blend}
MUTATIONS = {"polynomial": Polynomial, "gaussian": Gaussian}


def _from(kind: str, table: dict, value: Any, key: str):
    if isinstance(value, tuple(table.values())):
        return value
    if isinstance(value, str) and value in table:
        return table[value]()
    if isinstance(value, dict) and value.get("kind") in table:
        args = {k: v for k, v in value.items() if k != "kind"}
        cls = table[value["kind"]]
        bad = sorted(set(args) - set(cls.__dataclass_fields__))
        if bad:
            raise HybridnavError(f"{key}.{bad[0]}: unknown setting of {value['kind']}; expected "
                                 f"one of: {', '.join(cls.__dataclass_fields__)}")
        try:
            return cls(**args)
        except HybridnavError as exc:
            raise HybridnavError(f"{key}.{str(exc).split('(): ', 1)[-1]}") from None
    raise HybridnavError(f"{key}: expected a {kind} operator ({', '.join(table)}, or a table "
                         f"with kind and its settings), got {value!r}")


def crossover_from(value: Any, key: str = "crossover"):
    """An operator object from itself, a name or ``{kind = ..., settings}``."""
    return _from("crossover", CROSSOVERS, value, key)


def mutation_from(value: Any, key: str = "mutation"):
    """An operator object from itself, a name or ``{kind = ..., settings}``."""
    return _from("mutation", MUTATIONS, value, key)


def describe(op) -> dict[str, Any]:
    return {"kind": op.name, **asdict(op)}
