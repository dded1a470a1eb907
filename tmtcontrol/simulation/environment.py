"""Environment: the tilted plane of Fig. 2, its unilateral spring contact, and
stiffness profiles k_e(t) such as Fig. 3.

Task frame: origin at the circle centre on the plane; axis 0 ("normal") points
*into* the surface, so that the normal coordinate x grows with penetration and
the contact law reads, as in section III, ``f_e = k_e (x - x_e)`` with
``x_e = 0`` the surface; axes 1 and 2 span the plane.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .scenario import read_stiffness_table

__all__ = ["task_frame", "contact_force", "stiffness_samples"]


def task_frame(tilt_deg: float) -> np.ndarray:
    """Rotation R (3x3) whose columns are the task axes in the base frame.

    The plane's outward normal is base z rotated by ``tilt_deg`` about base y:
    ``n_out = (-sin t, 0, cos t)``. Columns: ``e_n = -n_out`` (into the
    surface), ``e_1 = y`` (along the plane, horizontal), ``e_2 = e_n x e_1``.
    """
    t = math.radians(tilt_deg)
    e_n = np.array([math.sin(t), 0.0, -math.cos(t)])
    e_1 = np.array([0.0, 1.0, 0.0])
    e_2 = np.cross(e_n, e_1)
    return np.column_stack([e_n, e_1, e_2])


def contact_force(x, dx, k_e, damping, x_e=0.0):
    """Unilateral spring(-damper) normal force, N (section III, eq. 13).

    ``f_e = max(0, k_e (x - x_e) + damping dx)`` while ``x > x_e``, else 0.
    Works on floats, NumPy arrays and CasADi symbols.
    """
    pen = x - x_e
    f = k_e * pen + damping * dx
    if isinstance(pen, (ca.SX, ca.MX, ca.DM)):
        return ca.if_else(pen > 0, ca.fmax(f, 0), 0)
    return np.where(pen > 0, np.maximum(f, 0.0), 0.0)


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
