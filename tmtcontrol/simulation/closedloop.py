"""One control period of the sampled closed loop, assembled symbolically.

At each sample t_k the controller reads the joint encoders (position through
fk) and the force sensor, asks the force-tracking law (``control.laws``) for
the normal-axis command of eq. (4) (the law owns its reference, eqs. 11-18 or
a baseline, and its impedance filter, eqs. 2-3), forms the inner loop
(eq. 6) and the Cartesian control force (eq. 5), mapped to joint torques
tau = J^T F. The tangential axes carry no force, so their impedance
adjustment is zero and their command is the circle itself. The torque is then
held (zero-order hold) while a CasADi integrator advances the continuous
plant, eq. (1) in joint space with the unilateral contact.

Two things real controllers have are part of the loop (beyond the paper):

* a computation delay of N samples (``delay``, structural): the torque
  computed at t_k is applied over [t_(k+N), t_(k+N+1)); the state carries
  the N torques computed but not yet applied;
* a guarded approach (first contact from a gap above the surface): while
  ``approach`` is 1 the normal command advances toward the surface at the
  approach speed, x_c = x_app, dx_c = v, ddx_c = 0, and the law's state is
  held. When the measured force exceeds the contact threshold the surface
  estimate becomes the contact point (plus the configured x_e error), and
  the law takes over with its desired force ramped from 0 to f_d over the
  force ramp. With f_d = 0 every law's command is the surface estimate, so
  the hand-over has no jump in position. Starting on the surface
  (``approach`` = 0, ramp = 1) is the paper's loop, unchanged.

:func:`build_step` returns ``step: ["s", "u", "p"] -> ["s_next", "log"]``,
whose vectors are laid out by :func:`state_layout`, :data:`INPUT`,
:func:`param_layout` and :data:`LOG`. Numeric settings (gains, f_d, law
parameters, stiffness, noise) are entries of ``p``/``u``; only the robot
options, the integrator and the law's structure change the Function. The
closed loop never asks which law it runs.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from ..control.impedance import inner_loop, joint_torque
from ..control.laws import MEASUREMENTS, Law
from ..model.puma560 import PUMA560_LINKS, Puma560
from .environment import contact_force

__all__ = ["INPUT", "LOG", "Layout", "state_layout", "param_layout", "controller_model",
           "damping_schedule", "build_step", "step_name", "build_plant", "build_controller",
           "controller_state_layout", "controller_param_layout", "MEASUREMENT", "command_layout", "DIAGNOSTICS"]


class Layout:
    """Named slices of a flat vector: ``layout["q"]`` is a slice."""

    def __init__(self, *fields: tuple[str, int]):
        self.slices = {}
        i = 0
        for name, n in fields:
            self.slices[name] = slice(i, i + n)
            i += n
        self.size = i

    def __getitem__(self, name):
        return self.slices[name]

    def split(self, vec):
        return {name: vec[s] for name, s in self.slices.items()}

    def pack(self, **values) -> np.ndarray:
        out = np.zeros(self.size)
        for name, s in self.slices.items():
            out[s] = np.ravel(values[name])
        return out


def state_layout(law: Law, delay: int = 0) -> Layout:
    """Closed-loop state: joints (rad, rad/s), force-sensor filter state (N),
    scheduled normal damping (N s/m), approach phase (1 while approaching,
    else 0), approach command x_app (m, task normal), progress of the f_d
    ramp (0..1), the controller's surface estimate x_e_hat (m), the
    ``delay`` torques waiting to be applied (N m, oldest first), then the
    law's own state."""
    return Layout(("q", 3), ("dq", 3), ("f_filt", 1), ("b_n", 1), ("approach", 1), ("x_app", 1),
                  ("ramp", 1), ("x_e_hat", 1), ("tau_wait", 3 * delay), ("law", len(law.states)))


INPUT = Layout(("pos_t", 2), ("vel_t", 2), ("acc_t", 2), ("k_e", 1), ("noise", 1))
"""Per-sample inputs: tangential reference (task axes 1, 2), true stiffness
k_e (N/m), force-sensor noise sample (N)."""


def param_layout(law: Law) -> Layout:
    """Constant parameters: impedance M, B, K and gains K_D, K_P (task frame);
    f_d (N); controller's x_e (m); force filter pole alpha; environment
    damping (N s/m); task frame R (column-major) and origin c (m); control
    period Ts (s); damping schedule on/off, target ratio, bounds on b
    (N s/m), rate limit (N s/m per s), largest and smallest stiffness
    estimate (N/m) and force threshold (N); approach speed (m/s), contact
    threshold (N) and f_d ramp rate (1/s); then the law's parameters."""
    return Layout(("m", 3), ("b", 3), ("k", 3), ("kd", 3), ("kp", 3), ("f_d", 1), ("x_e_hat", 1),
                  ("alpha", 1), ("d_e", 1), ("R", 9), ("c", 3), ("Ts", 1), ("sched", 1), ("zeta", 1),
                  ("b_min", 1), ("b_max", 1), ("b_rate", 1), ("k_hat_max", 1), ("k_hat_min", 1),
                  ("sched_f_th", 1), ("v_app", 1), ("f_contact", 1), ("ramp_rate", 1),
                  ("law", len(law.parameter_names)))


LOG = Layout(("q", 3), ("dq", 3), ("tau", 3), ("p", 3), ("X", 3), ("X_r", 3), ("X_c", 3),
             ("f_e", 1), ("f_m", 1), ("b_n", 1), ("f_d", 1), ("x_e_hat", 1))
"""Per-sample log at t_k: joints, torque applied over [t_k, t_k+1) (N m),
wrist position (base, m), task position X, reference X_r, command X_c (task,
m), true and measured normal force (N), normal impedance damping in use
(N s/m), desired force in use (N, ramped after an approach) and the surface
estimate (m)."""


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
def controller_model(mass_scale: float, compensate_friction: bool) -> Puma560:
    """The controller's model of the robot (D*^, h*^ of eq. 5): every mass and
    inertia scaled by ``mass_scale``."""
    links = tuple(dataclasses.replace(l, m=l.m * mass_scale, I=tuple(i * mass_scale for i in l.I),
                                      Jm=l.Jm * mass_scale) for l in PUMA560_LINKS)
    return Puma560(armature=True, friction="smooth" if compensate_friction else False, links=links)


def _task(robot: Puma560, q, dq, R, c):
    p = robot.fk(q)
    J = robot.jacobian(q)
    return p, J, ca.mtimes(R.T, p - c), ca.mtimes(R.T, ca.mtimes(J, dq))


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


def _control(model: Puma560, law: Law, S: dict, P: dict, ref: dict, R, q, dq, J, X, dX, f_sensor,
             delay: int, torque: bool = True) -> dict:
    """The controller at t_k from the sampled measurements, as MX expressions:
    the normal force through the sensor filter, the guarded approach, the
    (scheduled) damping, the law's command of eq. (4), and (``torque``) the
    inner loop (eq. 6) and control force (eq. 5) as joint torques, with the
    computation delay's queue. ``S``/``P`` are the state and parameter slices
    by name, ``ref`` the tangential reference (pos_t, vel_t, acc_t), ``q, dq,
    J, X, dX`` the joints and the task-frame kinematics of the encoders and
    ``f_sensor`` the normal force read this period (N, before the filter).
    Used by :func:`build_step` (the simulation) and :func:`build_controller`
    (the exported controller): one set of expressions for both."""
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
    out = {"f_m": f_m, "engaged": engaged, "x_e_hat": x_e_hat, "f_d": f_d, "b_n": b_n, "law_next": law_next,
           "X_r": X_r, "X_c": X_c, "dX_c": dX_c, "ddX_c": ddX_c, "ramp": ramp, "x_app": x_app,
           "tau": None, "tau_wait": None}
    if not torque:
        return out
    U = inner_loop(ddX_c, dX_c, X_c, dX, X, kd_vec, P["kp"])                           # eq. (6)
    F_e = ca.vertcat(f_m, 0, 0)
    tau = joint_torque(model.mass_matrix(q), model.bias(q, dq), J, model.jacobian_dot(q, dq),
                       ca.mtimes(R, U), ca.mtimes(R, F_e)) + model.friction(dq)        # eq. (5), J^T F
    if delay:           # apply the oldest waiting torque; queue this one
        queue = ca.vertcat(S["tau_wait"], tau)
        tau, tau_wait = queue[:3], queue[3:]
    else:
        tau_wait = ca.MX(0, 1)
    out.update(tau=tau, tau_wait=tau_wait)
    return out


def _plant_step(plant: Puma560, integrator: str, substeps: int, tol: float, contact_refine: int):
    """The plant over one period, time scaled to [0, 1] so Ts is a parameter:
    ``(coarse, choose, plant_flow)``; ``coarse`` (fixed step) is ``(z, pz) ->
    (zf, switched)``, ``choose`` the contact refinement (or None),
    ``plant_flow`` the CVODES integrator (``integrator="cvodes"``).
    ``pz = [tau (N m), k_e (N/m), d_e (N s/m), R (column-major), c (m), Ts (s)]``."""
    z = ca.SX.sym("z", 6)
    pz = ca.SX.sym("pz", 3 + 1 + 1 + 9 + 3 + 1)
    tau, k_e, d_e = pz[0:3], pz[3], pz[4]
    R = ca.reshape(pz[5:14], 3, 3)
    c, Ts = pz[14:17], pz[17]
    coarse = choose = plant_flow = None

    def ode(z):
        """Eq. (1) in joint space with the unilateral contact; and whether the
        contact pushes at z."""
        q, dq = z[0:3], z[3:6]
        _, J, X, dX = _task(plant, q, dq, R, c)
        f_env = contact_force(X[0], dX[0], k_e, d_e)
        F_env = R[:, 0] * f_env                                   # force on the environment, base frame
        ddq = plant.forward_dynamics(q, dq, tau - ca.mtimes(J.T, F_env))
        return Ts * ca.vertcat(dq, ddq), f_env > 0

    if integrator == "fixed":
        coarse = _rk4(ode, z, pz, substeps)
        if contact_refine > 1:
            # a period in which the contact force switches on or off (a kink of
            # max(0, .) that a fixed step would straddle) is integrated again
            # with contact_refine times more steps: the same coarse step called
            # n times over Ts/n (little extra code to compile)
            zm, z1, pm = ca.MX.sym("z", 6), ca.MX.sym("z1", 6), ca.MX.sym("pz", pz.numel())
            n = int(contact_refine)
            zr, p_sub = zm, ca.vertcat(pm[:-1], pm[-1] / n)
            for _ in range(n):
                zr = coarse(zr, p_sub)[0]
            keep = ca.Function("keep", [zm, z1, pm], [z1])
            refine = ca.Function("refine", [zm, z1, pm], [zr])
            choose = ca.Function.conditional("refine_at_contact_switch", [keep], refine)
    elif integrator == "cvodes":
        dae = {"x": z, "p": pz, "ode": ode(z)[0]}
        plant_flow = ca.integrator("plant", "cvodes", dae, 0.0, 1.0,
                                   {"abstol": tol, "reltol": tol, "max_num_steps": 100000})
    else:
        raise ValueError(f"integrator: expected 'fixed' or 'cvodes', got {integrator!r}")

    return coarse, choose, plant_flow


def step_name(law: Law, delay: int = 0) -> str:
    """The name of :func:`build_step`'s Function (and of its compiled library)."""
    return f"step_{law.name}" + (f"_delay{delay}" if delay else "")


def build_step(plant: Puma560, model: Puma560, law: Law, integrator: str = "fixed", substeps: int = 1,
               tol: float = 1e-10, delay: int = 0, contact_refine: int = 4) -> ca.Function:
    """One control period ``["s","u","p"] -> ["s_next","log"]`` with ``law``
    and a computation delay of ``delay`` samples.

    ``integrator="fixed"``: classical RK4, ``substeps`` per period; a period
    in which the contact force switches on or off is integrated again with
    ``contact_refine`` times as many steps (a branch in the compiled code:
    the refined steps run only in those periods). The controller is expanded
    to SX, fused with the coarse plant step, and the step can be compiled.
    ``"cvodes"``: CVODES with relative/absolute tolerance ``tol`` (MX, not
    compilable; the accuracy reference).
    """
    coarse, choose, plant_flow = _plant_step(plant, integrator, substeps, tol, contact_refine)

    # -- controller at t_k -------------------------------------------------------
    STATE, PARAM = state_layout(law, delay), param_layout(law)
    s = ca.MX.sym("s", STATE.size)
    u = ca.MX.sym("u", INPUT.size)
    p = ca.MX.sym("p", PARAM.size)
    S, U_in, P = STATE.split(s), INPUT.split(u), PARAM.split(p)
    R = ca.reshape(P["R"], 3, 3)
    q, dq = S["q"], S["dq"]
    pos, J, X, dX = _task(model, q, dq, R, P["c"])            # encoders through fk
    f_true = contact_force(X[0], dX[0], U_in["k_e"], P["d_e"])
    c = _control(model, law, S, P, U_in, R, q, dq, J, X, dX, f_true + U_in["noise"], delay)
    f_m, b_n, engaged, x_e_hat, f_d = c["f_m"], c["b_n"], c["engaged"], c["x_e_hat"], c["f_d"]
    tau, tau_wait, law_next, X_r, X_c = c["tau"], c["tau_wait"], c["law_next"], c["X_r"], c["X_c"]
    ramp, x_app = c["ramp"], c["x_app"]
    pz_val = ca.vertcat(tau, U_in["k_e"], P["d_e"], P["R"], P["c"], P["Ts"])
    z0 = ca.vertcat(q, dq)
    zf = ca.MX.zeros(6) if integrator == "fixed" else plant_flow(x0=z0, p=pz_val)["xf"]
    s_next = ca.vertcat(zf, f_m, b_n, ca.if_else(engaged, 0, 1), x_app, ramp, x_e_hat, tau_wait, law_next)
    log = ca.vertcat(q, dq, tau, pos, X, X_r, X_c, f_true, f_m, b_n, f_d, x_e_hat)
    name = step_name(law, delay)
    if integrator != "fixed":
        return ca.Function(name, [s, u, p], [s_next, log], ["s", "u", "p"], ["s_next", "log"])
    # the controller expanded to SX (compilable) and fused with the coarse plant
    # step, common subexpressions merged: the controller's model at q_k and the
    # plant's first stage share sin/cos of q_k (and, with an exact model, M, J
    # and the kinematics); the contact refinement a branch in the generated code
    ctrl = ca.Function("ctrl", [s, u, p], [z0, pz_val, s_next[6:], log]).expand()
    sx = [ca.SX.sym(n, ctrl.size1_in(i)) for i, n in enumerate(("s", "u", "p"))]
    z0s, pzs, rest, logs = ctrl(*sx)
    zc, switched = coarse(z0s, pzs)
    if choose is None:
        return ca.Function(name, sx, ca.cse([ca.vertcat(zc, rest), logs]), ["s", "u", "p"], ["s_next", "log"])
    fused = ca.Function(f"{name}_ctrl_plant", sx, ca.cse([z0s, pzs, zc, switched, rest, logs]))
    sm, um, pm = (ca.MX.sym(n, fused.size1_in(i)) for i, n in enumerate(("s", "u", "p")))
    z0m, pzm, zcm, sw, restm, logm = fused(sm, um, pm)
    s_next_m = ca.vertcat(choose(sw, z0m, zcm, pzm), restm)
    return ca.Function(name, [sm, um, pm], [s_next_m, logm], ["s", "u", "p"], ["s_next", "log"])


# -- the same loop split at the sensors: plant and controller as two Functions --------------------
# (software-in-the-loop: tmtcontrol.export generates C from build_controller and steps build_plant)

def build_plant(plant: Puma560, integrator: str = "fixed", substeps: int = 1, tol: float = 1e-10,
                contact_refine: int = 4) -> ca.Function:
    """The plant of :func:`build_step` alone over one period: ``["z","pz"] ->
    ["zf"]``, joints ``z = [q, dq]`` (rad, rad/s) and ``pz = [tau (N m), k_e
    (N/m), d_e (N s/m), R (column-major), c (m), Ts (s)]``, with the same
    integrator and contact refinement."""
    return _plant_function(*_plant_step(plant, integrator, substeps, tol, contact_refine), 6, 18)


def _plant_function(coarse, choose, flow, nz: int, npz: int) -> ca.Function:
    """``["z","pz"] -> ["zf"]`` from a plant step's parts (:func:`_plant_step`):
    the adaptive ``flow``, else the ``coarse`` RK4 step refined by ``choose``
    at a contact switch. Shared by the PUMA's and the 6-D loop's plants."""
    z, pz = ca.MX.sym("z", nz), ca.MX.sym("pz", npz)
    if flow is not None:
        zf = flow(x0=z, p=pz)["xf"]
    else:
        zc, switched = coarse(z, pz)
        zf = zc if choose is None else choose(switched, z, zc, pz)
    return ca.Function("plant", [z, pz], [zf], ["z", "pz"], ["zf"])


def controller_state_layout(law: Law, delay: int = 0, torque: bool = True) -> Layout:
    """The controller's own state: :func:`state_layout` without the joints
    (the delay queue only with ``torque``)."""
    full = state_layout(law, delay if torque else 0)
    return Layout(*((n, s.stop - s.start) for n, s in full.slices.items() if n not in ("q", "dq")))


def controller_param_layout(law: Law) -> Layout:
    """The controller's parameters: :func:`param_layout` without the
    environment's damping ``d_e`` (a property of the simulated surface)."""
    full = param_layout(law)
    return Layout(*((n, s.stop - s.start) for n, s in full.slices.items() if n != "d_e"))


MEASUREMENT = Layout(("q", 3), ("dq", 3), ("force", 3), ("pos_t", 2), ("vel_t", 2), ("acc_t", 2))
"""The controller's inputs each period: joint positions (rad) and velocities
(rad/s); the contact force on the tool (N, base frame; its normal component
is ``-R[:, 0] . force``); the tangential reference position (m), velocity
(m/s) and acceleration (m/s^2) on task axes 2 and 3."""


IK_NEWTON_STEPS = 4
"""Newton steps of the joint position command from the measured joints: the
command of eq. (4) lies up to f_d/k (0.1 m in the paper) from the measured
position, and four steps reach it to rounding on the paper's path."""


def command_layout(torque: bool = True) -> Layout:
    """The controller's outputs: the command of eq. (4) X_c, dX_c, ddX_c
    (task frame: m, m/s, m/s^2), the commanded wrist position p_c = R X_c + c
    (base frame, m), the joint position command q_c with fk(q_c) = p_c
    (:data:`IK_NEWTON_STEPS` Newton steps from the measured joints, the
    branch the robot is in) and the joint velocity command dq_c =
    J(q_c)^-1 R dX_c (rad, rad/s), and with ``torque`` the joint torques of
    eqs. (5)-(6) (N m)."""
    return Layout(("X_c", 3), ("dX_c", 3), ("ddX_c", 3), ("p_c", 3), ("q_c", 3), ("dq_c", 3),
                  ("tau", 3 if torque else 0))


DIAGNOSTICS = Layout(("X", 3), ("dX", 3), ("X_r", 3), ("p", 3), ("f_m", 1), ("b_n", 1), ("f_d", 1),
                     ("x_e_hat", 1))
"""What the controller computed on the way: task position and velocity
(m, m/s), reference X_r (m, task frame), wrist position p (m, base frame),
filtered normal force f_m (N), normal damping b_n (N s/m), desired force in
use f_d (N) and the surface estimate x_e_hat (m, task normal)."""


def build_controller(model: Puma560, law: Law, delay: int = 0, torque: bool = True,
                     name: str = "tmt_controller") -> ca.Function:
    """The controller of :func:`build_step` alone (the same expressions,
    :func:`_control`), expanded to SX: ``name: ["s","y","p"] ->
    ["s_next","cmd","diag"]`` with the state :func:`controller_state_layout`,
    the measurement :data:`MEASUREMENT`, the parameters
    :func:`controller_param_layout`, the command :func:`command_layout` and
    :data:`DIAGNOSTICS`. ``torque=False`` leaves out the inner loop (eqs.
    5-6) and the delay queue: the command for a position-controlled robot."""
    STATE, PARAM = controller_state_layout(law, delay, torque), controller_param_layout(law)
    s, y, p = ca.MX.sym("s", STATE.size), ca.MX.sym("y", MEASUREMENT.size), ca.MX.sym("p", PARAM.size)
    S, Y, P = STATE.split(s), MEASUREMENT.split(y), PARAM.split(p)
    R = ca.reshape(P["R"], 3, 3)
    q, dq = Y["q"], Y["dq"]
    pos, J, X, dX = _task(model, q, dq, R, P["c"])
    f_sensor = -ca.dot(R[:, 0], Y["force"])                 # normal force pushing on the surface
    c = _control(model, law, S, P, Y, R, q, dq, J, X, dX, f_sensor, delay if torque else 0, torque)
    p_c = ca.mtimes(R, c["X_c"]) + P["c"]
    q_c, J_c = q, J
    for _ in range(IK_NEWTON_STEPS):        # a fixed count: constant execution time
        q_c = q_c + ca.solve(J_c, p_c - (pos if q_c is q else model.fk(q_c)), "symbolicqr")
        J_c = model.jacobian(q_c)
    dq_c = ca.solve(J_c, ca.mtimes(R, c["dX_c"]), "symbolicqr")
    queue = c["tau_wait"] if torque else ca.MX(0, 1)
    s_next = ca.vertcat(c["f_m"], c["b_n"], ca.if_else(c["engaged"], 0, 1), c["x_app"], c["ramp"],
                        c["x_e_hat"], queue, c["law_next"])
    cmd = ca.vertcat(c["X_c"], c["dX_c"], c["ddX_c"], p_c, q_c, dq_c, c["tau"] if torque else ca.MX(0, 1))
    diag = ca.vertcat(X, dX, c["X_r"], pos, c["f_m"], c["b_n"], c["f_d"], c["x_e_hat"])
    return ca.Function(name, [s, y, p], [s_next, cmd, diag], ["s", "y", "p"],
                       ["s_next", "cmd", "diag"]).expand()
