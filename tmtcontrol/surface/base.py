"""The surface interface (what every shape provides) and the contact force law (section III, eq. 13).

Conventions (SI): the task frame's columns are the inward unit normal
``e_n`` (pointing *into* the surface) and two tangential axes; the task
coordinate along ``e_n`` is the penetration depth, positive inside the
surface, so ``x - x_e`` of eqs. (13)-(18) is that coordinate minus the
controller's belief of where the surface is.
"""

from __future__ import annotations

import abc
import math

import casadi as ca
import numpy as np

__all__ = ["Surface", "contact_force", "checked_frame"]


def contact_force(x, dx, k_e, damping, x_e=0.0):
    """Unilateral spring(-damper) normal force, N (section III, eq. 13).

    ``f_e = max(0, k_e (x - x_e) + damping dx)`` while ``x > x_e``, else 0:
    ``x`` the penetration depth (m), ``dx`` its rate (m/s), ``k_e`` the
    stiffness (N/m), ``damping`` the contact damping (N s/m). Works on
    floats, NumPy arrays and CasADi symbols.
    """
    pen = x - x_e
    f = k_e * pen + damping * dx
    if isinstance(pen, (ca.SX, ca.MX, ca.DM)):
        return ca.if_else(pen > 0, ca.fmax(f, 0), 0)
    try:
        ok = k_e >= 0 and damping >= 0          # numbers (a plant's every step): no array built; NaN fails
    except ValueError:                          # arrays
        ok = bool(np.all(np.asarray(k_e) >= 0) and np.all(np.asarray(damping) >= 0))
    if not ok:
        name, value = ("k_e", k_e) if not np.all(np.asarray(k_e) >= 0) else ("damping", damping)
        raise ValueError(f"{name}: must be finite and >= 0 (N/m, N s/m), got {value!r}")
    # a NaN depth or rate (a diverged state) gives NaN, never "no contact"
    return np.where(pen > 0, np.maximum(f, 0.0), np.where(np.isnan(f), np.nan, 0.0))


def orthonormal(R) -> bool:
    """Whether the 3 x 3 ``R`` is finite with orthonormal columns (to 1e-9)."""
    return bool(np.all(np.isfinite(R)) and np.allclose(R.T @ R, np.eye(3), atol=1e-9))


def checked_frame(kind: str, R, c) -> tuple[np.ndarray, np.ndarray]:
    """``(R, c)`` as read-only arrays (a surface is shared: geometry.surface_of
    builds each once), refused in one line naming ``kind`` unless R is a
    finite right-handed rotation (columns: inward normal, tangents; a
    left-handed frame would flip the cross products that build the frame
    along a curved part and the 6-D task's orientation) and ``c`` a finite
    point (m)."""
    R = np.array(R, dtype=float).reshape(3, 3)
    c = np.array(c, dtype=float).reshape(3)
    if not (orthonormal(R) and np.linalg.det(R) > 0):
        raise ValueError(f"{kind}: the task frame must be a finite right-handed rotation matrix")
    if not np.all(np.isfinite(c)):
        raise ValueError(f"{kind}: the point c must be finite, got {c.tolist()}")
    for a in (R, c):
        a.setflags(write=False)
    return R, c


class Surface(abc.ABC):
    """A contact surface.

    Attributes
    ----------
    kind : str
        The shape's name (part of the compiled loop's structure).
    turns : bool
        Whether the task frame turns from point to point (then the 6-D
        task's commanded orientation turns with it, :meth:`turn`).
    fields : tuple of (str, int)
        The shape's parameters as named fields of the closed loop's parameter
        vector (and of the exported controller's parameter struct), in order.
    """

    kind: str = ""
    fields: tuple[tuple[str, int], ...] = ()
    turns: bool = False
    """Whether the task frame turns along the surface (a curved shape)."""
    noun: str = "surface"
    """What the shape is called in figures and reports."""
    step_cost: float = 0.0
    """What the shape adds to a loop step's time, in units of a 3-joint
    arm's step on a plane (the sweep's estimate: ``Sweep.estimate_seconds``);
    0 for a shape whose chart costs a few operations."""
    analysis_cost: float = 0.0
    """Likewise for a scenario's limit analysis (``stability.limit``)."""
    exact_chart: bool = True
    """Whether the chart's depth and normal are the part's own at every depth
    (a plane, a sphere, a cylinder); False where :meth:`chart_error` computes
    how far they are (a measured map)."""

    @abc.abstractmethod
    def values(self) -> dict[str, np.ndarray]:
        """The numeric value of each of :attr:`fields`."""

    @abc.abstractmethod
    def coordinates(self, p, v, par: dict):
        """Symbolic (CasADi): ``(R, X, dX)`` at the tool point ``p`` (m, base
        frame) moving at ``v`` (m/s): the task frame R (3 x 3, columns inward
        normal, tangent 1, tangent 2), the task coordinates X (m; X[0] the
        penetration depth) and their rates dX (m/s). ``par`` maps each of
        :attr:`fields` to its symbols."""

    @abc.abstractmethod
    def point(self, X, par: dict):
        """Symbolic (CasADi): the base-frame point (m) of task coordinates
        ``X`` near the path (the commanded tool point of eq. 4)."""

    @abc.abstractmethod
    def frame(self, point=None) -> np.ndarray:
        """The task frame (3 x 3, base frame) at ``point`` (m)."""

    def normal(self, point=None) -> np.ndarray:
        """The inward unit normal at ``point``."""
        return self.frame(point)[:, 0]

    @abc.abstractmethod
    def to_base(self, X) -> np.ndarray:
        """Base-frame points (m, 3 x k) of task coordinates ``X`` (3 x k)."""

    @abc.abstractmethod
    def from_base(self, p) -> np.ndarray:
        """Task coordinates (3 x k) of base-frame points ``p`` (3 x k, m)."""

    def signed_distance(self, p) -> np.ndarray:
        """Penetration depth (m) of base-frame points ``p`` (3 x k): positive
        inside the surface, negative above it."""
        return np.asarray(self.from_base(np.asarray(p, dtype=float).reshape(3, -1)))[0]

    @abc.abstractmethod
    def shifted(self, offset: float) -> "Surface":
        """The same shape moved ``offset`` (m) along its inward normal (the
        surface the controller believes in with a location error)."""

    @property
    def key(self) -> str:
        """What identifies the shape's compiled expressions: its kind, and
        for a shape with data baked into them (a height map) the data."""
        return self.kind

    # -- the chart's motion (symbolic): what the inner loop and the command need ------------
    def velocity(self, X, dX, par: dict):
        """Symbolic: the base-frame velocity (m/s) of task coordinates ``X``
        moving at ``dX``: ``(d point / d X) dX``."""
        return self._motion()(X, dX, ca.DM.zeros(3), *self._par(par))[0]

    def acceleration(self, X, dX, ddX, par: dict):
        """Symbolic: the base-frame acceleration (m/s^2) of task coordinates
        ``X`` moving at ``dX`` and accelerating at ``ddX``: ``(d point / d X)
        ddX + d/dt(d point / d X) dX`` (the curvature feed-forward; 0 on a
        plane). The inner loop (eq. 6) acts on the task coordinates and this
        maps its output to the Cartesian acceleration of eq. (5)."""
        return self._motion()(X, dX, ddX, *self._par(par))[1]

    def turn(self, X, dX, ddX, par: dict):
        """Symbolic: ``(R_t, omega, alpha)``: the rotation taking the task
        frame at the chart's origin (X = 0) to the task frame at ``X``, and
        its angular velocity (rad/s) and acceleration (rad/s^2) in the base
        frame while X moves at ``dX``, ``ddX``; None on a shape whose frame
        does not turn (a plane)."""
        return None

    def concave_radius(self, s) -> np.ndarray:
        """The smallest concave radius of curvature (m) at tangential
        coordinates ``s`` (2 x k, the task coordinates ``X[1:]`` a path is
        given in): over every tangent direction, the radius of the tightest
        circle along which the surface bends towards the tool (away from the
        material); ``inf`` where it bends towards the tool in no direction (a
        plane, a convex part). A spherical tool tip of radius rho touches the
        surface at one point only where this exceeds rho (else it rests on
        the rims of the hollow, not at the tool point). The default: nowhere
        concave."""
        return np.full(np.asarray(s, dtype=float).reshape(2, -1).shape[1], np.inf)

    def chart_error(self, X) -> tuple[np.ndarray, np.ndarray] | None:
        """An approximate chart's error at task coordinates ``X`` (3 x k):
        ``(depth, normal)``, how far the chart's depth X_0 (m) and its normal
        (rad) are from the distance to the part's closest point and that
        point's normal; None for a chart that is exact at every depth
        (:attr:`exact_chart`, the default: a plane, a sphere, a cylinder).
        The verdicts add them to the force and orientation errors
        (:func:`tmtcontrol.simulation.metrics.segment_metrics`)."""
        return None

    def depth_limit(self) -> float:
        """The depth X_0 (m) beyond which :meth:`point` has no point of its
        own: on the outside of a sphere or a cylinder its radius, where the
        chart reaches the centre of curvature (deeper, it comes out the far
        side); ``inf`` on a chart without one (the default)."""
        return math.inf

    def primitive(self):
        """The part as a solid primitive, for a physics engine or a renderer
        (MuJoCo's contact, its pictures): ``(kind, centre, R, radius)`` with
        ``kind`` ``"plane"`` (``centre`` a point on it), ``"sphere"`` or
        ``"cylinder"`` (``centre`` its centre, on the axis ``R[:, 2]``;
        ``radius`` m), ``R`` the task frame there (base frame), the material
        on the side the inward normal ``R[:, 0]`` points into; None for a part
        that no primitive is (the inside of a sphere or a cylinder, a measured
        height map)."""
        return None

    def _par(self, par: dict) -> list:
        return [par[name] for name, _ in self.fields]

    def _cached(self, name: str, build) -> ca.Function:
        """The shape's Function ``name``, built once per :attr:`key`."""
        k = (self.key, name)
        if k not in _FUNCTIONS:
            if len(_FUNCTIONS) > 64:
                _FUNCTIONS.clear()
            _FUNCTIONS[k] = build()
        return _FUNCTIONS[k]

    def _motion(self) -> ca.Function:
        """``(X, dX, ddX, *fields) -> (v, a)`` by automatic differentiation of
        :meth:`point`."""
        def build():
            X, dX, ddX = (ca.SX.sym(k, 3) for k in ("X", "dX", "ddX"))
            par = {name: ca.SX.sym(name, n) for name, n in self.fields}
            p = self.point(X, par)
            v = ca.jtimes(p, X, dX)
            a = ca.jtimes(p, X, ddX) + ca.jtimes(v, X, dX)
            return ca.Function(f"{self.kind}_motion", [X, dX, ddX, *par.values()], [v, a],
                               ["X", "dX", "ddX", *par], ["v", "a"])
        return self._cached("motion", build)


_FUNCTIONS: dict = {}
"""The shapes' CasADi Functions by (key, name)."""
