"""Start posture and path check of any arm: inverse kinematics by CasADi's solvers.

The task is the robot's (:attr:`tmtcontrol.model.Robot.task`): the tool point
(3 equations) or the tool point and orientation (6). :func:`pose_solver`
builds one problem per robot (``rootfinder`` for a square task,
``nlpsol("ipopt")`` for a redundant arm): the joint vector closest to a
reference posture (least squares) whose tool point is at ``p`` and, on a
6-D task, whose tool orientation equals ``R_d``, within the joint limits::

    min_q |q - q_ref|^2   s.t.  fk_p(q) = p,  vee(R_d^T R(q) - R(q)^T R_d)/2 = 0,
                                tr(R_d^T R(q)) >= 1,  q_min <= q <= q_max

(the orientation equality is sin(theta) axis = 0 with cos(theta) >= 0, smooth
at the solution, unlike the rotation vector). For a square task the
constraints fix q up to the branch, which the reference selects; for a
redundant arm the objective resolves the redundancy. A robot with a
closed-form position inverse kinematics (``Robot.position_ik``, the PUMA's)
on a position task is solved by it (its default branch).

:func:`check_pose_path` walks one period of the circle (every
:data:`PATH_SAMPLES`-th of it), solving each point from the previous one, and
refuses the path with one line naming the path time and the reason:
unreachable (no solution even without limits), outside the joint limits
(a solution exists only beyond them), or near a singularity: the smallest
singular value of the task Jacobian J (the linear rows of the geometric
Jacobian in m/rad, and its angular rows in rad/rad on a 6-D task) below
:data:`MIN_SINGULAR_VALUE`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .scenario import ScenarioError

__all__ = ["MIN_SINGULAR_VALUE", "PATH_SAMPLES", "PathError", "pose_solver", "solve_pose", "PosePath",
           "check_pose_path", "task_jacobian"]


class PathError(ScenarioError):
    """The arm cannot follow the scenario's path: a pose unreachable, outside
    the joint limits or near a singularity (:func:`check_pose_path`). A
    scenario the schema accepts, refused when it runs (a sweep keeps such a
    case as a row, ``sweep.run.REFUSED``)."""

MIN_SINGULAR_VALUE = 0.02
"""Smallest singular value of J accepted along the path. On the UR5 (a6 =
0.08 m wrist) a wrist singularity or a stretched elbow drives it to 0; the
built-in paths keep it above 0.05."""

PATH_SAMPLES = 72
"""Points per period checked along the path (every 5 degrees of the circle)."""

POSE_TOL = 1e-9
"""Largest position (m) and orientation (rad) residual of an accepted pose."""


def _pose_equations(robot, q, par):
    """The task's equations at ``q`` (``par = [p, R_d, q_ref]``) and, on a 6-D
    task, tr(R_d^T R) (None on a position task)."""
    T = robot.functions.fk(q)
    if not robot.task.rotational:
        return T[:3, 3] - par[:3], None
    Rd = ca.reshape(par[3:12], 3, 3)
    E = ca.mtimes(Rd.T, T[:3, :3])
    return (ca.vertcat(T[:3, 3] - par[:3], 0.5 * ca.vertcat(E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1])),
            E[0, 0] + E[1, 1] + E[2, 2])


def task_jacobian(robot, q) -> np.ndarray:
    """The task Jacobian at ``q`` (NumPy): the geometric Jacobian's linear rows
    on a position task, all six rows on a 6-D task."""
    J = robot.jacobian(q)
    return J if robot.task.rotational else J[:3]


def pose_solver(robot, limits: bool = True, track: bool = False):
    """The solver of the module docstring for ``robot``, a function
    ``(x0, par, lo, hi) -> q`` with ``par = [p (3), R_d (9, column-major),
    q_ref (n)]``: ``nlpsol`` with IPOPT, least squares to the reference
    within the limits. With ``track`` and six joints (the path, each point
    solved from the previous one, 5 degrees of the circle away), the six pose
    equations are square and CasADi's ``rootfinder`` (``newton``) solves them
    from the previous pose, which keeps the branch (IPOPT was seen to jump to
    the UR5's flipped wrist there); the limits are checked after."""
    n, task = robot.n, robot.task
    q = ca.SX.sym("q", n)
    par = ca.SX.sym("par", 3 + 9 + n)
    g, trace = _pose_equations(robot, q, par)
    if track and task.square:
        rf = ca.rootfinder("pose", "newton", ca.Function("g", [q, par], [g]),
                           {"abstolStep": 1e-14, "abstol": 1e-13, "max_iter": 50, "error_on_fail": False})

        def solve(x0, p, lo, hi):
            return np.array(rf(x0, p)).ravel()
        return solve
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10,
            "ipopt.max_iter": 200}
    m = g.numel()
    g_all, lbg, ubg = (ca.vertcat(g, trace), np.r_[np.zeros(m), 1.0], np.r_[np.zeros(m), np.inf]) \
        if trace is not None else (g, np.zeros(m), np.zeros(m))
    nlp = ca.nlpsol("pose", "ipopt", {"x": q, "p": par, "f": ca.sumsqr(q - par[12:]), "g": g_all}, opts)

    def solve(x0, p, lo, hi):
        sol = nlp(x0=x0, p=p, lbx=lo, ubx=hi, lbg=lbg, ubg=ubg)
        return np.array(sol["x"]).ravel()
    return solve


def solve_pose(robot, solver, p, R_d, q_ref, limits: bool = True):
    """``(q, ok)``: the pose closest to ``q_ref`` with tool point ``p`` (m) and,
    on a 6-D task, orientation ``R_d``; ``ok`` when the residual is below
    :data:`POSE_TOL` (and, with ``limits``, q within the joint limits). A
    position task on a robot with a closed-form inverse kinematics
    (``Robot.position_ik``) is solved by it (``solver`` unused)."""
    n, rot = robot.n, robot.task.rotational
    lo = np.where(np.isfinite(robot.q_min), robot.q_min, -1e20) if limits else np.full(n, -1e20)
    hi = np.where(np.isfinite(robot.q_max), robot.q_max, 1e20) if limits else np.full(n, 1e20)
    q_ref = np.asarray(q_ref, dtype=float)
    if not rot and robot.position_ik is not None:
        try:
            q = np.asarray(robot.position_ik(np.asarray(p, float)), dtype=float)
        except ValueError:
            return q_ref, False
    else:
        R_d = np.eye(3) if R_d is None else R_d
        par = np.concatenate([np.asarray(p, float), np.asarray(R_d, float).ravel(order="F"), q_ref])
        q = solver(np.clip(q_ref, lo, hi), par, lo, hi)
    if not np.all(np.isfinite(q)):
        return q, False
    T = robot.fk(q)
    err = np.abs(T[:3, 3] - p).max()
    if rot:
        err = max(err, orientation_angle(np.asarray(R_d) @ T[:3, :3].T))
    ok = bool(err < POSE_TOL) and (not limits or bool(np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)))
    return q, ok


def orientation_angle(R_e) -> float:
    """The angle of the rotation ``R_e`` (rad, 0 to pi), by SciPy's
    ``Rotation`` (the rotation vector of :mod:`.geometry` is only defined
    below pi)."""
    from scipy.spatial.transform import Rotation

    return float(Rotation.from_matrix(R_e).magnitude())


@dataclass(frozen=True, eq=False)
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
    ``t`` their path times, s; ``R_d`` the commanded orientation, one 3 x 3
    or one per point, k x 3 x 3) from ``q_seed`` then from the previous pose;
    raise :class:`PathError` (one line: path time and reason) at the
    first point that is unreachable, outside the joint limits or near a
    singularity."""
    closed = not robot.task.rotational and robot.position_ik is not None
    start, track = (None, None) if closed else (pose_solver(robot), pose_solver(robot, track=True))
    free = None
    qs, sig = [], []
    q_prev = np.asarray(q_seed, dtype=float)
    R_all = np.asarray(R_d, dtype=float) if R_d is not None else None
    for k in range(points.shape[1]):
        R_d = R_all[k] if R_all is not None and R_all.ndim == 3 else R_all
        q, ok = solve_pose(robot, track if k else start, points[:, k], R_d, q_prev)
        if not ok and k == 0:
            q, ok = _start_from_nearby_seeds(robot, start, points[:, 0], R_d, q_prev)
        if not ok:
            free = free or (None if closed else pose_solver(robot, limits=False))
            q_free, ok_free = solve_pose(robot, free, points[:, k], R_d, q_prev, limits=False)
            if ok_free:
                out = np.flatnonzero((q_free < robot.q_min) | (q_free > robot.q_max))
                names = ", ".join(robot.joint_names[i] for i in out) or "a joint"
                raise PathError(f"trajectory: at path time t = {t[k]:.3f} s the pose is outside the joint "
                                f"limits ({names}) at {np.round(points[:, k], 4).tolist()} m")
            seed = "robot.q0" if k == 0 else "the previous path point"
            orient = " with the commanded orientation" if robot.task.rotational else ""
            raise PathError(f"trajectory: at path time t = {t[k]:.3f} s the pose is unreachable "
                            f"(tool point {np.round(points[:, k], 4).tolist()} m{orient}; no pose found "
                            f"from {seed})")
        sv = np.linalg.svd(task_jacobian(robot, q), compute_uv=False)
        s = sv[-1]
        if not s >= MIN_SINGULAR_VALUE:
            raise PathError(f"trajectory: at path time t = {t[k]:.3f} s the path passes near a singularity "
                            f"(smallest singular value of J {s:.3g} < {MIN_SINGULAR_VALUE:g})")
        qs.append(q)
        sig.append(sv)
        q_prev = q
    sig = np.asarray(sig)
    return PosePath(np.asarray(t, float), np.column_stack(qs), sig[:, -1], sig[:, 0] / sig[:, -1])
