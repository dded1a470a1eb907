"""The normal axis of the sampled loop with any force-tracking law.

The closed-form sampled model (``stability.sampled``) covers the two laws
whose linearisation is written out by hand. This module assembles the same
normal-axis loop for *any* registered law from the law's own CasADi update
(the Function the simulator compiles), so the analysis never branches on
the law:

* plant between samples (zero-order hold, exact discretisation):
  ``x'' = U + (f_app - k_e x - d_e x') / m_p`` with x measured from the true
  surface (x grows into it), ``m_p`` the robot's effective normal mass and
  the contact kept (the linearisation of the unilateral contact);
* at each sample: the force sensor (first-order filter ``alpha``), the law
  update with the controller's surface estimate ``x_e_hat = delta``, the
  inner loop of eq. (6) with the eq. (4) command;
* an optional computation delay of ``delay`` samples: the force of eq. (5)
  computed at t_k is applied from t_{k+delay}.

:func:`law_loop` finds the loop's equilibrium (Newton on the symbolic
one-period map), its Jacobian there and the spectral radius, which decides
local stability of the sampled loop; :func:`law_stiffness_limit` bisects on
it (the stable band of k_e: :func:`law_stiffness_band`). :func:`continuous_limit`
gives the law's continuous-time normal-axis system with the ideal inner loop
(x = x_c), whose characteristic polynomial the derivation checks compare with
each law's documented one (eq. 22 for ``tmt``/``known``). Units are SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..control.laws import MEASUREMENTS, Law, LawParameters
from .continuous import AnalysisError, _check, _pos
from .sampled import StiffnessBand, _zoh, stable_band

__all__ = ["LawLoop", "law_loop", "law_stiffness_limit", "law_stiffness_band", "continuous_limit", "implemented_limit",
           "stiffness_sequence"]


@dataclass(frozen=True, eq=False)
class LawLoop:
    """The sampled normal-axis loop of one law at one operating point.

    ``step`` is the CasADi map ``z -> (z_next, f_e)``; the state ``z`` is
    ``(x, x', f_filt, law state..., delayed (U, f) pairs...)``. ``z_eq`` its
    equilibrium, ``f_eq`` the force there (N), ``A`` the Jacobian of the map
    at ``z_eq`` and ``spectral_radius`` its largest eigenvalue magnitude
    (< 1: locally stable). ``residual`` is |F(z_eq) - z_eq|."""
    law: str
    k_e: float
    Ts: float
    delta: float
    delay: int
    step: ca.Function
    states: tuple[str, ...]
    z_eq: np.ndarray
    f_eq: float
    A: np.ndarray
    spectral_radius: float
    residual: float

    @property
    def stable(self) -> bool:
        return self.spectral_radius < 1.0

    def simulate(self, z0: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Iterate the (nonlinear) map ``n`` times from ``z0``: states
        (n+1, nz) and forces (n,)."""
        return _iterate(self.step, z0, n)


def _law_and_params(law, params) -> LawParameters:
    """``params``, or the law's defaults, checked to be ``law``'s (review 58:
    a law's name, or another law's parameters, failed inside with an
    AttributeError)."""
    if not isinstance(law, Law):
        raise AnalysisError(f"law: expected a Law (tmtcontrol.control.laws.get_law(name)), got {law!r}")
    if params is None:
        return law.parameters()
    if not isinstance(params, law.parameters):
        raise AnalysisError(f"params: expected the parameters of law {law.name!r} ({law.parameters.__name__}), "
                            f"got {type(params).__name__}")
    return params


def _loop_settings(alpha, d_e, kd, kp, delta=0.0) -> None:
    """Check the loop's settings beside the impedance (review 58: alpha = 2,
    d_e < 0 or kd < 0 were taken silently, alpha = NaN failed in LAPACK)."""
    from .sampled import check_loop_settings

    check_loop_settings(alpha, d_e, kd, kp)
    if isinstance(delta, bool) or not isinstance(delta, (int, float, np.floating, np.integer)) \
            or not np.isfinite(delta):
        raise AnalysisError(f"delta: expected a finite number (m), got {delta!r}")


def _iterate(step: ca.Function, z0: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    Z, F = step.mapaccum("acc", n)(z0)
    Z = np.hstack([np.reshape(z0, (-1, 1)), np.array(Z)])
    return Z.T, np.ravel(np.array(F))


def _step_function(law: Law, params: LawParameters, *, m, b, k, k_e, Ts, m_p, f_d, delta, kd, kp, alpha,
                   d_e, delay, inputs=(), model_scale=1.0):
    """The one-period map ``[z, *inputs] -> [z_next, f_e]``; numbers may be
    CasADi SX symbols listed in ``inputs`` (the design makes b and k inputs)."""
    nl = len(law.states)
    z = ca.SX.sym("z", 3 + nl + 2 * delay)
    x, v, f_filt = z[0], z[1], z[2]
    s = z[3:3 + nl]
    buf = z[3 + nl:]
    f_true = k_e * x + d_e * v
    f_m = alpha * f_filt + (1 - alpha) * f_true
    y = {"x": x, "dx": v, "f_m": f_m, "f_d": f_d, "x_e_hat": delta, "Ts": Ts, "m": m, "b": b, "k": k}
    _, x_c, dx_c, ddx_c, s_next = law.function()(ca.vertcat(*(y[n] for n in MEASUREMENTS)),
                                                  law.parameter_vector(params), s)
    U = ddx_c + kd * (dx_c - v) + kp * (x_c - x)                          # eq. (6), normal axis
    held = ca.vertcat(U, f_m)
    if delay:
        applied, buf_next = buf[0:2], ca.vertcat(buf[2:], held)
    else:
        applied, buf_next = held, ca.SX(0, 1)
    Ac = np.array([[0.0, 1.0], [-k_e / m_p, -d_e / m_p]])
    Bc = np.array([[0.0, 0.0], [model_scale, 1.0 / m_p]])     # eq. (5) with the model's mass model_scale m_p
    Phi, Gam = _zoh(Ac, Bc, Ts)
    xv_next = ca.mtimes(ca.DM(Phi), ca.vertcat(x, v)) + ca.mtimes(ca.DM(Gam), applied)
    z_next = ca.vertcat(xv_next, f_m, s_next, buf_next)
    names = ("x", "dx", "f_filt", *law.states, *(f"{w}[-{i}]" for i in range(delay, 0, -1) for w in ("U", "f")))
    return (ca.Function(f"loop_{law.name}", [z, *inputs], [z_next, f_true],
                        ["z", *(str(v) for v in inputs)], ["z_next", "f_e"]), names)


def _newton(fun, jac, z, iters=60, tol=1e-12):
    """Solve fun(z) = 0 by Newton with least-squares steps (the Jacobian may
    be singular along a continuum of equilibria)."""
    for _ in range(iters):
        r = np.ravel(np.array(fun(z)))
        scale = 1.0 + np.abs(z)
        if np.max(np.abs(r) / scale) < tol:
            break
        J = np.array(jac(z))
        dz = np.linalg.lstsq(J, -r, rcond=None)[0]
        z = z + dz
    return z


def law_loop(law: Law, params: LawParameters | None = None, *, m: float, b: float, k: float, k_e: float,
             Ts: float, m_p: float, f_d: float = 10.0, delta: float = 0.0, kd: float | None = None,
             kp: float | None = None, alpha: float = 0.0, d_e: float = 0.0, delay: int = 0,
             settle: float = 2.0, model_scale: float = 1.0) -> LawLoop:
    """The sampled normal-axis loop of ``law`` (see the module docstring).

    Parameters: impedance ``m, b, k`` (kg, N s/m, N/m; the law may override
    k), stiffness ``k_e`` (N/m), period ``Ts`` (s), effective normal mass
    ``m_p`` (kg), ``f_d`` (N), surface-location error ``delta`` (m,
    estimate minus true), inner-loop gains ``kd, kp`` (default b/m, k/m,
    eq. 9), force-filter pole ``alpha``, contact damping ``d_e`` (N s/m),
    computation delay ``delay`` (samples), the controller's model of the
    robot's mass relative to the true one ``model_scale`` (eq. 5's D*^ =
    model_scale D*: the inner loop's acceleration U acts scaled by it).
    The equilibrium is found by
    iterating the map for ``settle`` seconds from contact at rest (when that
    stays finite) and refining by Newton.
    """
    for name, val in (("m", m), ("k", k), ("k_e", k_e), ("Ts", Ts), ("m_p", m_p), ("f_d", f_d)):
        _pos(name, val)
    _pos("b", b, strict=False)          # an undamped impedance is a loop to judge (unstable), not bad input
    if not isinstance(delay, (int, np.integer)) or delay < 0:
        raise AnalysisError(f"delay: expected an integer >= 0 samples, got {delay!r}")
    _loop_settings(alpha, d_e, kd, kp, delta)
    _pos("settle", settle, strict=False)      # 0: Newton from the contact guess alone
    _pos("model_scale", model_scale)
    params = _law_and_params(law, params)
    kd = b / m if kd is None else kd
    kp = k / m if kp is None else kp
    F, names = _step_function(law, params, m=m, b=b, k=k, k_e=k_e, Ts=Ts, m_p=m_p, f_d=f_d, delta=delta,
                              kd=kd, kp=kp, alpha=alpha, d_e=d_e, delay=delay, model_scale=model_scale)
    nz = F.size1_in(0)
    z0 = np.zeros(nz)
    z0[3:3 + len(law.states)] = law.initial_state(params)
    guess = z0.copy()
    n = max(1, int(round(settle / Ts)))
    with np.errstate(all="ignore"):
        Z, _ = _iterate(F, z0, n)
    if np.all(np.isfinite(Z[-1])) and np.max(np.abs(Z[-1, :2])) < 1.0:
        guess = Z[-1]
    else:
        guess[0] = f_d / k_e
        guess[2] = f_d
    zs = ca.SX.sym("z", nz)
    res = ca.Function("res", [zs], [F(zs)[0] - zs])
    jac = ca.Function("jacobian", [zs], [ca.jacobian(F(zs)[0] - zs, zs)])
    z_eq = _newton(res, jac, guess)
    residual = float(np.max(np.abs(np.array(res(z_eq)))))
    A = np.array(jac(z_eq)) + np.eye(nz)                       # d(z_next)/dz = d(z_next - z)/dz + I
    rho = float(np.max(np.abs(np.linalg.eigvals(A))))
    f_eq = float(F(z_eq)[1])
    return LawLoop(law.name, k_e, Ts, delta, delay, F, names, np.ravel(z_eq), f_eq, A, rho, residual)


def stiffness_sequence(law: Law, params: LawParameters | None, k_es, duration: float,
                       **kw) -> list[tuple[LawLoop, np.ndarray]]:
    """Iterate the (nonlinear) sampled loop of ``law`` from contact at rest
    through constant stiffnesses ``k_es`` (N/m), ``duration`` seconds each
    (the state carries over at each switch); ``kw`` as :func:`law_loop`.
    Returns, per segment, its :class:`LawLoop` (equilibrium, spectral
    radius) and contact force (N; NaN/inf if it blows up)."""
    params = _law_and_params(law, params)
    z, out = None, []
    for k_e in k_es:
        lp = law_loop(law, params, k_e=k_e, **kw)
        if z is None:
            z = np.zeros(lp.z_eq.size)
            z[3:3 + len(law.states)] = law.initial_state(params)
        with np.errstate(all="ignore"):
            Z, F = lp.simulate(z, max(1, int(round(duration / lp.Ts))))
        z = Z[-1]
        out.append((lp, F))
    return out


def law_stiffness_band(law: Law, params: LawParameters | None = None, *, k_lo: float = 10.0,
                       k_hi: float = 1e9, rtol: float = 1e-6, within: float | None = None,
                       **kw) -> StiffnessBand:
    """The band of k_e (N/m) in which :func:`law_loop` is locally stable:
    ``stability.sampled.stable_band`` (a log grid from ``k_lo``, then
    bisection of each edge to ``rtol``); ``within`` the scenario's smallest
    stiffness (N/m), whose band is wanted."""
    def stable(ke):
        return law_loop(law, params, k_e=ke, **kw).spectral_radius < 1.0

    resonance = (kw["m_p"], kw["Ts"]) if "m_p" in kw and "Ts" in kw else None    # the sampling resonances
    return stable_band(stable, k_lo, k_hi, rtol, within=within, resonance=resonance)


def law_stiffness_limit(law: Law, params: LawParameters | None = None, *, k_lo: float = 10.0,
                        k_hi: float = 1e9, rtol: float = 1e-6, within: float | None = None, **kw) -> float:
    """Largest k_e (N/m) for which :func:`law_loop` is locally stable: the
    ``limit`` of :func:`law_stiffness_band`, the upper edge of the stable
    band that contains ``within`` (default: of the lowest stable band from
    ``k_lo``). ``inf`` if stable up to ``k_hi``; 0 if unstable at ``within``
    and at every stiffness scanned below it."""
    return law_stiffness_band(law, params, k_lo=k_lo, k_hi=k_hi, rtol=rtol, within=within, **kw).limit


def _limit_at_ts0(law: Law, params: LawParameters, m, b, k, k_e, f_d, delta):
    """The law's update at Ts -> 0 on the normal axis, f = k_e x: the symbols
    ``s`` (law states) and ``xv`` (x, x'), the command ``x_c, dx_c, ddx_c`` at
    Ts = 0 and the law state's derivative ``d s_next / d Ts`` at Ts = 0 (its
    update is a discretisation of an ODE)."""
    s = ca.SX.sym("s", len(law.states))
    xv = ca.SX.sym("xv", 2)
    Ts = ca.SX.sym("Ts")
    y = {"x": xv[0], "dx": xv[1], "f_m": k_e * xv[0], "f_d": f_d, "x_e_hat": delta, "Ts": Ts, "m": m, "b": b,
         "k": k}
    _, x_c, dx_c, ddx_c, s_next = law.function()(ca.vertcat(*(y[n] for n in MEASUREMENTS)),
                                                  law.parameter_vector(params), s)
    at0 = lambda e: ca.substitute(e, Ts, 0)
    return s, xv, at0(x_c), at0(dx_c), at0(ddx_c), at0(ca.jacobian(s_next, Ts))


def _equilibrium_jacobian(g, w, w0) -> tuple[np.ndarray, np.ndarray]:
    """``(dg/dw at w_eq, w_eq)`` with ``g(w_eq) = 0`` found by Newton from ``w0``."""
    res = ca.Function("res", [w], [g])
    jac = ca.Function("jacobian", [w], [ca.jacobian(g, w)])
    w_eq = _newton(res, jac, w0)
    return np.array(jac(w_eq)), np.ravel(w_eq)


def implemented_limit(law: Law, params: LawParameters | None = None, *, m: float, b: float, k: float,
                      k_e: float, f_d: float = 10.0, delta: float = 0.0, kd: float | None = None,
                      kp: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The law's continuous-time normal axis as it runs: the law's state
    derivative (``d s_next / d Ts`` at Ts = 0, as :func:`continuous_limit`)
    and the inner loop of eq. (6) on an exact model, ``x'' = ddx_c + K_D
    (dx_c - x') + K_P (x_c - x)`` (K_D = b/m, K_P = k/m unless given), with
    the command as the law computes it (the TMT reference enters without its
    derivatives, section IV). Returns ``(A, w_eq)``, the Jacobian at the
    equilibrium of the state ``(law states, x, x')``. Review 34: the ideal
    inner loop (x = x_c) of :func:`continuous_limit` scales the TMT loop's
    mass and damping by (1 - c) under an x_e error, which the running loop
    does not (its damping ratio there several times lower); at delta = 0
    the two agree (eq. 22 times the inner loop's ``s^2 + K_D s + K_P``)."""
    _check(m, b, k, k_e, f_d)
    _loop_settings(0.0, 0.0, kd, kp, delta)
    params = _law_and_params(law, params)
    kd = b / m if kd is None else kd
    kp = k / m if kp is None else kp
    s, xv, x_c, dx_c, ddx_c, sdot = _limit_at_ts0(law, params, m, b, k, k_e, f_d, delta)
    ddx = ddx_c + kd * (dx_c - xv[1]) + kp * (x_c - xv[0])
    return _equilibrium_jacobian(ca.vertcat(sdot, xv[1], ddx), ca.vertcat(s, xv),
                                 np.r_[law.initial_state(params), f_d / k_e, 0.0])


def continuous_limit(law: Law, params: LawParameters | None = None, *, m: float, b: float, k: float,
                     k_e: float, f_d: float = 10.0, delta: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The law's continuous-time normal axis with the ideal inner loop.

    The law's state derivative is ``d s_next / d Ts`` at Ts = 0 (its update
    is a discretisation of an ODE); the position follows the command,
    ``x = x_c`` and ``x' = dx_c`` (solved jointly with the law's own
    dependence on x, x', f = k_e x). Returns ``(A, s_eq)``: the Jacobian of
    the law state's derivative at its equilibrium, and that equilibrium.
    ``np.poly(A)`` is the monic characteristic polynomial. Laws with a
    per-sample update that has no continuous limit (Ts does not appear)
    give a zero row for that state."""
    _check(m, b, k, k_e, f_d)
    _loop_settings(0.0, 0.0, None, None, delta)
    params = _law_and_params(law, params)
    nl = len(law.states)
    s, xv, x_c, dx_c, _, sdot = _limit_at_ts0(law, params, m, b, k, k_e, f_d, delta)
    Jw, w_eq = _equilibrium_jacobian(ca.vertcat(sdot, x_c - xv[0], dx_c - xv[1]), ca.vertcat(s, xv),
                                     np.r_[law.initial_state(params), f_d / k_e, 0.0])
    # sdot = G_s ds + G_y dxv ;  0 = H_s ds + H_y dxv  ->  dxv = -H_y^-1 H_s ds
    G_s, G_y = Jw[:nl, :nl], Jw[:nl, nl:]
    H_s, H_y = Jw[nl:, :nl], Jw[nl:, nl:]
    A = G_s - G_y @ np.linalg.solve(H_y, H_s)
    return A, w_eq
