"""One robot interface, eq. (1) for any fixed-base serial arm: :func:`load_robot`.

``load_robot(source)`` returns a :class:`Robot` whatever the arm: the paper's
three-link PUMA 560 (its Euler-Lagrange model from :mod:`.puma560`, numbers
unchanged), an arm bundled with the package (``"ur5"``, ``"panda"``, URDFs in
``model/data/``) or any URDF file (parsed and checked by :mod:`.urdf`, its
dynamics by Featherstone's algorithms in :mod:`.featherstone`). Code above
``model/`` asks the robot for quantities and never which arm it is.

Joint space, SI units (rad or m, N m or N, kg m^2)::

    M(q) ddq + C(q, dq) dq + g(q) + tau_f(dq) = tau                  (1)

The robot offers, for the ``n`` actuated joints:

* NumPy in, NumPy out: :meth:`Robot.mass_matrix`, :meth:`Robot.bias`
  (``C dq + g``), :meth:`Robot.gravity`, :meth:`Robot.jacobian` (6 x n
  geometric Jacobian of the tip frame's origin, linear rows first, base
  axes), :meth:`Robot.fk` (4 x 4 pose of the tip in the base frame),
  :meth:`Robot.friction`, :meth:`Robot.forward_dynamics`,
  :meth:`Robot.inverse_dynamics`;
* the same as named CasADi SX Functions in :attr:`Robot.functions`
  (:class:`RobotFunctions`: inputs ``q``, ``dq``, ``ddq``, ``tau``), for the
  closed loop and the compiled rollout to build on.

Building a URDF robot's Functions is cached on disk keyed by the URDF's
content and the options (the folder of the compiled rollouts,
:func:`tmtcontrol.cache.cache_dir`), so a second load of the same
arm deserialises them instead of rebuilding the expressions.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import os
import pathlib
import stat
from dataclasses import dataclass
from importlib import resources

import casadi as ca
import numpy as np

from .urdf import Chain, ChainError, TipError, URDFError, parse_chain, read_urdf

__all__ = ["BUNDLED", "MIN_JOINTS", "Robot", "RobotFunctions", "Task", "URDFError", "load_robot", "task_of",
           "source_stamp", "unit_notes_of"]

BUNDLED = {
    "ur5": ("ur5.urdf", "tool0"),
    "panda": ("panda.urdf", "panda_hand_tcp"),
}
"""Arms shipped with the package: file in ``model/data/`` and default tip."""

MIN_JOINTS = 3
"""Fewest actuated joints a closed loop takes: the tool point's three coordinates."""

LARGE_REACH = 10.0
"""A reach (m) from which :meth:`Robot.unit_notes` asks whether the URDF's
lengths are millimetres (the largest industrial arms reach about 4 m)."""

LARGE_TURN = 4 * math.pi
"""A revolute joint limit (rad, two turns) from which :meth:`Robot.unit_notes`
asks whether the limits are degrees (170 degrees read as 170 rad)."""

TASK_RANK_SAMPLES = 8
"""Random poses at which :meth:`Robot.task_rank` evaluates the Jacobian (the
largest rank counts: one pose away from a singularity shows the joints span
the task)."""


@dataclass(frozen=True)
class Task:
    """The task a robot's closed loop controls, declared once from its joints.

    ``dim`` task axes: the tool point's position (3: the surface normal and
    two tangential axes) for an arm with 3 to 5 joints, position and
    orientation (6) for 6 or more. An arm with more joints than task axes is
    redundant: a null-space posture task (``robot.posture_kp``,
    ``robot.posture_kd``) holds its remaining freedom. Nothing above
    ``model/`` looks at the joint count; it asks the task.

    Attributes
    ----------
    n : int
        Actuated joints.
    dim : int
        Task axes, 3 or 6.
    """

    n: int
    dim: int

    @property
    def rotational(self) -> int:
        """Rotational task axes: 0 or 3."""
        return self.dim - 3

    @property
    def posture(self) -> bool:
        """Whether the arm is redundant for the task (a null-space posture task runs)."""
        return self.n > self.dim

    @property
    def what(self) -> str:
        """What the task axes control: ``"position"`` or ``"position and orientation"``."""
        return "position and orientation" if self.rotational else "position"

    @property
    def words(self) -> str:
        """The task in words, e.g. ``"position, with the null-space posture task"``
        (the ``robot`` command's line, the report's arm; docs/robots.md)."""
        return self.what + (", with the null-space posture task" if self.posture else "")

    @property
    def square(self) -> bool:
        """Whether the task Jacobian is square (as many joints as task axes)."""
        return self.n == self.dim

    @property
    def label(self) -> str:
        """A short name of the task's structure, e.g. ``"3x3"`` (joints x axes)."""
        return f"{self.n}x{self.dim}"


def task_of(n: int) -> Task:
    """The :class:`Task` of an arm with ``n`` actuated joints; a ``ValueError``
    below :data:`MIN_JOINTS`."""
    if n < MIN_JOINTS:
        raise ValueError(f"{n} actuated joint{'s' if n != 1 else ''}: the closed loop needs at least "
                         f"{MIN_JOINTS} (the tool point's position)")
    return Task(n, 3 if n < 6 else 6)


PUMA_JOINTS = ("joint1", "joint2", "joint3")
PUMA_TIP = "wrist_centre"


@dataclass(frozen=True, eq=False)
class RobotFunctions:
    """The robot's named CasADi SX Functions (inputs ``q``, ``dq``, ``ddq``, ``tau``).

    Attributes
    ----------
    fk : casadi.Function
        ``["q"] -> ["T"]``, 4 x 4 pose of the tip in the base frame (m).
    jacobian : casadi.Function
        ``["q"] -> ["J"]``, 6 x n geometric Jacobian of the tip origin, linear
        rows first, base axes.
    jacobian_dot : casadi.Function
        ``["q","dq"] -> ["Jdot_dq"]``, dJ/dt dq (6), m/s^2 and rad/s^2.
    mass_matrix : casadi.Function
        ``["q"] -> ["M"]`` (with armature).
    bias : casadi.Function
        ``["q","dq"] -> ["n"]``, ``C(q, dq) dq + g(q)``.
    gravity : casadi.Function
        ``["q"] -> ["g"]``.
    friction : casadi.Function
        ``["dq"] -> ["tau_f"]`` (zeros when disabled).
    inverse_dynamics : casadi.Function
        ``["q","dq","ddq"] -> ["tau"]``, ``M ddq + C dq + g + tau_f``.
    forward_dynamics : casadi.Function
        ``["q","dq","tau"] -> ["ddq"]``.
    """

    fk: ca.Function
    jacobian: ca.Function
    jacobian_dot: ca.Function
    mass_matrix: ca.Function
    bias: ca.Function
    gravity: ca.Function
    friction: ca.Function
    inverse_dynamics: ca.Function
    forward_dynamics: ca.Function


@dataclass(frozen=True, eq=False)
class Robot:
    """A fixed-base serial arm: joints, limits, and eq. (1) as Functions.

    Attributes
    ----------
    name : str
        The robot's name (``"puma560"``, or the URDF's ``<robot name>``).
    source : str
        ``"puma560"``, the bundled name, or the URDF's path.
    joint_names : tuple of str
        Actuated joints, base to tip.
    q_min, q_max : numpy.ndarray
        Position limits, rad or m (+-inf: none).
    dq_max, tau_max : numpy.ndarray
        Velocity (rad/s, m/s) and effort (N m, N) limits (inf: none).
    base, tip : str
        Base link (fixed to the world) and tip frame.
    held : dict
        Movable joints not actuated, with the value they are held at.
    link_masses : dict
        Mass of every link below the base, kg.
    functions : RobotFunctions
        The named CasADi SX Functions.
    chain : Chain or None
        The parsed URDF chain (None for the PUMA).
    urdf : str or None
        The URDF's text (None for the PUMA).
    armature : numpy.ndarray
        Rotor inertia on M's diagonal, kg m^2.
    key : str
        Cache key of the Functions (the URDF's content and the options).
    links : tuple of LinkParameters or None
        The PUMA's parameter set (None for a URDF arm).
    mass_scale : float
        The factor every mass and inertia was multiplied by.
    position_ik : callable or None
        A closed-form inverse kinematics of the tip position, ``p (3,) or (3,
        k) -> q`` (rad), where the arm has one (the PUMA's); None: solved
        numerically by the caller.
    """

    name: str
    source: str
    joint_names: tuple[str, ...]
    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    tau_max: np.ndarray
    base: str
    tip: str
    held: dict
    link_masses: dict
    functions: RobotFunctions
    chain: Chain | None = None
    urdf: str | None = None
    armature: np.ndarray | None = None
    key: str = ""
    links: tuple | None = None
    mass_scale: float = 1.0
    position_ik: object = None

    @property
    def n(self) -> int:
        """Number of actuated joints."""
        return len(self.joint_names)

    @property
    def prismatic(self) -> tuple[bool, ...]:
        """Which actuated joints are prismatic (their units m, m/s, N; the rest rad, rad/s, N m)."""
        if self.chain is None:
            return (False,) * self.n
        return tuple(j.type == "prismatic" for j in self.chain.joints)

    @functools.cached_property
    def task(self) -> Task:
        """The task its closed loop controls (:func:`task_of`); ``ValueError``
        below 3 joints, or when the joints cannot move the tool along every
        task axis (:meth:`task_rank` below the task's dimension: review 59, a
        6-joint arm with every axis along z failed inside CasADi's rootfinder
        with a traceback)."""
        task = task_of(self.n)
        rank = self.task_rank(task.dim)
        if rank < task.dim:
            raise ValueError(f"{self.n} actuated joints whose axes move the tool along at most {rank} of the "
                             f"{task.dim} axes of its task ({task.what}; the rank of the Jacobian at "
                             f"{TASK_RANK_SAMPLES} sampled poses): the closed loop needs all {task.dim}")
        return task

    def task_rank(self, dim: int = 6) -> int:
        """The largest rank of the Jacobian's first ``dim`` rows (3: the tool
        point's velocity; 6: with the angular one) at :data:`TASK_RANK_SAMPLES`
        seeded random poses within the joint limits (a turn either way where a
        joint has none): below ``dim``, no pose of the arm moves its tool along
        every axis (the joint axes do not span them). Rank counts the singular
        values above 1e-9 of the largest."""
        rng = np.random.default_rng(0)
        lo = np.where(np.isfinite(self.q_min), self.q_min, -math.pi)
        hi = np.where(np.isfinite(self.q_max), self.q_max, math.pi)
        best = 0
        for _ in range(TASK_RANK_SAMPLES):
            sv = np.linalg.svd(self.jacobian(rng.uniform(lo, hi))[:dim], compute_uv=False)
            best = max(best, int(np.count_nonzero(sv > 1e-9 * sv[0])) if sv[0] > 0 else 0)
            if best == dim:
                break
        return best

    @property
    def total_mass(self) -> float:
        """Mass of every link below the base, kg."""
        return float(sum(self.link_masses.values()))

    # -- NumPy in, NumPy out --------------------------------------------------------
    def fk(self, q) -> np.ndarray:
        """4 x 4 pose of the tip in the base frame at ``q``."""
        return np.array(self.functions.fk(_vec(q, self.n, "q")))

    def joint_origins(self, q) -> np.ndarray:
        """The arm's skeleton at ``q`` (what an animation draws): the base
        origin, the origin of every actuated joint's frame and the tip (3 x
        (n + 2), m, base frame). From the URDF chain's placements (the PUMA:
        its DH frames), numerically, the tip equal to :meth:`fk`'s."""
        q = _vec(q, self.n, "q")
        pts = [np.zeros(3)]
        if self.chain is not None:
            R, p = np.eye(3), np.zeros(3)
            frames = []
            for j, qi in zip(self.chain.joints, q):
                p = R @ j.p + p                           # the joint's origin (its frame before it moves)
                R = R @ j.R
                if j.type == "prismatic":
                    p = p + R @ (np.asarray(j.axis) * qi)
                else:
                    a = np.asarray(j.axis, dtype=float)
                    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
                    R = R @ (np.eye(3) + np.sin(qi) * K + (1 - np.cos(qi)) * K @ K)
                pts.append(p.copy())
                frames.append((R.copy(), p.copy()))
        else:
            from .puma560 import _dh

            T = np.eye(4)
            for qi, link in zip(q, self.links):
                T = T @ np.array(ca.DM(_dh(float(qi), link)))
                pts.append(T[:3, 3].copy())
        pts.append(self.fk(q)[:3, 3])
        return np.column_stack(pts)

    def jacobian(self, q) -> np.ndarray:
        """6 x n geometric Jacobian of the tip origin (linear rows first, base axes)."""
        return np.array(self.functions.jacobian(_vec(q, self.n, "q")))

    def mass_matrix(self, q) -> np.ndarray:
        """n x n joint-space inertia M(q), kg m^2 (kg for prismatic joints)."""
        return np.array(self.functions.mass_matrix(_vec(q, self.n, "q")))

    def bias(self, q, dq) -> np.ndarray:
        """``C(q, dq) dq + g(q)`` (n), N m."""
        return np.array(self.functions.bias(_vec(q, self.n, "q"), _vec(dq, self.n, "dq"))).ravel()

    def gravity(self, q) -> np.ndarray:
        """Gravity torque g(q) (n), N m."""
        return np.array(self.functions.gravity(_vec(q, self.n, "q"))).ravel()

    def friction(self, dq) -> np.ndarray:
        """Joint friction torque tau_f(dq) (n), N m."""
        return np.array(self.functions.friction(_vec(dq, self.n, "dq"))).ravel()

    def inverse_dynamics(self, q, dq, ddq) -> np.ndarray:
        """``tau = M ddq + C dq + g + tau_f`` (n), N m."""
        return np.array(self.functions.inverse_dynamics(_vec(q, self.n, "q"), _vec(dq, self.n, "dq"),
                                                        _vec(ddq, self.n, "ddq"))).ravel()

    def forward_dynamics(self, q, dq, tau) -> np.ndarray:
        """``ddq = M^-1 (tau - C dq - g - tau_f)`` (n)."""
        return np.array(self.functions.forward_dynamics(_vec(q, self.n, "q"), _vec(dq, self.n, "dq"),
                                                        _vec(tau, self.n, "tau"))).ravel()

    @property
    def moving_mass(self) -> float:
        """Mass carried by the actuated joints (every link that moves), kg."""
        if self.chain is None:
            return self.total_mass
        return float(sum(b.mass for b in self.chain.bodies))

    def dynamics(self, compiled: bool = True) -> ca.Function:
        """``["q","dq"] -> ["M","n"]``: the mass matrix and the bias in one
        Function, generated as C, compiled and cached on disk (keyed by
        :attr:`key`) when ``compiled`` and a C compiler is found, else the SX
        Function on CasADi's virtual machine (identical results: compiled with
        ``-ffp-contract=off``)."""
        f = self.functions
        q, dq = ca.SX.sym("q", self.n), ca.SX.sym("dq", self.n)
        fn = ca.Function("dynamics", [q, dq], [f.mass_matrix(q), f.bias(q, dq)], ["q", "dq"], ["M", "n"])
        if not compiled:
            return fn
        return _compiled(fn, self.key or hashlib.sha256(fn.serialize().encode()).hexdigest()[:20])

    def unit_notes(self) -> list[str]:
        """Values that read like a unit mistake, one line each for the command
        line to print (review 69: a URDF in millimetres ran as a 900 m arm,
        its model checks failing on the conditioning of M and blamed on the
        model; limits of 170 read as 170 rad): a reach above
        :data:`LARGE_REACH`, a revolute joint's limit beyond
        :data:`LARGE_TURN`."""
        notes = []
        reach = self.reach()
        if reach > LARGE_REACH:
            notes.append(f"robot {self.name}: reach {reach:.4g} m: an arm this long reads like lengths in "
                         "millimetres; if so, divide the URDF's lengths by 1000 (SI units: m)")
        kinds = [j.type for j in self.chain.joints] if self.chain is not None else ["revolute"] * self.n
        for name, kind, lo, hi in zip(self.joint_names, kinds, self.q_min, self.q_max):
            if kind == "revolute" and any(math.isfinite(x) and abs(x) > LARGE_TURN for x in (lo, hi)):
                notes.append(f"robot {self.name}: joint {name!r} limits [{lo:g}, {hi:g}] rad reach more than two "
                             "turns: if they are in degrees, write them in radians (SI units: rad)")
        return notes

    def reach(self) -> float:
        """Upper bound of the tip's distance from the first joint's axis origin, m:
        the sum of the distances between successive joint origins and to the tip
        (all joints at 0)."""
        if self.chain is None:              # PUMA: a2 + sqrt(a3^2 + d4^2) + |d3| from the shoulder
            from .puma560 import WRIST_OFFSET
            l1, l2, l3 = self.links
            return float(l2.a + math.hypot(l3.a, WRIST_OFFSET) + abs(l3.d))
        pts = [j.p for j in self.chain.joints[1:]] + [self.chain.tip_p]
        return float(sum(np.linalg.norm(p) for p in pts))


def unit_notes_of(source, load) -> list[str]:
    """:meth:`Robot.unit_notes` of the arm ``source`` names (as
    :func:`load_robot` takes it), loaded by ``load()`` for a user's URDF
    only: the PUMA and the bundled arms are SI (their tests check them), and
    a command need not build their dynamics for a note."""
    name = os.fspath(source)
    return [] if name.lower() in ("puma560", *BUNDLED) else load().unit_notes()


def source_stamp(source) -> tuple[int, int, int] | None:
    """``(inode, size, mtime in ns)`` of the URDF file :func:`load_robot`
    reads for ``source``; None for the PUMA or a bundled arm (read before any
    file of that name: review 48, a folder ``./ur5`` gave the UR5 a stamp
    that changed with each file written into it) and for a path that is not
    a regular file. A cache of loaded arms keyed on it loads a file rewritten
    in place again (review 47)."""
    name = os.fspath(source)
    if name.lower() in ("puma560", *BUNDLED):
        return None
    try:
        st = os.stat(name)
    except (OSError, ValueError):
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns) if stat.S_ISREG(st.st_mode) else None


def load_robot(source, tip: str | None = None, base: str | None = None, joints=None, *,
               friction: bool | str = True, armature=True, coulomb_velocity: float = 1e-2,
               mass_scale: float = 1.0, cache: bool = True) -> Robot:
    """Load a robot: the PUMA 560, a bundled arm, or a URDF file.

    Parameters
    ----------
    source : str or path
        ``"puma560"`` (the paper's three links, :class:`.Puma560`), a bundled
        arm (``"ur5"``: tip ``tool0``; ``"panda"``: tip ``panda_hand_tcp``),
        or the path of a ``.urdf`` file.
    tip : str, optional
        Link (or fixed frame) whose origin is the tool point. Default: the
        bundled arm's tip; for a file, the single leaf link (a branching tree
        needs it named).
    base : str, optional
        Link fixed to the world; default the root link.
    joints : sequence of str, optional
        Actuated joints; default every revolute, continuous or prismatic joint
        from base to tip. Other movable joints (a gripper's fingers) are held
        at their neutral value (0 clipped into their limits) and reported in
        :attr:`Robot.held`.
    friction : bool or "smooth"
        Joint friction ``b dq + f_c sign(dq)`` from ``<dynamics damping
        friction>`` (PUMA: its motor friction); ``"smooth"`` replaces
        ``sign(dq)`` by ``tanh(dq / coulomb_velocity)``; False: none.
    armature : bool or sequence of float
        Rotor inertia added to M's diagonal, kg m^2 (joint side). True: the
        source's own (PUMA: ``G^2 Jm``; a URDF has no standard element for it,
        so none); False: none; a sequence: one value per actuated joint.
    coulomb_velocity : float
        Velocity scale of the smooth Coulomb term, rad/s.
    mass_scale : float
        Every mass, inertia and rotor inertia multiplied by this factor (a
        controller's mismatched model, as ``model_mass_scale`` for the PUMA);
        1 leaves the numbers untouched.
    cache : bool
        Reuse the Functions built for the same URDF and options before.

    Raises
    ------
    URDFError
        A URDF that cannot be used, or a bad argument (one line).
    """
    if friction not in (True, False, "smooth"):
        raise URDFError(f"friction: expected True, False or 'smooth', got {friction!r}")
    if not (isinstance(coulomb_velocity, (int, float)) and coulomb_velocity > 0):
        raise URDFError(f"coulomb_velocity: must be > 0, got {coulomb_velocity!r}")
    if not (isinstance(mass_scale, (int, float)) and math.isfinite(mass_scale) and mass_scale > 0):
        raise URDFError(f"mass_scale: must be a finite number > 0, got {mass_scale!r}")
    if isinstance(source, str) and source.lower() == "puma560":
        return _puma(tip, base, joints, friction, armature, coulomb_velocity, float(mass_scale))
    if isinstance(source, str) and source.lower() in BUNDLED:
        fname, default_tip = BUNDLED[source.lower()]
        text = resources.files("tmtcontrol.model").joinpath("data", fname).read_text(encoding="utf-8")
        where, label, tip = f"{source.lower()} ({fname})", source.lower(), tip or default_tip
    else:
        path = os.fspath(source)
        if not os.path.exists(path) and os.sep not in path and not path.endswith(".urdf"):
            names = ", ".join(["puma560", *BUNDLED])       # a name, not a file: say which names there are
            raise URDFError(f"{path}: not a bundled arm ({names}) nor a URDF file")
        text = read_urdf(path)
        where = label = path
    chain = parse_chain(text, tip=tip, base=base, joints=joints, where=where)
    n = len(chain.joints)
    if armature is True or armature is False:
        arm = np.zeros(n)
    else:
        arm = np.asarray(armature, dtype=float).ravel()
        if arm.shape != (n,) or not np.all(np.isfinite(arm)) or np.any(arm < 0):
            raise URDFError(f"armature: expected {n} finite values >= 0 (kg m^2), got {armature!r}")
    masses = dict(chain.link_masses)
    if mass_scale != 1.0:
        arm = arm * mass_scale
        masses = {k: v * mass_scale for k, v in masses.items()}
        chain = dataclasses.replace(chain, link_masses=masses, bodies=tuple(
            dataclasses.replace(b, mass=b.mass * mass_scale, inertia=b.inertia * mass_scale) for b in chain.bodies))
    functions = _cached_functions(chain, text, arm, friction, coulomb_velocity, mass_scale, cache)
    J = chain.joints
    return Robot(name=chain.name, source=label, joint_names=tuple(j.name for j in J),
                 q_min=np.array([j.lower for j in J]), q_max=np.array([j.upper for j in J]),
                 dq_max=np.array([j.velocity for j in J]), tau_max=np.array([j.effort for j in J]),
                 base=chain.base, tip=chain.tip, held=dict(chain.held), link_masses=masses,
                 functions=functions, chain=chain, urdf=text, armature=arm,
                 key=cache_key(chain, text, arm, friction, coulomb_velocity, mass_scale), mass_scale=float(mass_scale))


# -- the PUMA through the interface -------------------------------------------------
def _puma(tip, base, joints, friction, armature, coulomb_velocity, mass_scale) -> Robot:
    from .puma560 import PUMA560_LINKS, Puma560

    if tip not in (None, PUMA_TIP):
        raise TipError(f"the PUMA 560's tip is {PUMA_TIP!r}, got {tip!r}")
    if base not in (None, "base"):
        raise ChainError("base", f"the PUMA 560's base is 'base', got {base!r}")
    if joints is not None and tuple(joints) != PUMA_JOINTS:
        raise ChainError("joints", f"the PUMA 560 actuates {', '.join(PUMA_JOINTS)}, got {list(joints)}")
    if armature not in (True, False):
        raise URDFError("armature: the PUMA 560 takes True (its rotor inertia G^2 Jm) or False")
    links = PUMA560_LINKS if mass_scale == 1.0 else tuple(   # as simulation.closedloop.controller_model
        dataclasses.replace(l, m=l.m * mass_scale, I=tuple(i * mass_scale for i in l.I), Jm=l.Jm * mass_scale)
        for l in PUMA560_LINKS)
    puma = Puma560(armature=armature, friction=friction, coulomb_velocity=coulomb_velocity, links=links)
    q, dq = puma.q, puma.dq
    frames = puma._frame_list
    R3 = frames[-1][:3, :3]
    T = ca.vertcat(ca.horzcat(R3, puma._p), ca.horzcat(ca.SX.zeros(1, 3), ca.SX.ones(1, 1)))
    Jw = ca.horzcat(ca.vertcat(0, 0, 1), frames[0][:3, 2], frames[1][:3, 2])
    J = ca.vertcat(puma._J, Jw)
    Jdot_dq = ca.vertcat(puma.expr["Jdot_dq"], ca.jtimes(Jw @ dq, q, dq))
    fns = RobotFunctions(
        fk=ca.Function("fk", [q], [T], ["q"], ["T"]),
        jacobian=ca.Function("jacobian", [q], [J], ["q"], ["J"]),
        jacobian_dot=ca.Function("jacobian_dot", [q, dq], [Jdot_dq], ["q", "dq"], ["Jdot_dq"]),
        mass_matrix=puma.mass_matrix, bias=puma.bias, gravity=puma.gravity, friction=puma.friction,
        inverse_dynamics=puma.inverse_dynamics, forward_dynamics=puma.forward_dynamics)
    inf = np.full(3, np.inf)
    masses = {f"link{i + 1}": l.m for i, l in enumerate(links)}
    arm = np.array([l.G ** 2 * l.Jm for l in links]) if armature else np.zeros(3)
    return Robot(name="puma560", source="puma560", joint_names=PUMA_JOINTS, q_min=-inf, q_max=inf.copy(),
                 dq_max=inf.copy(), tau_max=inf.copy(), base="base", tip=PUMA_TIP, held={},
                 link_masses=masses, functions=fns, armature=arm, key=_puma_key(armature, friction, coulomb_velocity, mass_scale), links=links,
                 mass_scale=mass_scale, position_ik=puma.inverse_kinematics)


# -- URDF robots ----------------------------------------------------------------------
_NAMES = [f.name for f in dataclasses.fields(RobotFunctions)]


def _build_functions(chain: Chain, arm, friction, coulomb_velocity) -> RobotFunctions:
    from .featherstone import build_expressions

    n = len(chain.joints)
    q, dq, ddq, tau = (ca.SX.sym(s, n) for s in ("q", "dq", "ddq", "tau"))
    e = build_expressions(chain, q, dq, ddq)
    b = ca.DM([j.damping for j in chain.joints])
    fc = ca.DM([j.friction for j in chain.joints])
    if friction is False:
        tau_f = ca.SX.zeros(n)
    elif friction == "smooth":
        tau_f = b * dq + fc * ca.tanh(dq / coulomb_velocity)
    else:
        tau_f = b * dq + fc * ca.sign(dq)
    A = ca.diag(ca.DM(arm))
    M = e["M"] + A if np.any(arm) else e["M"]
    Jdot_dq = ca.jtimes(e["J"] @ dq, q, dq)
    return RobotFunctions(
        fk=ca.Function("fk", [q], [e["T"]], ["q"], ["T"]),
        jacobian=ca.Function("jacobian", [q], [e["J"]], ["q"], ["J"]),
        jacobian_dot=ca.Function("jacobian_dot", [q, dq], [Jdot_dq], ["q", "dq"], ["Jdot_dq"]),
        mass_matrix=ca.Function("mass_matrix", [q], [M], ["q"], ["M"]),
        bias=ca.Function("bias", [q, dq], [e["bias"]], ["q", "dq"], ["n"]),
        gravity=ca.Function("gravity", [q], [e["g"]], ["q"], ["g"]),
        friction=ca.Function("friction", [dq], [tau_f], ["dq"], ["tau_f"]),
        inverse_dynamics=ca.Function("inverse_dynamics", [q, dq, ddq], [e["rnea"] + A @ ddq + tau_f],
                                     ["q", "dq", "ddq"], ["tau"]),
        forward_dynamics=ca.Function("forward_dynamics", [q, dq, tau], [ca.solve(M, tau - e["bias"] - tau_f)],
                                     ["q", "dq", "tau"], ["ddq"]))


def cache_key(chain: Chain, text: str, arm, friction, coulomb_velocity, mass_scale=1.0) -> str:
    """Key of a robot's Functions: the URDF's content, the chain chosen, the
    options, the sources of the modules that build them and CasADi's version."""
    h = hashlib.sha256(text.encode("utf-8"))
    here = pathlib.Path(__file__).parent
    for part in (chain.base, chain.tip, ",".join(j.name for j in chain.joints), repr(np.asarray(arm).tolist()),
                 repr(friction), repr(float(coulomb_velocity)), repr(float(mass_scale)), ca.__version__):
        h.update(b"\0" + part.encode())
    for module in ("featherstone.py", "urdf.py", "robot.py"):
        h.update((here / module).read_bytes())
    return h.hexdigest()[:20]


def _cached_functions(chain, text, arm, friction, coulomb_velocity, mass_scale, use_cache) -> RobotFunctions:
    if not use_cache:
        return _build_functions(chain, arm, friction, coulomb_velocity)
    from ..cache import cache_dir      # the one definition of the cache folder

    key = cache_key(chain, text, arm, friction, coulomb_velocity, mass_scale)
    path = cache_dir() / "robots" / f"{_safe(chain.name)}_{key}.casadi"
    data = _verified(path)
    if data is not None:
        try:
            return RobotFunctions(**dict(zip(_NAMES, _load_functions(data.decode("ascii")))))
        except (RuntimeError, ValueError):
            pass                                        # unreadable: rebuilt and rewritten below
    fns = _build_functions(chain, arm, friction, coulomb_velocity)
    try:
        s = ca.StringSerializer()
        for name in _NAMES:
            s.pack(getattr(fns, name))
        _store(path, s.encode().encode("ascii"))
    except OSError:
        pass                                            # an unwritable cache: built every time
    return fns


def _puma_key(armature, friction, coulomb_velocity, mass_scale) -> str:
    here = pathlib.Path(__file__).parent
    h = hashlib.sha256(repr((bool(armature), friction, float(coulomb_velocity), mass_scale, ca.__version__)).encode())
    for module in ("puma560.py", "robot.py"):
        h.update((here / module).read_bytes())
    return "puma560_" + h.hexdigest()[:20]


_CFLAGS = ["-O3", "-ffp-contract=off", "-fno-math-errno", "-fPIC", "-shared"]
"""-ffp-contract=off: no fused multiply-adds, so the compiled code computes
what CasADi's virtual machine computes."""


def _compiled(fn: ca.Function, key: str) -> ca.Function:
    """``fn`` generated as C, compiled and loaded as an external Function;
    cached as ``<cache>/robots/<name>_<key>.so`` (written under a temporary
    name and renamed). Built in a private build folder, removed however the
    build ends (:func:`tmtcontrol.cache.build_folder`); if the cache cannot be
    written, loaded from there (the mapping outlives the file). Without a
    compiler, or if compiling fails, ``fn``."""
    import subprocess

    from ..cache import build_folder, cache_dir, compiler      # the one cache folder and compiler choice
    from ..processes import run_compiler

    h = hashlib.sha256(f"{key} {' '.join(_CFLAGS)} {ca.__version__} {os.uname().machine}".encode())
    lib = cache_dir() / "robots" / f"{fn.name()}_{h.hexdigest()[:20]}.so"
    if _verified(lib) is not None:                            # a damaged or partial library is never loaded
        try:
            return ca.external(fn.name(), str(lib))
        except RuntimeError:
            pass                                              # rebuilt below
    cc = compiler()
    if cc is None:
        return fn
    try:
        with build_folder("robot") as build:
            gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
            gen.add(fn)
            cfile = gen.generate(str(build) + os.sep)
            built = build / "lib.so"
            run_compiler([cc, *_CFLAGS, cfile, "-o", str(built), "-lm"], build / "tmp")
            try:
                _store(lib, built.read_bytes())
                return ca.external(fn.name(), str(lib))
            except OSError:
                return ca.external(fn.name(), str(built))
    except (OSError, subprocess.SubprocessError, RuntimeError):
        return fn


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)[:40] or "robot"


def _store(path: pathlib.Path, data: bytes) -> None:
    """Write ``data`` to ``path`` and its SHA-256 to ``path.sha256``, each under a
    temporary name, fsync'ed and renamed (the checksum last, so a crash leaves an
    unverifiable file, which is rebuilt); a failed write (a full disk) leaves no
    staged file (:func:`tmtcontrol.cache.write_staged`)."""
    from ..cache import write_staged

    write_staged([(path, data), (_sidecar(path), hashlib.sha256(data).hexdigest().encode())])


def _verified(path: pathlib.Path) -> bytes | None:
    """The content of ``path`` if it matches its recorded SHA-256, else None."""
    try:
        data = path.read_bytes()
        recorded = _sidecar(path).read_text().strip()
    except OSError:
        return None
    return data if hashlib.sha256(data).hexdigest() == recorded else None


def _sidecar(path: pathlib.Path) -> pathlib.Path:
    return path.with_name(path.name + ".sha256")


def _load_functions(text: str) -> list:
    d = ca.StringDeserializer(text)
    out = [d.unpack() for _ in _NAMES]
    if not all(isinstance(f, ca.Function) and f.name() == name for f, name in zip(out, _NAMES)):
        raise ValueError("unexpected content")
    return out


def _vec(x, n: int, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float).ravel()
    if a.shape != (n,):
        raise ValueError(f"{name}: expected {n} values, got shape {np.shape(x)}")
    if not np.all(np.isfinite(a)):      # review 58: a NaN joint angle gave a NaN mass matrix, silently
        raise ValueError(f"{name}: expected finite values, got {a.tolist()!r}")
    return a
