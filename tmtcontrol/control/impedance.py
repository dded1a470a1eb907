"""Position-based impedance control, eqs. (2)-(6), in the task frame.

Every function works on CasADi symbols (and on NumPy arrays for the diagonal
gains given as vectors). Vectors are task-frame 3-vectors, normal axis first;
M, B, K, K_D, K_P are diagonal and given as 3-vectors. Units: m, s, N, kg.
"""

from __future__ import annotations

import casadi as ca

__all__ = ["impedance_acceleration", "command", "inner_loop", "control_force"]


def impedance_acceleration(F_e, X_a, dX_a, m, b, k):
    """Impedance filter, eq. (2): ``M Xa'' + B Xa' + K Xa = F_e`` solved for Xa''.
    Its transfer function is eq. (3), ``Xa(s) = (M s^2 + B s + K)^-1 F_e(s)``."""
    return (F_e - b * dX_a - k * X_a) / m


def command(X_r, X_a):
    """Eq. (4): X_c = X_r - X_a (the same for velocities and accelerations)."""
    return X_r - X_a


def inner_loop(ddX_c, dX_c, X_c, dX, X, kd, kp):
    """Eq. (6): U = Xc'' + K_D (Xc' - X') + K_P (Xc - X)."""
    return ddX_c + kd * (dX_c - dX) + kp * (X_c - X)


def control_force(D_hat, h_hat, U, F_e):
    """Eq. (5): F = D*^ U + h*^ + F_e (all in one frame)."""
    return ca.mtimes(D_hat, U) + h_hat + F_e
