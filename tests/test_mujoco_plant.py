"""The controller against MuJoCo's dynamics of the same URDF (issue: a plant nobody here wrote).

With the ideal spring contact the two runs differ only in the rigid-body
dynamics and their integration (tmtcontrol's RK4 of eq. 1 against MuJoCo's
own), so their steady forces agree within the force tolerance's tenth and
their traces within a few mN at the switches (measured 2.5 mN on the UR5's
first 4 s); the logged contact force is the spring of eq. (13) at the
penetration Pinocchio's forward kinematics gives for the logged joints.
"""

import numpy as np
import pytest

from tmtcontrol import Simulator, apply_overrides, load_scenario
from tmtcontrol.cli import main
from tmtcontrol.simulation.geometry import surface_of
from tmtcontrol.simulation.metrics import segment_metrics
from tmtcontrol.simulation.mujoco_plant import simulate_on_mujoco


@pytest.fixture(scope="module")
def ur5_short():
    sc = apply_overrides(load_scenario("ur5"), ["trajectory.cycles=0.5"])
    return simulate_on_mujoco(sc), Simulator(sc).run()


def test_a_short_ur5_run_on_mujoco_tracks_as_the_builtin_plant(ur5_short):
    mj, builtin = ur5_short
    assert mj.info["plant"] == "mujoco (spring contact)"
    (a,), (b,) = segment_metrics(mj), segment_metrics(builtin)
    assert a.verdict == b.verdict == "converged"
    assert abs(a.steady_state_error - b.steady_state_error) < 1e-3
    assert np.max(np.abs(mj.contact_force - builtin.contact_force)) < 5e-3     # N, measured 2.5e-3
    assert np.max(np.abs(mj.q - builtin.q)) < 1e-4                               # rad


def test_the_logged_force_is_k_e_times_the_penetration_pinocchio_gives(ur5_short):
    from tmtcontrol.model.verify import pinocchio_model
    from tmtcontrol.simulation.simulator import robot_of

    mj, _ = ur5_short
    sc = mj.scenario
    robot = robot_of(sc)
    fk = pinocchio_model(robot)
    surface = surface_of(sc)
    k = np.arange(0, mj.time.size, 97)
    depth = np.array([surface.signed_distance(fk(mj.q[:, i], mj.dq[:, i], np.zeros(robot.n))["fk"][:3, 3:])[0]
                      for i in k])
    v_n = np.array([surface.normal(None) @ (np.asarray(robot.jacobian(mj.q[:, i]))[:3] @ mj.dq[:, i]) for i in k])
    expected = np.maximum(mj.stiffness[k] * depth + sc.environment.damping * v_n, 0.0) * (depth > 0)
    np.testing.assert_allclose(mj.contact_force[k], expected, rtol=1e-9, atol=1e-9)


def test_the_puma_and_a_folder_that_is_no_export_are_refused_in_one_line(tmp_path, capsys):
    """The PUMA has no URDF for MuJoCo; the exported C runs against MuJoCo (tests/test_export_6d.py), a
    folder that is not an export is refused before anything runs."""
    assert main(["simulate", "paper", "--plant", "mujoco", "--out", str(tmp_path / "a")]) == 2
    assert "puma560 has no URDF" in capsys.readouterr().err
    assert main(["simulate", "ur5", "--plant", "mujoco", "--controller", str(tmp_path), "--out",
                 str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: --controller:") and "tmtcontrol export" in err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.heavy
@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_the_built_in_arms_on_mujoco_agree_segment_by_segment(arm):
    """The issue's acceptance: every segment's steady-state force within 1e-3 N of the built-in plant's, the
    same verdicts (the limits' included), traces within 0.1 N (the stiffness switches: measured ~0.03 N)."""
    sc = load_scenario(arm)
    mj, builtin = simulate_on_mujoco(sc), Simulator(sc).run()
    for a, b in zip(segment_metrics(mj), segment_metrics(builtin), strict=True):
        assert a.verdict == b.verdict, (a.reason, b.reason)
        assert abs(a.steady_state_error - b.steady_state_error) < 1e-3
    assert np.max(np.abs(mj.contact_force - builtin.contact_force)) < 0.1


def test_crosscheck_prints_both_plants_and_agrees_on_the_ur5(tmp_path, capsys):
    out = tmp_path / "xc"
    assert main(["crosscheck", "ur5", "--set", "trajectory.cycles=0.5", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "ss err MuJoCo" in text and "the plants agree" in text
    import json

    summary = json.loads((out / "crosscheck.json").read_text())
    assert summary["agree"] is True and summary["max_force_difference_N"] < 5e-3
    assert (out / "crosscheck.png").is_file()


def test_crosscheck_disagrees_when_a_plant_misses_the_force(monkeypatch, ur5_short):
    """A MuJoCo run whose steady force is off by twice the tolerance (a planted plant error): not agreed."""
    import dataclasses

    import tmtcontrol.simulation.mujoco_plant as mp
    from tmtcontrol.simulation.crosscheck import crosscheck

    mj, _ = ur5_short
    tol = mj.scenario.controller.force_tolerance
    off = dataclasses.replace(mj, contact_force=mj.contact_force + 2 * tol)
    monkeypatch.setattr(mp, "simulate_on_mujoco", lambda sc, max_steps=None: off)
    c = crosscheck(mj.scenario)
    assert not c.agree and not c.segments[0]["agree"]
    assert c.max_force_difference == pytest.approx(2 * tol, abs=5e-3)


def test_crosscheck_refuses_the_puma_in_one_line(tmp_path, capsys):
    assert main(["crosscheck", "paper", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "crosscheck: puma560 has no URDF" in err and not (tmp_path / "x").exists()
