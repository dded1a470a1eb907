"""The known-stiffness reference, eqs. (11)-(12): ``x_r = x_e + f_d / k_eff``
with ``k_eff = k k_e / (k + k_e)`` computed from an *assumed* k_e.

Needs x_e and k_e. Steady state: ``f_e = f_d k_eff(k_e) / k_eff(k_e_hat)``,
exact only when the assumed stiffness is the true one (the problem the paper
sets out to solve). Stability: eq. (22) with the reference fixed, i.e.
``m s^2 + b s + k + k_e``, stable for b > 0 (continuous time).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ..impedance import filtered_command
from .base import Law, LawParameters
from .tmt import eq22_polynomial, k_eff, known_reference

__all__ = ["KnownParameters", "KNOWN"]


class KnownParameters(LawParameters):
    kind: Literal["known"] = "known"
    assumed_stiffness: Annotated[float, Field(gt=0, allow_inf_nan=False, strict=True,
                                              description="assumed environment stiffness k_e, N/m",
                                              json_schema_extra={"unit": "N/m"})] = 5e3


def _update(y, p, s):
    x_r = known_reference(y["x_e_hat"], y["f_d"], y["k"], p["assumed_stiffness"])
    x_c, dx_c, ddx_c, xa, dxa = filtered_command(x_r, 0, 0, y["f_m"], s["x_a"], s["dx_a"],
                                                 y["m"], y["b"], y["k"], y["Ts"])
    return {"x_r": x_r, "x_c": x_c, "dx_c": dx_c, "ddx_c": ddx_c, "s_next": {"x_a": xa, "dx_a": dxa}}


def _steady_force(params, f_d, k, k_e, delta):
    """f_e = k_eff(k_e) (x_r - x_e - f_e/k) solved for f_e: ``f_d
    k_eff(k_e)/k_eff(k_e_hat) + k_eff(k_e) delta``."""
    return f_d * k_eff(k, k_e) / k_eff(k, params.assumed_stiffness) + k_eff(k, k_e) * delta


KNOWN = Law("known", KnownParameters, ("x_a", "dx_a"), _update, needs=("x_e", "k_e"),
            steady_force=_steady_force, characteristic_polynomial=eq22_polynomial,
            summary="eqs. (11)-(12) with an assumed k_e (the paper's baseline)")
