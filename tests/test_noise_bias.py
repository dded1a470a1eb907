"""A large sensor noise must not hide a bias (review of issue 28's verdicts).

The verdict allows 6 sensor-noise sigmas on |f_e - f_d| (the ripple the noise
drives), but a bias does not average out: the mean error over the last quarter
is held to the scenario's tolerance alone."""
import numpy as np
import pytest

from tmtcontrol import apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.control.laws import get_law
from tmtcontrol.simulation.metrics import judge_segment

F_D = 10.0
N = 4000                                   # a 4 s segment at 1 kHz
T = np.arange(N) * 1e-3
RIPPLE = 0.3 * np.sin(2 * np.pi * 50 * T)  # zero mean over every whole 20 ms period: a noise-driven ripple


@pytest.mark.parametrize("bias, verdict", [(0.0, "converged"), (0.009, "converged"), (0.011, "off_target"),
                                           (-0.05, "off_target")])
def test_the_mean_error_is_held_to_the_tolerance_without_the_noise_allowance(bias, verdict):
    # tolerance 0.01 N plus a 6-sigma allowance of 1.8 N (0.3 N of sensor noise): the ripple (0.6 N p-p) fits
    # the allowance, so only the mean (exactly `bias` over the last quarter, 1000 samples = 50 whole periods)
    # tells the cases apart; closed form, tolerance 1 mN either side of the 10 mN bound
    force = F_D + bias + RIPPLE
    got, reason = judge_segment(force, F_D, band=0.1 + 1.8, tolerance=0.01 + 1.8, bias_tolerance=0.01)
    assert got == verdict, reason
    if verdict == "off_target":
        assert "bias" in reason


def test_without_a_separate_bias_tolerance_the_rule_is_the_old_one():
    # noise-free runs: bias_tolerance defaults to the tolerance, and |mean| <= max|e|, so nothing changes
    force = F_D + 0.009 + 0.0005 * np.sin(2 * np.pi * 50 * T)
    assert judge_segment(force, F_D, band=0.1, tolerance=0.01)[0] == "converged"
    assert judge_segment(force + 0.002, F_D, band=0.1, tolerance=0.01)[0] == "off_target"


def test_a_surface_location_error_under_sensor_noise_is_not_converged(paper_sim):
    # the reviewer's case: 5,000 N/m, the surface believed 5 mm deeper, 0.5 N sensor noise. The law's own closed
    # form puts the steady force 0.29 N off f_d; with the noise allowance (3.01 N) the max-|e| rule alone called
    # it converged (exit 0). The mean error over the last quarter is that bias (within 0.1 N: the noise's own
    # shift through eq. (18) is a few tens of mN).
    sc = apply_overrides(paper_scenario(), ["controller.x_e_error=0.005", "sensor.noise_std=0.5",
                                            "sensor.seed=3", "trajectory.cycles=1"])
    r = paper_sim.run(sc)
    law = get_law("tmt")
    f_ss = law.steady_force(law.parameters(), F_D, 100.0, 5e3, 0.005)
    seg, = segment_metrics(r)
    last = r.contact_force[-len(r.time) // 4:]
    assert float(np.mean(last)) - F_D == pytest.approx(f_ss - F_D, abs=0.1)
    assert seg.verdict == "off_target" and "bias" in seg.reason
