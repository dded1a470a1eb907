"""Symbolic model of the first three links of the PUMA 560 (CasADi), eq. (1).

The paper's simulation study (section V) uses "a three link rotary robot
representing the first three links of the puma 560 arm". This module builds
that robot symbolically with CasADi ``SX`` and exposes named
:class:`casadi.Function` objects for kinematics, joint-space dynamics and the
Cartesian form of eq. (1)::

    D*(q) Xdd + h*(q, dq) + F_f* = F - F_e                          (1)

Conventions (SI units throughout: m, rad, kg, N, N m, s):

* standard Denavit-Hartenberg frames, base at the floor, gravity 9.81 m/s^2
  along -z of the base frame;
* the end-effector point is the wrist centre, 0.4318 m along z of frame 3;
* joint space: ``M(q) ddq + C(q, dq) dq + g(q) + tau_f(dq) = tau``;
* Cartesian space (X = fk(q), the wrist centre in the base frame):
  ``D* = J^-T M J^-1`` and ``h* = J^-T (C dq + g) - D* Jdot dq``, so gravity
  sits in h*; friction is kept apart as ``F_f* = J^-T tau_f``.

Two independent derivations are built: Euler-Lagrange (mass matrix from the
link Jacobians, Coriolis from Christoffel symbols, gravity from the potential
energy) is the model used everywhere; recursive Newton-Euler (``rnea``) is an
independent implementation used to check it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca

__all__ = ["LinkParameters", "PUMA560_LINKS", "GRAVITY", "WRIST_OFFSET", "Puma560"]

GRAVITY = 9.81
"""Magnitude of gravity, m/s^2, acting along -z of the base frame."""

WRIST_OFFSET = 0.4318
"""Distance of the wrist centre along z of frame 3, m (d4 of the PUMA 560)."""


@dataclass(frozen=True)
class LinkParameters:
    """Standard-DH kinematic and dynamic parameters of one revolute link.

    Attributes
    ----------
    d, a : float
        DH offset along z_{i-1} and length along x_i, m.
    alpha : float
        DH twist about x_i, rad.
    m : float
        Link mass, kg.
    r : tuple of float
        Centre of mass in link frame i, m.
    I : tuple of float
        Principal inertia about the centre of mass, in frame i (Ixx, Iyy, Izz),
        kg m^2.
    Jm : float
        Motor rotor inertia (motor side), kg m^2.
    G : float
        Gear ratio (motor/joint, signed).
    B : float
        Viscous friction (motor side), N m s/rad.
    Tc : tuple of float
        Coulomb friction (motor side) for positive and negative motor velocity, N m.
    """

    d: float
    a: float
    alpha: float
    m: float
    r: tuple[float, float, float]
    I: tuple[float, float, float]
    Jm: float
    G: float
    B: float
    Tc: tuple[float, float]


# Corke & Armstrong-Helouvry (1994), "A search for consensus among model
# parameters reported for the PUMA 560 robot", ICRA; the set shipped by the
# Robotics Toolbox (mdl_puma560 / models.DH.Puma560), links 1-3.
PUMA560_LINKS: tuple[LinkParameters, ...] = (
    LinkParameters(0.67183, 0.0, math.pi / 2, 0.0, (0.0, 0.0, 0.0), (0.0, 0.35, 0.0),
                   200e-6, -62.6111, 1.48e-3, (0.395, -0.435)),
    LinkParameters(0.0, 0.4318, 0.0, 17.4, (-0.3638, 0.006, 0.2275), (0.13, 0.524, 0.539),
                   200e-6, 107.815, 0.817e-3, (0.126, -0.071)),
    LinkParameters(0.15005, 0.0203, -math.pi / 2, 4.8, (-0.0203, -0.0141, 0.070),
                   (0.066, 0.086, 0.0125), 200e-6, -53.7063, 1.38e-3, (0.132, -0.105)),
)


def _dh(theta, link: LinkParameters):
    """Standard DH homogeneous transform A_i(theta) from frame i-1 to frame i."""
    ct, st = ca.cos(theta), ca.sin(theta)
    # a twist of +-90 deg has cos = 6.1e-17 in floating point: taken as the
    # exact 0 it is, so constant folding drops every term it multiplies
    ca_, sa = (0.0 if abs(v) < 1e-15 else v for v in (math.cos(link.alpha), math.sin(link.alpha)))
    return ca.vertcat(
        ca.horzcat(ct, -st * ca_, st * sa, link.a * ct),
        ca.horzcat(st, ct * ca_, -ct * sa, link.a * st),
        ca.horzcat(0, sa, ca_, link.d),
        ca.horzcat(0, 0, 0, 1),
    )


class Puma560:
    """Links 1-3 of the PUMA 560 as named CasADi Functions.

    Parameters
    ----------
    armature : bool
        Add the joint-side rotor inertia ``G^2 Jm`` to the diagonal of M.
    friction : bool or {"smooth"}
        ``True``: exact joint friction ``|G| (B |G| dq + Tc)`` with Tc+ for
        dq > 0, Tc- for dq < 0 and 0 at dq = 0. ``"smooth"``: the same with the
        Coulomb step replaced by ``tanh(dq/v) (Tc+ (1+tanh)/2 - Tc- (1-tanh)/2)``
        (C-infinity, suitable for fixed-step integration). ``False``: none.
    coulomb_velocity : float
        Joint velocity scale ``v`` of the smooth Coulomb variant, rad/s.
    links : tuple of LinkParameters
        Parameter set; defaults to :data:`PUMA560_LINKS`.

    Attributes
    ----------
    fk : casadi.Function
        ``["q"] -> ["p"]`` wrist-centre position in the base frame, m.
    jacobian : casadi.Function
        ``["q"] -> ["J"]``, J = dp/dq.
    jacobian_dot : casadi.Function
        ``["q","dq"] -> ["Jdot_dq"]``, the bias acceleration dJ/dt dq, m/s^2.
    mass_matrix, coriolis, coriolis_matrix, gravity : casadi.Function
        ``M(q)``, ``C(q, dq) dq``, ``C(q, dq)`` (Christoffel), ``g(q)``.
    friction, smooth_friction : casadi.Function
        ``["dq"] -> ["tau_f"]``, joint friction torque (zeros when disabled).
    inverse_dynamics, forward_dynamics : casadi.Function
        ``["q","dq","ddq"] -> ["tau"]`` (Lagrangian M, C, g) and
        ``["q","dq","tau"] -> ["ddq"]`` (Lagrangian M; the bias ``C dq + g``
        from the Newton-Euler recursion, which is ~15x cheaper).
    bias : casadi.Function
        ``["q","dq"] -> ["n"]``, ``C dq + g`` by Newton-Euler.
    rnea : casadi.Function
        Recursive Newton-Euler inverse dynamics (independent check).
    cartesian_inertia, cartesian_bias, cartesian_friction : casadi.Function
        D*(q), h*(q, dq) and F_f*(q, dq) of eq. (1).
    condition_number, manipulability : casadi.Function
        ``["q"] -> ["cond"]`` (Frobenius-norm condition number of J) and
        Yoshikawa's ``|det J|``.
    energy : casadi.Function
        ``["q","dq"] -> ["T","V"]`` kinetic and potential energy, J.
    """

    n = 3

    def __init__(self, armature: bool = True, friction: bool | str = True,
                 coulomb_velocity: float = 1e-2,
                 links: tuple[LinkParameters, ...] = PUMA560_LINKS):
        if friction not in (True, False, "smooth"):
            raise ValueError(f"friction: expected True, False or 'smooth', got {friction!r}")
        if not coulomb_velocity > 0:
            raise ValueError(f"coulomb_velocity: must be > 0, got {coulomb_velocity!r}")
        self.armature = bool(armature)
        self.friction_model = friction
        self.links = links
        q = ca.SX.sym("q", 3)
        dq = ca.SX.sym("dq", 3)
        ddq = ca.SX.sym("ddq", 3)
        tau = ca.SX.sym("tau", 3)
        self.q, self.dq, self.ddq, self.tau = q, dq, ddq, tau
        self._coulomb_velocity = coulomb_velocity
        # kinematics now (the simulator's path check needs nothing else); the
        # dynamics on first use of any of their attributes (_DYNAMICS)
        self._frame_list = self._frames(q)
        self._p = (self._frame_list[-1] @ ca.vertcat(0, 0, WRIST_OFFSET, 1))[:3]
        self._J = ca.jacobian(self._p, q)
        self.fk = ca.Function("fk", [q], [self._p], ["q"], ["p"])
        self.jacobian = ca.Function("jacobian", [q], [self._J], ["q"], ["J"])
        self.condition_number = ca.Function(
            "condition_number", [q], [ca.norm_fro(self._J) * ca.norm_fro(ca.inv(self._J))], ["q"], ["cond"])
        self.manipulability = ca.Function("manipulability", [q], [ca.fabs(ca.det(self._J))], ["q"], ["w"])

    _DYNAMICS = frozenset({
        "expr", "jacobian_dot", "mass_matrix", "coriolis", "coriolis_matrix", "gravity", "bias", "friction",
        "smooth_friction", "inverse_dynamics", "forward_dynamics", "rnea", "cartesian_inertia",
        "cartesian_bias", "cartesian_friction", "energy"})
    """Attributes built together on first access (about 15 ms of symbolic work)."""

    def __getattr__(self, name):
        if name in Puma560._DYNAMICS:
            self._build_dynamics()
            return self.__dict__[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _build_dynamics(self) -> None:
        q, dq, ddq, tau = self.q, self.dq, self.ddq, self.tau
        friction, coulomb_velocity = self.friction_model, self._coulomb_velocity
        frames, p, J = self._frame_list, self._p, self._J

        M = self._mass_matrix_expr(q, frames)
        V = self._potential_expr(frames)
        g = ca.gradient(V, q)
        C = self._christoffel(M, q, dq)
        tau_f_exact = self._friction_expr(dq, smooth=False, v=coulomb_velocity)
        tau_f_smooth = self._friction_expr(dq, smooth=True, v=coulomb_velocity)
        tau_f = {True: tau_f_exact, "smooth": tau_f_smooth, False: ca.SX.zeros(3)}[friction]
        if friction is False:
            tau_f_smooth = ca.SX.zeros(3)
        Cdq = C @ dq
        # The bias n(q, dq) = C dq + g from the Newton-Euler recursion with
        # ddq = 0: equal to the Christoffel form (tests: 1e-12) and ~15x
        # fewer operations, so forward dynamics and h* use it.
        bias = self._rnea_expr(q, dq, ca.SX.zeros(3), frames, armature=False)
        # Joint 1 turns about the vertical base axis, parallel to gravity, so the
        # joint-space dynamics do not depend on q1: M, C, g and n are evaluated
        # at q1 = 0, where the constant folding removes a third of the
        # operations (identical to 1e-14 with the full expressions, tested).
        at_q1_zero = ca.vertcat(0, q[1], q[2])
        M, C, g, bias = (ca.substitute(e, q, at_q1_zero) for e in (M, C, g, bias))

        # Cartesian form, eq. (1): D* Xdd + h* + F_f* = F - F_e
        Jinv = ca.inv(J)
        D = Jinv.T @ M @ Jinv
        Jdot_dq = ca.jacobian(J @ dq, q) @ dq
        h = Jinv.T @ bias - D @ Jdot_dq

        self.expr = {"p": p, "J": J, "M": M, "C": C, "Cdq": Cdq, "g": g, "tau_f": tau_f,
                     "bias": bias,
                     "D": D, "h": h, "Jdot_dq": Jdot_dq, "V": V}
        self.jacobian_dot = ca.Function("jacobian_dot", [q, dq], [Jdot_dq], ["q", "dq"],
                                        ["Jdot_dq"])
        self.mass_matrix = ca.Function("mass_matrix", [q], [M], ["q"], ["M"])
        self.coriolis = ca.Function("coriolis", [q, dq], [Cdq], ["q", "dq"], ["Cdq"])
        self.coriolis_matrix = ca.Function("coriolis_matrix", [q, dq], [C], ["q", "dq"], ["C"])
        self.gravity = ca.Function("gravity", [q], [g], ["q"], ["g"])
        self.bias = ca.Function("bias", [q, dq], [bias], ["q", "dq"], ["n"])
        self.friction = ca.Function("friction", [dq], [tau_f], ["dq"], ["tau_f"])
        self.smooth_friction = ca.Function("smooth_friction", [dq], [tau_f_smooth],
                                           ["dq"], ["tau_f"])
        tau_id = M @ ddq + Cdq + g + tau_f
        self.inverse_dynamics = ca.Function("inverse_dynamics", [q, dq, ddq], [tau_id],
                                            ["q", "dq", "ddq"], ["tau"])
        ddq_fd = ca.solve(M, tau - bias - tau_f)
        self.forward_dynamics = ca.Function("forward_dynamics", [q, dq, tau], [ddq_fd],
                                            ["q", "dq", "tau"], ["ddq"])
        self.rnea = ca.Function("rnea", [q, dq, ddq],
                                [self._rnea_expr(q, dq, ddq, frames) + tau_f],
                                ["q", "dq", "ddq"], ["tau"])
        self.cartesian_inertia = ca.Function("cartesian_inertia", [q], [D], ["q"], ["D"])
        self.cartesian_bias = ca.Function("cartesian_bias", [q, dq], [h], ["q", "dq"], ["h"])
        self.cartesian_friction = ca.Function("cartesian_friction", [q, dq], [Jinv.T @ tau_f],
                                              ["q", "dq"], ["F_f"])
        self.energy = ca.Function("energy", [q, dq], [0.5 * ca.dot(dq, M @ dq), V],
                                  ["q", "dq"], ["T", "V"])

    def inverse_kinematics(self, p, shoulder: int = 1, elbow: int = 1):
        """Joint angles (rad) placing the wrist centre at ``p`` (m), in closed form.

        ``p`` is one point (3,) or a path (3, n); the result has the same shape.
        The wrist centre lies at the lateral offset ``d3`` (link 3's DH d) from
        the vertical plane of the upper arm and forearm, which gives
        ``px sin q1 - py cos q1 = d3`` for q1; the arm in that plane is a
        two-link arm of lengths ``a2`` and ``sqrt(a3^2 + d4^2)``. ``shoulder``
        and ``elbow`` (+1 or -1) choose among the four solutions; the default
        (+1, +1) is the posture of the paper's path (upper arm raised in front
        of the base, q2 < 0 < q3). Raises ``ValueError`` naming the first
        unreachable point."""
        import numpy as np

        if shoulder not in (1, -1) or elbow not in (1, -1):
            raise ValueError(f"shoulder, elbow: expected +1 or -1, got {shoulder!r}, {elbow!r}")
        P = np.asarray(p, dtype=float)
        pts = P.reshape(3, -1)
        px, py, pz = pts
        l1, l2, l3 = self.links
        d1, a2, d3, a3, d4 = l1.d, l2.a, l3.d, l3.a, WRIST_OFFSET
        r = np.hypot(px, py)
        lw, psi = math.hypot(a3, d4), math.atan2(d4, a3)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):     # far points: refused below
            s = np.arcsin(d3 / r)
            q1 = np.arctan2(py, px) + (s if shoulder > 0 else np.pi - s)
            x = np.cos(q1) * px + np.sin(q1) * py
            y = pz - d1
            cb = (x * x + y * y - a2 * a2 - lw * lw) / (2 * a2 * lw)
        bad = ~(np.isfinite(q1) & (np.abs(cb) <= 1.0))
        if bad.any():
            target = np.round(pts[:, int(np.argmax(bad))], 4)
            raise ValueError(f"point {target.tolist()} m is outside the workspace")
        beta = elbow * np.arccos(cb)
        q2 = np.arctan2(y, x) - np.arctan2(lw * np.sin(beta), a2 + lw * np.cos(beta))
        q = np.vstack([q1, q2, beta - psi])
        q = (q + np.pi) % (2 * np.pi) - np.pi
        return q.reshape(P.shape)

    # -- derivation helpers ------------------------------------------------
    def _frames(self, q):
        """Base-to-frame-i transforms T_0^i, i = 1..3."""
        T = ca.SX.eye(4)
        frames = []
        for i, link in enumerate(self.links):
            T = T @ _dh(q[i], link)
            frames.append(T)
        return frames

    def _com(self, T, link):
        return (T @ ca.vertcat(*link.r, 1))[:3]

    def _mass_matrix_expr(self, q, frames):
        """M(q) = sum m Jv^T Jv + Jw^T R I R^T Jw (+ armature), Euler-Lagrange."""
        M = ca.SX.zeros(3, 3)
        for i, (T, link) in enumerate(zip(frames, self.links)):
            R = T[:3, :3]
            Jv = ca.jacobian(self._com(T, link), q)
            Jw = ca.SX.zeros(3, 3)
            for j in range(i + 1):
                Jw[:, j] = self._joint_axis(frames, j)
            Ic = R @ ca.diag(ca.vertcat(*link.I)) @ R.T
            M += link.m * Jv.T @ Jv + Jw.T @ Ic @ Jw
        if self.armature:
            M += ca.diag(ca.vertcat(*[l.G ** 2 * l.Jm for l in self.links]))
        return M

    @staticmethod
    def _joint_axis(frames, j):
        """z_{j}-1 axis of joint j (0-based) in the base frame."""
        return ca.vertcat(0, 0, 1) if j == 0 else frames[j - 1][:3, 2]

    def _potential_expr(self, frames):
        return sum(link.m * GRAVITY * self._com(T, link)[2]
                   for T, link in zip(frames, self.links))

    @staticmethod
    def _christoffel(M, q, dq):
        """C(q, dq) with C_ij = sum_k c_ijk dq_k (Christoffel symbols of M)."""
        n = q.shape[0]
        dM = [ca.jacobian(M[:, j], q) for j in range(n)]  # dM[j][i, k] = dM_ij/dq_k
        C = ca.SX.zeros(n, n)
        for i in range(n):
            for j in range(n):
                C[i, j] = sum(0.5 * (dM[j][i, k] + dM[k][i, j] - dM[k][j, i]) * dq[k]
                              for k in range(n))
        return C

    def _friction_expr(self, dq, smooth, v):
        out = []
        for i, link in enumerate(self.links):
            tcp, tcn = link.Tc
            if smooth:
                s = ca.tanh(dq[i] / v)
                coulomb = s * (tcp * (1 + s) / 2 - tcn * (1 - s) / 2)
            else:
                coulomb = ca.if_else(dq[i] > 0, tcp, ca.if_else(dq[i] < 0, tcn, 0))
            out.append(abs(link.G) * (link.B * abs(link.G) * dq[i] + coulomb))
        return ca.vertcat(*out)

    def _rnea_expr(self, q, dq, ddq, frames, armature=True):
        """Recursive Newton-Euler in the base frame (no friction).

        Forward pass: angular velocity/acceleration of each link, linear
        acceleration of each frame origin and link COM, with gravity entering as
        an upward acceleration of the base. Backward pass: force and moment at
        each joint; tau_i = z_{i-1} . n_i, plus armature G^2 Jm ddq_i.
        """
        n = len(self.links)
        origins = [ca.SX.zeros(3)] + [T[:3, 3] for T in frames]
        w = ca.SX.zeros(3)
        wd = ca.SX.zeros(3)
        a_o = ca.vertcat(0, 0, GRAVITY)
        kin = []
        for i, (T, link) in enumerate(zip(frames, self.links)):
            z = self._joint_axis(frames, i)
            wd = wd + z * ddq[i] + ca.cross(w, z * dq[i])
            w = w + z * dq[i]
            dp = origins[i + 1] - origins[i]
            a_o = a_o + ca.cross(wd, dp) + ca.cross(w, ca.cross(w, dp))
            c = self._com(T, link)
            rc = c - origins[i + 1]
            a_c = a_o + ca.cross(wd, rc) + ca.cross(w, ca.cross(w, rc))
            R = T[:3, :3]
            Ic = R @ ca.diag(ca.vertcat(*link.I)) @ R.T
            kin.append((z, w, wd, c, a_c, Ic))
        f_next = ca.SX.zeros(3)
        n_next = ca.SX.zeros(3)
        tau = [None] * n
        for i in reversed(range(n)):
            z, w, wd, c, a_c, Ic = kin[i]
            link = self.links[i]
            F = link.m * a_c
            n_i = (n_next + ca.cross(origins[i + 1] - origins[i], f_next)
                   + ca.cross(c - origins[i], F) + Ic @ wd + ca.cross(w, Ic @ w))
            f_next = f_next + F
            n_next = n_i
            tau[i] = ca.dot(z, n_i)
            if self.armature and armature:
                tau[i] += link.G ** 2 * link.Jm * ddq[i]
        return ca.vertcat(*tau)
