"""benchmarks/pinocchio_loop.py (the 6-D loop written again with Pinocchio in Python, the
reference of bench_arm.py's speed ratio) is the same closed loop as tmtcontrol's Simulator.

Two implementations of the same equations: Pinocchio's ABA, CRBA, RNEA and frame kinematics
with the controller in NumPy, against tmtcontrol's CasADi step (its own symbolic dynamics of
the URDF). Fed the same inputs (``Simulator.inputs()``), they integrate the same equations
with the same RK4 and contact refinement, so they may differ only by rounding: the operations
are ordered differently (recursive ABA vs. a symbolic solve with M; NumPy's LU vs. CasADi's QR),
about 1e-15 relative per evaluation, and the stable closed loop keeps this from growing much
over 500 steps (measured: 1.6e-12 N on a 12 N force). TOL = 1e-10 N leaves a factor of 60 for
another BLAS or Pinocchio build, and is far below what a change of the equations or of the
step rule gives (tested below: half the RK4 step, or no contact refinement, changes the force
by 3e-8 to 6e-8 N over the same 0.5 s; a dropped term gives far more).
"""
import importlib.util
import pathlib
import sys

import numpy as np
import pytest

from tmtcontrol import Simulator, apply_overrides, load_scenario
from tmtcontrol.simulation.simulator import robot_of

# Pinocchio (imported by the module) is in pyproject's test extra: no skip
ROOT = pathlib.Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("pinocchio_loop", ROOT / "benchmarks" / "pinocchio_loop.py")
pinocchio_loop = sys.modules["pinocchio_loop"] = importlib.util.module_from_spec(_spec)   # dataclasses look it up
_spec.loader.exec_module(pinocchio_loop)

TOL = 1e-10     # N; see the module docstring


@pytest.fixture(scope="module", params=["ur5", "panda"])
def first_half_second(request):
    """The built-in scenario's first 0.5 s (500 steps) in tmtcontrol and on Pinocchio."""
    sc = apply_overrides(load_scenario(request.param), ["trajectory.cycles=0.125"])
    sim = Simulator(sc, compile=False)
    U, P, s0, t = sim.inputs()
    loop = pinocchio_loop.PinocchioLoop(sc, robot_of(sc))
    return sc, sim.run(), loop, (U, P, s0)


def test_contact_force_matches_posesimulator(first_half_second):
    sc, ref, loop, inputs = first_half_second
    run = loop.run(*inputs)
    assert run.contact_force.size == 500 and ref.contact_force.max() > 10.0      # in contact, force built up
    assert run.refined >= 1            # the contact refinement ran (the start on the surface switches it on)
    assert np.abs(run.contact_force - ref.contact_force).max() <= TOL
    assert np.abs(run.measured_force - ref.measured_force).max() <= TOL
    assert np.abs(run.q - ref.q).max() <= 1e-12       # rad: the force's 1e-10 N over k_e = 5000 N/m is 2e-14 m
    assert np.abs(run.orientation_error - ref.orientation_error).max() <= 1e-12     # rad


@pytest.mark.parametrize("change", ["substeps", "refine"])
def test_the_tolerance_tells_a_different_step_rule_apart(first_half_second, change):
    """The comparison can fail: the same Pinocchio loop with half the RK4 step, or without the
    contact refinement, is a different discretisation, and its force differs by more than TOL."""
    sc, ref, loop, inputs = first_half_second
    other = pinocchio_loop.PinocchioLoop(sc, robot_of(sc))
    if change == "substeps":
        other.substeps = 2
    else:
        other.refine = 1
    run = other.run(*inputs)
    assert np.abs(run.contact_force - ref.contact_force).max() > 100 * TOL


def test_the_panda_comparison_sees_the_null_space_posture_task():
    """Without its posture gains the Panda's Pinocchio loop still tracks the task, but the
    redundant joint drifts: the joint angles differ by far more than the 1e-12 rad the
    comparison above allows (measured 0.1 rad), so the null-space term is compared too."""
    from tmtcontrol.control.laws import get_law
    from tmtcontrol.model.robot import task_of
    from tmtcontrol.simulation.closedloop import param_layout

    sc = apply_overrides(load_scenario("panda"), ["trajectory.cycles=0.125"])
    sim = Simulator(sc, compile=False)
    U, P, s0, _ = sim.inputs()
    layout = param_layout(task_of(7), get_law("tmt"))
    P = P.copy()
    P[layout["kp_post"]] = P[layout["kd_post"]] = 0.0
    run = pinocchio_loop.PinocchioLoop(sc, robot_of(sc)).run(U, P, s0)
    assert np.abs(run.q - sim.run().q).max() > 1e-3


def test_refuses_what_it_does_not_implement():
    sc = load_scenario("ur5")
    for override, key in (("controller.law=known", "controller.law"),
                          ("trajectory.approach_gap=0.01", "trajectory.approach_gap"),
                          ("controller.delay_samples=1", "controller.delay_samples"),
                          ("robot.model_mass_scale=1.1", "robot")):
        with pytest.raises(ValueError, match=key):
            pinocchio_loop.PinocchioLoop(apply_overrides(sc, [override]), robot_of(sc))


def test_docs_speed_table_is_the_committed_benchmark_run():
    """docs/robots.md's speed table is benchmarks/bench_arm.py's table of its committed JSON
    (regenerate both with ``python benchmarks/bench_arm.py`` then ``--markdown``); the
    accuracy figures of that run meet issue 30's bound, and the Pinocchio loop agreed with the
    compiled rollout over the whole 16 s to rounding (1e-9 N: TOL above, with room for 32x
    as many steps)."""
    import json

    spec = importlib.util.spec_from_file_location("bench_arm", ROOT / "benchmarks" / "bench_arm.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    doc = json.loads((ROOT / "benchmarks" / "arm_results.json").read_text())
    assert bench.markdown_table(doc) in (ROOT / "docs" / "robots.md").read_text()
    rows = {r["arm"]: r for r in doc["rows"]}
    assert list(rows) == ["puma560", "ur5", "panda"]
    for arm, r in rows.items():
        assert r["steps"] == 16000 and r["cvodes_error_N"] <= 1e-3, arm
        if arm != "puma560":
            assert r["pinocchio_difference_N"] <= 1e-9, arm
