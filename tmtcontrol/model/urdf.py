"""A fixed-base serial arm read from a URDF: the parsed, checked kinematic chain.

The file is parsed by ``urdf_parser_py`` (the ROS project's URDF parser, PyPI
``urdfdom-py``; XML by lxml), never by hand. This module then turns the link
tree into the data the rigid-body algorithms of :mod:`.featherstone` need
(:class:`Chain`): the actuated joints from the base link to the tip, each with
its constant placement in the previous moving body, its axis, limits and
friction, and one rigid body per actuated joint holding every link attached to
it rigidly (fixed joints, and movable joints that are held, such as a gripper's
fingers). Nothing symbolic is built here.

What is refused (:class:`URDFError`, a ``ValueError`` whose message is one
line naming the file, and the link, joint or key): a path that is not a
regular file or is larger than :data:`MAX_BYTES`; not XML; XML whose root is not
``<robot>``; a link or joint the parser rejects; a tip or base that does not
exist (the candidates listed); a tip that is not below the base; several leaf
links and no tip given (the leaves listed); a link that is the child of two
joints (a closed loop) or several root links; ``floating`` or ``planar``
joints (a floating base); a revolute or prismatic chain joint without
``<limit lower upper effort velocity>``, a continuous chain joint without
``<limit effort velocity>``; limits or masses the URDF spec does not allow
(lower > upper, effort or velocity <= 0, negative mass, a zero axis); any
number that is not finite (``nan``, ``inf``) in an origin, axis, mimic,
limit, dynamics, mass or inertia, before CasADi, Pinocchio or MuJoCo see the
file; a moving link without ``<inertial>``, with zero mass, or with an inertia
tensor that is not positive definite (massless frames attached by fixed joints
may omit ``<inertial>``; any inertia present must be positive semi-definite);
a mimic joint on the actuated chain or mimicking an actuated joint (off the
chain, a mimic joint is held at ``multiplier * value + offset`` of the held
joint it follows); more than :data:`MAX_JOINTS` actuated joints.

Conventions: SI units (m, rad, kg, kg m^2, N, N m, s) as the URDF spec fixes
them; a joint's child frame is its ``<origin>`` frame moved by the joint; held
joints sit at their neutral value, 0 clipped into their position limits.
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, field

import numpy as np

__all__ = ["URDFError", "ChainError", "TipError", "ChainJoint", "Body", "Chain", "MAX_BYTES", "read_urdf", "parse_chain"]

MAX_BYTES = 20 * 1024 * 1024
"""Largest URDF read, bytes (the biggest arm descriptions are a few hundred kB)."""

_MOVABLE = ("revolute", "continuous", "prismatic")


class URDFError(ValueError):
    """A URDF that cannot be used; the message is one line."""


class ChainError(URDFError):
    """The chain asked for is not in the file: the key at fault (``key``:
    ``"tip"``, ``"base"`` or ``"joints"``) is the request's, not the file's."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


class TipError(ChainError):
    """The tip frame asked for is not a link below the base."""

    def __init__(self, message: str):
        super().__init__("tip", message)


@dataclass(frozen=True, eq=False)
class ChainJoint:
    """One actuated joint of the chain.

    Attributes
    ----------
    name, type : str
        URDF joint name and type (revolute, continuous or prismatic).
    R, p : numpy.ndarray
        Rotation (3 x 3) and position (3, m) of the joint's ``<origin>`` frame
        in the previous moving body's frame (the base link for the first joint).
    axis : numpy.ndarray
        Unit axis (3,) in the joint frame.
    lower, upper : float
        Position limits, rad or m (-inf, inf for a continuous joint).
    velocity, effort : float
        Velocity limit (rad/s or m/s) and effort limit (N m or N).
    damping, friction : float
        Viscous (N m s/rad or N s/m) and Coulomb (N m or N) friction from
        ``<dynamics damping friction>`` (0 when absent).
    """

    name: str
    type: str
    R: np.ndarray
    p: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    velocity: float
    effort: float
    damping: float
    friction: float


@dataclass(frozen=True, eq=False)
class Body:
    """Rigid body moved by one actuated joint: every link fixed to it merged.

    Attributes
    ----------
    mass : float
        kg.
    com : numpy.ndarray
        Centre of mass (3,) in the body frame (the joint's child link frame), m.
    inertia : numpy.ndarray
        Rotational inertia (3 x 3) about the centre of mass, body axes, kg m^2.
    links : tuple of str
        The links merged into the body, the joint's child link first.
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray
    links: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class Chain:
    """The checked serial chain of a URDF, ready for the rigid-body algorithms.

    Attributes
    ----------
    name : str
        The robot's name in the URDF.
    base, tip : str
        Base link (fixed to the world) and tip link or frame.
    joints : tuple of ChainJoint
        Actuated joints, base to tip.
    bodies : tuple of Body
        ``bodies[i]`` is moved by ``joints[i]``.
    tip_body : int
        Index of the body the tip is fixed to (-1: the base).
    tip_R, tip_p : numpy.ndarray
        Tip frame in that body's frame (rotation, position in m).
    held : dict
        Movable joints that are not actuated, with the value they are held at
        (rad or m): off-chain joints such as gripper fingers, and chain joints
        left out of ``joints``.
    link_masses : dict
        Mass of every link below the base, kg (0 for massless frames).
    up : tuple of float
        The URDF root's +z (up: gravity acts along -z of the root link) in
        base coordinates: (0, 0, 1) when the base is the root; the joints'
        rotations above a lower base turn it, a movable one taken at 0
        (review 69: a wall-mounted arm read from its mount link had gravity
        along the mount's own -z).
    """

    name: str
    base: str
    tip: str
    joints: tuple[ChainJoint, ...]
    bodies: tuple[Body, ...]
    tip_body: int
    tip_R: np.ndarray
    tip_p: np.ndarray
    held: dict = field(default_factory=dict)
    link_masses: dict = field(default_factory=dict)
    up: tuple = (0.0, 0.0, 1.0)


def read_urdf(path) -> str:
    """The text of the URDF at ``path``, refusing anything but a regular file
    of at most :data:`MAX_BYTES` bytes (checked before reading)."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise URDFError(f"{path}: cannot read ({exc.strerror})") from None
    if not stat.S_ISREG(st.st_mode):
        raise URDFError(f"{path}: not a regular file")
    if st.st_size > MAX_BYTES:
        raise URDFError(f"{path}: {st.st_size} bytes, larger than the {MAX_BYTES} bytes a URDF may have here")
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise URDFError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise URDFError(f"{path}: not XML (not UTF-8 text)") from None


MAX_JOINTS = 12
"""The most actuated joints of a chain (industrial arms have 6 or 7, a dual arm
on a torso about 15 as two chains): the CasADi expressions of eq. (1) grow as
n^3, so a longer chain is refused at once instead of building for minutes."""


def parse_chain(text: str, tip: str | None = None, base: str | None = None,
                joints=None, where: str = "URDF") -> Chain:
    """Parse and check a URDF's text; the serial chain from ``base`` to ``tip``.

    Parameters
    ----------
    text : str
        The URDF (XML).
    tip : str, optional
        Link whose origin is the tool point; default the single leaf link.
    base : str, optional
        Link fixed to the world; default the root link.
    joints : sequence of str, optional
        The actuated joints (all on the base-tip path); default every movable
        joint on it.
    where : str
        Name used in error messages (the file's path).

    Raises
    ------
    URDFError
        One line naming the problem (see the module docstring).
    """
    robot = _parse(text, where)
    if not robot.links:
        raise URDFError(f"{where}: no <link>")
    _check_numbers(robot, where)
    for kind, items in (("link", robot.links), ("joint", robot.joints)):
        names = [x.name for x in items]
        twice = sorted({x for x in names if names.count(x) > 1})
        if twice:
            raise URDFError(f"{where}: {kind} {twice[0]!r} is defined twice")
    links = {l.name: l for l in robot.links}
    by_child: dict[str, object] = {}
    children: dict[str, list] = {name: [] for name in links}
    for j in robot.joints:
        for end in (j.parent, j.child):
            if end not in links:
                raise URDFError(f"{where}: joint {j.name!r} names link {end!r}, which does not exist")
        if j.child in by_child:
            raise URDFError(f"{where}: link {j.child!r} is the child of joints {by_child[j.child].name!r} and "
                            f"{j.name!r}: a closed loop, not a tree")
        by_child[j.child] = j
        children[j.parent].append(j)
        if j.type in ("floating", "planar"):
            raise URDFError(f"{where}: joint {j.name!r} is {j.type}: a floating base is not supported "
                            "(fixed-base arms only)")
        if j.type not in _MOVABLE + ("fixed",):
            raise URDFError(f"{where}: joint {j.name!r}: unknown type {j.type!r}")
    roots = [name for name in links if name not in by_child]
    if len(roots) != 1:
        raise URDFError(f"{where}: {'no root link (a closed loop)' if not roots else 'several root links: ' + ', '.join(roots)}")
    _no_cycle(roots[0], children, len(links), where)
    base = roots[0] if base is None else base
    if base not in links:
        raise ChainError("base", f"{where}: base link {base!r} does not exist; links: {', '.join(links)}")
    below = _subtree(base, children)
    frames = [l for l in below if l != base]
    if not frames:
        raise ChainError("base", f"{where}: no joint below the base link {base!r}")
    up = _up(base, by_child)
    if tip is None:
        leaves = [l for l in below if not children[l]]
        if len(leaves) != 1:
            # the request lacks its tip: the command line says --tip, a scenario robot.tip (review 19)
            raise TipError(f"{where}: the tree branches ({len(leaves)} leaf links: {', '.join(leaves)}); "
                           "give the tip link")
        tip = leaves[0]
    if tip not in links:
        raise TipError(f"{where}: tip {tip!r} is not a link; links below {base!r}: {', '.join(frames)}")
    if tip not in below or tip == base:
        raise TipError(f"{where}: tip {tip!r} is not below the base {base!r}; candidates: {', '.join(frames)}")
    path = []                                   # joints base -> tip
    link = tip
    while link != base:
        path.append(by_child[link])
        link = by_child[link].parent
    path.reverse()
    on_path = [j.name for j in path if j.type in _MOVABLE]
    if joints is None:
        actuated = on_path
    else:
        actuated = list(joints)
        for name in actuated:
            if name not in on_path:
                raise ChainError("joints", f"{where}: joint {name!r} is not a movable joint between {base!r} and {tip!r}; "
                                f"candidates: {', '.join(on_path)}")
        if len(set(actuated)) != len(actuated):
            raise ChainError("joints", f"{where}: a joint is named twice")
        actuated = [n for n in on_path if n in actuated]          # base-to-tip order
    if not actuated:
        raise URDFError(f"{where}: no revolute, continuous or prismatic joint between {base!r} and {tip!r}")
    if len(actuated) > MAX_JOINTS:
        raise URDFError(f"{where}: {len(actuated)} actuated joints between {base!r} and {tip!r}, more than "
                        f"{MAX_JOINTS} (the symbolic dynamics grow as n^3: a 30-joint chain takes minutes to build); "
                        "name the arm's joints (joints=...) or a nearer tip")
    held = _held_values(robot, [l for l in below if l != base], by_child, set(actuated), where)

    # walk the tree: every link's body (index of its actuated joint, -1 = base) and placement in it
    index = {name: k for k, name in enumerate(actuated)}
    place = {base: (-1, np.eye(3), np.zeros(3))}
    specs: list = [None] * len(actuated)
    for link in below:
        if link == base:
            continue
        j = by_child[link]
        b, R, p = place[j.parent]
        Ro, po = _origin(j.origin)
        Rj, pj = R @ Ro, R @ po + p
        if j.name in index:
            k = index[j.name]
            if b != k - 1:
                raise URDFError(f"{where}: joint {j.name!r} does not follow the previous actuated joint")
            specs[k] = (j, Rj, pj)
            place[link] = (k, np.eye(3), np.zeros(3))
        else:
            Rm, pm = (np.eye(3), np.zeros(3)) if j.type == "fixed" else _motion(j, held[j.name], where)
            place[link] = (b, Rj @ Rm, Rj @ pm + pj)

    chain_joints = tuple(_chain_joint(j, R, p, where) for j, R, p in specs)
    # what moves is the rigid body: the joint's child and the links fixed to it (a massless link whose mass sits
    # on a fixed '*_inertia' child is a common layout, and Pinocchio's; review 19): a moving link that carries
    # its body's mass alone is checked as moving, as before; one whose fixed links carry mass, by the body
    body_parts = [sorted((name for name in frames if place[name][0] == k), key=lambda name: name != j.child)
                  for k, (j, _, _) in enumerate(specs)]

    def massive(name):
        got = _inertial(links[name], where)
        return got is not None and got[0] > 0

    lone = {parts[0] for parts in body_parts if not any(massive(name) for name in parts[1:])}
    masses = {link: _check_inertial(links[link], where, moving=link in lone) for link in frames}
    bodies = []
    for (j, _, _), parts in zip(specs, body_parts):
        if not sum(masses[name] for name in parts) > 0:
            _check_inertial(links[j.child], where, moving=True)      # names what the moving link lacks
        body = _merge(links, parts, place)
        eig = np.linalg.eigvalsh(body.inertia)
        if not eig[0] > 0:
            raise URDFError(f"{where}: link {j.child!r}: the inertia of the rigid body it forms with "
                            f"{', '.join(parts[1:])} is not positive definite (eigenvalues "
                            f"{', '.join(f'{e:.3g}' for e in eig)} kg m^2)")
        bodies.append(body)
    tb, tR, tp = place[tip]
    return Chain(name=robot.name, base=base, tip=tip, joints=chain_joints, bodies=tuple(bodies), tip_body=tb,
                 tip_R=tR, tip_p=tp, held=held, link_masses=masses, up=up)


def _up(base: str, by_child: dict) -> tuple:
    """The root link's +z in the coordinates of ``base`` (gravity acts along
    the root's -z): the rotations of the joints' origins from the root down
    to the base, a movable joint above the base taken at 0, the URDF's zero
    pose (the base is fixed to the world; those joints are not modelled, as
    Pinocchio's reference holds them)."""
    R = np.eye(3)                                    # base -> root, built from the base up
    link = base
    while link in by_child:
        j = by_child[link]
        R = _origin(j.origin)[0] @ R
        link = j.parent
    return tuple(float(x) for x in R.T @ np.array([0.0, 0.0, 1.0]))


# -- helpers ------------------------------------------------------------------------
def _parse(text: str, where: str):
    from lxml import etree
    from urdf_parser_py import urdf
    from urdf_parser_py.xml_reflection import core

    try:
        root = etree.fromstring(text.encode("utf-8") if isinstance(text, str) else text,
                                etree.XMLParser(resolve_entities=False, no_network=True, huge_tree=False))
    except etree.XMLSyntaxError as exc:
        raise URDFError(f"{where}: not XML ({exc.msg if hasattr(exc, 'msg') else exc})") from None
    if root.tag != "robot":
        raise URDFError(f"{where}: not a URDF (root element <{root.tag}>, expected <robot>)")
    for el in root.iter():
        # urdf_parser_py skips unknown elements: an unexpanded <xacro:include> or macro call would lose what it adds
        if isinstance(el.tag, str) and el.tag.startswith("{") and "xacro" in el.tag[1:el.tag.find("}")]:
            raise URDFError(f"{where}: <xacro:{etree.QName(el).localname}> found: a xacro file; expand it first "
                            "(xacro FILE.urdf.xacro > FILE.urdf)")
    saved = core.on_error
    core.on_error = lambda message: None                   # unknown attributes (e.g. mu_viscous): ignored
    try:
        return urdf.URDF.from_xml(root, core.Path(urdf.URDF.XML_REFL.tag, tree=etree.ElementTree(root)))
    except (core.ParseError, ValueError, TypeError, AttributeError) as exc:
        message = " ".join(str(exc).split())
        raise URDFError(f"{where}: not a valid URDF ({message})") from None
    finally:
        core.on_error = saved


def _check_numbers(robot, where) -> None:
    """Every number of the kinematics finite (``nan`` and ``inf`` parse as
    floats): joint and inertial origins, axes, mimic multipliers and
    offsets, limits, dynamics, masses and inertias; refused here, before any
    other library (CasADi, Pinocchio, MuJoCo) sees the file."""
    def check(values, what):
        if values is None:
            return
        vals = values if isinstance(values, (list, tuple)) else [values]
        for v in vals:
            try:
                ok = v is None or math.isfinite(float(v))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise URDFError(f"{where}: {what} must be finite, got {v!r}")

    for j in robot.joints:
        name = f"joint {j.name!r}"
        if j.origin is not None:
            check(j.origin.xyz, f"{name} <origin xyz>")
            check(j.origin.rpy, f"{name} <origin rpy>")
        check(j.axis, f"{name} <axis xyz>")
        if j.mimic is not None:
            check(j.mimic.multiplier, f"{name} <mimic multiplier>")
            check(j.mimic.offset, f"{name} <mimic offset>")
        if j.limit is not None:
            for key in ("lower", "upper", "effort", "velocity"):
                check(getattr(j.limit, key, None), f"{name} <limit {key}>")
        if j.dynamics is not None:
            check(j.dynamics.damping, f"{name} <dynamics damping>")
            check(j.dynamics.friction, f"{name} <dynamics friction>")
    for link in robot.links:
        ine = link.inertial
        if ine is None:
            continue
        name = f"link {link.name!r}"
        check(ine.mass, f"{name} <mass>")
        if ine.origin is not None:
            check(ine.origin.xyz, f"{name} <inertial origin xyz>")
            check(ine.origin.rpy, f"{name} <inertial origin rpy>")
        if ine.inertia is not None:
            t = ine.inertia
            check([t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz], f"{name} <inertia>")


def _no_cycle(root, children, count, where):
    seen, stack = set(), [root]
    while stack:
        link = stack.pop()
        if link in seen:
            raise URDFError(f"{where}: link {link!r} is reached twice: a closed loop")
        seen.add(link)
        stack.extend(j.child for j in children[link])
    if len(seen) != count:
        missing = sorted(set(children) - seen)
        raise URDFError(f"{where}: links {', '.join(missing)} are not connected to the root (a closed loop)")


def _subtree(base, children) -> list[str]:
    """Links below ``base`` (inclusive), parents before children."""
    out, queue = [], [base]
    while queue:
        link = queue.pop(0)
        out.append(link)
        queue.extend(j.child for j in children[link])
    return out


def _finite(value, what, where):
    if value is None or not math.isfinite(float(value)):
        raise URDFError(f"{where}: {what}: expected a finite number, got {value!r}")
    return float(value)


def _held_values(robot, below, by_child, actuated, where) -> dict:
    """The value each movable joint off the actuated chain is held at, for the
    links ``below`` the base (the base's own parent joint is not in the model,
    review 32): 0 clipped into its limits; a mimic joint its leader's value times the
    multiplier plus the offset, leaders first whatever the file's order (a
    mimic of a mimic). Held limits must not be reversed (lower <= upper)."""
    joints = {j.name: j for j in robot.joints}
    inside = {by_child[l].name for l in below if l in by_child}
    held = {}
    mimics = []
    for name in (n for n in joints if n in inside):
        j = joints[name]
        if j.type not in _MOVABLE:
            continue
        lo, hi = -math.inf, math.inf
        if j.limit is not None and j.type != "continuous" and name not in actuated:
            lo, hi = float(j.limit.lower or 0.0), float(j.limit.upper or 0.0)
            if not lo <= hi:            # (equal: a range of one value, the URDF's default 0 to 0)
                raise URDFError(f"{where}: joint {name!r} (held, off the chain): <limit> lower {lo:g} must not "
                                f"exceed upper {hi:g}")
        if j.mimic is not None:
            if name in actuated:
                raise URDFError(f"{where}: joint {name!r} mimics {j.mimic.joint!r}: mimic joints on the actuated "
                                "chain are not supported")
            mimics.append(j)
            continue
        if name in actuated:
            continue
        held[name] = float(min(max(0.0, lo), hi))
    while mimics:
        ready = [j for j in mimics if j.mimic.joint in held]
        if not ready:
            j = mimics[0]
            if j.mimic.joint in actuated:
                raise URDFError(f"{where}: joint {j.name!r} mimics the actuated joint {j.mimic.joint!r}: "
                                "not supported (mimic joints are held, off the chain)")
            followed = {m.name for m in mimics}
            raise URDFError(f"{where}: joint {j.name!r} mimics {j.mimic.joint!r}, which is "
                            + ("a mimic joint of a cycle" if j.mimic.joint in followed
                               else "not a movable joint held below the base"))
        for j in ready:
            mult = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
            off = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
            held[j.name] = mult * held[j.mimic.joint] + off
            mimics.remove(j)
    return held


def _rpy(rpy) -> np.ndarray:
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _origin(pose):
    if pose is None:
        return np.eye(3), np.zeros(3)
    xyz = np.zeros(3) if pose.xyz is None else np.array(pose.xyz, dtype=float)
    R = np.eye(3) if pose.rpy is None else _rpy(pose.rpy)
    return R, xyz


def _axis(j, where) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0] if j.axis is None else j.axis, dtype=float)
    norm = float(np.linalg.norm(a)) if np.all(np.isfinite(a)) else 0.0
    if not norm > 0:
        raise URDFError(f"{where}: joint {j.name!r}: axis {list(j.axis)} is not a direction")
    return a / norm


def _motion(j, value, where):
    """Rotation and translation of a movable joint at ``value``."""
    a = _axis(j, where)
    if j.type == "prismatic":
        return np.eye(3), a * value
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(value) * K + (1 - math.cos(value)) * K @ K, np.zeros(3)


def _chain_joint(j, R, p, where) -> ChainJoint:
    lim = j.limit
    if lim is None:
        need = "effort velocity" if j.type == "continuous" else "lower upper effort velocity"
        raise URDFError(f"{where}: joint {j.name!r}: {j.type} joint without <limit {need}> (the chain's joints "
                        "need their limits)")
    velocity = _finite(lim.velocity, f"joint {j.name!r} <limit velocity>", where)
    effort = _finite(lim.effort, f"joint {j.name!r} <limit effort>", where)
    if not (velocity > 0 and effort > 0):
        raise URDFError(f"{where}: joint {j.name!r}: <limit> velocity and effort must be > 0, got "
                        f"{velocity:g}, {effort:g}")
    if j.type == "continuous":
        lower, upper = -math.inf, math.inf
    else:
        lower = _finite(lim.lower if lim.lower is not None else 0.0, f"joint {j.name!r} <limit lower>", where)
        upper = _finite(lim.upper if lim.upper is not None else 0.0, f"joint {j.name!r} <limit upper>", where)
        if not lower < upper:
            raise URDFError(f"{where}: joint {j.name!r}: <limit> lower {lower:g} must be < upper {upper:g}")
    damping = friction = 0.0
    if j.dynamics is not None:
        damping = _finite(j.dynamics.damping or 0.0, f"joint {j.name!r} <dynamics damping>", where)
        friction = _finite(j.dynamics.friction or 0.0, f"joint {j.name!r} <dynamics friction>", where)
        if damping < 0 or friction < 0:
            raise URDFError(f"{where}: joint {j.name!r}: <dynamics> damping and friction must be >= 0")
    return ChainJoint(name=j.name, type=j.type, R=R, p=p, axis=_axis(j, where), lower=lower, upper=upper,
                      velocity=velocity, effort=effort, damping=damping, friction=friction)


def _inertial(link, where):
    """(mass, com, inertia about com in link axes), or None without <inertial>."""
    ine = link.inertial
    if ine is None:
        return None
    m = _finite(ine.mass if ine.mass is not None else 0.0, f"link {link.name!r} <mass>", where)
    t = ine.inertia
    vals = [0.0] * 6 if t is None else [t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz]
    ixx, ixy, ixz, iyy, iyz, izz = (_finite(v, f"link {link.name!r} <inertia>", where) for v in vals)
    I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    R, c = _origin(ine.origin)
    return m, c, R @ I @ R.T


def _check_inertial(link, where, moving: bool) -> float:
    got = _inertial(link, where)
    if got is None:
        if moving:
            raise URDFError(f"{where}: link {link.name!r} moves but has no <inertial>")
        return 0.0
    m, _, I = got
    eig = np.linalg.eigvalsh(I)
    if m < 0:
        raise URDFError(f"{where}: link {link.name!r}: negative mass {m:g} kg")
    if moving and not m > 0:
        raise URDFError(f"{where}: link {link.name!r} moves but has zero mass")
    if moving and not eig[0] > 0:
        raise URDFError(f"{where}: link {link.name!r}: inertia is not positive definite "
                        f"(eigenvalues {', '.join(f'{e:.3g}' for e in eig)} kg m^2)")
    if eig[0] < -1e-12 * max(1.0, abs(eig[-1])):
        raise URDFError(f"{where}: link {link.name!r}: inertia is not positive semi-definite "
                        f"(eigenvalues {', '.join(f'{e:.3g}' for e in eig)} kg m^2)")
    if eig[0] + eig[1] < eig[2] * (1 - TRIANGLE_RTOL):
        # no mass distribution has a principal moment above the sum of the other two (I_zz = int x^2 + y^2 dm);
        # MuJoCo refuses such a body too, naming neither file nor link (review 19)
        raise URDFError(f"{where}: link {link.name!r}: inertia no body can have (principal moments "
                        f"{', '.join(f'{e:.4g}' for e in eig)} kg m^2: the largest exceeds the sum of the others)")
    return m


TRIANGLE_RTOL = 1e-6
"""Slack of the principal moments' triangle inequality, relative to the
largest: a thin rod or a flat plate meets it with equality, which a CAD
export rounded to a few digits may miss by its rounding."""


def _merge(links, parts, place) -> Body:
    """One body from the links ``parts`` (their placements in the body frame)."""
    m_tot, h, I_o = 0.0, np.zeros(3), np.zeros((3, 3))
    for name in parts:
        got = _inertial(links[name], "")
        if got is None:
            continue
        m, c, Ic = got
        _, R, p = place[name]
        cb = R @ c + p
        m_tot += m
        h += m * cb
        I_o += R @ Ic @ R.T + m * (cb @ cb * np.eye(3) - np.outer(cb, cb))     # about the body origin
    com = h / m_tot
    Ic = I_o - m_tot * (com @ com * np.eye(3) - np.outer(com, com))
    return Body(mass=m_tot, com=com, inertia=Ic, links=tuple(parts))
