"""The closed loop of a scenario's arm as the stability analyses see it, chosen by task dimension.

``stability.wholeloop`` (the loop frozen at a path point), ``stability.periodic``
(the loop along its periodic orbit) and ``stability.first_contact`` (short runs
from the scenario's start) run the same algorithms on any arm. What differs
between the position-only loop of the 3-joint PUMA (:mod:`.closedloop`,
:class:`.simulator.Simulator`) and the 6-D loop of an arm with 6 or more
joints (:mod:`.taskframe`, :class:`.posesim.PoseSimulator`) is gathered
here, behind one small interface: the simulator, the state layout, the log
row of the contact force, the step builder (with or without the contact
refinement), the checked path and the rollout inputs, and the kinematics the
analyses need to place a first guess (the joints that put the tool at a point
of the surface, the tool position, the joint rates of a tool velocity and the
effective normal mass).

:func:`arm_loop` picks the implementation on the task dimension, as
:func:`.posesim.simulator_for` does: nothing above this module asks which arm
it is. The PUMA's side calls exactly what the analyses called before (its
closed-form inverse kinematics, Cartesian inertia D* and 3 x 3 Jacobian), so
its numbers are unchanged bit for bit. On a 6-D arm the tool also holds its
commanded orientation R_d: the joints at a point are solved with it
(:func:`.posture.solve_pose`, CasADi's rootfinder or IPOPT; on a redundant
arm the pose where the null-space posture task is balanced), a tool velocity
has zero angular velocity (least-norm joint rates, as the 6-D simulator's
start) and the effective normal mass is ``1/(n^T J_v M^-1 J_v^T n)`` (J_v the
linear rows of J: the mass the normal axis meets with the other axes free).
Units are SI.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["ArmLoop", "PositionLoop", "PoseLoop", "arm_loop", "normal_mass"]


def normal_mass(robot, q, n) -> float:
    """Effective mass (kg) of a 6-D arm ``robot`` at joints ``q`` along the
    unit direction ``n`` (base frame): ``1/(n^T J_v M^-1 J_v^T n)``."""
    Jv = np.asarray(robot.jacobian(q))[:3]
    return float(1.0 / (n @ Jv @ np.linalg.solve(np.asarray(robot.mass_matrix(q)), Jv.T @ n)))


class ArmLoop:
    """What the analyses ask of a closed loop (see the module docstring).

    Attributes
    ----------
    sim : Simulator or PoseSimulator
        The scenario's simulator (its ``plant``, ``law``, ``rollout``).
    layout : Layout
        The closed-loop state.
    f_e : slice
        The true contact force's row in the step's log.
    name : str
        A short name of the loop's structure (for compiled libraries).
    cache_tag : str
        What identifies the arm beyond the scenario's structure (a URDF's
        content), for cache keys.
    """

    sim = layout = f_e = name = None
    delay = 0
    cache_tag = ""

    @property
    def plant(self):
        return self.sim.plant

    @property
    def law(self):
        return self.sim.law

    def build_step(self, contact_refine: int):
        """The scenario's step with the fixed-step integrator and
        ``contact_refine`` (1: no refinement)."""
        raise NotImplementedError

    def path(self, scenario):
        """The checked joint-space path of ``scenario`` (``.q``: n x k, rad)."""
        raise NotImplementedError

    def inputs(self, scenario, path):
        """``(U, P, s0, t)``: the rollout's inputs, parameters, start state and times."""
        return self.sim._inputs(scenario, path)

    def frame(self, scenario):
        """``(R, c)``: the task axes (normal first) in the base frame and the circle's centre (m)."""
        raise NotImplementedError

    def joints_at(self, point, seed):
        """Joints (rad) putting the tool at ``point`` (m, base frame), near ``seed``."""
        raise NotImplementedError

    def tool_position(self, q) -> np.ndarray:
        """The tool point (m, base frame) at joints ``q``."""
        raise NotImplementedError

    def joint_rates(self, q, v) -> np.ndarray:
        """Joint rates (rad/s) giving the tool point the velocity ``v`` (m/s, base frame)."""
        raise NotImplementedError

    def normal_mass(self, q, n) -> float:
        """The robot's effective mass (kg) along the unit direction ``n`` at ``q``."""
        raise NotImplementedError


class PositionLoop(ArmLoop):
    """The 3-joint PUMA's position-only loop (:mod:`.closedloop`)."""

    def __init__(self, scenario, compile="auto", sim=None):
        from .closedloop import LOG, state_layout
        from .simulator import Simulator

        self.sim = sim or Simulator(scenario, compile=compile)
        self.delay = self.sim.delay
        self.layout = state_layout(self.sim.law, self.sim.delay)
        self.f_e = LOG["f_e"]
        self.name = f"{self.sim.law.name}_d{self.sim.delay}"

    def build_step(self, contact_refine: int):
        from .closedloop import build_step

        sim = self.sim
        return build_step(sim.plant, sim.model, sim.law, "fixed", sim.scenario.simulation.substeps,
                          delay=sim.delay, contact_refine=contact_refine)

    def path(self, scenario):
        from .simulator import _path

        return _path(self.plant, scenario)

    def frame(self, scenario):
        from .environment import task_frame

        return task_frame(scenario.environment.tilt_deg), np.asarray(scenario.trajectory.center, dtype=float)

    def joints_at(self, point, seed=None):
        return self.plant.inverse_kinematics(point)

    def tool_position(self, q):
        return np.asarray(self.plant.fk(q)).ravel()

    def joint_rates(self, q, v):
        return np.linalg.solve(np.asarray(self.plant.jacobian(q)), v)

    def normal_mass(self, q, n):
        # 1/(n^T D*^-1 n) with the Cartesian inertia D* (stability.sampled.effective_mass's arithmetic)
        return float(1.0 / (n @ np.linalg.solve(np.asarray(self.plant.cartesian_inertia(q)), n)))


class PoseLoop(ArmLoop):
    """The 6-D loop of an arm with 6 or more joints (:mod:`.taskframe`)."""

    def __init__(self, scenario, compile="auto", sim=None):
        from .posesim import PoseSimulator, _frames
        from .taskframe import pose_log_layout, pose_state_layout

        self.sim = sim or PoseSimulator(scenario, compile=compile)
        n = self.sim.plant.n
        self.delay = self.sim.delay
        self.layout = pose_state_layout(n, self.sim.law, self.delay)
        self.f_e = pose_log_layout(n)["f_e"]
        self.name = f"pose{n}_{self.sim.law.name}_d{self.delay}"
        self.cache_tag = f"|{self.sim.plant.key}|{self.sim.model.key}"
        self._R_d = _frames(scenario)[1]
        self._posture = None

    def build_step(self, contact_refine: int):
        from .taskframe import build_pose_step

        sim = self.sim
        return build_pose_step(sim.plant, sim.model, sim.law, "fixed", sim.scenario.simulation.substeps,
                               contact_refine=contact_refine, delay=self.delay)

    def path(self, scenario):
        from .posesim import pose_path

        return pose_path(self.plant, scenario)

    def inputs(self, scenario, path):
        from .taskframe import pose_param_layout

        U, P, s0, t = self.sim._inputs(scenario, path)
        self._posture = pose_param_layout(self.plant.n, self.law).split(P)["q_post"]
        return U, P, s0, t

    def frame(self, scenario):
        from .geometry import surface_frame

        return surface_frame(scenario.environment), np.asarray(scenario.trajectory.center, dtype=float)

    def joints_at(self, point, seed):
        """As :meth:`ArmLoop.joints_at`. On a redundant arm, once :meth:`inputs`
        has given the null-space posture q_post, the pose where the posture
        task is balanced, ``M^ (q_post - q) = J^T w`` for some w (then the
        projected posture torque N^T M^ K_post (q_post - q) is 0): the pose
        closest to q_post (IPOPT), refined by CasADi's Newton rootfinder on
        the pose and balance equations; a fixed point of the loop is then
        found from near it."""
        from .posture import POSE_TOL, solve_pose

        if self.plant.n > 6 and self._posture is not None:
            q, ok = solve_pose(self.plant, self._solver, point, self._R_d, self._posture)
            if ok:
                par = np.r_[np.asarray(point, float), self._R_d.ravel(order="F"), self._posture]
                J, M = np.asarray(self.sim.model.jacobian(q)), np.asarray(self.sim.model.mass_matrix(q))
                w = np.linalg.lstsq(J.T, M @ (self._posture - q), rcond=None)[0]
                qb = np.array(self._balanced(np.r_[q, w], par)).ravel()[:self.plant.n]
                T = self.plant.fk(qb)
                if np.all(np.isfinite(qb)) and np.abs(T[:3, 3] - point).max() < POSE_TOL \
                        and np.abs(T[:3, :3] - self._R_d).max() < POSE_TOL:
                    return qb
                return q
        q, ok = solve_pose(self.plant, self._solver, point, self._R_d, seed)
        if not ok:
            raise ValueError(f"no pose with the tool at {np.round(point, 4).tolist()} m and the commanded "
                             "orientation near the given joints")
        return q

    @functools.cached_property
    def _balanced(self):
        import casadi as ca

        from .posture import _pose_equations

        n, model = self.plant.n, self.sim.model
        x, par = ca.SX.sym("x", n + 6), ca.SX.sym("par", 12 + n)
        q, w = x[:n], x[n:]
        pose, _ = _pose_equations(self.plant, q, par)
        balance = (ca.mtimes(model.functions.mass_matrix(q), par[12:] - q)
                   - ca.mtimes(model.functions.jacobian(q).T, w))
        g = ca.Function("balanced_pose_equations", [x, par], [ca.vertcat(pose, balance)], ["x", "par"], ["g"])
        return ca.rootfinder("balanced_pose", "newton", g, {"abstol": 1e-12, "abstolStep": 1e-14, "max_iter": 50,
                                                             "error_on_fail": False})

    @functools.cached_property
    def _solver(self):
        # a point solved from a nearby pose: the rootfinder keeps the branch on six joints; IPOPT on more
        from .posture import pose_solver

        return pose_solver(self.plant, track=True)

    def tool_position(self, q):
        return np.asarray(self.plant.fk(q))[:3, 3]

    def joint_rates(self, q, v):
        return np.linalg.pinv(np.asarray(self.plant.jacobian(q))) @ np.r_[v, np.zeros(3)]

    def normal_mass(self, q, n):
        return normal_mass(self.plant, q, n)


def arm_loop(scenario, compile="auto", sim=None) -> ArmLoop:
    """The loop of ``scenario``'s arm, chosen by its task dimension as
    :func:`.posesim.simulator_for` chooses the simulator (``sim``: one already
    built for the scenario's structure, reused)."""
    from .posesim import robot_of

    if robot_of(scenario).n < 6:
        return PositionLoop(scenario, compile, sim)
    return PoseLoop(scenario, compile, sim)
