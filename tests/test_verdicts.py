"""Issue #13: honest stability verdicts: the whole simulated loop linearised,
computation delay, surface-location error, switch jump vs overshoot, first
contact. Each prediction is checked against the nonlinear simulation."""
import json
import subprocess
import sys

import numpy as np
import pytest

from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.control.laws import get_law
from tmtcontrol.simulation.metrics import first_contact
from tmtcontrol.stability import (law_stiffness_limit, paper_effective_mass, scenario_stiffness_limit,
                                  switch_response, whole_loop_limit)

PAPER = dict(m=1.0, b=60.0, k=100.0, f_d=10.0)


def _point(rate, *sets):
    # the paper's loop at one point of its path (radius 0), 12 s at constant stiffness
    return apply_overrides(paper_scenario(), [f"controller.rate={rate}", "trajectory.cycles=3",
                                              "trajectory.radius=0.0", *sets])


def _verdicts(base, limit, factors):
    # "stable" for converged or off_target: just below the limit the oscillation still decays after
    # 12 s (off_target against the 0.01 N tolerance); the limit is about decay, not the tolerance
    sim = Simulator(base)
    return [{"converged": "stable", "off_target": "stable"}.get(v, v) for v in (
        segment_metrics(sim.run(apply_overrides(base, [f"environment.stiffness.values=[{limit * f}]"])))[0]
        .verdict for f in factors)]


@pytest.mark.parametrize("rate", [1000, 250])
def test_whole_loop_limit_matches_simulation_within_1_percent(rate):
    # The linearisation of the compiled step (full robot, inner loop, law) at a point: 1 % below
    # its limit the 12 s simulation converges, 1 % above it locks into the contact limit cycle.
    base = _point(rate)
    limit, points = whole_loop_limit(base, points=1)
    assert len(points) == 1 and np.isfinite(limit)
    assert _verdicts(base, limit, (0.99, 1.01)) == ["stable", "limit_cycle"]


def test_whole_loop_and_1d_model_agree_on_the_paper_path():
    # two independent models of the same loop: the whole loop linearised at 8 path points and the
    # 1-D law loop at the path's two extreme effective masses. The smallest limits agree to 0.5 %
    # (the 1-D model idealises the robot as a point mass m_p).
    sc = paper_scenario()
    whole, points = whole_loop_limit(sc, points=8, rtol=1e-4)
    one_d = scenario_stiffness_limit(sc)
    assert whole == pytest.approx(one_d, rel=5e-3)
    # along the path the limit varies by a few percent: the worst point is not the first one
    limits = [l for _, l in points]
    assert max(limits) / min(limits) > 1.02


def test_whole_loop_jacobian_is_the_derivative_of_the_step_and_far_warm_starts_fall_back():
    """The whole loop's A is the derivative of its step: central differences
    of the step at the equilibrium agree to 1e-6 (relative to A's largest
    entry; the difference step 1e-7 leaves truncation and rounding well below
    that). A stiffness 500x softer than the last one at the same point scales
    the warm start out of the workspace: the 1-D guess takes over."""
    from tmtcontrol.stability.wholeloop import WholeLoopModel

    m = WholeLoopModel(paper_scenario())
    w = m.at(5000.0)
    u = np.r_[m._u(0, 5000.0), m.P]
    d, h = m.dynamic, 1e-7
    fd = np.empty((d.size, d.size))
    for j, col in enumerate(d):
        e = np.zeros(w.s_eq.size)
        e[col] = h * (1.0 + abs(w.s_eq[col]))
        plus, minus = (np.ravel(np.array(m._f(w.s_eq + sgn * e, u)[0])) for sgn in (1, -1))
        fd[:, j] = (plus - minus)[d] / (2 * e[col])
    assert np.max(np.abs(fd - w.A)) < 1e-6 * np.max(np.abs(w.A))
    soft = m.at(10.0)                                # warm start from 5000 N/m would leave the workspace
    assert soft.residual < 1e-8 and soft.stable


@pytest.mark.heavy
def test_delay_of_one_sample_lowers_the_limit_and_simulation_agrees_within_2_percent():
    law, mp = get_law("tmt"), paper_effective_mass(worst=True)
    no_delay = law_stiffness_limit(law, **PAPER, Ts=1e-3, m_p=mp)
    delayed = law_stiffness_limit(law, **PAPER, Ts=1e-3, m_p=mp, delay=1)
    assert delayed < no_delay / 2.5                     # measured: 5.2e4 vs 1.63e5 N/m
    base = _point(1000, "controller.delay_samples=1")
    limit, _ = whole_loop_limit(base, points=1)
    assert limit == pytest.approx(delayed, rel=0.1)     # whole loop at one point vs 1-D at worst mass
    assert _verdicts(base, limit, (0.98, 1.02)) == ["stable", "limit_cycle"]


def test_paper_overshoot_after_a_switch_is_within_the_sampled_prediction(paper_result):
    # controller overshoot (after the unavoidable switch jump) vs the linear sampled model of the
    # same stiffness step, at the path's two extreme effective masses (the robot's m_p varies
    # between them along the path: allow 0.05 percentage points beyond the larger prediction)
    segs = segment_metrics(paper_result)
    k = [s.stiffness for s in segs]
    for i in range(1, len(segs)):
        jump_expected = 10.0 * (k[i] / k[i - 1] - 1.0)    # k_e step times the old penetration f_d/k_old
        assert segs[i].switch_jump == pytest.approx(jump_expected, rel=1e-3)
        pred = [switch_response(1.0, 60.0, 100.0, k[i - 1], k[i], 1e-3, mp)["overshoot_pct"]
                for mp in (paper_effective_mass(), paper_effective_mass(worst=True))]
        assert segs[i].overshoot_pct <= max(pred) + 0.05, (i, segs[i].overshoot_pct, pred)
        assert segs[i].overshoot_pct < 101.0         # a percentage of f_d, not the switch jump


@pytest.fixture(scope="module")
def approach_runs():
    base = apply_overrides(paper_scenario(), ["trajectory.cycles=0.5", "trajectory.approach_gap=0.005",
                                              "environment.stiffness.values=[1e5]"])
    sim = Simulator(base)
    guarded = sim.run()
    unguarded = sim.run(apply_overrides(base, ["controller.approach_speed=0"]))
    return guarded, unguarded


def test_guarded_approach_keeps_the_first_contact_peak_below_1_5_f_d(approach_runs):
    guarded, unguarded = approach_runs
    g, u = first_contact(guarded), first_contact(unguarded)
    # from a 5 mm gap onto 1e5 N/m: the law alone hits at 4-6 f_d with bounces (measured 5.6 f_d, 4)
    assert u.peak_ratio > 3.0 and u.bounces >= 2
    # the guarded move (10 mm/s, then f_d ramped over 0.25 s): touches after 0.5 s, peak <= 1.5 f_d
    assert g.time == pytest.approx(0.5, abs=0.02) and g.time <= 1.0
    assert g.peak_ratio <= 1.5
    # the hand-over has no jump: at the sample where the law takes over (measured force above the
    # 1 N threshold) the command moves by less than 0.1 mm (10 approach steps); the law's reference
    # then moves with the f_d ramp (f_d/k = 0.1 m over 0.25 s, 0.4 mm per sample)
    x_c = guarded.command_task[0]
    i = int(np.argmax(guarded.measured_force > 1.0))
    assert 0 < i and abs(x_c[i] - x_c[i - 1]) < 1e-4
    assert np.max(np.abs(np.diff(x_c[:i]))) == pytest.approx(1e-5)       # 10 mm/s x 1 ms before
    # and the law then tracks f_d
    seg = segment_metrics(guarded)[0]
    assert seg.verdict == "converged" and seg.steady_state_error < 0.01


# heavy (docs/testing.md's 2 s rule): 2.2 s on 2026-12-07's machine
@pytest.mark.heavy
def test_first_contact_in_summary_json(tmp_path):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "--out", str(out), "--no-plots",
                        "--set", "trajectory.cycles=0.25", "--set", "trajectory.approach_gap=0.003"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    fc = json.loads((out / "summary.json").read_text())["first_contact"]
    assert set(fc) == {"time", "peak_force", "peak_ratio", "bounces", "window"}
    assert fc["time"] == pytest.approx(0.3, abs=0.02)       # 3 mm at 10 mm/s
    # the 1 s run ends 0.69 s after the touch: the line says how much of the window it covers (the eighteenth
    # session: a 10 ms run printed "0 bounce(s) in the next second"); 1 s minus the touch, to rounding
    assert fc["window"] == pytest.approx(1.0 - fc["time"], abs=1e-9)
    assert f"bounce(s) in the {round(fc['window'] * 1e3)}\u00a0ms left of its segment" in r.stdout, r.stdout


@pytest.mark.heavy
def test_analyze_delay_and_x_e_error(capsys):
    from tmtcontrol.cli import main
    from tmtcontrol.stability import analyze

    kw = dict(m=1.0, b=60.0, k=100.0, k_e=2e4, Ts=1e-3)
    base, closer = analyze(**kw), analyze(**kw, x_e_error=-0.01)
    # without m_p the worst (largest) effective mass of the path is included
    assert base["max_stable_stiffness"] == pytest.approx(scenario_stiffness_limit(paper_scenario()), rel=1e-3)
    # the surface believed 10 mm closer than it is lowers the limit (1-D: -12 %), f_e = f_d still
    assert 0.8 < closer["max_stable_stiffness"] / base["max_stable_stiffness"] < 0.95
    assert closer["steady_state_force_x_e_error"] == pytest.approx(10.0)
    # the command line passes both on (one sample of delay: about 3x lower)
    assert main(["analyze", "--m", "1", "--b", "60", "--k", "100", "--ke", "2e4", "--ts", "0.001", "--json",
                 "--delay", "1", "--x-e-error", "-0.01"]) == 0
    both = json.loads(capsys.readouterr().out)
    assert both["delay"] == 1 and both["x_e_error"] == -0.01
    assert both["max_stable_stiffness"] < closer["max_stable_stiffness"] / 2.5
    assert main(["analyze", "--scenario", "paper", "--delay", "1"]) == 2
    assert capsys.readouterr().err.strip().startswith("error: --delay: not allowed with --scenario")


@pytest.mark.heavy
def test_analyze_with_an_x_e_error_that_keeps_the_tool_off_the_surface_says_so_and_exits_1(capsys):
    """Review 34: with x_e error -0.2 m at k_e = 2,000 N/m the reference stays outside the surface
    (delta + f_d/k < 0: -0.2 + 10/100 = -0.1 m), so the steady-state force is 0 N (the law's own
    closed form); the sampled verdict linearised a contact that does not exist and the command exited
    0. It now says there is no contact and exits 1; a small x_e error in contact still exits 0."""
    from tmtcontrol.cli import main

    base = ["analyze", "--m", "1", "--b", "60", "--k", "100", "--ke", "2000", "--ts", "0.001"]
    assert main([*base, "--x-e-error", "-0.2"]) == 1
    out, err = capsys.readouterr()
    assert "contact              NONE: the tool stays off the surface (steady-state force 0 N)" in out
    assert err.strip() == "no contact: the tool stays off the surface; see the contact line above"
    assert main([*base, "--x-e-error", "-0.001"]) == 0
    assert "contact              NONE" not in capsys.readouterr().out


@pytest.mark.heavy          # 2-3 s each on the 2026-12-07 machine (the README's command stays under 3 min)
def test_a_harmless_x_e_error_does_not_flip_the_verdict_just_below_the_limit():
    """Review 34: at k_e = 163,410 N/m, 6 N/m below the paper loop's limit (163,416.86 N/m, the
    reviewer's own bisection of the discrete loop; the closed form here gives 163,417), a +1 mm x_e
    error, harmless there (the compliance estimate is on its clip, so the loop is the one without
    it), read "sampled stable NO": the law loop's band, searched to 1e-4 and anchored at that
    stiffness, ended at it, and the strict k_e < limit failed although the spectral radius at k_e
    was below 1. Within the search's tolerance the radius at the stiffness decides: stable at
    163,410 with and without the error, unstable at 163,430 (radius above 1) with and without."""
    from tmtcontrol.stability.analysis import analyze

    kw = dict(m=1.0, b=60.0, k=100.0, Ts=1e-3, m_p=3.7176737929253623)
    for k_e, stable in ((163_410.0, True), (163_430.0, False)):
        for x_e_error in (0.0, 0.001):
            d = analyze(k_e=k_e, x_e_error=x_e_error, **kw)
            assert d["sampled_stable"] is stable and (d["spectral_radius"] < 1.0) is stable, (k_e, x_e_error)


def test_a_rounding_touch_at_the_start_is_no_contact():
    """Review 70: the UR5 with its part believed 15 cm nearer (x_e_error = -0.15 m) never touches, but its
    start leaves 9.8e-14 N of rounding, so the segment read "the contact is lost in the last quarter"
    (limit_cycle) and the crosscheck's plants disagreed (MuJoCo: off_target). A force at or below
    CONTACT_FLOOR f_d (10 nN at 10 N, first_contact's own floor) is no touch: off_target."""
    from tmtcontrol import Simulator, apply_overrides, load_scenario, segment_metrics
    from tmtcontrol.simulation.metrics import CONTACT_FLOOR

    sc = apply_overrides(load_scenario("ur5"), ["controller.x_e_error=-0.15", "trajectory.cycles=0.1"])
    r = Simulator(sc).run()
    assert 0 < r.contact_force.max() <= CONTACT_FLOOR * sc.controller.f_d        # the rounding, measured 9.8e-14 N
    (m,) = segment_metrics(r)
    assert (m.verdict, m.reason) == ("off_target", "no contact in the segment (the tool never reached the surface)")


def test_a_segment_that_never_touches_reports_the_whole_f_d_as_its_error_and_never_settles():
    """Review 72: a guarded approach too short to reach the part (0.1 m gap, a quarter cycle) has no
    touch in its segment; its desired force is still the approach's 0 N, so |f_e - f_d| read 0 N
    and the settling 0 s beside the verdict "no contact in the segment" (compare's row, simulate's
    summary.json, the report's FAIL line "worst steady-state |f_e - f_d| 0 N"). Against the task's
    f_d = 10 N and a force of 0 N the error is 10 N and the force never settles."""
    import math

    sc = apply_overrides(paper_scenario(), ["trajectory.approach_gap=0.1", "trajectory.cycles=0.25"])
    res = Simulator(sc).run()
    assert not np.any(res.contact_force > 0)                     # the premise: no touch at all
    (m,) = segment_metrics(res)
    assert m.verdict == "off_target" and "no contact in the segment" in m.reason
    assert m.steady_state_error == m.max_steady_error == sc.controller.f_d
    assert m.steady_rms_error == sc.controller.f_d
    assert math.isnan(m.settling_time) and math.isnan(m.settling_time_10mN)
