"""Geometry of the task: the surface's task frame, the commanded tool
orientation and the orientation error on SO(3).

Task frame (base-frame columns, normal axis first): ``e_n`` the plane's
*inward* unit normal, ``e_1`` base y projected onto the plane (base x when
the normal is nearly along y), ``e_2 = e_n x e_1``. For the tilt shorthand
(``environment.tilt_deg``, normal ``(sin t, 0, -cos t)``) this is
:func:`.environment.task_frame` exactly. The task frame's origin is the
circle's centre ``trajectory.center``.

Commanded tool orientation (6-D arms): ``R_d = [e_1, e_2, e_n]`` turned by
``trajectory.tool_spin_deg`` about ``e_n``: tool z along the inward normal.

Orientation error (the minimal representation of the rotational axes): the
rotation vector ``e_o = log(R_c R^T)^vee`` in the base frame, the axis times
the angle (rad) of the rotation that takes the tool orientation R to the
command R_c. It is regular for every angle below pi (no Euler-angle
singularity); :func:`rotation_vector` computes it from
``v = vee(R_e - R_e^T)/2 = sin(theta) axis`` and ``theta = atan2(|v|,
(tr R_e - 1)/2)``, with the series ``theta/sin(theta) = 1 + theta^2/6`` below
1e-9 rad.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ..surface import Surface, make_surface, normal_frame, tilt_frame

__all__ = ["surface_of", "surface_frame", "tool_orientation", "rotation_vector", "under_the_commanded_path"]


def surface_of(scenario) -> Surface:
    """The scenario's surface (:mod:`tmtcontrol.surface`): the plane of
    ``environment.normal`` (or, when unset, ``environment.tilt_deg``)
    through ``trajectory.center``, the task frame's origin; or the sphere or
    cylinder of ``environment.radius`` touching that plane there (a
    cylinder's axis along ``environment.axis``, default task axis 2)."""
    env, center = scenario.environment, scenario.trajectory.center
    heights = None
    if env.heightmap is not None:
        from .scenario.environment import read_height_grid

        heights = read_height_grid(env.heightmap)      # cached by the file's size and time: the same array
    # built once per surface (a height map's spline takes ~20 ms, and the loop, the analyses and the
    # figures each ask); the entry holds the heights, so their id is not reused while it lives
    key = (env, tuple(center), id(heights))
    if key not in _SURFACES:
        if len(_SURFACES) > 32:
            _SURFACES.clear()
        _SURFACES[key] = (heights, make_surface(env.shape, surface_frame(env), center, env.radius, env.side,
                                                env.axis, heights, env.grid_spacing))
    return _SURFACES[key][1]


_SURFACES: dict = {}


def under_the_commanded_path(scenario, X) -> np.ndarray:
    """Task coordinates (3 x k; 3 for 3) on the true part of the points
    under the path the controller commands: ``X`` are the path's tangential
    coordinates on the true part (``X[0]`` a depth), which the controller
    takes on its own part, the true one moved by ``controller.part_offset``
    d; the tool meets the true part under the point ``to_base(0, X[1:]) +
    d``, whose true chart coordinates these are at the depth ``X[0]`` (the
    same point on a plane moved by d's tangential part). ``X`` itself when d
    is 0. The path's checks and normal masses, the start and the frozen
    points are taken there (review 56: a 0.6 m sideways offset checked the
    path where it was not, and the run diverged instead of refusing)."""
    X = np.asarray(X, dtype=float)
    d = np.asarray(scenario.controller.part_offset, dtype=float)
    if not d.any():
        return X
    surface = surface_of(scenario)
    flat = X.reshape(3, -1)
    on = surface.to_base(np.vstack([np.zeros(flat.shape[1]), flat[1:]])) + d[:, None]
    out = np.array(surface.from_base(on), dtype=float).reshape(3, -1)
    out[0] = flat[0]
    return out.reshape(X.shape)


def surface_frame(environment) -> np.ndarray:
    """Rotation R (3x3): the task axes (normal, 1, 2) in the base frame, from
    ``environment.normal`` or, when unset, ``environment.tilt_deg``."""
    if environment.normal is None:
        return tilt_frame(environment.tilt_deg)
    return normal_frame(environment.normal)


def tool_orientation(R: np.ndarray, spin_deg: float = 0.0) -> np.ndarray:
    """The commanded tool orientation (3x3, base frame) on the task frame
    ``R``: tool z = e_n, tool x = e_1 turned by ``spin_deg`` about e_n."""
    s = math.radians(spin_deg)
    e_n, e_1, e_2 = R[:, 0], R[:, 1], R[:, 2]
    x = math.cos(s) * e_1 + math.sin(s) * e_2
    return np.column_stack([x, np.cross(e_n, x), e_n])


NEAR_PI = 1e-2
"""Below this sine of the angle, and beyond a right angle, :func:`rotation_vector`
takes the axis from the symmetric part of R (the skew part's ``sin(theta) u``
has lost it: review 54, an angle within 1e-9 of pi read as about 0)."""


def rotation_vector(R_e):
    """``log(R_e)^vee`` (3, rad) of a rotation matrix (CasADi symbol or NumPy
    array): the angle theta in [0, pi] times the unit axis u. From the skew
    part ``sin(theta) u`` (with theta/sin(theta) -> 1 at small angles); within
    :data:`NEAR_PI` of a half turn from the symmetric part,
    ``(R + R^T)/2 = cos(theta) I + (1 - cos(theta)) u u^T``, its largest
    diagonal's column, signed as the skew part (at pi itself either sign is
    the logarithm). Every branch is finite everywhere, and so are its
    derivatives in SX and MX alike: the sine is ``sqrt(fmax(v.v, 1e-300))``,
    equal to ``norm_2(v)`` bit for bit where it is above 1e-150, whose
    derivative ``v/|v|`` was NaN in MX at a skew part of exactly 0 (review
    55: at R_e = I, which ``R R^T`` gives exactly)."""
    if isinstance(R_e, np.ndarray):
        R_e = ca.DM(R_e)
        return np.array(rotation_vector(R_e)).ravel()
    v = 0.5 * ca.vertcat(R_e[2, 1] - R_e[1, 2], R_e[0, 2] - R_e[2, 0], R_e[1, 0] - R_e[0, 1])
    s = ca.sqrt(ca.fmax(ca.dot(v, v), 1e-300))
    c = 0.5 * (R_e[0, 0] + R_e[1, 1] + R_e[2, 2] - 1)
    theta = ca.atan2(s, c)
    scale = ca.if_else(s > 1e-9, theta / ca.fmax(s, 1e-9), 1 + s * s / 6)
    # near a half turn: u u^T from the symmetric part, its largest diagonal's column (u_j^2 >= 1/3 there)
    B = (0.5 * (R_e + R_e.T) - c * ca.DM.eye(3)) / ca.fmax(1 - c, 1.0)
    j0 = ca.logic_and(B[0, 0] >= B[1, 1], B[0, 0] >= B[2, 2])
    col = ca.if_else(j0, B[:, 0], ca.if_else(B[1, 1] >= B[2, 2], B[:, 1], B[:, 2]))
    u = col / ca.sqrt(ca.fmax(ca.mmax(ca.vertcat(B[0, 0], B[1, 1], B[2, 2])), 1e-12))
    u = ca.if_else(ca.dot(u, v) < 0, -u, u)
    return ca.if_else(ca.logic_and(c < 0, s < NEAR_PI), theta * u, scale * v)
