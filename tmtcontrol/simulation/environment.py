"""Environment: stiffness profiles k_e(t) such as Fig. 3 (the surface's shapes and
their contact law are :mod:`tmtcontrol.surface`; ``task_frame`` and
``contact_force`` are re-exported from there).

Task frame: origin at the circle centre on the plane; axis 0 ("normal") points
*into* the surface, so that the normal coordinate x grows with penetration and
the contact law reads, as in section III, ``f_e = k_e (x - x_e)`` with
``x_e = 0`` the surface; axes 1 and 2 span the plane.
"""

from __future__ import annotations

import numpy as np

from ..surface import contact_force
from ..surface import tilt_frame as task_frame
from .scenario import read_stiffness_table

__all__ = ["task_frame", "contact_force", "stiffness_samples"]


def stiffness_samples(profile, t: np.ndarray, default_segment: float) -> np.ndarray:
    """k_e at times ``t`` (N/m). ``default_segment`` (s) is the piecewise-constant
    segment length when the profile does not set one (the trajectory period)."""
    t = np.asarray(t, dtype=float)
    if profile.kind == "piecewise_constant":
        seg = profile.segment or default_segment
        idx = np.minimum(np.floor(t / seg + 1e-9).astype(int), len(profile.values) - 1)
        return np.asarray(profile.values, dtype=float)[idx]
    if profile.kind == "piecewise_linear":
        return np.interp(t, profile.times, profile.values)
    if profile.kind == "sinusoidal":
        return profile.mean + profile.amplitude * np.sin(2 * np.pi * t / profile.period)
    tt, kk = read_stiffness_table(profile.file)
    return np.interp(t, tt, kk)
