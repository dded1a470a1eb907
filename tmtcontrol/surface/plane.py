"""The plane: the paper's tilted surface (Fig. 2) or any plane given by its inward normal.

Task frame (base-frame columns, normal axis first): ``e_n`` the plane's
*inward* unit normal, ``e_1`` base y projected onto the plane (base x when
the normal is nearly along y), ``e_2 = e_n x e_1``; its origin ``c`` is a
point of the plane (the circle's centre). The tilt shorthand (the outward
normal is base z turned by ``tilt`` about base y) gives ``e_n = (sin t, 0,
-cos t)``, ``e_1 = y``: :func:`tilt_frame`. Task coordinates are
``X = R^T (p - c)``, the normal coordinate the penetration depth.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from .base import Surface, checked_frame

__all__ = ["Plane", "tilt_frame", "normal_frame"]


def tilt_frame(tilt_deg: float) -> np.ndarray:
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


def normal_frame(normal) -> np.ndarray:
    """The task frame of the module docstring for the inward ``normal``
    (normalised here); ``ValueError`` unless it is 3 finite numbers, not all
    zero (review 58: [0, 0, 0] printed a NumPy warning and a frame of NaN, a
    4-vector failed in matmul)."""
    e_n = np.asarray(normal, dtype=float)
    norm = np.linalg.norm(e_n) if e_n.shape == (3,) else 0.0
    if not (e_n.shape == (3,) and np.all(np.isfinite(e_n)) and norm > 0):
        raise ValueError(f"normal: expected 3 finite numbers, not all zero, got {np.asarray(normal).tolist()!r}")
    e_n = e_n / norm
    ref = np.array([0.0, 1.0, 0.0]) if abs(e_n[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e_1 = ref - (ref @ e_n) * e_n
    e_1 /= np.linalg.norm(e_1)
    return np.column_stack([e_n, e_1, np.cross(e_n, e_1)])


class Plane(Surface):
    """A plane through ``c`` (m) with task frame ``R`` (columns: inward normal, tangents).

    Parameters in the loop: ``R`` (9, column-major) and ``c`` (3, m).
    """

    kind = "plane"
    noun = "tilted plane"
    fields = (("R", 9), ("c", 3))

    def primitive(self):
        """``("plane", c, R, None)``: :meth:`Surface.primitive`."""
        return "plane", self.c, self.R, None

    def __init__(self, R, c):
        self.R, self.c = checked_frame(self.kind, R, c)

    @classmethod
    def from_tilt(cls, tilt_deg: float, c) -> "Plane":
        """The paper's plane, tilted ``tilt_deg`` about base y, through ``c``."""
        return cls(tilt_frame(tilt_deg), c)

    @classmethod
    def from_normal(cls, normal, c) -> "Plane":
        """The plane of inward ``normal`` through ``c``."""
        return cls(normal_frame(normal), c)

    def values(self) -> dict[str, np.ndarray]:
        return {"R": self.R.ravel(order="F"), "c": self.c.copy()}

    @staticmethod
    def coordinates(p, v, par: dict):
        R = ca.reshape(par["R"], 3, 3)
        return R, ca.mtimes(R.T, p - par["c"]), ca.mtimes(R.T, v)

    @staticmethod
    def point(X, par: dict):
        return ca.mtimes(ca.reshape(par["R"], 3, 3), X) + par["c"]

    @staticmethod
    def velocity(X, dX, par: dict):
        return ca.mtimes(ca.reshape(par["R"], 3, 3), dX)

    @staticmethod
    def acceleration(X, dX, ddX, par: dict):
        return ca.mtimes(ca.reshape(par["R"], 3, 3), ddX)

    @staticmethod
    def turn(X, dX, ddX, par: dict):
        return None                         # a plane's frame does not turn

    def rates(self, X, dX) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(v, omega)``: base-frame velocity (m/s) of coordinates
        moving at ``dX``; the frame does not turn (omega = 0)."""
        return self.R @ np.asarray(dX, dtype=float), np.zeros(3)

    def frame(self, point=None) -> np.ndarray:
        return self.R.copy()

    def to_base(self, X) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if X.ndim > 2:                      # a grid of points (3, a, b, ...)
            return self.to_base(X.reshape(3, -1)).reshape(X.shape)
        return (self.c[:, None] if X.ndim == 2 else self.c) + self.R @ X

    def from_base(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        return self.R.T @ (p - (self.c[:, None] if p.ndim == 2 else self.c))

    def shifted(self, offset: float) -> "Plane":
        return Plane(self.R, self.c + offset * self.R[:, 0])

    def __repr__(self) -> str:
        return f"Plane(normal={np.round(self.R[:, 0], 6).tolist()}, c={self.c.tolist()})"
