"""The 6-D task-frame loop on arms from load_robot (issue 30): scenario keys,
orientation error, operational-space torque and null space, start posture and
path check, the built-in UR5 and Panda scenarios."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from tmtcontrol.simulation.scenario import (ScenarioError, apply_overrides, arm_scenario, load_scenario,
                                            paper_scenario, scenario_from_dict, scenario_to_dict)


# -- scenario -------------------------------------------------------------------------------------

def test_default_robot_is_the_puma_and_the_paper_scenario_keeps_its_plane():
    sc = paper_scenario()
    assert sc.robot.model == "puma560" and sc.robot.tip is None and sc.robot.q0 is None
    assert sc.environment.normal is None and sc.environment.tilt_deg == 45.0


def test_tilt_shorthand_is_the_normal_it_stands_for():
    from tmtcontrol.simulation.environment import task_frame
    from tmtcontrol.simulation.geometry import surface_frame

    t = math.radians(30.0)
    sc = apply_overrides(arm_scenario("ur5"), [f"environment.normal=[{math.sin(t)!r}, 0.0, {-math.cos(t)!r}]"])
    # the same frame from the normal as from the tilt (rounding of sin/cos only)
    assert np.allclose(surface_frame(sc.environment), task_frame(30.0), atol=1e-15)
    R = surface_frame(sc.environment)
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-15) and np.isclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("change, key", [
    ({"environment": {"normal": [0.0, 0.0, -2.0]}}, "environment.normal"),
    ({"environment": {"point": [0.0, 0.0, 0.0]}}, "trajectory.center"),
])
def test_bad_plane_is_one_line_naming_the_key(change, key):
    d = {"robot": {"model": "ur5"}, "environment": {"normal": [0.0, 0.0, -1.0]}}
    for k, v in change.items():
        d[k] = {**d.get(k, {}), **v}
    with pytest.raises(ScenarioError) as exc:
        scenario_from_dict(d)
    assert str(exc.value).startswith(key) and "\n" not in str(exc.value)


def test_the_puma_takes_a_plane_by_its_normal(tmp_path):
    """Issue 38 listed "the PUMA refuses environment.normal" among the one
    loop's consequences; the scenario still refused it by the arm's name. The
    normal of the 45 deg tilt gives the tilt's run bit for bit (the same task
    frame to rounding, the same loop), and another plane runs and tracks f_d."""
    from tmtcontrol.simulation.metrics import segment_metrics
    from tmtcontrol.simulation.simulator import simulator_for

    t = math.radians(45.0)
    base = apply_overrides(paper_scenario(), ["trajectory.cycles=0.25"])
    d = scenario_to_dict(base)
    d["environment"].pop("tilt_deg")
    by_tilt = base
    by_normal = scenario_from_dict({**d, "environment": {**d["environment"],
                                                          "normal": [math.sin(t), 0.0, -math.cos(t)]}})
    a, b = (simulator_for(sc).run(sc) for sc in (by_tilt, by_normal))
    assert np.array_equal(a.contact_force, b.contact_force) and np.array_equal(a.q, b.q)
    other = scenario_from_dict({**d, "environment": {**d["environment"], "normal": [0.0, 0.5, -math.sqrt(0.75)]}})
    r = simulator_for(other).run(other)
    (seg,) = segment_metrics(r)
    # the plane of that normal through the centre: the tool sits f_e / k_e inside it along the normal
    # (the contact spring), to 1 um (the 0.25 s run's remaining transient is far below that)
    n = np.array([0.0, 0.5, -math.sqrt(0.75)])
    depth = n @ (r.position[:, -1] - np.array(other.trajectory.center))
    assert depth == pytest.approx(r.contact_force[-1] / 5000.0, abs=1e-6) and depth > 1.5e-3
    assert abs(seg.steady_state_error) < 1e-3       # 1 mN: the paper's steady tracking (157 uN on the tilt)


def test_plane_point_on_the_plane_is_accepted():
    # the point 0.1 m along e_1 from the centre lies on the plane
    sc = scenario_from_dict({"robot": {"model": "ur5"}, "environment": {"normal": [0.0, 0.0, -1.0],
                             "point": [0.5, -0.05, 0.55]}, "trajectory": {"center": [0.5, -0.15, 0.55]}})
    assert sc.environment.point == (0.5, -0.05, 0.55)


def test_builtin_arm_scenarios_load_by_name_and_round_trip(tmp_path):
    from tmtcontrol.simulation.scenario import dump_scenario

    for name in ("ur5", "panda"):
        sc = load_scenario(name)
        assert sc.robot.model == name and sc.controller.f_d == 10.0 and sc.controller.rate == 1000.0
        assert sc.environment.stiffness.values == paper_scenario().environment.stiffness.values
        f = tmp_path / f"{name}.toml"
        f.write_text(dump_scenario(sc))
        assert load_scenario(f) == sc


# -- orientation error ----------------------------------------------------------------------------

def test_rotation_vector_matches_scipy_for_every_angle_below_pi():
    from scipy.spatial.transform import Rotation

    from tmtcontrol.simulation.geometry import rotation_vector

    rng = np.random.default_rng(3)
    for angle in (0.0, 1e-12, 1e-7, 1e-3, 0.5, 2.0, 3.0, math.pi - 1e-3):
        axis = rng.standard_normal(3)
        r = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle)
        # atan2 form: rounding of the matrix entries only (1e-12 rad near pi, where sin is small)
        assert np.allclose(rotation_vector(r.as_matrix()), r.as_rotvec(), atol=1e-12), angle


# -- inner loop: eqs. (5)-(6) as operational-space computed torque -------------------------------

def _numeric_torque(robot, q, dq, U, F_e, tau_0):
    from tmtcontrol.simulation.closedloop import operational_space_torque

    f = robot.functions
    return np.array(ca.DM(operational_space_torque(f.mass_matrix(q), f.bias(q, dq), f.jacobian(q),
                                                   f.jacobian_dot(q, dq), ca.DM(U), ca.DM(F_e),
                                                   None if tau_0 is None else ca.DM(tau_0)))).ravel()


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_exact_model_gives_the_commanded_task_acceleration_and_posture_does_not_disturb_it(name):
    """Eq. (5) with D*^ = D*: the plant's task acceleration J ddq + dJ dq
    equals U when the contact force is measured exactly; a null-space torque
    (redundant Panda) leaves it unchanged (J M^-1 N^T = 0)."""
    from tmtcontrol.model import load_robot

    robot = load_robot(name, friction=False)          # the torque below compensates no friction
    rng = np.random.default_rng(7)
    n = robot.n
    for _ in range(3):
        q = rng.uniform(-1, 1, n) * 0.8 + (robot.q_min + robot.q_max) / 2 * np.isfinite(robot.q_min)
        q = np.clip(q, robot.q_min, robot.q_max)
        dq, U, F_e = rng.standard_normal(n), rng.standard_normal(6), np.r_[rng.standard_normal(3), 0, 0, 0]
        J = robot.jacobian(q)
        Jdot_dq = np.array(robot.functions.jacobian_dot(q, dq)).ravel()
        for tau_0 in (None, 50 * rng.standard_normal(n)):
            tau = _numeric_torque(robot, q, dq, U, F_e, tau_0)
            ddq = robot.forward_dynamics(q, dq, tau - J.T @ F_e)       # the plant, contact F_e on the tip
            # a linear solve of a conditioned system: rounding well below 1e-8
            assert np.allclose(J @ ddq + Jdot_dq, U, atol=1e-8), (name, tau_0 is None)
    if n > 6:
        t0 = 50 * rng.standard_normal(n)
        d = _numeric_torque(robot, q, dq, U, F_e, t0) - _numeric_torque(robot, q, dq, U, F_e, None)
        assert np.abs(d).max() > 1.0                                   # the posture torque acts ...
        assert np.abs(J @ np.linalg.solve(robot.mass_matrix(q), d)).max() < 1e-9   # ... in the null space


# -- path check ------------------------------------------------------------------------------------

@pytest.mark.parametrize("arm, changes, reason", [
    ("ur5", {"trajectory.center": [1.5, 0.0, 0.2]}, "unreachable"),
    ("ur5", {"trajectory.center": [0.0, 0.0, 0.5]}, "near a singularity"),
    ("panda", {"trajectory.center": [0.45, 0.1, 0.35], "trajectory.tool_spin_deg": 0.0,
               "environment.normal": [math.sin(math.pi / 4), 0.0, -math.cos(math.pi / 4)]},
     "outside the joint limits"),
])
def test_bad_path_is_refused_with_its_time_and_reason(arm, changes, reason):
    from tmtcontrol.simulation.simulator import path_of, robot_of

    sc = apply_overrides(arm_scenario(arm), [f"{k}={v!r}" for k, v in changes.items()])
    with pytest.raises(ScenarioError) as exc:
        path_of(robot_of(sc), sc)
    msg = str(exc.value)
    assert msg.startswith("trajectory: at path time t = ") and reason in msg and "\n" not in msg


def test_builtin_paths_are_checked_against_pinocchio():
    """The solved path poses put the tool on the circle with the commanded
    orientation, measured by Pinocchio's forward kinematics (independent of
    tmtcontrol's), within the joint limits and above the singularity bound."""
    pin = pytest.importorskip("pinocchio")
    from tmtcontrol.simulation.geometry import surface_frame, tool_orientation
    from tmtcontrol.simulation.simulator import path_of, robot_of
    from tmtcontrol.simulation.posture import MIN_SINGULAR_VALUE
    from tmtcontrol.simulation.trajectory import circle_reference

    for name in ("ur5", "panda"):
        sc = arm_scenario(name)
        robot = robot_of(sc)
        path = path_of(robot, sc)
        model = pin.buildModelFromXML(robot.urdf)
        data = model.createData()
        fid = model.getFrameId(robot.tip)
        R = surface_frame(sc.environment)
        R_d = tool_orientation(R, sc.trajectory.tool_spin_deg)
        ref = circle_reference(path.t, sc.trajectory.radius, sc.trajectory.period)
        for k in range(0, path.t.size, 9):
            qf = pin.neutral(model)
            idx = [model.joints[model.getJointId(j)].idx_q for j in robot.joint_names]
            qf[idx] = path.q[:, k]
            pin.framesForwardKinematics(model, data, qf)
            M = data.oMf[fid]
            target = np.asarray(sc.trajectory.center) + R @ np.r_[0.0, ref.pos[:, k]]
            assert np.abs(M.translation - target).max() < 1e-8           # POSE_TOL 1e-9 plus FK rounding
            assert np.abs(M.rotation - R_d).max() < 1e-8
        assert np.all(path.q >= robot.q_min[:, None]) and np.all(path.q <= robot.q_max[:, None])
        assert path.sigma_min.min() >= MIN_SINGULAR_VALUE


# -- closed loop -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ur5_short():
    from tmtcontrol.simulation.simulator import Simulator

    sc = apply_overrides(arm_scenario("ur5"), ["trajectory.cycles=0.5"])
    return Simulator(sc, compile=False).run()


def test_ur5_short_run_tracks_force_and_holds_orientation(ur5_short):
    """2 s of the UR5 scenario: after the first-contact transient (settles in
    ~0.12 s) the force is within 1e-3 N of f_d and the tool within 1 mrad of
    its command (the issue's steady-state bounds)."""
    r = ur5_short
    late = r.time >= 1.5
    assert np.abs(r.force_error[late]).max() < 1e-3
    assert r.orientation_error_norm[late].max() < 1e-3
    assert r.q.shape == (6, r.time.size)


def test_contact_force_is_stiffness_times_tip_penetration_from_logged_joints(ur5_short):
    """f_e = k_e d with d the tip's penetration along the inward normal,
    computed from the logged joints by Pinocchio's forward kinematics."""
    pin = pytest.importorskip("pinocchio")
    from tmtcontrol.simulation.geometry import surface_frame
    from tmtcontrol.simulation.simulator import robot_of

    r = ur5_short
    robot = robot_of(r.scenario)
    model = pin.buildModelFromXML(robot.urdf)
    data = model.createData()
    fid = model.getFrameId(robot.tip)
    e_n = surface_frame(r.scenario.environment)[:, 0]
    c = np.asarray(r.scenario.trajectory.center)
    ks = np.arange(0, r.time.size, 97)
    pen = np.empty(ks.size)
    for i, k in enumerate(ks):
        qf = pin.neutral(model)
        qf[:robot.n] = r.q[:, k]
        pin.framesForwardKinematics(model, data, qf)
        pen[i] = e_n @ (data.oMf[fid].translation - c)
    expected = r.stiffness[ks] * np.maximum(pen, 0.0)
    # FK agreement ~1e-15 m times k_e = 5e3 N/m: 1e-9 N is ample
    assert np.abs(r.contact_force[ks] - expected).max() < 1e-9
    assert pen[1:].min() > 0                                           # in contact along the run


def test_cli_prints_the_ur5_scenario_and_refuses_an_unreachable_path(tmp_path, capsys):
    from tmtcontrol.cli import main
    from tmtcontrol.simulation.scenario import dump_scenario

    assert main(["scenario", "ur5"]) == 0
    assert capsys.readouterr().out == dump_scenario(arm_scenario("ur5"))
    bad = tmp_path / "far.toml"
    bad.write_text(dump_scenario(apply_overrides(arm_scenario("ur5"), ["trajectory.center=[1.5, 0.0, 0.2]"])))
    out = tmp_path / "out"
    assert main(["simulate", str(bad), "--out", str(out), "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "path time t = 0.000 s" in err[0] and "unreachable" in err[0]
    assert not out.exists()


@pytest.mark.heavy
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_builtin_arm_scenario_converges_on_every_segment(name):
    """The paper's experiment on the arm: each 4 s segment's last second within
    1e-3 N of f_d, the tool within 1 mrad of its command."""
    from tmtcontrol.simulation.simulator import Simulator

    r = Simulator(arm_scenario(name)).run()
    for i in range(4):
        k = (r.time >= 4 * i + 3) & (r.time < 4 * i + 4)
        assert np.abs(r.force_error[k]).max() < 1e-3, (name, i)
        assert r.orientation_error_norm[k].max() < 1e-3, (name, i)


def test_sweep_and_compare_run_on_the_ur5(tmp_path):
    """A sweep file names the built-in 'ur5' scenario; its cases run the 6-D
    loop (the x_e error shifts the surface estimate: the TMT still converges)."""
    from tmtcontrol.simulation.compare import compare_laws
    from tmtcontrol.sweep.run import case_row
    from tmtcontrol.sweep.spec import load_sweep

    f = tmp_path / "s.toml"
    f.write_text('scenario = "ur5"\n[grid]\n"controller.x_e_error" = [0.002]\n"trajectory.cycles" = [0.25]\n')
    sw = load_sweep(f)
    assert sw.base["robot"]["model"] == "ur5"
    row = case_row(sw.base, sw.cases[0], limits=False)    # the UR5's limits: test_stability_6d
    assert row["verdict"] == "converged", row
    cmp = compare_laws(apply_overrides(arm_scenario("ur5"), ["trajectory.cycles=0.25"]), ["tmt"])
    assert cmp.runs["tmt"].result.q.shape[0] == 6


def test_analyze_scenario_uses_the_arms_effective_normal_mass():
    """analyze --scenario on the UR5: m_p is 1/(n^T J_v M^-1 J_v^T n) along
    the path, checked by its physical meaning: a unit force along n on the
    tip of the arm at rest (gravity held) accelerates the tip along n by
    1/m_p (forward dynamics, independent of the formula)."""
    from tmtcontrol.simulation.geometry import surface_frame
    from tmtcontrol.simulation.simulator import path_of, robot_of
    from tmtcontrol.stability.analysis import analyze_scenario, scenario_parameters

    sc = arm_scenario("ur5")
    p = scenario_parameters(sc)
    robot = robot_of(sc)
    n = surface_frame(sc.environment)[:, 0]
    acc = []
    for q in path_of(robot, sc).q.T:
        Jv = robot.jacobian(q)[:3]
        ddq = robot.forward_dynamics(q, np.zeros(6), robot.gravity(q) + Jv.T @ n)
        acc.append(n @ Jv @ ddq)
    # one linear solve each: rounding ~1e-12 relative
    assert np.isclose(p["m_p_min"], 1 / max(acc), rtol=1e-9) and np.isclose(p["m_p_max"], 1 / min(acc), rtol=1e-9)
    out = analyze_scenario(sc, points=1)       # one path point: the 6-D whole loop runs too (tests/test_stability_6d.py)
    assert list(out["m_p"]) == [p["m_p_min"], p["m_p_max"]] and out["whole_loop_limit"] > 0


def test_cli_simulates_the_ur5_briefly(tmp_path, capsys):
    from tmtcontrol.cli import main

    out = tmp_path / "run"
    assert main(["simulate", "ur5", "--set", "trajectory.cycles=0.25", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "scenario 'ur5': 1000 steps of 1 ms" in text
    # the PUMA's four figures and the orientation error of a 6-D arm
    assert {p.name for p in out.glob("*.png")} == {"fig3_stiffness.png", "fig4_force.png", "fig5_position.png",
                                                   "path3d.png", "orientation_error.png"}
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[15:21] == [f"q{i}" for i in range(1, 7)] and header[-3:] == ["e_n", "e_1", "e_2"]


def test_robot_model_path_is_read_relative_to_the_scenario_file(tmp_path):
    """A user's URDF next to the scenario file: the path resolves against the
    file's folder and the arm loads with the named tip; a missing file is one
    line naming robot.model."""
    from importlib import resources

    from tmtcontrol.simulation.simulator import robot_of
    from tmtcontrol.simulation.scenario import dump_scenario

    (tmp_path / "arms").mkdir()
    urdf = resources.files("tmtcontrol.model").joinpath("data", "ur5.urdf").read_text()
    (tmp_path / "arms" / "my_arm.urdf").write_text(urdf)
    sc = apply_overrides(arm_scenario("ur5"), ['robot.model="arms/my_arm.urdf"', 'robot.tip="tool0"'])
    f = tmp_path / "my.toml"
    f.write_text(dump_scenario(sc))
    loaded = load_scenario(f)
    assert loaded.robot.model == str(tmp_path / "arms" / "my_arm.urdf")
    robot = robot_of(loaded)
    assert robot.n == 6 and robot.tip == "tool0"
    missing = apply_overrides(sc, ['robot.model="nowhere.urdf"'])
    with pytest.raises(ScenarioError) as exc:
        robot_of(missing)
    assert str(exc.value).startswith("robot.model: ") and "\n" not in str(exc.value)


def test_start_posture_seed_of_the_wrong_length_is_one_line():
    from tmtcontrol.simulation.simulator import path_of, robot_of

    sc = apply_overrides(arm_scenario("ur5"), ["robot.q0=[0.0, 0.1, 0.2]"])
    with pytest.raises(ScenarioError, match=r"^robot\.q0: expected 6 values"):
        path_of(robot_of(sc), sc)


@pytest.mark.heavy           # the law-loop limit search of the report line takes seconds
def test_a_segment_off_target_on_the_ur5_is_reported_and_exits_1(tmp_path, capsys):
    """The 'known' law told the wrong stiffness (2e4 N/m instead of 5e3) misses
    f_d on the UR5: the run still writes its outputs, prints the segment with
    the 1-D prediction and the first-contact limit of the 6-D loop and exits 1."""
    from tmtcontrol.cli import main

    out = tmp_path / "run"
    rc = main(["simulate", "ur5", "--set", "trajectory.cycles=0.25", "--set", "controller.law=known",
               "--set", "controller.law.assumed_stiffness=2e4", "--out", str(out), "--no-plots"])
    err = capsys.readouterr().err
    assert rc == 1 and (out / "timeseries.csv").exists()
    # the loop's own limit of the 6-D loop (as analyze --scenario), the 1-D figure labelled small-signal
    assert "segment 1" in err and "the loop's limit " in err and "1-D small-signal " in err
    assert "could not be computed" not in err


def test_square_jacobian_shortcut_equals_the_lambda_form_of_eq_5():
    """UR5 (square J): operational_space_torque uses tau = M J^-1 (U - dJ dq) + J^T F_e + n;
    NumPy's Lambda form J^T ((J M^-1 J^T)^-1 (U - dJ dq) + F_e) + n is the reference. Equal to
    rounding: 1e-9 relative of |tau| (cond(J) on these states is below 1e3)."""
    from tmtcontrol.model import load_robot

    robot = load_robot("ur5", friction=False)
    f = robot.functions
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = np.clip(rng.uniform(-1.5, 1.5, 6), robot.q_min, robot.q_max)
        dq, U, F_e = rng.standard_normal(6), rng.standard_normal(6), np.r_[rng.standard_normal(3), 0, 0, 0]
        M, J = np.array(f.mass_matrix(q)), robot.jacobian(q)
        assert np.linalg.cond(J) < 1e3
        jd, nb = np.array(f.jacobian_dot(q, dq)).ravel(), np.array(f.bias(q, dq)).ravel()
        ref = J.T @ (np.linalg.inv(J @ np.linalg.solve(M, J.T)) @ (U - jd) + F_e) + nb
        got = _numeric_torque(robot, q, dq, U, F_e, None)
        assert np.allclose(got, ref, rtol=0, atol=1e-9 * np.abs(ref).max()), (got, ref)


def test_a_seed_the_pumas_closed_form_does_not_use_is_refused(tmp_path):
    """Issue 43: robot.q0 on the PUMA was accepted and silently ignored (its path
    is solved in closed form, one configuration): now one line, exit 2."""
    import subprocess
    import sys

    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "paper", "--set", "robot.q0=[0.1, 0.2, 0.3]",
                        "--out", str(out), "--no-plots"], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "robot.q0: not used" in r.stderr and not out.exists()


def test_an_override_of_the_plane_replaces_the_bases_other_form():
    """`--set environment.normal=...` on the paper scenario failed: the base's
    dump carries tilt_deg = 45, which --set cannot remove ("drop tilt_deg").
    An override of the normal replaces the base's tilt and one of the tilt the
    base's normal; both given must still agree."""
    from tmtcontrol.simulation.environment import task_frame
    from tmtcontrol.simulation.geometry import surface_frame

    n = [0.0, 0.5, -math.sqrt(0.75)]
    sc = apply_overrides(paper_scenario(), [f"environment.normal={n}"])
    assert sc.environment.normal == tuple(n)
    assert np.allclose(surface_frame(sc.environment)[:, 0], n, atol=1e-15)
    ur5 = apply_overrides(arm_scenario("ur5"), ["environment.tilt_deg=30"])
    assert ur5.environment.normal is None
    assert np.allclose(surface_frame(ur5.environment), task_frame(30.0), atol=1e-15)
    with pytest.raises(ScenarioError, match=r"^environment\.tilt_deg: 45 deg is not the plane"):
        apply_overrides(paper_scenario(), [f"environment.normal={n}", "environment.tilt_deg=45"])
