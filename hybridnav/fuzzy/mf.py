"""Membership functions with scikit-fuzzy's names, parameter order and formulas.

The bodies below reproduce ``skfuzzy/membership/generatemf.py`` (scikit-fuzzy 0.5.0, BSD licence)
operation for operation, so the sampled arrays are bit-for-bit the ones scikit-fuzzy builds (the
test suite checks this). They are copied rather than imported so that ``hybridnav.fuzzy`` does not
pay scikit-fuzzy's import time (it pulls in ``scipy.linalg``) unless :meth:`to_skfuzzy` is used.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["MF_PARAMS", "sample", "check_params"]

FloatArray = NDArray[np.float64]


def zmf(x: FloatArray, a: float, b: float) -> FloatArray:
    """Z-function (``skfuzzy.zmf``): 1 up to ``a``, 0 from ``b``."""
    y = np.ones(len(x))
    idx = np.logical_and(a <= x, x < (a + b) / 2.)
    y[idx] = 1 - 2. * ((x[idx] - a) / (b - a)) ** 2.
    idx = np.logical_and((a + b) / 2. <= x, x <= b)
    y[idx] = 2. * ((x[idx] - b) / (b - a)) ** 2.
    idx = x >= b
    y[idx] = 0
    return y


def smf(x: FloatArray, a: float, b: float) -> FloatArray:
    """S-function (``skfuzzy.smf``): 0 up to ``a``, 1 from ``b``."""
    y = np.ones(len(x))
    idx = x <= a
    y[idx] = 0
    idx = np.logical_and(a <= x, x <= (a + b) / 2.)
    y[idx] = 2. * ((x[idx] - a) / (b - a)) ** 2.
    idx = np.logical_and((a + b) / 2. <= x, x <= b)
    y[idx] = 1 - 2. * ((x[idx] - b) / (b - a)) ** 2.
    return y


def trimf(x: FloatArray, a: float, b: float, c: float) -> FloatArray:
    """Triangle (``skfuzzy.trimf`` with ``abc = [a, b, c]``)."""
    y = np.zeros(len(x))
    if a != b:
        idx = np.nonzero(np.logical_and(a < x, x < b))[0]
        y[idx] = (x[idx] - a) / float(b - a)
    if b != c:
        idx = np.nonzero(np.logical_and(b < x, x < c))[0]
        y[idx] = (c - x[idx]) / float(c - b)
    idx = np.nonzero(x == b)
    y[idx] = 1
    return y


def trapmf(x: FloatArray, a: float, b: float, c: float, d: float) -> FloatArray:
    """Trapezoid (``skfuzzy.trapmf`` with ``abcd = [a, b, c, d]``)."""
    y = np.ones(len(x))
    idx = np.nonzero(x <= b)[0]
    y[idx] = trimf(x[idx], a, b, b)
    idx = np.nonzero(x >= c)[0]
    y[idx] = trimf(x[idx], c, c, d)
    idx = np.nonzero(x < a)[0]
    y[idx] = np.zeros(len(idx))
    idx = np.nonzero(x > d)[0]
    y[idx] = np.zeros(len(idx))
    return y


def gaussmf(x: FloatArray, mean: float, sigma: float) -> FloatArray:
    """Gaussian (``skfuzzy.gaussmf``)."""
    return np.exp(-((x - mean) ** 2.) / (2 * sigma ** 2.))


def gbellmf(x: FloatArray, a: float, b: float, c: float) -> FloatArray:
    """Generalized bell ``1 / (1 + |(x - c) / a| ** (2 b))`` (``skfuzzy.gbellmf``)."""
    return 1. / (1. + np.abs((x - c) / a) ** (2 * b))


def sigmf(x: FloatArray, b: float, c: float) -> FloatArray:
    """Sigmoid ``1 / (1 + exp(-c (x - b)))`` (``skfuzzy.sigmf``: ``b`` is the centre)."""
    return 1. / (1. + np.exp(- c * (x - b)))


_FUNCS: dict[str, Callable[..., FloatArray]] = {
    "zmf": zmf, "smf": smf, "trimf": trimf, "trapmf": trapmf,
    "gaussmf": gaussmf, "gbellmf": gbellmf, "sigmf": sigmf,
}

#: Parameter names of each membership function, in scikit-fuzzy's order.
MF_PARAMS: dict[str, tuple[str, ...]] = {
    "zmf": ("a", "b"),
    "smf": ("a", "b"),
    "trimf": ("a", "b", "c"),
    "trapmf": ("a", "b", "c", "d"),
    "gaussmf": ("mean", "sigma"),
    "gbellmf": ("a", "b", "c"),
    "sigmf": ("b", "c"),
}


def check_params(mf: str, params: Sequence[float]) -> str | None:
    """Return what is wrong with finite ``params`` for ``mf`` (None when they are valid).

    Parameter counts are checked by the caller; this checks order and sign constraints:
    ``zmf``/``smf`` need ``a < b``; ``trimf`` needs ``a <= b <= c``; ``trapmf`` needs
    ``a <= b <= c <= d``; ``gaussmf`` needs ``sigma > 0``; ``gbellmf`` needs width ``a > 0`` and
    slope ``b > 0``; ``sigmf`` accepts any finite ``b, c``.
    """
    p = list(params)
    if mf in ("zmf", "smf"):
        if not p[0] < p[1]:
            return f"expected a < b for {mf}, got a={p[0]!r}, b={p[1]!r}"
    elif mf == "trimf":
        if not p[0] <= p[1] <= p[2]:
            return f"expected a <= b <= c for trimf, got {p!r}"
    elif mf == "trapmf":
        if not p[0] <= p[1] <= p[2] <= p[3]:
            return f"expected a <= b <= c <= d for trapmf, got {p!r}"
    elif mf == "gaussmf":
        if not p[1] > 0:
            return f"expected sigma > 0 for gaussmf, got sigma={p[1]!r}"
    elif mf == "gbellmf":
        if not p[0] > 0:
            return f"expected width a > 0 for gbellmf, got a={p[0]!r}"
        if not p[1] > 0:
            return f"expected slope b > 0 for gbellmf, got b={p[1]!r}"
    return None


def sample(mf: str, params: Sequence[float], x: FloatArray) -> FloatArray:
    """Sample membership function ``mf`` with ``params`` at the points ``x``.

    Parameters
    ----------
    mf : str
        One of :data:`MF_PARAMS`.
    params : sequence of float
        The parameters in scikit-fuzzy's order.
    x : ndarray of float, shape (M,)
        Points (a variable's universe).

    Returns
    -------
    ndarray of float, shape (M,)
        Membership degrees in [0, 1], equal bit for bit to scikit-fuzzy's.
    """
    x = np.asarray(x, dtype=np.float64)
    try:
        with np.errstate(all="ignore"):      # non-finite values are refused below
            y = _FUNCS[mf](x, *(float(v) for v in params))
    except OverflowError:               # a Python float power, e.g. gaussmf sigma = 1e308
        raise FloatingPointError(f"{mf}{tuple(params)} overflows") from None
    y = np.asarray(y, dtype=np.float64)
    if not np.all(np.isfinite(y)):  # cannot happen for validated parameters; be loud if it does
        raise FloatingPointError(f"{mf}{tuple(params)} produced non-finite membership values")
    return y
