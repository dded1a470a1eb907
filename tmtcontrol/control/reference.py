"""Reference laws for the normal axis: TMT (eqs. 14-18) and known stiffness (eqs. 11-12).

All functions work on floats and on CasADi symbols, so the derivation checks
(``derivations.py``) and the simulator use the very same expressions. Units:
positions m, forces N, stiffness N/m.
"""

from __future__ import annotations

import casadi as ca

__all__ = ["k_eff", "known_reference", "tmt_delta", "tmt_reference"]


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
    ratio = (f_e - force_threshold) / force_threshold
    w = ca.fmin(ca.fmax(ratio, 0), 1)
    w = w * w * (3 - 2 * w)
    f_safe = ca.fmax(f_e, force_threshold)
    c = ca.fmin(ca.fmax((x - x_e) / f_safe, 0), 1 / min_stiffness)
    return x_e + f_d / k + w * f_d * c
