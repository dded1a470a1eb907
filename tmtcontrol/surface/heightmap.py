"""A measured free-form surface: a grid of heights over the tangent plane, smoothed by a cubic B-spline.

The part is given by heights ``h[i, j]`` (m) measured along the outward
normal over a rectangular grid in the tangent plane at the path's centre
``c`` (task frame ``R = [e_n, t_1, t_2]``): rows along ``t_1``, columns
along ``t_2``, spacing ``du``, ``dv`` (m), the grid centred on ``c``. The
surface is ``S(u, v) = c + u t_1 + v t_2 - h(u, v) e_n`` with ``h`` CasADi's
cubic B-spline ``interpolant`` through the grid, shifted so that ``h(0, 0)
= 0`` (the surface passes through the path's centre). The spline is part of
the closed loop's expressions (symbolic and compiled; the heights are baked
into the compiled step and the exported C, so another map is another
structure).

Task coordinates ``X = (X_0, u, v)``: ``u``, ``v`` the tool point's
coordinates in the tangent plane (the path is given in them: the circle is
projected onto the part along e_n), and the depth

    X_0 = ((p - c) . e_n + h(u, v)) / sqrt(1 + h_u^2 + h_v^2),

the height of the point below the surface, along e_n, times the cosine of
the surface's slope: the distance along the local normal to first order
(beyond the grid a point lies on the tangent plane of the nearest edge
point, with that point's normal: height and slope are continuous across
the edge, so a plant excursion past it meets neither a cliff nor a jump in
depth or force).
**Approximation:** it is exact on a plane and where the surface is flat over
the depth. It is taken at the point's own (u, v), its projection along e_n,
which lies X_0 s from the closest surface point's (s the slope): the error
is about ``X_0^2 kappa s^2 / 2`` (kappa the surface's curvature), 5e-9 m at
a millimetre's depth on a 1 m radius at slope 0.1, and the normal is off
the closest point's by about ``X_0 kappa s`` rad (:meth:`HeightMap.chart_error`
computes both along a run, and a segment within its tolerances in the chart
only is not ``converged``: ``simulation.metrics``). The contact
force is ``k_e X_0`` along the local inward normal ``n = (e_n + h_u t_1 +
h_v t_2) / sqrt(1 + h_u^2 + h_v^2)``. The task frame is ``[n, e_1, n x
e_1]``, e_1 the unit tangent ``S_u / |S_u|``.
"""

from __future__ import annotations

import hashlib

import casadi as ca
import numpy as np

from .base import Surface, checked_frame
from .curved import _Curved

__all__ = ["HeightMap", "MIN_POINTS", "MAX_POINTS"]

MIN_POINTS = 4
"""Fewest grid points along each axis (a cubic B-spline needs four)."""

MAX_POINTS = 256
"""Most grid points along each axis (the heights are constants of the compiled loop)."""

CLOSEST_SEEDS = 31
"""Seeds per axis of :meth:`HeightMap.chart_error`'s search for the closest point."""


def _splines(H: np.ndarray, u: np.ndarray, v: np.ndarray, du: float, dv: float):
    """The map's spline through the path's centre and its slope Function,
    built once per grid of heights and spacing (:data:`_SPLINES`):
    ``(heights, h, height_slope, digest)``, ``heights`` read-only.

    CasADi's B-spline ``interpolant`` solves for the coefficients of the
    whole grid when it is made: 1.1 s for a 256 x 256 grid. A sweep
    validates every case's scenario and each case builds its surface, all
    with the same heights: without this, a 64-value stiffness sweep over a
    256 x 256 map spent 136 s building the same splines before its first
    case. The shift through the centre is subtracted from the spline of
    the measured heights (the interpolating spline of ``H - s`` is that of
    ``H`` less ``s``: a cubic B-spline reproduces constants), not made by a
    second solve."""
    raw = hashlib.sha256(np.ascontiguousarray(H).tobytes() + np.array([du, dv, *H.shape], float).tobytes()).digest()
    if raw not in _SPLINES:
        spline = ca.interpolant("height", "bspline", [u, v], H.ravel(order="F"))
        shift = float(spline([0.0, 0.0]))                  # through the path's centre
        heights = H - shift
        heights.setflags(write=False)
        x = ca.SX.sym("x", 2)
        h_fn = ca.Function("height", [x], [spline(x) - shift], ["uv"], ["h"])
        h = h_fn(x)
        slope = ca.Function("height_slope", [x], [h, ca.jacobian(h, x)], ["uv"], ["h", "dh"])
        digest = hashlib.sha256(heights.tobytes() + np.array([du, dv, *H.shape], float).tobytes()).hexdigest()[:16]
        if len(_SPLINES) >= 8:
            _SPLINES.pop(next(iter(_SPLINES)))
        _SPLINES[raw] = (heights, h_fn, slope, digest)
    return _SPLINES[raw]


_SPLINES: dict = {}
"""The maps' splines by the digest of their heights and spacing, the oldest
dropped beyond 8 (the heights are in the digest, so a map is never served
another's spline)."""


class HeightMap(_Curved):
    """Heights ``heights`` (m, rows along t_1, columns along t_2) on a grid
    of ``spacing`` (m; one number or (du, dv)) centred on ``c`` in the
    tangent plane of frame ``R``."""

    kind = "heightmap"
    noun = "measured part"
    # CasADi's B-spline and its derivatives in every step (generic de Boor code): the PUMA's step and limit
    # analysis on a 61 x 61 dome's map beside its plane, benchmarks/bench_heightmap.py
    # (benchmarks/heightmap_results.json: 12.4x and 11.1x extra; tests/test_inputs_wave3.py checks them within 10 %)
    step_cost = 12.0
    analysis_cost = 11.0
    exact_chart = False
    fields = (("R", 9), ("c", 3))

    def __init__(self, R, c, heights, spacing):
        self.R, self.c = checked_frame(self.kind, R, c)
        H = np.array(heights, dtype=float)
        if H.ndim != 2:
            raise ValueError(f"heightmap: expected a 2-D grid of heights, got {H.ndim} dimension(s)")
        if min(H.shape) < MIN_POINTS or max(H.shape) > MAX_POINTS:
            raise ValueError(f"heightmap: the grid must have {MIN_POINTS} to {MAX_POINTS} points along each axis, "
                             f"got {H.shape[0]} x {H.shape[1]}")
        if not np.all(np.isfinite(H)):
            raise ValueError("heightmap: a height is not finite (NaN or inf)")
        du, dv = np.broadcast_to(np.asarray(spacing, dtype=float), (2,))
        if not (np.isfinite(du) and np.isfinite(dv) and du > 0 and dv > 0):
            raise ValueError(f"grid_spacing: must be finite and > 0, got {spacing!r}")
        self.u = (np.arange(H.shape[0]) - (H.shape[0] - 1) / 2) * du
        self.v = (np.arange(H.shape[1]) - (H.shape[1] - 1) / 2) * dv
        heights, self._h, self._hfn, digest = _splines(H, self.u, self.v, du, dv)
        # a read-only view of the shared grid: its WRITEABLE flag cannot be set again (review 48: the cached array
        # itself could be, and a change then reached every later map of the same grid)
        self.heights = heights.view()
        self.heights.setflags(write=False)
        self._key = f"heightmap-{digest}"
        self.spacing = (float(du), float(dv))

    @property
    def key(self) -> str:
        return self._key

    @property
    def half_extent(self) -> tuple[float, float]:
        """Half the grid's size along t_1 and t_2 (m)."""
        return float(self.u[-1]), float(self.v[-1])

    # -- the shape ----------------------------------------------------------------------------
    def _slope(self, u, v):
        """``(h, h_u, h_v)`` at (u, v), symbolic."""
        # beyond the grid: on the tangent plane of the nearest edge point (the spline itself drops to 0 there)
        uc = ca.fmin(ca.fmax(u, float(self.u[0])), float(self.u[-1]))
        vc = ca.fmin(ca.fmax(v, float(self.v[0])), float(self.v[-1]))
        h, g = self._hfn(ca.vertcat(uc, vc))
        return h + g[0] * (u - uc) + g[1] * (v - vc), g[0], g[1]

    def _coords(self, p, par):
        F0 = ca.reshape(par["R"], 3, 3)
        w = p - par["c"]
        u, v = ca.dot(w, F0[:, 1]), ca.dot(w, F0[:, 2])
        h, hu, hv = self._slope(u, v)
        return ca.vertcat((ca.dot(w, F0[:, 0]) + h) / ca.sqrt(1 + hu * hu + hv * hv), u, v)

    def point(self, X, par):
        F0 = ca.reshape(par["R"], 3, 3)
        h, hu, hv = self._slope(X[1], X[2])
        g = ca.sqrt(1 + hu * hu + hv * hv)
        return par["c"] + X[1] * F0[:, 1] + X[2] * F0[:, 2] + (X[0] * g - h) * F0[:, 0]

    def _frame(self, X, par):
        F0 = ca.reshape(par["R"], 3, 3)
        e_n, t1, t2 = F0[:, 0], F0[:, 1], F0[:, 2]
        _, hu, hv = self._slope(X[1], X[2])
        n = (e_n + hu * t1 + hv * t2) / ca.sqrt(1 + hu * hu + hv * hv)
        e_1 = (t1 - hu * e_n) / ca.sqrt(1 + hu * hu)
        return ca.horzcat(n, e_1, ca.cross(n, e_1))

    # -- numeric ------------------------------------------------------------------------------
    def values(self) -> dict[str, np.ndarray]:
        return {"R": self.R.ravel(order="F"), "c": self.c.copy()}

    def _point_np(self, X):
        h, hu, hv = self._slope_np(X[1], X[2])
        e_n, t1, t2 = self.R[:, 0], self.R[:, 1], self.R[:, 2]
        s = X[0] * np.sqrt(1 + hu * hu + hv * hv) - h
        return self.c[:, None] + np.outer(t1, X[1]) + np.outer(t2, X[2]) + np.outer(e_n, s)

    def _slope_np(self, u, v):
        """:meth:`_slope` in NumPy for arrays of (u, v)."""
        u, v = np.asarray(u, dtype=float).ravel(), np.asarray(v, dtype=float).ravel()
        uc, vc = np.clip(u, self.u[0], self.u[-1]), np.clip(v, self.v[0], self.v[-1])
        h, g = (np.array(m) for m in self._hfn(np.vstack([uc, vc])))   # every column at once: h (1 x k), dh (1 x 2k)
        hu, hv = g.ravel()[0::2], g.ravel()[1::2]
        return h.ravel() + hu * (u - uc) + hv * (v - vc), hu, hv

    def height(self, u, v) -> float:
        """The surface's height (m, along the outward normal) at (u, v) of the
        tangent plane (beyond the grid: on the tangent plane of the nearest edge point)."""
        return float(self._slope_np(u, v)[0][0])

    def curvatures(self, s) -> tuple[np.ndarray, np.ndarray]:
        """The principal curvatures ``(k_1, k_2)``, ``k_1 >= k_2`` (1/m), of
        the spline surface at tangential coordinates ``s`` (2 x k: u, v in m),
        positive where the surface bends towards the tool (away from the
        material: a valley, the inside of a bowl), 0 beyond the grid (the part
        continues on its edge's tangent planes there). From the spline's own first and second
        derivatives: the surface is the graph ``z = h(u, v)`` along the
        outward normal, with first fundamental form ``I = [[1 + h_u^2, h_u
        h_v], [h_u h_v, 1 + h_v^2]]`` and second ``II = Hess(h) / sqrt(1 +
        h_u^2 + h_v^2)`` (normal towards the tool); the principal curvatures
        are the eigenvalues of ``I^-1 II``: ``H +- sqrt(H^2 - K)`` with the
        mean curvature ``H`` and the Gaussian ``K``."""
        s = np.asarray(s, dtype=float).reshape(2, -1)
        k = s.shape[1]
        if k == 0:
            return np.zeros(0), np.zeros(0)
        inside = (s[0] >= self.u[0]) & (s[0] <= self.u[-1]) & (s[1] >= self.v[0]) & (s[1] <= self.v[-1])
        uv = np.vstack([np.clip(s[0], self.u[0], self.u[-1]), np.clip(s[1], self.v[0], self.v[-1])])
        g, hess = (np.array(m) for m in self._second().map(k)(uv))        # g: 2 x k, hess: 2 x 2k
        hu, hv = g[0], g[1]
        huu, huv, hvv = hess[0, 0::2], hess[0, 1::2], hess[1, 1::2]
        E, F, G = 1 + hu * hu, hu * hv, 1 + hv * hv
        W = np.sqrt(1 + hu * hu + hv * hv)
        L, M, N = huu / W, huv / W, hvv / W
        det = E * G - F * F
        H = (E * N - 2 * F * M + G * L) / (2 * det)
        K = (L * N - M * M) / det
        root = np.sqrt(np.maximum(H * H - K, 0.0))
        return np.where(inside, H + root, 0.0), np.where(inside, H - root, 0.0)

    def chart_error(self, X) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`.base.Surface.chart_error`, computed, not estimated: for
        each point the closest point of the spline surface (the best of a
        grid of seeds within the projection foot's distance, then damped
        Gauss-Newton on ``|(u - u_p, v - v_p, z_p + h(u, v))|^2``), then how far the chart's
        depth is from the distance to it (m) and the chart's normal from its
        normal (rad); 0 off the part (``X_0 <= 0``: no force to misplace).
        The module's terms ``X_0^2 kappa s^2 / 2`` and ``X_0 kappa s`` are
        their leading order. Review 43: on a 0.5 m sphere's map at slope 0.2
        and 5 mm depth (2,000 N/m at 10 N) the normal was 2.1 mrad off the
        sphere's, at any grid spacing."""
        X = np.asarray(X, dtype=float).reshape(3, -1)
        if X.shape[1] == 0:
            return np.zeros(0), np.zeros(0)
        with np.errstate(all="ignore"):             # a diverged run's points: NaN or inf where they are
            return self._chart_error(X)

    def _chart_error(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h, hu, hv = self._slope_np(X[1], X[2])
        g = np.sqrt(1 + hu * hu + hv * hv)
        z = X[0] * g - h                            # the point's height along e_n (the chart's inverse)
        n_chart = np.vstack([np.ones_like(hu), hu, hv]) / g          # in (e_n, t_1, t_2)
        k = X.shape[1]

        def far(u, v):          # the squared distance from each point to S(u, v); u, v: (k,) or (k, seeds)
            up, vp, zp = (a.reshape(-1, *[1] * (u.ndim - 1)) for a in (X[1], X[2], z))
            return (u - up) ** 2 + (v - vp) ** 2 + (zp + self._slope_np(u.ravel(), v.ravel())[0].reshape(u.shape)) ** 2

        # the closest point is no further from the point than the projection's foot (X_0 g away), so its (u, v)
        # lies in that square around (u_p, v_p): the best of CLOSEST_SEEDS^2 seeds there (review 44: from the
        # point's own (u, v) alone, Gauss-Newton converges at the rate X_0 kappa and cycled beyond 1), then
        # Gauss-Newton with a step halved until the distance falls
        a = np.linspace(-1.0, 1.0, CLOSEST_SEEDS)
        A, B = (m.ravel() for m in np.meshgrid(a, a, indexing="ij"))
        reach = np.abs(X[0]) * g
        uu, vv = X[1][:, None] + reach[:, None] * A, X[2][:, None] + reach[:, None] * B
        D = far(uu, vv)
        best = np.argmin(D, axis=1)
        u, v, D = uu[np.arange(k), best], vv[np.arange(k), best], D[np.arange(k), best]
        for _ in range(100):
            h, hu, hv = self._slope_np(u, v)
            r = np.vstack([u - X[1], v - X[2], z + h])
            # J = [[1, 0], [0, 1], [h_u, h_v]]: the normal equations' 2 x 2 solve, in closed form
            a11, b, c = 1 + hu * hu, hu * hv, 1 + hv * hv
            ru, rv = r[0] + hu * r[2], r[1] + hv * r[2]
            det = a11 * c - b * b
            du, dv = (c * ru - b * rv) / det, (a11 * rv - b * ru) / det
            t = np.ones(k)
            D_new = far(u - du, v - dv)
            for _ in range(40):
                worse = D_new > D
                if not np.any(worse):
                    break
                t = np.where(worse, t / 2, t)
                D_new = far(u - t * du, v - t * dv)
            keep = D_new <= D                       # a step that cannot lower it: the point has converged
            u, v = np.where(keep, u - t * du, u), np.where(keep, v - t * dv, v)
            moved = np.where(keep, np.abs(t * du) + np.abs(t * dv), 0.0)
            D = np.where(keep, D_new, D)
            if np.max(moved) < 1e-13 * (1.0 + np.max(np.abs(X[1:]))):
                break
        h, hu, hv = self._slope_np(u, v)
        g = np.sqrt(1 + hu * hu + hv * hv)
        distance = np.sign(z + h) * np.sqrt((u - X[1]) ** 2 + (v - X[2]) ** 2 + (z + h) ** 2)
        n_true = np.vstack([np.ones_like(hu), hu, hv]) / g
        cross = np.linalg.norm(np.cross(n_chart.T, n_true.T), axis=1)
        angle = np.arctan2(cross, np.sum(n_chart * n_true, axis=0))       # exact near 0, unlike arccos
        off = X[0] <= 0                             # off the part: nothing to misplace (a NaN stays NaN)
        return np.where(off, 0.0, np.abs(X[0] - distance)), np.where(off, 0.0, angle)

    # the base's: none (the chart is linear in X_0 along e_n, it never folds; review 14: the curved shapes' rule,
    # inherited, read a radius a height map does not have)
    depth_limit = Surface.depth_limit

    def concave_radius(self, s) -> np.ndarray:
        """:meth:`.base.Surface.concave_radius`: ``1 / k_1`` of
        :meth:`curvatures` where ``k_1 > 0`` (the largest curvature towards
        the tool, over every tangent direction: a groove across the path
        counts as much as one along it), ``inf`` elsewhere."""
        k1 = self.curvatures(s)[0]
        return np.where(k1 > 0, 1.0 / np.where(k1 > 0, k1, 1.0), np.inf)

    def _second(self) -> ca.Function:
        """``uv -> (dh, d2h)``: the spline's gradient (2 x 1) and Hessian (2 x 2)."""
        def build():
            x = ca.SX.sym("uv", 2)
            hess, grad = ca.hessian(self._h(x), x)
            return ca.Function("height_curvature", [x], [grad, hess], ["uv"], ["dh", "d2h"])
        return self._cached("curvature", build)

    def shifted(self, offset: float):
        return HeightMap(self.R, self.c + offset * self.R[:, 0], self.heights, self.spacing)

    def __repr__(self) -> str:
        return (f"HeightMap(normal={np.round(self.R[:, 0], 6).tolist()}, c={self.c.tolist()}, "
                f"grid={self.heights.shape[0]}x{self.heights.shape[1]}, spacing={list(self.spacing)}, {self._key})")
