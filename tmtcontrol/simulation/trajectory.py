"""Reference paths in the surface's tangential coordinates: the circle of Fig. 2, a line, a raster.

Every path is given on task axes 1 and 2 (the surface's tangential
coordinates, :mod:`tmtcontrol.surface`), centred at the task-frame origin
(``trajectory.center``) and periodic with ``period``; ``radius`` is its
half-size (m). Positions in m, velocities in m/s, accelerations in m/s^2,
each analytic (no finite differences), so the feed-forward of eq. (4) is
exact:

* ``circle`` (section V): ``radius (cos wt, sin wt)``, ``w = 2 pi / period``;
* ``line``: back and forth along the direction ``direction_deg`` (from task
  axis 1): ``radius sin(wt) d``, at rest at both ends, fastest at the centre;
* ``raster``: a smooth lawn-mower pattern over the square of half-side
  ``radius`` turned by ``direction_deg``: ``lanes`` passes across along d
  (``radius sin(lanes w t / 2) d``) while the pattern advances across the
  lanes and back once per period (``-radius cos(wt) d_perp``): the sweep of a
  polishing or sanding tool, without corners (an infinite acceleration at a
  corner would be no reference for eq. 4).

How far a path reaches along each tangential axis is :func:`path_extent`,
not ``radius``: a circle reaches ``radius`` along both axes, a line ``radius
|cos|`` and ``radius |sin|`` of its direction, a raster up to ``radius
(|cos| + |sin|)`` (its patch turned by ``direction_deg``: up to ``radius
sqrt 2`` at 45 deg). The scenario's domain checks (the height map's grid, a
sphere's or cylinder's chart) use :func:`path_extent`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CircleReference", "PathReference", "circle_reference", "path_reference", "path_extent", "PATHS"]

PATHS = ("circle", "line", "raster")
"""The path kinds (``trajectory.path``)."""


@dataclass(frozen=True, eq=False)
class PathReference:
    """Tangential reference samples, each of shape (2, N): task axes 1 and 2."""
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


CircleReference = PathReference
"""The circle's reference (the name of earlier versions)."""


def circle_reference(t, radius: float, period: float) -> PathReference:
    """Circle ``radius (cos wt, sin wt)`` with ``w = 2 pi / period``."""
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi / period
    c, s = np.cos(w * t), np.sin(w * t)
    pos = radius * np.vstack([c, s])
    vel = radius * w * np.vstack([-s, c])
    acc = -radius * w ** 2 * np.vstack([c, s])
    return PathReference(t, pos, vel, acc)


def _harmonic(t, amplitude: float, w: float, phase: float = 0.0):
    """``amplitude sin(w t + phase)`` and its first two derivatives."""
    a = w * t + phase
    return amplitude * np.sin(a), amplitude * w * np.cos(a), -amplitude * w * w * np.sin(a)


def path_reference(t, trajectory) -> PathReference:
    """The reference of ``trajectory`` (the scenario's ``[trajectory]``
    section: ``path``, ``radius``, ``period``, ``lanes``, ``direction_deg``)
    at times ``t`` (s)."""
    kind = getattr(trajectory, "path", "circle")
    if kind == "circle":
        return circle_reference(t, trajectory.radius, trajectory.period)
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi / trajectory.period
    r = trajectory.radius
    th = np.radians(trajectory.direction_deg)
    d, d_perp = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
    if kind == "line":
        along = _harmonic(t, r, w)
        across = (np.zeros_like(t),) * 3
    elif kind == "raster":
        along = _harmonic(t, r, trajectory.lanes * w / 2)
        across = _harmonic(t, -r, w, np.pi / 2)                 # -r cos(wt): from one edge across and back
    else:
        raise ValueError(f"trajectory.path: expected one of {', '.join(PATHS)}, got {kind!r}")
    pos, vel, acc = (np.outer(d, a) + np.outer(d_perp, b) for a, b in zip(along, across))
    return PathReference(t, pos, vel, acc)


def path_extent(trajectory) -> tuple[float, float]:
    """How far the path of ``trajectory`` reaches from its centre along task
    axes 1 and 2 (m): ``max |pos_i(t)|`` over one period of
    :func:`path_reference`. Closed forms for the circle (``radius`` along
    both) and the line (``radius |cos|``, ``radius |sin|`` of
    ``direction_deg``); the raster's two harmonics have none, so it is its
    own position sampled over a period (at least 64 samples per pass), each
    local maximum of ``|pos_i|`` then refined by Newton's method on ``vel_i
    = 0`` (the path's analytic velocity and acceleration), kept within a
    sample of it: exact to rounding (tests/test_curved_refusals.py checks it
    against 2 million samples)."""
    kind = getattr(trajectory, "path", "circle")
    r = float(trajectory.radius)
    if kind == "circle" or r == 0.0:
        return r, r
    th = np.radians(trajectory.direction_deg)
    if kind == "line":
        return r * abs(float(np.cos(th))), r * abs(float(np.sin(th)))
    T = float(trajectory.period)
    n = 64 * int(getattr(trajectory, "lanes", 2)) + 256
    t = np.linspace(0.0, T, n, endpoint=False)
    dt = T / n
    pos = np.abs(path_reference(t, trajectory).pos)
    out = []
    for i in range(2):
        a = pos[i]
        peaks = np.flatnonzero((a >= np.roll(a, 1)) & (a >= np.roll(a, -1)))
        tk = t[peaks]
        lo, hi = tk - dt, tk + dt
        for _ in range(8):                    # Newton on vel_i = 0, kept within a sample of the peak
            ref = path_reference(tk, trajectory)
            acc = ref.acc[i]
            step = np.divide(ref.vel[i], acc, out=np.zeros_like(tk), where=np.abs(acc) > 0)
            tk = np.clip(tk - step, lo, hi)
        refined = np.abs(path_reference(tk, trajectory).pos[i])
        out.append(float(max(a.max(), refined.max(initial=0.0))))
    return out[0], out[1]
