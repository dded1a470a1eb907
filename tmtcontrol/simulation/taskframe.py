"""The 6-D closed loop in the surface's task frame, for arms with 6 or more joints.

The task is the tool frame's pose: three translational axes (the surface
normal and the two tangential axes of :mod:`.geometry`) and three rotational
axes. Position-based impedance control, eqs. (2)-(6), on each axis:

* normal axis: the force-tracking law (any registered law of
  ``control.laws``, unchanged declarations) gives the command x_c of eq. (4);
  the force-sensor filter, the guarded approach and the damping schedule are
  :mod:`.closedloop`'s own expressions (its ``_control`` without the inner
  loop), so the normal axis of a 6-D arm is the PUMA's normal axis;
* tangential axes: the impedance adjustment is zero (no tangential force)
  and the command is the circle;
* rotational axes: the command is the tool orientation R_c of
  :func:`.geometry.tool_orientation`. The rotational impedance filter's input
  is the contact moment about the tool point, zero for the point contact
  modelled here, so its adjustment X_a stays 0 and eq. (4) gives X_c = R_c;
  the rotational axes track it with the inner-loop gains of eq. (9),
  K_D = B_rot/M_rot, K_P = K_rot/M_rot. The orientation error is the rotation
  vector e_o = log(R_c R^T)^vee (base frame, rad) expressed on the task axes;
  the angular velocity is omega = J_w dq.

Inner loop, eqs. (5)-(6), as the operational-space computed torque with the
controller's model (M^, n^ = C^ dq + g^, J, dJ dq)::

    U   = [R (ddX_c + K_D (dX_c - dX) + K_P (X_c - X));  R (K_D,rot (-omega_task) + K_P,rot e_o,task)]
    Lambda = (J M^-1 J^T)^-1                      (D*^ of eq. 5)
    F   = Lambda (U - dJ dq) + F_e,  F_e = [f_m e_n; 0]
    tau = J^T F + n^ + N^T tau_0,  N^T = I - J^T Lambda J M^-1

For a square J (6 joints) J^T Lambda J M^-1 = I and N^T = 0: tau is eq. (5)
exactly. For a redundant arm (7 joints) ``tau_0 = M^ (K_post (q_post - q) -
D_post dq)`` is the null-space posture task (``robot.posture_kp``,
``robot.posture_kd``; q_post the solved start posture) and N^T is the
dynamically consistent projector: J M^-1 N^T = 0, so the posture torque does
not change the task acceleration (tested).

The plant is eq. (1) of the robot (``load_robot``) with the unilateral
contact acting on the tool point along the normal, integrated as the PUMA's
(RK4 with contact refinement, or CVODES). Nothing here asks which arm it
is: the task dimension follows from the robot (the 3-joint PUMA keeps its
position-only loop in :mod:`.closedloop`, bit for bit). This is a separate
builder sharing the law, the impedance helpers, the normal-axis controller
and the plant integrator with :mod:`.closedloop`, not a rewrite of it: the
PUMA's expressions there must serialise identically.

The computation delay (``controller.delay_samples`` = d) is the PUMA's: the
torque computed at t_k is applied over [t_(k+d), t_(k+d+1)), the state's
``tau_wait`` holding the d waiting torques of n joints (oldest first).

The exported controller (``tmtcontrol export``) is :func:`build_pose_controller`,
the step's controller alone (the same helper :func:`_pose_control`), with the
joint position command found by Newton steps on the pose; the plant alone is
:func:`build_pose_plant` (software in the loop).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..control.impedance import inner_loop
from ..control.laws import Law
from .closedloop import INPUT, Layout, _control, _plant_function, _rk4, param_layout
from .environment import contact_force
from .geometry import rotation_vector

__all__ = ["pose_state_layout", "pose_param_layout", "pose_log_layout", "POSE_INPUT", "build_pose_step",
           "operational_space_torque", "pose_step_name", "build_pose_plant", "build_pose_controller",
           "pose_controller_state_layout", "pose_controller_param_layout", "pose_measurement_layout",
           "pose_command_layout", "POSE_DIAGNOSTICS", "pose_ik_steps"]

POSE_INPUT = INPUT
"""Per-sample inputs, as the PUMA's loop: tangential reference, k_e, noise."""


def pose_state_layout(n: int, law: Law, delay: int = 0) -> Layout:
    """Closed-loop state: joints (n, rad; n, rad/s) then the normal axis'
    controller state of :func:`.closedloop.state_layout`, whose delay queue
    holds the ``delay`` torques of n joints computed but not yet applied (N m,
    oldest first)."""
    return Layout(("q", n), ("dq", n), ("f_filt", 1), ("b_n", 1), ("approach", 1), ("x_app", 1),
                  ("ramp", 1), ("x_e_hat", 1), ("tau_wait", n * delay), ("law", len(law.states)))


def pose_param_layout(n: int, law: Law) -> Layout:
    """The PUMA loop's parameters (:func:`.closedloop.param_layout`), then the
    commanded tool orientation R_d (column-major), the rotational inner-loop
    gains K_D,rot (1/s) and K_P,rot (1/s^2), the posture q_post (n) and the
    null-space gains K_post (1/s^2), D_post (1/s)."""
    base = param_layout(law)
    return Layout(*((k, s.stop - s.start) for k, s in base.slices.items()),
                  ("R_d", 9), ("kd_rot", 3), ("kp_rot", 3), ("q_post", n), ("kp_post", 1), ("kd_post", 1))


def pose_log_layout(n: int) -> Layout:
    """Per-sample log at t_k: joints, torque (N m), tool position (base, m),
    task position X, reference X_r, command X_c (task, m), true and measured
    normal force (N), normal damping (N s/m), desired force in use (N),
    surface estimate (m), and the orientation error e_o (rad, task axes)."""
    return Layout(("q", n), ("dq", n), ("tau", n), ("p", 3), ("X", 3), ("X_r", 3), ("X_c", 3),
                  ("f_e", 1), ("f_m", 1), ("b_n", 1), ("f_d", 1), ("x_e_hat", 1), ("e_o", 3))


def pose_step_name(law: Law, n: int, delay: int = 0) -> str:
    """The name of :func:`build_pose_step`'s Function (and of its compiled library)."""
    return f"pose{n}_step_{law.name}" + (f"_delay{delay}" if delay else "")


def operational_space_torque(M, n_bias, J, Jdot_dq, U, F_e, tau_0=None):
    """Eq. (5) mapped to the joints for a 6 x n Jacobian (n >= 6):
    ``tau = J^T (Lambda (U - dJ dq) + F_e) + n + N^T tau_0`` with
    ``Lambda = (J M^-1 J^T)^-1`` and the dynamically consistent null-space
    projector ``N^T = I - J^T Lambda J M^-1`` (``tau_0``: None for no
    null-space torque). CasADi symbols; base frame.

    For a square J (6 joints) J is invertible on the checked path and the
    same torque is ``tau = M J^-1 (U - dJ dq) + J^T F_e + n`` (Lambda =
    J^-T M J^-1): one 6 x 6 solve instead of two, about 8 % fewer
    instructions in the UR5's step; equal to the general form to rounding
    (tests/test_taskframe.py)."""
    if J.size1() == J.size2() and tau_0 is None:
        return ca.mtimes(M, ca.solve(J, U - Jdot_dq, "symbolicqr")) + ca.mtimes(J.T, F_e) + n_bias
    A = ca.solve(M, J.T, "symbolicqr")                  # M^-1 J^T (n x 6)
    Linv = ca.mtimes(J, A)                              # J M^-1 J^T
    tau = ca.mtimes(J.T, ca.solve(Linv, U - Jdot_dq, "symbolicqr") + F_e) + n_bias
    if tau_0 is not None:
        tau = tau + tau_0 - ca.mtimes(J.T, ca.solve(Linv, ca.mtimes(A.T, tau_0), "symbolicqr"))
    return tau


def _kinematics(robot, q, dq, R, c):
    T = robot.functions.fk(q)
    J = robot.functions.jacobian(q)
    p = T[:3, 3]
    return p, T[:3, :3], J, ca.mtimes(R.T, p - c), ca.mtimes(R.T, ca.mtimes(J[:3, :], dq))


def _plant_step(plant, integrator: str, substeps: int, tol: float, contact_refine: int):
    """As :func:`.closedloop._plant_step` for an n-joint robot:
    ``pz = [tau (n), k_e, d_e, R (9), c (3), Ts]``."""
    n = plant.n
    z = ca.SX.sym("z", 2 * n)
    pz = ca.SX.sym("pz", n + 1 + 1 + 9 + 3 + 1)
    tau, k_e, d_e = pz[0:n], pz[n], pz[n + 1]
    R = ca.reshape(pz[n + 2:n + 11], 3, 3)
    c, Ts = pz[n + 11:n + 14], pz[n + 14]

    def ode(z):
        q, dq = z[:n], z[n:]
        _, _, J, X, dX = _kinematics(plant, q, dq, R, c)
        f_env = contact_force(X[0], dX[0], k_e, d_e)
        ddq = plant.functions.forward_dynamics(q, dq, tau - ca.mtimes(J[:3, :].T, R[:, 0] * f_env))
        return Ts * ca.vertcat(dq, ddq), f_env > 0

    if integrator == "cvodes":
        flow = ca.integrator("plant", "cvodes", {"x": z, "p": pz, "ode": ode(z)[0]}, 0.0, 1.0,
                             {"abstol": tol, "reltol": tol, "max_num_steps": 100000})
        return None, None, flow
    if integrator != "fixed":
        raise ValueError(f"integrator: expected 'fixed' or 'cvodes', got {integrator!r}")
    coarse = _rk4(ode, z, pz, substeps)
    choose = None
    if contact_refine > 1:
        zm, z1, pm = ca.MX.sym("z", 2 * n), ca.MX.sym("z1", 2 * n), ca.MX.sym("pz", pz.numel())
        k = int(contact_refine)
        zr, p_sub = zm, ca.vertcat(pm[:-1], pm[-1] / k)
        for _ in range(k):
            zr = coarse(zr, p_sub)[0]
        choose = ca.Function.conditional("refine_at_contact_switch",
                                         [ca.Function("keep", [zm, z1, pm], [z1])],
                                         ca.Function("refine", [zm, z1, pm], [zr]))
    return coarse, choose, None


def _pose_control(model, law: Law, S: dict, P: dict, ref: dict, R, q, dq, kin, f_sensor, delay: int = 0,
                  torque: bool = True) -> dict:
    """The 6-D controller at t_k from the sampled measurements, as MX
    expressions: :func:`.closedloop._control` on the normal axis (force
    filter, guarded approach, damping schedule, the law's command of eq. 4),
    the orientation error e_o, and (``torque``) the inner loop (eq. 6) on the
    six task axes with the operational-space torque (eq. 5) and the
    computation delay's queue: the torque computed now is applied ``delay``
    periods later (``tau``, N m, the one applied over [t_k, t_k+1));
    ``tau_wait`` the queue after this period, oldest first. ``kin`` is
    :func:`_kinematics` of the encoders, ``f_sensor`` the normal force read
    this period (N, before the filter). Used by :func:`build_pose_step` (the
    simulation) and :func:`build_pose_controller` (the exported controller):
    one set of expressions for both."""
    n = model.n
    pos, R_tool, J, X, dX = kin
    c = _control(None, law, S, P, ref, R, q, dq, J[:3, :], X, dX, f_sensor, 0, torque=False)
    # rotational axes: X_c = R_d (X_a = 0), the error on the task axes
    e_o = ca.mtimes(R.T, rotation_vector(ca.mtimes(ca.reshape(P["R_d"], 3, 3), R_tool.T)))
    c.update(e_o=e_o, tau=None, tau_wait=None)
    if not torque:
        return c
    # translational axes, eq. (6) on the task axes (normal damping possibly scheduled, K_D = B/M)
    kd = ca.vertcat(ca.if_else(P["sched"] > 0, c["b_n"] / P["m"][0], P["kd"][0]), P["kd"][1:])
    U_pos = inner_loop(c["ddX_c"], c["dX_c"], c["X_c"], dX, X, kd, P["kp"])
    w = ca.mtimes(R.T, ca.mtimes(J[3:, :], dq))
    U_rot = inner_loop(0, 0, e_o, w, 0, P["kd_rot"], P["kp_rot"])
    U = ca.vertcat(ca.mtimes(R, U_pos), ca.mtimes(R, U_rot))
    F_e = ca.vertcat(R[:, 0] * c["f_m"], ca.MX.zeros(3))
    M = model.functions.mass_matrix(q)
    tau_0 = None
    if n > 6:                                                        # null-space posture task
        tau_0 = ca.mtimes(M, P["kp_post"] * (P["q_post"] - q) - P["kd_post"] * dq)
    tau = operational_space_torque(M, model.functions.bias(q, dq), J, model.functions.jacobian_dot(q, dq),
                                   U, F_e, tau_0) + model.functions.friction(dq)
    if delay:           # apply the oldest waiting torque; queue this one
        queue = ca.vertcat(S["tau_wait"], tau)
        tau, tau_wait = queue[:n], queue[n:]
    else:
        tau_wait = ca.MX(0, 1)
    c.update(tau=tau, tau_wait=tau_wait)
    return c


def build_pose_step(plant, model, law: Law, integrator: str = "fixed", substeps: int = 1, tol: float = 1e-10,
                    contact_refine: int = 4, delay: int = 0) -> ca.Function:
    """One control period of the 6-D loop, ``["s","u","p"] -> ["s_next","log"]``
    (layouts :func:`pose_state_layout`, :data:`POSE_INPUT`,
    :func:`pose_param_layout`, :func:`pose_log_layout`). ``plant`` and
    ``model`` are robots from ``load_robot`` with the same joints (the model
    may be mass-scaled or carry friction to compensate). ``delay``: the
    computation delay in samples, as the PUMA's loop (the torque computed at
    t_k is applied over [t_(k+delay), t_(k+delay+1)); the log's ``tau`` is
    the torque applied)."""
    n = plant.n
    if model.n != n or n < 6:
        raise ValueError(f"the 6-D loop needs a robot with >= 6 joints and a model with as many, got {n}, {model.n}")
    coarse, choose, flow = _plant_step(plant, integrator, substeps, tol, contact_refine)
    STATE, PARAM = pose_state_layout(n, law, delay), pose_param_layout(n, law)
    s, u, p = ca.MX.sym("s", STATE.size), ca.MX.sym("u", POSE_INPUT.size), ca.MX.sym("p", PARAM.size)
    S, U_in, P = STATE.split(s), POSE_INPUT.split(u), PARAM.split(p)
    R, c0 = ca.reshape(P["R"], 3, 3), P["c"]
    q, dq = S["q"], S["dq"]
    kin = _kinematics(model, q, dq, R, c0)                         # encoders through fk
    pos, _, _, X, dX = kin
    f_true = contact_force(X[0], dX[0], U_in["k_e"], P["d_e"])
    c = _pose_control(model, law, S, P, U_in, R, q, dq, kin, f_true + U_in["noise"], delay)
    tau, e_o = c["tau"], c["e_o"]
    pz = ca.vertcat(tau, U_in["k_e"], P["d_e"], P["R"], c0, P["Ts"])
    z0 = ca.vertcat(q, dq)
    rest = ca.vertcat(c["f_m"], c["b_n"], ca.if_else(c["engaged"], 0, 1), c["x_app"], c["ramp"], c["x_e_hat"],
                      *([c["tau_wait"]] if delay else []), c["law_next"])
    log = ca.vertcat(q, dq, tau, pos, X, c["X_r"], c["X_c"], f_true, c["f_m"], c["b_n"], c["f_d"],
                     c["x_e_hat"], e_o)
    name = pose_step_name(law, n, delay)
    if flow is not None:
        zf = flow(x0=z0, p=pz)["xf"]
        return ca.Function(name, [s, u, p], [ca.vertcat(zf, rest), log], ["s", "u", "p"], ["s_next", "log"])
    ctrl = ca.Function("ctrl", [s, u, p], [z0, pz, rest, log]).expand()
    sx = [ca.SX.sym(k, ctrl.size1_in(i)) for i, k in enumerate(("s", "u", "p"))]
    z0s, pzs, rests, logs = ctrl(*sx)
    zc, switched = coarse(z0s, pzs)
    if choose is None:
        return ca.Function(name, sx, ca.cse([ca.vertcat(zc, rests), logs]), ["s", "u", "p"], ["s_next", "log"])
    fused = ca.Function(f"{name}_ctrl_plant", sx, ca.cse([z0s, pzs, zc, switched, rests, logs]))
    sm, um, pm = (ca.MX.sym(k, fused.size1_in(i)) for i, k in enumerate(("s", "u", "p")))
    z0m, pzm, zcm, sw, restm, logm = fused(sm, um, pm)
    return ca.Function(name, [sm, um, pm], [ca.vertcat(choose(sw, z0m, zcm, pzm), restm), logm],
                       ["s", "u", "p"], ["s_next", "log"])


# -- the same loop split at the sensors: plant and controller as two Functions --------------------
# (software-in-the-loop: tmtcontrol.export generates C from build_pose_controller and steps build_pose_plant)

def build_pose_plant(plant, integrator: str = "fixed", substeps: int = 1, tol: float = 1e-10,
                     contact_refine: int = 4) -> ca.Function:
    """The plant of :func:`build_pose_step` alone over one period: ``["z","pz"]
    -> ["zf"]``, joints ``z = [q, dq]`` (n rad, n rad/s) and ``pz = [tau (n,
    N m), k_e (N/m), d_e (N s/m), R (column-major), c (m), Ts (s)]``, with the
    same integrator and contact refinement."""
    n = plant.n
    return _plant_function(*_plant_step(plant, integrator, substeps, tol, contact_refine), 2 * n, n + 15)


def pose_controller_state_layout(n: int, law: Law, delay: int = 0, torque: bool = True) -> Layout:
    """The 6-D controller's own state: :func:`pose_state_layout` without the
    joints (the delay queue only with ``torque``)."""
    full = pose_state_layout(n, law, delay if torque else 0)
    return Layout(*((k, s.stop - s.start) for k, s in full.slices.items() if k not in ("q", "dq")))


def pose_controller_param_layout(n: int, law: Law) -> Layout:
    """The 6-D controller's parameters: :func:`pose_param_layout` without the
    environment's damping ``d_e`` (a property of the simulated surface)."""
    full = pose_param_layout(n, law)
    return Layout(*((k, s.stop - s.start) for k, s in full.slices.items() if k != "d_e"))


def pose_measurement_layout(n: int) -> Layout:
    """The 6-D controller's inputs each period: joint positions (n, rad) and
    velocities (n, rad/s), the contact force on the tool (N, base frame), the
    tangential reference position (m), velocity (m/s) and acceleration
    (m/s^2) on task axes 2 and 3 (as :data:`.closedloop.MEASUREMENT`)."""
    return Layout(("q", n), ("dq", n), ("force", 3), ("pos_t", 2), ("vel_t", 2), ("acc_t", 2))


def pose_command_layout(n: int, torque: bool = True) -> Layout:
    """The 6-D controller's outputs: the command of eq. (4) on the translational
    axes X_c, dX_c, ddX_c (task frame: m, m/s, m/s^2), the commanded tool
    position p_c = R X_c + c (base frame, m), the joint position command q_c
    (n, rad) with the tool at p_c in the commanded orientation R_d
    (:func:`pose_ik_steps` Newton steps on the pose from the measured
    joints, least-norm steps on a redundant arm), the joint velocity
    command dq_c = J(q_c)^+ [R dX_c; 0] (n, rad/s), and with ``torque`` the
    joint torques of eqs. (5)-(6) (n, N m)."""
    return Layout(("X_c", 3), ("dX_c", 3), ("ddX_c", 3), ("p_c", 3), ("q_c", n), ("dq_c", n),
                  ("tau", n if torque else 0))


POSE_DIAGNOSTICS = Layout(("X", 3), ("dX", 3), ("X_r", 3), ("p", 3), ("f_m", 1), ("b_n", 1), ("f_d", 1),
                          ("x_e_hat", 1), ("e_o", 3))
"""As :data:`.closedloop.DIAGNOSTICS` (tool position instead of the wrist
centre) and the orientation error e_o (rad, task axes)."""


def pose_ik_steps(n: int) -> int:
    """Newton steps of the 6-D joint position command: 4 on a 6-joint arm
    (:data:`.closedloop.IK_NEWTON_STEPS`), 8 least-norm steps on a redundant
    arm, whose first steps converge slower. The command lies up to f_d/k
    (0.1 m) from the measured pose at the start of the built-in scenarios;
    these counts reach it to rounding there (tests/test_export_6d.py)."""
    from .closedloop import IK_NEWTON_STEPS

    return IK_NEWTON_STEPS if n == 6 else 2 * IK_NEWTON_STEPS


def _pose_newton(model, J, pos, R_tool, q, p_c, R_d):
    """:func:`pose_ik_steps` Newton steps on the pose error [p_c - p;
    log(R_d R^T)^vee] from the measured joints ``q`` (least-norm steps J^T (J
    J^T)^-1 on a redundant arm): ``(q_c, J(q_c))``."""
    n = model.n
    q_c, J_c, p, Rt = q, J, pos, R_tool
    for _ in range(pose_ik_steps(n)):       # a fixed count: constant execution time
        e = ca.vertcat(p_c - p, rotation_vector(ca.mtimes(R_d, Rt.T)))
        q_c = q_c + (ca.solve(J_c, e, "symbolicqr") if n == 6 else
                     ca.mtimes(J_c.T, ca.solve(ca.mtimes(J_c, J_c.T), e, "symbolicqr")))
        T = model.functions.fk(q_c)
        J_c, p, Rt = model.functions.jacobian(q_c), T[:3, 3], T[:3, :3]
    return q_c, J_c


def build_pose_controller(model, law: Law, delay: int = 0, torque: bool = True,
                          name: str = "tmt_controller") -> ca.Function:
    """The controller of :func:`build_pose_step` alone (the same expressions,
    :func:`_pose_control`), expanded to SX: ``name: ["s","y","p"] ->
    ["s_next","cmd","diag"]`` with the state
    :func:`pose_controller_state_layout`, the measurement
    :func:`pose_measurement_layout`, the parameters
    :func:`pose_controller_param_layout`, the command
    :func:`pose_command_layout` and :data:`POSE_DIAGNOSTICS`.
    ``torque=False`` leaves out the inner loop (eqs. 5-6) and the delay
    queue: the command for a position-controlled robot."""
    n = model.n
    STATE, PARAM = pose_controller_state_layout(n, law, delay, torque), pose_controller_param_layout(n, law)
    MEAS = pose_measurement_layout(n)
    s, y, p = ca.MX.sym("s", STATE.size), ca.MX.sym("y", MEAS.size), ca.MX.sym("p", PARAM.size)
    S, Y, P = STATE.split(s), MEAS.split(y), PARAM.split(p)
    R = ca.reshape(P["R"], 3, 3)
    q, dq = Y["q"], Y["dq"]
    kin = _kinematics(model, q, dq, R, P["c"])
    pos, R_tool, J, X, dX = kin
    f_sensor = -ca.dot(R[:, 0], Y["force"])                 # normal force pushing on the surface
    c = _pose_control(model, law, S, P, Y, R, q, dq, kin, f_sensor, delay if torque else 0, torque)
    p_c = ca.mtimes(R, c["X_c"]) + P["c"]
    q_c, J_c = _pose_newton(model, J, pos, R_tool, q, p_c, ca.reshape(P["R_d"], 3, 3))
    v_c = ca.vertcat(ca.mtimes(R, c["dX_c"]), ca.MX.zeros(3))
    dq_c = (ca.solve(J_c, v_c, "symbolicqr") if n == 6 else
            ca.mtimes(J_c.T, ca.solve(ca.mtimes(J_c, J_c.T), v_c, "symbolicqr")))
    queue = c["tau_wait"] if torque else ca.MX(0, 1)
    s_next = ca.vertcat(c["f_m"], c["b_n"], ca.if_else(c["engaged"], 0, 1), c["x_app"], c["ramp"],
                        c["x_e_hat"], queue, c["law_next"])
    cmd = ca.vertcat(c["X_c"], c["dX_c"], c["ddX_c"], p_c, q_c, dq_c, c["tau"] if torque else ca.MX(0, 1))
    diag = ca.vertcat(X, dX, c["X_r"], pos, c["f_m"], c["b_n"], c["f_d"], c["x_e_hat"], c["e_o"])
    return ca.Function(name, [s, y, p], [s_next, cmd, diag], ["s", "y", "p"],
                       ["s_next", "cmd", "diag"]).expand()
