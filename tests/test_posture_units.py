"""The start pose's extra seeds (simulation.posture._start_from_nearby_seeds),
with a stand-in solver whose answer is known: it reaches the true pose q*
only from q* itself, so only a seed that turns the right joint by the right
shift finds it."""
import math

import numpy as np

from tmtcontrol.simulation.posture import SEED_SHIFTS, _start_from_nearby_seeds, pose_solver, solve_pose
from tmtcontrol.simulation.scenario import arm_scenario
from tmtcontrol.simulation.simulator import Simulator, robot_of


def test_a_start_pose_behind_a_wrist_turn_is_found_from_a_shifted_seed():
    sc = arm_scenario("ur5")
    robot = robot_of(sc)
    q_star = Simulator(sc, compile=False).path(sc).q[:, 0]
    T = robot.fk(q_star)
    p, R_d = T[:3, 3], T[:3, :3]
    q_seed = q_star.copy()
    q_seed[3] -= math.pi                       # the wrist turned by a half turn from the pose: SEED_SHIFTS has pi
    assert math.pi in SEED_SHIFTS

    def solver(x0, par, lo, hi):              # reaches q* from q* only; elsewhere stays where it started
        return q_star.copy() if np.allclose(x0, q_star, rtol=0, atol=1e-12) else np.array(x0, dtype=float)

    assert solve_pose(robot, solver, p, R_d, q_seed)[1] is False      # not from the seed itself
    q, ok = _start_from_nearby_seeds(robot, solver, p, R_d, q_seed)
    assert ok and np.array_equal(q, q_star)
    # none of the seeds reaches it when the pose is two joints away: the seed is returned, not ok
    far = q_seed.copy()
    far[1] += 0.3
    q, ok = _start_from_nearby_seeds(robot, solver, p, R_d, far)
    assert not ok and np.array_equal(q, far)


def test_the_tracking_solver_reaches_the_pose_to_its_tolerance():
    """The path's Newton solver (rootfinder, track=True) from a pose 0.05 rad
    away returns one whose tool point and orientation residual are below
    POSE_TOL = 1e-9 (its own absolute tolerances are 1e-13 and 1e-14)."""
    sc = arm_scenario("ur5")
    robot = robot_of(sc)
    q_star = Simulator(sc, compile=False).path(sc).q[:, 0]
    T = robot.fk(q_star)
    track = pose_solver(robot, track=True)
    q, ok = solve_pose(robot, track, T[:3, 3], T[:3, :3], q_star + 0.05)
    assert ok and np.max(np.abs(robot.fk(q)[:3, 3] - T[:3, 3])) < 1e-12


def test_a_path_beyond_a_joint_limit_names_the_joint_and_the_point():
    """The UR5's base turned out of reach (its range narrowed to 0.1 rad,
    well away from both base angles of the start pose): the path check finds
    the pose without the limits, and the one-line error names the joint
    beyond its limit (only that one) and the tool point to 0.1 mm."""
    import dataclasses

    import pytest

    from tmtcontrol.simulation.posture import check_pose_path
    from tmtcontrol.simulation.scenario import ScenarioError

    sc = arm_scenario("ur5")
    robot = robot_of(sc)
    q_star = Simulator(sc, compile=False).path(sc).q[:, 0]
    q_min, q_max = robot.q_min.copy(), robot.q_max.copy()
    q_min[0], q_max[0] = q_star[0] + 1.5, q_star[0] + 1.6
    narrow = dataclasses.replace(robot, q_min=q_min, q_max=q_max)
    T = robot.fk(q_star)
    point = T[:3, 3] + np.array([3.4123e-4, -2.6077e-4, 1.7e-4])     # 4th decimals that 3 or 5 would change
    with pytest.raises(ScenarioError) as err:
        check_pose_path(narrow, point[:, None], T[:3, :3], np.array([0.0]), q_star)
    msg = str(err.value)
    assert "outside the joint limits (shoulder_pan_joint)" in msg, msg
    assert f"at {np.round(point, 4).tolist()} m" in msg and "\n" not in msg
