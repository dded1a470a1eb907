"""The report's eq. (1) rows check the scenario's own arm (issue: the arm's own model in its report).

A UR5 report used to show the PUMA's four eq. (1) rows; with a scenario the
``model`` check group runs :func:`tmtcontrol.model.verify.check_robot` on the
scenario's arm (identities and Pinocchio, an independent implementation) and
the derivations leave the PUMA-only rows out. The rows must fail when the
arm's model is wrong.
"""

import numpy as np
import pytest

from tmtcontrol.checks import check_groups, run_check_group
from tmtcontrol.checks.derivations import MODEL_CHECKS
from tmtcontrol.simulation.scenario import load_scenario, paper_scenario


def test_a_ur5_scenario_checks_the_ur5_model_and_not_the_pumas():
    sc = load_scenario("ur5")
    assert check_groups(sc)[-2:] == ["model", "arm"] and "model" not in check_groups()
    rows = run_check_group("model", scenario=sc)
    identities = [r for r in rows if r.equation == "(1)" and "normal mass" not in r.name]
    assert identities and all(r.name.endswith("(ur5)") for r in identities) and all(r.passed for r in rows)
    assert any(r.name.startswith("M = Pinocchio crba") for r in rows)     # the independent reference is there
    paper_rows = {r.name for r in run_check_group("derivations", scenario=sc)}
    puma_rows = {r.name for r in run_check_group("derivations")}
    assert len(puma_rows - paper_rows) == len(MODEL_CHECKS)                   # the PUMA's eq. (1) rows left out


def test_the_paper_scenario_checks_the_puma_against_pinocchio():
    rows = run_check_group("model", scenario=paper_scenario())
    assert all(r.passed for r in rows) and sum(r.name.endswith("(puma560)") for r in rows) >= 6
    assert any("Pinocchio" in r.name for r in rows)


def test_a_wrong_ur5_mass_matrix_fails_its_rows(monkeypatch):
    from tmtcontrol.model.robot import Robot

    right = Robot.mass_matrix
    monkeypatch.setattr(Robot, "mass_matrix", lambda self, q: 1.01 * np.asarray(right(self, q)))
    rows = {r.name: r for r in run_check_group("model", scenario=load_scenario("ur5"))}
    bad = rows["M = Pinocchio crba (ur5)"]
    assert not bad.passed and bad.residual == pytest.approx(0.01, rel=1e-6)   # 1 % off, exactly what was broken
    assert rows["M symmetric (ur5)"].passed                                    # a scaled M is still symmetric


# -- planted bugs (issue: check that fails on a broken arm loop): each one a user's `check --scenario` must catch


def _flip_rotation_vector(monkeypatch, where):
    import tmtcontrol.simulation.closedloop as closedloop
    import tmtcontrol.simulation.geometry as geometry

    import casadi as ca

    right = geometry.rotation_vector

    def flipped(R):               # the helper with its sign flipped, for NumPy and CasADi input alike
        if isinstance(R, np.ndarray):
            return np.array(flipped(ca.DM(R))).ravel()
        return -right(R)

    for module in where:
        monkeypatch.setattr({"geometry": geometry, "closedloop": closedloop}[module], "rotation_vector", flipped)


def _heavy_checks_out(monkeypatch):
    """The paper's, the laws' and the loop's checks left out (tested elsewhere); the arm's stay."""
    from tmtcontrol.checks import derivations, laws, loop

    monkeypatch.setattr(derivations, "run_checks", lambda seed=2024, model=True: [])
    monkeypatch.setattr(loop, "run_loop_checks", lambda seed=2024: [])
    monkeypatch.setattr(laws, "law_checks", lambda law, seed=2024: [])


@pytest.mark.parametrize("arm", ["ur5", "panda"])
@pytest.mark.parametrize("bug, failing", [
    ("orientation error sign in the controller", "loop orientation error"),
    ("sign inside the shared rotation-vector helper", "rotation vector"),
    ("effective normal mass with M for M^-1", "effective normal mass"),
])
def test_check_scenario_exits_1_on_a_planted_bug(arm, bug, failing, monkeypatch, capsys):
    from tmtcontrol.cli import main

    _heavy_checks_out(monkeypatch)
    if bug.startswith("orientation"):
        _flip_rotation_vector(monkeypatch, ["closedloop"])
    elif bug.startswith("sign inside"):
        _flip_rotation_vector(monkeypatch, ["geometry", "closedloop"])
    else:
        import tmtcontrol.simulation.simulator as simulator

        def wrong(robot, q, n):
            Jv = np.asarray(robot.jacobian(q))[:3]
            return float(1.0 / (n @ Jv @ np.asarray(robot.mass_matrix(q)) @ Jv.T @ n))

        monkeypatch.setattr(simulator, "normal_mass", wrong)
    assert main(["check", "--scenario", arm, "--json"]) == 1, bug
    import json

    rows = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in rows if not r["passed"]][0].startswith(failing), bug


def test_the_unbroken_arms_pass_the_independent_rows():
    from tmtcontrol.checks.model import independent_checks

    for arm in ("ur5", "panda"):
        rows = independent_checks(load_scenario(arm))
        assert [r.passed for r in rows] == [True, True, True], [(r.name, r.residual) for r in rows]
    assert len(independent_checks(paper_scenario())) == 2          # a position task has no orientation error


def test_the_loop_orientation_row_follows_a_curved_parts_turning_frame(monkeypatch):
    """Mutation run 13: on a plane the commanded orientation R_d is the same at every point, so the row's
    branch for a part whose frame turns (its command is the tool orientation on the frame where the commanded
    tangential coordinates meet the part) could be inverted unseen. On a dome under the UR5 the row passes
    with the turning frame (1e-9) and, taken from the fixed R_d instead, the same states are off by far
    more."""
    from tmtcontrol.checks import model as checks_model

    from tmtcontrol.simulation.scenario import apply_overrides

    # a dome: the path starts 0.1 m along task axis 1, 0.33 rad round its 0.3 m radius (on the pipe's start, on
    # its axis's line through the centre, the turning and the fixed frame agree)
    sc = apply_overrides(load_scenario("ur5"), ['environment.shape="sphere"', "environment.radius=0.3"])
    row = checks_model.orientation_error_check(sc, 2024)
    assert row.passed and row.residual <= 1e-9, (row.name, row.residual)

    class Fixed:                         # the pipe, its frame's turning hidden from the check
        def __init__(self, s):
            self._s = s

        def __getattr__(self, name):
            return getattr(self._s, name)

        turns = False

    import tmtcontrol.simulation.geometry as geometry

    real = geometry.surface_of
    monkeypatch.setattr(geometry, "surface_of", lambda scenario: Fixed(real(scenario)))
    wrong = checks_model.orientation_error_check(sc, 2024)
    assert not wrong.passed and wrong.residual > 1e-3, wrong.residual


def test_the_normal_mass_row_without_pinocchio_says_so_and_passes(monkeypatch):
    """Mutation run 13: the row's fallback when Pinocchio cannot model the arm (ImportError or
    NotImplementedError from model.verify.pinocchio_model) was untested: it says "not compared" and
    names why, rather than raising."""
    import tmtcontrol.model.verify as verify
    from tmtcontrol.checks.model import normal_mass_check

    for exc in (ImportError("no module named pinocchio"), NotImplementedError("a joint Pinocchio lacks")):
        def refuse(robot, exc=exc):
            raise exc

        monkeypatch.setattr(verify, "pinocchio_model", refuse)
        row = normal_mass_check(load_scenario("ur5"))
        assert row.passed and row.method == "not compared" and row.note == f"Pinocchio not available: {exc}"
