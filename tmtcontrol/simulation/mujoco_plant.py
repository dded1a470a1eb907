"""The closed loop against MuJoCo's rigid-body dynamics: a plant nobody here wrote.

:func:`simulate_on_mujoco` runs a scenario's own controller (the expressions
the built-in step runs, :func:`.cosim.builtin_controller`) at the scenario's
rate with zero-order hold against MuJoCo's model of the same URDF
(:func:`tmtcontrol.model.against_mujoco.mujoco_model`), integrated by MuJoCo
(RK4) at :data:`SUBSTEPS` steps per control period. The contact is the
``spring`` model: the ideal contact law of eq. (13), ``f_e = k_e x + d_e
dx`` along the surface's inward normal at the tool point while the tool is
inside, computed from MuJoCo's own kinematics of the tool frame and applied
as the generalised force ``-J_v^T n f_e`` each MuJoCo step. What differs
from the built-in run is then the rigid-body dynamics and their
integration, not the contact: a check of eq. (1) in the loop. (MuJoCo's
own soft contact, calibrated to k_e, is not modelled here.)

Held joints (a gripper's fingers) are made fixed joints in the URDF MuJoCo
loads (at their held value 0; another value is refused); joint
friction is refused (MuJoCo's model of it differs from eq. (1)'s smooth
Coulomb and viscous terms), as is an arm without a URDF (the PUMA).
"""

from __future__ import annotations

import time

import numpy as np

from ..surface import contact_force
from .cosim import builtin_controller, run_split
from .scenario import ScenarioError

__all__ = ["SUBSTEPS", "MujocoPlant", "simulate_on_mujoco"]

SUBSTEPS = 10
"""MuJoCo steps per control period (0.1 ms at 1 kHz): the spring of the
stiffest built-in surface (1e5 N/m on about 3 kg) oscillates at 30 Hz, so the
RK4 step resolves it to far below the force tolerance."""


class MujocoPlant:
    """MuJoCo's arm as a :func:`.cosim.run_split` plant (module docstring)."""

    def __init__(self, robot, surface, Ts: float, d_e: float, substeps: int = SUBSTEPS):
        from ..model.against_mujoco import mujoco_model

        self.mujoco, self.model, self.data = mj, m, d = mujoco_model(robot, lock_held=True)
        m.opt.timestep = Ts / substeps
        m.opt.integrator = mj.mjtIntegrator.mjINT_RK4
        m.dof_damping[:] = 0.0
        m.dof_frictionloss[:] = 0.0
        self.robot, self.surface, self.d_e, self.substeps = robot, surface, float(d_e), substeps
        self.act = np.array([m.jnt_dofadr[m.joint(name).id] for name in robot.joint_names])
        self.qadr = np.array([m.jnt_qposadr[m.joint(name).id] for name in robot.joint_names])
        names = [m.body(i).name for i in range(m.nbody)]
        self.tip = m.body(robot.tip).id
        self.base = m.body(robot.base).id if robot.base in names else 0
        self.n = robot.n
        self._jp, self._jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))

    def _set(self, z):
        self.data.qpos[self.qadr], self.data.qvel[self.act] = z[:self.n], z[self.n:]

    def _contact(self, k_e):
        """``(f_e, normal, J_v)`` at MuJoCo's current state (base frame)."""
        mj, m, d = self.mujoco, self.model, self.data
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_jacBody(m, d, self._jp, self._jr, self.tip)
        Rb, pb = d.xmat[self.base].reshape(3, 3), d.xpos[self.base]
        p = Rb.T @ (d.xpos[self.tip] - pb)
        Jv = Rb.T @ self._jp[:, self.act]
        v = Jv @ d.qvel[self.act]
        normal = self.surface.normal(p)
        depth = float(self.surface.signed_distance(p[:, None])[0])
        return float(contact_force(depth, float(normal @ v), k_e, self.d_e)), normal, Jv

    def sense(self, z, k_e):
        self._set(z)
        f, normal, _ = self._contact(k_e)
        return f, normal

    def advance(self, z, tau, k_e):
        mj, m, d = self.mujoco, self.model, self.data
        self._set(z)
        for _ in range(self.substeps):
            f, normal, Jv = self._contact(k_e)
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self.act] = tau - Jv.T @ (normal * f)      # the surface pushes back along -n
            mj.mj_step(m, d)
        return np.r_[d.qpos[self.qadr], d.qvel[self.act]]


def mujoco_plant_for(sim, scenario) -> tuple[MujocoPlant, dict]:
    """The :class:`MujocoPlant` of ``scenario`` (its Simulator ``sim``) and the
    run's ``info`` entries; a scenario MuJoCo cannot run is refused in one
    line (:class:`ScenarioError`)."""
    if scenario.robot.friction:
        raise ScenarioError("robot.friction: the MuJoCo plant has no model of eq. (1)'s joint friction; "
                            "set robot.friction = false to run on MuJoCo")
    try:
        plant = MujocoPlant(sim.plant, sim.surface, scenario.controller.Ts, scenario.environment.damping)
    except NotImplementedError as exc:
        raise ScenarioError(f"robot.model: {exc}") from None
    return plant, {"integrator": f"MuJoCo RK4, {SUBSTEPS} steps per period", "plant": "mujoco (spring contact)",
                   "mujoco": getattr(plant.mujoco, "__version__", "?")}


def simulate_on_mujoco(scenario, max_steps: int | None = None):
    """The scenario's controller against :class:`MujocoPlant`; a
    :class:`~.simulator.SimulationResult` with ``info["plant"] == "mujoco
    (spring contact)"``, judged by the same rules as the built-in run (the
    exported C against MuJoCo: :func:`tmtcontrol.export.sil.simulate_with_controller`
    with ``plant="mujoco"``)."""
    from .simulator import Simulator, check_run_size

    check_run_size(scenario, max_steps)
    t0 = time.perf_counter()
    sim = Simulator(scenario, compile=False)
    plant, info = mujoco_plant_for(sim, scenario)
    control, n_cmd = builtin_controller(sim, scenario)
    return run_split(sim, scenario, control, plant,
                     {**info, "code": f"mujoco {info['mujoco']}", "build_time_s": time.perf_counter() - t0}, n_cmd)
