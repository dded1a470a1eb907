"""Time-domain simulation of the 6-D task-frame loop (arms with >= 6 joints).

:class:`PoseSimulator` is :class:`.simulator.Simulator` for an arm loaded by
``load_robot`` (``robot.model``): it checks the whole path before simulating
(:func:`.posture.check_pose_path`: reachable with the commanded tool
orientation, within the joint limits, away from singularities; a failure is
one line naming the path time), starts on the surface at the solved start
posture, builds the step of :func:`.taskframe.build_pose_step` and rolls it
out with the same compiled :class:`.rollout.Rollout`. Its result is a
:class:`PoseSimulationResult`: the PUMA's named series (joint arrays with n
rows) plus the orientation error.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from ..control.laws import get_law
from ..files import check_interrupt
from ..model import URDFError, load_robot
from ..model.urdf import TipError
from .closedloop import INPUT
from .environment import stiffness_samples
from .geometry import surface_frame, tool_orientation
from .posture import PATH_SAMPLES, PosePath, check_pose_path, pose_solver, solve_pose
from .rollout import Rollout
from .scenario import Scenario, ScenarioError
from .simulator import (STIFFNESS_ESTIMATE_FORCE, SimulationResult, Simulator, _structure,
                        check_run_size, contact_threshold_of)
from .taskframe import build_pose_step, pose_log_layout, pose_param_layout, pose_state_layout
from .trajectory import circle_reference

__all__ = ["PoseSimulator", "PoseSimulationResult", "robot_of", "pose_path", "simulator_for"]


@dataclass(frozen=True)
class PoseSimulationResult(SimulationResult):
    """A :class:`.simulator.SimulationResult` of the 6-D loop; ``q``, ``dq``,
    ``tau`` have one row per joint, and ``orientation_error`` (3, N) is the
    rotation vector log(R_c R^T) on the task axes (rad)."""
    orientation_error: np.ndarray | None = None

    @property
    def traces(self):
        """As :attr:`.simulator.SimulationResult.traces`, on the scenario's surface frame."""
        from .traces import SimulationTraces

        sc = self.scenario
        return SimulationTraces(
            time=self.time, contact_force=self.contact_force, desired_force=self.desired_force,
            stiffness=self.stiffness, stiffness_estimate=self.stiffness_estimate, position=self.position,
            reference_position=self.reference_position, surface_frame=surface_frame(sc.environment),
            center=np.asarray(sc.trajectory.center, dtype=float), radius=float(sc.trajectory.radius),
            orientation_error=self.orientation_error_norm)

    @property
    def orientation_error_norm(self) -> np.ndarray:
        """Angle between the tool orientation and its command (N,), rad."""
        return np.linalg.norm(self.orientation_error, axis=0)


@functools.lru_cache(maxsize=8)
def _robot(model: str, tip, friction, armature: bool, mass_scale: float):
    return load_robot(model, tip=tip, friction=friction, armature=armature, mass_scale=mass_scale)


def robot_of(scenario: Scenario, controller: bool = False):
    """The simulated arm of ``scenario`` (``controller``: the controller's
    model of it, mass-scaled, with the friction it compensates); a
    :class:`ScenarioError` naming ``robot.model``/``robot.tip`` if it cannot
    be loaded."""
    r = scenario.robot
    friction = ("smooth" if r.compensate_friction else False) if controller else ("smooth" if r.friction else False)
    try:
        return _robot(r.model, r.tip, friction, r.armature, r.model_mass_scale if controller else 1.0)
    except URDFError as exc:
        key = "robot.tip" if isinstance(exc, TipError) else "robot.model"
        raise ScenarioError(f"{key}: {exc}") from None


def _frames(sc: Scenario):
    R = surface_frame(sc.environment)
    return R, tool_orientation(R, sc.trajectory.tool_spin_deg), np.asarray(sc.trajectory.center, dtype=float)


_PATHS: dict = {}


def pose_path(robot, sc: Scenario) -> PosePath:
    """:func:`.posture.check_pose_path` over one period of the circle
    (:data:`.posture.PATH_SAMPLES` points), seeded by ``robot.q0`` (default
    the middle of the joint limits); computed once per distinct path."""
    tr, r = sc.trajectory, sc.robot
    R, R_d, c = _frames(sc)
    if r.q0 is not None and len(r.q0) != robot.n:
        raise ScenarioError(f"robot.q0: expected {robot.n} values (one per joint of {robot.name}), got {len(r.q0)}")
    for i, (v, lo, hi) in enumerate(zip(r.q0 or (), robot.q_min, robot.q_max)):
        if not lo <= v <= hi:          # the seed itself: not the path's fault
            raise ScenarioError(f"robot.q0[{i}]: {v:g} is outside {robot.joint_names[i]}'s limits [{lo:.4g}, {hi:.4g}]")
    seed = np.asarray(r.q0, float) if r.q0 is not None else np.where(
        np.isfinite(robot.q_min) & np.isfinite(robot.q_max), (robot.q_min + robot.q_max) / 2, 0.0)
    key = (robot.key, tuple(c), tr.radius, tr.period, R.tobytes(), R_d.tobytes(), seed.tobytes())
    if key not in _PATHS:
        t = np.arange(PATH_SAMPLES) * tr.period / PATH_SAMPLES
        ref = circle_reference(t, tr.radius, tr.period)
        pts = c[:, None] + R @ np.vstack([np.zeros(t.size), ref.pos])
        if len(_PATHS) > 16:
            _PATHS.clear()
        _PATHS[key] = check_pose_path(robot, pts, R_d, t, seed)
    return _PATHS[key]


class PoseSimulator:
    """Build once, run many times: the 6-D loop of ``scenario``'s arm.

    Parameters
    ----------
    scenario : Scenario
        ``robot.model`` an arm with >= 6 joints.
    compile : bool or "auto"
        As :class:`.simulator.Simulator`.
    """

    def __init__(self, scenario: Scenario, compile: bool | str = "auto"):
        self.scenario = sc = scenario
        t0 = time.perf_counter()
        self.plant = robot_of(sc)
        if self.plant.n < 6:
            raise ScenarioError(f"robot.model: the 6-D loop needs an arm with at least 6 joints, "
                                f"{self.plant.name} has {self.plant.n}")
        self.model = robot_of(sc, controller=True)
        self.law = get_law(sc.controller.law.kind)
        compile = compile if sc.simulation.integrator == "fixed" else False
        s = sc.simulation
        self.delay = sc.controller.delay_samples
        self.rollout = Rollout(build_pose_step(self.plant, self.model, self.law, s.integrator, s.substeps, s.tol,
                                               s.contact_refine, self.delay), compile=compile)
        self.build_time = time.perf_counter() - t0
        self._structure = _structure(sc)

    @property
    def step(self):
        return self.rollout.step

    def run(self, scenario: Scenario | None = None, max_steps: int | None = None) -> PoseSimulationResult:
        """Simulate ``scenario`` (default the one given at construction; same
        arm and integrator)."""
        sc = scenario or self.scenario
        check_run_size(sc, max_steps)
        if _structure(sc) != self._structure:
            raise ValueError("run(): scenario differs in robot options, integrator, law or delay from the "
                             "one this PoseSimulator was built for; build a new one")
        path = pose_path(self.plant, sc)
        U, P, s0, t = self._inputs(sc, path)
        t0 = time.perf_counter()
        S, L = self.rollout.run(s0, U, P)
        check_interrupt()
        run_time = time.perf_counter() - t0
        Simulator._check_finite(S, L, t, self.plant.n)
        return self._result(sc, t, L, U, path, {"integrator": sc.simulation.integrator, "code": self.rollout.how,
                                                "build_time_s": self.build_time, "run_time_s": run_time,
                                                "steps": t.size, "robot": self.plant.name})

    def inputs(self, sc: Scenario | None = None):
        """``(U, P, s0, t)``: the rollout's inputs, parameters, start state and times."""
        sc = sc or self.scenario
        return self._inputs(sc, pose_path(self.plant, sc))

    def _inputs(self, sc: Scenario, path: PosePath):
        Ts = sc.controller.Ts
        N = int(round(sc.duration / Ts))
        if N < 1:
            raise ScenarioError(f"trajectory.cycles: the run (cycles x period = {sc.duration:g} s) is shorter "
                                f"than one control period (1/controller.rate = {Ts:g} s)")
        t = np.arange(N) * Ts
        R, R_d, c = _frames(sc)
        ref = circle_reference(t, sc.trajectory.radius, sc.trajectory.period)
        k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
        if not np.all(np.isfinite(k_e)) or np.any(k_e <= 0):
            raise ScenarioError("environment.stiffness: profile must stay finite and > 0")
        noise = (sc.sensor.noise_std * np.random.default_rng(sc.sensor.seed).standard_normal(N)
                 if sc.sensor.noise_std > 0 else np.zeros(N))
        U = np.vstack([ref.pos, ref.vel, ref.acc, k_e[None, :], noise[None, :]])
        assert U.shape[0] == INPUT.size
        imp, ctl, law, n = sc.impedance, sc.controller, self.law, self.plant.n
        kd, kp = imp.gains
        alpha = sc.sensor.pole(Ts)
        sch = ctl.damping_schedule
        on = sch.kind == "zeta"
        gap = sc.trajectory.approach_gap
        q0 = path.q[:, 0]
        if gap > 0:
            q0, ok = solve_pose(self.plant, pose_solver(self.plant), c + R @ np.r_[-gap, ref.pos[:, 0]], R_d, q0)
            if not ok:
                raise ScenarioError(f"trajectory.approach_gap: the start {gap:g} m above the surface is not "
                                    "reachable with the commanded orientation within the joint limits")
        P = pose_param_layout(n, law).pack(
            m=imp.m, b=imp.b, k=imp.k, kd=kd, kp=kp, f_d=ctl.f_d, x_e_hat=ctl.x_e_error, alpha=alpha,
            d_e=sc.environment.damping, R=R.ravel(order="F"), c=c, Ts=Ts,
            sched=1.0 if on else 0.0, zeta=sch.zeta if on else 1.0, b_min=sch.b_min if on else 0.0,
            b_max=sch.b_max if on else 1.0, b_rate=sch.rate if on else 1.0, k_hat_max=sch.k_max if on else 1.0,
            k_hat_min=sch.min_stiffness if on else 1.0, sched_f_th=sch.force_threshold if on else 1.0,
            v_app=ctl.approach_speed,
            f_contact=contact_threshold_of(sc, alpha),
            ramp_rate=1.0 / ctl.force_ramp, law=law.parameter_vector(ctl.law),
            R_d=R_d.ravel(order="F"), kd_rot=np.divide(imp.b_rot, imp.m_rot), kp_rot=np.divide(imp.k_rot, imp.m_rot),
            q_post=q0, kp_post=sc.robot.posture_kp, kd_post=sc.robot.posture_kd)
        # start at rest in the task's rotation, moving with the circle (least-norm joint rates)
        v0 = np.r_[R @ np.r_[0.0, ref.vel[:, 0]], np.zeros(3)]
        dq0 = np.linalg.pinv(self.plant.jacobian(q0)) @ v0
        b0 = min(max(imp.b[0], sch.b_min), sch.b_max) if on else imp.b[0]
        guarded = gap > 0 and ctl.approach_speed > 0
        s0 = pose_state_layout(n, law, self.delay).pack(
            q=q0, dq=dq0, f_filt=0.0, b_n=b0, approach=1.0 if guarded else 0.0, x_app=-gap,
            ramp=0.0 if guarded else 1.0, x_e_hat=ctl.x_e_error, tau_wait=np.zeros(n * self.delay),
            law=law.initial_state(ctl.law))
        return U, P, s0, t

    def _result(self, sc, t, L, U, path, info) -> PoseSimulationResult:
        lg = pose_log_layout(self.plant.n).split(L)
        R, _, c = _frames(sc)
        to_base = lambda X: c[:, None] + R @ X
        f_m = lg["f_m"][0]
        depth = lg["X"][0] - lg["x_e_hat"][0]
        with np.errstate(divide="ignore", invalid="ignore"):
            k_hat = np.where((f_m > STIFFNESS_ESTIMATE_FORCE) & (depth > 0), f_m / depth, np.nan)
        return PoseSimulationResult(
            scenario=sc, time=t, q=lg["q"], dq=lg["dq"], tau=lg["tau"], position=lg["p"],
            reference_position=to_base(lg["X_r"]), command_position=to_base(lg["X_c"]),
            position_task=lg["X"], reference_task=lg["X_r"], command_task=lg["X_c"],
            contact_force=lg["f_e"][0], measured_force=f_m, desired_force=lg["f_d"][0],
            stiffness=U[INPUT["k_e"]][0], stiffness_estimate=k_hat, damping=lg["b_n"][0], path=path,
            info=info, orientation_error=lg["e_o"])


def simulator_for(scenario: Scenario, compile: bool | str = "auto"):
    """The simulator of ``scenario``'s arm, chosen by its task dimension: the
    position-only loop (:class:`.simulator.Simulator`) for an arm with fewer
    than 6 joints (the PUMA's 3), else the 6-D loop (:class:`PoseSimulator`)."""
    from .simulator import Simulator

    if robot_of(scenario).n < 6:
        return Simulator(scenario, compile=compile)
    return PoseSimulator(scenario, compile=compile)
