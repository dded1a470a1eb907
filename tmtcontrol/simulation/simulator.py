"""Time-domain simulation of the sampled TMT closed loop (section V), on any arm and surface.

:class:`Simulator` loads the scenario's arm (``load_robot``: the paper's
PUMA, a bundled arm or a URDF), checks the whole path before simulating
(:func:`.posture.check_pose_path`: reachable, within the joint limits, away
from singularities; a failure is one line naming the path time), builds the
per-period step of :func:`.closedloop.build_step` for the robot's task and
the scenario's surface, compiles its rollout once (:class:`.rollout.Rollout`)
and runs it; every numeric setting (gains, f_d, stiffness profile, noise,
Ts, the surface's parameters) is a runtime input, so :meth:`Simulator.run`
can be called again, with another scenario of the same structure, without
recompiling. :class:`SimulationResult` holds the named time series.

The analyses (``stability/``) use the same Simulator through its public
loop interface: :attr:`Simulator.layout`, :attr:`Simulator.log`,
:meth:`Simulator.build_step`, :meth:`Simulator.inputs`,
:meth:`Simulator.path`, :meth:`Simulator.joints_at`,
:meth:`Simulator.tool_position`, :meth:`Simulator.joint_rates` and
:meth:`Simulator.normal_mass`: one algorithm on any arm.
"""

from __future__ import annotations

import functools
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from ..control.laws import get_law, is_package_law
from ..files import VerdictFailed, check_interrupt
from ..model import URDFError, load_robot
from ..model.robot import source_stamp
from ..model.urdf import TipError
from .closedloop import INPUT, build_step, build_tangent, log_layout, param_layout, state_layout, step_name
from .geometry import surface_of, tool_orientation, under_the_commanded_path
from .limits import JointLimits, LimitUse, limit_use, limits_of
from .posture import PATH_SAMPLES, PosePath, check_pose_path, pose_solver, solve_pose, task_jacobian
from .rollout import Rollout
from .environment import CONTACT_NOISE_SIGMAS, contact_detection_threshold, has_approach, stiffness_samples
from .scenario import Scenario, ScenarioError, ScheduledDamping, paper_scenario
from .traces import SimulationTraces
from .trajectory import path_extent, path_reference

__all__ = ["Simulator", "SimulationResult", "SimulationError", "PosePath", "check_run_size", "MAX_STEPS", "robot_task",
           "contact_detection_threshold", "contact_threshold_of", "robot_of", "path_of", "check_joint_settings",
           "structure", "structure_key", "normal_mass", "simulator_for"]

STIFFNESS_ESTIMATE_FORCE = 0.5
"""Force (N) above which the logged stiffness estimate f_m/(x - x_e) of
eq. (14) is reported (NaN below: no contact, or noise)."""

RUNAWAY_RATE = 1e3
"""A joint rate (rad/s) at or above which a run has diverged (``Simulator._check_finite``)."""

MAX_STEPS = 1_000_000
"""Default limit on control steps per run (1,000 s at 1 kHz); raise it with
``max_steps`` (CLI ``--max-steps``)."""

_BYTES_PER_STEP = 8 * 2 * 60 + 300
"""Rough memory per control step: state, log and inputs (about 60 doubles,
held twice) plus one CSV row."""


def contact_threshold_of(scenario: Scenario, alpha: float) -> float:
    """:func:`contact_detection_threshold` of ``scenario`` (N); a
    :class:`ScenarioError` if its guarded approach (``trajectory.approach_gap``
    > 0) would end only at or above ``controller.f_d``: the approach would
    push past the desired force before the law engages (a first-contact
    overshoot the user did not ask for). The key named is the one that
    raised it: ``sensor.noise_std`` when the noise margin does."""
    ctl = scenario.controller
    f = contact_detection_threshold(ctl.contact_threshold, scenario.sensor.noise_std, alpha)
    if has_approach(scenario) and f >= ctl.f_d:
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
        # digit by digit up to 1e15; beyond, the exponent (review 13: a 1e300 s period printed 300 digits)
        gib = steps * _BYTES_PER_STEP / 2**30
        # a run under a GiB in MiB (review 59: a small --max-steps refusal said "about 0.0 GiB")
        size = ((f"{gib:,.1f}" if gib < 1e15 else f"{gib:.3g}") + " GiB" if gib >= 1 else
                f"{max(gib * 1024, 1):,.0f} MiB")
        raise ScenarioError(
            "trajectory.cycles: " + (f"{steps:,.0f}" if steps < 1e15 else f"{steps:.3g}")
            + f" control steps ({scenario.duration:g} s at {scenario.controller.rate:g} Hz, about "
            + size + f") exceed the limit of {limit:,}; shorten the run or raise the limit with --max-steps")
    return int(round(steps))


def _cvodes_run(rollout, s0, inputs, params):
    """``rollout.run`` with CVODES inside: its failure (the state running
    away, a tolerance it cannot meet) is a :class:`SimulationError` naming
    CVODES' flag, and a Ctrl-C inside its right-hand side (which CasADi turns
    into a solver failure) an interrupt; SUNDIALS' and CasADi's messages and
    input dumps, written to the process' standard error, are kept off the
    terminal while it runs (review 13: 130 lines and a traceback) and shown
    after a run that succeeded."""
    import re
    import tempfile

    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):        # no real standard error (captured): nothing to keep off
        fd = None
    with tempfile.TemporaryFile() as kept:
        saved = None
        if fd is not None:
            sys.stderr.flush()
            saved = os.dup(fd)
            os.dup2(kept.fileno(), fd)
        try:
            out = rollout.run(s0, inputs, params)
        except RuntimeError as exc:
            failure = exc
        else:
            failure = None
        finally:
            if saved is not None:
                os.dup2(saved, fd)
                os.close(saved)
        if failure is None:
            kept.seek(0)
            text = kept.read().decode(errors="replace")
            if text:
                sys.stderr.write(text)
            return out
    check_interrupt()
    flag = re.findall(r'CVode returned "(\w+)"', str(failure))
    raise SimulationError("simulation diverged: the CVODES integrator stopped" + (f" ({flag[-1]})" if flag else "")
                          + "; check the stiffness, gains, control rate and simulation.tol")


class SimulationError(VerdictFailed):
    """The simulation diverged (non-finite or runaway state)."""


@functools.lru_cache(maxsize=8)
def _robot(model: str, tip, friction, armature: bool, mass_scale: float, stamp=None):
    # ``stamp``: the file's identity (``model.robot.source_stamp``), so that a URDF rewritten in place is loaded again
    return load_robot(model, tip=tip, friction=friction, armature=armature, mass_scale=mass_scale)


def robot_of(scenario: Scenario, controller: bool = False):
    """The simulated arm of ``scenario`` (``controller``: the controller's
    model of it, mass-scaled by ``robot.model_mass_scale``, with the friction
    it compensates); a :class:`ScenarioError` naming ``robot.model`` /
    ``robot.tip`` if it cannot be loaded."""
    r = scenario.robot
    friction = ("smooth" if r.compensate_friction else False) if controller else ("smooth" if r.friction else False)
    try:
        return _robot(r.model, r.tip, friction, r.armature, r.model_mass_scale if controller else 1.0,
                      source_stamp(r.model))
    except URDFError as exc:
        key = "robot.tip" if isinstance(exc, TipError) else "robot.model"
        raise ScenarioError(f"{key}: {exc}") from None


def robot_task(robot):
    """``robot.task``, or a :class:`ScenarioError` naming ``robot.model`` (an arm
    with fewer joints than the closed loop needs)."""
    try:
        return robot.task
    except ValueError as exc:
        raise ScenarioError(f"robot.model: {robot.name} has {exc}") from None


def structure(scenario: Scenario):
    """What changes the compiled step (everything else is a runtime input):
    the files a scenario names (a URDF, a height map) by their content, so
    that one rewritten in place is another structure (review 47)."""
    r, s = scenario.robot, scenario.simulation
    return (r.model, r.tip, r.armature, r.friction, r.model_mass_scale, r.compensate_friction,
            s.integrator, (s.substeps, s.contact_refine) if s.integrator == "fixed" else s.tol,
            scenario.controller.law.kind, scenario.controller.delay_samples, scenario.controller.hold,
            surface_of(scenario).key, robot_of(scenario).key)


@functools.lru_cache(maxsize=1)
def _package_digest() -> str:
    """SHA-256 of the package's Python sources (``tmtcontrol.cache.package_digest``):
    any change of the code that builds the closed loop gives new cache keys."""
    from ..cache import package_digest

    return package_digest()


def structure_key(scenario: Scenario, law) -> str | None:
    """A key that identifies the compiled step of ``scenario`` without building
    it: the package's sources, the structural settings, the arm's and the
    controller model's content and the law's declaration. None for a law
    that is not the package's own declaration (its code is not covered by
    the digest; the step's serialisation is the key then): one derived from
    a package law (``TMT.replace(name=..., steady_force=...)``) shares its
    update but not its other fields."""
    if not is_package_law(law):
        return None
    return repr((_package_digest(), structure(scenario), robot_of(scenario).key,
                 robot_of(scenario, controller=True).key, law.name, law.states, law.parameter_names))


def _frames(sc: Scenario):
    """``(surface, R_d)``: the scenario's surface and the commanded tool
    orientation (tool z along the inward normal at the path's centre)."""
    surface = surface_of(sc)
    return surface, tool_orientation(surface.frame(sc.trajectory.center), sc.trajectory.tool_spin_deg)


def orientation_at(sc: Scenario, surface, points, R_d):
    """The commanded tool orientation at base-frame ``points`` (3 or 3 x k,
    m): ``R_d`` on a surface whose frame does not turn, else the tool
    orientation on the task frame at each point (k x 3 x 3 for 3 x k
    points)."""
    if not surface.turns:
        return R_d
    pts = np.asarray(points, dtype=float)
    spin = sc.trajectory.tool_spin_deg
    if pts.ndim == 1:
        return tool_orientation(surface.frame(pts), spin)
    return np.stack([tool_orientation(surface.frame(p), spin) for p in pts.T])


_PATHS: dict = {}


def check_joint_settings(robot, sc: Scenario, limits: bool = True) -> None:
    """A :class:`ScenarioError` naming the key if ``sc``'s per-joint settings
    do not fit ``robot``: ``robot.q0`` (one value per joint, each within
    its joint's limits, and only for an arm whose path is solved from a
    seed) and, with ``limits``, ``robot.tau_max`` / ``robot.dq_max``
    (:func:`.limits.limits_of`). Cheap (no path is solved): a sweep checks
    every arm its cases run before the first case (``sweep.spec``)."""
    r = sc.robot
    if r.q0 is not None and len(r.q0) != robot.n:
        raise ScenarioError(f"robot.q0: expected {robot.n} values (one per joint of {robot.name}), got {len(r.q0)}")
    if r.q0 is not None and robot.position_ik is not None and not robot_task(robot).rotational:
        raise ScenarioError(f"robot.q0: not used: {robot.name}'s path is solved by its closed-form inverse "
                            "kinematics (one configuration), not from a seed; leave q0 unset")
    for i, (v, lo, hi) in enumerate(zip(r.q0 or (), robot.q_min, robot.q_max)):
        if not lo <= v <= hi:          # the seed itself: not the path's fault
            raise ScenarioError(f"robot.q0[{i}]: {v:g} is outside {robot.joint_names[i]}'s limits [{lo:.4g}, {hi:.4g}]")
    if limits:
        limits_of(robot, sc)


def path_of(robot, sc: Scenario) -> PosePath:
    """:func:`.posture.check_pose_path` over one period of the path
    (:data:`.posture.PATH_SAMPLES` points), seeded by ``robot.q0`` (default
    the middle of the joint limits); computed once per distinct path (the
    arrays are read-only)."""
    tr, r = sc.trajectory, sc.robot
    surface, R_d = _frames(sc)
    check_joint_settings(robot, sc, limits=False)
    finite = np.isfinite(robot.q_min) & np.isfinite(robot.q_max)
    seed = np.asarray(r.q0, float) if r.q0 is not None else np.where(
        finite, (np.where(finite, robot.q_min, 0.0) + np.where(finite, robot.q_max, 0.0)) / 2, 0.0)
    offset = tuple(float(v) for v in sc.controller.part_offset)
    key = (robot.key, repr(surface), tr.path, tr.radius, tr.period, tr.lanes, tr.direction_deg, R_d.tobytes(),
           seed.tobytes(), offset)
    if key not in _PATHS:
        robot_task(robot)
        t = np.arange(PATH_SAMPLES) * tr.period / PATH_SAMPLES
        ref = path_reference(t, tr)
        # on the true part, under the path the controller commands on its part (moved by controller.part_offset)
        pts = surface.to_base(under_the_commanded_path(sc, np.vstack([np.zeros(t.size), ref.pos])))
        if len(_PATHS) > 16:
            _PATHS.clear()
        try:
            path = check_pose_path(robot, pts, orientation_at(sc, surface, pts, R_d), t, seed)
        except ScenarioError as exc:
            if not any(offset):
                raise
            raise type(exc)(f"{exc}; the path under the controller's part, moved by controller.part_offset = "
                            f"{list(offset)} m") from None
        for a in (path.t, path.q, path.sigma_min, path.condition_number):
            a.setflags(write=False)
        _PATHS[key] = path
    return _PATHS[key]


def normal_mass(robot, q, n) -> float:
    """Effective mass (kg) of ``robot`` at joints ``q`` along the unit
    direction ``n`` (base frame): ``1/(n^T J_v M^-1 J_v^T n)``, J_v the linear
    rows of the geometric Jacobian (the mass the normal axis meets with the
    other axes free)."""
    Jv = np.asarray(robot.jacobian(q))[:3]
    return float(1.0 / (n @ Jv @ np.linalg.solve(np.asarray(robot.mass_matrix(q)), Jv.T @ n)))


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Time series of one simulation, sampled at the control instants t_k.

    Positions are in the base frame (m) unless named ``*_task`` (task frame,
    normal axis first); forces in N; stiffness in N/m; joint arrays have one
    row per joint.
    """
    scenario: Scenario
    time: np.ndarray                 # (N,) s
    q: np.ndarray                    # (n, N) rad
    dq: np.ndarray                   # (n, N) rad/s
    tau: np.ndarray                  # (n, N) N m, held over [t_k, t_k+1)
    position: np.ndarray             # (3, N) tool point X
    reference_position: np.ndarray   # (3, N) X_r
    command_position: np.ndarray     # (3, N) X_c = X_r - X_a (eq. 4)
    position_task: np.ndarray        # (3, N)
    reference_task: np.ndarray       # (3, N)
    command_task: np.ndarray         # (3, N)
    contact_force: np.ndarray        # (N,) true normal force f_e
    measured_force: np.ndarray       # (N,) sensor output (noise, filter)
    desired_force: np.ndarray        # (N,) f_d in use (ramped after a guarded approach)
    stiffness: np.ndarray            # (N,) true k_e(t)
    stiffness_estimate: np.ndarray   # (N,) f_m / (x - x_e) of eq. (14), N/m; NaN where f_m <= 0.5 N or x <= x_e
    damping: np.ndarray              # (N,) normal impedance damping in use, N s/m
    path: PosePath
    info: dict = field(default_factory=dict)
    orientation_error: np.ndarray | None = None   # (3, N) rotation vector log(R_d R^T), task axes, rad; None: position task
    limits: JointLimits | None = None             # the arm's limits the run is judged against (.limits)
    tool: str = "tool point"                      # what ``position`` is: "<robot> <tip frame> origin"
    posture_drift: np.ndarray | None = None       # (n,) rad: a redundant arm's drift over whole periods (below)

    @property
    def Ts(self) -> float:
        return self.scenario.controller.Ts

    @property
    def force_error(self) -> np.ndarray:
        """f_e - f_d, N."""
        return self.contact_force - self.desired_force

    @property
    def orientation_error_norm(self) -> np.ndarray:
        """Angle between the tool orientation and its command (N,), rad (0 on a position task)."""
        if self.orientation_error is None:
            return np.zeros(self.time.size)
        return np.linalg.norm(self.orientation_error, axis=0)

    def limit_use(self, start: float = -np.inf, end: float = np.inf) -> LimitUse | None:
        """The torques, joint rates and positions over ``start <= t < end``
        (s) against :attr:`limits` (:func:`.limits.limit_use`); None without limits."""
        if self.limits is None:
            return None
        w = (self.time >= start) & (self.time < end)
        return limit_use(self.limits, self.time[w], self.q[:, w], self.dq[:, w], self.tau[:, w], self.Ts)

    @property
    def traces(self) -> SimulationTraces:
        """The series the figures draw and the surface under them, without
        the scenario (the arrays are shared, not copied)."""
        sc = self.scenario
        oriented = self.orientation_error is not None
        surface = surface_of(sc)
        # X_d: the reference's tangential coordinates on the controller's part (depth 0; the true part moved by
        # controller.part_offset); the true surface around the path
        desired = (surface.to_base(np.vstack([np.zeros(self.time.size), self.reference_task[1:]]))
                   + np.asarray(sc.controller.part_offset, dtype=float)[:, None])
        r = 1.4 * max(*path_extent(sc.trajectory), 1e-3)           # around the path's true reach (a turned raster)
        u = np.linspace(-r, r, 25 if surface.turns else 2)
        U, V = np.meshgrid(u, u, indexing="ij")
        mesh = surface.to_base(np.stack([np.zeros_like(U), U, V]))
        return SimulationTraces(
            time=self.time, contact_force=self.contact_force, desired_force=self.desired_force,
            stiffness=self.stiffness, stiffness_estimate=self.stiffness_estimate, position=self.position,
            reference_position=self.reference_position, surface_frame=surface.frame(sc.trajectory.center),
            center=np.asarray(sc.trajectory.center, dtype=float), radius=float(sc.trajectory.radius),
            orientation_error=self.orientation_error_norm if oriented else None, tool=self.tool,
            desired_position=desired, surface_mesh=mesh,
            surface_name=surface.noun)


class Simulator:
    """Build once, run many times: the closed loop of ``scenario``'s arm on its surface.

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
        if scenario is not None and not isinstance(scenario, Scenario):     # review 58: 'paper' failed inside
            raise TypeError(f"Simulator: expected a Scenario (tmtcontrol.load_scenario({scenario!r}) reads one), "
                            f"got {type(scenario).__name__}")
        self.scenario = sc = scenario or paper_scenario()
        t0 = time.perf_counter()
        self.plant = robot_of(sc)
        self.task = robot_task(self.plant)
        self.model = robot_of(sc, controller=True)
        self.surface = surface_of(sc)
        self.law = get_law(sc.controller.law.kind)
        self.delay = sc.controller.delay_samples
        self.hold = sc.controller.hold == "mid_period"
        # CVODES cannot be code-generated: that reference runs on the virtual machine
        compile = compile if sc.simulation.integrator == "fixed" else False
        key = structure_key(sc, self.law)
        if key is None:
            self.rollout = Rollout(self._build_step(), compile=compile)
        else:           # a cached library is found without building the step
            self.rollout = Rollout(self._build_step, compile=compile,
                                   structure=(step_name(self.law, self.delay, self.hold), key))
        self.build_time = time.perf_counter() - t0
        self._structure = structure(sc)
        self.layout = state_layout(self.task, self.law, self.delay, self.hold)
        """The closed-loop state's layout."""
        self.log = log_layout(self.task)
        """The step's log layout (``log["f_e"]``: the true contact force's row)."""
        self.name = f"{self.task.label}_{self.law.name}_d{self.delay}" + ("_mid" if self.hold else "")
        """A short name of the loop's structure (for compiled libraries)."""
        self.cache_tag = f"|{self.plant.key}|{self.model.key}"
        """What identifies the arm beyond the scenario's structure, for cache keys."""
        self._posture = None

    @property
    def step(self):
        """The closed-loop step Function (built on first use)."""
        return self.rollout.step

    @property
    def f_e(self) -> slice:
        """The true contact force's row in the step's log."""
        return self.log["f_e"]

    def _build_step(self, contact_refine: int | None = None):
        s = self.scenario.simulation
        return build_step(self.plant, self.model, self.law, s.integrator, s.substeps, s.tol, self.delay,
                          s.contact_refine if contact_refine is None else contact_refine, self.surface, self.hold)

    def build_step(self, contact_refine: int):
        """The scenario's step with the fixed-step integrator and
        ``contact_refine`` (1: no refinement), for the analyses."""
        s = self.scenario.simulation
        return build_step(self.plant, self.model, self.law, "fixed", s.substeps, s.tol, self.delay,
                          contact_refine, self.surface, self.hold)

    def build_tangent(self, dynamic):
        """The scenario's tangent-linear step on the state indices ``dynamic``
        (:func:`.closedloop.build_tangent`), for the periodic analysis."""
        return build_tangent(self.plant, self.model, self.law, dynamic, self.scenario.simulation.substeps,
                             self.delay, self.surface, self.hold)

    def run(self, scenario: Scenario | None = None, max_steps: int | None = None) -> SimulationResult:
        """Simulate ``scenario`` (default: the one given at construction). It
        must have the same structure (arm, robot options, integrator, law,
        delay, surface shape); everything numeric may differ. Runs longer than
        ``max_steps`` control steps (default :data:`MAX_STEPS`) are refused
        before any allocation."""
        sc = scenario or self.scenario
        check_run_size(sc, max_steps)
        if structure(sc) != self._structure:
            raise ValueError("run(): scenario differs in robot options, integrator, law, delay or surface from the "
                             "one this Simulator was built for; build a new Simulator")
        path = path_of(self.plant, sc)
        inputs, params, s0, t = self._inputs(sc, path)
        t0 = time.perf_counter()
        if sc.simulation.integrator == "cvodes":
            S, L = _cvodes_run(self.rollout, s0, inputs, params)
        else:
            S, L = self.rollout.run(s0, inputs, params)
        check_interrupt()            # CasADi may swallow Ctrl-C inside a long evaluation
        run_time = time.perf_counter() - t0
        self._check_finite(S, L, t, self.task.n)
        return self._result(sc, t, L, inputs, path,
                            {"integrator": sc.simulation.integrator, "code": self.rollout.how,
                             "build_time_s": self.build_time, "run_time_s": run_time,
                             "steps": t.size, "robot": self.plant.name})

    # -- the loop as the analyses see it -------------------------------------------
    def path(self, scenario: Scenario | None = None) -> PosePath:
        """The checked joint-space path of ``scenario`` (``.q``: n x k, rad)."""
        return path_of(self.plant, scenario or self.scenario)

    def inputs(self, scenario: Scenario | None = None, path: PosePath | None = None):
        """``(U, P, s0, t)``: the rollout's inputs, parameters, start state and times."""
        sc = scenario or self.scenario
        return self._inputs(sc, path if path is not None else path_of(self.plant, sc))

    def joints_at(self, point, seed=None, scenario: Scenario | None = None):
        """Joints (rad) putting the tool at ``point`` (m, base frame) near
        ``seed`` (on a 6-D task in the commanded orientation R_d). On a
        redundant arm, once :meth:`inputs` has given the null-space posture
        q_post, the pose where the posture task is balanced, ``M^ (q_post -
        q) = J^T w`` for some w (then the projected posture torque N^T M^
        K_post (q_post - q) is 0): the pose closest to q_post (IPOPT), refined
        by CasADi's Newton rootfinder on the pose and balance equations.
        ``scenario``: the scenario whose commanded orientation holds (default
        the Simulator's)."""
        from .posture import POSE_TOL

        surface, R_d = _frames(scenario or self.scenario)
        R_d = orientation_at(scenario or self.scenario, surface, point, R_d)
        seed = self.path().q[:, 0] if seed is None else seed
        if self.task.posture and self._posture is not None:
            q, ok = solve_pose(self.plant, self._solver, point, R_d, self._posture)
            if ok:
                par = np.r_[np.asarray(point, float), R_d.ravel(order="F"), self._posture]
                J, M = task_jacobian(self.model, q), np.asarray(self.model.mass_matrix(q))
                w = np.linalg.lstsq(J.T, M @ (self._posture - q), rcond=None)[0]
                qb = np.array(self._balanced(np.r_[q, w], par)).ravel()[:self.plant.n]
                T = self.plant.fk(qb)
                if np.all(np.isfinite(qb)) and np.abs(T[:3, 3] - point).max() < POSE_TOL \
                        and (not self.task.rotational or np.abs(T[:3, :3] - R_d).max() < POSE_TOL):
                    return qb
                return q
        q, ok = solve_pose(self.plant, self._solver, point, R_d, seed)
        if not ok:
            raise ValueError(f"no pose with the tool at {np.round(point, 4).tolist()} m"
                             + (" and the commanded orientation" if self.task.rotational else "")
                             + " near the given joints")
        return q

    @functools.cached_property
    def _balanced(self):
        import casadi as ca

        from .posture import _pose_equations

        n, d, model = self.plant.n, self.task.dim, self.model
        x, par = ca.SX.sym("x", n + d), ca.SX.sym("par", 12 + n)
        q, w = x[:n], x[n:]
        pose, _ = _pose_equations(self.plant, q, par)
        J = model.functions.jacobian(q)
        J = J if self.task.rotational else J[:3, :]
        balance = ca.mtimes(model.functions.mass_matrix(q), par[12:] - q) - ca.mtimes(J.T, w)
        g = ca.Function("balanced_pose_equations", [x, par], [ca.vertcat(pose, balance)], ["x", "par"], ["g"])
        return ca.rootfinder("balanced_pose", "newton", g, {"abstol": 1e-12, "abstolStep": 1e-14, "max_iter": 50,
                                                             "error_on_fail": False})

    @functools.cached_property
    def _solver(self):
        # a point solved from a nearby pose: the rootfinder keeps the branch on a square task; IPOPT on more
        return pose_solver(self.plant, track=True)

    def tool_position(self, q) -> np.ndarray:
        """The tool point (m, base frame) at joints ``q``."""
        return np.asarray(self.plant.fk(q))[:3, 3]

    def joint_rates(self, q, v, w=None) -> np.ndarray:
        """Joint rates (rad/s) giving the tool point the velocity ``v`` (m/s,
        base frame) and, on a 6-D task, the angular velocity ``w`` (rad/s,
        base frame; default 0) (least-norm on a redundant arm)."""
        v = np.asarray(v, dtype=float)
        J = task_jacobian(self.plant, q)
        if self.task.rotational:
            v = np.r_[v, np.zeros(3) if w is None else np.asarray(w, dtype=float)]
        return np.linalg.solve(J, v) if self.task.square else np.linalg.pinv(J) @ v

    def normal_mass(self, q, n) -> float:
        """The arm's effective mass (kg) along the unit direction ``n`` at ``q``
        (:func:`normal_mass`)."""
        return normal_mass(self.plant, q, n)

    # -- helpers -------------------------------------------------------------------
    def _inputs(self, sc: Scenario, path: PosePath):
        Ts = sc.controller.Ts
        N = int(round(sc.duration / Ts))
        if N < 1:
            raise ScenarioError(f"trajectory.cycles: the run (cycles x period = {sc.duration:g} s) is shorter "
                                f"than one control period (1/controller.rate = {Ts:g} s)")
        t = np.arange(N) * Ts
        surface, R_d = _frames(sc)
        ref = path_reference(t, sc.trajectory)
        k_e = stiffness_samples(sc.environment.stiffness, t, sc.trajectory.period)
        if not np.all(np.isfinite(k_e)) or np.any(k_e <= 0):
            raise ScenarioError("environment.stiffness: profile must stay finite and > 0")
        if sc.sensor.noise_std > 0:         # numpy.random only then: importing it takes ~6 ms
            with np.errstate(over="ignore"):        # an absurd std (1e308 N) overflows: the run says it diverged
                noise = sc.sensor.noise_std * np.random.default_rng(sc.sensor.seed).standard_normal(N)
        else:
            noise = np.zeros(N)
        U = np.vstack([ref.pos, ref.vel, ref.acc, k_e[None, :], noise[None, :]])
        imp, ctl, law, task = sc.impedance, sc.controller, self.law, self.task
        kd, kp = imp.gains
        alpha = sc.sensor.pole(Ts)
        sch = ctl.damping_schedule
        on = sch.kind == "zeta"
        if not on:      # its parameters unused (sched = 0), yet the exported defaults a user may switch on
            sch = ScheduledDamping()
        # start on the surface (x = x_e, zero force) or approach_gap above it, moving with the path
        gap = sc.trajectory.approach_gap
        q0 = path.q[:, 0]
        start = surface.to_base(under_the_commanded_path(sc, np.r_[-gap, ref.pos[:, 0]]))   # below path.q[:, 0]
        if gap > 0:
            q0, ok = solve_pose(self.plant, None if self.plant.position_ik is not None and not task.rotational
                                else pose_solver(self.plant), start, orientation_at(sc, surface, start, R_d), q0)
            if not ok:
                raise ScenarioError(f"trajectory.approach_gap: the start {gap:g} m above the surface is not "
                                    "reachable" + (" with the commanded orientation" if task.rotational else "")
                                    + " within the joint limits")
        P = param_layout(task, law, surface).pack(
            m=imp.m, b=imp.b, k=imp.k, kd=kd, kp=kp, f_d=ctl.f_d, x_e_hat=ctl.x_e_error, alpha=alpha,
            d_e=sc.environment.damping, **surface.values(), part_offset=ctl.part_offset, Ts=Ts,
            sched=1.0 if on else 0.0, zeta=sch.zeta, b_min=sch.b_min, b_max=sch.b_max, b_rate=sch.rate,
            k_hat_max=sch.k_max, k_hat_min=sch.min_stiffness, sched_f_th=sch.force_threshold,
            v_app=ctl.approach_speed, f_contact=contact_threshold_of(sc, alpha),
            ramp_rate=1.0 / ctl.force_ramp, law=law.parameter_vector(ctl.law),
            R_d=R_d.ravel(order="F"), kd_rot=np.divide(imp.b_rot, imp.m_rot), kp_rot=np.divide(imp.k_rot, imp.m_rot),
            q_post=q0, kp_post=sc.robot.posture_kp, kd_post=sc.robot.posture_kd,
            tau_max=limits_of(self.plant, sc).torque_clip)
        if task.posture:
            self._posture = np.asarray(q0, dtype=float).copy()
        # at rest in the task's rotation, moving with the path (least-norm joint rates on a redundant arm)
        dq0 = self.joint_rates(q0, *surface.rates(np.r_[-gap, ref.pos[:, 0]], np.r_[0.0, ref.vel[:, 0]]))
        b0 = min(max(imp.b[0], sch.b_min), sch.b_max) if on else imp.b[0]
        guarded = gap > 0 and ctl.approach_speed > 0
        # the approach starts where the tool is: gap above the true part, -gap - n.d deep in the controller's chart
        # (its part moved by controller.part_offset d; first order on a curved part, exact on a plane)
        x_app = -gap - float(surface.normal(start) @ np.asarray(ctl.part_offset, dtype=float))
        s0 = state_layout(task, law, self.delay, self.hold).pack(
            q=q0, dq=dq0, f_filt=0.0, b_n=b0, approach=1.0 if guarded else 0.0, x_app=x_app,
            ramp=0.0 if guarded else 1.0, x_e_hat=ctl.x_e_error, tau_wait=np.zeros(task.n * self.delay),
            tau_prev=np.zeros(task.n * self.hold), held=np.zeros(int(self.hold)),
            law=law.initial_state(ctl.law))
        return U, P, s0, t

    @staticmethod
    def _check_finite(S, L, t, n: int):
        """Raise :class:`SimulationError` at the first sample where the state
        S or log L is not finite or a joint velocity (rows n..2n of S, an arm
        of n joints) runs away."""
        # fast path: a sum is finite only if every term is (a false alarm from
        # overflow falls through to the exact test below)
        if np.isfinite(S.sum()) and np.isfinite(L.sum()) and np.abs(S[n:2 * n]).max() < RUNAWAY_RATE:
            return
        bad = ~(np.all(np.isfinite(S), axis=0) & np.all(np.isfinite(L), axis=0)
                & (np.abs(S[n:2 * n]).max(axis=0) < RUNAWAY_RATE))
        if bad.any():
            k = int(np.argmax(bad))
            dq = S[n:2 * n, k]
            what = (f"joint {int(np.nanargmax(np.abs(dq))) + 1} at {np.nanmax(np.abs(dq)):.3g} rad/s"
                    if np.isfinite(dq).any() and np.nanmax(np.abs(dq)) >= RUNAWAY_RATE else "a state not finite")
            # review 57: a depth f_d/k_e beyond the arm's reach diverged with this line naming neither
            raise SimulationError(f"simulation diverged at t = {t[k]:.4f} s ({what}); check the stiffness, "
                                  "gains and control rate, and that the depth f_d/k_e is within the arm's reach "
                                  "and torque")

    def _result(self, sc, t, L, U, path, info) -> SimulationResult:
        lg = self.log.split(np.ascontiguousarray(L))       # rows contiguous (the compiled rollout's already are)
        surface = surface_of(sc)
        f_m = lg["f_m"][0]
        depth = lg["X"][0] - lg["x_e_hat"][0]
        with np.errstate(divide="ignore", invalid="ignore"):
            k_hat = np.where((f_m > STIFFNESS_ESTIMATE_FORCE) & (depth > 0), f_m / depth, np.nan)
        # X_r, X_c are in the controller's chart: its part is the true one moved by controller.part_offset
        d = np.asarray(sc.controller.part_offset, dtype=float)[:, None]
        return SimulationResult(
            scenario=sc, time=t, q=lg["q"], dq=lg["dq"], tau=lg["tau"], position=lg["p"],
            reference_position=surface.to_base(lg["X_r"]) + d, command_position=surface.to_base(lg["X_c"]) + d,
            position_task=lg["X"], reference_task=lg["X_r"], command_task=lg["X_c"],
            contact_force=lg["f_e"][0], measured_force=f_m, desired_force=lg["f_d"][0],
            stiffness=U[INPUT["k_e"]][0], stiffness_estimate=k_hat, damping=lg["b_n"][0], path=path,
            info=info, orientation_error=lg["e_o"] if self.task.rotational else None,
            limits=limits_of(self.plant, sc), tool=f"{self.plant.name} {self.plant.tip} origin",
            posture_drift=_posture_drift(lg["q"], sc) if self.task.posture else None)


def _posture_drift(q: np.ndarray, sc: Scenario) -> np.ndarray | None:
    """A redundant arm's null-space drift (n,), rad: the path returns to its
    start every period, so the joints would too; the largest |q(k T) - q(0)|
    over the whole periods k T of the run, per joint (None: shorter than one
    period)."""
    every = int(round(sc.trajectory.period / sc.controller.Ts))
    ends = np.arange(every, q.shape[1], every)
    return np.max(np.abs(q[:, ends] - q[:, :1]), axis=1) if ends.size else None


def simulator_for(scenario: Scenario, compile: bool | str = "auto") -> Simulator:
    """The :class:`Simulator` of ``scenario`` (one loop for every arm; kept for
    callers of the earlier API)."""
    return Simulator(scenario, compile=compile)
