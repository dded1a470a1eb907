"""Position-based impedance control, eqs. (2)-(6), in the task frame.

Every function works on CasADi symbols (and on NumPy arrays for the diagonal
gains given as vectors). Vectors are task-frame 3-vectors, normal axis first;
M, B, K, K_D, K_P are diagonal and given as 3-vectors. Units: m, s, N, kg.
"""

from __future__ import annotations

import casadi as ca

__all__ = ["impedance_acceleration", "command", "inner_loop", "control_force", "joint_torque", "impedance_filter_step",
           "filtered_command"]


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


def joint_torque(M_hat, n_hat, J, Jdot_dq, U, F_e):
    """Eq. (5) mapped to the joints, tau = J^T F, without forming D*^.

    With D*^ = J^-T M^ J^-1 and h*^ = J^-T n^ - D*^ Jdot dq (the Cartesian
    form of eq. 1), J^T F = M^ J^-1 (U - Jdot dq) + n^ + J^T F_e: one 3x3
    solve instead of an inverse and two products (all vectors in the base
    frame; n^ = C dq + g of the controller's model)."""
    return ca.mtimes(M_hat, ca.solve(J, U - Jdot_dq, "symbolicqr")) + n_hat + ca.mtimes(J.T, F_e)


def impedance_filter_step(x_a, dx_a, f, m, b, k, Ts, substeps: int = 4):
    """Eq. (2) over one control period with the force ``f`` held (zero-order
    hold): the controller's discretisation of the impedance filter, RK4 with
    ``substeps`` steps. Returns ``(x_a, dx_a)`` at the next sample. For the
    filter's poles p, |p| Ts / substeps < 0.3 keeps it within 1e-6 of the
    exact ZOH discretisation."""
    h = Ts / substeps

    def rhs(xa, va):
        return va, impedance_acceleration(f, xa, va, m, b, k)

    for _ in range(substeps):
        k1 = rhs(x_a, dx_a)
        k2 = rhs(x_a + h / 2 * k1[0], dx_a + h / 2 * k1[1])
        k3 = rhs(x_a + h / 2 * k2[0], dx_a + h / 2 * k2[1])
        k4 = rhs(x_a + h * k3[0], dx_a + h * k3[1])
        x_a, dx_a = (x_a + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]),
                     dx_a + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]))
    return x_a, dx_a


def filtered_command(x_r, dx_r, ddx_r, f, x_a, dx_a, m, b, k, Ts):
    """The impedance filter as a building block of a law: the command of
    eq. (4) for reference (x_r, dx_r, ddx_r) and filter input ``f`` (N), and
    the filter's next state. Returns ``(x_c, dx_c, ddx_c, x_a_next, dx_a_next)``."""
    ddx_a = impedance_acceleration(f, x_a, dx_a, m, b, k)
    x_a_next, dx_a_next = impedance_filter_step(x_a, dx_a, f, m, b, k, Ts)
    return command(x_r, x_a), command(dx_r, dx_a), command(ddx_r, ddx_a), x_a_next, dx_a_next
