"""Integral force-error law: the reference driven by the integrated force error.

    x_r = x_e_hat + f_d/k + k_i * I,      I' = f_d - f_m,      x_r' = k_i (f_d - f_m)

through the standard impedance filter of eqs. (2)-(4) (``k_i`` in m/(N s)).
Integral force feedback, the classical remedy for an unknown stiffness:
whatever k_e and whatever error in x_e_hat, the only equilibrium of
I' = 0 is f_m = f_d. Needs x_e only as the start of the reference (any error is
integrated away); does not need k_e.

With the ideal inner loop (x = x_c) and f = k_e (x - x_e) the normal-axis
characteristic polynomial is

    m s^3 + (b + m k_i k_e) s^2 + (k + k_e + b k_i k_e) s + k k_i k_e,

Hurwitz for all m, b, k, k_i, k_e > 0 (a2 a1 > a3 a0 holds term by term), so
continuous-time stability is unconditional; as k_i grows two roots tend to
those of m s^2 + b s + k (the slow one about -k/b where b^2 >> 4 m k: -1.716
for the paper's impedance, k/b = 1.667; review 16), the third to
-(b + m k_i k_e)/m. The sampled loop adds a
limit: the forward-Euler integral has loop gain Ts k_i k_e per sample, so
k_e < 2/(Ts k_i) at the very least (``stability.laws`` gives the exact
sampled limit). The integral is updated with the force error of the
current sample (forward Euler), after it is used.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ..impedance import filtered_command
from .base import Law, LawParameters

__all__ = ["IntegralParameters", "INTEGRAL"]


class IntegralParameters(LawParameters):
    kind: Literal["integral"] = "integral"
    k_i: Annotated[float, Field(
        gt=0, allow_inf_nan=False, strict=True,
        description="integral gain from force error to reference, m/(N s)",
        json_schema_extra={"unit": "m/(N s)"})] = 0.03


def _update(y, p, s):
    e_f = y["f_d"] - y["f_m"]
    x_r = y["x_e_hat"] + y["f_d"] / y["k"] + p["k_i"] * s["I"]
    dx_r = p["k_i"] * e_f
    x_c, dx_c, ddx_c, xa, dxa = filtered_command(x_r, dx_r, 0, y["f_m"], s["x_a"], s["dx_a"],
                                                 y["m"], y["b"], y["k"], y["Ts"])
    return {"x_r": x_r, "x_c": x_c, "dx_c": dx_c, "ddx_c": ddx_c,
            "s_next": {"x_a": xa, "dx_a": dxa, "I": s["I"] + y["Ts"] * e_f}}


def _steady_force(params, f_d, k, k_e, delta):
    return f_d


def _poly(params, m, b, k, k_e, f_d=10.0, delta=0.0):
    k_i = params.k_i
    return [m, b + m * k_i * k_e, k + k_e + b * k_i * k_e, k * k_i * k_e]


INTEGRAL = Law("integral", IntegralParameters, ("x_a", "dx_a", "I"), _update, needs=("x_e",),
               steady_force=_steady_force, characteristic_polynomial=_poly,
               summary="reference driven by the integrated force error, gain k_i")
