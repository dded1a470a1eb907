"""Symbolic checks of the paper's derivation, run on the code that runs.

One named check per step of the derivation (eqs. 7-25) plus the robot-model
identities behind eq. (1). Each check builds the claim from the expressions
the simulator uses — ``control/laws`` (eqs. 11-18), ``control/impedance.py``
(eqs. 2-6), ``stability/continuous.py`` (eqs. 22, 25) and ``model/puma560.py`` (eq. 1) —
never from formulas retyped here, with CasADi symbols evaluated at seeded
random points (relative tolerance stated per check), and SymPy where an
exact limit is needed (eq. 18). The implementations are injected through
:class:`Implementation`, so tests can substitute a wrong law or model and see
the check fail.

``docs/derivations.md`` gives the derivation in full, including the
discrepancy found at eq. (18).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import casadi as ca
import numpy as np

from .. import stability
from ..control import impedance
from ..control.laws import tmt as reference
from ..simulation import closedloop

__all__ = ["CheckResult", "Implementation", "run_checks", "format_checks", "CHECKS"]

RTOL = 1e-9
"""Default relative tolerance of the randomized multi-point checks: double
precision round-off through a few hundred operations stays below ~1e-12."""


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check."""
    name: str
    equation: str
    claim: str
    method: str
    residual: float
    passed: bool
    tolerance: float = RTOL
    note: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "equation": self.equation, "claim": self.claim,
                "method": self.method, "residual": self.residual, "passed": self.passed,
                "tolerance": self.tolerance, "note": self.note}


def _default_robot():
    from ..model import Puma560

    return Puma560(armature=True, friction=True)


def _default_model():
    """The PUMA with every mass and inertia 20 % too large and friction
    compensated: a controller model that differs from the plant."""
    import dataclasses

    from ..model import PUMA560_LINKS, Puma560

    links = tuple(dataclasses.replace(l, m=l.m * 1.2, I=tuple(i * 1.2 for i in l.I), Jm=l.Jm * 1.2)
                  for l in PUMA560_LINKS)
    return Puma560(armature=True, friction="smooth", links=links)


@dataclass(frozen=True)
class Implementation:
    """The implemented expressions the checks exercise (defaults: the package's)."""
    tmt_reference: Callable = reference.tmt_reference
    tmt_delta: Callable = reference.tmt_delta
    known_reference: Callable = reference.known_reference
    k_eff: Callable = reference.k_eff
    impedance_acceleration: Callable = impedance.impedance_acceleration
    command: Callable = impedance.command
    inner_loop: Callable = impedance.inner_loop
    control_force: Callable = impedance.control_force
    joint_torque: Callable = closedloop.operational_space_torque
    critical_damping: Callable = stability.critical_damping
    tmt_error_tf: Callable = stability.tmt_error_tf
    impedance_gains: Callable = None
    robot: Any = field(default_factory=_default_robot)
    model: Any = field(default_factory=_default_model)

    def gains(self, m, b, k):
        """(K_D, K_P) the simulator derives from (M, B, K)."""
        if self.impedance_gains is not None:
            return self.impedance_gains(m, b, k)
        from ..simulation.scenario import ImpedanceSettings

        return ImpedanceSettings(m=tuple(m), b=tuple(b), k=tuple(k)).gains


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def _result(name, eq, claim, method, residual, tol=RTOL, note=""):
    ok = bool(np.isfinite(residual) and residual <= tol)
    return CheckResult(name, eq, claim, method, float(residual), ok, tol, note)


def _q_samples(rng, robot, n):
    """Random well-conditioned joint states."""
    out = []
    while len(out) < n:
        q = rng.uniform(-math.pi, math.pi, 3)
        if float(robot.condition_number(q)) < 50:
            out.append((q, rng.uniform(-1, 1, 3)))
    return out


# -- controller and closed loop ------------------------------------------------------

def check_eq7(impl: Implementation, rng) -> CheckResult:
    """Eq. (7): plant (1) + control law (5) + inner loop (6) give the error
    dynamics with the robot-dynamic-uncertainty term."""
    sym = {n: ca.SX.sym(n, 3) for n in ("q", "dq", "Xr", "dXr", "ddXr", "Xa", "dXa", "Fe", "m", "b", "k",
                                        "kd", "kp")}
    s = sym
    rob, mod = impl.robot, impl.model
    X, J = rob.fk(s["q"]), rob.jacobian(s["q"])
    dX = ca.mtimes(J, s["dq"])
    D, h, Ff = rob.cartesian_inertia(s["q"]), rob.cartesian_bias(s["q"], s["dq"]), rob.cartesian_friction(s["q"], s["dq"])
    Dh, hh = mod.cartesian_inertia(s["q"]), mod.cartesian_bias(s["q"], s["dq"])
    ddXa = impl.impedance_acceleration(s["Fe"], s["Xa"], s["dXa"], s["m"], s["b"], s["k"])
    Xc, dXc, ddXc = impl.command(s["Xr"], s["Xa"]), impl.command(s["dXr"], s["dXa"]), impl.command(s["ddXr"], ddXa)
    U = impl.inner_loop(ddXc, dXc, Xc, dX, X, s["kd"], s["kp"])
    F = impl.control_force(Dh, hh, U, s["Fe"])                        # eq. (5)
    ddX = ca.solve(D, F - s["Fe"] - h - Ff)                           # eq. (1)
    E, dE, ddE = s["Xr"] - X, s["dXr"] - dX, s["ddXr"] - ddX
    lhs = ddE + s["kd"] * dE + s["kp"] * E
    rhs = ca.solve(Dh, ca.mtimes(D - Dh, ddX) + (h - hh) + Ff) + ddXa + s["kd"] * s["dXa"] + s["kp"] * s["Xa"]
    f = ca.Function("eq7", list(sym.values()), [lhs, rhs])
    # eq. (5) as the loop applies it: the joint torque of the closed loop (closedloop.operational_space_torque,
    # square and general forms) against J^T F of the Cartesian law above, with the controller's model and
    # dq != 0 (review 24: the J-dot dq term could go missing from the loop's torque with every check passing)
    q, dq, U, Fe = (ca.MX.sym(n, 3) for n in ("q", "dq", "U", "Fe"))    # MX: the loop's solves are MX's
    Jm, Mh, nh, Jd = mod.jacobian(q), mod.mass_matrix(q), mod.bias(q, dq), mod.jacobian_dot(q, dq)
    cart = ca.mtimes(Jm.T, impl.control_force(mod.cartesian_inertia(q), mod.cartesian_bias(q, dq), U, Fe))
    loop = ca.Function("eq5_loop", [q, dq, U, Fe], [cart, impl.joint_torque(Mh, nh, Jm, Jd, U, Fe),
                                                    impl.joint_torque(Mh, nh, Jm, Jd, U, Fe, ca.MX.zeros(3))])
    res = 0.0
    for q, dq in _q_samples(rng, rob, 12):
        vals = [q, dq] + [rng.normal(size=3) for _ in range(6)] + [rng.uniform(0.5, 2, 3), rng.uniform(1, 100, 3),
                                                                      rng.uniform(10, 1e3, 3), rng.uniform(1, 100, 3),
                                                                      rng.uniform(10, 1e3, 3)]
        a, b = f(*vals)
        want, square, general = loop(q, dq, rng.normal(size=3), vals[7])
        res = max(res, _rel(a, b), _rel(square, want), _rel(general, want))
    return _result("closed-loop error dynamics", "(7)",
                   "E'' + K_D E' + K_P E = D^-1[dD X'' + dh + F_f] + Xa'' + K_D Xa' + K_P Xa",
                   "CasADi: PUMA plant (eq. 1) with friction under the implemented eqs. (4)-(6) "
                   "and a 20 % mass-model error; both sides at 12 random states; the loop's joint "
                   "torque (square and general forms) equal to J^T F there", res)


def check_eq8_9(impl: Implementation, rng) -> CheckResult:
    """Eqs. (8)-(9): with an exact model the loop is the target impedance,
    with B = M K_D and K = M K_P."""
    rob = impl.robot
    s = {n: ca.SX.sym(n, 3) for n in ("q", "dq", "Xa", "dXa", "Fe", "ddXr")}
    res = 0.0
    for q, dq in _q_samples(rng, rob, 8):
        m, b, k = rng.uniform(0.5, 2, 3), rng.uniform(1, 100, 3), rng.uniform(10, 1e3, 3)
        kd, kp = (np.asarray(g, dtype=float) for g in impl.gains(m, b, k))
        res = max(res, _rel(m * kd, b), _rel(m * kp, k))                     # eq. (9)
        X, J = rob.fk(s["q"]), rob.jacobian(s["q"])
        dX = ca.mtimes(J, s["dq"])
        D, h = rob.cartesian_inertia(s["q"]), rob.cartesian_bias(s["q"], s["dq"])
        Ff = rob.cartesian_friction(s["q"], s["dq"])
        ddXa = impl.impedance_acceleration(s["Fe"], s["Xa"], s["dXa"], m, b, k)
        # E = Xa and E' = Xa' (matched initial conditions): Xr = X + Xa
        Xr, dXr = X + s["Xa"], dX + s["dXa"]
        Xc, dXc, ddXc = impl.command(Xr, s["Xa"]), impl.command(dXr, s["dXa"]), impl.command(s["ddXr"], ddXa)
        U = impl.inner_loop(ddXc, dXc, Xc, dX, X, kd, kp)
        F = impl.control_force(D, h + Ff, U, s["Fe"])                          # exact model
        ddX = ca.solve(D, F - s["Fe"] - h - Ff)
        ddE = s["ddXr"] - ddX
        target = m * ddE + b * s["dXa"] + k * s["Xa"]                          # M E'' + B E' + K E
        f = ca.Function("eq9", list(s.values()), [target, s["Fe"]])
        a, c = f(q, dq, *[rng.normal(size=3) for _ in range(4)])
        res = max(res, _rel(a, c))
    return _result("target impedance in the ideal case", "(8)-(9)",
                   "exact model: F_e = M E'' + B E' + K E, with B = M K_D and K = M K_P",
                   "CasADi: exact-model PUMA loop with E = Xa, E' = Xa'; gains from the "
                   "scenario's ImpedanceSettings; 8 random states and impedances", res)


def check_eq11_12(impl: Implementation, rng) -> CheckResult:
    """Eqs. (11)-(12): the known-stiffness reference gives f_e = f_d at rest."""
    z = ca.SX.sym("z", 3)   # x, x_a, f_e at rest
    p = ca.SX.sym("p", 5)   # x_e, f_d, k, k_e, m
    x, xa, fe = z[0], z[1], z[2]
    x_e, f_d, k, k_e, m = (p[i] for i in range(5))
    xr = impl.known_reference(x_e, f_d, k, k_e)
    g = ca.vertcat(fe - k_e * (x - x_e),                                   # eq. (13)
                   impl.impedance_acceleration(fe, xa, 0, m, 0, k),          # eq. (2) at rest
                   impl.command(xr, xa) - x)                                 # eq. (4), E = Xa
    solve = ca.rootfinder("static", "newton", ca.Function("g", [z, p], [g]), {"abstol": 1e-10, "error_on_fail": False})
    keff = ca.Function("keff", [p], [impl.k_eff(k, k_e)])
    res = 0.0
    for _ in range(20):
        pv = np.array([rng.normal() * 0.1, rng.uniform(1, 50), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 6), 1.0])
        zs = np.asarray(solve(np.zeros(3), pv)).ravel()
        res = max(res, _rel(zs[2], pv[1]))
        kv = float(keff(pv))
        res = max(res, abs(1 / kv - (1 / pv[2] + 1 / pv[3])) * kv)   # springs in series
    return _result("known-stiffness steady state", "(11)-(12)",
                   "x_r = x_e + f_d/k_eff, k_eff = k k_e/(k + k_e) gives f_e = f_d at rest",
                   "CasADi Newton rootfinder on the static loop (eqs. 2, 4, 13) with the implemented "
                   "known_reference; k_eff as springs in series; 20 random cases", res)


def check_eq14_15(impl: Implementation, rng) -> CheckResult:
    """Eqs. (14)-(15): replacing k_e by f_e/(x - x_e) on the contact path."""
    res = 0.0
    for _ in range(40):
        k, k_e, _ = rng.uniform(10, 1e3), 10 ** rng.uniform(2, 6), rng.normal() * 0.1
        u = rng.uniform(1e-5, 1e-2)
        f_e = k_e * u                                                         # eq. (13)
        k_hat = f_e / u                                                       # eq. (14)
        res = max(res, _rel(float(impl.k_eff(k, k_hat)), float(impl.k_eff(k, k_e))))
        res = max(res, _rel(float(impl.k_eff(k, k_hat)), k * f_e / (k * u + f_e)))   # eq. (15), right form
    return _result("stiffness replaced by measured force", "(14)-(15)",
                   "on f_e = k_e (x - x_e): k_eff(k, f_e/(x - x_e)) = k_eff(k, k_e) = k f_e/(k(x - x_e) + f_e)",
                   "implemented k_eff at 40 random contact states", res)


def check_eq16_17(impl: Implementation, rng) -> CheckResult:
    """Eqs. (16)-(17): the implemented TMT reference is x_e + the modification
    term, and equals the known-stiffness reference with the true k_e."""
    res = 0.0
    f_th, k_min = 0.5, 1.0
    for _ in range(40):
        k, k_e, x_e, f_d = rng.uniform(10, 1e3), 10 ** rng.uniform(2, 5), rng.normal() * 0.1, rng.uniform(1, 50)
        f_e = rng.uniform(2 * f_th, 100)
        x = x_e + f_e / k_e
        xr = float(impl.tmt_reference(x, f_e, x_e, f_d, k, f_th, k_min))
        res = max(res, _rel(xr - x_e, float(impl.tmt_delta(x, f_e, x_e, f_d, k))))           # (16) vs (17)
        res = max(res, _rel(xr, float(impl.known_reference(x_e, f_d, k, k_e))))              # = eq. (11)
        # off the contact path too (any x, f_e): eq. (17) = f_d / k_eff(k, f_e/(x - x_e))
        xo = x_e + rng.uniform(1e-5, 1e-2)
        res = max(res, _rel(float(impl.tmt_delta(xo, f_e, x_e, f_d, k)),
                            f_d / float(impl.k_eff(k, f_e / (xo - x_e)))))
    return _result("TMT reference and modification term", "(16)-(17)",
                   "x_r = x_e + f_d (k(x - x_e) + f_e)/(k f_e) = x_e + f_d/k_eff(k, f_e/(x - x_e)); "
                   "on the contact path it equals eq. (11) with the true k_e",
                   "implemented tmt_reference (full-law regime) vs tmt_delta and known_reference, "
                   "40 random states", res)


def check_eq18(impl: Implementation, rng) -> CheckResult:
    """Eq. (18): the f_e = 0 branch and the paper's L'Hopital step, verified."""
    import sympy as sp

    fe, u, fd, k, ke, c = sp.symbols("f_e u f_d k k_e c", positive=True)
    delta = sp.sympify(impl.tmt_delta(u, fe, 0, fd, k))
    paths = {"x - x_e = c f_e^2": c * fe ** 2, "x - x_e = f_e/k_e (contact)": fe / ke,
             "x - x_e = c (fixed)": c}
    # cancel, not simplify: the limits are rational in f_d, k, k_e, and cancel's normal form
    # decides "difference == 0" without simplify's 0.2 s (and its import of sympy.physics.units)
    limits = {name: sp.cancel(sp.limit(delta.subs(u, g), fe, 0, "+")) for name, g in paths.items()}
    expect = {"x - x_e = c f_e^2": fd / k, "x - x_e = f_e/k_e (contact)": fd / k + fd / ke,
              "x - x_e = c (fixed)": sp.oo}
    res = 0.0
    for name, lim in limits.items():
        if expect[name] is sp.oo:
            res = max(res, 0.0 if lim is sp.oo else 1.0)
        else:
            val = sp.cancel(lim - expect[name])
            num = float(val.subs({fd: 10.0, k: 100.0, ke: 5e3})) if val != 0 else 0.0
            res = max(res, abs(num))
    # the implemented law at f_e = 0 (and just below the threshold) is x_e + f_d/k
    for _ in range(10):
        x_e, f_d, kk = rng.normal() * 0.1, rng.uniform(1, 50), rng.uniform(10, 1e3)
        for f_e, x in ((0.0, x_e), (0.0, x_e - 1e-3), (0.2, x_e + 1e-4)):
            xr = float(impl.tmt_reference(x, f_e, x_e, f_d, kk, 0.5, 100.0))
            res = max(res, _rel(xr, x_e + f_d / kk))
    note = ("L'Hopital's f_d/k holds only along paths where (x - x_e)/f_e -> 0; along the "
            "physical contact path f_e = k_e (x - x_e) the limit is f_d/k + f_d/k_e = f_d/k_eff, and "
            "with x - x_e fixed it diverges. The two-variable limit does not exist: eq. (18)'s "
            "f_e = 0 branch is a choice (right for the non-contact phase), and the reference jumps "
            "by f_d/k_e at first contact unless blended (the implementation blends).")
    return _result("f_e = 0 branch and L'Hopital limit", "(18)",
                   "x_r = x_e + f_d/k at f_e = 0; lim eq. (17) = f_d/k only if (x - x_e) = o(f_e), "
                   "= f_d/k + f_d/k_e on the contact path",
                   "SymPy limits of the implemented tmt_delta along 3 approach paths; implemented "
                   "tmt_reference at f_e = 0 and below its threshold", res, note=note)


def _eq22_residual_function(impl: Implementation):
    """Symbolic eq. (19) with the implemented TMT reference on the contact path,
    minus eq. (22)'s left side plus its right side."""
    eps, deps, ddeps = ca.SX.sym("eps"), ca.SX.sym("deps"), ca.SX.sym("ddeps")
    m, b, k, k_e, f_d, x_e = (ca.SX.sym(n) for n in ("m", "b", "k", "k_e", "f_d", "x_e"))
    x = x_e - eps                                                             # eps = x_e - x
    f_e = k_e * (x - x_e)                                                     # eq. (13)
    x_r = impl.tmt_reference(x, f_e, x_e, f_d, k, 1e-9, 1e-12)                # eq. (16), full law
    e = x_r - x
    # x_r' = x_e' and x_r'' = x_e'' (section IV): e' = eps', e'' = eps''
    eq19 = m * ddeps + b * deps + k * e - k_e * (x - x_e)
    eq22 = m * ddeps + b * deps + (k + k_e) * eps + f_d * (k + k_e) / k_e
    args = [eps, deps, ddeps, m, b, k, k_e, f_d, x_e]
    return ca.Function("eq22", args, [eq19, eq22, ca.gradient(eq19, ca.vertcat(ddeps, deps, eps))])


def check_eq19_22(impl: Implementation, rng) -> CheckResult:
    """Eqs. (19)-(22): the closed loop with the implemented TMT reference."""
    f = _eq22_residual_function(impl)
    res = 0.0
    for _ in range(30):
        m, b, k, k_e = rng.uniform(0.5, 2), rng.uniform(1, 100), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 5)
        f_d, x_e = rng.uniform(1, 50), rng.normal() * 0.1
        eps = -rng.uniform(1e-4, 1e-2)                                        # in contact: x > x_e
        a, c, coeff = f(eps, rng.normal(), rng.normal(), m, b, k, k_e, f_d, x_e)
        res = max(res, _rel(a, c))
        # the characteristic polynomial of the derived loop is stability.tmt_error_tf's
        den = np.asarray(impl.tmt_error_tf(m, b, k, k_e).den[0][0], dtype=float)
        res = max(res, _rel(np.asarray(coeff).ravel(), den / den[0] * m))
    return _result("closed loop with the TMT reference", "(19)-(22)",
                   "m e'' + b e' + k e = k_e (x - x_e) with eq. (16) becomes "
                   "m e'' + b e' + (k + k_e) eps = -f_d (k + k_e)/k_e; its polynomial is the analysed one",
                   "CasADi: eq. (19) with the implemented tmt_reference on the contact path; "
                   "coefficients by differentiation vs python-control tf of stability.py; 30 random cases",
                   res)


def check_eq23_24(impl: Implementation, rng) -> CheckResult:
    """Eqs. (23)-(24): the steady state of the derived loop is f_e = f_d."""
    import control as ct                    # here, not at the top: the law and loop checks import this module

    f = _eq22_residual_function(impl)
    eps = ca.SX.sym("eps")
    p = ca.SX.sym("p", 6)
    g = ca.Function("g", [eps, p], [f(eps, 0, 0, *[p[i] for i in range(6)])[0]])
    solve = ca.rootfinder("ss", "newton", g, {"abstol": 1e-10, "error_on_fail": False})
    res = 0.0
    for _ in range(20):
        m, b, k, k_e = rng.uniform(0.5, 2), rng.uniform(1, 100), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 5)
        f_d, x_e = rng.uniform(1, 50), rng.normal() * 0.1
        e_ss = float(solve(-0.5 * f_d / k_e, [m, b, k, k_e, f_d, x_e]))
        res = max(res, _rel(-k_e * e_ss, f_d))                               # f_e = k_e (x - x_e)
        res = max(res, _rel(float(np.real(ct.dcgain(stability.tmt_error_ss(m, b, k, k_e)))), 1.0))
    return _result("steady state f_e = f_d", "(23)-(24)",
                   "at rest, (k + k_e)(x_e - x) = -f_d (k + k_e)/k_e, so f_e = k_e (x - x_e) = f_d",
                   "CasADi Newton on the derived eq. (22) at rest; python-control DC gain of the "
                   "analysed system; 20 random cases", res)


def check_eq25(impl: Implementation, rng) -> CheckResult:
    """Eq. (25): b = 2 sqrt(m (k + k_e)) is critical damping."""
    res = 0.0
    for _ in range(30):
        m, k, k_e = rng.uniform(0.5, 2), rng.uniform(10, 1e3), 10 ** rng.uniform(2, 6)
        b = float(impl.critical_damping(m, k, k_e))
        disc = b * b - 4 * m * (k + k_e)                                     # double root
        res = max(res, abs(disc) / (4 * m * (k + k_e)))
        poles = np.roots(np.asarray(impl.tmt_error_tf(m, b, k, k_e).den[0][0], dtype=float))
        res = max(res, float(np.max(np.abs(poles.imag)) / np.max(np.abs(poles))) ** 2)
    return _result("critical damping", "(25)",
                   "b = 2 sqrt(m (k + k_e)) makes m s^2 + b s + (k + k_e) a double root",
                   "discriminant of the analysed polynomial at the implemented critical_damping; "
                   "30 random cases", res, tol=1e-12)


# -- robot model identities (eq. 1) ---------------------------------------------------

def check_mass_matrix(impl: Implementation, rng) -> CheckResult:
    rob = impl.robot
    res = 0.0
    for q, _ in _q_samples(rng, rob, 20):
        M = np.asarray(rob.mass_matrix(q))
        res = max(res, _rel(M, M.T))
        if np.linalg.eigvalsh(0.5 * (M + M.T)).min() <= 0:
            res = max(res, 1.0)
    return _result("mass matrix symmetric positive definite", "(1)",
                   "M(q) = M(q)^T > 0", "20 random q: symmetry residual and smallest eigenvalue", res)


def check_skew(impl: Implementation, rng) -> CheckResult:
    rob = impl.robot
    q, dq = ca.SX.sym("q", 3), ca.SX.sym("dq", 3)
    Mdot = ca.Function("Mdot", [q, dq], [ca.reshape(ca.jtimes(ca.vec(rob.mass_matrix(q)), q, dq), 3, 3)])
    res = 0.0
    for qv, dqv in _q_samples(rng, rob, 20):
        S = np.asarray(Mdot(qv, dqv)) - 2 * np.asarray(rob.coriolis_matrix(qv, dqv))
        res = max(res, float(np.max(np.abs(S + S.T)) / max(1.0, np.max(np.abs(S)))))
    return _result("dM/dt - 2C skew-symmetric", "(1)", "x^T (dM/dt - 2C) x = 0 for all x",
                   "CasADi AD of the implemented M, Christoffel C; 20 random states", res)


def check_cartesian_inertia(impl: Implementation, rng) -> CheckResult:
    rob = impl.robot
    res = 0.0
    for q, _ in _q_samples(rng, rob, 20):
        J = np.asarray(rob.jacobian(q))
        Ji = np.linalg.inv(J)
        res = max(res, _rel(np.asarray(rob.cartesian_inertia(q)), Ji.T @ np.asarray(rob.mass_matrix(q)) @ Ji))
    return _result("Cartesian inertia", "(1)", "D* = J^-T M J^-1",
                   "implemented cartesian_inertia vs NumPy from mass_matrix and jacobian; 20 random q", res)


def check_cartesian_dynamics(impl: Implementation, rng) -> CheckResult:
    rob = impl.robot
    res = 0.0
    for q, dq in _q_samples(rng, rob, 20):
        ddq = rng.normal(size=3)
        J = np.asarray(rob.jacobian(q))
        Xdd = J @ ddq + np.asarray(rob.jacobian_dot(q, dq)).ravel()
        F = (np.asarray(rob.cartesian_inertia(q)) @ Xdd + np.asarray(rob.cartesian_bias(q, dq)).ravel()
             + np.asarray(rob.cartesian_friction(q, dq)).ravel())
        res = max(res, _rel(J.T @ F, np.asarray(rob.inverse_dynamics(q, dq, ddq)).ravel()))
    return _result("Cartesian form consistent with joint space", "(1)",
                   "J^T (D* X'' + h* + F_f*) = M q'' + C q' + g + tau_f",
                   "implemented Cartesian and joint-space Functions at 20 random states", res)


CHECKS = (check_eq7, check_eq8_9, check_eq11_12, check_eq14_15, check_eq16_17, check_eq18,
          check_eq19_22, check_eq23_24, check_eq25, check_mass_matrix, check_skew,
          check_cartesian_inertia, check_cartesian_dynamics)


MODEL_CHECKS = (check_mass_matrix, check_skew, check_cartesian_inertia, check_cartesian_dynamics)
"""The eq. (1) checks of the PUMA's closed-form model (with a scenario the
report checks its own arm instead: :mod:`.model`)."""


def run_checks(impl: Implementation | None = None, seed: int = 2024, model: bool = True) -> list[CheckResult]:
    """Run every check (``model``: with the PUMA's eq. (1) checks,
    :data:`MODEL_CHECKS`); a check that raises is reported as failed."""
    impl = impl or Implementation()
    out = []
    for i, chk in enumerate(CHECKS):
        if not model and chk in MODEL_CHECKS:
            continue
        rng = np.random.default_rng(seed + i)
        try:
            out.append(chk(impl, rng))
        except Exception as exc:  # a broken implementation must fail its check, not crash the run
            name = chk.__doc__.strip().splitlines()[0] if chk.__doc__ else chk.__name__
            out.append(CheckResult(chk.__name__, "", name, "raised", float("nan"), False,
                                   note=f"{type(exc).__name__}: {exc}"))
    return out


def format_checks(results: list[CheckResult]) -> str:
    """A table: equation, name, residual, verdict, then claim and method."""
    lines = [f"{'eq.':<10} {'check':<44} {'residual':>10}  verdict", "-" * 76]
    for r in results:
        lines.append(f"{r.equation:<10} {r.name:<44} {r.residual:>10.2e}  {'PASS' if r.passed else 'FAIL'}")
        lines.append(f"{'':<10}   claim:  {r.claim}")
        lines.append(f"{'':<10}   method: {r.method}")
        if r.note:
            lines.append(f"{'':<10}   note:   {r.note}")
    n_fail = sum(not r.passed for r in results)
    lines.append("-" * 76)
    lines.append(f"{len(results) - n_fail} passed, {n_fail} failed")
    return "\n".join(lines)
