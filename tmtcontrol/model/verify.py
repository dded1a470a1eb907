"""Checks of a robot model: physical identities and agreement with Pinocchio.

:func:`check_robot` evaluates, at seeded random configurations within the
joint limits, the identities every rigid-body model of eq. (1) satisfies:

* M(q) symmetric and positive definite;
* the energy identity ``dq^T (Mdot - 2 C) dq = 0`` (Mdot by CasADi's forward
  derivative of M along dq, ``C dq = bias - g``);
* inverse dynamics of forward dynamics gives back tau;
* the Jacobian's linear rows are the derivative of the tip position of fk;

and, when Pinocchio (``pin``) is importable, the agreement with it (an
independent C++ implementation): M, bias, g, J, fk to :data:`TOLERANCE`
relative, and ``RNEA(q, dq, ABA(q, dq, tau)) = tau`` with Pinocchio's ABA. The
Pinocchio model of a URDF arm is built from the same URDF text (held joints
locked at their values); the PUMA's from its DH parameters (a revolute-z joint
per link placed by the previous link's DH transform, inertias and armature
from the robot's parameter set, :data:`~tmtcontrol.model.puma560.PUMA560_LINKS` unless scaled). Friction is not part of
the comparison (Pinocchio's algorithms have none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

__all__ = ["TOLERANCE", "Identity", "RobotCheck", "check_robot", "random_states", "pinocchio_model"]

TOLERANCE = 1e-10
"""Relative agreement required (Frobenius norm of the difference over that of
the reference): double precision leaves about 1e-14 after the few hundred
operations of these algorithms, so 1e-10 is far above rounding and far below
any modelling error (a wrong inertia or axis gives 1e-3 and more)."""


@dataclass(frozen=True)
class Identity:
    """One check: its worst value over the configurations, and the verdict.

    Attributes
    ----------
    name : str
        What is checked.
    worst : float
        Worst relative error (or, for positive definiteness, the smallest
        eigenvalue of M over the configurations, kg m^2).
    limit : float
        The bound ``worst`` must meet (``<= limit``; for positive definiteness ``> limit``).
    ok : bool
        Whether it holds at every configuration.
    """

    name: str
    worst: float
    limit: float
    ok: bool


@dataclass(frozen=True)
class RobotCheck:
    """The result of :func:`check_robot`.

    Attributes
    ----------
    identities : tuple of Identity
    samples, seed : int
        Number of random configurations and the generator's seed.
    reference : str
        ``"pinocchio X.Y.Z"``, or why Pinocchio was not compared.
    """

    identities: tuple[Identity, ...]
    samples: int
    seed: int
    reference: str

    @property
    def ok(self) -> bool:
        """Every identity holds."""
        return all(i.ok for i in self.identities)


def _rel(a, b, floor: float = 0.0) -> float:
    """||a - b|| / max(||b||, ``floor``) (Frobenius; the absolute difference where
    both are 0). ``floor``: the quantity's natural size where ``b`` may be zero
    but for rounding (the gravity torque of an arm whose axes are all vertical:
    3.6e-15 N m from one library and exactly 0 from the other read as a relative
    error of 1; review 19). ``b`` is
    taken in ``a``'s shape when they hold the same number of entries (a one-joint
    arm's Jacobian: 6 x 1 here, 6 from another library); NumPy's broadcasting of
    6 x 1 against 6 compared every row with every other (3.16 on a right model)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        if a.size != b.size:
            raise ValueError(f"cannot compare a {a.shape} array with a {b.shape} array")
        b = b.reshape(a.shape)
    scale = max(float(np.linalg.norm(b)), floor)
    return float(np.linalg.norm(a - b) / scale) if scale > 0 else float(np.linalg.norm(a - b))


def random_states(robot, samples: int, seed: int = 0):
    """``samples`` seeded (q, dq, tau): q uniform within the position limits
    (+-pi where a joint has none; +-0.5 m for an unlimited prismatic joint), dq
    uniform in +-2 rad/s (or m/s), tau uniform in +-10 N m."""
    rng = np.random.default_rng(seed)
    n = robot.n
    lo, hi = robot.q_min.copy(), robot.q_max.copy()
    prismatic = np.array(robot.prismatic, dtype=bool)
    span = np.where(prismatic, 0.5, math.pi)
    lo = np.where(np.isfinite(lo), lo, -span)
    hi = np.where(np.isfinite(hi), hi, span)
    for _ in range(samples):
        yield rng.uniform(lo, hi), rng.uniform(-2, 2, n), rng.uniform(-10, 10, n)


def check_robot(robot, samples: int = 20, seed: int = 0, pinocchio: bool = True) -> RobotCheck:
    """Evaluate the identities (see the module docstring) at ``samples`` seeded
    random states; compare with Pinocchio if ``pinocchio`` and it is importable."""
    f = robot.functions
    n = robot.n
    q, dq = ca.SX.sym("q", n), ca.SX.sym("dq", n)
    M = f.mass_matrix(q)
    bias, grav = f.bias(q, dq), f.gravity(q)
    Cdq = bias - grav
    Mdot = ca.jtimes(M, q, dq)
    Mdot_quad = ca.dot(dq, Mdot @ dq)
    # the residual's scale is that of the quantities it is computed from (C dq is the difference of
    # the bias and the gravity torque, each of which may be far larger than their difference): the
    # rounding of the terms, not their sum, which the identity makes small or zero; and a floor of the
    # arm's own size (|M| |dq|^3, the order of dq^T Mdot dq), where every term vanishes (a mass on its axis)
    adq = ca.fabs(dq)
    scale = (ca.dot(adq, ca.fabs(Mdot) @ adq) + 2 * ca.dot(adq, ca.fabs(bias) + ca.fabs(grav))
             + ca.norm_fro(M) * ca.norm_2(dq) ** 3)
    energy = ca.Function("energy_identity", [q, dq], [Mdot_quad - 2 * ca.dot(dq, Cdq), scale],
                         ["q", "dq"], ["residual", "scale"])
    p = f.fk(q)[:3, 3]
    dpdq = ca.Function("dpdq", [q], [ca.jacobian(p, q)], ["q"], ["dp_dq"])

    worst = {k: 0.0 for k in ("sym", "energy", "idfd", "jfk")}
    min_eig = math.inf
    ref = None
    reference = "not compared"
    if pinocchio:
        try:
            ref = pinocchio_model(robot)
            import pinocchio as pin
            reference = f"pinocchio {pin.__version__}"
        except ImportError:
            reference = "not compared (pinocchio not installed)"
        except NotImplementedError as exc:
            reference = f"not compared ({exc})"
    pworst = {k: 0.0 for k in ("M", "bias", "g", "J", "fk", "aba")}
    for qi, dqi, taui in random_states(robot, samples, seed):
        Mi = robot.mass_matrix(qi)
        worst["sym"] = max(worst["sym"], _rel(Mi, Mi.T))
        min_eig = min(min_eig, float(np.linalg.eigvalsh(0.5 * (Mi + Mi.T))[0]))
        r, s = (float(v) for v in energy(qi, dqi))
        worst["energy"] = max(worst["energy"], abs(r) / s if s > 0 else abs(r))
        ddq = robot.forward_dynamics(qi, dqi, taui)
        worst["idfd"] = max(worst["idfd"], _rel(robot.inverse_dynamics(qi, dqi, ddq), taui))
        worst["jfk"] = max(worst["jfk"], _rel(robot.jacobian(qi)[:3], np.array(dpdq(qi))))
        if ref is not None:
            got = ref(qi, dqi, taui)
            ours_rnea = robot.inverse_dynamics(qi, dqi, got["aba"]) - robot.friction(dqi)
            pworst["M"] = max(pworst["M"], _rel(Mi, got["M"]))
            # a torque's natural size where the bias or gravity vanishes: what the arm's inertia gives at an
            # acceleration of 9.81 rad/s^2 plus |dq|^2 (gravity at ~1 m reach, the velocity terms' order)
            floor = float(np.linalg.norm(Mi)) * (9.81 + float(dqi @ dqi))
            pworst["bias"] = max(pworst["bias"], _rel(robot.bias(qi, dqi), got["bias"], floor))
            pworst["g"] = max(pworst["g"], _rel(robot.gravity(qi), got["g"], floor))
            pworst["J"] = max(pworst["J"], _rel(robot.jacobian(qi), got["J"]))
            pworst["fk"] = max(pworst["fk"], _rel(robot.fk(qi), got["fk"]))
            pworst["aba"] = max(pworst["aba"], _rel(ours_rnea, taui))
    tol = TOLERANCE
    ids = [Identity("M symmetric", worst["sym"], tol, worst["sym"] <= tol),
           Identity("M positive definite (smallest eigenvalue)", min_eig, 0.0, min_eig > 0),
           Identity("energy: dq^T (Mdot - 2C) dq = 0", worst["energy"], tol, worst["energy"] <= tol),
           Identity("inverse_dynamics(forward_dynamics(tau)) = tau", worst["idfd"], tol, worst["idfd"] <= tol),
           Identity("J linear rows = d fk / dq", worst["jfk"], tol, worst["jfk"] <= tol)]
    if ref is not None:
        for key, label in (("M", "M = Pinocchio crba"), ("bias", "bias = Pinocchio rnea(q, dq, 0)"),
                           ("g", "g = Pinocchio gravity"), ("J", "J = Pinocchio frame Jacobian"),
                           ("fk", "fk = Pinocchio frame placement"),
                           ("aba", "RNEA(q, dq, Pinocchio ABA(q, dq, tau)) = tau")):
            ids.append(Identity(label, pworst[key], tol, pworst[key] <= tol))
    return RobotCheck(identities=tuple(ids), samples=samples, seed=seed, reference=reference)


def pinocchio_model(robot):
    """An evaluator ``(q, dq, tau) -> dict(M, bias, g, J, fk, aba)`` built with
    Pinocchio, independent of tmtcontrol's algorithms.

    Raises
    ------
    ImportError
        Pinocchio is not installed.
    NotImplementedError
        Pinocchio's URDF parser (urdfdom) refuses a file tmtcontrol reads (a
        tab between two numbers).

    A base below the URDF's root (fixed to it, ``Chain.up``) is Pinocchio's
    frame of that link: the joints above it held, ``fk`` and ``J`` turned
    into its coordinates, gravity Pinocchio's own along the root's -z (review
    69: the reference was skipped there, and the gravity it would have
    caught was the base link's -z).
    """
    import pinocchio as pin

    if robot.chain is None:
        model, tip = _puma_pinocchio(robot)
    else:
        try:
            model = pin.buildModelFromXML(robot.urdf)
        except (ValueError, RuntimeError) as exc:    # urdfdom is stricter (a tab between numbers; review 19)
            raise NotImplementedError(f"Pinocchio's URDF parser refuses the file: {' '.join(str(exc).split())}") \
                from None
        qref = pin.neutral(model)
        lock = []
        for jid in range(1, model.njoints):
            name = model.names[jid]
            if name in robot.joint_names:
                continue
            value = robot.held.get(name, 0.0)
            idx, nq = model.joints[jid].idx_q, model.joints[jid].nq
            qref[idx:idx + nq] = [math.cos(value), math.sin(value)] if nq == 2 else [value]
            lock.append(jid)
        if lock:
            model = pin.buildReducedModel(model, lock, qref)
        if [model.names[i] for i in range(1, model.njoints)] != list(robot.joint_names):
            raise NotImplementedError("Pinocchio's joint order differs from the chain's")
        if robot.mass_scale != 1.0:
            s = robot.mass_scale
            for i in range(model.njoints):
                I = model.inertias[i]
                model.inertias[i] = pin.Inertia(I.mass * s, I.lever, I.inertia * s)
        if robot.armature is not None:
            model.armature = np.asarray(robot.armature, float)
        tip = model.getFrameId(robot.tip)
    data = model.createData()
    # the base's placement in Pinocchio's world (the root; identity when the base is the root): constant, every
    # joint above the base being held
    base_in_world = np.eye(4)
    if robot.chain is not None:
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        base_in_world = data.oMf[model.getFrameId(robot.base)].homogeneous.copy()
    to_base = np.linalg.inv(base_in_world)
    R_wb = base_in_world[:3, :3]
    nqs = [model.joints[i].nq for i in range(1, model.njoints)]

    def to_pin(q):
        out = []
        for qi, nq in zip(q, nqs):
            out += [math.cos(qi), math.sin(qi)] if nq == 2 else [qi]
        return np.array(out)

    def evaluate(q, dq, tau):
        qp = to_pin(q)
        M = pin.crba(model, data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.rnea(model, data, qp, dq, np.zeros(len(dq))).copy()
        g = pin.computeGeneralizedGravity(model, data, qp).copy()
        pin.framesForwardKinematics(model, data, qp)
        fk = to_base @ data.oMf[tip].homogeneous
        J = pin.computeFrameJacobian(model, data, qp, tip, pin.LOCAL_WORLD_ALIGNED).copy()
        J[:3], J[3:] = R_wb.T @ J[:3], R_wb.T @ J[3:]
        aba = pin.aba(model, data, qp, dq, tau).copy()
        return {"M": M, "bias": bias, "g": g, "J": J, "fk": fk, "aba": aba}

    return evaluate


def _puma_pinocchio(robot):
    """The PUMA's links 1-3 as a Pinocchio model from the DH parameters."""
    import pinocchio as pin

    from .puma560 import GRAVITY, WRIST_OFFSET

    model = pin.Model()
    model.gravity = pin.Motion(np.array([0, 0, -GRAVITY, 0, 0, 0]))
    parent, placement = 0, pin.SE3.Identity()
    arm = []
    for i, link in enumerate(robot.links):
        jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        # frame i relative to the joint frame (frame i-1 rotated by q): Tz(d) Tx(a) Rx(alpha)
        dh = pin.SE3(pin.utils.rpyToMatrix(link.alpha, 0, 0), np.array([link.a, 0, link.d]))
        body = pin.Inertia(link.m, np.array(link.r), np.diag(link.I))
        model.appendBodyToJoint(jid, dh.act(body), pin.SE3.Identity())
        arm.append(link.G ** 2 * link.Jm)
        parent, placement = jid, dh
    tip = model.addFrame(pin.Frame("wrist_centre", parent, 0,
                                   placement * pin.SE3(np.eye(3), np.array([0, 0, WRIST_OFFSET])),
                                   pin.FrameType.OP_FRAME))
    model.armature = np.array(arm) * (1.0 if np.any(robot.armature) else 0.0)
    return model, tip


def describe(robot, check: RobotCheck | None = None) -> str:
    """The chain as text: joints with limits and moving masses, total mass,
    reach, tip frame, held joints, and the identities' results."""
    lines = [f"robot {robot.name} ({robot.source}): {robot.n} actuated joints, base {robot.base!r}, "
             f"tip {robot.tip!r}"]
    bodies = robot.chain.bodies if robot.chain is not None else None
    masses = list(robot.link_masses.values())
    kinds = [j.type for j in robot.chain.joints] if robot.chain is not None else ["revolute"] * robot.n
    lines.append(f"  {'joint':<24} {'type':<10} {'q_min':>9} {'q_max':>9} {'dq_max':>8} {'tau_max':>8} "
                 f"{'mass kg':>8}")
    for i, name in enumerate(robot.joint_names):
        m = bodies[i].mass if bodies is not None else masses[i]
        lines.append(f"  {name:<24} {kinds[i]:<10} {_num(robot.q_min[i]):>9} {_num(robot.q_max[i]):>9} "
                     f"{_num(robot.dq_max[i]):>8} {_num(robot.tau_max[i]):>8} {m:>8.4g}")
    lines.append("  units: rad, rad/s, N m (m, m/s, N for prismatic joints); mass moved by each joint "
                 "(its link and everything fixed to it)")
    lines.append(f"  total mass {robot.total_mass:.4g} kg (moving {robot.moving_mass:.4g} kg); "
                 f"reach {robot.reach():.4g} m (sum of the link offsets from joint 1)")
    T = robot.fk(np.zeros(robot.n))
    lines.append(f"  tip {robot.tip!r} at q = 0: position [{', '.join(f'{v:.4f}' for v in T[:3, 3])}] m "
                 f"in {robot.base!r}")
    if robot.held:
        lines.append("  held (not actuated): " + ", ".join(f"{k} = {v:g}" for k, v in robot.held.items()))
    try:                        # what the closed loop controls on this arm (review 32: said for an unusable one)
        task = robot.task
        lines.append(f"  closed loop: a {task.dim}-axis task ({task.words})")
    except ValueError as exc:
        lines.append(f"  closed loop: none: {exc}; simulate and every loop command refuse this arm")
    if check is not None:
        lines.append(f"checks at {check.samples} random states (seed {check.seed}); reference: {check.reference}")
        for ident in check.identities:
            verdict = "ok  " if ident.ok else "FAIL"
            bound = f"> {ident.limit:g}" if "definite" in ident.name else f"<= {ident.limit:g}"
            lines.append(f"  {verdict} {ident.name:<50} {ident.worst:.3g} ({bound})")
        lines.append("all checks pass" if check.ok else "FAIL: a check does not hold")
    return "\n".join(lines)


def _num(x: float) -> str:
    return "none" if not np.isfinite(x) else f"{x:.4g}"
