"""Derivation checks: they pass on the implementation and fail on injected faults."""
import json
import subprocess
import sys
import types

import casadi as ca
import numpy as np
import pytest

from tmtcontrol import stability
from tmtcontrol.checks import derivations
from tmtcontrol.control.laws import tmt as reference
from tmtcontrol.cli import main
from tmtcontrol.checks.derivations import Implementation, run_checks


@pytest.fixture(scope="module")
def default_impl():
    return Implementation()


@pytest.fixture(scope="module")
def results(default_impl):
    return {r.name: r for r in run_checks(default_impl)}


def test_all_checks_pass(results):
    assert len(results) == 13
    failed = [r.name for r in results.values() if not r.passed]
    assert not failed
    for r in results.values():
        assert r.residual <= r.tolerance and r.claim and r.method and r.equation


def test_eq18_reports_the_discrepancy(results):
    r = results["f_e = 0 branch and L'Hopital limit"]
    assert "f_d/k + f_d/k_e" in r.claim and "contact" in r.note


def failing(impl):
    return {r.equation for r in run_checks(impl) if not r.passed}


def robot_with(base, **overrides):
    """A stand-in robot: every Function of ``base`` but the ones overridden."""
    ns = types.SimpleNamespace(**{k: v for k, v in vars(base).items()})
    for k, v in overrides.items():
        setattr(ns, k, v)
    return ns


def sign_flipped_tmt(x, f_e, x_e, f_d, k, f_th, k_min):
    return 2 * x_e - reference.tmt_reference(x, f_e, x_e, f_d, k, f_th, k_min) + 0 * x


def wrong_branch_tmt(x, f_e, x_e, f_d, k, f_th, k_min):
    full = reference.tmt_reference(x, f_e, x_e, f_d, k, f_th, k_min)
    return ca.if_else(f_e < 2 * f_th, x_e, full) if isinstance(full, ca.SX) else (x_e if f_e < 2 * f_th else full)


def no_force_feedforward(D, h, U, F_e):
    return ca.mtimes(D, U) + h


def flipped_damping_inner_loop(ddXc, dXc, Xc, dX, X, kd, kp):
    return ddXc - kd * (dXc - dX) + kp * (Xc - X)


def missing_term_delta(x, f_e, x_e, f_d, k):
    return f_d * (k * (x - x_e)) / (k * f_e)


def loop_torque_without_jdot(M, n, J, Jdot_dq, U, F_e, tau_0=None):
    """Review 24's mutant: the loop's torque without - J-dot dq (its paper run off by 60 mN, 6x the tolerance)."""
    from tmtcontrol.simulation.closedloop import operational_space_torque

    return operational_space_torque(M, n, J, 0 * Jdot_dq, U, F_e, tau_0)


def loop_torque_general_form_off(M, n, J, Jdot_dq, U, F_e, tau_0=None):
    """The general (redundant-arm) form 0.01 % off; the square form right."""
    from tmtcontrol.simulation.closedloop import operational_space_torque

    tau = operational_space_torque(M, n, J, Jdot_dq, U, F_e, tau_0)
    return tau if tau_0 is None else 1.0001 * tau


@pytest.mark.parametrize("change,expected", [
    # review 24: rows (7), (8)-(9) checked impedance.control_force, which the loop does not call; the loop's
    # joint torque now enters (7)
    (dict(joint_torque=loop_torque_without_jdot), {"(7)"}),
    (dict(joint_torque=loop_torque_general_form_off), {"(7)"}),
    (dict(tmt_reference=sign_flipped_tmt), {"(16)-(17)", "(19)-(22)", "(23)-(24)"}),
    (dict(tmt_reference=wrong_branch_tmt), {"(18)"}),
    (dict(tmt_delta=missing_term_delta), {"(16)-(17)", "(18)"}),
    (dict(control_force=no_force_feedforward), {"(7)", "(8)-(9)"}),
    # (8)-(9) evaluates at matched velocities (Xc' = X'), where K_D drops out
    (dict(inner_loop=flipped_damping_inner_loop), {"(7)"}),
    (dict(k_eff=lambda k, k_e: k + k_e), {"(11)-(12)", "(14)-(15)", "(16)-(17)"}),
    (dict(known_reference=lambda x_e, f_d, k, k_e: x_e + f_d / k), {"(11)-(12)", "(16)-(17)"}),
    # eq. (7) holds for any X_a, so only the impedance checks can see this one
    (dict(impedance_acceleration=lambda F, xa, dxa, m, b, k: (F - b * dxa + k * xa) / m), {"(8)-(9)", "(11)-(12)"}),
    (dict(impedance_gains=lambda m, b, k: (tuple(b), tuple(k))), {"(8)-(9)"}),
    (dict(critical_damping=lambda m, k, k_e: np.sqrt(m * (k + k_e))), {"(25)"}),
    (dict(tmt_error_tf=lambda m, b, k, k_e: stability.tmt_error_tf(m, b, k, 2 * k_e)), {"(19)-(22)", "(25)"}),
])
def test_injected_law_faults_are_caught(default_impl, change, expected):
    impl = Implementation(robot=default_impl.robot, model=default_impl.model, **change)
    fails = failing(impl)
    assert expected <= fails, fails


def test_injected_robot_faults_are_caught(default_impl):
    rob = default_impl.robot
    q, dq = rob.q, rob.dq
    M = rob.expr["M"]
    asym = ca.Function("mass_matrix", [q], [M + 0.01 * ca.vertcat(ca.horzcat(0, 1, 0), ca.SX.zeros(2, 3))])
    bad_C = ca.Function("coriolis_matrix", [q, dq], [0.5 * rob.expr["C"]])
    no_jinv = ca.Function("cartesian_inertia", [q], [M])
    no_gravity = ca.Function("cartesian_bias", [q, dq], [rob.expr["h"] - ca.solve(rob.expr["J"].T, rob.expr["g"])])
    mk = lambda **o: Implementation(robot=robot_with(rob, **o), model=default_impl.model)
    names = lambda impl: {r.name for r in run_checks(impl) if not r.passed}
    assert "mass matrix symmetric positive definite" in names(mk(mass_matrix=asym))
    assert "dM/dt - 2C skew-symmetric" in names(mk(coriolis_matrix=bad_C))
    assert "Cartesian inertia" in names(mk(cartesian_inertia=no_jinv))
    assert {"Cartesian form consistent with joint space", "closed-loop error dynamics"} & names(mk(cartesian_bias=no_gravity))


def test_a_crashing_implementation_fails_its_check(default_impl):
    def boom(*a):
        raise ZeroDivisionError("boom")

    res = run_checks(Implementation(robot=default_impl.robot, model=default_impl.model, k_eff=boom))
    crashed = [r for r in res if r.method == "raised"]
    assert crashed and not any(r.passed for r in crashed)


@pytest.mark.heavy
def test_cli_check_table_and_json(monkeypatch, capsys):
    # one real run of the command (JSON); the table renders the same results in-process
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "check", "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    from tmtcontrol.control.laws import laws

    # 13 paper checks, then 2 per law plus one per documented polynomial, then 3 loop checks and the
    # analysed-vs-simulated loop beyond the paper (checks.loop.check_extensions: delay, filter, m != 1, mass error)
    assert len(data) == 13 + sum(2 + (law.characteristic_polynomial is not None) for law in laws().values()) + 3 + 1
    assert all(item["passed"] for item in data)
    for item in data:
        assert {"name", "equation", "claim", "method", "residual", "passed"} <= set(item)
    assert any(item["equation"] == "(18)" for item in data)
    import tmtcontrol.checks as checks_pkg
    from tmtcontrol.checks.derivations import CheckResult

    monkeypatch.setattr(checks_pkg, "all_checks", lambda **kw: [CheckResult(**d) for d in data])
    assert main(["check"]) == 0
    out = capsys.readouterr().out
    assert f"{len(data)} passed, 0 failed" in out and "(22)" in out and "integral: characteristic polynomial" in out


def test_cli_check_exits_1_on_failure(monkeypatch, capsys, default_impl):
    orig = derivations.run_checks
    bad = Implementation(robot=default_impl.robot, model=default_impl.model, tmt_delta=missing_term_delta)
    monkeypatch.setattr(derivations, "run_checks", lambda **kw: orig(bad))
    assert main(["check"]) == 1
    assert "FAIL" in capsys.readouterr().out
