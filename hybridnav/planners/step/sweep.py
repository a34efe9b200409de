"""The swept-footprint check of :func:`~hybridnav.planners.step.stepfit.feasible_steps`: rolled
out block by block, pruned by bounding boxes, exact where the boxes are inconclusive.

:func:`sweep` integrates the robot's compiled model from its state towards every candidate a
block of control cycles at a time (:func:`roll_block`) and, after every block, tests the pieces
of the block the move uses -- the straight pieces between consecutive rollout samples of every
footprint disk, up to the first sample within ``reach`` of the candidate. A candidate leaves the
batch, and is integrated no further, as soon as its move ends or one of its pieces collides
(nothing later can make it safe again).

The verdict is the exact piecewise test, computed by the same functions on the same numbers as
ever: :meth:`World.segment_collides` for the static obstacles and for the moving circles frozen
at each piece's start time, the point-to-segment distance to the other robots' disks and
:meth:`World.inside_workspace` at each piece's end -- obstacle by obstacle
(:meth:`World.singles`: a world's test is true where one of its obstacles' is). The pruning only
decides which pieces each of them sees, and skips a piece only where it provably cannot collide:

1. the pieces are grouped in stretches of :data:`_STRIDE`; a stretch's samples lie in a box and
   its pieces (straight segments between them) too, and every footprint disk lies within
   ``model.footprint_extent`` of the robot's position, so every disk along the stretch lies
   within that of the box;
2. for the stretches that box leaves in doubt, the footprint is computed and each disk's centres
   along the stretch give a box of their own;
3. then each piece's box;
4. a piece whose box is, by more than the disk's radius plus the margin, farther from an
   obstacle's box (:meth:`World.boxes`; moving circles over the stretch's times), from another
   robot's disk or from the workspace border cannot touch it and is not tested against it.

For many boxes the static obstacles and the border are asked of the world's
:meth:`~World.clear_map` (a grid of cells farther than the reach from all of them) in a few
operations per box; for few, of each obstacle's box. "Farther" includes a slack of ``1e-9`` of the
workspace's scale, far above the rounding error of the box arithmetic and of the exact tests, so
a skipped test could only have said "no collision". Likewise a sample is only tested for being
within ``reach`` of its candidate when its stretch's box is, and the candidate's being in sight
from where its move ends is tested obstacle by obstacle where boxes say it may be blocked.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hybridnav.native.boxes import boxes_near as compiled_boxes_near
from hybridnav.native.boxes import disks_near as compiled_disks_near
from hybridnav.native.boxes import near_any as compiled_near_any
from hybridnav.native.boxes import pieces_near as compiled_pieces_near
from hybridnav.native.boxes import reach_first as compiled_reach_first
from hybridnav.native.boxes import static_hits as compiled_static_hits
from hybridnav.native.boxes import stretch_boxes as compiled_stretch_boxes
from hybridnav.world import point_segment_distance

__all__ = ["costly_cycles", "roll_block", "sweep"]

FloatArray = NDArray[np.float64]

# rollout pieces per stretch, the unit of the bounding-box pruning
_STRIDE = 8
# control cycles integrated per compiled call: a candidate whose move has ended is integrated
# no further (a divisor of the blocks of roll_block) ...
_SUB = 32
# ... for models whose step has more operations than this (the point mass: 53, the unicycle:
# 200, the tractor-trailer: 309)
_CHEAP = 100
# boxes x static obstacles from which the clear map pays (fewer: each obstacle's box at once)
_MAP_FROM = 1 << 14
# pieces tested exactly per call (bounds the memory of the (pieces, obstacles) arrays)
_BLOCK = 1 << 16


def roll_block(model, n: int) -> tuple[int, int]:
    """Control cycles between two checks for a batch of ``n`` candidates, and per compiled call.

    Short blocks stop the integration of a large batch soon after its moves collide; small
    batches, whose checks cost more per sample (a check's cost is mostly per call below a few
    hundred candidates, and most candidates a swarm asks about at that size are feasible, so
    driven to their end anyway), take long blocks -- 256 cycles for models with costly cycles,
    64 for cheap ones (whose block is one compiled call that drives ended moves on). Within a
    block the moves that have ended are integrated no further, :data:`_SUB` cycles at a time, for models whose cycle
    costs more than a compiled call's overhead (those with trigonometry: a step function of more
    than :data:`_CHEAP` operations). Both are multiples of :data:`_STRIDE`.
    """
    cheap = _cycle_cost(model) <= _CHEAP
    if cheap:       # a cheap model integrates a whole block in one call, ended moves too
        return (64, 64) if n < 1024 else (16, 16)
    block = 256 if n < 256 else 64 if n < 1024 else 16
    return block, _SUB


def costly_cycles(model) -> bool:
    """Whether the model's control cycle costs more than a compiled call's overhead (a step
    function of more than :data:`_CHEAP` operations: trigonometry), so that a candidate's
    rollout, not the check's calls, is what a check mostly costs."""
    return _cycle_cost(model) > _CHEAP


def _cycle_cost(model) -> int:
    """Operations of one control cycle of the model's compiled step (cached on the model)."""
    cost = model.__dict__.get("_sweep_cycle_cost")
    if cost is None:
        cost = model.__dict__["_sweep_cycle_cost"] = int(model.function("step").n_instructions())
    return cost


class _Sweep:
    """What the pieces of one robot's moves are tested against, prepared once per call."""

    def __init__(self, model, env, margin: float) -> None:
        self.model = model
        self.env = env
        self.margin = float(margin)
        world = env.world
        self.world, self.moving = world, env.moving
        self.static_world = env.static
        self.static = env.static.singles()
        self.n_static = len(self.static)
        self.movers = env.moving.singles()
        self.other_c, self.other_r = env.robot_discs
        self.extent = model.footprint_extent          # None: bound the footprint disks instead
        scale = max(abs(v) for v in world.workspace) + (self.extent or 0.0) + self.margin
        self.slack = 1e-9 * (1.0 + scale)
        # everything frozen during the plan: static obstacles, then the other robots' disks
        self.f_lo, self.f_hi, self.f_pad = env.frozen_boxes

    @classmethod
    def of(cls, model, env, margin: float) -> _Sweep:
        """The one for ``model`` and ``margin`` in ``env`` (kept in ``env``: a plan checks its
        candidates many times in the same surroundings; nothing here changes after
        :meth:`__init__`)."""
        cache = env.__dict__.setdefault("_sweeps", {})
        key = (id(model), float(margin))
        found = cache.get(key)
        if found is None or found.model is not model:
            if len(cache) >= 8:
                cache.pop(next(iter(cache)))
            found = cache[key] = cls(model, env, margin)
        return found

    # ---- which stretches and pieces need the exact test ------------------------------------

    def _near_each(self, lo: FloatArray, hi: FloatArray, reach, t0, t1):
        """What may come within ``reach`` of the boxes ``[lo, hi]`` (shape (..., 2)): the
        border (...,), each frozen obstacle (static ones, then the other robots' disks;
        (..., F)) and each moving circle anywhere between the times ``t0`` and ``t1``
        (broadcasting against (...); (..., M))."""
        thr = np.asarray(reach) + self.slack
        xmin, xmax, ymin, ymax = self.world.workspace
        border = ~((lo[..., 0] - xmin >= thr) & (xmax - hi[..., 0] >= thr)   # NaN: near
                   & (lo[..., 1] - ymin >= thr) & (ymax - hi[..., 1] >= thr))
        frozen = _boxes_near(lo, hi, self.f_lo, self.f_hi, self.f_pad, thr)
        return border, frozen, self._near_moving(lo, hi, thr, t0, t1)

    def _near_moving(self, lo: FloatArray, hi: FloatArray, thr, t0, t1) -> NDArray[np.bool_]:
        """Whether each moving circle may come within ``thr`` (the slack included) of the boxes
        between the times ``t0`` and ``t1``: (..., M)."""
        if self.movers:
            m_lo, m_hi, m_pad = self.moving.boxes(t0, t1)
            return _boxes_near(lo, hi, m_lo, m_hi, m_pad, thr)
        return np.zeros(lo.shape[:-1] + (0,), dtype=bool)

    def _near(self, lo: FloatArray, hi: FloatArray, reach: float, t0, t1) -> NDArray[np.bool_]:
        """Whether anything may come within ``reach`` of the boxes (see :meth:`_near_each`):
        for many boxes, the static obstacles and the border by the world's
        :meth:`~World.clear_map` (a few operations per box), the others box by box."""
        if lo[..., 0].size * self.n_static < _MAP_FROM:
            near = compiled_near_any(lo, hi, np.asarray(reach) + self.slack, self.world.workspace,
                                     self.f_lo, self.f_hi, self.f_pad)
            if near is None:
                border, frozen, moving = self._near_each(lo, hi, reach, t0, t1)
                return border | frozen.any(axis=-1) | moving.any(axis=-1)
            if self.movers:
                m_lo, m_hi, m_pad = self.moving.boxes(t0, t1)
                near |= _boxes_near(lo, hi, m_lo, m_hi, m_pad, reach + self.slack).any(axis=-1)
            return near
        near = ~self.static_world.clear_map(reach).free(lo, hi)
        thr = reach + self.slack
        if len(self.other_r):
            near |= _boxes_near(lo, hi, self.f_lo[self.n_static:], self.f_hi[self.n_static:],
                                self.f_pad[self.n_static:], thr).any(axis=-1)
        if self.movers:
            m_lo, m_hi, m_pad = self.moving.boxes(t0, t1)
            near |= _boxes_near(lo, hi, m_lo, m_hi, m_pad, thr).any(axis=-1)
        return near

    def _near_disks(self, C: FloatArray, need: FloatArray, t0, t1) -> NDArray[np.bool_]:
        """Whether anything may come within ``need[j]`` of footprint disk ``j`` along each
        stretch of its centres ``C`` (ns, samples, nd, 2): :meth:`_near` of each disk's box.
        Compiled (:func:`hybridnav.native.boxes.disks_near`) where :meth:`_near` tests the
        boxes one by one: the same booleans."""
        got = None
        if len(C) * self.n_static < _MAP_FROM:
            got = compiled_disks_near(C, need + self.slack, self.world.workspace, self.f_lo,
                                      self.f_hi, self.f_pad)
        if got is None:        # each disk's box along the stretch: its one stretch of samples
            boxes = [_stretch_boxes(C[:, :, j:j + 1], 1) for j in range(len(need))]
            return np.stack([self._near(c_lo[:, 0], c_hi[:, 0], need[j], t0, t1)
                             for j, (c_lo, c_hi) in enumerate(boxes)], axis=1)
        lo, hi, near = got
        if self.movers:
            m_lo, m_hi, m_pad = self.moving.boxes(t0, t1)
            for j in range(len(need)):
                near[:, j] |= _boxes_near(lo[:, j], hi[:, j], m_lo, m_hi, m_pad,
                                          need[j] + self.slack).any(axis=-1)
        return near

    def check(self, S: FloatArray, npieces: NDArray[np.int_], k0: int, lo: FloatArray,
              hi: FloatArray) -> NDArray[np.bool_]:
        """Whether a used piece of each move collides.

        Parameters
        ----------
        S : ndarray, shape (na, b + 1, nx)
            Rollout samples ``k0 .. k0 + b`` of the candidates.
        npieces : ndarray of int, shape (na,)
            Pieces ``k0 .. k0 + npieces - 1`` are used (0 to ``b``).
        k0 : int
            Index of the first sample (a multiple of :data:`_STRIDE`).
        lo, hi : ndarray, shape (na, stretches, 2)
            The box of the positions along each stretch.

        Returns
        -------
        ndarray of bool, shape (na,)
        """
        model = self.model
        na, b1, nx = S.shape
        b = b1 - 1
        bad = np.zeros(na, dtype=bool)
        if na == 0 or b == 0:
            return bad
        nst = -(-b // _STRIDE)
        if self.extent is not None:                  # 1. the robot's positions and extent
            reach = self.extent + self.margin
            full = None
        else:                                        # 1. (unknown extent) the footprint disks
            full, radii = model.footprint(S.reshape(-1, nx))
            full = full.reshape(na, b1, len(radii), 2)
            reach = float(np.max(radii)) + self.margin
            lo, hi = _stretch_boxes(full, nst)
        used = (np.arange(nst) * _STRIDE)[None, :] < npieces[:, None]
        t, dt = self.env.t, model.dt
        first = k0 + np.arange(nst) * _STRIDE
        t0, t1 = t + first * dt, t + (first + _STRIDE) * dt
        rows, gs = np.nonzero(used & self._near(lo, hi, reach, t0, t1))
        if not len(rows):
            return bad
        # 2. the footprint along those stretches: each disk's box
        idx = rows[:, None] * b1 + np.minimum(gs[:, None] * _STRIDE
                                              + np.arange(_STRIDE + 1)[None, :], b)
        if full is None:
            C, radii = model.footprint(S.reshape(-1, nx)[idx.ravel()])
            C = C.reshape(len(rows), _STRIDE + 1, len(radii), 2)       # (ns, 9, nd, 2)
        else:
            C = full.reshape((-1,) + full.shape[2:])[idx]
        need = np.asarray(radii, dtype=float) + self.margin           # (nd,)
        if len(need) > 1:
            near_disk = self._near_disks(C, need, t0[gs], t1[gs])           # (ns, nd)
        else:
            near_disk = np.ones((len(rows), 1), dtype=bool)
        q = gs[:, None] * _STRIDE + np.arange(_STRIDE)[None, :]       # (ns, _STRIDE) pieces
        valid = q < npieces[rows, None]
        for j in range(len(need)):
            sel = valid & near_disk[:, j, None]
            if not sel.any():
                continue
            # 3. each piece's box; 4. the exact test against what it may touch
            A, B = C[:, :-1, j][sel], C[:, 1:, j][sel]
            owner = np.broadcast_to(rows[:, None], q.shape)[sel]
            tk = t + (k0 + q)[sel] * dt               # the pieces' start times
            for lo_ in range(0, len(A), _BLOCK):
                at = slice(lo_, lo_ + _BLOCK)
                hit = self.touches(A[at], B[at], need[j], tk[at])
                bad[owner[at][hit]] = True
        return bad

    def touches(self, A: FloatArray, B: FloatArray, need: float, t: FloatArray,
                border: bool = True) -> NDArray[np.bool_]:
        """Whether a disk of radius ``need`` swept along ``A -> B`` (moving circles frozen at
        the times ``t``) touches an obstacle or another robot's disk, or (``border``) ends
        outside the workspace shrunk by ``need``: exactly the tests of the whole world, each
        obstacle's only where the boxes say it may touch."""
        out = np.zeros(len(A), dtype=bool)
        few = len(A) * self.n_static < _MAP_FROM
        thr = np.asarray(need) + self.slack
        got = few and compiled_pieces_near(A, B, thr, self.world.workspace, self.f_lo,
                                           self.f_hi, self.f_pad)
        near = slice(None)
        if got:               # compiled: the pieces' boxes and the tests of _near_each
            lo, hi, at_border, frozen = got
            moving = self._near_moving(lo, hi, thr, t, t)
        else:
            lo, hi = np.minimum(A, B), np.maximum(A, B)
            if not few:       # the clear map first, each obstacle's box for the rest
                near = np.flatnonzero(self._near(lo, hi, need, t, t))
                if not len(near):
                    return out
                A, B, t, lo, hi = A[near], B[near], t[near], lo[near], hi[near]
            at_border, frozen, moving = self._near_each(lo, hi, need, t, t)
        hit = np.zeros(len(A), dtype=bool)
        at = np.flatnonzero(at_border)
        if border and len(at):
            hit[at] |= ~self.world.inside_workspace(B[at], need)
        ns = len(self.static)
        columns = np.flatnonzero(frozen.any(axis=0))
        if ns and len(columns) and columns[0] < ns:
            # the static obstacles' exact tests of every (piece, obstacle) pair left, compiled
            rows, obs = np.nonzero(frozen[:, :ns])
            got = compiled_static_hits(self.static_world, A[rows], B[rows], obs, need)
            if got is not None:
                hit[rows[got]] = True
                columns = columns[columns >= ns]
        for o in columns:
            at = np.flatnonzero(frozen[:, o])
            if o < ns:
                hit[at] |= self.static[o].segment_collides(A[at], B[at], radius=need)
            else:
                dd, _ = point_segment_distance(self.other_c[o - ns], A[at], B[at])
                hit[at] |= dd < need + self.other_r[o - ns]
        for o in np.flatnonzero(moving.any(axis=0)):
            at = np.flatnonzero(moving[:, o])
            hit[at] |= self.movers[o].segment_collides(A[at], B[at], radius=need, t=t[at])
        out[near] = hit
        return out


def _stretch_boxes(pts: FloatArray, nst: int) -> tuple[FloatArray, FloatArray]:
    """Boxes ``lo, hi`` (na, nst, 2) of the points ``pts`` (na, samples, m, 2) of each stretch:
    samples ``g * _STRIDE`` to ``(g + 1) * _STRIDE`` (the last stretch may be short). Compiled
    (:mod:`hybridnav.native.boxes`) where it is: the same minima and maxima."""
    boxes = compiled_stretch_boxes(pts, nst, _STRIDE)
    if boxes is not None:
        return boxes
    na, n1, m, _ = pts.shape
    T = np.moveaxis(pts, 1, 0)                                  # (samples, na, m, 2)
    pad = nst * _STRIDE + 1 - n1
    if pad:   # a short last stretch: repeat its last sample (the box stays the same)
        T = np.concatenate([T, np.broadcast_to(T[-1:], (pad,) + T.shape[1:])])
    T = np.ascontiguousarray(T)
    head = T[:-1].reshape(nst, _STRIDE, na, m, 2)
    tail = T[_STRIDE::_STRIDE]                                  # (nst, na, m, 2)
    lo = np.minimum(head.min(axis=1), tail).min(axis=2)        # (nst, na, 2)
    hi = np.maximum(head.max(axis=1), tail).max(axis=2)
    return lo.transpose(1, 0, 2), hi.transpose(1, 0, 2)


def _boxes_near(lo: FloatArray, hi: FloatArray, o_lo: FloatArray, o_hi: FloatArray,
                o_pad: FloatArray, thr) -> NDArray[np.bool_]:
    """Whether each obstacle box ``[o_lo, o_hi]`` (shape (K, 2) or (..., K, 2)), padded by
    ``o_pad``, is closer than ``thr`` to each box ``[lo, hi]`` (shape (..., 2)): (..., K).
    (The Euclidean distance between two boxes is a lower bound of the distance between their
    points; a box with a NaN corner is near everything.) For one threshold and (K, 2) obstacle
    boxes, the compiled test (:mod:`hybridnav.native.boxes`: the same operations) where it is."""
    near = compiled_boxes_near(lo, hi, o_lo, o_hi, o_pad, thr)
    if near is not None:
        return near
    reach = np.asarray(thr)[..., None] + o_pad
    gx = np.maximum(np.maximum(o_lo[..., 0] - hi[..., 0, None], lo[..., 0, None] - o_hi[..., 0]),
                    0.0)
    gy = np.maximum(np.maximum(o_lo[..., 1] - hi[..., 1, None], lo[..., 1, None] - o_hi[..., 1]),
                    0.0)
    return ~(gx * gx + gy * gy >= reach * reach)


def _reach_first(traj: FloatArray, P: FloatArray, nst: int, reach: float, reach2: float):
    """The boxes ``lo, hi`` (na, nst, 2) of the positions of the rollout samples ``traj`` (na,
    samples, nx) along each stretch, and per row the first of the samples ``1 ..`` within
    ``reach`` of its target ``P`` (na, 2), minus one (-1: none; a sample is only looked at where
    one of its row's boxes comes within ``reach2`` of the target). Compiled
    (:func:`hybridnav.native.boxes.reach_first`) where it is: the same numbers."""
    got = compiled_reach_first(traj, P, nst, _STRIDE, reach, reach2)
    if got is not None:
        return got
    lo, hi = _stretch_boxes(traj[:, :, None, :2], nst)
    gx = np.maximum(np.maximum(lo[..., 0] - P[:, None, 0], P[:, None, 0] - hi[..., 0]), 0.0)
    gy = np.maximum(np.maximum(lo[..., 1] - P[:, None, 1], P[:, None, 1] - hi[..., 1]), 0.0)
    close = np.flatnonzero((gx * gx + gy * gy <= reach2).any(axis=1))
    Pc = P[close]
    within = np.hypot(traj[close, 1:, 0] - Pc[:, None, 0],
                      traj[close, 1:, 1] - Pc[:, None, 1]) <= reach
    first = np.full(len(traj), -1, dtype=np.int64)
    done = within.any(axis=1)
    first[close[done]] = within[done].argmax(axis=1)
    return lo, hi, first


def _integrate(model, X0: FloatArray, P: FloatArray, b: int, sub: int, reach: float):
    """``b`` control cycles from ``X0`` towards ``P``, ``sub`` at a time, a candidate no
    further once a sample is within ``reach`` of it (its later samples repeat that state).

    Returns the samples ``(na, b + 1, nx)``, the pieces each move uses in the block (``q + 1``
    when sample ``q + 1`` is the first within reach, else ``b``), whether the move ended, and
    the boxes ``lo, hi`` (na, stretches, 2) of the positions along each stretch. (A sample is
    only looked at for reach when its stretch's box comes within reach of the candidate.)
    """
    na = len(X0)
    nst = -(-b // _STRIDE)
    # one compiled call for the block: its samples as they come; else assembled
    part = None if sub >= b else np.empty((na, b + 1, model.nx))
    if part is not None:
        part[:, 0] = X0
    lo, hi = np.empty((na, nst, 2)), np.empty((na, nst, 2))
    npieces = np.full(na, b)
    ended = np.zeros(na, dtype=bool)
    live = np.arange(na)
    reach2 = reach * reach * (1.0 + 1e-9)
    j = 0
    while j < b and len(live):
        s = min(sub, b - j)
        rows = slice(None) if len(live) == na else live     # (a slice copies less)
        Pl = P[rows]
        if part is None:
            part = traj = model.rollout(X0, Pl, s)             # (na, b + 1, nx)
        else:
            traj = model.rollout(part[rows, j], Pl, s)         # (nl, s + 1, nx)
            part[rows, j + 1:j + s + 1] = traj[:, 1:]
        g0, ns = j // _STRIDE, -(-s // _STRIDE)
        blo, bhi, first = _reach_first(traj, Pl, ns, reach, reach2)
        lo[rows, g0:g0 + ns], hi[rows, g0:g0 + ns] = blo, bhi
        done = np.flatnonzero(first >= 0)
        now = live[done]
        ended[now] = True
        npieces[now] = j + first[done] + 1
        if j + s < b:
            final = traj[done, -1]
            part[now, j + s + 1:] = final[:, None]
            lo[now, g0 + ns:] = hi[now, g0 + ns:] = final[:, None, :2]
        live = np.delete(live, done)
        j += s
    return part, npieces, ended, lo, hi


def sweep(model, x0: FloatArray, P: FloatArray, env, *, steps: int, reach: float,
          margin: float, end_margin: float | None = None) -> NDArray[np.bool_]:
    """Roll out from ``x0`` towards every candidate and test the moves' swept footprints, and
    whether each candidate is in sight from where its move ends (the verdict of
    :func:`~hybridnav.planners.step.stepfit.feasible_steps`, which documents the parameters).

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    n = len(P)
    x0 = np.asarray(x0, dtype=float)
    bad = np.zeros(n, dtype=bool)
    last = np.full(n, steps)
    end = np.empty((n, 2))
    check = _Sweep.of(model, env, margin)
    d0 = np.hypot(x0[0] - P[:, 0], x0[1] - P[:, 1])
    last[d0 <= reach] = 0
    end[:] = x0[:2]                         # (also where the distance is NaN: never integrated)
    active = np.flatnonzero(d0 > reach)
    cur = np.repeat(x0[None], len(active), axis=0)
    block, sub = roll_block(model, len(active))
    k = 0
    while k < steps and len(active):
        b = min(block, steps - k)
        part, npieces, done, lo, hi = _integrate(model, cur, P[active], b, sub, reach)
        hit = check.check(part, npieces, k, lo, hi)
        bad[active[hit]] = True
        fin = done & ~hit
        last[active[fin]] = k + npieces[fin]
        end[active[fin]] = part[fin, npieces[fin], :2]
        keep = ~done & ~hit
        active, cur = active[keep], part[keep, -1]
        k += b
    end[active] = cur[:, :2]
    # the candidate itself must be in sight: the whole-body disk swept straight from where the
    # move ends to the candidate keeps the margin too (the next step is planned from there)
    ok = ~bad
    sel = np.flatnonzero(ok)
    if len(sel):
        body = model.radius + (margin if end_margin is None else end_margin)
        ok[sel] = ~check.touches(end[sel], P[sel], body, env.t + last[sel] * model.dt,
                                 border=False)
    return ok
