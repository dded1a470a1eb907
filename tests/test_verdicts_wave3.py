"""Issue 28 item 3: segment verdicts that read whole periods of the forcing and
judge tracking against the scenario's tolerance (``controller.force_tolerance``).

Each case of the issue gets the verdict it must get, with the independent
reason it is known: growth or decay of the oscillation measured here over
whole path periods, a closed form of the steady force or of the ramp lag,
the periodicity of a forced response."""
import numpy as np
import pytest

from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.control.laws import get_law
from tmtcontrol.simulation.metrics import format_table, judge_segment, segments

SIMULATED_LIMIT = 1.6725e5
"""The paper scenario's largest stable constant stiffness (N/m), found by
bisection in the simulator (16 s at one stiffness: above it the force
oscillation grows from one 4 s path period to the next, below it it decays);
to 1e-4, the bisection's last bracket was [167246.7, 167248.5] N/m."""


def k_eff(k, k_e):
    return k * k_e / (k + k_e)


def _run(sim, *sets):
    return sim.run(apply_overrides(paper_scenario(), list(sets)))


def _per_period(r, period=4000):
    """Peak-to-peak of the force over each whole path period (4 s)."""
    f = r.contact_force
    return np.array([np.ptp(f[i:i + period]) for i in range(0, f.size, period)])


@pytest.fixture(scope="module")
def near_limit(paper_sim):
    return _run(paper_sim, f"environment.stiffness.values=[{0.9976 * SIMULATED_LIMIT}]")


def test_just_below_the_limit_is_stable_but_not_converged(near_limit, paper_sim):
    # 0.9976x the simulated limit: a +-4 N oscillation still there at 16 s, decaying about 25 % per
    # circle (measured here over whole path periods, where the phase along the path cancels; within a
    # circle it grows and shrinks by 2x, which fooled the half-window comparison into 'converged')
    amp = _per_period(near_limit)
    assert np.all(amp[1:] < amp[:-1]) and 0.7 < amp[-1] / amp[-2] < 0.8
    assert amp[-1] > 5.0
    seg, = segment_metrics(near_limit)
    assert seg.verdict == "off_target", seg.reason
    assert "still decaying" in seg.reason and "whole periods" in seg.reason
    # 1 % above the limit: the contact is lost (the contact limit cycle)
    above, = segment_metrics(_run(paper_sim, f"environment.stiffness.values=[{1.01 * SIMULATED_LIMIT}]"))
    assert above.verdict == "limit_cycle"


def test_sinusoidal_stiffness_is_a_stable_forced_response(paper_sim):
    # 1e4 +- 5e3 N/m with a 1 s period, 16x below the limit: the force error is periodic with the
    # stiffness (it repeats from one 1 s period to the next within 1 mN: no growth, no decay)
    # and 0.34 N in size, 34x the 0.01 N tolerance: stable, not converged, never 'diverged'
    sets = ['environment.stiffness.kind="sinusoidal"', "environment.stiffness.mean=1e4",
            "environment.stiffness.amplitude=5e3", "environment.stiffness.period=1.0"]
    r = _run(paper_sim, *sets)
    e = r.contact_force - 10.0
    assert np.abs(e[-1000:] - e[-2000:-1000]).max() < 1e-3
    assert 0.3 < np.abs(e[-1000:]).max() < 0.4
    segs = segment_metrics(r)
    assert [s.verdict for s in segs] == ["off_target"] * 4
    assert all("periodic forced response" in s.reason for s in segs)
    # with a tolerance the response fits in, the same run converges
    loose = segment_metrics(_run(paper_sim, *sets, "controller.force_tolerance=0.5"))
    assert [s.verdict for s in loose] == ["converged"] * 4 and loose[0].tolerance == 0.5


RAMPS = ["environment.stiffness.kind=\"piecewise_linear\"", "environment.stiffness.times=[0, 4, 8, 12]",
         "environment.stiffness.values=[5e3, 2e4, 2e3, 1e4]"]


def _ramp_lag(k, dk):
    """Quasi-static force lag of a moving reference (tests/test_simulate.py's smooth profiles):
    k_eff (K_D/K_P) f_d |k_e'| / k_e^2, N."""
    return k_eff(100.0, k) * 0.6 * 10.0 * abs(dk) / k ** 2


@pytest.fixture(scope="module")
def ramps(paper_sim):
    return _run(paper_sim, *RAMPS)


def test_ramps_are_cut_at_their_knots_and_judged_against_the_closed_form_lag(ramps):
    assert segments(ramps) == [(0, 4000), (4000, 8000), (8000, 12000), (12000, 16000)]
    segs = segment_metrics(ramps)
    # the lag over each segment's last quarter (largest at its start for the rising ramps, at its end
    # for the falling one): 0.0084, 0.64, 0.0185 N, and none on the hold; the verdict is converged
    # where it is within 0.01 N (the lag's prediction is within 0.8-1.15x of the simulation)
    lag = [_ramp_lag(1.625e4, 3750), _ramp_lag(2e3, -4500), _ramp_lag(8e3, 2000), 0.0]
    expected = ["converged" if 1.15 * x < 0.01 else "off_target" for x in lag]
    assert expected == ["converged", "off_target", "off_target", "converged"]
    assert [s.verdict for s in segs] == expected, [s.reason for s in segs]
    for s, x in zip(segs[:3], lag):
        assert 0.8 * x <= s.steady_state_error <= 1.15 * x + 5e-3
    # a smooth lag is no oscillation: no segment is called diverged or a limit cycle
    assert not {"diverged", "limit_cycle"} & {s.verdict for s in segs}


def test_ramps_from_a_csv_table_get_the_same_segments_and_verdicts(ramps, paper_sim, tmp_path):
    table = tmp_path / "k.csv"
    table.write_text("t,k_e\n0,5000\n4,20000\n8,2000\n12,10000\n")
    r = _run(paper_sim, "environment.stiffness.kind=\"table\"", f"environment.stiffness.file=\"{table}\"")
    np.testing.assert_array_equal(r.stiffness, ramps.stiffness)
    assert segments(r) == segments(ramps)
    assert [s.verdict for s in segment_metrics(r)] == [s.verdict for s in segment_metrics(ramps)]


def test_a_step_table_is_cut_at_its_steps_not_per_path_period(paper_sim, tmp_path):
    # steps at 3 s and 5.5 s (not multiples of the 4 s path period), each a 1 ms ramp: three segments
    # starting at the first sample of each new stiffness
    table = tmp_path / "k.csv"
    table.write_text("t,k_e\n0,4000\n3,4000\n3.001,9000\n5.5,9000\n5.501,3000\n")
    r = _run(paper_sim, "environment.stiffness.kind=\"table\"", f"environment.stiffness.file=\"{table}\"",
             "trajectory.cycles=2")
    assert segments(r) == [(0, 3001), (3001, 5501), (5501, 8000)]
    segs = segment_metrics(r)
    assert [s.stiffness for s in segs[1:]] == pytest.approx([9000.0, 3000.0], rel=1e-3)


@pytest.mark.parametrize("x_e_error", [0.005, 1.0])
def test_surface_location_error_biases_the_force_off_target(paper_sim, x_e_error):
    # eq. (18) with the surface believed delta deeper: the law's own closed form of the steady force
    # (0.29 N off at delta = 5 mm; about 10x f_d at 1 m) is beyond the tolerance
    r = _run(paper_sim, f"controller.x_e_error={x_e_error}", "trajectory.cycles=1")
    law = get_law("tmt")
    f_ss = law.steady_force(law.parameters(), 10.0, 100.0, 5e3, x_e_error)
    assert abs(f_ss - 10.0) > 0.2
    seg, = segment_metrics(r)
    assert seg.steady_state_error == pytest.approx(abs(f_ss - 10.0), rel=0.05)
    assert seg.verdict == "off_target" and "bias" in seg.reason


@pytest.mark.heavy          # 2-3 s each on the 2026-12-07 machine (the README's command stays under 3 min)
def test_integral_law_with_a_small_gain_is_off_target():
    # k_i = 3e-4 m/(N s): the closed loop's slow root (integral law's characteristic polynomial,
    # control/laws/integral.py) at the softest stiffness 2e3 N/m is -0.028 1/s, a 36 s time constant
    # nine times the 4 s segment: the error left by the switch cannot be within 0.01 N at its end
    law = get_law("integral")
    poly = law.characteristic_polynomial(law.parameters(k_i=3e-4), 1.0, 60.0, 100.0, 2e3)
    slow = -max(np.roots(poly).real)
    assert 1 / slow > 30.0
    sc = apply_overrides(paper_scenario(), ["controller.law=integral", "controller.law.k_i=3e-4"])
    segs = segment_metrics(Simulator(sc).run())
    assert segs[2].steady_state_error > 0.3
    assert all(s.verdict == "off_target" for s in segs), [s.reason for s in segs]


def test_the_table_shows_the_tolerance_and_noise_widens_it(paper_result):
    segs = segment_metrics(paper_result)
    head = format_table(segs).splitlines()[0]
    assert "tol (" in head and head.index("tol (") < head.index("verdict")
    assert [s.tolerance for s in segs] == [0.01] * 4


def _ripple(noise_std, amplitude):
    t = np.arange(4000) * 1e-3
    return 10.0 + amplitude * np.sin(2 * np.pi * 37.0 * t)


def test_tolerance_and_band_on_synthetic_forces():
    # closed forms on f = f_d + a sin(2 pi 37 t): max |e| = a, the oscillation (swing between
    # consecutive extrema) 2a; tolerance 0.01 N, band 0.1 N
    def judge(a, tol=0.01, band=0.1):
        return judge_segment(_ripple(0, a), 10.0, band, tol)[0]

    assert judge(0.009) == "converged"            # within the tolerance, no oscillation above the band
    assert judge(0.02) == "off_target"            # 2x the tolerance, 0.4x the band: no limit cycle
    assert judge(0.02, tol=0.03) == "converged"
    assert judge(0.06) == "limit_cycle"           # sustained, swing 0.12 N above the 0.1 N band
    # a constant bias is off target whatever its size
    f = np.full(4000, 10.5)
    assert judge_segment(f, 10.0, 0.1, 0.01) == ("off_target", judge_segment(f, 10.0, 0.1, 0.01)[1])
    assert "bias of +500 mN" in judge_segment(f, 10.0, 0.1, 0.01)[1]
    # a segment too short for two windows (10 samples) is judged by the tolerance alone, not assumed
    assert judge_segment(np.full(10, 10.005), 10.0, 0.1, 0.01)[0] == "converged"
    assert judge_segment(np.full(10, 10.5), 10.0, 0.1, 0.01)[0] == "off_target"


def test_an_excursion_before_the_last_window_is_named_not_called_a_bias():
    """Review 43: a 2 mm step of a measured part met once, 3.23 s into a 4 s segment of one path period, gave
    "|f_e - f_d| up to 137 mN ...: a bias of +82.1 uN": the last window (the last half of the last quarter) held
    80 uN and the bias named was its mean, the excursion outside it. Made-up forces (N): 80 uN off f_d with a
    dip of 137 mN for 20 ms at 3.23 s. The reason names the excursion, when, and what the last window held;
    with two whole periods in the segment (the dip in the first only: no forced response) it does so without
    the caveat; a dip inside the last window is judged on that window's own terms (the old words)."""
    f = np.full(4000, 10.0 + 80e-6)
    f[3230:3250] -= 0.137
    verdict, why = judge_segment(f, 10.0, 0.1, 0.01, periods=(4000,), Ts=1e-3)
    assert verdict == "off_target"
    assert why == ("|f_e - f_d| up to 137 mN at the end (tolerance 10 mN): an excursion to \u2212137 mN 3.23 s into "
                   "the segment, the last 0.5 s within 80 µN (a segment of fewer than two periods of the forcing "
                   "cannot tell a transient from a forced response)"), why
    f2 = np.full(4000, 10.0 + 80e-6)
    f2[3050:3070] -= 0.137               # periods of 0.4 s: the last window is 0.8 s, from 3.2 s
    verdict, why = judge_segment(f2, 10.0, 0.1, 0.01, periods=(400,), Ts=1e-3)
    assert verdict == "off_target" and why.endswith("an excursion to \u2212137 mN 3.05 s into the segment, the last "
                                                    "0.8 s (whole periods) within 80 µN"), why
    g = np.full(4000, 10.0 + 80e-6)
    g[3800:3820] -= 0.137
    assert "an excursion" not in judge_segment(g, 10.0, 0.1, 0.01, periods=(4000,), Ts=1e-3)[1]


# -- issue 27 item 17: tests that tell each mutation apart ---------------------------------------

def _synthetic(result, force, *sets):
    """``result`` (the paper's run: 4 segments of 4 s, path period 4 s) with its contact force
    replaced by ``force`` (N) and its scenario by the paper's with ``sets``: the metrics then
    follow from closed forms of ``force``."""
    import dataclasses

    return dataclasses.replace(result, contact_force=np.asarray(force, dtype=float),
                               scenario=apply_overrides(paper_scenario(), list(sets)))


def _sine(result, amplitude):
    return 10.0 + amplitude * np.sin(2 * np.pi * 37.0 * result.time)


def test_the_ripple_band_is_1_percent_of_f_d(paper_result):
    # a sustained 37 Hz oscillation of +-0.075 N: swing 0.15 N between extrema, above the band
    # 0.01 f_d = 0.1 N and below twice it; every segment keeps it (no decay): a limit cycle
    segs = segment_metrics(_synthetic(paper_result, _sine(paper_result, 0.075)))
    assert [s.verdict for s in segs] == ["limit_cycle"] * 4
    # +-0.04 N (swing 0.08 N, under the band): no oscillation to judge, 4x the tolerance: off target
    assert {s.verdict for s in segment_metrics(_synthetic(paper_result, _sine(paper_result, 0.04)))} == {"off_target"}


def test_the_band_and_the_tolerance_take_the_sensor_noise(paper_result):
    # with sensor noise the run is compared with its noise-free twin (here the paper's run itself,
    # whose error is < 1 mN): what the noise did is the +-0.075 N ripple, standard deviation
    # 0.075/sqrt(2) = 0.053 N, so band and tolerance widen by 6 x 0.053 = 0.318 N: 0.328 N, and the
    # same ripple is within both (converged); 1e-3 relative covers the twin's own sub-mN error
    segs = segment_metrics(_synthetic(paper_result, _sine(paper_result, 0.075), "sensor.noise_std=0.05"))
    assert [s.verdict for s in segs] == ["converged"] * 4
    assert segs[0].tolerance == pytest.approx(0.01 + 6 * 0.075 / np.sqrt(2), rel=1e-3)


def test_first_contact_counts_losses_of_contact_not_samples(paper_result):
    from tmtcontrol.simulation.metrics import first_contact

    # touch at 0.1 s, lose the contact for 5 samples at 0.3 s and for 3 at 0.6 s: two bounces
    f = np.full(paper_result.time.size, 10.0)
    f[:100] = 0.0
    f[300:305] = 0.0
    f[600:603] = 0.0
    fc = first_contact(_synthetic(paper_result, f))
    assert fc.time == pytest.approx(0.1) and fc.bounces == 2 and fc.peak_force == 10.0


def test_first_contact_ignores_a_rounding_force_at_the_start(paper_result):
    """Review 47: a height map's spline leaves 7.6e-14 N at t = 0 where the path
    starts on the part, and first contact read 0.000 s against the analytic
    sphere's 0.001 s. A force below f_d x 1e-9 (10 nN here) is not a touch; the
    paper's own first step (25 mN) is, and so is 1 uN."""
    from tmtcontrol.simulation.metrics import first_contact

    f = np.full(paper_result.time.size, 10.0)
    f[0], f[1], f[2] = 7.6e-14, 0.0, 9.6e-13
    assert first_contact(_synthetic(paper_result, f)).time == pytest.approx(0.003)
    f[1] = 1e-6
    assert first_contact(_synthetic(paper_result, f)).time == pytest.approx(0.001)
    assert first_contact(paper_result).time == pytest.approx(0.001)


def test_first_contact_window_ends_with_the_first_segment(paper_result):
    from tmtcontrol.simulation.metrics import first_contact

    # first touch at 3.5 s (0.5 s before the first segment ends at 4 s): the 1 s window would reach
    # 30 N in segment 2 (a switch, not the first contact) and a loss of contact at 4.2 s
    f = np.zeros(paper_result.time.size)
    f[3500:4000] = 10.0
    f[4000:] = 30.0
    f[4200:4210] = 0.0
    fc = first_contact(_synthetic(paper_result, f))
    assert fc.time == pytest.approx(3.5) and fc.peak_force == 10.0 and fc.bounces == 0
    # the window it covers says so: 0.5 s of its segment, not the full second (the eighteenth session: a
    # 10 ms run printed "0 bounce(s) in the next second"); the samples 3.5-3.999 s cover 0.5 s to 1e-12
    assert fc.window == pytest.approx(0.5, abs=1e-12)
    f[:] = 10.0
    assert first_contact(_synthetic(paper_result, f)).window == 1.0     # a whole second inside the segment


def test_a_response_always_inside_the_band_settles_at_once(paper_result):
    from tmtcontrol.simulation.metrics import settling_time

    t = np.arange(10) * 1e-3
    assert settling_time(np.full(10, 0.05), 0.1, t) == 0.0
    assert np.isnan(settling_time(np.r_[np.zeros(9), 0.2], 0.1, t))
    segs = segment_metrics(_synthetic(paper_result, np.full(paper_result.time.size, 10.0)))
    assert [s.settling_time for s in segs] == [0.0] * 4 and [s.settling_time_10mN for s in segs] == [0.0] * 4


def test_a_segment_stiffness_is_its_mean(ramps):
    # the first ramp, 5e3 -> 2e4 N/m over its 4000 samples: mean (5e3 + 2e4)/2 less half a step
    segs = segment_metrics(ramps)
    step = 1.5e4 / 4000
    assert segs[0].stiffness == pytest.approx(12500.0 - step / 2, rel=1e-9)
    assert segs[3].stiffness == pytest.approx(1e4, rel=1e-12)


def test_the_steady_rms_is_over_the_last_quarter(paper_result):
    # 1 N off for the first three quarters of each segment, on f_d in the last: RMS 0 there
    f = np.full(paper_result.time.size, 10.0)
    within = (np.arange(f.size) % 4000) < 3000
    f[within] = 11.0
    segs = segment_metrics(_synthetic(paper_result, f))
    assert [s.steady_rms_error for s in segs] == [0.0] * 4
    assert [s.steady_state_error for s in segs] == [0.0] * 4


def _law_step(name, y, state=None, **params):
    from tmtcontrol.control.laws import MEASUREMENTS

    law = get_law(name)
    prm = law.parameters(**params)
    s0 = law.initial_state(prm) if state is None else np.array([state.get(n, v) for n, v in
                                                               zip(law.states, law.initial_state(prm))])
    out = law.function()(np.array([y[n] for n in MEASUREMENTS]), law.parameter_vector(prm), s0)
    x_r, s_next = float(out[0]), np.ravel(np.array(out[4]))
    return x_r, dict(zip(law.states, s_next))


Y = dict(x=2e-3, dx=0.0, f_m=8.0, f_d=10.0, x_e_hat=0.0, Ts=1e-3, m=1.0, b=60.0, k=100.0)


def test_integral_law_is_forward_euler():
    # x_r = x_e_hat + f_d/k + k_i I uses the integral before this sample's update (documented forward
    # Euler), and I_next = I + Ts (f_d - f_m)
    x_r, s = _law_step("integral", Y, {"I": 0.5}, k_i=0.03)
    assert x_r == pytest.approx(0.0 + 10.0 / 100.0 + 0.03 * 0.5, abs=1e-15)
    assert s["I"] == pytest.approx(0.5 + 1e-3 * 2.0, abs=1e-15)


def test_rls_covariance_trace_is_bounded():
    # P = 1e6 I (trace 2e6 >> the bound 1e4), an update in contact (f_m = 8 N > 2 x 0.5 N, no reset)
    # with forgetting 0.995: the direction orthogonal to the regressor keeps 1e6/0.995, so without
    # the bound the trace would exceed 1e6; with it, it is scaled down to the bound exactly
    x_r, s = _law_step("rls", Y, {"P_kk": 1e6, "P_ff": 1e6}, reset_error=1e9)
    assert s["P_kk"] + s["P_ff"] == pytest.approx(1e4, rel=1e-12)


def test_rls_updates_only_above_twice_the_force_threshold():
    law = get_law("rls")
    theta0 = law.initial_state(law.parameters())
    # 1.5 x the 0.5 N threshold: no update (theta and P as before); 2.5 x: an update
    est = [i for i, n in enumerate(law.states) if n.startswith(("theta", "P_"))]
    _, held = _law_step("rls", dict(Y, f_m=0.75))
    assert [held[law.states[i]] for i in est] == [theta0[i] for i in est]
    _, moved = _law_step("rls", dict(Y, f_m=1.25))
    assert moved["theta_k"] != theta0[law.states.index("theta_k")]


# -- issue 28 item 8: contact detection robust to sensor noise -----------------------------------

@pytest.fixture(scope="module")
def noisy_approach():
    base = apply_overrides(paper_scenario(), ["trajectory.cycles=0.5", "trajectory.approach_gap=0.005",
                                              "environment.stiffness.values=[1e5]", "sensor.noise_std=0.5"])
    return base, Simulator(base)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_guarded_approach_with_noise_peaks_below_1_5_f_d(noisy_approach, seed):
    from tmtcontrol.simulation.metrics import first_contact

    # 5 mm at 10 mm/s onto 1e5 N/m with 0.5 N sensor noise: noise alone must not end the approach
    # (one sample above 1 N did, at 0.14-0.21 s, and the hit peaked at 2.6-2.9 f_d); the true first
    # touch is at gap / speed = 0.5 s and the peak stays below 1.5 f_d
    base, sim = noisy_approach
    r = sim.run(apply_overrides(base, [f"sensor.seed={seed}"]))
    fc = first_contact(r)
    assert fc.time == pytest.approx(0.5, abs=0.02)
    assert fc.peak_ratio <= 1.5
    # the hand-over happens after the touch, not before it
    approach_ends = int(np.argmax(r.desired_force > 0))
    assert r.contact_force[approach_ends - 1] > 0.0


def test_contact_threshold_adds_six_sigma_of_the_filtered_noise():
    from tmtcontrol.simulation.simulator import contact_detection_threshold

    # without noise: the threshold itself, so every noise-free run is unchanged bit for bit
    assert contact_detection_threshold(1.0, 0.0, 0.3) == 1.0
    # with noise, no filter: 1 + 6 x 0.5 = 4 N
    assert contact_detection_threshold(1.0, 0.5, 0.0) == 4.0
    # with the filter pole a: 6 times the filtered noise's std, sqrt((1 - a)/(1 + a)) sigma, which a
    # filter (scipy's lfilter) of 200,000 Gaussian samples reproduces (1 % is about 5 standard errors)
    from scipy.signal import lfilter

    a, sigma = 0.73, 0.5
    n = sigma * np.random.default_rng(3).standard_normal(200_000)
    std = float(np.std(lfilter([1 - a], [1, -a], n)[100:]))
    assert contact_detection_threshold(1.0, sigma, a) == pytest.approx(1.0 + 6 * std, rel=0.01)


@pytest.mark.heavy
def test_the_reports_tracking_verdict_uses_the_scenarios_tolerance():
    # the known law with k_e assumed 50 % high settles 0.065 N off f_d (eqs. 11-12): it fails the
    # default 0.01 N tolerance and passes a scenario tolerance of 0.07 N, which the verdict quotes
    from tmtcontrol import fmt
    from tmtcontrol.report.document import Report, _simulation
    from tmtcontrol.stability import scenario_parameters

    base = ["controller.law=known", "controller.law.assumed_stiffness=7500", "trajectory.cycles=1",
            "environment.stiffness.values=[5e3]"]
    passed = []
    for tol in (0.01, 0.07):
        sc = apply_overrides(paper_scenario(), base + [f"controller.force_tolerance={tol}"])
        rep = Report(sc, "test")
        _simulation(rep, sc, scenario_parameters(sc))
        (v,) = rep.verdicts
        assert f"(tolerance {fmt.qty(tol, 'N')})" in v.value
        passed.append(v.passed)
    assert passed == [False, True]


@pytest.mark.heavy
def test_simulate_exits_1_and_says_why_a_segment_is_not_converged(tmp_path, capsys):
    from tmtcontrol.cli import main

    # 5 mm surface-location error, 1 s at 5e3 N/m: the TMT bias (about 0.29 N, as above) is the reason
    code = main(["simulate", "--no-plots", "--out", str(tmp_path / "o"), "--set", "trajectory.cycles=0.25",
                 "--set", "controller.x_e_error=0.005"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1
    assert err[0].startswith("off_target: segment 1 (0-1 s), k_e = 5,000 N/m, the loop's limit ")
    assert "(tolerance 10 mN): a bias of +2" in err[0] and " mN" in err[0].split("a bias of")[1]


@pytest.mark.parametrize("sigma, verdict, kept", [(0.03, "limit_cycle", "98.5 %"), (0.0, "limit_cycle", "100 %"),
                                                  (0.2, "off_target", None)])
def test_a_sustained_oscillations_reason_says_how_much_of_its_amplitude_it_keeps(sigma, verdict, kept):
    """Review 56 (low): "does not decay over 0.5 s" of an oscillation that lost 1.5 % per 0.5 s read as
    no decay at all. A 40 Hz sine decaying as exp(-sigma t) keeps exp(-sigma W) of its peak-to-peak
    from one 0.5 s window to the next (20 whole cycles each: the extrema at the same phases), which the
    reason now prints to 3 digits: exp(-0.015) = 98.5 %; at sigma = 0.2, exp(-0.1) = 90.5 % < 95 %:
    not sustained, judged on its size (off_target)."""
    from tmtcontrol.simulation.metrics import judge_segment

    t = np.arange(4000) * 1e-3
    f = 10.0 + 2.0 * np.exp(-sigma * t) * np.sin(2 * np.pi * 40.0 * t)
    got, why = judge_segment(f, 10.0, 0.1, 0.01, periods=(4000,), Ts=1e-3)
    assert got == verdict, why
    if kept:
        assert why.endswith(f"does not decay over 0.5 s (it keeps {kept} of its amplitude; 95 % or more is "
                            "sustained)"), why
