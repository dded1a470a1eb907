"""The closed loop against MuJoCo's rigid-body dynamics, and optionally its contact: a plant nobody here wrote.

:func:`simulate_on_mujoco` runs a scenario's own controller (the expressions
the built-in step runs, :func:`.cosim.builtin_controller`) at the scenario's
rate with zero-order hold against MuJoCo's model of the same URDF
(:func:`tmtcontrol.model.against_mujoco.mujoco_model`), integrated by MuJoCo
(RK4) at :data:`SUBSTEPS` steps per control period. Two contact models,
``simulation.mujoco_contact``:

``spring`` (default): the ideal contact law of eq. (13), ``f_e = k_e x +
d_e dx`` along the surface's inward normal at the tool point while the
tool is inside, computed from MuJoCo's own kinematics of the tool frame
and applied as the generalised force ``-J_v^T n f_e`` each MuJoCo step.
What differs from the built-in run is then the rigid-body dynamics and
their integration, not the contact: a check of eq. (1) in the loop.

``contact``: MuJoCo's own soft contact between the part, a MuJoCo geom (a
plane, or a sphere or cylinder worked from outside), and a sphere of
``robot.tool_radius`` (default :data:`TOOL_RADIUS`) on the tool frame whose
lowest point along the tool's z axis is the tool point. MuJoCo's contact is a soft constraint: with
``solref = (-K, -B)`` and a constant impedance ``d`` (``solimp = (d, d,
...)``, :data:`CONTACT_IMPEDANCE`) the constraint force at rest is
``K r / ((1 - d) A^)`` for a penetration r, where ``A^`` is MuJoCo's fixed
approximation of the contact's inverse inertia (``efc_diagApprox``: the
translational ``body_invweight0`` of the two bodies). :func:`contact_solref`
sets ``K = k_e (1 - d) A^`` and ``B = d_e (1 - d) A^``, updated each period
as k_e steps, so the resting force is k_e r (the static calibration is a
test, 0.1 %). In motion the force also follows the applied push by a
fraction of order ``A / R`` (R = (1-d)/d A^, the constraint's
regulariser), which the small d keeps small: the transients differ from
the built-in spring's, the steady force does not. Friction:
``simulation.mujoco_friction`` (Coulomb coefficient, 0: a frictionless
point contact, MuJoCo's ``condim`` 1; > 0: ``condim`` 3, elliptic cones).
A concave part (``side = "inside"``) and a height map have no MuJoCo
primitive: refused in one line (the ``spring`` model runs them).

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
from .scenario.robot import TOOL_RADIUS

__all__ = ["SUBSTEPS", "MujocoPlant", "simulate_on_mujoco", "check_contact", "CONTACT_IMPEDANCE", "TOOL_RADIUS", "contact_solref",
           "contact_inverse_inertia", "add_part", "add_tool"]

SUBSTEPS = 10
"""MuJoCo steps per control period (0.1 ms at 1 kHz): the spring of the
stiffest built-in surface (1e5 N/m on about 3 kg) oscillates at 30 Hz, so the
RK4 step resolves it to far below the force tolerance."""


CONTACT_IMPEDANCE = 0.01
"""MuJoCo's constraint impedance d of the ``contact`` model (``solimp`` d0 =
dwidth = d: constant with the penetration). Small, so the regulariser R =
(1-d)/d A^ is large against the true inverse inertia and the force follows
the spring k_e r rather than the applied push (module docstring)."""


NOSLIP_ITERATIONS = 20
"""MuJoCo's no-slip solver's iterations with friction (``simulation.mujoco_friction > 0``)."""


def contact_solref(k_e: float, d_e: float, A_hat: float, d: float = CONTACT_IMPEDANCE) -> tuple[float, float]:
    """MuJoCo's ``solref = (-K, -B)`` (direct stiffness and damping) whose
    resting contact force on a penetration r at speed v is ``k_e r + d_e
    v``: ``K = k_e (1 - d) A^``, ``B = d_e (1 - d) A^`` with ``A^`` the
    contact's ``efc_diagApprox`` (module docstring)."""
    return -k_e * (1.0 - d) * A_hat, -d_e * (1.0 - d) * A_hat


def contact_inverse_inertia(model, geoms) -> float:
    """MuJoCo's approximation A^ (1/kg) of the inverse inertia of a contact
    between ``geoms`` (two geom ids): the two bodies' translational
    ``body_invweight0`` (computed at the model's reference posture, so not
    the posture's true value), the ``efc_diagApprox`` of its normal row."""
    return float(sum(model.body_invweight0[model.geom_bodyid[g], 0] for g in geoms))


def _no_primitive(surface) -> str:
    # review 65's low: "(worked from inside, or measured)" read oddly after "bowl" and "measured part" alike
    return (f"MuJoCo has no solid primitive for this {surface.noun} (its own contact takes a plane or the outside "
            "of a sphere or cylinder); use simulation.mujoco_contact = \"spring\"")


def _contact_geom(geom, friction: float) -> None:
    geom.condim = 3 if friction > 0 else 1
    geom.friction = [friction, 0.0, 0.0]
    geom.solimp = [CONTACT_IMPEDANCE, CONTACT_IMPEDANCE, 0.001, 0.5, 2.0]
    geom.margin = 0.0


def _quat(R) -> list:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return q.tolist()


def add_part(mujoco, body, surface, friction: float = 0.0):
    """Add ``surface`` (its :meth:`~tmtcontrol.surface.Surface.primitive`: a
    plane, or a sphere or cylinder with the tool outside) to the MjSpec
    ``body`` (its frame: the surface's base frame) as a contact geom
    colliding only with the tool; a part that is no primitive raises
    :class:`ValueError` saying so."""
    shape = surface.primitive()
    if shape is None:
        raise ValueError(_no_primitive(surface))
    kind, centre, R, radius = shape
    g = body.add_geom()
    g.pos = np.asarray(centre, dtype=float).tolist()
    n, t1 = R[:, 0], R[:, 1]
    geom, size, frame = {          # MuJoCo's geom of each primitive (a cylinder's axis, R[:, 2], is the geom's z)
        "plane": ("mjGEOM_PLANE", [0.0, 0.0, 1.0], np.column_stack([t1, np.cross(-n, t1), -n])),  # z: out, infinite
        "sphere": ("mjGEOM_SPHERE", [radius, 0.0, 0.0], R),
        "cylinder": ("mjGEOM_CYLINDER", [radius, 1.0, 0.0], R),                                     # 2 m long
    }[kind]
    g.type, g.size, g.quat = getattr(mujoco.mjtGeom, geom), size, _quat(frame)
    g.name = "tmt_part"
    g.contype, g.conaffinity = 0, 1
    _contact_geom(g, friction)
    return g


def add_tool(body, friction: float = 0.0, radius: float = TOOL_RADIUS):
    """Add the tool's sphere of ``radius`` (m; the scenario's
    ``robot.tool_radius``, default :data:`TOOL_RADIUS`) to the MjSpec
    ``body``: its point furthest along the body's z axis (the tool's, along
    the inward normal: into the part) at the body's origin, the tool point."""
    import mujoco

    g = body.add_geom()
    g.name = "tmt_tool"
    g.type, g.size = mujoco.mjtGeom.mjGEOM_SPHERE, [float(radius), 0.0, 0.0]
    g.pos = [0.0, 0.0, -float(radius)]
    g.density = 0.0                                   # massless: the arm's inertia stays the URDF's
    g.contype, g.conaffinity = 1, 0
    _contact_geom(g, friction)
    return g


class MujocoPlant:
    """MuJoCo's arm as a :func:`.cosim.run_split` plant (module docstring)."""

    def __init__(self, robot, surface, Ts: float, d_e: float, substeps: int = SUBSTEPS, contact: str = "spring",
                 friction: float = 0.0, tool_radius: float = TOOL_RADIUS):
        from ..model.against_mujoco import base_body, base_id, import_mujoco, mujoco_model

        edit = None
        if contact == "contact":
            mujoco = import_mujoco()

            def edit(spec):
                add_part(mujoco, base_body(spec, robot), surface, friction)
                add_tool(spec.body(robot.tip), friction, tool_radius)
        elif contact != "spring":
            raise ValueError(f"contact: expected 'spring' or 'contact', got {contact!r}")
        self.contact = contact
        self.mujoco, self.model, self.data = mj, m, d = mujoco_model(robot, lock_held=True, edit=edit)
        m.opt.timestep = Ts / substeps
        m.opt.integrator = mj.mjtIntegrator.mjINT_RK4
        m.dof_damping[:] = 0.0
        m.dof_frictionloss[:] = 0.0
        # eq. (1) has no joint stops (the arm's limits are judged, not enforced), and a diverging run must end
        # as one (the loop's own check), not be reset silently to qpos0 by MuJoCo
        m.opt.disableflags |= mj.mjtDisableBit.mjDSBL_LIMIT | getattr(mj.mjtDisableBit, "mjDSBL_AUTORESET", 0)
        self.robot, self.surface, self.d_e, self.substeps = robot, surface, float(d_e), substeps
        self.act = np.array([m.jnt_dofadr[m.joint(name).id] for name in robot.joint_names])
        self.qadr = np.array([m.jnt_qposadr[m.joint(name).id] for name in robot.joint_names])
        self.tip = m.body(robot.tip).id
        self.base = base_id(m, robot)
        self.n = robot.n
        self._jp, self._jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        if contact == "contact":
            if friction > 0:
                m.opt.cone = mj.mjtCone.mjCONE_ELLIPTIC
                # the friction rows share the normal's calibrated soft solref, whose damping is 0 without
                # contact damping: alone they barely resist a slip (0.013 N at 0.16 m/s for any mu); MuJoCo's
                # no-slip solver makes them Coulomb's (the slip stops while |f_t| < mu f_n, else mu f_n)
                m.opt.noslip_iterations = NOSLIP_ITERATIONS
            self.geoms = np.array([m.geom("tmt_part").id, m.geom("tmt_tool").id])
            self.A_hat = contact_inverse_inertia(m, self.geoms)
            self._k_e, self._f6 = None, np.zeros(6)

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

    def _stiffness(self, k_e):
        if k_e != self._k_e:                          # the calibrated solref of this stiffness, on both geoms
            self.model.geom_solref[self.geoms] = contact_solref(k_e, self.d_e, self.A_hat)
            self._k_e = k_e

    def _mujoco_force(self):
        """MuJoCo's normal contact force (N, pushing apart) between the part and the tool, 0 without contact."""
        mj, m, d = self.mujoco, self.model, self.data
        for i in range(d.ncon):
            if {d.contact[i].geom1, d.contact[i].geom2} == set(self.geoms.tolist()):
                mj.mj_contactForce(m, d, i, self._f6)
                return float(self._f6[0])
        return 0.0

    def sense(self, z, k_e):
        self._set(z)
        if self.contact == "spring":
            f, normal, _ = self._contact(k_e)
            return f, normal
        # MuJoCo's force at this state under the torque held now (the soft constraint's force depends on it)
        self._stiffness(k_e)
        self.mujoco.mj_forward(self.model, self.data)
        _, normal, _ = self._contact(k_e)
        return self._mujoco_force(), normal

    def advance(self, z, tau, k_e):
        mj, m, d = self.mujoco, self.model, self.data
        self._set(z)
        if self.contact == "contact":
            self._stiffness(k_e)
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self.act] = tau
            for _ in range(self.substeps):
                mj.mj_step(m, d)
            return np.r_[d.qpos[self.qadr], d.qvel[self.act]]
        for _ in range(self.substeps):
            f, normal, Jv = self._contact(k_e)
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[self.act] = tau - Jv.T @ (normal * f)      # the surface pushes back along -n
            mj.mj_step(m, d)
        return np.r_[d.qpos[self.qadr], d.qvel[self.act]]


def check_contact(scenario, surface) -> None:
    """Refuse in one line (:class:`ScenarioError` naming the key) what the
    scenario cannot have on MuJoCo: eq. (1)'s joint friction, friction on
    the spring, or MuJoCo's contact on a part it has no primitive for."""
    if scenario.robot.friction:
        raise ScenarioError("robot.friction: the MuJoCo plant has no model of eq. (1)'s joint friction; "
                            "set robot.friction = false to run on MuJoCo")
    s = scenario.simulation
    if s.mujoco_friction > 0 and s.mujoco_contact != "contact":
        raise ScenarioError("simulation.mujoco_friction: only MuJoCo's own contact has friction; set "
                            "simulation.mujoco_contact = \"contact\" (the spring is frictionless)")
    if s.mujoco_contact == "contact" and surface.primitive() is None:
        raise ScenarioError(f"simulation.mujoco_contact: {_no_primitive(surface)}")


def mujoco_plant_for(sim, scenario) -> tuple[MujocoPlant, dict]:
    """The :class:`MujocoPlant` of ``scenario`` (its Simulator ``sim``) and the
    run's ``info`` entries; a scenario MuJoCo cannot run is refused in one
    line (:class:`ScenarioError`)."""
    s = scenario.simulation
    check_contact(scenario, sim.surface)
    try:
        plant = MujocoPlant(sim.plant, sim.surface, scenario.controller.Ts, scenario.environment.damping,
                            contact=s.mujoco_contact, friction=s.mujoco_friction,
                            tool_radius=scenario.robot.tool_radius)
    except NotImplementedError as exc:
        raise ScenarioError(f"robot.model: {exc}") from None
    what = ("spring contact" if s.mujoco_contact == "spring" else
            f"MuJoCo contact, d = {CONTACT_IMPEDANCE:g}" + (f", friction {s.mujoco_friction:g}" if s.mujoco_friction
                                                            else ""))
    return plant, {"integrator": f"MuJoCo RK4, {SUBSTEPS} steps per period", "plant": f"mujoco ({what})",
                   "mujoco": getattr(plant.mujoco, "__version__", "?")}


def simulate_on_mujoco(scenario, max_steps: int | None = None):
    """The scenario's controller against :class:`MujocoPlant`; a
    :class:`~.simulator.SimulationResult` with ``info["plant"] == "mujoco
    (spring contact)"``, judged by the same rules as the built-in run (the
    exported C against MuJoCo: :func:`tmtcontrol.export.sil.simulate_with_controller`
    with ``plant="mujoco"``). The built-in plant's own settings
    (:meth:`~.scenario.SimulationSettings.builtin_only`) are set back to their
    defaults (:meth:`~.scenario.SimulationSettings.on_mujoco`): the result's
    scenario, and the stiffness limit its verdicts quote, are those of the
    run MuJoCo made."""
    from ..model.against_mujoco import MUJOCO_WARNINGS
    from .simulator import SimulationError, Simulator, check_run_size

    scenario = scenario.replace(simulation=scenario.simulation.on_mujoco())
    check_run_size(scenario, max_steps)
    t0 = time.perf_counter()
    sim = Simulator(scenario, compile=False)
    plant, info = mujoco_plant_for(sim, scenario)
    control, n_cmd = builtin_controller(sim, scenario)
    seen = len(MUJOCO_WARNINGS)
    try:
        return run_split(sim, scenario, control, plant,
                         {**info, "code": f"mujoco {info['mujoco']}", "build_time_s": time.perf_counter() - t0}, n_cmd)
    except SimulationError as exc:
        if len(MUJOCO_WARNINGS) > seen:         # what MuJoCo said about it (its warning, kept off the console)
            raise SimulationError(f"{exc} (MuJoCo: {MUJOCO_WARNINGS[seen]})") from None
        raise
