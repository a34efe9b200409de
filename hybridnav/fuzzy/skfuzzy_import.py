"""Bringing a scikit-fuzzy ``ControlSystem`` in (:func:`hybridnav.fuzzy.from_skfuzzy`).

scikit-fuzzy stores each term as membership values sampled on its variable's universe; a
hybridnav system stores membership functions by shape and parameters and samples them on
``np.linspace(lo, hi, points)``. A term is taken over when one of hybridnav's shapes
(``trimf``, ``trapmf``, ``gaussmf``, ``gbellmf``, ``sigmf``, ``zmf``, ``smf``) with parameters
recovered from the samples reproduces every sample to :data:`TOLERANCE` (and is exactly 0
where the samples are: whether a rule fires depends on it); the evaluation then samples
the same values, so the system evaluates as scikit-fuzzy computes it. Anything else (a
universe that is not evenly spaced, a term of another shape, several outputs, an ``and``/``or``
other than min/max, a defuzzifier other than the centroid) is refused with a message naming it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hybridnav.errors import HybridnavError
from hybridnav.fuzzy.mf import MF_PARAMS, check_params, sample

__all__ = ["TOLERANCE", "document"]

#: Largest difference between a term's samples and the recovered membership function.
TOLERANCE = 1e-9


def _linear_fit(x: np.ndarray, y: np.ndarray) -> tuple[float, float] | None:
    keep = np.isfinite(x) & np.isfinite(y)
    if keep.sum() < 2 or np.ptp(x[keep]) == 0:
        return None
    try:
        slope, icpt = np.polyfit(x[keep], y[keep], 1)
    except (np.linalg.LinAlgError, ValueError):
        return None
    return float(slope), float(icpt)


def _edges(x: np.ndarray, mu: np.ndarray, idx: np.ndarray, corner: float | None,
           foot: float, rising: bool) -> list[tuple[float, float]]:
    """Candidate (foot, corner) pairs of one edge of a triangle or trapezoid: where it is 0 and
    where it is 1.

    ``idx``: the samples strictly between 0 and 1 on this edge; ``corner``: where the edge
    reaches 1 when that is fixed (the top's sample, or the apex the other edge gives);
    ``foot``: the nearest sample beyond the edge where the membership is 0. One sample leaves
    the edge's line free: anchored at the corner or at the foot, whichever reproduces it."""
    fit = _linear_fit(x[idx], mu[idx]) if len(idx) >= 2 else None
    if fit is not None and (fit[0] > 0) == rising and fit[0] != 0:
        return [(-fit[1] / fit[0], (1.0 - fit[1]) / fit[0])]
    out = []
    if len(idx) == 1:
        j = int(idx[0])
        if corner is not None and mu[j] < 1:     # the line from (corner, 1) through the sample
            out.append((corner + (x[j] - corner) / (1.0 - mu[j]), corner))
        if mu[j] > 0:                            # the line from (foot, 0) through the sample
            out.append((foot, foot + (x[j] - foot) / mu[j]))
    elif len(idx) == 0:                          # a vertical edge (or one beyond the universe)
        c = corner if corner is not None else foot
        out.append((min(foot, c) if rising else max(foot, c), c))
    return out


def _piecewise_linear(x: np.ndarray, mu: np.ndarray) -> list[tuple[str, list[float]]]:
    """trimf / trapmf parameters that may reproduce ``mu``: the edges' lines through the samples
    between 0 and 1, for each place the top (or a triangle's apex) can be."""
    n = len(x)
    dx = x[1] - x[0] if n > 1 else 1.0
    top = np.flatnonzero(mu >= 1.0 - 1e-12)
    mid = np.flatnonzero((mu > 1e-12) & (mu < 1.0 - 1e-12))
    peak = int(top[0]) if len(top) else int(np.argmax(mu))
    last = int(top[-1]) if len(top) else peak
    out: list[tuple[str, list[float]]] = []
    if mu.max() <= TOLERANCE:                # zero on the whole universe: a triangle beyond it
        return [("trimf", [x[-1] + dx, x[-1] + 2 * dx, x[-1] + 3 * dx])]
    # the apex between samples: the largest sample belongs to either edge
    splits = [(peak, last)] if len(top) else [(peak, peak - 1), (peak + 1, peak)]
    for lo_top, hi_top in splits:
        R, F = mid[mid < lo_top], mid[mid > hi_top]
        zl = x[R[0] - 1] if len(R) and R[0] > 0 else (x[R[0]] - dx if len(R) else
                                                       (x[lo_top - 1] if lo_top > 0 else x[0]))
        zr = x[F[-1] + 1] if len(F) and F[-1] + 1 < n else (x[F[-1]] + dx if len(F) else
                                                           (x[hi_top + 1] if hi_top + 1 < n
                                                            else x[-1]))
        if len(top):
            pairs = [(r, f) for r in _edges(x, mu, R, x[lo_top], zl, True)
                     for f in _edges(x, mu, F, x[hi_top], zr, False)]
        else:                                # the apex: fixed by the better-determined edge
            pairs = [(r, f) for r in _edges(x, mu, R, None, zl, True)
                     for f in _edges(x, mu, F, r[1], zr, False)]
            pairs += [(r, f) for f in _edges(x, mu, F, None, zr, False)
                      for r in _edges(x, mu, R, f[1], zl, True)]
        if not len(top) and len(R) == 1 and len(F) == 1 and mu[R[0]] < 1 and mu[F[0]] < 1:
            # one sample on each edge: any apex p keeping both feet beyond the zero samples
            xr, mr, xf, mf_ = x[R[0]], mu[R[0]], x[F[0]], mu[F[0]]
            kr, kf = 1.0 / (1.0 - mr), 1.0 / (1.0 - mf_)
            p_hi = min(xf, (zl - xr * kr) / (1.0 - kr)) if kr != 1 else xf
            p_lo = max(xr, (zr - xf * kf) / (1.0 - kf)) if kf != 1 else xr
            if p_lo <= p_hi:
                p = 0.5 * (p_lo + p_hi)
                pairs.append(((p - (p - xr) * kr, p), (p + (xf - p) * kf, p)))
        if not len(top) and len(R) + len(F) == 1:
            # one sample above 0: on the rising or the falling edge of a triangle between the
            # zero samples around it
            j = int((R if len(R) else F)[0])
            xj, mj = x[j], mu[j]
            k = 1.0 - 1.0 / mj                   # < 0: the apex moves against the foot
            a = 0.5 * (max(zl, (zr - xj / mj) / k) + xj)     # apex p(a) before zr
            p = a + (xj - a) / mj
            if zl <= a < xj and p < zr:
                pairs.append(((a, p), (0.5 * (p + zr), p)))
            d = 0.5 * (xj + min(zr, (zl - xj / mj) / k))     # apex p(d) after zl
            p = d - (d - xj) / mj
            if xj < d <= zr and p > zl:
                pairs.append(((0.5 * (zl + p), p), (d, p)))
        for (a, b), (d, c) in pairs:
            if abs(b - c) <= 1e-9 * max(1.0, abs(b)):
                out.append(("trimf", [a, b, d]))
            out.append(("trapmf", [a, b, c, d]))
    return out


def _smooth(x: np.ndarray, mu: np.ndarray) -> list[tuple[str, list[float]]]:
    """gaussmf / gbellmf / sigmf / zmf / smf parameters that may reproduce ``mu``."""
    cands: list[tuple[str, list[float]]] = []
    ok = mu > 1e-9
    if ok.sum() >= 3:                        # gauss: log mu is a parabola
        try:
            c2, c1, c0 = np.polyfit(x[ok], np.log(mu[ok]), 2)
        except (np.linalg.LinAlgError, ValueError):
            c2 = c1 = 0.0
        if c2 < 0:
            sigma = float(np.sqrt(-1.0 / (2.0 * c2)))
            cands.append(("gaussmf", [float(-c1 / (2.0 * c2)), sigma]))
    mid = (mu > 1e-9) & (mu < 1.0 - 1e-9)
    if mid.sum() >= 2:                       # sigmoid: the logit is a line
        fit = _linear_fit(x[mid], np.log(mu[mid] / (1.0 - mu[mid])))
        if fit and fit[0] != 0:
            cands.append(("sigmf", [-fit[1] / fit[0], fit[0]]))
        # bell centred on a sample: log(1/mu - 1) = 2b log|x - c| - 2b log a
        c = float(x[int(np.argmax(mu))])
        far = mid & (np.abs(x - c) > 0)
        fit = _linear_fit(np.log(np.abs(x[far] - c)), np.log(1.0 / mu[far] - 1.0))
        if fit and fit[0] > 0:
            cands.append(("gbellmf", [float(np.exp(-fit[1] / fit[0])), fit[0] / 2.0, c]))
    # z / s: between a and b, u = (x - a) / (b - a) is sqrt((1 - mu) / 2) where mu >= 1/2 and
    # 1 - sqrt(mu / 2) below (the z-function's two parabolas), a line in x
    for kind, m in (("zmf", mu), ("smf", 1.0 - mu)):
        tr = (m > 1e-12) & (m < 1.0 - 1e-12)
        if tr.sum() >= 2:
            u = np.where(m[tr] >= 0.5, np.sqrt((1.0 - m[tr]) / 2.0), 1.0 - np.sqrt(m[tr] / 2.0))
            fit = _linear_fit(x[tr], u)
            if fit and fit[0] > 0:
                cands.append((kind, [-fit[1] / fit[0], (1.0 - fit[1]) / fit[0]]))
        full, empty = np.flatnonzero(m >= 1.0 - 1e-12), np.flatnonzero(m <= 1e-12)
        if len(full) and len(empty) and full[-1] < empty[0]:
            cands.append((kind, [float(x[full[-1]]), float(x[empty[0]])]))
    return cands


def _variants(mf: str, params: list[float], x: np.ndarray):
    """``params`` and, for trimf / trapmf, each corner also moved onto a sample a rounding away
    or rounded to 12 digits (exact zeros where scikit-fuzzy's are: whether a rule fires at all
    depends on them), corners kept in order."""
    if mf not in ("trimf", "trapmf"):
        yield params
        return
    import itertools

    scale = 1e-9 * max(1.0, float(np.max(np.abs(x))))
    k = np.clip(np.searchsorted(x, params), 1, len(x) - 1)
    near = np.where(np.abs(x[k] - params) < np.abs(x[k - 1] - params), x[k], x[k - 1])
    # the corner as fitted, on the sample, or as written (12 significant digits: 0.3, not
    # 0.30000000000000004, whose sample is then exactly 0 as scikit-fuzzy's is not)
    options = [tuple(dict.fromkeys([p] + ([float(q)] if abs(q - p) <= scale else [])
                                   + [float(f"{p:.12g}")]))
               for p, q in zip(params, near)]
    for combo in itertools.islice(itertools.product(*options), 81):
        yield [float(v) for v in np.maximum.accumulate(combo)]


def _term(var: str, term: str, x: np.ndarray, mu: np.ndarray) -> dict[str, Any]:
    mu = np.asarray(mu, dtype=float)
    if mu.shape != x.shape or not np.all(np.isfinite(mu)):
        raise HybridnavError(f"from_skfuzzy: {var}.{term}: expected finite membership values "
                             f"on the universe's {len(x)} points")
    for mf, params in _piecewise_linear(x, mu) + _smooth(x, mu):
        params = [float(p) for p in params]
        for variant in _variants(mf, params, x):
            if len(variant) != len(MF_PARAMS[mf]) or not all(np.isfinite(variant)) \
                    or check_params(mf, variant) is not None:
                continue
            with np.errstate(all="ignore"):
                got = sample(mf, variant, x)
            # the same samples to TOLERANCE, and exactly 0 where scikit-fuzzy's are (whether
            # a rule fires at all depends on it)
            if np.all(np.isfinite(got)) and np.max(np.abs(got - mu)) <= TOLERANCE \
                    and np.array_equal(got == 0.0, mu == 0.0):
                return {"name": term, "mf": mf, "params": variant}
    raise HybridnavError(
        f"from_skfuzzy: {var}.{term}: expected a membership function hybridnav represents "
        f"({', '.join(MF_PARAMS)}) matching every sample to {TOLERANCE:g}; its samples match "
        "none of them")


def _universe(v) -> tuple[np.ndarray, dict[str, Any]]:
    x = np.asarray(v.universe, dtype=float)
    if x.ndim != 1 or len(x) < 2 or not np.all(np.isfinite(x)):
        raise HybridnavError(f"from_skfuzzy: {v.label}: expected a finite universe of at least "
                             "2 points")
    even = np.linspace(x[0], x[-1], len(x))
    if not x[-1] > x[0] or np.max(np.abs(x - even)) > 1e-12 * max(1.0, np.max(np.abs(x))):
        raise HybridnavError(f"from_skfuzzy: {v.label}: expected an evenly spaced increasing "
                             "universe (np.linspace or np.arange); hybridnav samples "
                             "np.linspace(lo, hi, points)")
    # recovered and checked on the points hybridnav samples (np.arange's can be an ulp off
    # them, and a membership of 1e-15 where scikit-fuzzy's is 0 makes a rule fire)
    terms = [_term(v.label, str(name), even, t.mf) for name, t in v.terms.items()]
    return x, {"name": str(v.label), "range": [float(x[0]), float(x[-1])], "points": len(x),
               "terms": terms}


def _antecedent(a, inputs: set[str]) -> Any:
    from skfuzzy.control.term import Term, TermAggregate

    if isinstance(a, Term):
        if str(a.parent.label) not in inputs:
            raise HybridnavError(f"from_skfuzzy: a rule's antecedent uses {a.parent.label!r}, "
                                 "which is not an input")
        return [str(a.parent.label), str(a.label)]
    if isinstance(a, TermAggregate):
        if a.kind == "not":
            return {"not": _antecedent(a.term1, inputs)}
        if a.kind in ("and", "or"):
            items = []
            for part in (a.term1, a.term2):       # flatten nested aggregates of the same kind
                sub = _antecedent(part, inputs)
                items += sub[a.kind] if isinstance(sub, dict) and a.kind in sub else [sub]
            return {a.kind: items}
    raise HybridnavError(f"from_skfuzzy: expected an antecedent of terms combined with &, | "
                         f"and ~, got {type(a).__name__}")


def document(system: Any, *, name: str | None = None, default: float | None = None,
             description: str = "") -> dict[str, Any]:
    """The scikit-fuzzy ``ControlSystem`` ``system`` as a ``hybridnav-fis/1`` document
    (:func:`hybridnav.fuzzy.from_skfuzzy` builds the system from it).

    Parameters
    ----------
    system : skfuzzy.control.ControlSystem
        One consequent, centroid defuzzification, rules with scikit-fuzzy's default ``and``
        (minimum) and ``or`` (maximum), evenly spaced universes, terms of a shape hybridnav
        represents (module docstring).
    name : str, optional
        The system's name (default: ``"skfuzzy"``).
    default : float, optional
        The output when no rule fires (scikit-fuzzy leaves it unset; default: the middle of the
        output's universe).
    description : str
        Stored with the system.

    Returns
    -------
    dict
        The document: the system evaluates as scikit-fuzzy's ``ControlSystemSimulation``
        computes (inputs clipped to their universes, as hybridnav does).

    Raises
    ------
    HybridnavError
        Naming the variable, term or rule hybridnav cannot represent.
    """
    from skfuzzy.control import ControlSystem

    if not isinstance(system, ControlSystem):
        raise HybridnavError(f"from_skfuzzy: expected a skfuzzy.control.ControlSystem, got "
                             f"{type(system).__name__}")
    rules = list(system.rules)
    if not rules:
        raise HybridnavError("from_skfuzzy: expected a control system with at least one rule")
    outs = list(system.consequents)
    if len(outs) != 1:
        raise HybridnavError(f"from_skfuzzy: expected one consequent (output), got {len(outs)}: "
                             + ", ".join(str(o.label) for o in outs))
    out = outs[0]
    if out.defuzzify_method != "centroid":
        raise HybridnavError(f"from_skfuzzy: {out.label}: expected centroid defuzzification, "
                             f"got {out.defuzzify_method!r}")
    ins = sorted(system.antecedents, key=lambda v: str(v.label))
    inputs = [_universe(v)[1] for v in ins]
    x_out, output = _universe(out)
    output["defuzz"] = "centroid"
    output["default"] = float((x_out[0] + x_out[-1]) / 2.0 if default is None else default)
    names = {v["name"] for v in inputs}
    doc_rules = []
    for i, r in enumerate(rules):
        if r.and_func is not np.fmin or r.or_func is not np.fmax:
            raise HybridnavError(f"from_skfuzzy: rule {i}: expected the default and (np.fmin) "
                                 "and or (np.fmax)")
        cons = list(r.consequent)
        if len(cons) != 1:
            raise HybridnavError(f"from_skfuzzy: rule {i}: expected one consequent term, got "
                                 f"{len(cons)}")
        c = cons[0]
        term = getattr(c, "term", c)
        weight = float(getattr(c, "weight", 1.0))
        doc_rules.append({"if": _antecedent(r.antecedent, names), "then": str(term.label),
                          "weight": weight})
    return {"format": "hybridnav-fis/1", "name": name or "skfuzzy", "description": description,
            "inputs": inputs, "output": output, "rules": doc_rules}
