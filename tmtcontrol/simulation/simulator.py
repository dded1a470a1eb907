"""Time-domain simulation of the sampled TMT closed loop (section V).

:class:`Simulator` builds the per-period step (``closedloop.build_step``),
compiles its rollout once (``codegen.Rollout``) and runs it; every numeric
setting (gains, f_d, stiffness profile, noise, Ts, plane geometry) is a
runtime input, so :meth:`Simulator.run` can be called again, with another
scenario of the same structure, without recompiling.
:class:`SimulationResult` holds the named time series.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .closedloop import INPUT, LOG, PARAM, STATE, build_step, controller_model
from .rollout import Rollout
from .environment import stiffness_samples, task_frame
from ..model.puma560 import Puma560
from .scenario import Scenario, ScenarioError, paper_scenario
from .trajectory import circle_reference

__all__ = ["Simulator", "SimulationResult", "SimulationError", "PathReport", "check_path"]

MAX_CONDITION = 100.0
"""Largest Jacobian condition number accepted along the path."""


class SimulationError(RuntimeError):
    """The simulation diverged (non-finite or runaway state)."""


@dataclass(frozen=True)
class PathReport:
    """Joint-space image of the circle and its conditioning."""
    q: np.ndarray                 # (3, n) joint angles along one cycle, rad
    condition_number: np.ndarray  # (n,)

    @property
    def max_condition(self) -> float:
        return float(self.condition_number.max())


def _structure(scenario: Scenario):
    """What changes the compiled step (everything else is a runtime input)."""
    r, s = scenario.robot, scenario.simulation
    return (r.armature, r.friction, r.model_mass_scale, r.compensate_friction,
            s.integrator, s.substeps if s.integrator == "fixed" else s.tol)


def check_path(robot: Puma560, scenario: Scenario, n: int = 361) -> PathReport:
    """Inverse kinematics around the circle; raises :class:`ScenarioError` if a
    point is unreachable or the Jacobian is near-singular (cond > 100)."""
    tr = scenario.trajectory
    R = task_frame(scenario.environment.tilt_deg)
    ref = circle_reference(np.linspace(0, tr.period, n), tr.radius, tr.period)
    qs, conds = [], []
    q = np.array([0.0, -0.6, 0.4])
    for k in range(n):
        p = np.asarray(tr.center) + R @ np.r_[0.0, ref.pos[:, k]]
        try:
            q = robot.inverse_kinematics(p, q0=q)
        except ValueError:
            raise ScenarioError(f"trajectory: point {np.round(p, 4).tolist()} m of the circle is "
                                "outside the workspace (unreachable path)") from None
        c = float(robot.condition_number(q))
        if not c < MAX_CONDITION:
            raise ScenarioError(f"trajectory: the path passes near a singularity (Jacobian "
                                f"condition number {c:.3g} > {MAX_CONDITION:g} at {np.round(p, 4).tolist()} m)")
        qs.append(q)
        conds.append(c)
    return PathReport(np.array(qs).T, np.array(conds))


@dataclass(frozen=True)
class SimulationResult:
    """Time series of one simulation, sampled at the control instants t_k.

    Positions are in the base frame (m) unless named ``*_task`` (task frame,
    normal axis first); forces in N; stiffness in N/m.
    """
    scenario: Scenario
    time: np.ndarray                 # (N,) s
    q: np.ndarray                    # (3, N) rad
    dq: np.ndarray                   # (3, N) rad/s
    tau: np.ndarray                  # (3, N) N m, held over [t_k, t_k+1)
    position: np.ndarray             # (3, N) wrist centre X
    reference_position: np.ndarray   # (3, N) X_r
    command_position: np.ndarray     # (3, N) X_c = X_r - X_a (eq. 4)
    position_task: np.ndarray        # (3, N)
    reference_task: np.ndarray       # (3, N)
    command_task: np.ndarray         # (3, N)
    contact_force: np.ndarray        # (N,) true normal force f_e
    measured_force: np.ndarray       # (N,) sensor output (noise, filter)
    desired_force: np.ndarray        # (N,) f_d
    stiffness: np.ndarray            # (N,) true k_e(t)
    stiffness_estimate: np.ndarray   # (N,) f_m / (x - x_e) of eq. (14); NaN out of contact
    damping: np.ndarray              # (N,) normal impedance damping in use, N s/m
    path: PathReport
    info: dict = field(default_factory=dict)

    @property
    def Ts(self) -> float:
        return self.scenario.controller.Ts

    @property
    def force_error(self) -> np.ndarray:
        """f_e - f_d, N."""
        return self.contact_force - self.desired_force


class Simulator:
    """Build once, run many times.

    Parameters
    ----------
    scenario : Scenario, optional
        Defaults to :func:`paper_scenario`.
    compile : bool
        Compile the rollout to C (cached on disk). ``False`` (or no
        compiler, or ``integrator = "cvodes"``) runs on CasADi's virtual machine.

    Examples
    --------
    >>> sim = Simulator(paper_scenario())          # doctest: +SKIP
    >>> res = sim.run()                             # doctest: +SKIP
    >>> res.contact_force[-1]                       # doctest: +SKIP
    10.0001...
    """

    def __init__(self, scenario: Scenario | None = None, compile: bool = True):
        self.scenario = scenario or paper_scenario()
        sc = self.scenario
        t0 = time.perf_counter()
        self.plant = Puma560(armature=sc.robot.armature,
                             friction="smooth" if sc.robot.friction else False)
        self.model = controller_model(sc.robot.model_mass_scale, sc.robot.compensate_friction)
        self.step = build_step(self.plant, self.model, sc.simulation.integrator,
                               sc.simulation.substeps, sc.simulation.tol)
        self.rollout = Rollout(self.step, compile=compile)
        self.build_time = time.perf_counter() - t0
        self._structure = _structure(sc)

    def run(self, scenario: Scenario | None = None) -> SimulationResult:
        """Simulate ``scenario`` (default: the one given at construction). It
        must have the same structure (robot options, integrator); everything
        numeric may differ."""
        sc = scenario or self.scenario
        if _structure(sc) != self._structure:
            raise ValueError("run(): scenario differs in robot options or integrator from the "
                             "one this Simulator was built for; build a new Simulator")
        path = check_path(self.plant, sc)
        inputs, params, s0, t = self._inputs(sc, path)
        t0 = time.perf_counter()
        S, L = self.rollout.run(s0, inputs, params)
        run_time = time.perf_counter() - t0
        self._check_finite(S, L, t)
        return self._result(sc, t, L, inputs, path,
                            {"integrator": sc.simulation.integrator, "code": self.rollout.how,
                             "build_time_s": self.build_time, "run_time_s": run_time,
                             "steps": t.size})

    # -- helpers -------------------------------------------------------------------
    def _inputs(self, sc: Scenario, path: PathReport):
        Ts = sc.controller.Ts
        N = int(round(sc.duration / Ts))
        if N < 1:
            raise ScenarioError("trajectory.cycles: simulated time is shorter than one control period")
        t = np.arange(N) * Ts
        R = task_frame(sc.environment.tilt_deg)
        c = np.asarray(sc.trajectory.center, dtype=float)
        ref = circle_reference(t, sc.trajectory.radius, sc.trajectory.period)
        k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
        if not np.all(np.isfinite(k_e)) or np.any(k_e <= 0):
            raise ScenarioError("environment.stiffness: profile must stay finite and > 0")
        rng = np.random.default_rng(sc.sensor.seed)
        noise = sc.sensor.noise_std * rng.standard_normal(N) if sc.sensor.noise_std > 0 else np.zeros(N)
        U = np.vstack([ref.pos, ref.vel, ref.acc, k_e[None, :], noise[None, :]])
        kd, kp = sc.impedance.gains
        fc = sc.sensor.filter_cutoff
        alpha = float(np.exp(-2 * np.pi * fc * Ts)) if fc > 0 else 0.0
        ctl = sc.controller
        P = PARAM.pack(m=sc.impedance.m, b=sc.impedance.b, k=sc.impedance.k, kd=kd, kp=kp,
                       f_d=ctl.f_d, law=0 if ctl.law == "tmt" else 1,
                       k_assumed=ctl.assumed_stiffness, f_th=ctl.force_threshold,
                       k_min=ctl.min_stiffness, x_e_hat=ctl.x_e_error, alpha=alpha,
                       d_e=sc.environment.damping, R=R.ravel(order="F"), c=c, Ts=Ts,
                       sched=1.0 if ctl.damping_schedule == "zeta" else 0.0, zeta=ctl.schedule_zeta,
                       b_min=ctl.schedule_b_min, b_max=ctl.schedule_b_max, b_rate=ctl.schedule_rate,
                       k_hat_max=ctl.schedule_k_max)
        # start on the surface (x = x_e, zero force), moving with the circle
        q0 = path.q[:, 0]
        dq0 = np.linalg.solve(np.asarray(self.plant.jacobian(q0)), R @ np.r_[0.0, ref.vel[:, 0]])
        b0 = min(max(sc.impedance.b[0], ctl.schedule_b_min), ctl.schedule_b_max)
        s0 = STATE.pack(q=q0, dq=dq0, xa=0.0, dxa=0.0, f_filt=0.0, b_n=b0)
        return U, P, s0, t

    @staticmethod
    def _check_finite(S, L, t):
        bad = ~(np.all(np.isfinite(S), axis=0) & np.all(np.isfinite(L), axis=0)
                & (np.abs(S[3:6]).max(axis=0) < 1e3))
        if bad.any():
            k = int(np.argmax(bad))
            raise SimulationError(f"simulation diverged at t = {t[k]:.4f} s (non-finite or runaway "
                                  "joint velocity); check the stiffness, gains and control rate")

    @staticmethod
    def _result(sc, t, L, U, path, info) -> SimulationResult:
        lg = LOG.split(L)
        R = task_frame(sc.environment.tilt_deg)
        c = np.asarray(sc.trajectory.center, dtype=float)[:, None]
        to_base = lambda X: c + R @ X
        f_m = lg["f_m"][0]
        depth = lg["X"][0] - sc.controller.x_e_error
        with np.errstate(divide="ignore", invalid="ignore"):
            k_hat = np.where((f_m > sc.controller.force_threshold) & (depth > 0), f_m / depth, np.nan)
        return SimulationResult(
            scenario=sc, time=t, q=lg["q"], dq=lg["dq"], tau=lg["tau"], position=lg["p"],
            reference_position=to_base(lg["X_r"]), command_position=to_base(lg["X_c"]),
            position_task=lg["X"], reference_task=lg["X_r"], command_task=lg["X_c"],
            contact_force=lg["f_e"][0], measured_force=f_m,
            desired_force=np.full(t.size, sc.controller.f_d), stiffness=U[INPUT["k_e"]][0],
            stiffness_estimate=k_hat, damping=lg["b_n"][0], path=path, info=info)
