"""Derivation checks that hold for any arm: the task-frame closed loop of a
scenario's arm, with the ideal inner loop (the controller's model equal to
the plant), is the paper's loop.

The checks build the closed loop from the expressions the simulator uses —
the robot's CasADi Functions (eq. 1, ``load_robot``), the impedance filter,
command and inner loop of ``control/impedance.py`` (eqs. 2, 4, 6), the TMT
reference of ``control/laws/tmt.py`` (eq. 16), the rotation-vector error of
``simulation/geometry.py`` and the inner loop's torque
:func:`.closedloop.operational_space_torque` (eq. 5; on a redundant arm with
the dynamically consistent null-space projector), the torque of the
simulator's one loop — never formulas retyped here, and evaluate each claim at seeded random joint states within
the joint limits (well conditioned: the smallest singular value of the task
Jacobian at least :data:`MIN_SINGULAR_VALUE`), with random commands. CasADi
cannot simplify ``J M^-1 J^T (J M^-1 J^T)^-1`` to the identity symbolically
for a URDF arm, so every claim is numeric, with its tolerance stated.

Checks (one :class:`.derivations.CheckResult` each):

* eqs. (5)-(6): the task acceleration ``J ddq + dJ dq`` of the plant under
  the inner-loop torque equals the command U (eq. 6 realised, with the
  contact force fed forward);
* eqs. (19)-(22): on the normal axis, with the impedance filter (eq. 2), the
  command (eq. 4) and the TMT reference (eq. 16) at matched initial
  conditions (E = X_a), the arm's normal acceleration satisfies eq. (22),
  ``m eps'' + b eps' + (k + k_e) eps = -f_d (k + k_e)/k_e`` (eps = x_e - x);
* null space (a 6-D task, and a position task on an arm of 4 or 5 joints,
  whose loop has the posture task too): a joint torque tau_0 through
  ``N^T`` does not change the task acceleration (``J M^-1 N^T = 0``), while
  on a redundant arm it does move the joints (the posture task acts);
* on a curved surface (sphere, cylinder), eqs. (19)-(22) again with the
  depth along the local normal as the normal coordinate and the inner loop
  mapped through the surface's chart, at joint states along the path;
* tangential and rotational impedance (6-D only): with no tangential force
  and no contact moment the tangential axes follow ``M E'' + B E' + K E = 0``
  and the rotational axes ``M_rot w' + B_rot w = K_rot e_o`` (rotation-vector
  error e_o, angular velocity w, task axes): eq. (8) on those axes.

The implementations are injected through :class:`ArmImplementation`, so a
test can substitute a model with another mass, or a projector without
``M^-1``, and see the checks fail.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import casadi as ca
import numpy as np

from ..control import impedance
from ..control.laws import tmt as reference
from .derivations import CheckResult, _result

__all__ = ["ArmImplementation", "arm_implementation", "run_arm_checks", "ARM_RTOL", "MIN_SINGULAR_VALUE",
           "STATES"]

ARM_RTOL = 1e-8
"""Relative tolerance of every arm check. The plant's acceleration comes
from a solve with M and the controller's from solves with M and
``J M^-1 J^T``: at the states drawn (smallest singular value of J >= 0.05,
so cond(J M^-1 J^T) stays below ~1e6) round-off stays below ~1e-10; a model
or projector error is 1e-3 or more."""

MIN_SINGULAR_VALUE = 0.05
"""Smallest singular value of the task Jacobian (linear rows m/rad, angular
rad/rad) at a drawn state: away from singularities, as the path check
requires (:data:`.posture.MIN_SINGULAR_VALUE` is 0.02)."""

STATES = 12
"""Random joint states per check."""


@dataclass(frozen=True)
class ArmImplementation:
    """What the arm checks exercise. ``plant``: the simulated arm
    (``load_robot``); ``model``: the controller's model of it (the ideal
    inner loop: the same robot); ``torque``: the inner loop's torque
    ``(M, n, J, Jdot_dq, U, F_e, tau_0) -> tau`` (default: the simulator's
    for the arm's task dimension)."""
    plant: Any
    model: Any
    torque: Callable | None = None
    tmt_reference: Callable = reference.tmt_reference
    impedance_acceleration: Callable = impedance.impedance_acceleration
    command: Callable = impedance.command
    inner_loop: Callable = impedance.inner_loop
    surface: Any = None            # the scenario's surface (a curved one adds its own normal-axis check)
    path_q: Any = None             # joint states along the scenario's path (n x k, rad)

    @property
    def task_dim(self) -> int:
        """The robot's task axes (:attr:`tmtcontrol.model.Robot.task`): 3 or 6."""
        return self.plant.task.dim

    def inner_torque(self, M, n_bias, J, Jdot_dq, U, F_e, tau_0=None):
        """The inner loop's torque as the simulator computes it for this task dimension."""
        if self.torque is not None:
            return self.torque(M, n_bias, J, Jdot_dq, U, F_e, tau_0)
        from ..simulation.closedloop import operational_space_torque

        return operational_space_torque(M, n_bias, J, Jdot_dq, U, F_e, tau_0)


def arm_implementation(scenario) -> ArmImplementation:
    """The scenario's arm as the simulator loads it (``robot.model``, tip,
    friction, armature), as both plant and model: the ideal inner loop."""
    from ..simulation.simulator import robot_of

    from ..simulation.geometry import surface_of
    from ..simulation.simulator import path_of

    plant = robot_of(scenario)
    surface = surface_of(scenario)
    path_q = path_of(plant, scenario).q if surface.turns else None
    return ArmImplementation(plant=plant, model=plant, surface=surface, path_q=path_q)


def _states(impl: ArmImplementation, rng, count: int):
    """Random (q, dq) within the joint limits (+-pi where there is none),
    with the task Jacobian's smallest singular value >= MIN_SINGULAR_VALUE."""
    rob, d = impl.plant, impl.task_dim
    lo = np.where(np.isfinite(rob.q_min), rob.q_min, -np.pi)
    hi = np.where(np.isfinite(rob.q_max), rob.q_max, np.pi)
    out = []
    for _ in range(200 * count):
        q = rng.uniform(lo, hi)
        if np.linalg.svd(rob.jacobian(q)[:d], compute_uv=False).min() >= MIN_SINGULAR_VALUE:
            out.append((q, rng.uniform(-1, 1, rob.n)))
            if len(out) == count:
                return out
    raise RuntimeError(f"fewer than {count} well-conditioned states of {rob.name} in {200 * count} draws")


def _loop(impl: ArmImplementation, U, F_n, tau_0=None):
    """The closed loop at symbolic (q, dq): the plant's joint and task
    accelerations under the inner-loop torque for the base-frame command U
    (task_dim) with the normal contact force F_n along ``e_n`` (3, base
    frame, its size the force) fed forward by the controller and acting on
    the plant's tool point."""
    n, d = impl.plant.n, impl.task_dim
    q, dq = ca.MX.sym("q", n), ca.MX.sym("dq", n)
    mf, pf = impl.model.functions, impl.plant.functions
    J, Jd = mf.jacobian(q)[:d, :], mf.jacobian_dot(q, dq)[:d]
    F_e = ca.vertcat(F_n, ca.MX.zeros(d - 3))
    tau = impl.inner_torque(mf.mass_matrix(q), mf.bias(q, dq), J, Jd, U, F_e, tau_0) + mf.friction(dq)
    Jp = pf.jacobian(q)
    ddq = pf.forward_dynamics(q, dq, tau - ca.mtimes(Jp[:3, :].T, F_n))
    acc = ca.mtimes(Jp[:d, :], ddq) + pf.jacobian_dot(q, dq)[:d]
    return q, dq, ddq, acc


def _rotation(rng) -> np.ndarray:
    """A random rotation matrix (angle below 0.9 pi: away from the rotation vector's cut)."""
    from scipy.spatial.transform import Rotation

    axis = rng.normal(size=3)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * rng.uniform(0.0, 0.9 * np.pi)).as_matrix()


def check_task_acceleration(impl: ArmImplementation, rng) -> CheckResult:
    """Eqs. (5)-(6): the task acceleration equals the inner-loop command U."""
    d = impl.task_dim
    U, F_n = ca.MX.sym("U", d), ca.MX.sym("F_n", 3)
    q, dq, _, acc = _loop(impl, U, F_n)
    f = ca.Function("task_acceleration", [q, dq, U, F_n], [acc], ["q", "dq", "U", "F_n"], ["acc"])
    res = 0.0
    for qv, dqv in _states(impl, rng, STATES):
        Uv = rng.normal(scale=2.0, size=d)
        n = rng.normal(size=3)
        acc_v = np.asarray(f(qv, dqv, Uv, n / np.linalg.norm(n) * rng.uniform(0, 50))).ravel()
        res = max(res, float(np.max(np.abs(acc_v - Uv)) / max(1.0, np.max(np.abs(Uv)))))
    what = ("operational-space torque (closedloop.operational_space_torque), 6-D task" if d == 6 else
            "operational-space torque (closedloop.operational_space_torque), position task")
    return _result(f"ideal inner loop realises U ({impl.plant.name})", "(5)-(6)",
                   "model = plant: J q'' + dJ q' = U for any U and contact force (fed forward)",
                   f"CasADi: {impl.plant.name} plant (eq. 1) under the {what}; {STATES} random states in the "
                   "joint limits, random U and contact force", res, ARM_RTOL)


def check_normal_axis(impl: ArmImplementation, rng) -> CheckResult:
    """Eqs. (19)-(22) on the normal axis of the arm's task-frame loop."""
    d = impl.task_dim
    s = {k: ca.MX.sym(k) for k in ("m", "b", "k", "k_e", "f_d", "u")}
    e_n, U_rest = ca.MX.sym("e_n", 3), ca.MX.sym("U_rest", d - 1)
    R = ca.MX.sym("R", 3, 3)                       # task axes, e_n first (the surface frame)
    n = impl.plant.n
    q, dq = ca.MX.sym("q", n), ca.MX.sym("dq", n)
    mf = impl.model.functions
    p = mf.fk(q)[:3, 3]
    x, dx = ca.dot(e_n, p), ca.dot(e_n, ca.mtimes(mf.jacobian(q)[:3, :], dq))
    x_e = x - s["u"]                                 # penetration u > 0: in contact
    f_e = s["k_e"] * (x - x_e)                       # eq. (13)
    x_r = impl.tmt_reference(x, f_e, x_e, s["f_d"], s["k"], 1e-9, 1e-12)   # eq. (16), full law
    # matched initial conditions E = X_a (E = x_r - x), x_r' = x_r'' = 0 (section IV)
    x_a, dx_a = x_r - x, -dx
    ddx_a = impl.impedance_acceleration(f_e, x_a, dx_a, s["m"], s["b"], s["k"])            # eq. (2)
    x_c, dx_c, ddx_c = impl.command(x_r, x_a), impl.command(0, dx_a), impl.command(0, ddx_a)   # eq. (4)
    u_n = impl.inner_loop(ddx_c, dx_c, x_c, dx, x, s["b"] / s["m"], s["k"] / s["m"])        # eq. (6), eq. (9) gains
    U_task = ca.vertcat(u_n, U_rest)
    U = ca.mtimes(R, U_task[:3]) if d == 3 else ca.vertcat(ca.mtimes(R, U_task[:3]), ca.mtimes(R, U_task[3:]))
    # the plant, with the true contact force f_e on the tool point and the measured one fed forward
    pf = impl.plant.functions
    J = mf.jacobian(q)[:d, :]
    tau = impl.inner_torque(mf.mass_matrix(q), mf.bias(q, dq), J, mf.jacobian_dot(q, dq)[:d],
                            U, ca.vertcat(e_n * f_e, ca.MX.zeros(d - 3))) + mf.friction(dq)
    ddq = pf.forward_dynamics(q, dq, tau - ca.mtimes(pf.jacobian(q)[:3, :].T, e_n * f_e))
    ddx = ca.dot(e_n, ca.mtimes(pf.jacobian(q)[:3, :], ddq) + pf.jacobian_dot(q, dq)[:3])
    eps, deps, ddeps = x_e - x, -dx, -ddx
    k, k_e, f_d = s["k"], s["k_e"], s["f_d"]
    lhs = s["m"] * ddeps + s["b"] * deps + (k + k_e) * eps
    rhs = -f_d * (k + k_e) / k_e
    scale = ca.fmax(1.0, ca.fmax(ca.fabs(rhs), ca.fabs((k + k_e) * eps)))
    f = ca.Function("normal_axis", [q, dq, R, e_n, U_rest, *s.values()], [(lhs - rhs) / scale])
    res = 0.0
    for qv, dqv in _states(impl, rng, STATES):
        Rv = _rotation(rng)
        vals = [rng.uniform(0.5, 2), rng.uniform(1, 100), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 5),
                rng.uniform(1, 50), rng.uniform(1e-4, 1e-2)]
        res = max(res, abs(float(f(qv, dqv, Rv, Rv[:, 0], rng.normal(size=d - 1), *vals))))
    return _result(f"normal axis is eq. (22) ({impl.plant.name})", "(19)-(22)",
                   "model = plant, E = X_a: the arm's normal axis with eqs. (2), (4), (6) and the TMT reference "
                   "(16) obeys m eps'' + b eps' + (k + k_e) eps = -f_d (k + k_e)/k_e, eps = x_e - x",
                   f"CasADi: {impl.plant.name} plant in a random task frame, contact force k_e (x - x_e) on the "
                   f"tool point; the other axes' U random; {STATES} random states and impedances", res, ARM_RTOL)


def check_null_space(impl: ArmImplementation, rng) -> CheckResult:
    """Null space: the posture torque does not change the task acceleration."""
    d, n = impl.task_dim, impl.plant.n
    U, F_n, tau_0 = ca.MX.sym("U", d), ca.MX.sym("F_n", 3), ca.MX.sym("tau_0", n)
    q, dq, ddq0, acc0 = _loop(impl, U, F_n)
    q1, dq1, ddq1, acc1 = _loop(impl, U, F_n, tau_0)
    acc1, ddq1 = ca.substitute([acc1, ddq1], [q1, dq1], [q, dq])
    M = impl.plant.functions.mass_matrix(q)
    f = ca.Function("null_space", [q, dq, U, F_n, tau_0],
                    [acc1 - acc0, ddq1 - ddq0, ca.solve(M, tau_0)])
    res, moved = 0.0, 0.0
    for qv, dqv in _states(impl, rng, STATES):
        t0 = rng.normal(scale=20.0, size=n)
        dacc, dddq, free = (np.asarray(v).ravel() for v in f(qv, dqv, rng.normal(size=d), rng.normal(size=3), t0))
        res = max(res, float(np.max(np.abs(dacc)) / np.max(np.abs(free))))
        moved = max(moved, float(np.max(np.abs(dddq)) / np.max(np.abs(free))))
    note = ""
    if n > d:
        if moved < 1e-3:        # a projector that removes every torque would hide the posture task
            res = max(res, 1.0)
            note = f"the null-space torque does not move the joints (largest |change of q''| {moved:.1e} of M^-1 tau_0)"
        else:
            note = f"it does move the joints: largest change of q'' {moved:.2g} of M^-1 tau_0"
    else:
        note = "square Jacobian: N^T = 0, so tau_0 must vanish entirely"
    return _result(f"null-space torque leaves the task alone ({impl.plant.name})", "(5), null space",
                   "J q'' + dJ q' is the same with and without a joint torque tau_0 through "
                   "N^T = I - J^T Lambda J M^-1",
                   f"CasADi: {impl.plant.name} loop with and without a random tau_0 (20 N m scale); change of the "
                   f"task acceleration over |M^-1 tau_0|; {STATES} random states", res, ARM_RTOL, note)


def check_tangential_rotational(impl: ArmImplementation, rng) -> CheckResult:
    """Eq. (8) on the tangential and rotational axes of the 6-D task."""
    from ..simulation.geometry import rotation_vector

    n = impl.plant.n
    q, dq = ca.MX.sym("q", n), ca.MX.sym("dq", n)
    R, R_d = ca.MX.sym("R", 3, 3), ca.MX.sym("R_d", 3, 3)
    X_r, dX_r, ddX_r = (ca.MX.sym(k, 2) for k in ("X_r", "dX_r", "ddX_r"))
    m, b, k = (ca.MX.sym(v, 5) for v in ("m", "b", "k"))     # tangential 1, 2 then rotational 1-3
    u_n = ca.MX.sym("u_n")
    mf, pf = impl.model.functions, impl.plant.functions
    T, J = mf.fk(q), mf.jacobian(q)
    X = ca.mtimes(R.T, T[:3, 3])[1:]
    dX = ca.mtimes(R.T, ca.mtimes(J[:3, :], dq))[1:]
    kd, kp = b / m, k / m                                                            # eq. (9)
    U_t = impl.inner_loop(ddX_r, dX_r, X_r, dX, X, kd[:2], kp[:2])                  # X_a = 0: X_c = X_r
    e_o = ca.mtimes(R.T, rotation_vector(ca.mtimes(R_d, T[:3, :3].T)))
    w = ca.mtimes(R.T, ca.mtimes(J[3:, :], dq))
    U_rot = impl.inner_loop(0, 0, e_o, w, 0, kd[2:], kp[2:])
    U = ca.vertcat(ca.mtimes(R, ca.vertcat(u_n, U_t)), ca.mtimes(R, U_rot))
    tau = impl.inner_torque(mf.mass_matrix(q), mf.bias(q, dq), J, mf.jacobian_dot(q, dq), U,
                            ca.MX.zeros(6)) + mf.friction(dq)
    ddq = pf.forward_dynamics(q, dq, tau)
    a = ca.mtimes(pf.jacobian(q), ddq) + pf.jacobian_dot(q, dq)
    a_t, dw = ca.mtimes(R.T, a[:3])[1:], ca.mtimes(R.T, a[3:])
    E, dE, ddE = X_r - X, dX_r - dX, ddX_r - a_t
    lhs = ca.vertcat(m[:2] * ddE + b[:2] * dE + k[:2] * E,                          # = F_t = 0
                     m[2:] * dw + b[2:] * w - k[2:] * e_o)                           # = moment = 0
    scale = ca.vertcat(ca.fmax(1, ca.fmax(ca.fabs(m[:2] * ddX_r), ca.fabs(k[:2] * E))),
                       ca.fmax(1, ca.fabs(k[2:] * e_o)))
    f = ca.Function("tangential_rotational", [q, dq, R, R_d, X_r, dX_r, ddX_r, m, b, k, u_n], [lhs / scale])
    res = 0.0
    for qv, dqv in _states(impl, rng, STATES):
        Rv = _rotation(rng)
        X_now = (Rv.T @ impl.plant.fk(qv)[:3, 3])[1:]
        R_now = impl.plant.fk(qv)[:3, :3]
        Rd = _rotation(rng) @ R_now if rng.uniform() < 0.5 else R_now     # some states on the command
        vals = [X_now + rng.normal(scale=0.01, size=2), rng.normal(scale=0.1, size=2), rng.normal(size=2),
                rng.uniform(0.5, 2, 5), rng.uniform(1, 100, 5), rng.uniform(10, 1e3, 5), rng.normal()]
        res = max(res, float(np.max(np.abs(np.asarray(f(qv, dqv, Rv, Rd, *vals))))))
    return _result(f"tangential and rotational impedance ({impl.plant.name})", "(8)-(9), other axes",
                   "model = plant, X_a = 0: M E'' + B E' + K E = 0 on the tangential axes and "
                   "M_rot w' + B_rot w = K_rot e_o on the rotational axes (e_o = log(R_c R^T), task axes)",
                   f"CasADi: {impl.plant.name} loop with eq. (6) on every axis and the rotation-vector error of "
                   f"geometry.rotation_vector; {STATES} random states, task frames, commands and impedances",
                   res, ARM_RTOL)


def check_curved_normal_axis(impl: ArmImplementation, rng) -> CheckResult:
    """Eqs. (19)-(22) on a curved surface: the normal coordinate is the depth
    along the local normal, the inner loop maps through the chart."""
    surface, d, n = impl.surface, impl.task_dim, impl.plant.n
    s = {k: ca.MX.sym(k) for k in ("m", "b", "k", "k_e", "f_d", "u")}
    U_rest = ca.MX.sym("U_rest", d - 1)
    q, dq = ca.MX.sym("q", n), ca.MX.sym("dq", n)
    par = {k: ca.DM(v) for k, v in surface.values().items()}
    mf, pf = impl.model.functions, impl.plant.functions
    p, Jv = mf.fk(q)[:3, 3], mf.jacobian(q)[:3, :]
    R, X, dX = surface.coordinates(p, ca.mtimes(Jv, dq), par)
    x, dx = X[0], dX[0]
    x_e = x - s["u"]
    f_e = s["k_e"] * (x - x_e)                                                               # eq. (13)
    x_r = impl.tmt_reference(x, f_e, x_e, s["f_d"], s["k"], 1e-9, 1e-12)                    # eq. (16)
    x_a, dx_a = x_r - x, -dx
    ddx_a = impl.impedance_acceleration(f_e, x_a, dx_a, s["m"], s["b"], s["k"])              # eq. (2)
    x_c, dx_c, ddx_c = impl.command(x_r, x_a), impl.command(0, dx_a), impl.command(0, ddx_a)  # eq. (4)
    u_n = impl.inner_loop(ddx_c, dx_c, x_c, dx, x, s["b"] / s["m"], s["k"] / s["m"])          # eq. (6)
    U_task = ca.vertcat(u_n, U_rest)
    U = surface.acceleration(X, dX, U_task[:3], par)
    if d == 6:
        U = ca.vertcat(U, ca.mtimes(R, U_task[3:]))
    F_n = R[:, 0] * f_e
    J = mf.jacobian(q)[:d, :]
    tau = impl.inner_torque(mf.mass_matrix(q), mf.bias(q, dq), J, mf.jacobian_dot(q, dq)[:d],
                            U, ca.vertcat(F_n, ca.MX.zeros(d - 3))) + mf.friction(dq)
    ddq = pf.forward_dynamics(q, dq, tau - ca.mtimes(pf.jacobian(q)[:3, :].T, F_n))
    # the depth's acceleration by the chain rule through the inverse chart (coordinates of the plant's
    # tool point), not through the chart's own acceleration
    x_plant = surface.coordinates(pf.fk(q)[:3, 3], ca.MX.zeros(3), par)[1][0]
    dx_plant = ca.jtimes(x_plant, q, dq)
    ddx = ca.jtimes(dx_plant, q, dq) + ca.jtimes(dx_plant, dq, ddq)
    eps, deps, ddeps = x_e - x, -dx, -ddx
    k, k_e, f_d = s["k"], s["k_e"], s["f_d"]
    lhs = s["m"] * ddeps + s["b"] * deps + (k + k_e) * eps
    rhs = -f_d * (k + k_e) / k_e
    scale = ca.fmax(1.0, ca.fmax(ca.fabs(rhs), ca.fabs((k + k_e) * eps)))
    f = ca.Function("curved_normal_axis", [q, dq, U_rest, *s.values()], [(lhs - rhs) / scale])
    res = 0.0
    cols = np.linspace(0, impl.path_q.shape[1] - 1, STATES).astype(int)
    for j in cols:
        vals = [rng.uniform(0.5, 2), rng.uniform(1, 100), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 5),
                rng.uniform(1, 50), rng.uniform(1e-4, 1e-2)]
        res = max(res, abs(float(f(impl.path_q[:, j], rng.uniform(-1, 1, n), rng.normal(size=d - 1), *vals))))
    return _result(f"normal axis is eq. (22) on the {surface.kind} ({impl.plant.name})", "(19)-(22)",
                   f"model = plant, E = X_a: on the {surface.kind}, the depth along the local normal obeys eq. (22) "
                   "with the inner loop mapped through the surface's chart (curvature fed forward)",
                   f"CasADi: {impl.plant.name} plant at {STATES} joint states along the scenario's path, random "
                   "joint rates and impedances; the depth's acceleration by the chain rule through the surface's "
                   "coordinates of the plant's tool point", res, ARM_RTOL)


CHECKS_3D = (check_task_acceleration, check_normal_axis)
CHECKS_6D = (check_task_acceleration, check_normal_axis, check_null_space, check_tangential_rotational)


def run_arm_checks(impl: ArmImplementation, seed: int = 2024) -> list[CheckResult]:
    """The arm checks for ``impl``'s task dimension (the rotational check on
    a 6-D task only; the null-space check there and wherever the arm has
    more joints than its task, review 62: a 4-joint arm's posture task went
    unchecked); a check that raises is reported as failed."""
    out = []
    task = impl.plant.task
    checks = CHECKS_6D if task.dim == 6 else ((*CHECKS_3D, check_null_space) if task.posture else CHECKS_3D)
    if impl.surface is not None and impl.surface.turns:
        checks = (*checks, check_curved_normal_axis)
    for i, chk in enumerate(checks):
        rng = np.random.default_rng(seed + 100 + i)
        try:
            out.append(chk(impl, rng))
        except Exception as exc:  # a broken implementation must fail its check, not crash the run
            out.append(CheckResult(chk.__name__, "", chk.__doc__.strip().splitlines()[0], "raised", float("nan"),
                                   False, ARM_RTOL, note=f"{type(exc).__name__}: {exc}"))
    return out
