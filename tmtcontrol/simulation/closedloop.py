"""One control period of the sampled closed loop, for every arm and every surface, assembled symbolically.

At each sample t_k the controller reads the joint encoders (the tool point
and orientation through fk) and the force sensor, asks the force-tracking
law (``control.laws``) for the normal-axis command of eq. (4) (the law owns
its reference, eqs. 11-18 or a baseline, and its impedance filter, eqs.
2-3), forms the inner loop (eq. 6) on every task axis and the control force
of eq. (5), mapped to joint torques. The torque is held (zero-order hold)
while a CasADi integrator advances the continuous plant, eq. (1) in joint
space with the unilateral contact of the surface (:mod:`tmtcontrol.surface`).

The task is the robot's (:attr:`tmtcontrol.model.Robot.task`), declared
once: the tool point's position (3 axes) on an arm with 3 to 5 joints, its
position and orientation (6 axes) on 6 or more; an arm with more joints than
task axes also runs a null-space posture task. On each axis:

* normal axis (task axis 0, the surface's inward normal): the law's command
  x_c of eq. (4), with the force-sensor filter, the guarded approach and the
  damping schedule;
* tangential axes: the impedance adjustment is zero (no tangential force)
  and the command is the path;
* rotational axes (6-D task): the command is the tool orientation R_d of
  :func:`.geometry.tool_orientation`, on a curved surface turned with the
  surface's frame at the command's point (``surface.turn``), its angular
  velocity and acceleration fed forward. The rotational impedance filter's
  input is the contact moment about the tool point, zero for the point
  contact modelled here, so its adjustment stays 0 and eq. (4) gives X_c =
  R_d; they track it with the inner-loop gains of eq. (9), K_D = B_rot/M_rot,
  K_P = K_rot/M_rot. The orientation error is the rotation vector
  e_o = log(R_d R^T)^vee (base frame, rad) on the task axes; the angular
  velocity omega = J_w dq.

On a curved surface the task coordinates are the surface's chart (depth
along the local normal, arc lengths): eq. (6) acts on them and its output
is mapped to a Cartesian acceleration through the chart
(``surface.acceleration``: the curvature feed-forward; a plane's is R U).

Inner loop, eqs. (5)-(6), as the operational-space computed torque with the
controller's model (M^, n^ = C^ dq + g^, the task Jacobian J: the linear rows
of the geometric Jacobian, and the angular rows on a 6-D task)::

    U   = R-rotated ddX_c + K_D (dX_c - dX) + K_P (X_c - X)   per task axis (eq. 6)
    tau = M^ J^-1 (U - dJ dq) + n^ + J^T F_e                  square J (eq. 5, J^T F)
    tau = J^T (Lambda (U - dJ dq) + F_e) + n^ + N^T tau_0     redundant arm,
          Lambda = (J M^-1 J^T)^-1,  N^T = I - J^T Lambda J M^-1,
          tau_0 = M^ (K_post (q_post - q) - D_post dq)

with F_e = f_m e_n; N^T is the dynamically consistent projector (J M^-1 N^T
= 0: the posture torque does not change the task acceleration, tested).

Two things real controllers have are part of the loop (beyond the paper):

* a computation delay of N samples (``delay``, structural): the torque
  computed at t_k is applied over [t_(k+N), t_(k+N+1)); the state carries
  the N torques computed but not yet applied;
* a mid-period hold (``hold``, structural; ``controller.hold =
  "mid_period"``): the torque held over [t_k, t_k+1) is extrapolated to the
  period's middle from the last two computed, tau_k + (tau_k - tau_k-1)/2.
  The zero-order hold applies the torque computed at t_k for the whole
  period, a lag of Ts/2 that leaves a force ripple proportional to Ts where
  the task's feed-forward changes (a curved part's turning normal, a
  circle's centripetal acceleration); the extrapolation cancels its first
  order (the ripple falls with Ts^2; docs/surfaces.md). A jump
  of the computed torque (the impedance filter's answer to a stiffness
  step) is overshot by half for one period, which the torque-limit verdicts
  see. It adds a lead to the loop that the whole-loop and periodic analyses
  see (they run this step); the 1-D sampled model does not. With a
  computation delay the extrapolation still aims at t_k + Ts/2 (the delay
  is not predicted);
* a guarded approach (first contact from a gap above the surface): while
  ``approach`` is 1 the normal command advances toward the surface at the
  approach speed, x_c = x_app, dx_c = v, ddx_c = 0, and the law's state is
  held. When the measured force exceeds the contact threshold the surface
  estimate becomes the contact point (plus the configured x_e error), and
  the law takes over with its desired force ramped from 0 to f_d over the
  force ramp. Starting on the surface (``approach`` = 0, ramp = 1) is the
  paper's loop, unchanged.

:func:`build_step` returns ``step: ["s", "u", "p"] -> ["s_next", "log"]``,
laid out by :func:`state_layout`, :data:`INPUT`, :func:`param_layout` and
:func:`log_layout`. Numeric settings (gains, f_d, law parameters, the
surface's parameters, stiffness, noise) are entries of ``p``/``u``; only the
robot, the surface's shape, the integrator and the law's structure change
the Function. The closed loop never asks which law, arm or shape it runs.
:func:`build_controller` (the exported controller) and :func:`build_plant`
(software in the loop) are the same loop split at the sensors.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..control.impedance import inner_loop
from ..control.laws import MEASUREMENTS, Law
from ..surface import Plane, contact_force
from .geometry import rotation_vector

__all__ = ["INPUT", "Layout", "state_layout", "param_layout", "log_layout", "damping_schedule",
           "operational_space_torque", "build_step", "build_tangent", "step_name", "build_plant",
           "build_controller", "controller_state_layout", "controller_param_layout", "measurement_layout",
           "command_layout", "diagnostics_layout", "ik_steps", "IK_NEWTON_STEPS", "plant_inputs_layout", "kinematics",
           "MID_PERIOD", "believed"]


class Layout:
    """Named slices of a flat vector: ``layout["q"]`` is a slice. A field may
    have size 0 (a part the task does not have); :meth:`pack` needs no value
    for it."""

    def __init__(self, *fields: tuple[str, int]):
        self.slices = {}
        i = 0
        for name, n in fields:
            self.slices[name] = slice(i, i + n)
            i += n
        self.size = i

    def __getitem__(self, name):
        return self.slices[name]

    def __contains__(self, name) -> bool:
        return name in self.slices

    def sizes(self) -> dict:
        """Field name -> size."""
        return {k: s.stop - s.start for k, s in self.slices.items()}

    def split(self, vec):
        return {name: vec[s] for name, s in self.slices.items()}

    def pack(self, **values) -> np.ndarray:
        out = np.zeros(self.size)
        for name, s in self.slices.items():
            if s.stop > s.start:
                out[s] = np.ravel(values[name])
        return out


def state_layout(task, law: Law, delay: int = 0, hold: bool = False) -> Layout:
    """Closed-loop state: joints (n rad, n rad/s), force-sensor filter state
    (N), scheduled normal damping (N s/m), approach phase (1 while
    approaching, else 0), approach command x_app (m, task normal), progress
    of the f_d ramp (0..1), the controller's surface estimate x_e_hat (m),
    the ``delay`` torques of n joints waiting to be applied (N m, oldest
    first), with the mid-period ``hold`` the last period's computed torque
    (n, N m) and whether there was one (0/1), then the law's own state."""
    n, h = task.n, int(bool(hold))
    return Layout(("q", n), ("dq", n), ("f_filt", 1), ("b_n", 1), ("approach", 1), ("x_app", 1),
                  ("ramp", 1), ("x_e_hat", 1), ("tau_wait", n * delay), ("tau_prev", n * h), ("held", h),
                  ("law", len(law.states)))


INPUT = Layout(("pos_t", 2), ("vel_t", 2), ("acc_t", 2), ("k_e", 1), ("noise", 1))
"""Per-sample inputs: tangential reference (task axes 1, 2), true stiffness
k_e (N/m), force-sensor noise sample (N)."""

MID_PERIOD = 0.5
"""With the mid-period hold, the held torque is tau_k + MID_PERIOD (tau_k -
tau_k-1): the linear extrapolation of the computed torque to t_k + Ts/2, the
time the zero-order hold's torque acts on average."""


def param_layout(task, law: Law, surface=Plane) -> Layout:
    """Constant parameters: impedance M, B, K and gains K_D, K_P (translational
    task axes); f_d (N); controller's x_e (m); force filter pole alpha;
    environment damping (N s/m); the surface's parameters (a plane: task
    frame R, column-major, and origin c, m: the true part's); the error of
    the controller's part position (m, base frame: it believes the origin at
    c + part_offset); control period Ts (s); damping
    schedule on/off, target ratio, bounds on b (N s/m), rate limit (N s/m
    per s), largest and smallest stiffness estimate (N/m) and force
    threshold (N); approach speed (m/s), contact threshold (N) and f_d ramp
    rate (1/s); the law's parameters; on a 6-D task the commanded tool
    orientation R_d (column-major) and the rotational gains K_D,rot (1/s),
    K_P,rot (1/s^2); on a redundant arm the posture q_post (n, rad) and the
    null-space gains K_post (1/s^2), D_post (1/s); the drive's torque clip
    tau_max (n, N m; inf: no clip, ``robot.saturate`` off)."""
    r, post = task.rotational, task.posture
    return Layout(("m", 3), ("b", 3), ("k", 3), ("kd", 3), ("kp", 3), ("f_d", 1), ("x_e_hat", 1),
                  ("alpha", 1), ("d_e", 1), *surface.fields, ("part_offset", 3), ("Ts", 1), ("sched", 1),
                  ("zeta", 1),
                  ("b_min", 1), ("b_max", 1), ("b_rate", 1), ("k_hat_max", 1), ("k_hat_min", 1),
                  ("sched_f_th", 1), ("v_app", 1), ("f_contact", 1), ("ramp_rate", 1),
                  ("law", len(law.parameter_names)),
                  ("R_d", 9 if r else 0), ("kd_rot", r), ("kp_rot", r),
                  ("q_post", task.n if post else 0), ("kp_post", 1 if post else 0), ("kd_post", 1 if post else 0),
                  ("tau_max", task.n))


def log_layout(task) -> Layout:
    """Per-sample log at t_k: joints, torque applied over [t_k, t_k+1) (N m),
    tool position (base, m), task position X, reference X_r, command X_c
    (task, m), true and measured normal force (N), normal impedance damping
    in use (N s/m), desired force in use (N, ramped after an approach), the
    surface estimate (m) and, on a 6-D task, the orientation error e_o (rad,
    task axes)."""
    n = task.n
    return Layout(("q", n), ("dq", n), ("tau", n), ("p", 3), ("X", 3), ("X_r", 3), ("X_c", 3),
                  ("f_e", 1), ("f_m", 1), ("b_n", 1), ("f_d", 1), ("x_e_hat", 1), ("e_o", task.rotational))


def plant_inputs_layout(task, surface=Plane) -> Layout:
    """The plant's parameters over one period: joint torques (n, N m), k_e
    (N/m), contact damping d_e (N s/m), the surface's parameters, Ts (s)."""
    return Layout(("tau", task.n), ("k_e", 1), ("d_e", 1), *surface.fields, ("Ts", 1))


def damping_schedule(b_prev, f_m, depth, m, k, P):
    """Stiffness-scheduled normal damping: eq. (25) used online.

    ``b* = 2 zeta sqrt(m (k + k_hat))`` with the TMT estimate
    ``k_hat = f_m/depth`` (eq. 14), clamped to [k_hat_min, k_hat_max];
    while the force is below twice the threshold (no usable estimate, or
    noise) the target is the previous value (hold). The result is clamped to
    [b_min, b_max] and rate-limited to ``b_rate`` N s/m per second.
    """
    ok = ca.logic_and(f_m > 2 * P["sched_f_th"], depth > 0)
    k_hat = ca.fmin(ca.fmax(f_m / ca.fmax(depth, 1e-12), P["k_hat_min"]), P["k_hat_max"])
    target = ca.if_else(ok, 2 * P["zeta"] * ca.sqrt(m * (k + k_hat)), b_prev)
    target = ca.fmin(ca.fmax(target, P["b_min"]), P["b_max"])
    step = P["b_rate"] * P["Ts"]
    return b_prev + ca.fmin(ca.fmax(target - b_prev, -step), step)


def operational_space_torque(M, n_bias, J, Jdot_dq, U, F_e, tau_0=None):
    """Eq. (5) mapped to the joints for a d x n task Jacobian (n >= d):
    ``tau = J^T (Lambda (U - dJ dq) + F_e) + n + N^T tau_0`` with
    ``Lambda = (J M^-1 J^T)^-1`` and the dynamically consistent null-space
    projector ``N^T = I - J^T Lambda J M^-1`` (``tau_0``: None for no
    null-space torque). CasADi symbols; base frame.

    For a square J (Lambda = J^-T M J^-1) the same torque is ``tau = M J^-1
    (U - dJ dq) + n + J^T F_e``: one solve instead of two (equal to the
    general form to rounding, tests/test_taskframe.py)."""
    if J.size1() == J.size2() and tau_0 is None:
        return ca.mtimes(M, ca.solve(J, U - Jdot_dq, "symbolicqr")) + n_bias + ca.mtimes(J.T, F_e)
    A = ca.solve(M, J.T, "symbolicqr")                  # M^-1 J^T (n x d)
    Linv = ca.mtimes(J, A)                              # J M^-1 J^T
    tau = ca.mtimes(J.T, ca.solve(Linv, U - Jdot_dq, "symbolicqr") + F_e) + n_bias
    if tau_0 is not None:
        tau = tau + tau_0 - ca.mtimes(J.T, ca.solve(Linv, ca.mtimes(A.T, tau_0), "symbolicqr"))
    return tau


def kinematics(robot, surface, q, dq, P):
    """The encoders through fk: ``(p, R_tool, J, R, X, dX)``: tool point (m,
    base), tool orientation, the 6 x n geometric Jacobian, and the
    surface's task frame and coordinates at p (m, m/s)."""
    T = robot.functions.fk(q)
    J = robot.functions.jacobian(q)
    p = T[:3, 3]
    R, X, dX = surface.coordinates(p, ca.mtimes(J[:3, :], dq), P)
    return p, T[:3, :3], J, R, X, dX


def _rk4(ode, z, pz, n: int) -> ca.Function:
    """``n`` classical Runge-Kutta steps over [0, 1]: ``(z, pz) -> (zf,
    switched)``, ``switched`` = 1 if the contact state differs between the
    stages (the period contains a kink of the contact force)."""
    h = 1.0 / n
    zf, states = z, []
    for _ in range(n):
        k1, c1 = ode(zf)
        k2, c2 = ode(zf + h / 2 * k1)
        k3, c3 = ode(zf + h / 2 * k2)
        k4, c4 = ode(zf + h * k3)
        zf = zf + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        states += [c1, c2, c3, c4]
    on = sum(states)
    switched = ca.logic_and(on > 0, on < len(states))
    return ca.Function(f"plant_rk{n}", [z, pz], ca.cse([zf, switched]), ["z", "pz"], ["zf", "switched"])


def _plant_ode(plant, surface):
    """The plant's right-hand side over time scaled to [0, 1]: ``(z, pz,
    ode)``, SX symbols of the joints ``z = [q, dq]`` and the plant's inputs
    ``pz`` (:func:`plant_inputs_layout`), and ``ode(z)`` -> (Ts [dq; ddq],
    whether the contact pushes at z): eq. (1) in joint space with the
    unilateral contact."""
    n = plant.n
    PZ = plant_inputs_layout(plant.task, surface)
    z = ca.SX.sym("z", 2 * n)
    pz = ca.SX.sym("pz", PZ.size)
    Z = PZ.split(pz)

    def ode(z):
        q, dq = z[:n], z[n:]
        _, _, J, R, X, dX = kinematics(plant, surface, q, dq, Z)
        f_env = contact_force(X[0], dX[0], Z["k_e"], Z["d_e"])
        F_env = R[:, 0] * f_env                                   # force on the environment, base frame
        ddq = plant.functions.forward_dynamics(q, dq, Z["tau"] - ca.mtimes(J[:3, :].T, F_env))
        return Z["Ts"] * ca.vertcat(dq, ddq), f_env > 0

    return z, pz, ode


def _plant_step(plant, surface, integrator: str, substeps: int, tol: float, contact_refine: int):
    """The plant over one period, time scaled to [0, 1] so Ts is a parameter:
    ``(coarse, choose, flow)``; ``coarse`` (fixed step) is ``(z, pz) ->
    (zf, switched)``, ``choose`` the contact refinement (or None), ``flow``
    the CVODES integrator (``integrator="cvodes"``); ``pz`` laid out by
    :func:`plant_inputs_layout`."""
    n = plant.n
    z, pz, ode = _plant_ode(plant, surface)
    if integrator == "cvodes":
        flow = ca.integrator("plant", "cvodes", {"x": z, "p": pz, "ode": ode(z)[0]}, 0.0, 1.0,
                             {"abstol": tol, "reltol": tol, "max_num_steps": 100000,
                              # a failure is the simulator's SimulationError, one line (not CasADi's and
                              # SUNDIALS' warnings and input dumps on the terminal)
                              "show_eval_warnings": False, "disable_internal_warnings": True})
        return None, None, flow
    if integrator != "fixed":
        raise ValueError(f"integrator: expected 'fixed' or 'cvodes', got {integrator!r}")
    coarse = _rk4(ode, z, pz, substeps)
    choose = None
    if contact_refine > 1:
        # a period in which the contact force switches on or off (a kink of
        # max(0, .) that a fixed step would straddle) is integrated again
        # with contact_refine times more steps: the same coarse step called
        # k times over Ts/k (little extra code to compile)
        zm, z1, pm = ca.MX.sym("z", 2 * n), ca.MX.sym("z1", 2 * n), ca.MX.sym("pz", pz.numel())
        k = int(contact_refine)
        zr, p_sub = zm, ca.vertcat(pm[:-1], pm[-1] / k)
        for _ in range(k):
            zr = coarse(zr, p_sub)[0]
        choose = ca.Function.conditional("refine_at_contact_switch",
                                         [ca.Function("keep", [zm, z1, pm], [z1])],
                                         ca.Function("refine", [zm, z1, pm], [zr]))
    return coarse, choose, None


def _control(model, law: Law, surface, S: dict, P: dict, ref: dict, q, dq, kin, f_sensor, delay: int,
             torque: bool = True, hold: bool = False) -> dict:
    """The controller at t_k from the sampled measurements, as MX expressions:
    the normal force through the sensor filter, the guarded approach, the
    (scheduled) damping, the law's command of eq. (4), the orientation error
    on a 6-D task, and (``torque``) the inner loop (eq. 6) and control force
    (eq. 5) as joint torques, with the computation delay's queue (``tau``,
    N m, the one applied over [t_k, t_k+1); ``tau_wait`` the queue after
    this period, oldest first) and, with ``hold``, the torque extrapolated
    to the middle of the period (:data:`MID_PERIOD`; ``tau_prev``/``held``
    the state it keeps). ``S``/``P`` are the state and parameter
    slices by name, ``ref`` the tangential reference (pos_t, vel_t, acc_t),
    ``kin`` :func:`kinematics` of the encoders and ``f_sensor`` the normal
    force read this period (N, before the filter). Used by :func:`build_step`
    (the simulation) and :func:`build_controller` (the exported controller):
    one set of expressions for both."""
    task = model.task
    pos, R_tool, J, R, X, dX = kin
    f_m = P["alpha"] * S["f_filt"] + (1 - P["alpha"]) * f_sensor   # measured normal force
    # guarded approach: contact detected now ends it; the surface estimate becomes the contact point
    approaching = S["approach"] > 0
    detect = ca.logic_and(approaching, f_m > P["f_contact"])
    engaged = ca.logic_not(ca.logic_and(approaching, ca.logic_not(detect)))
    x_e_hat = ca.if_else(detect, X[0] + P["x_e_hat"], S["x_e_hat"])
    f_d = P["f_d"] * S["ramp"]
    # normal damping: fixed, or scheduled from the stiffness estimate (K_D = B/M kept, eq. 9)
    b_sched = damping_schedule(S["b_n"], f_m, X[0] - x_e_hat, P["m"][0], P["k"][0], P)
    b_n = ca.if_else(P["sched"] > 0, b_sched, P["b"][0])
    kd_vec = ca.vertcat(ca.if_else(P["sched"] > 0, b_n / P["m"][0], P["kd"][0]), P["kd"][1:])
    y = {"x": X[0], "dx": dX[0], "f_m": f_m, "f_d": f_d, "x_e_hat": x_e_hat, "Ts": P["Ts"],
         "m": P["m"][0], "b": b_n, "k": P["k"][0]}
    x_r, x_c, dx_c, ddx_c, law_next = law.function()(ca.vertcat(*(y[n] for n in MEASUREMENTS)),
                                                     P["law"], S["law"])
    x_r, x_c, dx_c, ddx_c = (ca.if_else(engaged, a, b) for a, b in
                             ((x_r, S["x_app"]), (x_c, S["x_app"]), (dx_c, P["v_app"]), (ddx_c, 0)))
    law_next = ca.if_else(engaged, law_next, S["law"])
    X_r = ca.vertcat(x_r, ref["pos_t"])
    X_c, dX_c, ddX_c = (ca.vertcat(x_c, ref["pos_t"]), ca.vertcat(dx_c, ref["vel_t"]),
                        ca.vertcat(ddx_c, ref["acc_t"]))                              # eq. (4)
    ramp = ca.if_else(engaged, ca.fmin(S["ramp"] + P["ramp_rate"] * P["Ts"], 1.0), S["ramp"])
    x_app = ca.if_else(engaged, S["x_app"], S["x_app"] + P["v_app"] * P["Ts"])
    # rotational axes: X_c = R_d (X_a = 0) turned with the surface's frame at the command (a curved
    # surface: its angular velocity and acceleration fed forward), the error on the task axes
    R_d, w_d, a_d = None, 0, 0
    if task.rotational:
        R_d = ca.reshape(P["R_d"], 3, 3)
        turn = surface.turn(X_c, dX_c, ddX_c, P)
        if turn is not None:
            R_t, w_d, a_d = turn
            R_d, w_d, a_d = ca.mtimes(R_t, R_d), ca.mtimes(R.T, w_d), ca.mtimes(R.T, a_d)
    e_o = ca.mtimes(R.T, rotation_vector(ca.mtimes(R_d, R_tool.T))) if task.rotational else ca.MX(0, 1)
    out = {"f_m": f_m, "engaged": engaged, "x_e_hat": x_e_hat, "f_d": f_d, "b_n": b_n, "law_next": law_next,
           "X_r": X_r, "X_c": X_c, "dX_c": dX_c, "ddX_c": ddX_c, "ramp": ramp, "x_app": x_app, "e_o": e_o,
           "R_d": R_d, "w_d": w_d, "tau": None, "tau_wait": None, "tau_prev": ca.MX(0, 1), "held": ca.MX(0, 1)}
    if not torque:
        return out
    U = surface.acceleration(X, dX, inner_loop(ddX_c, dX_c, X_c, dX, X, kd_vec, P["kp"]), P)   # eq. (6)
    F_e = R[:, 0] * f_m
    Jdot_dq = model.functions.jacobian_dot(q, dq)
    if task.rotational:
        w = ca.mtimes(R.T, ca.mtimes(J[3:, :], dq))
        U = ca.vertcat(U, ca.mtimes(R, inner_loop(a_d, w_d, e_o, w, 0, P["kd_rot"], P["kp_rot"])))
        F_e = ca.vertcat(F_e, ca.MX.zeros(3))
    else:
        J, Jdot_dq = J[:3, :], Jdot_dq[:3]
    M = model.functions.mass_matrix(q)
    tau_0 = (ca.mtimes(M, P["kp_post"] * (P["q_post"] - q) - P["kd_post"] * dq)     # null-space posture
             if task.posture else None)
    tau = operational_space_torque(M, model.functions.bias(q, dq), J, Jdot_dq, U, F_e, tau_0) \
        + model.functions.friction(dq)                                                # eq. (5)
    if hold:            # the torque at t_k + Ts/2, extrapolated from the last two (the first period: as computed)
        out.update(tau_prev=tau, held=ca.MX(1))
        tau = tau + MID_PERIOD * S["held"] * (tau - S["tau_prev"])
    # the drive's clip (robot.saturate; inf: none); a NaN or infinite torque stays so (fmin/fmax would return the
    # bound and hide it from every finiteness check: review 14, a measured dq of 1e160 gave -tau_max, return code 0)
    tau = ca.if_else(ca.fabs(tau) < ca.inf, ca.fmin(ca.fmax(tau, -P["tau_max"]), P["tau_max"]), tau)
    if delay:           # apply the oldest waiting torque; queue this one
        queue = ca.vertcat(S["tau_wait"], tau)
        tau, tau_wait = queue[:task.n], queue[task.n:]
    else:
        tau_wait = ca.MX(0, 1)
    out.update(tau=tau, tau_wait=tau_wait)
    return out


def step_name(law: Law, delay: int = 0, hold: bool = False) -> str:
    """The name of :func:`build_step`'s Function (and of its compiled library)."""
    return f"step_{law.name}" + (f"_delay{delay}" if delay else "") + ("_mid" if hold else "")


def _surface_parameters(P: dict, surface) -> list:
    return [P[name] for name, _ in surface.fields]


def _sampled_control(plant, model, law: Law, delay: int, surface, hold: bool):
    """The controller's side of one period as MX: ``((s, u, p), (z0, pz,
    rest, log))``, the step's inputs, the joints at t_k, the plant's inputs
    over the period (the held torque, k_e, d_e, the surface's parameters,
    Ts), the controller's next state and the period's log row."""
    task = plant.task
    if model.n != task.n:
        raise ValueError(f"plant and model must have the same joints, got {task.n} and {model.n}")
    STATE, PARAM = state_layout(task, law, delay, hold), param_layout(task, law, surface)
    s, u, p = ca.MX.sym("s", STATE.size), ca.MX.sym("u", INPUT.size), ca.MX.sym("p", PARAM.size)
    S, U_in, P = STATE.split(s), INPUT.split(u), PARAM.split(p)
    q, dq = S["q"], S["dq"]
    P_c = believed(P)                                             # the controller's part
    kin = kinematics(model, surface, q, dq, P_c)                  # encoders through fk
    pos, _, J, _, X, dX = kin
    R_t, X_t, dX_t = surface.coordinates(pos, ca.mtimes(J[:3, :], dq), P)    # on the true part
    f_true = contact_force(X_t[0], dX_t[0], U_in["k_e"], P["d_e"])
    f_sensor = f_true + U_in["noise"]
    if surface.turns:   # the force along the true normal, read along the believed one (a plane's are the same)
        f_sensor = f_sensor * ca.dot(R_t[:, 0], kin[3][:, 0])
    c = _control(model, law, surface, S, P_c, U_in, q, dq, kin, f_sensor, delay, hold=hold)
    pz = ca.vertcat(c["tau"], U_in["k_e"], P["d_e"], *_surface_parameters(P, surface), P["Ts"])
    z0 = ca.vertcat(q, dq)
    rest = ca.vertcat(c["f_m"], c["b_n"], ca.if_else(c["engaged"], 0, 1), c["x_app"], c["ramp"], c["x_e_hat"],
                      c["tau_wait"], c["tau_prev"], c["held"], c["law_next"])
    log = ca.vertcat(q, dq, c["tau"], pos, X, c["X_r"], c["X_c"], f_true, c["f_m"], c["b_n"], c["f_d"],
                     c["x_e_hat"], c["e_o"])
    return (s, u, p), (z0, pz, rest, log)


def build_step(plant, model, law: Law, integrator: str = "fixed", substeps: int = 1, tol: float = 1e-10,
               delay: int = 0, contact_refine: int = 4, surface=Plane, hold: bool = False) -> ca.Function:
    """One control period ``["s","u","p"] -> ["s_next","log"]`` with ``law``
    and a computation delay of ``delay`` samples. ``plant`` and ``model``
    are robots (``load_robot``) with the same joints (the model may be
    mass-scaled or carry friction to compensate); ``surface`` the surface's
    shape (a :class:`tmtcontrol.surface.Surface` class or instance).

    ``integrator="fixed"``: classical RK4, ``substeps`` per period; a period
    in which the contact force switches on or off is integrated again with
    ``contact_refine`` times as many steps (a branch in the compiled code:
    the refined steps run only in those periods). The controller is expanded
    to SX, fused with the coarse plant step, and the step can be compiled.
    ``"cvodes"``: CVODES with relative/absolute tolerance ``tol`` (MX, not
    compilable; the accuracy reference). ``hold``: the held torque
    extrapolated to the middle of the period (``controller.hold =
    "mid_period"``, :data:`MID_PERIOD`).
    """
    coarse, choose, flow = _plant_step(plant, surface, integrator, substeps, tol, contact_refine)
    (s, u, p), (z0, pz, rest, log) = _sampled_control(plant, model, law, delay, surface, hold)
    name = step_name(law, delay, hold)
    if flow is not None:
        zf = flow(x0=z0, p=pz)["xf"]
        return ca.Function(name, [s, u, p], [ca.vertcat(zf, rest), log], ["s", "u", "p"], ["s_next", "log"])
    # the controller expanded to SX (compilable) and fused with the coarse plant
    # step, common subexpressions merged: the controller's model at q_k and the
    # plant's first stage share the kinematics (and, with an exact model, M and
    # J); the contact refinement a branch in the generated code
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


def build_tangent(plant, model, law: Law, dynamic, substeps: int = 1, delay: int = 0, surface=Plane,
                  hold: bool = False) -> ca.Function:
    """The tangent-linear step of :func:`build_step` (fixed step, no contact
    refinement), for the periodic analysis: ``["s","u","p"] -> ["s_next",
    "log"]`` with ``s = [s; v]`` -> ``[step(s); A(s) v]``, ``A = d step/d s``
    restricted to the state indices ``dynamic`` (``v`` and ``A v`` on them),
    and the log the true contact force f_e (N).

    Forward-mode AD (``casadi.jtimes``) piece by piece: the controller's side
    (:func:`_sampled_control`) and the plant's right-hand side are each an SX
    Function carrying its own directional derivative, and the Runge-Kutta
    stages call the plant's four times, so the generated C holds each piece
    once. It computes what the forward derivative of the whole fused step
    computes (bit for bit on the bundled scenarios; ``tests/test_tangent.py``
    to 1e-12), and the Panda's compiles in a third of the time
    (docs/speed.md)."""
    idx = np.asarray(dynamic, dtype=int).tolist()
    (s, u, p), (z0, pz, rest, log) = _sampled_control(plant, model, law, delay, surface, hold)
    f_e = log[log_layout(plant.task)["f_e"]]
    ctrl = ca.Function("ctrl", [s, u, p], [z0, pz, rest, f_e]).expand()
    sx = [ca.SX.sym(k, ctrl.size1_in(i)) for i, k in enumerate(("s", "u", "p"))]
    v = ca.SX.sym("v", len(idx))
    direction = ca.SX.zeros(sx[0].numel())
    direction[idx] = v
    outs = ctrl(*sx)
    ctrl_tan = ca.Function("ctrl_tangent", [*sx, v],
                           ca.cse([*outs, *(ca.jtimes(o, sx[0], direction) for o in outs[:3])]))
    z, pzs, ode = _plant_ode(plant, surface)
    dz, dpz = ca.SX.sym("dz", z.numel()), ca.SX.sym("dpz", pzs.numel())
    rhs = ode(z)[0]
    ode_tan = ca.Function("ode_tangent", [z, pzs, dz, dpz],
                          ca.cse([rhs, ca.jtimes(rhs, ca.vertcat(z, pzs), ca.vertcat(dz, dpz))]))
    sm, um, pm = (ca.MX.sym(k, ctrl.size1_in(i)) for i, k in enumerate(("s", "u", "p")))
    vm = ca.MX.sym("v", len(idx))
    zf, pzm, restm, f_em, dzf, dpzm, drest = ctrl_tan(sm, um, pm, vm)
    h = 1.0 / substeps                       # the stages of _rk4, on the value and its direction
    for _ in range(substeps):
        k1, d1 = ode_tan(zf, pzm, dzf, dpzm)
        k2, d2 = ode_tan(zf + h / 2 * k1, pzm, dzf + h / 2 * d1, dpzm)
        k3, d3 = ode_tan(zf + h / 2 * k2, pzm, dzf + h / 2 * d2, dpzm)
        k4, d4 = ode_tan(zf + h * k3, pzm, dzf + h * d3, dpzm)
        zf = zf + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        dzf = dzf + h / 6 * (d1 + 2 * d2 + 2 * d3 + d4)
    Av = ca.vertcat(dzf, drest)[idx]
    return ca.Function("tangent_step", [ca.vertcat(sm, vm), um, pm], [ca.vertcat(zf, restm, Av), f_em],
                       ["s", "u", "p"], ["s_next", "log"])


# -- the same loop split at the sensors: plant and controller as two Functions --------------------
# (software-in-the-loop: tmtcontrol.export generates C from build_controller and steps build_plant)

def build_plant(plant, integrator: str = "fixed", substeps: int = 1, tol: float = 1e-10,
                contact_refine: int = 4, surface=Plane) -> ca.Function:
    """The plant of :func:`build_step` alone over one period: ``["z","pz"]
    -> ["zf"]``, joints ``z = [q, dq]`` (n rad, n rad/s) and ``pz`` laid out
    by :func:`plant_inputs_layout`, with the same integrator and contact
    refinement."""
    coarse, choose, flow = _plant_step(plant, surface, integrator, substeps, tol, contact_refine)
    z = ca.MX.sym("z", 2 * plant.n)
    pz = ca.MX.sym("pz", plant_inputs_layout(plant.task, surface).size)
    if flow is not None:
        zf = flow(x0=z, p=pz)["xf"]
    else:
        zc, switched = coarse(z, pz)
        zf = zc if choose is None else choose(switched, z, zc, pz)
    return ca.Function("plant", [z, pz], [zf], ["z", "pz"], ["zf"])


def controller_state_layout(task, law: Law, delay: int = 0, torque: bool = True, hold: bool = False) -> Layout:
    """The controller's own state: :func:`state_layout` without the joints
    (the delay queue and the mid-period hold's torque only with ``torque``)."""
    full = state_layout(task, law, delay if torque else 0, hold and torque)
    return Layout(*((k, s.stop - s.start) for k, s in full.slices.items() if k not in ("q", "dq")))


def controller_param_layout(task, law: Law, surface=Plane) -> Layout:
    """The controller's parameters: :func:`param_layout` without the
    environment's damping ``d_e`` (a property of the simulated surface) and
    the part's position error (the controller's ``c`` is where it believes
    the part: :func:`believed`)."""
    full = param_layout(task, law, surface)
    return Layout(*((k, s.stop - s.start) for k, s in full.slices.items() if k not in ("d_e", "part_offset")))


def believed(P: dict) -> dict:
    """The parameters ``P`` (split by :func:`param_layout`, symbolic or
    numeric) as the controller sees them: the part's origin ``c`` where it
    believes it, ``c + part_offset`` (``controller.part_offset``)."""
    return {**P, "c": P["c"] + P["part_offset"]}


def measurement_layout(task) -> Layout:
    """The controller's inputs each period: joint positions (n, rad) and
    velocities (n, rad/s); the contact force on the tool (N, base frame; its
    normal component is ``-e_n . force``); the tangential reference position
    (m), velocity (m/s) and acceleration (m/s^2) on task axes 1 and 2."""
    n = task.n
    return Layout(("q", n), ("dq", n), ("force", 3), ("pos_t", 2), ("vel_t", 2), ("acc_t", 2))


IK_NEWTON_STEPS = 4
"""Newton steps of the joint position command from the measured joints on a
square task: the command of eq. (4) lies up to f_d/k (0.1 m in the paper)
from the measured position, and four steps reach it to rounding on the
built-in paths; a redundant arm takes twice as many least-norm steps."""


def ik_steps(task) -> int:
    """Newton steps of the joint position command: :data:`IK_NEWTON_STEPS`
    on a square task, twice as many least-norm steps on a redundant arm
    (whose first steps converge slower; tests/test_export_6d.py)."""
    return IK_NEWTON_STEPS if task.square else 2 * IK_NEWTON_STEPS


def command_layout(task, torque: bool = True) -> Layout:
    """The controller's outputs: the command of eq. (4) on the translational
    axes X_c, dX_c, ddX_c (task frame: m, m/s, m/s^2), the commanded tool
    position p_c (the surface's point of X_c, R X_c + c on a plane; base
    frame, m), the joint position command q_c (n, rad) with the tool at p_c
    (and, on a 6-D task, in the commanded
    orientation R_d) by :func:`ik_steps` Newton steps from the measured
    joints, the joint velocity command dq_c = J(q_c)^+ [v_c; w_c] (n, rad/s;
    v_c the chart's velocity of dX_c, R dX_c on a plane, w_c the command's
    angular velocity, 0 on a plane), and with ``torque`` the joint torques of
    eqs. (5)-(6) (n, N m)."""
    n = task.n
    return Layout(("X_c", 3), ("dX_c", 3), ("ddX_c", 3), ("p_c", 3), ("q_c", n), ("dq_c", n),
                  ("tau", n if torque else 0))


def diagnostics_layout(task) -> Layout:
    """What the controller computed on the way: task position and velocity
    (m, m/s), reference X_r (m, task frame), tool position p (m, base
    frame), filtered normal force f_m (N), normal damping b_n (N s/m),
    desired force in use f_d (N), the surface estimate x_e_hat (m, task
    normal) and, on a 6-D task, the orientation error e_o (rad, task axes)."""
    return Layout(("X", 3), ("dX", 3), ("X_r", 3), ("p", 3), ("f_m", 1), ("b_n", 1), ("f_d", 1),
                  ("x_e_hat", 1), ("e_o", task.rotational))


def _least_norm(J, e):
    """J^-1 e for a square J, else the least-norm solution J^T (J J^T)^-1 e."""
    if J.size1() == J.size2():
        return ca.solve(J, e, "symbolicqr")
    return ca.mtimes(J.T, ca.solve(ca.mtimes(J, J.T), e, "symbolicqr"))


def _task_jacobian(task, J):
    return J if task.rotational else J[:3, :]


def _newton(model, J, pos, R_tool, q, p_c, R_d):
    """:func:`ik_steps` Newton steps on the task error (tool position, and
    orientation log(R_d R^T)^vee on a 6-D task) from the measured joints
    ``q`` (least-norm steps on a redundant arm): ``(q_c, J_task(q_c))``."""
    task = model.task
    q_c, J_c, p, Rt = q, _task_jacobian(task, J), pos, R_tool
    for _ in range(ik_steps(task)):       # a fixed count: constant execution time
        e = p_c - p
        if task.rotational:
            e = ca.vertcat(e, rotation_vector(ca.mtimes(R_d, Rt.T)))
        q_c = q_c + _least_norm(J_c, e)
        T = model.functions.fk(q_c)
        J_c, p, Rt = _task_jacobian(task, model.functions.jacobian(q_c)), T[:3, 3], T[:3, :3]
    return q_c, J_c


def build_controller(model, law: Law, delay: int = 0, torque: bool = True, name: str = "tmt_controller",
                     surface=Plane, hold: bool = False) -> ca.Function:
    """The controller of :func:`build_step` alone (the same expressions,
    :func:`_control`), expanded to SX: ``name: ["s","y","p"] ->
    ["s_next","cmd","diag"]`` with the state :func:`controller_state_layout`,
    the measurement :func:`measurement_layout`, the parameters
    :func:`controller_param_layout`, the command :func:`command_layout` and
    :func:`diagnostics_layout`. ``torque=False`` leaves out the inner loop
    (eqs. 5-6) and the delay queue: the command for a position-controlled
    robot. ``hold``: the torque extrapolated to the middle of the period
    (:data:`MID_PERIOD`)."""
    task = model.task
    hold = hold and torque
    STATE, PARAM = controller_state_layout(task, law, delay, torque, hold), controller_param_layout(task, law, surface)
    MEAS = measurement_layout(task)
    s, y, p = ca.MX.sym("s", STATE.size), ca.MX.sym("y", MEAS.size), ca.MX.sym("p", PARAM.size)
    S, Y, P = STATE.split(s), MEAS.split(y), PARAM.split(p)
    q, dq = Y["q"], Y["dq"]
    kin = kinematics(model, surface, q, dq, P)
    pos, R_tool, J, R, X, dX = kin
    f_sensor = -ca.dot(R[:, 0], Y["force"])                 # normal force pushing on the surface
    c = _control(model, law, surface, S, P, Y, q, dq, kin, f_sensor, delay if torque else 0, torque, hold)
    p_c = surface.point(c["X_c"], P)
    q_c, J_c = _newton(model, J, pos, R_tool, q, p_c, c["R_d"])
    v_c = surface.velocity(c["X_c"], c["dX_c"], P)
    if task.rotational:
        v_c = ca.vertcat(v_c, ca.mtimes(R, c["w_d"]) if isinstance(c["w_d"], ca.MX) else ca.MX.zeros(3))
    dq_c = _least_norm(J_c, v_c)
    queue = c["tau_wait"] if torque else ca.MX(0, 1)
    s_next = ca.vertcat(c["f_m"], c["b_n"], ca.if_else(c["engaged"], 0, 1), c["x_app"], c["ramp"],
                        c["x_e_hat"], queue, c["tau_prev"], c["held"], c["law_next"])
    cmd = ca.vertcat(c["X_c"], c["dX_c"], c["ddX_c"], p_c, q_c, dq_c, c["tau"] if torque else ca.MX(0, 1))
    diag = ca.vertcat(X, dX, c["X_r"], pos, c["f_m"], c["b_n"], c["f_d"], c["x_e_hat"], c["e_o"])
    return ca.Function(name, [s, y, p], [s_next, cmd, diag], ["s", "y", "p"],
                       ["s_next", "cmd", "diag"]).expand()
