"""Time-domain simulation of the sampled TMT closed loop (section V).

:class:`Simulator` builds the per-period step (``closedloop.build_step``),
compiles its rollout once (``codegen.Rollout``) and runs it; every numeric
setting (gains, f_d, stiffness profile, noise, Ts, plane geometry) is a
runtime input, so :meth:`Simulator.run` can be called again, with another
scenario of the same structure, without recompiling.
:class:`SimulationResult` holds the named time series.
"""

from __future__ import annotations

import functools
import hashlib
import pathlib
import time
from dataclasses import dataclass, field

import numpy as np

from ..files import VerdictFailed, check_interrupt
from ..control.laws import get_law
from .closedloop import INPUT, LOG, build_step, controller_model, param_layout, state_layout, step_name
from .rollout import Rollout
from .environment import stiffness_samples, task_frame
from ..model.puma560 import Puma560
from .scenario import Scenario, ScenarioError, paper_scenario
from .trajectory import circle_reference
from .traces import SimulationTraces

__all__ = ["Simulator", "SimulationResult", "SimulationError", "PathReport", "check_path",
           "check_run_size", "MAX_STEPS", "contact_detection_threshold",
           "contact_threshold_of"]

MAX_CONDITION = 100.0
"""Largest Jacobian condition number accepted along the path."""

STIFFNESS_ESTIMATE_FORCE = 0.5
"""Force (N) above which the logged stiffness estimate f_m/(x - x_e) of
eq. (14) is reported (NaN below: no contact, or noise)."""

MAX_STEPS = 1_000_000
"""Default limit on control steps per run (1,000 s at 1 kHz); raise it with
``max_steps`` (CLI ``--max-steps``)."""

_BYTES_PER_STEP = 8 * 2 * 60 + 300
"""Rough memory per control step: state, log and inputs (about 60 doubles,
held twice) plus one CSV row."""


CONTACT_NOISE_SIGMAS = 6.0
"""Standard deviations of the filtered sensor noise added to the contact
threshold of the guarded approach (a Gaussian sample exceeds 6 sigma about
once in 1e9 samples: no false contact in a 1,000 s approach at 1 kHz)."""


def contact_detection_threshold(threshold: float, noise_std: float, alpha: float) -> float:
    """The measured force (N) that ends the guarded approach:
    ``controller.contact_threshold`` plus :data:`CONTACT_NOISE_SIGMAS` standard
    deviations of the sensor noise after the force filter, ``noise_std
    sqrt((1 - alpha)/(1 + alpha))`` (the first-order filter
    ``f_m = alpha f_m + (1 - alpha)(f + n)`` with pole ``alpha``; 0: none).
    Noise alone then never ends the approach early (one sample above 1 N with
    0.5 N noise did, 0.3 s early, taking the surface 3 mm too high and hitting
    at 2.6-2.9 f_d);
    without noise it is the threshold itself."""
    if noise_std == 0:
        return threshold
    return threshold + CONTACT_NOISE_SIGMAS * noise_std * (((1.0 - alpha) / (1.0 + alpha)) ** 0.5)


def contact_threshold_of(scenario: Scenario, alpha: float) -> float:
    """:func:`contact_detection_threshold` of ``scenario`` (N); a
    :class:`ScenarioError` if its guarded approach (``trajectory.approach_gap``
    > 0) would end only at or above ``controller.f_d``: the approach would
    push past the desired force before the law engages (a first-contact
    overshoot the user did not ask for). The key named is the one that
    raised it: ``sensor.noise_std`` when the noise margin does."""
    ctl = scenario.controller
    f = contact_detection_threshold(ctl.contact_threshold, scenario.sensor.noise_std, alpha)
    if scenario.trajectory.approach_gap > 0 and ctl.approach_speed > 0 and f >= ctl.f_d:
        if ctl.contact_threshold >= ctl.f_d:
            raise ScenarioError(f"controller.contact_threshold: {ctl.contact_threshold:g} N is not below "
                                f"controller.f_d = {ctl.f_d:g} N; the guarded approach would push past f_d")
        raise ScenarioError(
            f"sensor.noise_std: the guarded approach ends at a filtered force of {f:.3g} N (contact_threshold "
            f"{ctl.contact_threshold:g} N + {CONTACT_NOISE_SIGMAS:g} sigma of the filtered noise), not below "
            f"controller.f_d = {ctl.f_d:g} N; filter the force (sensor.filter_cutoff), lower the noise or "
            "controller.contact_threshold")
    return f


def check_run_size(scenario: Scenario, max_steps: int | None = None) -> int:
    """Number of control steps of ``scenario``; raise :class:`ScenarioError`
    (with the estimate) if it exceeds ``max_steps`` (default :data:`MAX_STEPS`)."""
    limit = MAX_STEPS if max_steps is None else max_steps
    if limit < 1:
        raise ScenarioError(f"--max-steps: must be >= 1, got {limit}")
    steps = scenario.duration / scenario.controller.Ts
    if steps > limit:
        raise ScenarioError(
            f"trajectory.cycles: {steps:,.0f} control steps ({scenario.duration:g} s at "
            f"{scenario.controller.rate:g} Hz, about {steps * _BYTES_PER_STEP / 2**30:,.1f} GiB) exceed the "
            f"limit of {limit:,}; shorten the run or raise the limit with --max-steps")
    return int(round(steps))


class SimulationError(VerdictFailed):
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
    return (r.model, r.tip, r.armature, r.friction, r.model_mass_scale, r.compensate_friction,
            s.integrator, (s.substeps, s.contact_refine) if s.integrator == "fixed" else s.tol,
            scenario.controller.law.kind,
            scenario.controller.delay_samples)


@functools.lru_cache(maxsize=1)
def _package_digest() -> str:
    """SHA-256 of the package's Python sources: any change of the code that
    builds the closed loop gives new cache keys."""
    root = pathlib.Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def structure_key(scenario: Scenario, law) -> str | None:
    """A key that identifies the compiled step of ``scenario`` without building
    it: the package's sources, the structural settings and the law's
    declaration. None for a law declared outside the package (its code is
    not covered by the digest; the step's serialisation is the key then)."""
    if not getattr(law.update, "__module__", "").startswith(__package__.split(".")[0] + "."):
        return None
    return repr((_package_digest(), _structure(scenario), law.name, law.states, law.parameter_names))


def check_path(robot: Puma560, scenario: Scenario, n: int = 361) -> PathReport:
    """Inverse kinematics around the circle (closed form, the default
    branch); raises :class:`ScenarioError` if a point is unreachable or the
    Jacobian is near-singular (cond > 100)."""
    tr = scenario.trajectory
    R = task_frame(scenario.environment.tilt_deg)
    ref = circle_reference(np.linspace(0, tr.period, n), tr.radius, tr.period)
    P = np.asarray(tr.center)[:, None] + R @ np.vstack([np.zeros(n), ref.pos])
    try:
        q = robot.inverse_kinematics(P)
    except ValueError as exc:
        raise ScenarioError(f"trajectory: unreachable path ({exc})") from None
    conds = np.asarray(robot.condition_number.map(n)(q)).ravel()
    k = int(np.argmax(~(conds < MAX_CONDITION)))
    if not conds[k] < MAX_CONDITION:
        raise ScenarioError(f"trajectory: the path passes near a singularity (Jacobian "
                            f"condition number {conds[k]:.3g} > {MAX_CONDITION:g} at "
                            f"{np.round(P[:, k], 4).tolist()} m)")
    return PathReport(q, conds)


_PATHS: dict = {}


def _path(robot: Puma560, scenario: Scenario) -> PathReport:
    """:func:`check_path`, computed once per distinct path (the IK depends only
    on the robot's kinematics, the circle and the surface tilt); the arrays
    are read-only."""
    tr = scenario.trajectory
    key = (tuple(tr.center), tr.radius, tr.period, scenario.environment.tilt_deg, robot.links)
    if key not in _PATHS:
        rep = check_path(robot, scenario)
        rep.q.setflags(write=False)
        rep.condition_number.setflags(write=False)
        if len(_PATHS) > 64:
            _PATHS.clear()
        _PATHS[key] = rep
    return _PATHS[key]


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
    desired_force: np.ndarray        # (N,) f_d in use (ramped after a guarded approach)
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

    @property
    def traces(self) -> SimulationTraces:
        """The series the figures draw and the surface under them, without
        the scenario (the arrays are shared, not copied)."""
        sc = self.scenario
        return SimulationTraces(
            time=self.time, contact_force=self.contact_force, desired_force=self.desired_force,
            stiffness=self.stiffness, stiffness_estimate=self.stiffness_estimate, position=self.position,
            reference_position=self.reference_position, surface_frame=task_frame(sc.environment.tilt_deg),
            center=np.asarray(sc.trajectory.center, dtype=float), radius=float(sc.trajectory.radius))


class Simulator:
    """Build once, run many times.

    Parameters
    ----------
    scenario : Scenario, optional
        Defaults to :func:`paper_scenario`.
    compile : bool or "auto"
        Compile the rollout to C (cached on disk). ``"auto"`` (default): use
        a cached library, else compile once this Simulator has run more than
        :data:`~tmtcontrol.simulation.rollout.COMPILE_AFTER` steps (short
        runs stay on the virtual machine; results are bit-identical either
        way). ``True``: compile now. ``False`` (or no compiler, or
        ``integrator = "cvodes"``) runs on CasADi's virtual machine.

    Examples
    --------
    >>> sim = Simulator(paper_scenario())          # doctest: +SKIP
    >>> res = sim.run()                             # doctest: +SKIP
    >>> res.contact_force[-1]                       # doctest: +SKIP
    10.0001...
    """

    def __init__(self, scenario: Scenario | None = None, compile: bool | str = "auto"):
        self.scenario = scenario or paper_scenario()
        sc = self.scenario
        if sc.robot.model.lower() != "puma560":      # this loop is built on the PUMA's own model class
            from .posesim import robot_of

            n = robot_of(sc).n                        # a model that cannot be loaded: its own one line
            raise ScenarioError(
                f"robot.model: {sc.robot.model!r} has {n} joint{'s' if n != 1 else ''}: "
                + ("Simulator is the 3-joint PUMA 560's position-only loop; an arm with 6 or more joints runs "
                   "PoseSimulator (simulator_for picks the loop)" if n >= 6 else
                   "the 6-D task needs 6 or more (the position-only task is the 3-joint PUMA 560's; docs/robots.md)"))
        t0 = time.perf_counter()
        self.plant = Puma560(armature=sc.robot.armature,
                             friction="smooth" if sc.robot.friction else False)
        self.law = get_law(sc.controller.law.kind)
        self.delay = sc.controller.delay_samples
        # CVODES cannot be code-generated: that reference runs on the virtual machine
        compile = compile if sc.simulation.integrator == "fixed" else False
        key = structure_key(sc, self.law)
        if key is None:
            self.rollout = Rollout(self._build_step(), compile=compile)
        else:           # a cached library is found without building the step
            self.rollout = Rollout(self._build_step, compile=compile,
                                   structure=(step_name(self.law, self.delay), key))
        self.build_time = time.perf_counter() - t0
        self._structure = _structure(sc)

    @functools.cached_property
    def model(self) -> Puma560:
        """The controller's model of the robot (eq. 5's D*^, h*^)."""
        sc = self.scenario
        return controller_model(sc.robot.model_mass_scale, sc.robot.compensate_friction)

    @property
    def step(self):
        """The closed-loop step Function (built on first use)."""
        return self.rollout.step

    def _build_step(self):
        sc = self.scenario
        return build_step(self.plant, self.model, self.law, sc.simulation.integrator, sc.simulation.substeps,
                          sc.simulation.tol, self.delay, sc.simulation.contact_refine)

    def run(self, scenario: Scenario | None = None, max_steps: int | None = None) -> SimulationResult:
        """Simulate ``scenario`` (default: the one given at construction). It
        must have the same structure (robot options, integrator); everything
        numeric may differ. Runs longer than ``max_steps`` control steps
        (default :data:`MAX_STEPS`) are refused before any allocation."""
        sc = scenario or self.scenario
        check_run_size(sc, max_steps)
        if _structure(sc) != self._structure:
            raise ValueError("run(): scenario differs in robot options, integrator, law or delay from the "
                             "one this Simulator was built for; build a new Simulator")
        path = _path(self.plant, sc)
        inputs, params, s0, t = self._inputs(sc, path)
        t0 = time.perf_counter()
        S, L = self.rollout.run(s0, inputs, params)
        check_interrupt()            # CasADi may swallow Ctrl-C inside a long evaluation
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
            raise ScenarioError(f"trajectory.cycles: the run (cycles x period = {sc.duration:g} s) is shorter "
                                f"than one control period (1/controller.rate = {Ts:g} s)")
        t = np.arange(N) * Ts
        R = task_frame(sc.environment.tilt_deg)
        c = np.asarray(sc.trajectory.center, dtype=float)
        ref = circle_reference(t, sc.trajectory.radius, sc.trajectory.period)
        k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
        if not np.all(np.isfinite(k_e)) or np.any(k_e <= 0):
            raise ScenarioError("environment.stiffness: profile must stay finite and > 0")
        if sc.sensor.noise_std > 0:         # numpy.random only then: importing it takes ~6 ms
            noise = sc.sensor.noise_std * np.random.default_rng(sc.sensor.seed).standard_normal(N)
        else:
            noise = np.zeros(N)
        U = np.vstack([ref.pos, ref.vel, ref.acc, k_e[None, :], noise[None, :]])
        kd, kp = sc.impedance.gains
        alpha = sc.sensor.pole(Ts)
        ctl, law = sc.controller, self.law
        sch = ctl.damping_schedule
        on = sch.kind == "zeta"
        P = param_layout(law).pack(
            m=sc.impedance.m, b=sc.impedance.b, k=sc.impedance.k, kd=kd, kp=kp, f_d=ctl.f_d,
            x_e_hat=ctl.x_e_error, alpha=alpha, d_e=sc.environment.damping, R=R.ravel(order="F"), c=c, Ts=Ts,
            sched=1.0 if on else 0.0, zeta=sch.zeta if on else 1.0, b_min=sch.b_min if on else 0.0,
            b_max=sch.b_max if on else 1.0, b_rate=sch.rate if on else 1.0, k_hat_max=sch.k_max if on else 1.0,
            k_hat_min=sch.min_stiffness if on else 1.0, sched_f_th=sch.force_threshold if on else 1.0,
            v_app=ctl.approach_speed, f_contact=contact_threshold_of(sc, alpha),
            ramp_rate=1.0 / ctl.force_ramp,
            law=law.parameter_vector(ctl.law))
        # start on the surface (x = x_e, zero force) or approach_gap above it, moving with the circle
        gap = sc.trajectory.approach_gap
        q0 = path.q[:, 0] if gap == 0 else self.plant.inverse_kinematics(
            c + R @ np.r_[-gap, ref.pos[:, 0]])
        dq0 = np.linalg.solve(np.asarray(self.plant.jacobian(q0)), R @ np.r_[0.0, ref.vel[:, 0]])
        b0 = min(max(sc.impedance.b[0], sch.b_min), sch.b_max) if on else sc.impedance.b[0]
        guarded = gap > 0 and ctl.approach_speed > 0
        s0 = state_layout(law, self.delay).pack(
            q=q0, dq=dq0, f_filt=0.0, b_n=b0, approach=1.0 if guarded else 0.0, x_app=-gap,
            ramp=0.0 if guarded else 1.0, x_e_hat=ctl.x_e_error, tau_wait=np.zeros(3 * self.delay),
            law=law.initial_state(ctl.law))
        return U, P, s0, t

    @staticmethod
    def _check_finite(S, L, t, n: int = 3):
        """Raise :class:`SimulationError` at the first sample where the state
        S or log L is not finite or a joint velocity (rows n..2n of S, an arm
        of n joints) runs away."""
        # fast path: a sum is finite only if every term is (a false alarm from
        # overflow falls through to the exact test below)
        if np.isfinite(S.sum()) and np.isfinite(L.sum()) and np.abs(S[n:2 * n]).max() < 1e3:
            return
        bad = ~(np.all(np.isfinite(S), axis=0) & np.all(np.isfinite(L), axis=0)
                & (np.abs(S[n:2 * n]).max(axis=0) < 1e3))
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
        depth = lg["X"][0] - lg["x_e_hat"][0]
        with np.errstate(divide="ignore", invalid="ignore"):
            k_hat = np.where((f_m > STIFFNESS_ESTIMATE_FORCE) & (depth > 0), f_m / depth, np.nan)
        return SimulationResult(
            scenario=sc, time=t, q=lg["q"], dq=lg["dq"], tau=lg["tau"], position=lg["p"],
            reference_position=to_base(lg["X_r"]), command_position=to_base(lg["X_c"]),
            position_task=lg["X"], reference_task=lg["X_r"], command_task=lg["X_c"],
            contact_force=lg["f_e"][0], measured_force=f_m,
            desired_force=lg["f_d"][0], stiffness=U[INPUT["k_e"]][0],
            stiffness_estimate=k_hat, damping=lg["b_n"][0], path=path, info=info)
