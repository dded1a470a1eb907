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
    assert rows and all(r.name.endswith("(ur5)") and r.equation == "(1)" and r.passed for r in rows)
    assert any(r.name.startswith("M = Pinocchio crba") for r in rows)     # the independent reference is there
    paper_rows = {r.name for r in run_check_group("derivations", scenario=sc)}
    puma_rows = {r.name for r in run_check_group("derivations")}
    assert len(puma_rows - paper_rows) == len(MODEL_CHECKS)                   # the PUMA's eq. (1) rows left out


def test_the_paper_scenario_checks_the_puma_against_pinocchio():
    rows = run_check_group("model", scenario=paper_scenario())
    assert all(r.name.endswith("(puma560)") and r.passed for r in rows)
    assert any("Pinocchio" in r.name for r in rows)


def test_a_wrong_ur5_mass_matrix_fails_its_rows(monkeypatch):
    from tmtcontrol.model.robot import Robot

    right = Robot.mass_matrix
    monkeypatch.setattr(Robot, "mass_matrix", lambda self, q: 1.01 * np.asarray(right(self, q)))
    rows = {r.name: r for r in run_check_group("model", scenario=load_scenario("ur5"))}
    bad = rows["M = Pinocchio crba (ur5)"]
    assert not bad.passed and bad.residual == pytest.approx(0.01, rel=1e-6)   # 1 % off, exactly what was broken
    assert rows["M symmetric (ur5)"].passed                                    # a scaled M is still symmetric
