"""One control period of the sampled closed loop, assembled symbolically.

At each sample t_k the controller reads the joint encoders (position through
fk) and the force sensor, forms the reference (TMT eq. 18 or eqs. 11-12), the
impedance adjustment (eqs. 2-3), the command (eq. 4), the inner loop (eq. 6)
and the Cartesian control force (eq. 5), mapped to joint torques tau = J^T F.
The torque and the measured force are then held (zero-order hold) while a
CasADi integrator advances the continuous plant, eq. (1) in joint space with
the unilateral contact, together with the impedance filter driven by the held
force (its ZOH-equivalent discretisation).

:func:`build_step` returns ``step: ["s", "u", "p"] -> ["s_next", "log"]``,
whose vectors are laid out by :data:`STATE`, :data:`INPUT`, :data:`PARAM` and
:data:`LOG`. Numeric settings are entries of ``p``/``u``, so changing gains,
f_d, stiffness or noise needs no new Function; only the robot options and the
integrator (kind, sub-steps) change its structure.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from .environment import contact_force
from ..control.impedance import command, control_force, impedance_acceleration, inner_loop
from ..control.reference import known_reference, tmt_reference
from ..model.puma560 import PUMA560_LINKS, Puma560

__all__ = ["STATE", "INPUT", "PARAM", "LOG", "Layout", "controller_model", "damping_schedule",
           "build_step"]


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


STATE = Layout(("q", 3), ("dq", 3), ("xa", 3), ("dxa", 3), ("f_filt", 1), ("b_n", 1))
"""Closed-loop state: joints (rad, rad/s), impedance adjustment X_a (m, m/s,
task frame), force-sensor filter state (N), scheduled normal damping (N s/m)."""

INPUT = Layout(("pos_t", 2), ("vel_t", 2), ("acc_t", 2), ("k_e", 1), ("noise", 1))
"""Per-sample inputs: tangential reference (task axes 1, 2), true stiffness
k_e (N/m), force-sensor noise sample (N)."""

PARAM = Layout(("m", 3), ("b", 3), ("k", 3), ("kd", 3), ("kp", 3), ("f_d", 1), ("law", 1),
               ("k_assumed", 1), ("f_th", 1), ("k_min", 1), ("x_e_hat", 1), ("alpha", 1),
               ("d_e", 1), ("R", 9), ("c", 3), ("Ts", 1), ("sched", 1), ("zeta", 1),
               ("b_min", 1), ("b_max", 1), ("b_rate", 1), ("k_hat_max", 1))
"""Constant parameters: impedance M, B, K and gains K_D, K_P (task frame);
f_d (N); law (0 = TMT, 1 = known); assumed k_e (N/m); TMT force threshold (N)
and minimum stiffness (N/m); controller's x_e (m); force filter pole alpha;
environment damping (N s/m); task frame R (column-major) and origin c (m);
control period Ts (s); damping schedule on/off, target damping ratio, bounds
on b (N s/m), its rate limit (N s/m per s) and the largest stiffness estimate
used (N/m)."""

LOG = Layout(("q", 3), ("dq", 3), ("tau", 3), ("p", 3), ("X", 3), ("X_r", 3), ("X_c", 3),
             ("f_e", 1), ("f_m", 1), ("b_n", 1))
"""Per-sample log at t_k: joints, torque (N m), wrist position (base, m), task
position X, reference X_r, command X_c (task, m), true and measured normal
force (N), normal impedance damping in use (N s/m)."""


def damping_schedule(b_prev, f_m, depth, m, k, P):
    """Stiffness-scheduled normal damping: eq. (25) used online.

    ``b* = 2 zeta sqrt(m (k + k_hat))`` with the TMT estimate
    ``k_hat = f_m/depth`` (eq. 14), clamped to [min_stiffness, k_hat_max];
    while the force is below twice the TMT threshold (no usable estimate, or
    noise) the target is the previous value (hold). The result is clamped to
    [b_min, b_max] and rate-limited to ``b_rate`` N s/m per second.
    """
    ok = ca.logic_and(f_m > 2 * P["f_th"], depth > 0)
    k_hat = ca.fmin(ca.fmax(f_m / ca.fmax(depth, 1e-12), P["k_min"]), P["k_hat_max"])
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


def build_step(plant: Puma560, model: Puma560, integrator: str = "fixed", substeps: int = 4,
               tol: float = 1e-10) -> ca.Function:
    """One control period ``["s","u","p"] -> ["s_next","log"]``.

    ``integrator="fixed"``: CasADi 'rk' (RK4, ``substeps`` per period,
    ``simplify``), the step expanded to SX so it can be compiled.
    ``"cvodes"``: CVODES with relative/absolute tolerance ``tol`` (MX, not
    compilable; the accuracy reference).
    """
    # -- plant over one period, time scaled to [0, 1] so Ts is a parameter ----
    z = ca.SX.sym("z", 12)
    q, dq, xa, dxa = z[0:3], z[3:6], z[6:9], z[9:12]
    pz = ca.SX.sym("pz", 3 + 1 + 1 + 1 + 9 + 9 + 3 + 1)
    tau, f_m, k_e, d_e = pz[0:3], pz[3], pz[4], pz[5]
    m, b, k = pz[6:9], pz[9:12], pz[12:15]
    R = ca.reshape(pz[15:24], 3, 3)
    c, Ts = pz[24:27], pz[27]
    _, J, X, dX = _task(plant, q, dq, R, c)
    f_env = contact_force(X[0], dX[0], k_e, d_e)
    F_env = R[:, 0] * f_env                                   # force on the environment, base frame
    ddq = plant.forward_dynamics(q, dq, tau - ca.mtimes(J.T, F_env))   # eq. (1) in joint space
    ddxa = impedance_acceleration(ca.vertcat(f_m, 0, 0), xa, dxa, m, b, k)  # eq. (2)
    dae = {"x": z, "p": pz, "ode": Ts * ca.vertcat(dq, ddq, dxa, ddxa)}
    if integrator == "fixed":
        plant_flow = ca.integrator("plant", "rk", dae, 0.0, 1.0,
                          {"simplify": True, "number_of_finite_elements": int(substeps)})
    elif integrator == "cvodes":
        plant_flow = ca.integrator("plant", "cvodes", dae, 0.0, 1.0,
                          {"abstol": tol, "reltol": tol, "max_num_steps": 100000})
    else:
        raise ValueError(f"integrator: expected 'fixed' or 'cvodes', got {integrator!r}")

    # -- controller at t_k -------------------------------------------------------
    s = ca.MX.sym("s", STATE.size)
    u = ca.MX.sym("u", INPUT.size)
    p = ca.MX.sym("p", PARAM.size)
    S, U_in, P = STATE.split(s), INPUT.split(u), PARAM.split(p)
    R = ca.reshape(P["R"], 3, 3)
    q, dq = S["q"], S["dq"]
    pos, J, X, dX = _task(model, q, dq, R, P["c"])            # encoders through fk
    f_true = contact_force(X[0], dX[0], U_in["k_e"], P["d_e"])
    f_filt = P["alpha"] * S["f_filt"] + (1 - P["alpha"]) * (f_true + U_in["noise"])
    f_m = f_filt                                               # measured normal force
    # normal damping: fixed, or scheduled from the stiffness estimate (K_D = B/M kept, eq. 9)
    b_sched = damping_schedule(S["b_n"], f_m, X[0] - P["x_e_hat"], P["m"][0], P["k"][0], P)
    b_n = ca.if_else(P["sched"] > 0, b_sched, P["b"][0])
    b_vec = ca.vertcat(b_n, P["b"][1:])
    kd_vec = ca.vertcat(ca.if_else(P["sched"] > 0, b_n / P["m"][0], P["kd"][0]), P["kd"][1:])
    x_r_tmt = tmt_reference(X[0], f_m, P["x_e_hat"], P["f_d"], P["k"][0], P["f_th"], P["k_min"])
    x_r_known = known_reference(P["x_e_hat"], P["f_d"], P["k"][0], P["k_assumed"])
    x_r = ca.if_else(P["law"] == 0, x_r_tmt, x_r_known)
    X_r = ca.vertcat(x_r, U_in["pos_t"])
    dX_r = ca.vertcat(0, U_in["vel_t"])                        # x_r'' = x_e'' = 0 (section IV)
    ddX_r = ca.vertcat(0, U_in["acc_t"])
    F_e = ca.vertcat(f_m, 0, 0)
    ddxa = impedance_acceleration(F_e, S["xa"], S["dxa"], P["m"], b_vec, P["k"])     # eq. (2)
    X_c, dX_c, ddX_c = (command(X_r, S["xa"]), command(dX_r, S["dxa"]),
                        command(ddX_r, ddxa))                                          # eq. (4)
    U = inner_loop(ddX_c, dX_c, X_c, dX, X, kd_vec, P["kp"])                           # eq. (6)
    F = control_force(model.cartesian_inertia(q), model.cartesian_bias(q, dq),
                      ca.mtimes(R, U), ca.mtimes(R, F_e))                              # eq. (5)
    tau = ca.mtimes(J.T, F) + model.friction(dq)

    pz_val = ca.vertcat(tau, f_m, U_in["k_e"], P["d_e"], P["m"], b_vec, P["k"], P["R"],
                        P["c"], P["Ts"])
    zf = plant_flow(x0=ca.vertcat(q, dq, S["xa"], S["dxa"]), p=pz_val)["xf"]
    s_next = ca.vertcat(zf, f_filt, b_n)
    log = ca.vertcat(q, dq, tau, pos, X, X_r, X_c, f_true, f_m, b_n)
    step = ca.Function("tmt_step", [s, u, p], [s_next, log], ["s", "u", "p"], ["s_next", "log"])
    return step.expand() if integrator == "fixed" else step
