"""Checks of every force-tracking law's claims, run on the law's own update.

For each registered law (``control.laws``), on the sampled normal-axis loop
assembled from the very CasADi update the simulator compiles
(``stability.lawloop``):

* **steady state**: the equilibrium of the symbolic closed loop gives the
  force the law declares (``Law.steady_force``) for several stiffnesses and
  surface-location errors;
* **tracking**: from contact at rest, the loop iterated through the paper's
  stiffness sequence (5e3, 2e4, 2e3, 1e4 N/m, 4 s each, 1 kHz) ends every
  segment within 0.01 N of the claim, and, where the law's equilibrium is
  isolated, the spectral radius there is below 1;
* **characteristic polynomial**: where the law documents one (eq. 22 for
  ``tmt``/``known``, the third-order polynomial of ``integral``), the
  continuous-time ideal-inner-loop linearisation of the update has exactly
  those roots.

A law whose update is wrong (a sign flipped, a term dropped) fails at least
one of them; the tests register such a law and see it fail.
"""

from __future__ import annotations

import numpy as np

from ..control.laws import Law, laws
from ..stability.lawloop import continuous_limit, law_loop, stiffness_sequence
from .derivations import CheckResult

__all__ = ["law_checks", "run_law_checks", "PAPER_STIFFNESS", "CHECK_M_P"]

PAPER_STIFFNESS = (5e3, 2e4, 2e3, 1e4)
"""The paper's stiffness sequence, N/m."""

CHECK_M_P = 3.3
"""Effective normal mass of the checks' loop, kg (the paper path's, about
3.30 kg; any positive value tests the same claims)."""

_IMPEDANCE = {"m": 1.0, "b": 60.0, "k": 100.0}
STEADY_TOL = 1e-8
"""Relative tolerance of the equilibrium force against the claim: Newton
converges to 1e-12 in the state; the force is k_e times a position, so
1e-8 of f_d leaves four decades for conditioning."""
TRACK_TOL = 0.01
"""Force band (N) at the end of each 4 s segment: the acceptance band of
the law comparison."""


def _fail(name, eq, claim, exc) -> CheckResult:
    return CheckResult(name, eq, claim, "raised", float("nan"), False, note=f"{type(exc).__name__}: {exc}")


def _steady(law: Law) -> CheckResult:
    name, eq = f"{law.name}: steady state", "law"
    claim = "equilibrium force of the sampled loop = the law's steady_force(f_d, k, k_e, x_e error)"
    if law.steady_force is None:
        return CheckResult(name, eq, claim, "no steady-state claim declared", float("nan"), False)
    params = law.parameters()
    res = 0.0
    try:
        for k_e in (2e3, 2e4):
            for delta in (0.0, -2e-3, 1e-3):
                lp = law_loop(law, params, **_IMPEDANCE, k_e=k_e, Ts=1e-3, m_p=CHECK_M_P, f_d=10.0, delta=delta)
                want = law.steady_force(params, 10.0, _IMPEDANCE["k"], k_e, delta)
                res = max(res, abs(lp.f_eq - want) / 10.0)
    except Exception as exc:  # a broken law must fail its check, not crash the run
        return _fail(name, eq, claim, exc)
    return CheckResult(name, eq, claim, "Newton on the symbolic one-period map, k_e in {2e3, 2e4} N/m, "
                       "x_e error in {0, -2, +1} mm", res, bool(res <= STEADY_TOL), STEADY_TOL)


def _tracking(law: Law) -> CheckResult:
    name, eq = f"{law.name}: tracks the paper's stiffness sequence", "law"
    claim = ("from contact at rest, |f_e - claim| <= 0.01 N at the end of every 4 s segment"
             + ("; spectral radius < 1 at each equilibrium" if law.linear_analysis else ""))
    params = law.parameters()
    kw = dict(**_IMPEDANCE, Ts=1e-3, m_p=CHECK_M_P, f_d=10.0)
    worst, rho_max = 0.0, 0.0
    try:
        segments = stiffness_sequence(law, params, PAPER_STIFFNESS, 4.0, **kw)
        for k_e, (lp, F) in zip(PAPER_STIFFNESS, segments):
            want = law.steady_force(params, 10.0, _IMPEDANCE["k"], k_e, 0.0) if law.steady_force else 10.0
            err = abs(F[-1] - want)
            worst = max(worst, err if np.isfinite(err) else np.inf)
            if law.linear_analysis:
                rho_max = max(rho_max, lp.spectral_radius)
    except Exception as exc:
        return _fail(name, eq, claim, exc)
    ok = worst <= TRACK_TOL and (rho_max < 1.0 or not law.linear_analysis)
    note = _radius_note(rho_max, kw["Ts"]) if law.linear_analysis else ""
    return CheckResult(name, eq, claim, "the 1-D sampled loop (m_p = 3.3 kg, 1 kHz) iterated 16 s with the "
                       "law's default parameters", worst, bool(ok), TRACK_TOL, note)


def _radius_note(rho: float, Ts: float) -> str:
    """The largest spectral radius, and whether it is the impedance filter's
    slow pole (eq. 3: m s^2 + b s + k = 0), which no stiffness moves: then the
    k_e-dependent modes are faster and the number says nothing about k_e."""
    slow = float(np.max(np.abs(np.exp(Ts * np.roots([_IMPEDANCE["m"], _IMPEDANCE["b"], _IMPEDANCE["k"]])))))
    text = f"largest spectral radius {rho:.6f}"
    return text + (" (the impedance filter's slow pole, the same for every k_e)" if abs(rho - slow) < 1e-9 else "")


def _polynomial(law: Law, rng) -> CheckResult | None:
    if law.characteristic_polynomial is None:
        return None
    name, eq = f"{law.name}: characteristic polynomial", "law"
    claim = ("the ideal-inner-loop linearisation of the update has the documented polynomial, "
             "with and without a surface-location error")
    params = law.parameters()
    res = 0.0
    try:
        for i in range(6):
            m, b, k = rng.uniform(0.5, 5), rng.uniform(10, 200), rng.uniform(10, 1000)
            k_e, f_d = 10 ** rng.uniform(3, 5), rng.uniform(1, 50)
            # delta from 5 mm-scale errors towards the robot up to 0.9 of the penetration f_d/k_e
            delta = 0.0 if i < 3 else rng.uniform(-5.0, 0.9) * f_d / k_e
            A, _ = continuous_limit(law, params, m=m, b=b, k=k, k_e=k_e, f_d=f_d, delta=delta)
            want = np.asarray(law.characteristic_polynomial(params, m, b, k, k_e, f_d, delta), dtype=float)
            want = want / want[0]
            got = np.real(np.poly(A))
            if got.size != want.size:
                return CheckResult(name, eq, claim, "degree", float("inf"), False,
                                   note=f"degree {got.size - 1}, documented {want.size - 1}")
            res = max(res, float(np.max(np.abs(got - want) / np.abs(want))))
    except Exception as exc:
        return _fail(name, eq, claim, exc)
    return CheckResult(name, eq, claim, "d(update)/dTs at Ts = 0 with x = x_c, linearised, at 6 random "
                       "(m, b, k, k_e, f_d), 3 with a random x_e error delta; coefficientwise (monic)",
                       res, bool(res <= 1e-9), 1e-9)


def law_checks(law: Law, seed: int = 2024) -> list[CheckResult]:
    """The checks of one law (see the module docstring)."""
    out = [_steady(law), _tracking(law)]
    poly = _polynomial(law, np.random.default_rng(seed))
    return out + ([poly] if poly is not None else [])


def run_law_checks(seed: int = 2024) -> list[CheckResult]:
    """:func:`law_checks` for every registered law."""
    return [r for law in laws().values() for r in law_checks(law, seed)]
