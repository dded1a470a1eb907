"""Adaptive impedance with an online damping-offset term: Jung, Hsia and
Bonitz, "Force tracking impedance control of robot manipulators under
unknown environment", IEEE Trans. Control Systems Technology 12(3), 2004.

The impedance has no stiffness (k = 0) and the reference is the surface
estimate (x_r = x_e_hat); the force error drives the filter and an adaptive
velocity offset Phi (m/s), updated once per sample:

    m x_a'' + b (x_a' + Phi(t)) = f_m - f_d,                    
    Phi(t) = Phi(t - Ts) + sigma (f_d - f_m)(t - Ts) / b,
    x_c = x_r - x_a                                                (eq. 4)

with ``sigma`` dimensionless. At an equilibrium x_a' = x_a'' = 0 and Phi is
constant, so f_m = f_d and then Phi = 0: zero steady-state force error for
any k_e and any x_e error. Needs x_e only as the start of the reference;
does not need k_e. The impedance stiffness of the scenario is not used (the
law sets k = 0); m and b (and the damping schedule, if on) are.

Stability of the sampled update. Phi integrates the force error with gain
sigma/(b Ts) per second, so with the ideal inner loop (x = x_c) and
f = k_e (x - x_e) the continuous approximation of the loop is

    m s^3 + b s^2 + k_e s + k_e sigma / Ts,

Hurwitz if and only if b k_e > m k_e sigma/Ts, i.e.

    0 < sigma < b Ts / m                                           (bound)

independent of k_e: a necessary condition as Ts k_e/b -> 0. The exact
sampled normal-axis loop (``stability.lawloop``: ZOH plant of effective mass
m_p, inner loop, one-sample update) has a lower limit as k_e grows; with
the paper's m = 1 kg, b = 60 N s/m, Ts = 1 ms and m_p = 3.3 kg, where the
bound is 0.06:

    k_e (N/m)          1e3      1e4      1e5
    sigma limit        0.058    0.055    0.026

(docs/laws.md; a test checks the bound at 1e3 N/m against the sampled model
and the simulator). The default sigma = 0.02 keeps a factor 3 below the
bound and is stable up to k_e ~ 1.1e5 N/m at 1 kHz (docs/laws.md's table:
1.114e5 N/m; review 16: this said 1.2e5, and the loop is a limit cycle at
1.18e5).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ..impedance import filtered_command
from .base import Law, LawParameters

__all__ = ["AdaptiveDampingParameters", "ADAPTIVE_DAMPING", "sigma_bound"]


def sigma_bound(m, b, Ts):
    """The stability bound of the sampled adaptive update, sigma < b Ts/m
    (continuous approximation, see the module docstring)."""
    return b * Ts / m


class AdaptiveDampingParameters(LawParameters):
    kind: Literal["adaptive_damping"] = "adaptive_damping"
    sigma: Annotated[float, Field(
        gt=0, allow_inf_nan=False, strict=True,
        description="update rate of the adaptive velocity offset Phi (dimensionless); "
                    "stable for sigma < b Ts / m")] = 0.02


def _update(y, p, s):
    e_f = y["f_d"] - y["f_m"]
    x_r = y["x_e_hat"]
    # the filter input: f_m - f_d - b Phi, with k = 0
    x_c, dx_c, ddx_c, xa, dxa = filtered_command(x_r, 0, 0, -e_f - y["b"] * s["Phi"], s["x_a"], s["dx_a"],
                                                 y["m"], y["b"], 0, y["Ts"])
    return {"x_r": x_r, "x_c": x_c, "dx_c": dx_c, "ddx_c": ddx_c,
            "s_next": {"x_a": xa, "dx_a": dxa, "Phi": s["Phi"] + p["sigma"] * e_f / y["b"]}}


def _steady_force(params, f_d, k, k_e, delta):
    return f_d


ADAPTIVE_DAMPING = Law("adaptive_damping", AdaptiveDampingParameters, ("x_a", "dx_a", "Phi"), _update,
                       needs=("x_e",), steady_force=_steady_force,
                       summary="Jung-Hsia-Bonitz 2004: k = 0, adaptive velocity offset, rate sigma")
