"""The trajectory modification technique (TMT), eqs. (14)-(18): the paper's law.

The unknown k_e of eqs. (11)-(12) is replaced by ``f_e / (x - x_e)``
(eq. 14), giving the reference of eq. (16)/(18) from measured quantities
only. Needs x_e (not k_e). Steady state: f_e = f_d for any constant k_e
(eqs. 23-24), where f_d is at least twice ``force_threshold`` (below, the
safeguard's blend settles lower: :func:`_steady_force`). Stability: eq.
(22), ``m s^2 + b s + (k + k_e)``, stable for b > 0 in continuous time; the sampled loop has a stiffness limit (see
``stability.sampled``).

The reference functions work on floats and on CasADi symbols, so the
derivation checks and the simulator use the very same expressions. Units:
positions m, forces N, stiffness N/m.
"""

from __future__ import annotations

from typing import Annotated, Literal

import casadi as ca
from pydantic import Field

from ..impedance import filtered_command
from .base import Law, LawParameters

__all__ = ["k_eff", "known_reference", "tmt_delta", "tmt_reference", "TmtParameters", "TMT", "eq22_polynomial",
           "tmt_polynomial", "compliance_estimate"]


def k_eff(k, k_e):
    """Effective stiffness of impedance and environment in series, eq. (12)."""
    return k * k_e / (k + k_e)


def known_reference(x_e, f_d, k, k_e):
    """x_r = x_e + f_d / k_eff with a given (assumed) k_e, eqs. (11)-(12)."""
    return x_e + f_d / k_eff(k, k_e)


def tmt_delta(x, f_e, x_e, f_d, k):
    """The raw trajectory modification term, eq. (17):
    ``f_d (k (x - x_e) + f_e) / (k f_e)`` — undefined at f_e = 0."""
    return f_d * (k * (x - x_e) + f_e) / (k * f_e)


def tmt_reference(x, f_e, x_e, f_d, k, force_threshold, min_stiffness):
    """TMT reference x_r of eq. (18) with safeguards for f_e -> 0 and noise.

    Eq. (18) is ``x_e + f_d/k`` at f_e = 0 and ``x_e + f_d/k + f_d c`` with the
    compliance estimate ``c = (x - x_e)/f_e`` (= 1/k_e, eq. 14) otherwise. The
    implementation

    * uses the f_e = 0 branch while the measured force is below
      ``force_threshold`` (a noisy force near zero makes ``c`` meaningless),
      switching to the full law by twice the threshold through a C1 smoothstep
      weight, so x_r never jumps;
    * clips ``c`` to ``[0, 1/min_stiffness]``: a spring has non-negative
      compliance, and the bound keeps a noisy ratio from commanding a deep
      reference.

    Where ``f_e >= 2 force_threshold`` and ``0 <= c <= 1/min_stiffness`` the
    value is exactly eq. (16)/(18).
    """
    w, c = compliance_estimate(x, f_e, x_e, force_threshold, min_stiffness)
    return x_e + f_d / k + w * f_d * c


def compliance_estimate(x, f_e, x_e, force_threshold, min_stiffness):
    """The safeguarded compliance estimate of eq. (14), ``c = (x - x_e)/f_e``
    clipped to ``[0, 1/min_stiffness]``, and the weight ``w`` (0 below
    ``force_threshold``, 1 from twice it, C1 smoothstep between) with which
    eq. (18) uses it (see :func:`tmt_reference`)."""
    ratio = (f_e - force_threshold) / force_threshold
    w = ca.fmin(ca.fmax(ratio, 0), 1)
    w = w * w * (3 - 2 * w)
    f_safe = ca.fmax(f_e, force_threshold)
    c = ca.fmin(ca.fmax((x - x_e) / f_safe, 0), 1 / min_stiffness)
    return w, c


class TmtParameters(LawParameters):
    kind: Literal["tmt"] = "tmt"
    force_threshold: Annotated[float, Field(
        gt=0, allow_inf_nan=False, strict=True,
        description="below it the f_e = 0 branch of eq. (18) is used, blended up to twice it, N",
        json_schema_extra={"unit": "N"})] = 0.5
    min_stiffness: Annotated[float, Field(
        gt=0, allow_inf_nan=False, strict=True,
        description="lower bound of the stiffness estimate (upper bound of its compliance), N/m",
        json_schema_extra={"unit": "N/m"})] = 100.0


def _update(y, p, s):
    x_r = tmt_reference(y["x"], y["f_m"], y["x_e_hat"], y["f_d"], y["k"], p["force_threshold"],
                        p["min_stiffness"])
    # x_r' = x_r'' = 0 as in section IV (x_r'' = x_e'' = 0)
    x_c, dx_c, ddx_c, xa, dxa = filtered_command(x_r, 0, 0, y["f_m"], s["x_a"], s["dx_a"],
                                                 y["m"], y["b"], y["k"], y["Ts"])
    return {"x_r": x_r, "x_c": x_c, "dx_c": dx_c, "ddx_c": ddx_c, "s_next": {"x_a": xa, "dx_a": dxa}}


def _steady_force(params, f_d, k, k_e, delta):
    """f_e = f_d (eqs. 23-24) while the compliance estimate at f_d, c = 1/k_e
    - delta/f_d, lies within its clip [0, 1/min_stiffness]; beyond, it sits
    on the clip c* (0, or 1/min_stiffness: a surface softer than
    min_stiffness, or one believed far too deep), the reference is x_e_hat +
    f_d (1/k + c*), and f_e = k_eff (delta + f_d/k + f_d c*); 0 where the
    free-space reference x_e_hat + f_d/k (eq. 18's f_e = 0 branch, the
    approach) lies outside the surface: the tool never reaches it. Review 9:
    the upper clip and the contact loss were missing (10 N claimed for
    6.67 N on a 50 N/m surface, and for 0 N with the surface believed 15 cm
    too close). Review 16: all of this holds where the force reaches twice
    ``force_threshold``, above which eq. (18) has its full weight; for f_d
    below it (a light force, or a threshold set high) the weight w < 1 at the
    equilibrium, which is then the root of the steady balance

        f (1/k_e + 1/k) = delta + f_d/k + w(f) f_d c(f)

    (x_a = f/k, x = x_c, f = k_e (x - x_e); ``scipy.optimize.brentq`` on
    [0, the balance's bound with c at its clip]): 9.830 N for f_d = 10 N and
    force_threshold = 8 N on 5e3 N/m (10 N was claimed; the simulation
    settles at 9.830 N)."""
    if delta + f_d / k <= 0.0:
        return 0.0
    c, c_max = 1.0 / k_e - delta / f_d, 1.0 / params.min_stiffness
    clip = 0.0 if c < 0.0 else c_max
    steady = f_d if 0.0 <= c <= c_max else max(0.0, k_eff(k, k_e) * (delta + f_d / k + f_d * clip))
    if steady >= 2.0 * params.force_threshold:        # eq. (18) at its full weight there
        return steady
    return _blended_equilibrium(params, f_d, k, k_e, delta)


def _blended_equilibrium(params, f_d, k, k_e, delta):
    """The steady force where eq. (18)'s weight w is below 1 (see
    :func:`_steady_force`), from the same safeguards as
    :func:`compliance_estimate`, in floats."""
    from scipy.optimize import brentq

    ft, c_max = params.force_threshold, 1.0 / params.min_stiffness

    def balance(f):
        w = min(max((f - ft) / ft, 0.0), 1.0)
        c = min(max((f / k_e - delta) / max(f, ft), 0.0), c_max)
        return f * (1.0 / k_e + 1.0 / k) - delta - f_d / k - w * w * (3.0 - 2.0 * w) * f_d * c

    # balance(0) = -(delta + f_d/k) < 0 (in contact); w c <= c_max bounds the root above
    hi = (delta + f_d / k + f_d * c_max) / (1.0 / k_e + 1.0 / k)
    hi = hi * (1.0 + 1e-12) + 1e-300
    return float(brentq(balance, 0.0, hi, xtol=1e-15 * hi, rtol=1e-15))


def eq22_polynomial(params, m, b, k, k_e, f_d=10.0, delta=0.0):
    """Eq. (22): m s^2 + b s + (k + k_e), for a reference that does not
    depend on the position (the known law: an x_e error only shifts it)."""
    return [m, b, k + k_e]


def tmt_polynomial(params, m, b, k, k_e, f_d=10.0, delta=0.0):
    """Eq. (22) with a surface-location error ``delta`` (m, estimate minus
    true), valid while the compliance estimate stays positive (c < 1):

        m (1 - c) s^2 + b (1 - c) s + k_e + k (1 - c),   c = delta k_e / f_d

    Linearising eq. (18) at f_e = f_d gives ``d x_r / d x = c``, so with
    x = x_c = x_r - x_a the filter state obeys x = -x_a/(1 - c) and eq. (2)
    becomes ``m s^2 + b s + k + k_e/(1 - c)``, the same roots. Read in the
    position: the stiffness is ``k_e + k(1 - c)`` (it changes by at most k)
    while the apparent mass and damping scale by (1 - c). delta = 0 is eq.
    (22).

    Where the estimate at the equilibrium, 1/k_e - delta/f_d, lies on its
    clip (:func:`compliance_estimate`: below 0, c >= 1, a surface believed
    deeper than the tool presses into it; above 1/min_stiffness), the
    reference does not move with the position and the loop is eq. (22)'s,
    ``m s^2 + b s + k + k_e`` (review 22: c >= 1 gave a pole at +34 /s and
    "UNSTABLE" for a loop the simulation shows settling)."""
    c = delta * k_e / f_d
    min_stiffness = (params if params is not None else TmtParameters()).min_stiffness
    if c >= 1.0 or 1.0 / k_e - delta / f_d > 1.0 / min_stiffness:
        return [m, b, k + k_e]
    return [m * (1.0 - c), b * (1.0 - c), k_e + k * (1.0 - c)]


TMT = Law("tmt", TmtParameters, ("x_a", "dx_a"), _update, needs=("x_e",), steady_force=_steady_force,
          characteristic_polynomial=tmt_polynomial,
          summary="trajectory modification technique, eq. (18) (the paper)")
