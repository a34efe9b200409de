"""Proofs of Lyapunov conditions on a region by interval branch and bound.

:func:`certify` proves, for ``xdot = f(x)``, a candidate ``V`` and the set
``K = box ∩ {V <= level} ∩ {g(x) > 0}`` (``g``: the model's admissibility constraints), one of:

strict (Lyapunov)
    ``V > 0`` and ``Vdot < 0`` on ``K`` except at the equilibrium ``x*``. Boxes are split until, on
    each, interval arithmetic (:class:`~hybridnav.analysis.interval.IntervalFunction`) shows the
    box outside the free space (``g <= 0``), outside the level set (``V > level``), or
    ``V > 0`` and ``Vdot < 0`` on all of it. Near ``x*``, where ``Vdot`` vanishes, a small box
    ``B`` around ``x*`` is handled by the linearization: with interval enclosures of the Hessians
    of ``V`` and ``Vdot`` over ``B`` (positive / negative definite for every matrix in them, by
    the eigenvalues of the midpoint matrix and the norm of the radius matrix) and of their values
    and gradients at ``x*``, Taylor's theorem gives ``V > 0 > Vdot`` on ``B`` outside a radius
    ``r0`` (zero when ``V``, ``Vdot`` and their gradients vanish exactly at ``x*``).
LaSalle
    ``Vdot <= 0`` on ``K`` (``V`` need not be positive definite), and every box either has ``Vdot < 0`` or a Lie derivative
    ``L_f^k Vdot`` (``k = 1..K``) that is nonzero throughout, so no trajectory can stay in
    ``{Vdot = 0}`` there; boxes inside ``{V < eps}`` are left out. By LaSalle's invariance principle
    every trajectory that starts in ``K`` (when ``K`` is positively invariant) ends in ``{V < eps}``.

Invariance of ``K`` is checked on the box's faces: on each face either ``V > level``, the state is
outside the free space, or the flow points into the box (``f_i >= 0`` on a lower face, ``<= 0`` on
an upper one) — with ``Vdot <= 0`` inside, no trajectory leaves ``K`` (Nagumo's theorem). Faces of
coordinates declared periodic (an angle spanning a whole turn) are skipped only where ``V``, ``f``
and ``g`` are shown ``2 pi``-periodic in that coordinate
(:func:`~hybridnav.analysis.interval.periodic_in`); otherwise they are checked.

Non-smooth systems: ``Vdot = grad V . f`` differentiates only ``V``, and it is the derivative of
``V`` along every solution wherever ``V`` is smooth and ``f`` continuous (the chain rule needs
``x(t)`` differentiable, which it is); with ``f`` Lipschitz, solutions are also unique, which the
faces' invariance argument needs. So saturations in ``f`` (``fmin``, ``fmax``, ``fabs``: kinks,
Lipschitz) are certified box by box like smooth dynamics; jumps of ``f`` (``floor``, ``sign``,
an undecided comparison, ``atan2`` across its cut) and non-Lipschitz points (``sqrt`` or a
fractional power at 0) leave a box undecided. A saturation that surely holds one side on a box is as smooth there as that side
(:class:`~hybridnav.analysis.interval.IntervalFunction`). The local ball's Taylor argument and
LaSalle's Lie derivatives differentiate ``f`` and need it smooth where they are used.

A box that cannot be decided down to ``min_width`` is *undecided*; its centre is evaluated, and a
centre where the interval enclosure there shows the violation is returned as a counterexample.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as cs
import numpy as np

from hybridnav.analysis.interval import (
    IntervalFunction,
    UnsupportedOperation,
    periodic_in,
)
from hybridnav.analysis.region import Box

log = logging.getLogger(__name__)

__all__ = ["Certificate", "certify"]


@dataclass
class Certificate:
    """What :func:`certify` established.

    Attributes
    ----------
    status : str
        ``"proved"``, ``"counterexample"`` or ``"undecided"`` (``"not_applicable"`` when an
        operation has no interval extension).
    claim : str
        What was proved and on which set (empty unless ``status == "proved"``).
    method : str
        How: the number of boxes, the local ball, the faces.
    counterexample : ndarray or None
        A state violating the condition (from an undecided box's centre).
    invariant : bool or None
        Whether the faces showed ``K`` positively invariant (None: not checked).
    boxes : int
        Boxes evaluated.
    undecided : int
        Boxes left undecided (at ``min_width`` or when the budget ran out).
    details : dict
        The ball (centre, half-widths, ``r0``), counts per reason, undecided boxes (a few).
    """

    status: str
    claim: str
    method: str
    counterexample: np.ndarray | None = None
    invariant: bool | None = None
    boxes: int = 0
    undecided: int = 0
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        from hybridnav.fileio import json_ready

        return json_ready({"status": self.status, "claim": self.claim, "method": self.method,
                           "counterexample": None if self.counterexample is None
                           else self.counterexample.tolist(),
                           "invariant": self.invariant, "boxes": self.boxes,
                           "undecided": self.undecided, "details": self.details})


def certify(
    x: cs.SX,
    f: cs.SX,
    V: cs.SX,
    box: Box,
    *,
    level: float | None = None,
    constraints: cs.SX | None = None,
    center: np.ndarray | None = None,
    lasalle: bool = False,
    lie_order: int = 3,
    eps: float | None = None,
    periodic: Sequence[int] = (),
    ball: float = 1e-3,
    max_boxes: int = 300_000,
    batch: int = 4096,
    min_width: float = 1e-9,
    faces: bool = True,
) -> Certificate:
    """Prove the Lyapunov (or LaSalle) conditions on ``K = box ∩ {V <= level} ∩ {g > 0}``.

    Parameters
    ----------
    x : casadi.SX
        State symbols (a column of ``nx``).
    f : casadi.SX
        The closed loop ``xdot = f(x)``, in ``x`` only (parameters substituted).
    V : casadi.SX
        The candidate, in ``x`` only.
    box : Box
        The region.
    level : float, optional
        Restrict to ``{V <= level}``.
    constraints : casadi.SX, optional
        ``g(x)``; only states with every ``g_j > 0`` count (the model's free space).
    center : array_like, optional
        The equilibrium ``x*`` (strict route: the local ball sits there).
    lasalle : bool
        Prove ``Vdot <= 0`` and LaSalle's condition instead of strict decrease.
    lie_order : int
        Highest Lie derivative of ``Vdot`` used by the LaSalle route.
    eps : float, optional
        LaSalle route: boxes inside ``{V < eps}`` are left out (default ``1e-6`` times ``level``,
        or times the largest ``V`` on the box's corners).
    periodic : sequence of int
        Coordinates whose faces are identified (angles over a whole turn): no face check.
    ball : float
        Half-width of the local box around ``center``, as a fraction of each side of ``box``.
    max_boxes : int
        Budget of evaluated boxes.
    batch : int
        Boxes evaluated per vectorized call.
    min_width : float
        Boxes narrower than this (relative to the box's sides) are not split further.
    faces : bool
        Check the faces for positive invariance.

    Returns
    -------
    Certificate
    """
    from hybridnav.errors import HybridnavError

    nx = int(x.numel())
    if cs.SX(V).numel() != 1 or cs.SX(f).numel() != nx or len(box.lower) != nx:
        raise HybridnavError(
            f"certify: expected a scalar V, f with {nx} entries and a box over {nx} states, got "
            f"V {cs.SX(V).shape}, f {cs.SX(f).shape}, box of {len(box.lower)}")
    if not (np.all(np.isfinite(box.lower)) and np.all(np.isfinite(box.upper))
            and np.all(box.lower <= box.upper)):
        raise HybridnavError(f"certify: expected finite bounds lo <= hi, got {box.to_dict()}")
    bad = [i for i in periodic if not 0 <= int(i) < nx]
    if bad:
        raise HybridnavError(f"certify: periodic: {bad} are not coordinates 0..{nx - 1}")
    if center is not None:
        center = np.asarray(center, dtype=float).ravel()
        if center.shape != (nx,) or not np.all(np.isfinite(center)):
            raise HybridnavError(f"certify: center: expected {nx} finite numbers, got "
                                 f"{center.tolist()}")
        if not box.contains(center):
            # the Taylor ball is expanded from x*: outside the box it would be clipped away
            # from its own centre
            raise HybridnavError(f"certify: center {center.tolist()} lies outside the box "
                                 f"{box.to_dict()}")
    g = cs.SX(0, 1) if constraints is None else cs.vec(cs.SX(constraints))
    ng = int(g.numel())
    vdot = cs.jtimes(V, x, f)
    gdot = cs.jtimes(g, x, f) if ng else cs.SX(0, 1)
    outs = [V, vdot, g, f, gdot]
    lie = []
    if lasalle:
        d = vdot
        for _ in range(lie_order):
            d = cs.jtimes(d, x, f)
            lie.append(d)
        outs += lie
    try:
        F = IntervalFunction(x, outs)
        # the mean-value form of Vdot (its value and gradient), and f alone (faces' Lipschitz
        # check): smaller functions, evaluated only on the boxes that need them
        F_mv = IntervalFunction(x, [vdot, cs.gradient(vdot, x)])
        F_f = IntervalFunction(x, [f])
    except UnsupportedOperation as exc:
        return Certificate("not_applicable", "", f"interval arithmetic: {exc}")
    # a coordinate's faces are identified only where V, f and g are 2 pi-periodic in it (shown
    # from the expressions); otherwise the flow through th = pi leaves K and must be checked
    asked = sorted({int(i) for i in periodic})
    periodic = [i for i in asked if periodic_in(x, [V, f, g], i)]
    refused = [i for i in asked if i not in periodic]
    if periodic:
        # identified faces need the box to cover a whole turn: the float 2 pi is short of it
        # (and a declared range may be a hair short), so such a side is widened to
        # lower + 2 pi rounded up (the same states again, V and f being periodic)
        up = box.upper.astype(float).copy()
        for i in periodic:
            up[i] = max(up[i], np.nextafter(box.lower[i] + np.nextafter(2 * np.pi, np.inf),
                                            np.inf))
        box = Box(box.names, box.lower.astype(float), up)
    point = cs.Function("point", [x], [V, vdot, g, f])
    iv, idot = 0, 1
    ig = slice(2, 2 + ng)
    if_ = slice(2 + ng, 2 + ng + nx)
    igd = slice(2 + ng + nx, 2 + 2 * ng + nx)
    il = slice(2 + 2 * ng + nx, 2 + 2 * ng + nx + len(lie))
    clamp = {2 + j: (0.0, np.inf) for j in range(ng)}
    lower, upper = box.lower.astype(float), box.upper.astype(float)
    width = np.where(upper > lower, upper - lower, 1.0)
    cap = np.inf if level is None else float(level)

    # Vdot's scale, for what counts as zero to rounding at a sampled state (LaSalle's counterexample
    # needs Vdot clearly positive)
    probe = box.sample(1024, np.random.default_rng(0))
    dprobe = np.asarray(point.map(len(probe))(probe.T)[1]).ravel()
    dprobe = dprobe[np.isfinite(dprobe)]
    zero_tol = 1e-12 * max(1.0, float(np.max(np.abs(dprobe))) if len(dprobe) else 1.0)
    details: dict[str, Any] = {"region": box.to_dict(), "level": level, "zero_tol": zero_tol,
                               "route": "lasalle" if lasalle else "strict",
                               "periodic": [box.names[i] for i in periodic]}
    if refused:
        details["periodic_refused"] = {
            box.names[i]: "V, f or g depends on it other than through sin/cos of an integer "
                          "multiple, so its faces are checked like any other" for i in refused}
    # ---- the local ball around x*
    local = None
    if center is not None and not lasalle:
        local = _local_ball(x, V, f, np.asarray(center, dtype=float), width * ball, lower,
                            upper)
        details["ball"] = local["details"]
        if not local["ok"]:
            local = None
    if lasalle:
        if eps is None:
            corners = _corners(lower, upper)
            vc = np.asarray(cs.Function("v", [x], [V]).map(len(corners))(corners.T)).ravel()
            top = cap if np.isfinite(cap) else float(np.nanmax(np.abs(vc)))
            eps = 1e-6 * max(top, 1e-300)
        details["eps"] = eps

    # ---- the queue: the interior box, and the faces (tag 2 i + side), as arrays
    los, his, tags = [lower[None]], [upper[None]], [np.array([-1])]
    if faces:
        for i in range(nx):
            if i in periodic:
                continue                  # a side of zero width gets both faces: f_i = 0 there
            for side, val in ((0, lower[i]), (1, upper[i])):
                lo_f, hi_f = lower.copy(), upper.copy()
                lo_f[i] = hi_f[i] = val
                los.append(lo_f[None])
                his.append(hi_f[None])
                tags.append(np.array([2 * i + side]))
    stack = [(np.vstack(los), np.vstack(his), np.concatenate(tags))]
    counts = {"outside_free_space": 0, "outside_level": 0, "local_ball": 0, "decreasing": 0,
              "lasalle_lie": 0, "eps_set": 0, "face_above_level": 0, "face_inward": 0,
              "obstacle_boundary_split": 0}
    evaluated = 0
    leftovers: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    face_cex = None
    cex = None
    while stack and evaluated < max_boxes:
        lo, hi, tag = _take(stack, batch)
        evaluated += len(lo)
        ol, oh, sm, ct = F(lo, hi, clamp, continuity=True)
        # Vdot = grad V . f is the derivative of V along every solution where V is smooth and f
        # continuous (the chain rule needs only V's derivative); f Lipschitz makes solutions
        # unique, which the faces' invariance argument needs: a kink of f (a saturation,
        # fmin/fmax/fabs) is allowed, a jump or a square root at 0 leaves the box undecided
        v_smooth = sm[:, iv] & np.all(ct[:, if_], axis=1)
        # LaSalle's Lie derivatives differentiate Vdot, hence f: they need f smooth
        f_smooth = sm[:, iv] & np.all(sm[:, if_], axis=1) & sm[:, idot]
        v_lo, v_hi = ol[:, iv], oh[:, iv]
        # boxes the natural enclosure leaves undecided only because of Vdot
        # (on small boxes only: the form is second-order accurate there, and on large ones it
        # costs an evaluation of Vdot's gradient for little)
        need = (~(tag >= 0) & (oh[:, idot] >= 0) & v_smooth & sm[:, idot]
                & ~(ol[:, iv] > cap) & ((ol[:, iv] > 0) | bool(lasalle))
                & (np.max((hi - lo) / width, axis=1) <= MV_WIDTH))
        if ng:
            need &= np.all(ol[:, ig] > 0, axis=1)
        d_hi = oh[:, idot].copy()
        if need.any():
            k = np.flatnonzero(need)
            d_hi[k] = _mean_value_bound(F_mv, lo[k], hi[k], d_hi[k])
        done = np.zeros(len(lo), dtype=bool)
        if ng:
            out = np.any(oh[:, ig] <= 0, axis=1)
            counts["outside_free_space"] += int(out.sum())
            done |= out
        above = ~done & (v_lo > cap)
        is_face = tag >= 0
        counts["outside_level"] += int((above & ~is_face).sum())
        counts["face_above_level"] += int((above & is_face).sum())
        done |= above
        # faces: the flow points into the box
        if is_face.any():
            dim, side = tag // 2, tag % 2
            rows = np.flatnonzero(is_face & ~done)
            fl, fh = ol[rows, if_][np.arange(len(rows)), dim[rows]], \
                oh[rows, if_][np.arange(len(rows)), dim[rows]]
            inward = np.where(side[rows] == 0, fl >= 0, fh <= 0)
            if inward.any():
                # Nagumo's condition (f_i >= 0 allowed, not > 0) keeps every solution in K only
                # where solutions are unique: f Lipschitz on the face thickened outwards (the
                # face alone cannot see sqrt(x - 1) beyond it)
                r = rows[inward]
                tl, th = lo[r].copy(), hi[r].copy()
                k = np.arange(len(r))
                thick = 1e-9 * width[dim[r]]
                tl[k, dim[r]] -= np.where(side[r] == 0, thick, 0.0)
                th[k, dim[r]] += np.where(side[r] == 1, thick, 0.0)
                _, _, _, tct = F_f(tl, th, continuity=True)
                inward[np.flatnonzero(inward)] &= np.all(tct, axis=1)
            done[rows[inward]] = True
            counts["face_inward"] += int(inward.sum())
        interior = ~is_face & ~done
        if local is not None:
            inside = interior & np.all((lo >= local["lo"]) & (hi <= local["hi"]), axis=1)
            counts["local_ball"] += int(inside.sum())
            done |= inside
            interior &= ~inside
        if lasalle:
            small = interior & (v_hi < eps)
            counts["eps_set"] += int(small.sum())
            done |= small
            interior &= ~small
            strict = interior & (d_hi < 0) & v_smooth
            nonzero = np.zeros(len(lo), dtype=bool)
            lower_smooth = f_smooth.copy()
            for k in range(len(lie)):
                lk_lo, lk_hi = ol[:, il][:, k], oh[:, il][:, k]
                nonzero |= ((lk_lo > 0) | (lk_hi < 0)) & lower_smooth
                lower_smooth &= sm[:, il][:, k]
            leaves = interior & ~strict & (d_hi <= 0) & nonzero & f_smooth
            counts["decreasing"] += int(strict.sum())
            counts["lasalle_lie"] += int(leaves.sum())
            done |= strict | leaves
        else:
            ok = interior & (v_lo > 0) & (d_hi < 0) & v_smooth
            counts["decreasing"] += int(ok.sum())
            done |= ok
        if ng:
            # a box decided by decrease that may hold an obstacle's boundary (g = 0) inside the
            # level set is only done where the flow points out of the obstacle (gdot > 0), so
            # that K is invariant there too; otherwise it is split further (and, if it cannot
            # be, left undecided)
            decided = done & ~is_face & ~np.any(oh[:, ig] <= 0, axis=1) & ~(v_lo > cap)
            straddle = (ol[:, ig] == 0) & (oh[:, ig] > 0)
            # (the local ball too: an obstacle boundary through it is as much K's boundary)
            unsafe = decided & np.any(straddle & ~(ol[:, igd] > 0), axis=1)
            counts["obstacle_boundary_split"] += int(unsafe.sum())
            done &= ~unsafe
        rest = np.flatnonzero(~done)
        if not len(rest):
            continue
        lo, hi, tag = lo[rest], hi[rest], tag[rest]
        # a centre that violates the condition (and surely lies in K) is a counterexample
        mid = (lo + hi) / 2
        bad, bad_face = _violations(point, mid, tag, ng, cap, center, width, lasalle, local,
                                    zero_tol)
        if len(bad):
            # claimed only where the interval enclosure at the centre shows the violation
            pl, ph, _ = F(mid[bad], mid[bad], clamp)
            sure = (pl[:, idot] > 0) if lasalle else (ph[:, iv] <= 0) | (pl[:, idot] >= 0)
            sure &= ph[:, iv] <= cap            # and the centre surely in {V <= level}
            if sure.any():
                cex = mid[bad[np.flatnonzero(sure)[0]]]
                break
        if bad_face is not None and face_cex is None:
            face_cex = mid[bad_face]
        if face_cex is not None:
            # the flow leaves through a face: K is not shown invariant whatever the other faces
            # do, so no budget is spent on them
            keep_interior = tag < 0
            lo, hi, tag = lo[keep_interior], hi[keep_interior], tag[keep_interior]
            stack[:] = [(a[t < 0], b[t < 0], t[t < 0]) for a, b, t in stack if np.any(t < 0)]
            if not len(lo):
                continue
        rel = (hi - lo) / width
        tiny = rel.max(axis=1) < min_width
        if tiny.any():
            leftovers.append((lo[tiny], hi[tiny], tag[tiny]))
        keep = ~tiny
        if keep.any():
            stack.append(_bisect(lo[keep], hi[keep], tag[keep], rel[keep]))
    remaining = sum(len(s[0]) for s in stack)
    undecided = remaining + sum(len(s[0]) for s in leftovers)
    faces_undecided = sum(int(np.sum(s[2] >= 0)) for s in stack + leftovers)
    details.update(counts=counts, boxes=evaluated, budget=max_boxes, min_width=min_width,
                   undecided_faces=faces_undecided)
    if leftovers or stack:
        details["undecided_examples_lo"] = (leftovers + stack)[0][0][:5].tolist()
    invariant = None
    if faces:
        invariant = face_cex is None and faces_undecided == 0
        if face_cex is not None:
            details["face_counterexample"] = face_cex.tolist()
        if invariant and local is not None and level is not None and local["details"]["r0"] > 0:
            # Vdot < 0 is only shown outside the rounding radius r0: {V <= level} is invariant
            # only if that ball lies inside {V < level}, off its boundary
            r0 = local["details"]["r0"]
            c = local["center"]
            _, bh, _ = F((c - r0)[None], (c + r0)[None], clamp)
            if not bh[0, iv] < cap:
                invariant = False
                details["invariance_refused"] = (
                    f"the ball of the rounding radius r0 = {r0:.3g} around x*, where Vdot < 0 is "
                    f"not shown, reaches V = {bh[0, iv]:.3g} >= the level {cap:.6g}")
    where = _set_text(box, level, ng)
    if cex is not None:
        v, d = (float(a) for a in np.asarray(point(cex)[:2]).ravel()[:2])
        return Certificate("counterexample", "", f"interval branch and bound: after {evaluated} "
                           f"boxes, the centre of an undecided box violates the condition "
                           f"(V = {v:.6g}, Vdot = {d:.6g})", counterexample=np.asarray(cex),
                           invariant=invariant, boxes=evaluated, undecided=undecided,
                           details=details)
    interior_left = undecided - faces_undecided
    if lasalle and not interior_left and invariant is not True:
        # LaSalle's conclusion needs K positively invariant: without it nothing follows
        return Certificate("undecided", "", f"interval branch and bound: LaSalle's conditions "
                           f"hold on every box ({evaluated}), but K was not shown positively "
                           "invariant (faces or obstacle boundaries)", invariant=invariant,
                           boxes=evaluated, undecided=undecided, details=details)
    if interior_left:
        why = "the budget ran out" if stack else f"boxes reached the minimum width {min_width:g}"
        return Certificate("undecided", "", f"interval branch and bound: {interior_left} of "
                           f"{evaluated} boxes undecided ({why})", invariant=invariant,
                           boxes=evaluated, undecided=undecided, details=details)
    # without a centre nothing is excluded: the claim holds on all of K
    ball_text, except_text = "", ("except at x*" if center is not None else "everywhere")
    if local is not None:
        r0 = local["details"]["r0"]
        if r0 > 0:
            except_text = f"except within r0 = {r0:.3g} of x*"
        ball_text = (f"; within the box |x - x*| <= {np.array2string(local['half'], precision=3)}"
                     f" around x* = {np.array2string(local['center'], precision=6)} by the "
                     f"interval Hessians (Taylor), outside the radius r0 = {r0:.3g} of x*")
    inv_text = {True: "; K is positively invariant (faces: V > level or the flow points "
                      "inward; obstacle boundaries: V > level or the flow points away)",
                False: "; positive invariance of K was not shown on the faces",
                None: ""}[invariant]
    if lasalle:
        claim = (f"Vdot <= 0 on K = {where} outside {{V < {eps:.3g}}}, where no trajectory "
                 f"stays in {{Vdot = 0}} (Vdot < 0 or a Lie derivative L_f^k Vdot, k <= "
                 f"{len(lie)}, is nonzero){inv_text}: by LaSalle's invariance principle every "
                 f"trajectory starting in K enters {{V < {eps:.3g}}} and then stays in "
                 f"{{V <= {eps:.3g}}}")
    else:
        claim = f"V > 0 and Vdot < 0 on K = {where}, {except_text}{ball_text}{inv_text}"
        if not invariant and face_cex is not None:
            claim += (f" (the flow leaves K through a face, e.g. at "
                      f"{np.array2string(np.asarray(face_cex), precision=6)})")
    method = (f"interval branch and bound over {evaluated} boxes "
              f"({', '.join(f'{k} {v}' for k, v in counts.items() if v)})")
    return Certificate("proved", claim, method, invariant=invariant, boxes=evaluated,
                       undecided=undecided, details=details)


# ---------------------------------------------------------------------------------------------


#: boxes at most this wide (relative to the region's sides) also get the mean-value form of Vdot
MV_WIDTH = 1 / 256


def _mean_value_bound(F_mv, lo, hi, d_hi):
    """The upper bound of Vdot on each box: the smaller of its natural enclosure ``d_hi`` and the
    mean-value form ``Vdot(c) + sum_i |dVdot/dx_i|(box) * r_i`` (centre ``c``, half-widths ``r``),
    which is second-order accurate on small boxes where terms cancel (a quadratic candidate's
    cross terms). The caller uses it where Vdot is smooth on the box (its gradient is then the
    derivative there) and, with constraints, the box lies in the free space."""
    mid = (lo + hi) / 2
    both_lo, both_hi, sm = F_mv(np.vstack([lo, mid]), np.vstack([hi, mid]))
    n = len(lo)
    g_lo, g_hi = both_lo[:n, 1:], both_hi[:n, 1:]
    c_hi = both_hi[n:, :1]
    smooth = sm[:n, 0]
    # the half-widths about the rounded centre, rounded up: on a box a few ulps wide the centre
    # rounds to one end and (hi - lo) / 2 is half the distance to the other
    r = np.nextafter(np.maximum(mid - lo, hi - mid), np.inf)
    with np.errstate(invalid="ignore", over="ignore"):
        s = np.sum(np.maximum(np.abs(g_lo), np.abs(g_hi)) * r, axis=1)
        mv = c_hi[:, 0] + s
        mv = mv + 8 * np.finfo(float).eps * (np.abs(c_hi[:, 0]) + s) + 1e-300
    ok = smooth & np.isfinite(mv)
    return np.where(ok, np.minimum(d_hi, mv), d_hi)


def _take(stack, n):
    """Up to ``n`` boxes from the top of the stack (depth first)."""
    lo, hi, tag = stack.pop()
    if len(lo) > n:
        stack.append((lo[n:], hi[n:], tag[n:]))
        lo, hi, tag = lo[:n], hi[:n], tag[:n]
    return lo, hi, tag


def _bisect(lo, hi, tag, rel):
    """Split each box in two across its widest side (relative to the region)."""
    k = np.argmax(rel, axis=1)
    r = np.arange(len(lo))
    mid = (lo[r, k] + hi[r, k]) / 2
    lo2, hi1 = lo.copy(), hi.copy()
    hi1[r, k] = mid
    lo2[r, k] = mid
    return (np.vstack([lo, lo2]), np.vstack([hi1, hi]), np.concatenate([tag, tag]))


def _violations(point, mid, tag, ng, cap, center, width, lasalle, local, zero_tol):
    """Indices of the interior centres violating the condition in floating point (the caller
    re-checks them with intervals), and of a face centre (inside the level set and the free space)
    where the flow leaves the box (None where there is none)."""
    nx = mid.shape[1]
    out = point.map(len(mid))(mid.T)
    v = np.asarray(out[0]).ravel()
    d = np.asarray(out[1]).ravel()
    free = np.ones(len(mid), dtype=bool)
    if ng:
        free = np.all(np.asarray(out[2]).reshape(ng, -1) > 0, axis=0)
    inside = free & np.isfinite(v) & (v <= cap)
    away = np.ones(len(mid), dtype=bool)
    if center is not None:
        away = np.max(np.abs(mid - center) / width, axis=1) > 1e-9
    if local is not None:
        away &= ~np.all((mid >= local["lo"]) & (mid <= local["hi"]), axis=1)
    violated = (d > zero_tol) if lasalle else ((v <= 0) | (d >= 0))
    bad = np.flatnonzero((tag < 0) & inside & away & violated & ~np.isnan(d))
    fv = np.asarray(out[3]).reshape(nx, -1).T
    rows = np.flatnonzero((tag >= 0) & inside)
    dim, side = tag[rows] // 2, tag[rows] % 2
    fi = fv[rows, dim]
    leaving = rows[np.where(side == 0, fi < 0, fi > 0)]
    return bad, (int(leaving[0]) if len(leaving) else None)


def _local_ball(x, V, f, center, half, lower, upper) -> dict[str, Any]:
    """The Taylor argument on the box ``center +- half`` (shrunk up to 3 times by 10).

    ``V`` and ``f`` are first specialized to the box (:meth:`IntervalFunction.specialize`): a
    saturation that surely holds one side there is replaced by it, so that its Hessians are
    those of the function on the box (a saturated controller is linear near its target)."""
    nx = int(x.numel())
    nf = int(f.numel())
    whole = IntervalFunction(x, [V, f])
    c = center[None]
    info: dict[str, Any] = {"center": center.tolist()}
    for shrink in range(4):
        h = half / 10.0 ** shrink
        lo = np.maximum(center - h, lower)[None]
        hi = np.minimum(center + h, upper)[None]
        spec = whole.specialize(x, lo[0], hi[0])
        Vs, fs = spec[0], cs.vertcat(*spec[1:1 + nf])
        vdot = cs.jtimes(Vs, x, fs)
        HV, gV = cs.hessian(Vs, x)
        HD, gD = cs.hessian(vdot, x)
        F = IntervalFunction(x, [Vs, gV, HV, vdot, gD, HD])
        pl, ph, _ = F(c, c)
        ol, oh, smooth = F(lo, hi)
        if not smooth[0].all():          # (undefined outputs are not smooth either)
            info.update(ok=False, reason="V or Vdot is not smooth on the ball")
            continue
        m_v = _min_eig(ol[0, 1 + nx:1 + nx + nx * nx], oh[0, 1 + nx:1 + nx + nx * nx], nx)
        base = 2 + 2 * nx + nx * nx
        m_d = -_max_eig(ol[0, base:], oh[0, base:], nx)
        if not (m_v > 0 and m_d > 0):
            info.update(ok=False, reason=f"Hessian bounds not definite (V: {m_v:.3g}, "
                                         f"-Vdot: {m_d:.3g})")
            continue
        gv = float(np.linalg.norm(np.maximum(np.abs(pl[0, 1:1 + nx]), np.abs(ph[0, 1:1 + nx]))))
        c_v = max(0.0, -float(pl[0, 0]))
        i_d = 1 + nx + nx * nx
        gd = float(np.linalg.norm(np.maximum(np.abs(pl[0, i_d + 1:i_d + 1 + nx]),
                                             np.abs(ph[0, i_d + 1:i_d + 1 + nx]))))
        c_d = max(0.0, float(ph[0, i_d]))
        r0 = max(_root(m_v / 2, gv, c_v), _root(m_d / 2, gd, c_d))
        if r0 >= float(np.min(h)):
            info.update(ok=False, reason=f"rounding radius r0 = {r0:.3g} exceeds the ball")
            continue
        info.update(ok=True, reason="", half=h.tolist(), r0=r0, min_eig_hessian_V=m_v,
                    min_eig_minus_hessian_vdot=m_d)
        return {"ok": True, "lo": lo[0], "hi": hi[0], "half": h, "center": center,
                "details": info}
    return {"ok": False, "details": info}


def _root(a, b, c) -> float:
    """The positive root of a s^2 - b s - c (a > 0, b, c >= 0)."""
    return float((b + np.sqrt(b * b + 4 * a * c)) / (2 * a))


def _sym_interval(lo, hi, n):
    lo, hi = lo.reshape(n, n), hi.reshape(n, n)
    lo, hi = np.maximum(lo, lo.T), np.minimum(hi, hi.T)   # the true Hessian is symmetric
    return (lo + hi) / 2, (hi - lo) / 2


def _min_eig(lo, hi, n) -> float:
    """A lower bound on the smallest eigenvalue of every symmetric matrix in [lo, hi]."""
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        return -np.inf
    mid, rad = _sym_interval(lo, hi, n)
    if np.abs(rad).max() > 1e150:
        return -np.inf
    ev = float(np.linalg.eigvalsh(mid).min())
    # (the norms below may overflow to inf for huge radii: then no bound, which is right)
    # eigvalsh's backward error is a few ulp of |mid|: relative, so tiny Hessians keep their sign
    with np.errstate(over="ignore"):
        return ev - float(np.linalg.norm(rad, "fro")) - 1e-12 * np.abs(mid).max() - 1e-300


def _max_eig(lo, hi, n) -> float:
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        return np.inf
    return -_min_eig(-hi, -lo, n)


def _corners(lower, upper) -> np.ndarray:
    n = len(lower)
    grid = np.array(np.meshgrid(*[[0, 1]] * n, indexing="ij")).reshape(n, -1).T
    return lower + grid * (upper - lower)


def _set_text(box: Box, level, ng) -> str:
    parts = [" x ".join(f"{n} in [{lo:g}, {hi:g}]" for n, lo, hi in
                        zip(box.names, box.lower, box.upper))]
    if level is not None:
        parts.append(f"V <= {level:.6g}")
    if ng:
        parts.append("the free space")
    return "{" + "; ".join(parts) + "}"
