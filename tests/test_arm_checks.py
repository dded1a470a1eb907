"""The derivation checks that hold for any arm (``tmtcontrol.checks.arm``,
``tmtcontrol check --scenario``): they pass on the PUMA, the UR5 and the
Panda with the simulator's own expressions, and fail on deliberately broken
variants (a model with another mass, a projector without M^-1, a wrong
impedance filter), which shows each can fail."""
import json

import casadi as ca
import pytest

from tmtcontrol.checks.arm import ARM_RTOL, ArmImplementation, arm_implementation, run_arm_checks
from tmtcontrol.cli import main
from tmtcontrol.model import load_robot
from tmtcontrol.simulation.scenario import load_scenario

ARMS = ("puma560", "ur5", "panda")


def _by_eq(results):
    return {r.equation: r for r in results}


@pytest.mark.parametrize("arm", ARMS)
def test_every_arm_check_passes_on_the_bundled_arms(arm):
    robot = load_robot(arm)
    results = run_arm_checks(ArmImplementation(robot, robot))
    # the 3-joint PUMA has the position-only task: no null space, no rotational axes
    assert len(results) == (2 if arm == "puma560" else 4)
    for r in results:
        assert r.passed, (r.name, r.residual, r.note)
        assert r.tolerance == ARM_RTOL and r.residual <= ARM_RTOL


@pytest.mark.parametrize("n", [4, 5])
def test_a_4_or_5_joint_position_task_checks_its_posture_torque(n):
    """Review 62: `check --scenario` on the UR5 cut after joint 4 or 5 (a position task with the posture task on
    the free joints) left the null-space check out (6-D only). It runs there now and passes with the loop's own
    projector; a projector without M^-1 fails it, and one that removes every torque fails as not moving the
    joints: each way it can fail."""
    from tmtcontrol.simulation.closedloop import operational_space_torque
    from tmtcontrol.simulation.scenario import apply_overrides

    tip = {4: "wrist_1_link", 5: "wrist_2_link"}[n]
    impl = arm_implementation(apply_overrides(load_scenario("ur5"), [f'robot.tip="{tip}"']))
    assert impl.plant.n == n and impl.task_dim == 3
    results = _by_eq(run_arm_checks(impl))
    assert results["(5), null space"].passed and "does move the joints" in results["(5), null space"].note
    assert all(r.passed for r in results.values())
    wrong = _by_eq(run_arm_checks(ArmImplementation(impl.plant, impl.plant, torque=_projector_without_minv)))
    assert not wrong["(5), null space"].passed
    no_posture = lambda M, nb, J, Jd, U, F_e, tau_0=None: operational_space_torque(M, nb, J, Jd, U, F_e, None)
    none = _by_eq(run_arm_checks(ArmImplementation(impl.plant, impl.plant, torque=no_posture)))["(5), null space"]
    assert not none.passed and "does not move the joints" in none.note


def test_the_scenarios_arm_is_the_simulated_one():
    for name, arm, count in (("paper", "puma560", 2), ("ur5", "ur5", 4)):
        impl = arm_implementation(load_scenario(name))
        assert impl.plant.name == arm and impl.model is impl.plant         # ideal inner loop: model = plant
        assert [r.passed for r in run_arm_checks(impl)] == [True] * count


@pytest.mark.parametrize("arm", ARMS)
def test_a_model_with_another_mass_fails_the_loop_checks(arm):
    # 20 % heavier model: the inner loop no longer realises U, so eq. (22) and the other axes' impedance fail
    results = _by_eq(run_arm_checks(ArmImplementation(load_robot(arm), load_robot(arm, mass_scale=1.2))))
    assert not results["(5)-(6)"].passed and results["(5)-(6)"].residual > 1e-2
    assert not results["(19)-(22)"].passed and results["(19)-(22)"].residual > 1e-2
    if arm != "puma560":
        assert not results["(8)-(9), other axes"].passed


def _projector_without_minv(M, n_bias, J, Jdot_dq, U, F_e, tau_0=None):
    """taskframe.operational_space_torque with N^T = I - J^T Lambda J (M^-1 left out)."""
    Linv = ca.mtimes(J, ca.solve(M, J.T, "symbolicqr"))
    tau = ca.mtimes(J.T, ca.solve(Linv, U - Jdot_dq, "symbolicqr") + F_e) + n_bias
    if tau_0 is not None:
        tau = tau + tau_0 - ca.mtimes(J.T, ca.solve(Linv, ca.mtimes(J, tau_0), "symbolicqr"))
    return tau


@pytest.mark.parametrize("arm", ("ur5", "panda"))
def test_a_projector_without_the_inverse_mass_fails_the_null_space_check(arm):
    robot = load_robot(arm)
    results = _by_eq(run_arm_checks(ArmImplementation(robot, robot, torque=_projector_without_minv)))
    assert not results["(5), null space"].passed and results["(5), null space"].residual > 1e-2
    assert results["(5)-(6)"].passed                   # the task part of the torque is still right


def test_a_projector_that_removes_every_torque_fails_on_the_redundant_arm():
    from tmtcontrol.simulation.closedloop import operational_space_torque

    robot = load_robot("panda")
    no_posture = lambda M, n, J, Jd, U, F_e, tau_0=None: operational_space_torque(M, n, J, Jd, U, F_e, None)
    r = _by_eq(run_arm_checks(ArmImplementation(robot, robot, torque=no_posture)))["(5), null space"]
    assert not r.passed and "does not move the joints" in r.note


def test_a_wrong_impedance_filter_fails_the_normal_axis_check():
    robot = load_robot("ur5")
    wrong = lambda F_e, x_a, dx_a, m, b, k: (F_e - b * dx_a + k * x_a) / m          # sign of K flipped
    results = _by_eq(run_arm_checks(ArmImplementation(robot, robot, impedance_acceleration=wrong)))
    assert not results["(19)-(22)"].passed and results["(5)-(6)"].passed


@pytest.fixture
def arm_checks_only(monkeypatch):
    """The paper's, the laws' and the loop's checks left out (tested elsewhere, ~5 s)."""
    from tmtcontrol.checks import derivations, laws, loop

    monkeypatch.setattr(derivations, "run_checks", lambda seed=2024, model=True: [])
    monkeypatch.setattr(loop, "run_loop_checks", lambda seed=2024: [])
    monkeypatch.setattr(laws, "law_checks", lambda law, seed=2024: [])


def test_cli_check_scenario_adds_the_arm_rows(arm_checks_only, capsys):
    assert main(["check", "--scenario", "panda", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    arm = rows[-4:]                      # the loop's rows (checks.arm), after the model's (checks.model)
    assert [r["equation"] for r in arm] == ["(5)-(6)", "(19)-(22)", "(5), null space", "(8)-(9), other axes"]
    model = rows[:-4]
    assert len(model) >= 8 and any("Pinocchio" in r["name"] for r in model)
    assert all(r["passed"] for r in rows) and all("panda" in r["name"] for r in arm)


def test_cli_check_exits_1_when_an_arm_check_fails(arm_checks_only, monkeypatch, capsys):
    import tmtcontrol.checks.arm as arm

    heavy = lambda sc: ArmImplementation(load_robot("ur5"), load_robot("ur5", mass_scale=1.2))
    monkeypatch.setattr(arm, "arm_implementation", heavy)
    assert main(["check", "--scenario", "ur5"]) == 1
    assert "FAIL" in capsys.readouterr().out


@pytest.mark.parametrize("argv, flag", [(["check", "--scenario", "no_such.toml"], "no_such.toml"),
                                        (["check", "--scenario", "paper", "--set"], "--set")])
def test_cli_check_scenario_bad_input_is_one_line_exit_2(argv, flag, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and flag in err and "Traceback" not in err


def test_cli_check_scenario_with_an_arm_that_cannot_be_loaded_is_exit_2(tmp_path, capsys):
    from tmtcontrol.simulation.scenario import dump_scenario

    text = dump_scenario(load_scenario("ur5")).replace('model = "ur5"', 'model = "missing_arm.urdf"')
    assert 'model = "missing_arm.urdf"' in text
    (tmp_path / "arm.toml").write_text(text)
    assert main(["check", "--scenario", str(tmp_path / "arm.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: robot.model: ") and "missing_arm.urdf" in err


def test_the_curved_normal_axis_check_passes_on_the_pipe_and_fails_a_wrong_filter():
    """On a curved part (ur5-pipe: the UR5 outside a cylinder) the normal
    axis check follows the depth along the local normal through the
    surface's chart (eqs. 19-22 at each point, with the ideal inner loop):
    it passes on the running code, and with the impedance filter's K sign
    flipped it fails while the inner-loop check (independent of the filter)
    passes."""
    impl = arm_implementation(load_scenario("ur5-pipe"))
    assert impl.surface.kind == "cylinder" and impl.task_dim == 6
    results = _by_eq(run_arm_checks(impl))
    curved = results["(19)-(22)"]
    assert "on the cylinder" in curved.name
    assert all(r.passed for r in results.values()), [(r.name, r.residual) for r in results.values()]
    wrong = lambda F_e, x_a, dx_a, m, b, k: (F_e - b * dx_a + k * x_a) / m          # sign of K flipped
    bad = _by_eq(run_arm_checks(ArmImplementation(impl.plant, impl.model, impedance_acceleration=wrong,
                                                  surface=impl.surface, path_q=impl.path_q)))
    assert not bad["(19)-(22)"].passed and bad["(19)-(22)"].residual > 1e-2 and bad["(5)-(6)"].passed
