"""Reference paths: the circle on the tilted plane of Fig. 2.

The circle lies in the plane (task axes 1 and 2), centred at the task-frame
origin, traversed once per ``period`` at constant angular rate. Positions in m,
velocities in m/s, accelerations in m/s^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CircleReference", "circle_reference"]


@dataclass(frozen=True)
class CircleReference:
    """Tangential reference samples, each of shape (2, N): task axes 1 and 2."""
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


def circle_reference(t, radius: float, period: float) -> CircleReference:
    """Circle ``radius (cos wt, sin wt)`` with ``w = 2 pi / period``."""
    t = np.asarray(t, dtype=float)
    w = 2 * np.pi / period
    c, s = np.cos(w * t), np.sin(w * t)
    pos = radius * np.vstack([c, s])
    vel = radius * w * np.vstack([-s, c])
    acc = -radius * w ** 2 * np.vstack([c, s])
    return CircleReference(t, pos, vel, acc)
