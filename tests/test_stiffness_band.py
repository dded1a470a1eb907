"""The stable band of k_e (review finding F2): a stiff contact damper makes the
sampled loop unstable on soft surfaces, below a band of stable stiffnesses; the
limit is that band's upper edge, not 0 (stability.sampled.stable_band, the one
grid-and-bisection search behind largest_stable, max_stable_stiffness,
law_stiffness_limit and the scenario's limits)."""
import functools
import math
import re

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from tmtcontrol.control.laws import get_law
from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
from tmtcontrol.stability.analysis import analysis_kwargs, analyze, format_analysis, scenario_parameters, \
    scenario_stiffness_limit
from tmtcontrol.stability.lawloop import law_stiffness_band
from tmtcontrol.stability.sampled import (largest_stable, max_stable_stiffness, spectral_radii, spectral_radius,
                                          stable_band, stiffness_band)

M, B, K, TS, MP = 1.0, 60.0, 100.0, 1e-3, 3.7          # paper impedance, 1 kHz, about the path's worst mass


def _jury_margin(k_e, d_e, m_p=MP):
    """Jury's stability margin of the 1-D loop's (x, x') block, for each k_e
    (array, N/m), derived independently of stability.sampled: with eq. (9)'s
    gains K_D = b/m, K_P = k/m the impedance filter cancels from eq. (6) and the
    TMT reference (dx_r = dx - df/k_e) leaves U = -f (1/m + K_P/k_e) - K_D x';
    with eq. (5)'s force feed-forward the held acceleration is
    u_k = f_k (1/m_p - 1/m - K_P/k_e) - K_D x'_k, f_k = k_e x_k + d_e x'_k, on
    x'' = -(k_e x + d_e x')/m_p + u_k (exact ZOH: the exponential of the
    augmented matrix). The loop's other eigenvalues are the impedance filter's
    (0.998286, stable) and 0. On P(z) = z^2 + a1 z + a0 the margin is the
    smallest of 1 - |a0|, P(1), P(-1) (> 0: both roots inside the unit circle)."""
    k_e = np.atleast_1d(np.asarray(k_e, dtype=float))
    aug = np.zeros((k_e.size, 3, 3))
    aug[:, 0, 1], aug[:, 1, 0], aug[:, 1, 1], aug[:, 1, 2] = 1.0, -k_e / m_p, -d_e / m_p, 1.0
    E = expm(aug * TS)
    Phi, Gam = E[:, :2, :2], E[:, :2, 2:]
    c = 1 / m_p - 1 / M - (K / M) / k_e
    gain = np.stack([c * k_e, c * d_e - B / M], axis=1)[:, None, :]
    closed = Phi + Gam @ gain
    a1, a0 = -np.trace(closed, axis1=1, axis2=2), np.linalg.det(closed)
    margin = np.minimum(np.minimum(1 - np.abs(a0), 1 + a1 + a0), 1 - a1 + a0)
    radius = np.array([max(abs(np.roots([1.0, x, y]))) for x, y in zip(a1, a0)])
    clear = np.abs(margin) > 1e-9                            # away from an edge, where rounding decides
    assert np.array_equal((margin > 0)[clear], (radius < 1.0)[clear])      # Jury's test agrees with the roots
    return margin if margin.size > 1 else float(margin[0])


@functools.lru_cache
def _jury_edges(d_e, lo=1.0, hi=1e8):
    """Where Jury's margin changes sign on [lo, hi] N/m (a grid 1.12x apart, the
    edges being decades apart), each edge by brentq to 1e-12 relative."""
    g = np.geomspace(lo, hi, 161)
    s = np.sign(_jury_margin(g, d_e))
    return tuple(brentq(_jury_margin, g[i], g[i + 1], args=(d_e,), rtol=1e-12) for i in np.flatnonzero(np.diff(s)))


def test_the_band_of_the_1d_loop_matches_jury_on_its_characteristic_polynomial():
    """d_e = 200 N s/m: Jury gives an unstable band below ~11.1 N/m and the upper
    edge ~7.12e5 N/m; the scan finds both edges to its 1e-6 bisection (allowed
    3e-6). Without contact damping there is no lower edge (stable from the scan's
    start) and the upper edge is the paper's limit."""
    lower, upper = _jury_edges(200.0)
    assert round(lower) == 11 and 5e5 < upper < 1e6                   # docs/theory.md: "about 11 N/m"
    band = stiffness_band(M, B, K, TS, MP, d_e=200.0)
    assert band.unstable_below
    assert band.lower == pytest.approx(lower, rel=3e-6) and band.upper == pytest.approx(upper, rel=3e-6)
    assert max_stable_stiffness(M, B, K, TS, MP, d_e=200.0) == band.upper           # was 0 (unstable at 10 N/m)
    assert spectral_radius(M, B, K, 10.0, TS, MP, d_e=200.0) == pytest.approx(1.20, abs=5e-3)   # the review's
    (edge,) = _jury_edges(0.0)
    plain = stiffness_band(M, B, K, TS, MP)
    assert not plain.unstable_below and plain.lower == 10.0
    assert plain.upper == pytest.approx(edge, rel=3e-6)


def test_the_law_loop_band_agrees_with_the_closed_form():
    """Two implementations of the same loop: the TMT law's own update
    (stability.lawloop, min_stiffness lowered to 1 N/m so that its compliance
    clip, inactive in the closed form, stays out of the band) at d_e = 200:
    both edges within 5e-4 (the law loop bisects to 1e-4)."""
    law = get_law("tmt")
    band = law_stiffness_band(law, law.parameters(min_stiffness=1.0), m=M, b=B, k=K, Ts=TS, m_p=MP, f_d=10.0,
                              d_e=200.0)
    closed = stiffness_band(M, B, K, TS, MP, d_e=200.0)
    assert band.unstable_below
    assert band.lower == pytest.approx(closed.lower, rel=5e-4)
    assert band.upper == pytest.approx(closed.upper, rel=5e-4)


def test_the_stiffness_margin_is_negative_below_the_band():
    """The stability chart's margin (decades) at d_e = 200: negative in the
    unstable band of soft surfaces (10 N/m), positive inside the band, negative
    above it; the band's edges from Jury."""
    from tmtcontrol.stability.sampled import stiffness_margin

    lower, upper = _jury_edges(200.0)
    limits, margin = stiffness_margin(M, B, K, MP, [TS], [10.0, 1e3, 2 * upper], d_e=200.0)
    assert limits[0] == pytest.approx(upper, rel=3e-6)
    assert margin[:, 0] == pytest.approx([math.log10(10.0 / lower), math.log10(upper / 1e3), -math.log10(2)],
                                         rel=1e-5)


def _plain_scan(stable, k_lo=10.0, k_hi=1e9, rtol=1e-6, points=49):
    """The search before the fix, written out: the first unstable point of a log
    grid from k_lo, bisection from the grid point before it; 0 if unstable at k_lo."""
    prev = None
    for ke in np.geomspace(k_lo, k_hi, points):
        if not stable(ke):
            break
        prev = ke
    else:
        return math.inf
    if prev is None:
        return 0.0
    lo, hi = float(prev), float(ke)
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


@pytest.mark.parametrize("within", [None, 2e3, 1.7e5, 1e7])
def test_a_loop_stable_from_the_scan_start_keeps_its_limit_bit_for_bit(within):
    """Where the loop is stable at the scan's start, the limit is exactly the plain
    upward scan's, wherever the scenario's smallest stiffness lies (in the band,
    within one grid step of the edge, or above the limit: then the band below)."""
    f = lambda ke: spectral_radius(M, B, K, ke, TS, MP) < 1.0
    assert largest_stable(f, within=within) == _plain_scan(f)
    assert largest_stable(lambda ke: ke < 1e10, within=within) == math.inf


@pytest.mark.heavy
def test_the_paper_limit_is_bit_for_bit_the_plain_scan():
    """The paper scenario's closed-form limit (163,417 N/m at the worse mass) is
    exactly the vectorised plain scan of max_stable_stiffness before the fix."""
    p = scenario_parameters(paper_scenario())
    grid = np.geomspace(10.0, 1e10, 121)

    def plain_closed_form(mp):           # the vectorised scan of max_stable_stiffness before the fix
        i = int(np.flatnonzero(spectral_radii(p["m"], p["b"], p["k"], grid, p["Ts"], mp) >= 1.0)[0])
        return _plain_scan(lambda ke: spectral_radius(p["m"], p["b"], p["k"], ke, p["Ts"], mp) < 1.0,
                           grid[i - 1], grid[i], points=2)
    expected = min(plain_closed_form(mp) for mp in (p["m_p_min"], p["m_p_max"]))
    assert round(expected) == 163417
    assert scenario_stiffness_limit(paper_scenario(), p) == expected


def test_the_band_that_contains_the_scenario_and_the_verdicts_on_either_side():
    """A toy loop stable on [20, 100] and [1e3, 1e5] N/m: the band containing the
    scenario's smallest stiffness gives the limit; a scenario in the gap gets the
    band below (a limit under it: the verdict fails); one below every band gets 0
    with the band above reported; none stable: 0 and NaN edges."""
    two = lambda ke: 20.0 <= ke <= 100.0 or 1e3 <= ke <= 1e5
    first = stable_band(two)
    assert (first.lower, first.upper, first.limit) == pytest.approx((20.0, 100.0, 100.0), rel=2e-6)
    upper = stable_band(two, within=5e3)
    assert (upper.lower, upper.limit) == pytest.approx((1e3, 1e5), rel=2e-6) and upper.unstable_below
    gap = stable_band(two, within=300.0)
    assert gap.limit == pytest.approx(100.0, rel=2e-6) and gap.limit < 300.0
    below = stable_band(two, within=12.0)
    assert below.limit == 0.0 and below.lower == pytest.approx(20.0, rel=2e-6)
    assert stable_band(two, within=5.0).scan_from == 5.0           # the scan starts at the scenario if lower
    none = stable_band(lambda ke: False)
    assert none.limit == 0.0 and math.isnan(none.lower) and math.isnan(none.upper)


def test_contact_damping_limit_and_analyze_report_the_band():
    """environment.damping = 200 N s/m on the paper scenario (2e3-2e4 N/m): the
    limit is the band's upper edge (~7.11e5 N/m, not 0) and analyze says the band.
    At d_e = 2000 N s/m the loop is unstable up to ~380 N/m (Jury; the TMT law's
    compliance clip, below min_stiffness = 100 N/m, plays no part there): a
    scenario from 150 N/m is sampled-unstable with max stable k_e 0, and the text
    says its smallest stiffness lies below the band."""
    sc = apply_overrides(paper_scenario(), ["environment.damping=200"])
    p = scenario_parameters(sc)
    limit = scenario_stiffness_limit(sc, p)
    (_, edge) = _jury_edges(200.0)
    assert 7.0e5 < limit < edge                    # the path's worst mass 3.72 kg > 3.7: a little below Jury's
    a = analyze(**analysis_kwargs(p))
    assert a["max_stable_stiffness"] == limit and a["sampled_stable"]
    assert a["stable_band"]["unstable_below"] and a["stable_band"]["upper"] == limit
    assert 10.0 < a["stable_band"]["lower"] < 20.0
    text = format_analysis(a)
    assert re.search(r"stable band +k_e in \[11\.\d+, 711\d{3}\] N/m", text), text
    (lower, _) = _jury_edges(2000.0)
    assert round(lower, -1) == 380.0                                  # docs/theory.md: "about 380 N/m"
    low = apply_overrides(paper_scenario(), ["environment.damping=2000", "environment.stiffness.values=[150,2e4]"])
    p_low = scenario_parameters(low)
    b = analyze(**analysis_kwargs(p_low))
    assert b["max_stable_stiffness"] == 0.0 and not b["sampled_stable"]
    assert b["stable_band"]["lower"] == pytest.approx(lower, rel=0.03)      # the path's masses 3.30-3.72 kg
    assert scenario_stiffness_limit(low, p_low) == 0.0
    text = format_analysis(b)
    assert "below the band       the smallest stiffness 150 N/m: unstable" in text and "sampled stable       NO" in text


def test_the_whole_loop_search_takes_the_scenarios_band():
    """The whole-loop linearisation (stability.wholeloop, the TMT law with its
    compliance clip) at d_e = 2000 N s/m: stable below the clip (~100 N/m),
    unstable up to ~380 N/m (as Jury's 1-D band), stable again above. A scenario
    from 500 N/m gets the upper band's edge (the 1-D loop's 5.84e6 N/m at the
    worst mass; this path point's mass is smaller, so up to 10 % higher), not the
    lower band's ~100 N/m that a plain upward scan returns; one from 150 N/m gets a
    limit below 150 (its verdict fails)."""
    from tmtcontrol.stability.wholeloop import WholeLoopModel, whole_loop_limit

    sc = apply_overrides(paper_scenario(), ["environment.damping=2000", "environment.stiffness.values=[500,2e4]"])
    mdl = WholeLoopModel(sc)
    one_d = scenario_stiffness_limit(sc)
    limit, _ = whole_loop_limit(sc, points=1, rtol=1e-3, model=mdl, within=500.0)
    assert one_d < limit < 1.1 * one_d
    plain, _ = whole_loop_limit(sc, points=1, rtol=1e-3, model=mdl)
    assert 90.0 < plain < 110.0
    assert whole_loop_limit(sc, points=1, rtol=1e-3, model=mdl, within=150.0)[0] < 150.0


def test_below_the_laws_min_stiffness_the_law_loop_decides():
    """d_e = 200 at 10 N/m: the closed form (no compliance clip) is unstable
    (radius 1.20), the TMT law clips its compliance below min_stiffness = 100 N/m
    and its own loop is stable there, so the analysis takes the law loop."""
    from tmtcontrol.stability.analysis import closed_form_applies
    from tmtcontrol.stability.lawloop import law_loop

    assert closed_form_applies("tmt", 0, 0.0, 2e3) and not closed_form_applies("tmt", 0, 0.0, 10.0)
    assert closed_form_applies("known", 0, 0.0, 10.0)
    law = get_law("tmt")
    assert not closed_form_applies("tmt", 0, 0.0, 50.0, law.parameters(min_stiffness=60.0))
    assert closed_form_applies("tmt", 0, 0.0, 50.0, law.parameters(min_stiffness=40.0))
    assert spectral_radius(M, B, K, 10.0, TS, MP, d_e=200.0) > 1.1
    assert law_loop(law, m=M, b=B, k=K, k_e=10.0, Ts=TS, m_p=MP, d_e=200.0).spectral_radius < 1.0


@pytest.mark.heavy
def test_simulate_no_longer_quotes_a_zero_limit(paper_sim, tmp_path, capsys):
    """The reviewer's CLI case (a3b_cli.sh, shortened): d_e = 200 with a segment at
    8e5 N/m, above the limit: exit 1 and the line quotes the loop's limit, within 1 %
    of the simulator bisection's 7.27e5 N/m (the test below), and the 1-D figure
    ~7.11e5 N/m, not 0. Heavy: the contact damper's periodic and first-contact
    searches take half a minute; the message's wiring is tested in seconds by
    test_limits.py::test_simulate_analyze_sweep_and_report_quote_the_one_deciding_limit."""
    from tmtcontrol.cli import main

    code = main(["simulate", "paper", "--out", str(tmp_path / "out"), "--no-plots",
                 "--set", "environment.damping=200", "--set", "environment.stiffness.values=[8e5]",
                 "--set", "trajectory.cycles=1"])
    err = capsys.readouterr().err
    assert code == 1
    m = re.search(r"the loop's limit ([\d,]+) N/m \([a-z -]+; as tmtcontrol analyze --scenario\), "
                  r"1-D small-signal ([\d,]+) N/m", err)
    assert m, err
    loop, small = (float(g.replace(",", "")) for g in m.groups())
    assert small == pytest.approx(7.11e5, rel=2e-3)
    assert loop == pytest.approx(7.27e5, rel=1e-2)


@pytest.mark.heavy          # 2.6-11 s on the 2026-12-07 machine (the README's command stays under 3 min)
def test_the_limit_with_contact_damping_matches_a_simulator_bisection():
    """d_e = 200 N s/m: the simulated loop's constant-k_e limit (the review measured
    7.27e5 N/m) by bisection in the compiled simulator (first_contact.simulated_limit,
    to 1e-3): the printed limit lies below it by at most 4 % (it takes the path's
    worst effective mass: 2-2.5 % in the review's 19 other configurations)."""
    from tmtcontrol.stability.first_contact import simulated_limit

    sc = apply_overrides(paper_scenario(), ["environment.damping=200"])
    limit = scenario_stiffness_limit(sc)
    simulated = simulated_limit(sc, 0.9 * limit, 1.2 * limit, rtol=1e-3)
    assert 0.96 * simulated < limit < simulated
    assert simulated == pytest.approx(7.27e5, rel=5e-3)


def test_a_sampling_resonance_window_ends_the_band():
    """Regression (review 9): where the contact mode turns pi per period, k_1 =
    m_p (pi/Ts)^2 (2.96e6 N/m at m_p = 0.3 kg, 1 kHz), the loop is unstable in a
    window 2.4 % wide just below k_1, which the 121-point grid stepped over:
    the limit read 4.7e7 N/m and a range across the window 'stable'. Known
    independently: Jury's test on the characteristic polynomial (above), its
    sign change found by brentq between a stable point and one inside."""
    m_p = 0.3
    k_1 = m_p * (math.pi / TS) ** 2
    assert _jury_margin(2.95e6, 0.0, m_p) < 0                                  # the review's unstable point
    assert _jury_margin(0.95 * k_1, 0.0, m_p) > 0 and _jury_margin(k_1 * (1 - 1e-6), 0.0, m_p) < 0
    edge = brentq(lambda x: _jury_margin(x, 0.0, m_p), 0.95 * k_1, k_1 * (1 - 1e-6), rtol=1e-12)
    assert max_stable_stiffness(M, B, K, TS, m_p) == pytest.approx(edge, rel=3e-6)
    # the grid alone steps over the window: its band reaches far above k_1
    plain = stable_band(lambda ke: spectral_radius(M, B, K, ke, TS, m_p) < 1.0, 10.0, 1e10, 1e-6, 121,
                        scan=lambda g: spectral_radii(M, B, K, g, TS, m_p) < 1.0)
    assert plain.limit > 10 * k_1
    # a range across the window is not sampled-stable; its limit is the window's edge
    out = analyze(M, B, K, k_e_min=2e6, k_e_max=1e7, Ts=TS, m_p=(m_p, m_p))
    assert out["sampled_stable"] is False and out["max_stable_stiffness"] == pytest.approx(edge, rel=3e-6)
    # the paper's loop (m_p 3.7 kg) is unchanged: its first resonance, 3.7e7 N/m, is far above its limit
    assert max_stable_stiffness(M, B, K, TS, MP) < 0.01 * MP * (math.pi / TS) ** 2


def test_the_band_stops_below_at_a_resonances_unstable_sliver():
    """Review 71: at k_e = 3.652e7 N/m (m = 5, b = 10, k = 10, Ts = 1 ms, m_p = 3.7 kg), just above the
    first sampling resonance m_p (pi/Ts)^2 = 3.6518e7 N/m, the loop is unstable on a sliver below it
    (3.6488e7-3.6518e7 N/m, found by the reviewer's own model); the band's lower edge was searched
    on the coarse grid only and went down through the sliver to 10 N/m. Checked here on a dense scan
    of the sampled loop's radius: unstable just below the edge, stable from just above it to k_e."""
    from tmtcontrol.stability.sampled import spectral_radius, stiffness_band

    band = stiffness_band(5.0, 10.0, 10.0, 1e-3, 3.7, within=3.652e7)     # what analyze --ke 3.652e7 reports
    lower = band.lower
    rho = lambda ke: spectral_radius(5.0, 10.0, 10.0, ke, 1e-3, 3.7)
    assert 3.648e7 < lower < 3.652e7 < band.upper
    assert rho(lower * (1 - 1e-5)) >= 1.0                       # the sliver is just below the edge
    assert all(rho(ke) < 1.0 for ke in np.geomspace(lower * (1 + 1e-5), 3.652e7, 40))
    assert rho(3.6500e7) >= 1.0                                   # inside the sliver, as the review found
