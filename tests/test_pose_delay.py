"""The computation delay in the 6-D task-frame loop (issue 30): the torque
computed at t_k is applied over [t_(k+d), t_(k+d+1)), as in the PUMA's loop.

The identity checked, independent of how the queue is written: the torque
the loop *computes* at t_k is the torque the same loop without delay applies
from the same state (the delay-free step evaluated on the delayed run's
states, the queue left out); the delayed run's logged (applied) torque is
that sequence shifted by d samples, zeros before (the queue starts empty).
The same check runs on the PUMA's loop (``closedloop``), so both loops have
one meaning of ``controller.delay_samples``."""

from __future__ import annotations

import numpy as np
import pytest

from tmtcontrol.simulation.scenario import apply_overrides, load_scenario, paper_scenario

SHORT = ["trajectory.cycles=0.04"]      # 160 periods of the 4 s circle: contact, the law running


def _runs(arm: str, delay: int):
    """(applied torque log of the delayed run (n, N), computed torque at each
    of its states (n, N), its states before each period, n, layout)."""
    from tmtcontrol.simulation.closedloop import build_step, log_layout, state_layout
    from tmtcontrol.simulation.simulator import Simulator

    base = paper_scenario() if arm == "puma560" else load_scenario(arm)
    sc = apply_overrides(base, [*SHORT, f"controller.delay_samples={delay}"])
    sim = Simulator(sc, compile=False)
    U, P, s0, _ = sim.inputs(sc)
    task = sim.task
    n = task.n
    log, layout = log_layout(task), state_layout(task, sim.law, delay)
    step0 = build_step(sim.plant, sim.model, sim.law, delay=0)
    layout0 = state_layout(task, sim.law, 0)
    S, L = sim.rollout.run(s0, U, P)
    before = np.hstack([s0[:, None], S[:, :-1]])                   # the state at t_k
    parts = layout.split(before)
    assert parts["tau_wait"].shape[0] == n * delay
    s_nodelay = np.vstack([parts[k] for k, s in layout0.slices.items() if s.stop > s.start])   # without the queue
    _, L0 = step0.map(U.shape[1])(s_nodelay, U, P)
    computed = np.array(L0)[log["tau"]]
    return L[log["tau"]], computed, parts, n


@pytest.mark.parametrize("arm", ["ur5", "puma560"])
@pytest.mark.parametrize("delay", [1, 2])
def test_applied_torque_is_the_computed_torque_shifted_by_the_delay(arm, delay):
    """Bit for bit: the delayed and the delay-free step evaluate the same
    expressions for the computed torque on CasADi's virtual machine."""
    applied, computed, parts, n = _runs(arm, delay)
    N = applied.shape[1]
    assert np.array_equal(applied[:, :delay], np.zeros((n, delay)))        # the queue starts empty
    assert np.array_equal(applied[:, delay:], computed[:, :N - delay])
    # the queue at t_k holds the torques of t_(k-d) .. t_(k-1), oldest first
    k = N // 2
    assert np.array_equal(parts["tau_wait"][:, k].reshape(delay, n).T, computed[:, k - delay:k])
    # the computed torque is not trivially constant (the identity would not tell a shift)
    assert np.ptp(computed[0, delay:]) > 1e-3


def test_delay_zero_keeps_the_6d_loop_as_before():
    """delay_samples = 0: no queue in the state, the step's name without a
    delay suffix, and the run equal to the one recorded before the 6-D loop
    had a delay (tests/data/ur5_delay0_before_delay.csv: the first 160
    periods of the UR5 scenario, contact force and torques). Bit for bit on
    the machine that recorded it (measured); the tolerance, 1e-12 relative,
    leaves room for another CPU's libm only, far below any change of the
    loop's arithmetic."""
    import pathlib

    from tmtcontrol.simulation.simulator import Simulator
    from tmtcontrol.model.robot import task_of
    from tmtcontrol.simulation.closedloop import state_layout

    sim = Simulator(apply_overrides(load_scenario("ur5"), SHORT), compile=False)
    assert state_layout(task_of(6), sim.law).size == 2 * 6 + 6 + len(sim.law.states)
    assert sim.step.name() == "step_tmt"
    ref = np.loadtxt(pathlib.Path(__file__).parent / "data" / "ur5_delay0_before_delay.csv", delimiter=",")
    r = sim.run()
    assert r.time.size == ref.shape[0] == 160
    np.testing.assert_allclose(r.contact_force, ref[:, 1], rtol=1e-12, atol=1e-12 * np.abs(ref[:, 1]).max())
    np.testing.assert_allclose(r.tau, ref[:, 2:].T, rtol=0, atol=1e-12 * np.abs(ref[:, 2:]).max())
    one = Simulator(apply_overrides(load_scenario("ur5"), [*SHORT, "controller.delay_samples=1"]),
                        compile=False)
    assert one.step.name() == "step_tmt_delay1"
    assert one.step.size1_in(0) == sim.step.size1_in(0) + 6


@pytest.mark.heavy
def test_ur5_scenario_with_a_delay_of_one_sample_converges():
    """The whole UR5 scenario (16 s) with delay 1: every segment converged
    (within controller.force_tolerance) and the tool within 1 mrad of its
    command over the last second (issue 30's bounds)."""
    from tmtcontrol.simulation.metrics import segment_metrics
    from tmtcontrol.simulation.simulator import Simulator

    r = Simulator(apply_overrides(load_scenario("ur5"), ["controller.delay_samples=1"])).run()
    segs = segment_metrics(r)
    # the force tracks in every segment; the 12 s switch drives joint 2 past the URDF's 150 N m (over_limit,
    # tests/test_joint_limits.py), which the verdict says while the force-tracking verdict stays converged
    assert all(s.verdict == "converged" or (s.verdict == "over_limit"
                                            and s.reason.endswith("the force tracking alone: converged"))
               for s in segs), [(s.verdict, s.reason) for s in segs]
    assert max(abs(s.steady_state_error) for s in segs) < 1e-3
    assert r.orientation_error_norm[r.time >= r.time[-1] - 1.0].max() < 1e-3
