"""The 6-D closed loop of ``tmtcontrol.simulation.closedloop`` written again with Pinocchio in Python.

A reference implementation for speed (issue 30: the compiled rollout against
"the same closed loop written with Pinocchio in Python, its ABA per RK4
stage, the controller in NumPy") and for correctness (a second, independent
implementation of the same equations; ``tests/test_pinocchio_loop.py``
compares the contact force with :class:`tmtcontrol.Simulator`).

Nothing of tmtcontrol's symbolic model or controller is used: the arm is
Pinocchio's model of the same URDF text (``robot.urdf``, held joints locked,
the robot's armature), its tip the frame ``robot.tip``; the dynamics are
Pinocchio's ABA (plant), CRBA, RNEA and frame kinematics (controller); the
controller is written below in NumPy. From tmtcontrol only the run's numbers
are taken: ``Simulator(sc).inputs()`` (the tangential reference, k_e and
noise per sample, the parameter vector with the task frame R, the commanded
tool orientation R_d, the gains, and the start state), read by name through
the layouts.

One control period, as ``closedloop.build_step`` on a 6-D task (paper eqs. 1-6, 13, 18):

* sensor: f_e = max(0, k_e x + d_e dx) while x > 0 (x: tip depth along the
  inward normal), f_m = alpha f_filt + (1 - alpha)(f_e + noise);
* normal axis, TMT (eq. 18 with its safeguards: the smoothstep weight
  between force_threshold and twice it, the compliance clipped to
  [0, 1/min_stiffness]) and the impedance filter eq. (2) stepped by RK4 with
  4 substeps per period; x_c = x_r - x_a (eq. 4);
* tangential axes: the circle; rotational axes: e_o = R^T log(R_d R^T_tool)
  (Pinocchio's log3), omega = R^T J_w dq, U_rot = K_P,rot e_o - K_D,rot omega;
* inner loop eq. (6) and the operational-space torque eq. (5):
  tau = J^T (Lambda (U - dJ dq) + F_e) + C dq + g, Lambda = (J M^-1 J^T)^-1,
  plus, for 7 joints, the null-space posture torque N^T M (K (q_post - q) - D dq);
* plant: q'' = ABA(q, dq, tau - J_p^T n f_e) with the torque held, classical
  RK4 with ``substeps`` steps per period; a period whose four stages do not
  all agree on contact on/off is integrated again from its start with
  ``contact_refine`` times as many steps.

Supported: the TMT law, no guarded approach, no computation delay, fixed normal damping, the
controller's model equal to the plant (no mass scaling, no friction); the
built-in ``ur5`` and ``panda`` scenarios are such. Anything else raises
ValueError naming the setting.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from tmtcontrol.model.robot import task_of
from tmtcontrol.simulation.closedloop import INPUT as POSE_INPUT, param_layout, state_layout

__all__ = ["PinocchioLoop", "PinocchioRun", "pinocchio_arm"]

FILTER_SUBSTEPS = 4
"""RK4 steps of the impedance filter per control period (as ``control.impedance``)."""


def pinocchio_arm(robot):
    """``(model, tip)``: Pinocchio's model of ``robot``'s URDF text (joints not
    actuated locked at their held values; the robot's armature) and the id of
    its tip frame."""
    model = pin.buildModelFromXML(robot.urdf)
    qref = pin.neutral(model)
    lock = []
    for jid in range(1, model.njoints):
        name = model.names[jid]
        if name not in robot.joint_names:
            qref[model.joints[jid].idx_q] = robot.held.get(name, 0.0)
            lock.append(jid)
    if lock:
        model = pin.buildReducedModel(model, lock, qref)
    if [model.names[i] for i in range(1, model.njoints)] != list(robot.joint_names):
        raise ValueError("robot: Pinocchio's joint order differs from the chain's")
    if any(model.joints[i].nq != 1 for i in range(1, model.njoints)):
        raise ValueError("robot: a continuous joint (nq = 2) is not supported here")
    if robot.armature is not None:
        model.armature = np.asarray(robot.armature, float)
    return model, model.getFrameId(robot.tip)


@dataclass(frozen=True)
class PinocchioRun:
    """Per-sample log at t_k (N samples): joints (n, N; rad, rad/s), torque (n, N; N m),
    true and measured normal force (N), orientation error (3, N; rad, task axes); and
    the number of periods integrated again for a contact switch."""
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    contact_force: np.ndarray
    measured_force: np.ndarray
    orientation_error: np.ndarray
    refined: int = 0


class PinocchioLoop:
    """The 6-D loop of scenario ``sc`` on Pinocchio: ``PinocchioLoop(sc, robot).run(U, P, s0)``
    with ``(U, P, s0, t) = Simulator(sc).inputs()`` and ``robot`` the scenario's arm
    (``tmtcontrol.simulation.simulator.robot_of(sc)``)."""

    def __init__(self, sc, robot):
        r, ctl = sc.robot, sc.controller
        if ctl.law.kind != "tmt":
            raise ValueError(f"controller.law: only 'tmt' is written here, got {ctl.law.kind!r}")
        if ctl.damping_schedule.kind != "off":
            raise ValueError("controller.damping_schedule: only 'off' is written here")
        if ctl.delay_samples:
            raise ValueError("controller.delay_samples: the computation delay is not written here; set 0")
        if sc.trajectory.approach_gap > 0:
            raise ValueError("trajectory.approach_gap: the guarded approach is not written here; set 0")
        if ctl.hold != "zero_order":
            raise ValueError("controller.hold: only the zero-order hold is written here")
        if any(ctl.part_offset):
            raise ValueError("controller.part_offset: the part position error is not written here; set 0")
        if sc.environment.shape != "plane":
            raise ValueError("environment.shape: only the plane is written here")
        if r.model_mass_scale != 1.0 or r.friction or r.compensate_friction:
            raise ValueError("robot: the controller's model must equal the plant (no mass scale, no friction)")
        if sc.simulation.integrator != "fixed":
            raise ValueError("simulation.integrator: only 'fixed' (RK4) is written here")
        self.model, self.tip = pinocchio_arm(robot)
        self.data = self.model.createData()
        self.n = self.model.nv
        self.substeps = sc.simulation.substeps
        self.refine = sc.simulation.contact_refine
        self.threshold = ctl.law.force_threshold
        self.min_stiffness = ctl.law.min_stiffness
        self.law = sc.controller.law.kind
        self._refined = 0

    # -- plant: eq. (1) with the unilateral contact, ABA per stage ------------------------------
    def _ode(self, q, dq, tau, k_e, d_e, n_dir, c):
        """(ddq, contact on) at (q, dq) with the torque ``tau`` held."""
        model, data = self.model, self.data
        J = pin.computeFrameJacobian(model, data, q, self.tip, pin.LOCAL_WORLD_ALIGNED)  # also places the frame
        Jp = J[:3]
        depth = n_dir @ (data.oMf[self.tip].translation - c)
        f = k_e * depth + d_e * (n_dir @ (Jp @ dq)) if depth > 0 else 0.0
        f = max(f, 0.0)
        return pin.aba(model, data, q, dq, tau - Jp.T @ (n_dir * f)), f > 0

    def _rk4(self, q, dq, tau, h, steps, env):
        """``steps`` RK4 steps of ``h`` s; and whether the contact state differed between stages."""
        on = []
        for _ in range(steps):
            a1, c1 = self._ode(q, dq, tau, *env)
            q2, v2 = q + h / 2 * dq, dq + h / 2 * a1
            a2, c2 = self._ode(q2, v2, tau, *env)
            q3, v3 = q + h / 2 * v2, dq + h / 2 * a2
            a3, c3 = self._ode(q3, v3, tau, *env)
            q4, v4 = q + h * v3, dq + h * a3
            a4, c4 = self._ode(q4, v4, tau, *env)
            q, dq = q + h / 6 * (dq + 2 * v2 + 2 * v3 + v4), dq + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            on += [c1, c2, c3, c4]
        return q, dq, 0 < sum(on) < len(on)

    def _plant(self, q, dq, tau, Ts, env):
        q1, dq1, switched = self._rk4(q, dq, tau, Ts / self.substeps, self.substeps, env)
        if switched and self.refine > 1:        # a kink of the contact force inside the period
            self._refined += 1
            k = self.refine
            q1, dq1 = q, dq
            for _ in range(k):
                q1, dq1, _ = self._rk4(q1, dq1, tau, Ts / k / self.substeps, self.substeps, env)
        return q1, dq1

    # -- the normal-axis law: TMT eq. (18) and the impedance filter eq. (2) -----------------------
    def _tmt(self, x, f_m, x_e, f_d, k):
        thr = self.threshold
        w = min(max((f_m - thr) / thr, 0.0), 1.0)
        w = w * w * (3 - 2 * w)
        comp = min(max((x - x_e) / max(f_m, thr), 0.0), 1.0 / self.min_stiffness)
        return x_e + f_d / k + w * f_d * comp

    @staticmethod
    def _filter(x_a, v_a, f, m, b, k, Ts):
        acc = lambda xa, va: (f - b * va - k * xa) / m
        h = Ts / FILTER_SUBSTEPS
        for _ in range(FILTER_SUBSTEPS):
            k1x, k1v = v_a, acc(x_a, v_a)
            k2x, k2v = v_a + h / 2 * k1v, acc(x_a + h / 2 * k1x, v_a + h / 2 * k1v)
            k3x, k3v = v_a + h / 2 * k2v, acc(x_a + h / 2 * k2x, v_a + h / 2 * k2v)
            k4x, k4v = v_a + h * k3v, acc(x_a + h * k3x, v_a + h * k3v)
            x_a, v_a = x_a + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x), v_a + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        return x_a, v_a

    # -- the rollout ----------------------------------------------------------------------------
    def run(self, U, P, s0, steps: int | None = None) -> PinocchioRun:
        model, data, tip, n = self.model, self.data, self.tip, self.n
        from tmtcontrol.control.laws import get_law
        law = get_law(self.law)
        Pn = param_layout(task_of(n), law).split(np.asarray(P, float))
        S = state_layout(task_of(n), law).split(np.asarray(s0, float))
        u = POSE_INPUT.split(np.asarray(U, float))
        if S["approach"][0] > 0:
            raise ValueError("start state: approaching (guarded approach) is not written here")
        N = U.shape[1] if steps is None else min(steps, U.shape[1])
        R = Pn["R"].reshape(3, 3, order="F")
        R_d = Pn["R_d"].reshape(3, 3, order="F")
        c, n_dir = Pn["c"], R[:, 0]
        Ts, alpha, d_e = float(Pn["Ts"][0]), float(Pn["alpha"][0]), float(Pn["d_e"][0])
        m, b, k = Pn["m"], Pn["b"], Pn["k"]
        kd, kp, kd_rot, kp_rot = Pn["kd"], Pn["kp"], Pn["kd_rot"], Pn["kp_rot"]
        f_d_set, ramp_rate = float(Pn["f_d"][0]), float(Pn["ramp_rate"][0])
        posture = Pn["q_post"].size > 0               # a redundant arm's null-space posture task
        q_post = Pn["q_post"] if posture else np.zeros(n)
        kp_post, kd_post = (float(Pn["kp_post"][0]), float(Pn["kd_post"][0])) if posture else (0.0, 0.0)
        q, dq = S["q"].copy(), S["dq"].copy()
        f_filt, ramp, x_e_hat = float(S["f_filt"][0]), float(S["ramp"][0]), float(S["x_e_hat"][0])
        x_a, v_a = (float(v) for v in S["law"])
        log = PinocchioRun(q=np.empty((n, N)), dq=np.empty((n, N)), tau=np.empty((n, N)),
                           contact_force=np.empty(N), measured_force=np.empty(N), orientation_error=np.empty((3, N)))
        zero = np.zeros(n)
        self._refined = 0
        for i in range(N):
            k_e = u["k_e"][0, i]
            # encoders through the kinematics; velocities for dJ dq
            pin.forwardKinematics(model, data, q, dq, zero)
            pin.updateFramePlacement(model, data, tip)
            J = pin.computeFrameJacobian(model, data, q, tip, pin.LOCAL_WORLD_ALIGNED)
            dJdq = pin.getFrameClassicalAcceleration(model, data, tip, pin.LOCAL_WORLD_ALIGNED).vector
            T = data.oMf[tip]
            X = R.T @ (T.translation - c)
            dX = R.T @ (J[:3] @ dq)
            f_true = max(k_e * X[0] + d_e * dX[0], 0.0) if X[0] > 0 else 0.0
            f_m = alpha * f_filt + (1 - alpha) * (f_true + u["noise"][0, i])
            f_d = f_d_set * ramp
            # normal axis: TMT reference, impedance filter, command (eqs. 2-4, 18)
            x_r = self._tmt(X[0], f_m, x_e_hat, f_d, k[0])
            dd_a = (f_m - b[0] * v_a - k[0] * x_a) / m[0]
            X_c = np.r_[x_r - x_a, u["pos_t"][:, i]]
            dX_c = np.r_[-v_a, u["vel_t"][:, i]]
            ddX_c = np.r_[-dd_a, u["acc_t"][:, i]]
            x_a, v_a = self._filter(x_a, v_a, f_m, m[0], b[0], k[0], Ts)
            ramp = min(ramp + ramp_rate * Ts, 1.0)
            # inner loop eq. (6): translation on the task axes, rotation by the rotation vector
            U_pos = ddX_c + kd * (dX_c - dX) + kp * (X_c - X)
            e_o = R.T @ pin.log3(R_d @ T.rotation.T)
            w = R.T @ (J[3:] @ dq)
            U_rot = kp_rot * e_o - kd_rot * w
            Ub = np.r_[R @ U_pos, R @ U_rot]
            F_e = np.r_[n_dir * f_m, 0.0, 0.0, 0.0]
            # eq. (5) as the operational-space torque with Pinocchio's M and C dq + g
            M = pin.crba(model, data, q)
            M = np.triu(M) + np.triu(M, 1).T
            nle = pin.rnea(model, data, q, dq, zero)
            A = np.linalg.solve(M, J.T)                   # M^-1 J^T
            Linv = J @ A                                   # Lambda^-1
            tau = J.T @ (np.linalg.solve(Linv, Ub - dJdq) + F_e) + nle
            if n > 6:                                      # null-space posture task
                tau_0 = M @ (kp_post * (q_post - q) - kd_post * dq)
                tau = tau + tau_0 - J.T @ np.linalg.solve(Linv, A.T @ tau_0)
            log.q[:, i], log.dq[:, i], log.tau[:, i] = q, dq, tau
            log.contact_force[i], log.measured_force[i], log.orientation_error[:, i] = f_true, f_m, e_o
            f_filt = f_m
            q, dq = self._plant(q, dq, tau, Ts, (k_e, d_e, n_dir, c))
        return dataclasses.replace(log, refined=self._refined)


def _main():
    """A quick look: the UR5 scenario's first second on Pinocchio and in tmtcontrol."""
    import time

    from tmtcontrol import Simulator, apply_overrides, load_scenario
    from tmtcontrol.simulation.simulator import robot_of

    sc = apply_overrides(load_scenario("ur5"), ["trajectory.cycles=0.25"])
    sim = Simulator(sc)
    U, P, s0, t = sim.inputs()
    t0 = time.perf_counter()
    run = PinocchioLoop(sc, robot_of(sc)).run(U, P, s0)
    dt = time.perf_counter() - t0
    ref = sim.run()
    print(f"{t.size} steps in {dt:.2f} s ({dt / t.size * 1e6:.0f} us/step); max |f_e - f_e(tmtcontrol)| "
          f"{np.abs(run.contact_force - ref.contact_force).max():.3g} N, "
          f"max |e_o - e_o(tmtcontrol)| {np.abs(run.orientation_error - ref.orientation_error).max():.3g} rad, "
          f"max |tau - tau(tmtcontrol)| {np.abs(run.tau - ref.tau).max():.3g} N m")


if __name__ == "__main__":
    _main()
