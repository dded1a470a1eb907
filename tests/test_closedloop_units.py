"""Closed forms for small pieces of the one closed loop (simulation.closedloop)
that the whole-run tests exercise only through their effect."""
import math

import casadi as ca
import pytest

from tmtcontrol.simulation.closedloop import damping_schedule

P = {"sched_f_th": 0.5, "k_hat_min": 1e3, "k_hat_max": 1e6, "zeta": 1.0, "b_min": 10.0, "b_max": 500.0,
     "b_rate": 2000.0, "Ts": 1e-3}


def _b(b_prev, f_m, depth, m=1.0, k=100.0, **over):
    return float(ca.DM(damping_schedule(b_prev, f_m, depth, m, k, {**P, **over})))


def test_the_scheduled_damping_moves_towards_eq_25_at_its_rate():
    """eq. (25) online: target 2 zeta sqrt(m (k + k_hat)), k_hat = f_m/depth;
    each period the damping moves towards it by at most b_rate Ts = 2 N s/m."""
    target = 2.0 * math.sqrt(1.0 * (100.0 + 10.0 / 1e-3))          # k_hat = 1e4 N/m: 201.0 N s/m
    assert _b(target - 1.5, 10.0, 1e-3) == pytest.approx(target, rel=1e-12)       # within one step: reached
    assert _b(100.0, 10.0, 1e-3) == pytest.approx(102.0, rel=1e-12)               # far below: +b_rate Ts
    assert _b(300.0, 10.0, 1e-3) == pytest.approx(298.0, rel=1e-12)               # far above: -b_rate Ts
    assert _b(100.0, 10.0, 1e-3, zeta=2.0) == pytest.approx(102.0, rel=1e-12)


def test_the_scheduled_damping_holds_below_the_force_threshold_and_clamps():
    assert _b(123.0, 0.9, 1e-3) == 123.0                  # f_m below 2 x 0.5 N: hold
    assert _b(123.0, 10.0, -1e-3) == 123.0                # no penetration: hold
    # k_hat clamped to 1e6: target 2 sqrt(1e6 + 100) = 2000.1, clamped to b_max = 500, reached at the rate
    assert _b(499.5, 10.0, 1e-9) == pytest.approx(500.0, rel=1e-12)
    assert _b(11.0, 10.0, 1e-3, b_max=10.5, b_min=10.2) == pytest.approx(10.5, rel=1e-12)
