"""A simulated 2-D laser range finder (a TurtleBot3's LDS-01 by default) and the world it shows.

:func:`raycast` casts ``B`` beams from each of ``N`` points against every obstacle of a
:class:`~hybridnav.world.World` at once (NumPy broadcasting over points, beams and obstacles:
circles analytically, segment, rectangle and polygon edges by ray-segment intersection), giving
the exact range to the first surface along each beam. :class:`Lidar` turns that into a reading:
Gaussian range noise of standard deviation ``noise`` from a generator the caller seeds, and a
return only where the true surface lies within ``max_range`` and the noisy range within
``[min_range, max_range]`` (what the sensor reports otherwise, nothing). :class:`SensedWorld` is
that reading seen through the two queries the reactive planners ask of a world,
:meth:`~hybridnav.world.World.nearest` and :meth:`~hybridnav.world.World.nearest_each`: the
nearest return, and the nearest return of each obstacle (the beams are labelled with the obstacle
they hit, an ideal segmentation of the scan).

With ``noise = 0`` the nearest return differs from the exact nearest surface point only by the
beam spacing: the exact nearest point lies within half a beam step of some beam, and that beam's
range is at most ``d / cos(step / 2)`` for a flat surface at distance ``d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hybridnav.world.geometry import FloatArray, _points
from hybridnav.world.world import World

__all__ = ["LDS01", "Lidar", "SensedWorld", "beam_angles", "raycast"]


def beam_angles(headings, beams: int) -> FloatArray:
    """World-frame beam directions ``(N, beams)``: ``beams`` beams evenly spaced over a full turn,
    the first along each robot's heading."""
    headings = np.asarray(headings, dtype=float).reshape(-1, 1)
    return headings + (2.0 * math.pi / beams) * np.arange(beams)[None, :]


def raycast(world: World, P, angles, t: float = 0.0) -> FloatArray:
    """Range from each point along each beam to each obstacle's surface.

    Parameters
    ----------
    world : World
    P : array_like, shape (N, 2)
        The beams' origins.
    angles : array_like, shape (N, B)
        World-frame beam directions (radians).
    t : float
        Time at which moving circles are placed.

    Returns
    -------
    ndarray, shape (N, B, K)
        The smallest ``r >= 0`` with ``P + r (cos a, sin a)`` on obstacle ``k``'s boundary
        (``inf``: the beam misses it). An origin inside a circle or closed polygon sees its
        boundary from inside.
    """
    P = _points(P)
    n = P.shape[0]
    angles = np.asarray(angles, dtype=float).reshape(n, -1)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=-1)          # (N, B, 2)
    out = np.full((n, angles.shape[1], len(world.obstacles)), np.inf)
    if world._c_idx.size:
        C = world._centers(t, n)                                      # (1 or N, C, 2)
        oc = P[:, None, :] - C                                        # (N, C, 2)
        b = np.einsum("nbi,nci->nbc", d, oc)                          # (N, B, C)
        cc = (np.einsum("nci,nci->nc", oc, oc) - world._cr[None] ** 2)[:, None, :]
        disc = b * b - cc
        root = np.sqrt(np.maximum(disc, 0.0))
        near, far = -b - root, -b + root
        r = np.where(near >= 0.0, near, np.where(far >= 0.0, far, np.inf))
        out[:, :, world._c_idx] = np.where(disc >= 0.0, r, np.inf)
    if world._g_idx.size:
        A, e = world._eA, world._eB - world._eA                       # (E, 2)
        w = A[None, :, :] - P[:, None, :]                             # (N, E, 2)
        denom = d[:, :, None, 0] * e[None, None, :, 1] - d[:, :, None, 1] * e[None, None, :, 0]
        we = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0])[:, None, :]   # (N, 1, E)
        wd = w[:, None, :, 0] * d[:, :, None, 1] - w[:, None, :, 1] * d[:, :, None, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = we / denom
            s = wd / denom
        hit = (denom != 0.0) & (r >= 0.0) & (s >= 0.0) & (s <= 1.0)
        r = np.where(hit, r, np.inf)
        out[:, :, world._g_idx] = np.minimum.reduceat(r, world._g_start, axis=2)
    return out


@dataclass(frozen=True)
class Lidar:
    """A 2-D laser range finder: ``beams`` beams over a full turn, the first along the robot's
    heading, returns between ``min_range`` and ``max_range``, Gaussian range noise of standard
    deviation ``noise`` (scenario units). The defaults are the TurtleBot3's LDS-01 (360 beams,
    1 degree apart, 0.12-3.5 m)."""

    beams: int = 360
    min_range: float = 0.12
    max_range: float = 3.5
    noise: float = 0.0

    def scan(self, world: World, P, headings, t: float = 0.0,
             rng: np.random.Generator | None = None) -> SensedWorld:
        """One scan from each point (heading ``headings``, ``(N,)``) at time ``t``.

        ``rng`` draws the range noise, ``(N, beams)`` normal values per scan whatever is hit
        (so a run's noise depends on its seed and its number of scans only); it may be None
        without noise.
        """
        P = _points(P)
        angles = beam_angles(headings, self.beams)
        per = raycast(world, P, angles, t)
        true = per.min(axis=2) if per.shape[2] else np.full(angles.shape, np.inf)
        owner = per.argmin(axis=2) if per.shape[2] else np.full(angles.shape, -1)
        measured = true
        if self.noise > 0:
            measured = true + self.noise * rng.standard_normal(true.shape)
        valid = (true <= self.max_range) & (measured >= self.min_range) & \
            (measured <= self.max_range)
        return SensedWorld(world, P, angles, np.where(valid, measured, np.inf),
                           np.where(valid, owner, -1))


@dataclass(frozen=True)
class SensedWorld:
    """One scan, answering the nearest-obstacle queries of :class:`~hybridnav.world.World` for
    the points it was taken from.

    Parameters
    ----------
    world : World
        The scanned world (its obstacle list: indices refer to it).
    origins : ndarray, shape (N, 2)
    angles : ndarray, shape (N, B)
    ranges : ndarray, shape (N, B)
        The measured ranges; ``inf`` where the beam gave no return.
    owner : ndarray of int, shape (N, B)
        The obstacle each return came from (``-1``: none).
    """

    world: World
    origins: FloatArray
    angles: FloatArray
    ranges: FloatArray
    owner: np.ndarray

    @property
    def obstacles(self):
        """The scanned world's obstacles (whether there is anything to see)."""
        return self.world.obstacles

    def points(self) -> FloatArray:
        """The returns as points ``(N, B, 2)`` (NaN where none)."""
        r = np.where(np.isfinite(self.ranges), self.ranges, np.nan)
        return self.origins[:, None, :] + r[..., None] * np.stack(
            [np.cos(self.angles), np.sin(self.angles)], axis=-1)

    def _check(self, P) -> None:
        P = _points(P)
        if P.shape != self.origins.shape or not np.array_equal(P, self.origins):
            raise ValueError("SensedWorld: queried at other points than the scan was taken from")

    def nearest(self, P, t: float = 0.0):
        """As :meth:`World.nearest`, from the scan: the shortest return's range, its point and
        obstacle (``inf``, NaN and ``-1`` where the scan has no return)."""
        self._check(P)
        n = len(self.origins)
        b = np.argmin(self.ranges, axis=1)
        rows = np.arange(n)
        clear = self.ranges[rows, b]
        near = self.points()[rows, b]
        idx = self.owner[rows, b]
        return clear, near, np.where(np.isfinite(clear), idx, -1)

    def nearest_each(self, P, t: float = 0.0):
        """As :meth:`World.nearest_each`, from the scan: per obstacle its shortest return
        (``inf`` where none returned; the point is then the origin itself, so a force pointing
        away from it is zero)."""
        self._check(P)
        n, k = len(self.origins), len(self.world.obstacles)
        mine = self.owner[:, :, None] == np.arange(k)[None, None, :]          # (N, B, K)
        r = np.where(mine, self.ranges[:, :, None], np.inf)
        b = np.argmin(r, axis=1)                                              # (N, K)
        clear = np.take_along_axis(r, b[:, None, :], axis=1)[:, 0, :]
        pts = self.points()
        near = np.take_along_axis(pts, b[:, :, None], axis=1)                 # (N, K, 2)
        near = np.where(np.isfinite(clear)[..., None], near, self.origins[:, None, :])
        return clear, near


#: The TurtleBot3's LDS-01, noise-free.
LDS01 = Lidar()
