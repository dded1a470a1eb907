"""Start posture and path check of a 6-D arm: inverse kinematics by CasADi's solvers.

:func:`pose_solver` builds one problem per robot (``rootfinder`` for six
joints, ``nlpsol("ipopt")`` for more):
the joint vector closest to a reference posture (least squares) whose tool
point is at ``p`` and whose tool orientation equals ``R_d``, within the joint
limits::

    min_q |q - q_ref|^2   s.t.  fk_p(q) = p,  vee(R_d^T R(q) - R(q)^T R_d)/2 = 0,
                                tr(R_d^T R(q)) >= 1,  q_min <= q <= q_max

(the orientation equality is sin(theta) axis = 0 with cos(theta) >= 0, smooth
at the solution, unlike the rotation vector). For 6 joints the constraints
fix q up to the branch, which the reference selects; for a redundant arm the
objective resolves the redundancy.

:func:`check_pose_path` walks one period of the circle (every
:data:`PATH_SAMPLES`-th of it), solving each point from the previous one, and
refuses the path with one line naming the path time and the reason:
unreachable (no solution even without limits), outside the joint limits
(a solution exists only beyond them), or near a singularity: the smallest
singular value of the 6 x n geometric Jacobian J (linear rows in m/rad,
angular rows in rad/rad) below :data:`MIN_SINGULAR_VALUE`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .scenario import ScenarioError

__all__ = ["MIN_SINGULAR_VALUE", "PATH_SAMPLES", "pose_solver", "solve_pose", "PosePath", "check_pose_path"]

MIN_SINGULAR_VALUE = 0.02
"""Smallest singular value of J accepted along the path. On the UR5 (a6 =
0.08 m wrist) a wrist singularity or a stretched elbow drives it to 0; the
built-in paths keep it above 0.05."""

PATH_SAMPLES = 72
"""Points per period checked along the path (every 5 degrees of the circle)."""

POSE_TOL = 1e-9
"""Largest position (m) and orientation (rad) residual of an accepted pose."""


def _pose_equations(robot, q, par):
    T = robot.functions.fk(q)
    Rd = ca.reshape(par[3:12], 3, 3)
    E = ca.mtimes(Rd.T, T[:3, :3])
    return (ca.vertcat(T[:3, 3] - par[:3], 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])),
            E[0, 0] + E[1, 1] + E[2, 2])


def pose_solver(robot, limits: bool = True, track: bool = False):
    """The solver of the module docstring for ``robot``, a function
    ``(x0, par, lo, hi) -> q`` with ``par = [p (3), R_d (9, column-major),
    q_ref (n)]``: ``nlpsol`` with IPOPT, least squares to the reference
    within the limits. With ``track`` and six joints (the path, each point
    solved from the previous one, 5 degrees of the circle away), the six pose
    equations are square and CasADi's ``rootfinder`` (``newton``) solves them
    from the previous pose, which keeps the branch (IPOPT was seen to jump to
    the UR5's flipped wrist there); the limits are checked after."""
    n = robot.n
    q = ca.SX.sym("q", n)
    par = ca.SX.sym("par", 3 + 9 + n)
    g, trace = _pose_equations(robot, q, par)
    if track and n == 6:
        rf = ca.rootfinder("pose", "newton", ca.Function("g", [q, par], [g]),
                           {"abstolStep": 1e-14, "abstol": 1e-13, "max_iter": 50, "error_on_fail": False})

        def solve(x0, p, lo, hi):
            return np.array(rf(x0, p)).ravel()
        return solve
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10,
            "ipopt.max_iter": 200}
    nlp = ca.nlpsol("pose", "ipopt", {"x": q, "p": par, "f": ca.sumsqr(q - par[12:]), "g": ca.vertcat(g, trace)},
                    opts)

    def solve(x0, p, lo, hi):
        sol = nlp(x0=x0, p=p, lbx=lo, ubx=hi, lbg=np.r_[np.zeros(6), 1.0], ubg=np.r_[np.zeros(6), np.inf])
        return np.array(sol["x"]).ravel()
    return solve


def solve_pose(robot, solver, p, R_d, q_ref, limits: bool = True):
    """``(q, ok)``: the pose closest to ``q_ref`` with tool point ``p`` (m) and
    orientation ``R_d``; ``ok`` when the residual is below :data:`POSE_TOL`
    (and, with ``limits``, q within the joint limits)."""
    n = robot.n
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -1e20) if limits else np.full(n, -1e20)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, 1e20) if limits else np.full(n, 1e20)
    q_ref = np.asarray(q_ref, dtype=float)
    par = np.concatenate([np.asarray(p, float), np.asarray(R_d, float).ravel(order="F"), q_ref])
    q = solver(np.clip(q_ref, lo, hi), par, lo, hi)
    if not np.all(np.isfinite(q)):
        return q, False
    T = robot.fk(q)
    err = max(np.abs(T[:3, 3] - p).max(), orientation_angle(np.asarray(R_d) @ T[:3, :3].T))
    ok = bool(err < POSE_TOL) and (not limits or bool(np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)))
    return q, ok


def orientation_angle(R_e) -> float:
    """The angle of the rotation ``R_e`` (rad, 0 to pi), by SciPy's
    ``Rotation`` (the rotation vector of :mod:`.geometry` is only defined
    below pi)."""
    from scipy.spatial.transform import Rotation

    return float(Rotation.from_matrix(R_e).magnitude())


@dataclass(frozen=True)
class PosePath:
    """Joint-space image of one period of the path and its conditioning."""
    t: np.ndarray                 # (k,) path times, s
    q: np.ndarray                 # (n, k) joints, rad
    sigma_min: np.ndarray         # (k,) smallest singular value of J
    condition_number: np.ndarray  # (k,) largest over smallest singular value of J

    @property
    def max_condition(self) -> float:
        return float(self.condition_number.max())


SEED_SHIFTS = (math.pi / 2, -math.pi / 2, math.pi)
"""Joint shifts (rad) of the extra start seeds: IPOPT finds the start pose
from ``robot.q0``; when it does not, each joint of the seed is turned by each
of these in turn (kept within its limits), since a reachable pose can lie
behind a joint limit or a wrist flip from the seed (a tool spin of 150 deg on
the UR5's default seed)."""


def _start_from_nearby_seeds(robot, solver, p, R_d, q_seed):
    """``(q, ok)``: the start pose from the seeds of :data:`SEED_SHIFTS`,
    the solution closest to ``q_seed`` among those found (deterministic)."""
    best, found = None, []
    for j in range(robot.n):
        for d in SEED_SHIFTS:
            seed = np.array(q_seed, dtype=float)
            seed[j] = np.clip(seed[j] + d, robot.q_min[j], robot.q_max[j])
            q, ok = solve_pose(robot, solver, p, R_d, seed)
            if ok:
                found.append(q)
    if found:
        best = min(found, key=lambda q: float(np.sum((q - q_seed) ** 2)))
        return best, True
    return np.asarray(q_seed, dtype=float), False


def check_pose_path(robot, points, R_d, t, q_seed) -> PosePath:
    """Solve the pose at every path point (``points`` 3 x k, base frame, m;
    ``t`` their path times, s) from ``q_seed`` then from the previous pose;
    raise :class:`ScenarioError` (one line: path time and reason) at the
    first point that is unreachable, outside the joint limits or near a
    singularity."""
    start, track = pose_solver(robot), pose_solver(robot, track=True)
    free = None
    qs, sig = [], []
    q_prev = np.asarray(q_seed, dtype=float)
    for k in range(points.shape[1]):
        q, ok = solve_pose(robot, track if k else start, points[:, k], R_d, q_prev)
        if not ok and k == 0:
            q, ok = _start_from_nearby_seeds(robot, start, points[:, 0], R_d, q_prev)
        if not ok:
            free = free or pose_solver(robot, limits=False)
            q_free, ok_free = solve_pose(robot, free, points[:, k], R_d, q_prev, limits=False)
            if ok_free:
                out = np.flatnonzero((q_free < robot.q_min) | (q_free > robot.q_max))
                names = ", ".join(robot.joint_names[i] for i in out) or "a joint"
                raise ScenarioError(f"trajectory: at path time t = {t[k]:.3f} s the pose is outside the joint "
                                    f"limits ({names}) at {np.round(points[:, k], 4).tolist()} m")
            seed = "robot.q0" if k == 0 else "the previous path point"
            raise ScenarioError(f"trajectory: at path time t = {t[k]:.3f} s the pose is unreachable "
                                f"(tool point {np.round(points[:, k], 4).tolist()} m with the commanded "
                                f"orientation; no pose found from {seed})")
        sv = np.linalg.svd(robot.jacobian(q), compute_uv=False)
        s = sv[-1]
        if not s >= MIN_SINGULAR_VALUE:
            raise ScenarioError(f"trajectory: at path time t = {t[k]:.3f} s the path passes near a singularity "
                                f"(smallest singular value of J {s:.3g} < {MIN_SINGULAR_VALUE:g})")
        qs.append(q)
        sig.append(sv)
        q_prev = q
    sig = np.asarray(sig)
    return PosePath(np.asarray(t, float), np.column_stack(qs), sig[:, -1], sig[:, 0] / sig[:, -1])
