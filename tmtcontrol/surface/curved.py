"""Curved surfaces: the sphere and the cylinder, each on a chart whose origin is the path's centre.

A curved part (a pipe, a tank, a bowl) is given by its tangent plane at the
path's centre ``c`` (the same inward normal ``e_n`` and task frame ``R =
[e_n, t_1, t_2]`` as a :class:`.plane.Plane` there), its radius ``r`` (m)
and the side the tool works on: ``outside`` (a convex part: the centre of
curvature lies inside the material, ``c + r e_n``) or ``inside`` (a bowl or
the bore of a pipe: the centre lies above the surface, ``c - r e_n``).

Task coordinates ``X = (X_0, s_1, s_2)``: ``X_0`` the penetration depth
along the local inward normal (``r - |p - centre|`` outside, ``|p - centre|
- r`` inside: the signed distance to the closest surface point, so the
contact law of section III, eq. (13), ``f_e = k_e (X_0 - x_e)``, holds at the
closest point exactly); ``s_1``, ``s_2`` arc lengths on the surface from the
path's centre:

* sphere: ``s_1 = r theta`` (longitude about ``t_2``), ``s_2 = r phi``
  (latitude towards ``t_2``); the chart is regular for ``|phi| < pi/2``;
* cylinder (axis along ``t_2``): ``s_1 = r theta`` round the axis, ``s_2``
  the distance along the axis.

The task frame at a point is ``[e_n, e_1, e_2]``, e_n the local inward
normal and e_1, e_2 the unit tangents of the coordinate lines; at the path's
centre it is the tangent plane's R. A path given in tangential coordinates
(the circle of Fig. 2) is therefore wrapped onto the surface: its arc
lengths are kept along the coordinate lines. The inner loop acts on these
coordinates; :meth:`.base.Surface.acceleration` adds the curvature terms
(``d/dt (dp/dX) dX``) so that eq. (6) still gives ``ddX = U`` exactly with
an exact model, and the 6-D task's commanded orientation turns with the
frame (:meth:`.base.Surface.turn`), with its angular velocity and
acceleration fed forward.
"""

from __future__ import annotations

import math
import numbers

import casadi as ca
import numpy as np

from .base import Surface, checked_frame, orthonormal

__all__ = ["Sphere", "Cylinder", "SIDES"]

SIDES = {"outside": 1.0, "inside": -1.0}
"""The side the tool works on, and its sign in the loop's parameter ``side``."""


class _Curved(Surface):
    """A shape of constant radius on the chart of the module docstring.

    Parameters in the loop: ``R`` (9, column-major, the tangent plane's
    frame at the path's centre), ``c`` (3, m, the path's centre),
    ``radius`` (m) and ``side`` (+1 outside, -1 inside).
    """

    fields = (("R", 9), ("c", 3), ("radius", 1), ("side", 1))
    turns = True

    def __init__(self, R, c, radius: float, side: str = "outside"):
        self.R, self.c = checked_frame(self.kind, R, c)
        if not (isinstance(radius, numbers.Real) and math.isfinite(radius) and radius > 0):
            raise ValueError(f"radius: a {self.kind} needs a radius, finite and > 0 (m), got {radius!r}")
        if side not in SIDES:
            raise ValueError(f"side: expected 'outside' or 'inside', got {side!r}")
        self.radius, self.side = float(radius), side

    # -- what a shape states -----------------------------------------------------------------
    @staticmethod
    def _axes(par):
        """``(a, t1, t2, u0, centre, r, sigma)`` from the parameters: the
        frame's columns, the unit vector from the centre of curvature to the
        path's centre, the centre of curvature (for a cylinder a point of
        the axis), the radius and the side's sign."""
        F0 = ca.reshape(par["R"], 3, 3)
        a, t1, t2 = F0[:, 0], F0[:, 1], F0[:, 2]
        r, sigma = par["radius"], par["side"]
        return a, t1, t2, -sigma * a, par["c"] + sigma * r * a, r, sigma

    @staticmethod
    def _coords(p, par):
        """Symbolic task coordinates (3) of the base-frame point ``p``."""
        raise NotImplementedError

    @staticmethod
    def _local(p, par):
        """``(x, y, z, q_a, r, sigma)``: ``p`` from the centre of curvature
        along ``u0``, ``t1`` and ``t2``, its offset from the path's centre
        along the normal ``q_a = (p - c).a``, the radius and the side's
        sign. Taken from ``q = p - c`` (``x = r - sigma q_a``): the point
        minus a far centre would carry r eps of rounding into y and z."""
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        q = p - par["c"]
        q_a = ca.dot(q, a)
        return r - sigma * q_a, ca.dot(q, t1), ca.dot(q, t2), q_a, r, sigma

    @staticmethod
    def _depth(q_a, d2, dist, r, sigma):
        """The depth ``sigma (r - dist)`` (``dist`` the distance from the
        centre of curvature, or from the axis) without subtracting two
        numbers near r: ``r^2 - dist^2 = sigma q_a (2 r - sigma q_a) - d2``
        (``d2`` the squared distance across the normal line: y^2 + z^2 on
        a sphere, y^2 on a cylinder). Review 12: on a sphere of radius 1e7 m
        the subtraction left 1e-9 m of noise in the depth, the periodic orbit
        did not converge and its limit read 25 % low."""
        return (q_a * (2 * r - sigma * q_a) - sigma * d2) / (r + dist)

    @staticmethod
    def _frame(X, par):
        """Symbolic task frame (3 x 3) at task coordinates ``X``."""
        raise NotImplementedError

    def _frame_at(self, p, X, par):
        """Symbolic task frame at the point ``p`` (coordinates ``X``): by
        default :meth:`_frame` of X; a shape may state it from p directly
        (fewer operations in the plant, which needs only the normal)."""
        return self._frame(X, par)

    # -- the interface, derived once -------------------------------------------------------
    def _fn(self, name: str) -> ca.Function:
        def build():
            par = {n: ca.SX.sym(n, k) for n, k in self.fields}
            p, v, X, dX, ddX = (ca.SX.sym(k, 3) for k in ("p", "v", "X", "dX", "ddX"))
            if name == "coordinates":
                Xp = self._coords(p, par)
                return ca.Function(f"{self.kind}_coordinates", [p, v, *par.values()],
                                   [self._frame_at(p, Xp, par), Xp, ca.jtimes(Xp, p, v)], ["p", "v", *par],
                                   ["R_task", "X", "dX"])
            if name == "point":
                return ca.Function(f"{self.kind}_point", [X, *par.values()], [self.point(X, par)], ["X", *par], ["p"])
            # turn: from the frame at the chart's origin (a height map's is tilted by its slope there)
            Rt = ca.mtimes(self._frame(X, par), self._frame(ca.DM.zeros(3), par).T)
            dRt = ca.reshape(ca.jtimes(ca.vec(Rt), X, dX), 3, 3)
            W = ca.mtimes(dRt, Rt.T)                                                   # skew(omega)
            w = ca.vertcat(W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]) / 2
            alpha = ca.jtimes(w, X, dX) + ca.jtimes(w, dX, ddX)
            return ca.Function(f"{self.kind}_turn", [X, dX, ddX, *par.values()], [Rt, w, alpha],
                               ["X", "dX", "ddX", *par], ["R_t", "omega", "alpha"])
        return self._cached(name, build)

    def coordinates(self, p, v, par: dict):
        R, X, dX = self._fn("coordinates")(p, v, *self._par(par))
        return R, X, dX

    def turn(self, X, dX, ddX, par: dict):
        return tuple(self._fn("turn")(X, dX, ddX, *self._par(par)))

    # -- numeric -------------------------------------------------------------------------------
    def values(self) -> dict[str, np.ndarray]:
        return {"R": self.R.ravel(order="F"), "c": self.c.copy(), "radius": np.array([self.radius]),
                "side": np.array([SIDES[self.side]])}

    def _vals(self) -> list:
        return list(self.values().values())

    def to_base(self, X) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        flat = X.reshape(3, -1)
        if type(self)._point_np is not _Curved._point_np:        # the shape's NumPy form (many points: the logs)
            return self._point_np(flat).reshape(X.shape)
        out = np.array(self._fn("point").map(flat.shape[1])(flat, *self._vals()))
        return out.reshape(X.shape)

    def _point_np(self, X):
        """:meth:`point` in NumPy for 3 x k coordinates (a shape may state it;
        tests/test_surfaces.py checks it against the symbolic chart)."""
        raise NotImplementedError

    def from_base(self, p) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        flat = p.reshape(3, -1)
        f = self._fn("coordinates").map(flat.shape[1])
        out = np.array(f(flat, np.zeros_like(flat), *self._vals())[1])
        return out.reshape(p.shape)

    def frame(self, point=None) -> np.ndarray:
        if point is None:
            return self.R.copy()
        p = np.asarray(point, dtype=float).reshape(3)
        R = np.array(self._fn("coordinates")(p, np.zeros(3), *self._vals())[0])
        # at the centre of curvature (or on the axis) the normal is 0/0: NaN, or rounding's arbitrary vectors
        if np.all(np.isfinite(p)) and not orthonormal(R):
            raise ValueError(f"{self.kind}: no task frame at {p.tolist()} (the centre of curvature or the axis)")
        return R

    def rates(self, X, dX) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(v, omega)``: the base-frame velocity (m/s) and the task
        frame's angular velocity (rad/s) of coordinates ``X`` moving at ``dX``."""
        v = self._motion()(X, dX, np.zeros(3), *self._vals())[0]
        w = self._fn("turn")(X, dX, np.zeros(3), *self._vals())[1]
        return np.array(v).ravel(), np.array(w).ravel()

    def concave_radius(self, s) -> np.ndarray:
        """:meth:`.base.Surface.concave_radius`: ``radius`` everywhere on the
        inside (a bowl, a bore), ``inf`` on the outside (convex)."""
        k = np.asarray(s, dtype=float).reshape(2, -1).shape[1]
        return np.full(k, self.radius if self.side == "inside" else np.inf)

    def depth_limit(self) -> float:
        """:meth:`.base.Surface.depth_limit`: the radius on the outside (the
        centre of curvature lies ``r`` deep), ``inf`` on the inside."""
        return self.radius if self.side == "outside" else math.inf

    def shifted(self, offset: float):
        return type(self)(self.R, self.c + offset * self.R[:, 0], self.radius, self.side)

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(normal={np.round(self.R[:, 0], 6).tolist()}, c={self.c.tolist()}, "
                f"radius={self.radius!r}, side={self.side!r})")


class Sphere(_Curved):
    """A sphere of radius ``radius`` (m) touching the tangent plane ``(R, c)``
    at ``c``; the tool on its ``side`` (``outside``: a dome, ``inside``: a bowl)."""

    kind = "sphere"

    @property
    def noun(self) -> str:
        """What the part is called in figures and reports: a dome from outside, a bowl from inside
        (review 28: "sphere" for the Panda's bowl)."""
        return "dome" if self.side == "outside" else "bowl"

    def primitive(self):
        """:meth:`Surface.primitive`: the solid when the tool works on its outside, else None (no solid)."""
        if self.side != "outside":
            return None
        return self.kind, self.c + self.radius * self.R[:, 0], self.R, self.radius

    @staticmethod
    def _coords(p, par):
        x, y, z, q_a, r, sigma = _Curved._local(p, par)
        rho = ca.sqrt(x * x + y * y)
        depth = _Curved._depth(q_a, y * y + z * z, ca.sqrt(rho * rho + z * z), r, sigma)
        return ca.vertcat(depth, r * ca.atan2(y, x), r * ca.atan2(z, rho))

    @staticmethod
    def _unit(X, par):
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        th, ph = X[1] / r, X[2] / r
        return ca.cos(ph) * (ca.cos(th) * u0 + ca.sin(th) * t1) + ca.sin(ph) * t2

    @staticmethod
    def point(X, par):
        # centre + (r - sigma X_0) u, written from c: along the normal a,
        # sigma r (1 - cos(ph) cos(th)) + X_0 cos(ph) cos(th), with 1 - cos(ph) cos(th) =
        # 2 sin^2(ph/2) + 2 cos(ph) sin^2(th/2) (no difference of numbers near r)
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        th, ph = X[1] / r, X[2] / r
        cc, one_minus = ca.cos(ph) * ca.cos(th), 2 * ca.sin(ph / 2) ** 2 + 2 * ca.cos(ph) * ca.sin(th / 2) ** 2
        return (par["c"] + (sigma * r * one_minus + X[0] * cc) * a
                + (r - sigma * X[0]) * (ca.cos(ph) * ca.sin(th) * t1 + ca.sin(ph) * t2))

    def _point_np(self, X):
        a, t1, t2 = (self.R[:, i, None] for i in range(3))
        r, sigma = self.radius, SIDES[self.side]
        th, ph = X[1] / r, X[2] / r
        cc, one_minus = np.cos(ph) * np.cos(th), 2 * np.sin(ph / 2) ** 2 + 2 * np.cos(ph) * np.sin(th / 2) ** 2
        return (self.c[:, None] + (sigma * r * one_minus + X[0] * cc) * a
                + (r - sigma * X[0]) * (np.cos(ph) * np.sin(th) * t1 + np.sin(ph) * t2))

    def _frame_at(self, p, X, par):
        # the same frame as _frame(X), from the radial direction u without trigonometry:
        # e_1 = -sigma (t2 x u)/|t2 x u| (the longitude's tangent), e_2 = e_n x e_1
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        w = p - centre
        u = w / ca.norm_2(w)
        e_n = -sigma * u
        c = ca.cross(t2, u)
        e_1 = -sigma * c / ca.norm_2(c)
        return ca.horzcat(e_n, e_1, ca.cross(e_n, e_1))

    @staticmethod
    def _frame(X, par):
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        th, ph = X[1] / r, X[2] / r
        e_1 = -ca.sin(th) * u0 + ca.cos(th) * t1
        e_2 = -ca.sin(ph) * (ca.cos(th) * u0 + ca.sin(th) * t1) + ca.cos(ph) * t2
        return ca.horzcat(-sigma * Sphere._unit(X, par), e_1, e_2)


class Cylinder(_Curved):
    """A cylinder of radius ``radius`` (m) touching the tangent plane ``(R,
    c)`` along the line through ``c`` in the direction of the frame's third
    column ``t_2`` (its axis); the tool on its ``side`` (``outside``: a pipe's
    or shaft's surface, ``inside``: a bore)."""

    kind = "cylinder"

    @property
    def noun(self) -> str:
        """A pipe or shaft from outside, a bore from inside."""
        return "cylinder" if self.side == "outside" else "bore"

    def primitive(self):
        """:meth:`Surface.primitive`: the solid when the tool works on its outside, else None (no solid)."""
        if self.side != "outside":
            return None
        return self.kind, self.c + self.radius * self.R[:, 0], self.R, self.radius

    @staticmethod
    def _coords(p, par):
        x, y, z, q_a, r, sigma = _Curved._local(p, par)
        return ca.vertcat(_Curved._depth(q_a, y * y, ca.sqrt(x * x + y * y), r, sigma), r * ca.atan2(y, x), z)

    @staticmethod
    def point(X, par):
        # centre + (r - sigma X_0) u + X_2 t2 written from c, as the sphere's: 1 - cos(th) = 2 sin^2(th/2)
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        th = X[1] / r
        return (par["c"] + (2 * sigma * r * ca.sin(th / 2) ** 2 + X[0] * ca.cos(th)) * a
                + (r - sigma * X[0]) * ca.sin(th) * t1 + X[2] * t2)

    def _point_np(self, X):
        a, t1, t2 = (self.R[:, i, None] for i in range(3))
        r, sigma = self.radius, SIDES[self.side]
        th = X[1] / r
        return (self.c[:, None] + (2 * sigma * r * np.sin(th / 2) ** 2 + X[0] * np.cos(th)) * a
                + (r - sigma * X[0]) * np.sin(th) * t1 + X[2] * t2)

    def _frame_at(self, p, X, par):
        # from the radial direction u without trigonometry: e_1 = -sigma t2 x u, e_2 = t2
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        w = p - centre
        w_r = w - ca.dot(w, t2) * t2
        u = w_r / ca.norm_2(w_r)
        return ca.horzcat(-sigma * u, -sigma * ca.cross(t2, u), t2)

    @staticmethod
    def _frame(X, par):
        a, t1, t2, u0, centre, r, sigma = _Curved._axes(par)
        th = X[1] / r
        u = ca.cos(th) * u0 + ca.sin(th) * t1
        return ca.horzcat(-sigma * u, -ca.sin(th) * u0 + ca.cos(th) * t1, t2)
