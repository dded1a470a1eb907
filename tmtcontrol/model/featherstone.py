"""Rigid-body algorithms on a URDF chain in CasADi SX: eq. (1) for any serial arm.

Featherstone's algorithms (R. Featherstone, *Rigid Body Dynamics Algorithms*,
Springer 2008) over the :class:`~tmtcontrol.model.urdf.Chain` parsed by
:mod:`.urdf`, written with 3-vectors in each body's own frame:

* forward kinematics: ``T_0^i = T_0^{i-1} X_tree_i X_J(q_i)``; the tip pose
  and its geometric Jacobian (linear rows first, base axes);
* the recursive Newton-Euler algorithm (RNEA, Featherstone's table 5.1):
  ``tau = M(q) ddq + C(q, dq) dq + g(q)`` with gravity 9.81 m/s^2 along -z of
  the URDF's root link (the base frame's -z when the base is the root;
  ``Chain.up``) entering as an upward acceleration of the base;
* the composite rigid body algorithm (CRBA, table 6.2) for ``M(q)``.

Why not a library: Pinocchio's wheel has no CasADi bindings, and
adam-robotics 0.5.0 (whose CasADi backend builds these algorithms from a URDF)
needs the ``liecasadi`` package its CasADi extra does not install, models a
floating base only (an (n+6) x (n+6) mass matrix), and raised a dimension
error in its CRBA on the Panda URDF (its prismatic, mimic finger joints). The
results are checked against Pinocchio to 1e-10 in the tests.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .urdf import Chain

__all__ = ["GRAVITY", "build_expressions"]

GRAVITY = 9.81
"""Magnitude of gravity, m/s^2, along -z of the URDF's root link (``Chain.up``
in the base frame: -z of the base when the base is the root)."""


def _const(A) -> ca.SX:
    """A numeric matrix as SX, entries below 1e-15 in magnitude set to the exact
    zero they stand for (cos of a right angle), so constant folding drops them."""
    A = np.where(np.abs(np.asarray(A, dtype=float)) < 1e-15, 0.0, A)
    return ca.SX(ca.DM(A))


def _rot(axis, angle) -> ca.SX:
    """Rotation by ``angle`` about the unit ``axis`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    c, s = ca.cos(angle), ca.sin(angle)
    if np.count_nonzero(a) == 1:          # a coordinate axis: the usual sparse rotation
        i = int(np.flatnonzero(a)[0])
        sgn = float(np.sign(a[i]))
        j, k = (i + 1) % 3, (i + 2) % 3
        R = ca.SX.zeros(3, 3)
        R[i, i] = 1
        R[j, j] = c
        R[k, k] = c
        R[k, j] = sgn * s
        R[j, k] = -sgn * s
        return R
    K = _const([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return ca.SX.eye(3) + s * K + (1 - c) * (K @ K)


def _joint(j, qi):
    """Rotation E (joint frame -> child, as R) and translation of joint ``j`` at ``qi``."""
    if j.type == "prismatic":
        return ca.SX.eye(3), _const(j.axis) * qi
    return _rot(j.axis, qi), ca.SX.zeros(3)


def build_expressions(chain: Chain, q, dq, ddq) -> dict:
    """SX expressions of the chain's kinematics and dynamics.

    Returns a dict with ``T`` (4 x 4 tip pose in the base frame), ``J``
    (6 x n, linear rows first, base axes), ``M`` (CRBA), ``bias``
    (``C dq + g``, RNEA with ddq = 0), ``g`` (RNEA with dq = ddq = 0) and
    ``rnea`` (``M ddq + C dq + g``). No friction or armature (added by the
    caller).
    """
    n = len(chain.joints)
    # placements: parent body -> body i, as rotation R_i and origin p_i in the parent's frame
    Rs, ps = [], []
    for i, j in enumerate(chain.joints):
        Rj, pj = _joint(j, q[i])
        Rt, pt = _const(j.R), _const(j.p)
        Rs.append(Rt @ Rj)
        ps.append(Rt @ pj + pt)
    # forward kinematics
    R0, p0 = [], []
    R, p = ca.SX.eye(3), ca.SX.zeros(3)
    for i in range(n):
        p = R @ ps[i] + p
        R = R @ Rs[i]
        R0.append(R)
        p0.append(p)
    if chain.tip_body < 0:
        Rb, pb = ca.SX.eye(3), ca.SX.zeros(3)
    else:
        Rb, pb = R0[chain.tip_body], p0[chain.tip_body]
    R_tip = Rb @ _const(chain.tip_R)
    p_tip = Rb @ _const(chain.tip_p) + pb
    T = ca.vertcat(ca.horzcat(R_tip, p_tip), ca.horzcat(ca.SX.zeros(1, 3), ca.SX.ones(1, 1)))
    J = ca.SX.zeros(6, n)
    for i, j in enumerate(chain.joints):
        if i > chain.tip_body:
            continue
        z = R0[i] @ _const(j.axis)
        if j.type == "prismatic":
            J[:3, i] = z
        else:
            J[:3, i] = ca.cross(z, p_tip - p0[i])
            J[3:, i] = z
    return {"T": T, "J": J, "p": p_tip, "R": R_tip,
            "M": _crba(chain, Rs, ps),
            "bias": _rnea(chain, Rs, ps, dq, ca.SX.zeros(n), GRAVITY),
            "g": _rnea(chain, Rs, ps, ca.SX.zeros(n), ca.SX.zeros(n), GRAVITY),
            "rnea": _rnea(chain, Rs, ps, dq, ddq, GRAVITY)}


def _motion_subspace(j):
    a = _const(j.axis)
    return (ca.SX.zeros(3), a) if j.type == "prismatic" else (a, ca.SX.zeros(3))


def _body_inertia(body):
    """(mass, first moment h = m c, rotational inertia about the body origin)."""
    m, c = body.mass, np.asarray(body.com)
    I_o = np.asarray(body.inertia) + m * (c @ c * np.eye(3) - np.outer(c, c))
    return m, _const(m * c), _const(I_o)


def _rnea(chain, Rs, ps, dq, ddq, gravity):
    """Recursive Newton-Euler in body coordinates (Featherstone table 5.1)."""
    n = len(chain.joints)
    w, v = ca.SX.zeros(3), ca.SX.zeros(3)
    # base acceleration = -gravity: up along the URDF root's +z (Chain.up, base coordinates)
    aw, av = ca.SX.zeros(3), _const(gravity * np.asarray(chain.up, dtype=float))
    forces = []
    for i, j in enumerate(chain.joints):
        E = Rs[i].T                                               # parent coordinates -> body i
        r = ps[i]
        sw, sv = _motion_subspace(j)
        # X_i applied to the parent's velocity and acceleration
        w_p, v_p = E @ w, E @ (v + ca.cross(w, r))
        aw_p, av_p = E @ aw, E @ (av + ca.cross(aw, r))
        w, v = w_p + sw * dq[i], v_p + sv * dq[i]
        # a_i = X a_p + S ddq + v x S dq
        aw = aw_p + sw * ddq[i] + ca.cross(w, sw * dq[i])
        av = av_p + sv * ddq[i] + ca.cross(w, sv * dq[i]) + ca.cross(v, sw * dq[i])
        m, h, I_o = _body_inertia(chain.bodies[i])
        # f = I a + v x* I v, spatial inertia about the body origin
        fl = m * av - ca.cross(h, aw)
        fn = I_o @ aw + ca.cross(h, av)
        pl = m * v - ca.cross(h, w)
        pn = I_o @ w + ca.cross(h, v)
        fl = fl + ca.cross(w, pl)
        fn = fn + ca.cross(w, pn) + ca.cross(v, pl)
        forces.append([fn, fl])
    tau = [None] * n
    for i in reversed(range(n)):
        fn, fl = forces[i]
        sw, sv = _motion_subspace(chain.joints[i])
        tau[i] = ca.dot(sw, fn) + ca.dot(sv, fl)
        if i > 0:                                                # X_i^T f to the parent
            R, r = Rs[i], ps[i]
            pl = R @ fl
            forces[i - 1][1] = forces[i - 1][1] + pl
            forces[i - 1][0] = forces[i - 1][0] + R @ fn + ca.cross(r, pl)
    return ca.vertcat(*tau)


def _crba(chain, Rs, ps):
    """Composite rigid body algorithm (Featherstone table 6.2), 6 x 6 spatial
    inertias [angular; linear] about each body's origin."""
    n = len(chain.joints)
    Ic = []
    for body in chain.bodies:
        m, h, I_o = _body_inertia(body)
        hx = ca.skew(h)
        Ic.append(ca.blockcat([[I_o, hx], [hx.T, m * ca.SX.eye(3)]]))
    X = []                       # motion transforms parent -> body i
    for i in range(n):
        E = Rs[i].T
        X.append(ca.blockcat([[E, ca.SX.zeros(3, 3)], [-E @ ca.skew(ps[i]), E]]))
    S = [ca.vertcat(*_motion_subspace(j)) for j in chain.joints]
    for i in reversed(range(1, n)):
        Ic[i - 1] = Ic[i - 1] + X[i].T @ Ic[i] @ X[i]
    M = ca.SX.zeros(n, n)
    for i in range(n):
        F = Ic[i] @ S[i]
        M[i, i] = ca.dot(S[i], F)
        k = i
        while k > 0:
            F = X[k].T @ F
            k -= 1
            M[i, k] = ca.dot(F, S[k])
            M[k, i] = M[i, k]
    return M
