"""Stiffness limits along the moving path (monodromy, stability.periodic) and from the
scenario's own start (stability.first_contact), against closed forms and bisection in
the simulator (issue 28, items 1, 2 and 4)."""
import math

import numpy as np
import pytest

from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario

# a short path (1 s circle) at 250 Hz: 250 samples per period, cheap on CasADi's virtual machine
CHEAP = ["controller.rate=250", "trajectory.period=1.0"]


@pytest.fixture(scope="module")
def cheap_model():
    from tmtcontrol.stability.periodic import PeriodicModel

    return PeriodicModel(apply_overrides(paper_scenario(), CHEAP), compile=False)


def test_a_virtual_machine_tangent_step_does_not_serve_a_compiled_request(cheap_model):
    """Regression: the tangent steps were memoised by loop structure alone, so after
    one PeriodicModel(compile=False) every later model of the same loop ran its
    periodic search on CasADi's virtual machine (test_simulate_quotes_the_first_
    contact_limit_in_the_bistable_region took 30 s after such a test, 2 s without)."""
    from tmtcontrol.stability.periodic import PeriodicModel

    assert cheap_model.rollout.how == "vm"
    compiled = PeriodicModel(cheap_model.scenario, compile=True)
    assert compiled.rollout is not cheap_model.rollout
    assert compiled.rollout.how in ("compiled", "cached")
    assert PeriodicModel(cheap_model.scenario, compile=False).rollout.how == "vm"


@pytest.mark.parametrize("kw, said", [({"iters": 0}, "iters"), ({"iters": 2.5}, "iters"),
                                      ({"tol": 0.0}, "tol"), ({"tol": float("nan")}, "tol")])
def test_a_periodic_search_with_no_newton_step_or_no_tolerance_is_refused(cheap_model, kw, said):
    """Regression: ``PeriodicModel.at(k_e, iters=0)`` ended in UnboundLocalError
    (the shooting loop never ran, its monodromy was never set); a tolerance of 0
    or NaN could never be met. Each is refused naming the argument."""
    from tmtcontrol.stability.continuous import AnalysisError

    with pytest.raises(AnalysisError, match=f"^{said}: must be"):
        cheap_model.at(2e4, **kw)


def _balance(A_abs):
    """D and D^-1 from stability.periodic._balancing, checked here against what balancing means: in
    D^-1 A D each state's off-diagonal row and column have equal 2-norms (1e-8)."""
    from tmtcontrol.stability.periodic import _balancing

    d = _balancing(A_abs)
    B = A_abs * d[None, :] / d[:, None]
    np.fill_diagonal(B, 0.0)
    rows, cols = np.linalg.norm(B, axis=1), np.linalg.norm(B, axis=0)
    coupled = (rows > 0) | (cols > 0)
    np.testing.assert_allclose(rows[coupled], cols[coupled], rtol=1e-8)
    return np.diag(d), np.diag(1.0 / d)


def _groups(mean):
    """The strongly connected groups of states (scipy's csgraph) of a nonnegative matrix's pattern."""
    from scipy.sparse.csgraph import connected_components

    count, group = connected_components(mean != 0, directed=True, connection="strong")
    return [np.ix_(np.flatnonzero(group == g), np.flatnonzero(group == g)) for g in range(count)]


def _balanced_power_growth(A, N):
    """Per group of states, max over 1 <= L <= N of ||D^-1 A^L D|| / ||D^-1 A D|| (A^L's diagonal block is
    the block's power), the largest over the groups (at least 1)."""
    out = 1.0
    for block in _groups(np.abs(A)):
        D, Di = _balance(np.abs(A)[block])
        norms = [np.linalg.norm(Di @ np.linalg.matrix_power(A[block], L) @ D, 2) for L in range(1, N + 1)]
        if norms[0] > 0:                 # (a group the step overwrites carries nothing on)
            out = max(out, max(norms) / norms[0])
    return out


def _brute_growth(As, chunk):
    """Per group of states: max over starts b (every ``chunk`` samples) and 1 <= L <= N of
    ||D^-1 A_(b+L-1) ... A_b D||_2 (indices round the period), over the largest ||D^-1 A_b D||_2; D balancing
    the mean |A_b|; the largest over the groups (at least 1)."""
    N = len(As)
    starts = range(0, N, chunk)
    mean = np.mean([np.abs(As[b]) for b in starts], axis=0)
    out = 1.0
    for block in _groups(mean):
        sub = [A[block] for A in As]
        D, Di = _balance(mean[block])
        best = 0.0
        for b in starts:
            prod = np.eye(sub[0].shape[0])
            for L in range(N):
                prod = sub[(b + L) % N] @ prod
                best = max(best, np.linalg.norm(Di @ prod @ D, 2))
        one = max(np.linalg.norm(Di @ sub[b] @ D, 2) for b in starts)
        if one > 0:
            out = max(out, best / one)
    return out


def _pieces(As, chunk):
    """The transition matrices of the ``chunk``-sample pieces of the period ``As`` as
    ``PeriodicModel._growth`` hands them to ``_window_growth``: ``pieces[j][tau - 1]`` = A_(b+tau-1) ... A_b."""
    out = []
    for b in range(0, len(As), chunk):
        P, run = np.eye(As[0].shape[0]), []
        for A in As[b:b + chunk]:
            P = A @ P
            run.append(P)
        out.append(np.array(run))
    return out


def test_the_window_growth_multiplies_in_order_over_whole_periods():
    """Review 41's survivors: pieces multiplied in the wrong order (P @ end instead of end @ P) and the last
    round of windows (those ending a whole period of pieces after their start) dropped both passed, the
    tests' Jacobians nearly commuting and their growth peaking inside a period. Here every sample has its
    own random, non-normal Jacobian and a slow expansion (1.004 a sample), so the growth peaks at the
    longest windows: the pruned figure is the brute-force one (1e-10, rounding of the products)."""
    from tmtcontrol.stability.periodic import GROWTH_CHUNK, _window_growth

    rng = np.random.default_rng(41)
    n, N = 5, 4 * GROWTH_CHUNK
    As = [1.004 * (np.eye(n) + 0.08 * rng.standard_normal((n, n))) for _ in range(N)]
    want = _brute_growth(As, GROWTH_CHUNK)
    assert _window_growth(_pieces(As, GROWTH_CHUNK)) == pytest.approx(want, rel=1e-10) and want > 2.0


def test_a_window_growth_beyond_the_floats_is_infinite_not_an_error():
    """Found in the eleventh session (review 41 left the NaN pre-check's removal alive): a period whose
    one-step Jacobians are finite but whose products overflow (entries of 1e150: a piece's second product
    is 1e300, its third inf) raised numpy's LinAlgError out of the balancing (the squared entries
    overflowed) instead of an infinite growth; a NaN anywhere, at a piece's start or inside it, is
    infinite too. Scaling every Jacobian by 1e-200 (products underflow to 0) leaves the floor of 1
    (exact). The balancing does not depend on the matrix's scale (1e-12)."""
    from tmtcontrol.stability.periodic import GROWTH_CHUNK, _balancing, _window_growth

    rng = np.random.default_rng(11)
    As = [np.eye(3) + 0.3 * rng.standard_normal((3, 3)) for _ in range(2 * GROWTH_CHUNK)]
    assert np.isfinite(_window_growth(_pieces(As, GROWTH_CHUNK)))
    with np.errstate(all="ignore"):
        assert _window_growth(_pieces([1e150 * A for A in As], GROWTH_CHUNK)) == math.inf
        assert _window_growth(_pieces([1e-200 * A for A in As], GROWTH_CHUNK)) == 1.0
        for at in (0, 3, GROWTH_CHUNK):
            bad = [A.copy() for A in As]
            bad[at][1, 2] = np.nan
            assert _window_growth(_pieces(bad, GROWTH_CHUNK)) == math.inf
    M = np.abs(rng.standard_normal((4, 4)))
    d = _balancing(M)
    for c in (1e200, 1e-300):
        assert _balancing(c * M) / _balancing(c * M)[0] == pytest.approx(d / d[0], rel=1e-12)


def test_the_transient_growth_does_not_depend_on_units_or_on_where_the_period_starts():
    """Review 38: the growth was ||Phi(t, 0)|| / ||Phi(1, 0)|| in SI units, so a state in kN instead of N moved
    it 1.6-fold (and the limit with it), and a path starting half a period later hid a 7.5e6-fold growth
    behind 1.0. Now every window start every GROWTH_CHUNK samples, in balanced coordinates: on a made-up
    period of 200 random Jacobians with one unstable arc, a state's unit scaled by 1e6, 1e3, 37 or 1e-3
    leaves the figure as it was (1e-8: the balancing's convergence; scipy's matrix_balance, which rounds
    to powers of 2, moved it up to 11-fold here), a start moved by
    a whole piece not at all (1e-12), by part of one at most by the decay over that part before the arc
    (0.97 a sample here: a bound of 0.97^GROWTH_CHUNK; on review 38's 4-joint arm, 3 %); the figure is the
    brute-force one (1e-10)."""
    from tmtcontrol.stability.periodic import GROWTH_CHUNK, _window_growth

    rng = np.random.default_rng(38)
    n, N = 6, 4 * GROWTH_CHUNK
    base = 0.97 * np.eye(n) + 0.005 * rng.standard_normal((n, n))
    unstable = np.eye(n) * 1.08 + 0.05 * rng.standard_normal((n, n))
    As = [unstable if 60 <= j < 120 else base for j in range(N)]
    As = [A * np.array([1, 1e3, 1, 1e-2, 1, 1])[:, None] / np.array([1, 1e3, 1, 1e-2, 1, 1])[None, :] for A in As]

    pieces = lambda seq: _pieces(seq, GROWTH_CHUNK)

    g = _window_growth(pieces(As))
    assert g == pytest.approx(_brute_growth(As, GROWTH_CHUNK), rel=1e-10) and g > 50
    for i in range(n):
        for unit in (1e6, 1e3, 37.0, 1e-3):
            S = np.ones(n)
            S[i] = unit
            assert _window_growth(pieces([S[:, None] * A / S[None, :] for A in As])) == pytest.approx(g, rel=1e-8)
    assert _window_growth(pieces(As[GROWTH_CHUNK:] + As[:GROWTH_CHUNK])) == pytest.approx(g, rel=1e-12)
    worst = 0.97 ** GROWTH_CHUNK * np.max(np.abs(np.linalg.eigvals(base))) / 0.97
    for shift in (7, 25, 43):
        assert worst <= _window_growth(pieces(As[shift:] + As[:shift])) / g <= 1 / worst


def test_monodromy_of_a_path_standing_still_is_the_frozen_jacobian_to_the_period():
    """Closed form: with the path standing still (radius 0) the orbit is the frozen
    fixed point and Phi = A^N, so rho(Phi) = rho(A)^N. Tolerance 1e-6 relative: the
    two Jacobians come from different code (SX in the rolled-out step vs MX AD in
    stability.wholeloop), agreeing to ~1e-12 per sample."""
    from tmtcontrol.stability.periodic import PeriodicModel

    sc = apply_overrides(paper_scenario(), [*CHEAP, "trajectory.radius=0.0"])
    mdl = PeriodicModel(sc, compile=False)
    for k_e in (2e4, 4.1e4):
        per = mdl.at(k_e)
        frozen = mdl.frozen.at(k_e, 0.0)
        assert per.samples == 250
        want = np.linalg.matrix_power(frozen.A, per.samples)
        assert np.max(np.abs(per.monodromy - want)) <= 1e-6 * max(1.0, np.max(np.abs(want)))
        assert per.spectral_radius == pytest.approx(frozen.spectral_radius ** per.samples, rel=1e-6)
        assert per.residual < 1e-8
        # the transient growth: every window is a power of A: max over L <= N of ||D^-1 A^L D|| / ||D^-1 A D||,
        # D balancing |A| (scipy.linalg.matrix_balance)
        assert per.transient_growth == pytest.approx(_balanced_power_growth(frozen.A, per.samples), rel=1e-6)


class _Measured:
    """A stand-in for PeriodicModel whose orbit at k_e has closed-form measures:
    spectral radius (k_e / k_rho), transient growth GROWTH_BOUND (k_e / k_g)^2,
    and no orbit above k_lost (AnalysisError)."""

    scenario = None

    def __init__(self, k_rho, k_g, k_lost):
        self.k_rho, self.k_g, self.k_lost, self.asked = k_rho, k_g, k_lost, []

    def at(self, k_e, growth="always"):
        from types import SimpleNamespace

        from tmtcontrol.stability.continuous import AnalysisError
        from tmtcontrol.stability.periodic import GROWTH_BOUND

        self.asked.append(k_e)
        if k_e > self.k_lost:
            raise AnalysisError("no orbit")
        return SimpleNamespace(spectral_radius=k_e / self.k_rho, transient_growth=GROWTH_BOUND * (k_e / self.k_g) ** 2)


@pytest.mark.parametrize("k_rho, k_g, k_lost, want, set_by", [
    (1e5, 3e5, 9e5, 1e5, "spectral radius"),
    (3e5, 1e5, 9e5, 1e5, "transient growth"),
    (3e5, 2e5, 1e5, 1e5, "orbit lost"),
], ids=["floquet", "growth", "lost"])
def test_the_periodic_search_ends_where_the_first_of_its_measures_fails(k_rho, k_g, k_lost, want, set_by):
    """periodic_search's limit is the smallest of three stiffnesses known in closed form (the
    spectral radius reaching 1, the transient growth reaching GROWTH_BOUND, the orbit lost) and
    says which; the radius and growth it reports are the stable side's (xtol 1e-5 in log k_e:
    1e-5 relative). Without the growth bound (inf) the growth case ends at the next measure."""
    import math
    import re

    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.periodic import GROWTH_BOUND, periodic_search

    model = _Measured(k_rho, k_g, k_lost)
    found = periodic_search(None, model=model, bracket=(3e4, 2e6))
    assert found.k_e == pytest.approx(want, rel=2e-5) and found.set_by == set_by
    assert found.spectral_radius == pytest.approx(found.k_e / k_rho, rel=2e-5)
    assert found.transient_growth == pytest.approx(GROWTH_BOUND * (found.k_e / k_g) ** 2, rel=5e-5)
    assert found.spectral_radius < 1 and found.transient_growth < GROWTH_BOUND
    if set_by == "transient growth":
        assert periodic_search(None, model=_Measured(k_rho, k_g, k_lost), bracket=(3e4, 2e6),
                               growth_bound=float("inf")).k_e == pytest.approx(k_rho, rel=2e-5)
    with pytest.raises(AnalysisError, match="^growth_bound: must be > 1"):
        periodic_search(None, model=model, bracket=(3e4, 2e6), growth_bound=1.0)
    # review 39: a bound below the growth at the smallest stiffness the search widens to (8 steps of 0.1 in
    # log k_e below 3e4: 1.348e4 N/m, growth 1e5 (1.348e4 / k_g)^2 = 1.8e3) is said so, not "no boundary found"
    # alone; review 40: and what the other end was
    k_low = 3e4 * math.exp(-0.8)
    with pytest.raises(AnalysisError, match=re.escape(
            f"(at {k_low:.4g} N/m the transient growth {GROWTH_BOUND * (k_low / k_g) ** 2:.3g} is at or above the "
            f"bound 100 (spectral radius {k_low / k_rho:.3g}); at 2e+06 N/m ")):
        periodic_search(None, model=_Measured(k_rho, k_g, k_lost), bracket=(3e4, 2e6), growth_bound=100.0)


class _Given:
    """A stand-in for PeriodicModel with ``measures(k_e)`` = (spectral radius, transient growth) or None
    (no orbit: AnalysisError)."""

    scenario = None

    def __init__(self, measures):
        self.measures = measures

    def at(self, k_e, growth="always"):
        from types import SimpleNamespace

        from tmtcontrol.stability.continuous import AnalysisError

        m = self.measures(k_e)
        if m is None:
            raise AnalysisError("no orbit")
        return SimpleNamespace(spectral_radius=m[0], transient_growth=m[1])


def test_the_periodic_searchs_last_widening_is_tried_and_a_failure_names_both_ends():
    """Review 40: (a) the bracket's eighth widening (3e4 e^-0.8 = 13,480 N/m) was computed and never tested:
    a loop stable below 3e4 e^-0.75 = 14,170 N/m said "no stability boundary found" although that bracket
    holds; (b) a failure named neither end's state, so an inverted bracket (a growth falling with k_e, met
    at the stiff end only), a loop unstable everywhere and an orbit never found read alike."""
    import math

    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.periodic import periodic_search

    edge = 3e4 * math.exp(-0.75)
    found = periodic_search(None, model=_Given(lambda k: (0.5, 10.0) if k < edge else (2.0, math.nan)),
                            bracket=(3e4, 2e6))
    assert found.k_e == pytest.approx(edge, rel=2e-5) and found.set_by == "spectral radius"
    with pytest.raises(AnalysisError, match=r"\(at 1\.348e\+04 N/m the transient growth 7\.42e\+05 is at or above "
                       r"the bound 1e\+05 \(spectral radius 0\.1\); at 4\.451e\+06 N/m the orbit is stable "
                       r"\(spectral radius 0\.1, transient growth 2\.25e\+03\)\)$"):
        periodic_search(None, model=_Given(lambda k: (0.1, 1e5 * 1e5 / k)), bracket=(3e4, 2e6))
    with pytest.raises(AnalysisError, match=r"\(at 1\.348e\+04 N/m the orbit is unstable \(spectral radius 2\); "
                       r"at 2e\+06 N/m the orbit is unstable \(spectral radius 2\)\)$"):
        periodic_search(None, model=_Given(lambda k: (2.0, math.nan)), bracket=(3e4, 2e6))
    with pytest.raises(AnalysisError, match=r"\(at 1\.348e\+04 N/m no periodic orbit in contact was found; "
                       r"at 2e\+06 N/m no periodic orbit in contact was found\)$"):
        periodic_search(None, model=_Given(lambda k: None), bracket=(3e4, 2e6))


def test_the_periodic_searchs_own_bracket_is_the_frozen_limits_widened_two_percent(monkeypatch):
    """Review 41's survivor: periodic_search called without a bracket (as periodic_limit(scenario) is)
    starts from the frozen loop's smallest and largest limits along the path, each 2 % outward; the low
    end's / 1.02 mutated away passed every test (the deciding limit passes its own bracket). The frozen
    limits are stubbed (1e4 and 1.3e4 N/m) and the first two stiffnesses asked are recorded (exp(log k):
    1e-12 relative). A frozen loop without a finite limit is refused in one sentence."""
    import math

    from tmtcontrol.stability import onedim, wholeloop
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.periodic import periodic_search

    monkeypatch.setattr(onedim, "scenario_parameters", lambda sc: {"k_e_min": 5e3})
    monkeypatch.setattr(onedim, "scenario_stiffness_limit", lambda sc: 1.1e4)
    frozen = []
    monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda sc, **kw: frozen.append(kw) or (
        1e4, [(0.0, 1e4), (1.0, 1.3e4), (2.0, 1.1e4)]))
    asked = []
    model = _Given(lambda k: asked.append(k) or ((0.5, 10.0) if k < 1.15e4 else (2.0, math.nan)))
    model.frozen = "the frozen model"
    found = periodic_search(None, model=model)
    assert asked[:2] == [pytest.approx(1e4 / 1.02, rel=1e-12), pytest.approx(1.3e4 * 1.02, rel=1e-12)]
    assert found.k_e == pytest.approx(1.15e4, rel=2e-5)
    (kw,) = frozen
    assert kw["model"] == "the frozen model" and kw["guess"] == 1.1e4 and kw["within"] == 5e3
    monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda sc, **kw: (math.inf, [(0.0, math.inf)]))
    with pytest.raises(AnalysisError, match="^the frozen loop has no finite stiffness limit"):
        periodic_search(None, model=model)


@pytest.mark.heavy          # 2-3 s each on the 2026-12-07 machine (the README's command stays under 3 min)
def test_monodromy_along_the_moving_circle_is_the_product_of_independent_jacobians(cheap_model):
    """The tangent-linear rollouts (forward-mode AD in the compiled-step form,
    stability.periodic) against the product A_(N-1) ... A_0 of the whole-loop
    Jacobians (reverse/MX AD in stability.wholeloop, another CasADi graph)
    evaluated at the orbit's own states, the path moving. Tolerance 1e-9 of the
    largest entry: 250 products of Jacobians that agree to ~1e-13 each."""
    from tmtcontrol.simulation.closedloop import INPUT

    mdl = cheap_model
    k_e = 3e4
    per = mdl.at(k_e)
    d = mdl.dynamic
    U = mdl._inputs(k_e)
    S, _ = mdl.frozen.loop.rollout.run(per.s_orbit, U, mdl.P)
    states = np.column_stack([per.s_orbit, S[:, :-1]])
    want = np.eye(d.size)
    for j in range(per.samples):
        A = np.array(mdl.frozen._jac(states[:, j], np.r_[U[:, j], mdl.P]))[np.ix_(d, d)]
        want = A @ want
    assert U[INPUT["k_e"]].min() == U[INPUT["k_e"]].max() == k_e
    assert np.ptp(U[0]) > 0.01                   # the path moves (a circle, not a point)
    assert np.max(np.abs(per.monodromy - want)) <= 1e-9 * np.max(np.abs(want))
    assert per.spectral_radius == pytest.approx(np.max(np.abs(np.linalg.eigvals(want))), rel=1e-9)
    # the transient growth from the same independent Jacobians, by brute force: every window from a start every
    # GROWTH_CHUNK samples to every end up to one period later, in the coordinates balancing the mean |A| at the
    # starts (1e-9: products as above; 2-norms of matrices whose entries agree to that)
    from tmtcontrol.stability.periodic import GROWTH_CHUNK

    As = [np.array(mdl.frozen._jac(states[:, j], np.r_[U[:, j], mdl.P]))[np.ix_(d, d)] for j in range(per.samples)]
    assert per.transient_growth == pytest.approx(_brute_growth(As, GROWTH_CHUNK), rel=1e-9)
    assert per.transient_growth >= 1.0


@pytest.mark.heavy   # a bisection in the simulator (5.5 s): the cross-check runs in CI's heavy step
def test_periodic_limit_within_1_percent_of_the_simulator_where_the_frozen_minimum_is_not(cheap_model):
    """The simulated loop (compiled step, along the circle, constant k_e) converges at
    0.99x the periodic limit and does not at 1.01x; the frozen-point minimum is more
    than 1 % below (so this case tells the two apart). The simulated decay per period
    is the monodromy's spectral radius (2 %: the measured max difference between
    periods also carries the faster modes)."""
    from tmtcontrol.stability.first_contact import LoopRunner, periodic_decay
    from tmtcontrol.stability.periodic import periodic_limit
    from tmtcontrol.stability.wholeloop import whole_loop_limit

    sc = cheap_model.scenario
    frozen_min, points = whole_loop_limit(sc, points=8, rtol=1e-3, model=cheap_model.frozen)
    limit = periodic_limit(sc, model=cheap_model,
                           bracket=(frozen_min / 1.02, max(l for _, l in points) * 1.02))
    assert frozen_min < 0.99 * limit
    runner = LoopRunner(sc, compile=False)
    below = periodic_decay(runner, 0.99 * limit, 5)
    assert below < 1.0
    assert periodic_decay(runner, 1.01 * limit, 5) > 1.0
    assert below == pytest.approx(cheap_model.at(0.99 * limit).spectral_radius, rel=0.02)
    # the default model and bracket (the frozen loop's limits over the path, widened 2 %) find the same root
    assert periodic_limit(sc) == pytest.approx(limit, rel=1e-4)


def test_periodic_orbit_refuses_a_period_that_is_not_whole_samples():
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.periodic import PeriodicModel

    with pytest.raises(AnalysisError, match="trajectory.period"):
        PeriodicModel(apply_overrides(paper_scenario(), ["controller.rate=250", "trajectory.period=1.001"]),
                      compile=False)


@pytest.mark.heavy          # 2.6-11 s on the 2026-12-07 machine (the README's command stays under 3 min)
def test_first_contact_limit_at_minus_10_mm_within_2_percent_of_full_runs(paper_sim):
    """Issue 28 item 1: at delta = -10 mm the start locks into a contact limit cycle
    from about 1.2e5 N/m, 20 % below the small-signal limit (143,816 N/m, the 1-D
    law loop). The short-run bisection (3 s runs) must lie within 2 % of what the
    scenario's own 16 s runs show: one settles at 0.98x, the other keeps cycling at
    1.02x."""
    from tmtcontrol.stability.first_contact import LoopRunner, first_contact_limit

    sc = apply_overrides(paper_scenario(), ["controller.x_e_error=-0.01"])
    runner = LoopRunner(sc, sim=paper_sim)
    limit = first_contact_limit(sc, 1.45e5, runner=runner)
    assert 1.0e5 < limit < 1.3e5                      # well below the small-signal limit: bistable
    for factor, cycling in ((0.98, False), (1.02, True)):
        f = runner.run(factor * limit, 16.0)
        last = f[-1000:]
        assert bool(np.ptp(last) > 0.2 * sc.controller.f_d) is cycling, factor


@pytest.mark.heavy
def test_the_smaller_limit_decides_the_scenario_verdict(monkeypatch):
    """analyze_scenario(limits=True): k_e max = 2e4 N/m; a first-contact limit below it
    fails the verdict even when the periodic limit is above, and the text says which."""
    from tmtcontrol.stability import analysis, first_contact, periodic, wholeloop

    monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda *a, **k: (1e5, [(0.0, 1e5), (1.0, 1.1e5)]))
    monkeypatch.setattr(periodic, "periodic_search",
                        lambda *a, **k: periodic.PeriodicLimit(1.05e5, "spectral radius", 0.99, 1.0))
    for first, stable in ((1.9e4, False), (2.1e4, True), (2e5, True)):
        monkeypatch.setattr(first_contact, "first_contact_limit", lambda sc, hi, **k: min(first, hi))
        a = analysis.analyze_scenario(paper_scenario(), limits=True)
        assert a["sampled_stable"] is stable
        assert a["limit"] == min(first, 1.05e5)
        assert a["limit_from"] == ("first contact" if first < 1.05e5 else "periodic orbit")
        text = analysis.format_analysis(a)
        assert f"along the path       {1.05e5:.6g} N/m" in text
        assert (f"from first contact   {first:.6g} N/m (the scenario's own start settles below it" if first < 1.05e5
                else f"from first contact   >= {1.05e5:.6g} N/m (the scenario's own start settles up to the "
                     "periodic limit, where the search stops)") in text
        # the 1-D figure (163,417 N/m) is above the deciding limit: labelled small-signal, not a safe limit
        assert a["max_stable_stiffness"] > a["limit"]
        assert "max stable k_e" not in text
        assert f"small-signal k_e     {a['max_stable_stiffness']:.6g} N/m" in text and "not a safe limit" in text
    # a deciding limit above the 1-D figure: that figure is a safe limit and says so
    monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda *a, **k: (1.9e5, [(0.0, 1.9e5), (1.0, 2e5)]))
    monkeypatch.setattr(periodic, "periodic_search",
                        lambda *a, **k: periodic.PeriodicLimit(2e5, "spectral radius", 0.99, 1.0))
    a = analysis.analyze_scenario(paper_scenario(), limits=True)
    assert a["limit"] == 2e5 > a["max_stable_stiffness"]
    assert f"max stable k_e       {a['max_stable_stiffness']:.6g} N/m" in analysis.format_analysis(a)


# -- heavy: the issue's cases against bisection in the simulator -------------------------------------------------

PERIODIC_CASES = {
    "1 ms": [],
    "2 ms": ["controller.rate=500"],
    "4 ms": ["controller.rate=250"],
    "delay 1": ["controller.delay_samples=1"],
    "delay 2": ["controller.delay_samples=2"],
    "filter 100 Hz": ["sensor.filter_cutoff=100"],
    "m 2, b 120, k 200": ["impedance.m=[2,1,1]", "impedance.b=[120,20,20]", "impedance.k=[200,100,100]"],
    "scheduled damping": ["controller.damping_schedule.kind=zeta"],
}


@pytest.mark.heavy
@pytest.mark.parametrize("case", sorted(PERIODIC_CASES))
def test_periodic_limit_matches_simulated_bisection_within_1_percent(case):
    from tmtcontrol.stability.first_contact import simulated_limit
    from tmtcontrol.stability.periodic import periodic_limit

    sc = apply_overrides(paper_scenario(), PERIODIC_CASES[case])
    predicted = periodic_limit(sc)
    simulated = simulated_limit(sc, predicted / 1.05, predicted * 1.05, rtol=1e-3)
    assert predicted == pytest.approx(simulated, rel=0.01)


@pytest.mark.heavy
@pytest.mark.parametrize("delta", [-0.002, -0.005, -0.01])
def test_first_contact_limit_matches_full_runs_within_2_percent(delta):
    """Bisection on the scenario's own 16 s runs (the last second judged as in
    first_contact.settles) against the short-run analysis."""
    import math

    from tmtcontrol.stability.analysis import scenario_stiffness_limit
    from tmtcontrol.stability.first_contact import LoopRunner, first_contact_limit

    sc = apply_overrides(paper_scenario(), [f"controller.x_e_error={delta}"])
    runner = LoopRunner(sc)
    small = scenario_stiffness_limit(sc)
    limit = first_contact_limit(sc, small, runner=runner)

    def settles_long(k):
        f = runner.run(k, 16.0)
        last, before = np.ptp(f[-1000:]), np.ptp(f[-2000:-1000])
        return not (last >= 0.2 * sc.controller.f_d and last >= 0.8 * before)

    lo, hi = limit / 1.1, min(limit * 1.1, small)
    assert settles_long(lo) and not settles_long(hi)
    while hi / lo > 1.001:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if settles_long(mid) else (lo, mid)
    assert limit == pytest.approx(lo, rel=0.02)


@pytest.mark.heavy
def test_analyze_scenario_json_gives_both_limits(tmp_path):
    import json
    import subprocess
    import sys

    from tmtcontrol.simulation.scenario import dump_scenario

    path = tmp_path / "s.toml"
    path.write_text(dump_scenario(apply_overrides(paper_scenario(), [*CHEAP, "controller.x_e_error=-0.01"])))
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "analyze", "--scenario", str(path), "--json"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode in (0, 1), r.stderr
    d = json.loads(r.stdout)
    assert d["first_contact_limit"] < d["periodic_limit"]
    assert d["limit"] == d["first_contact_limit"]
    assert d["whole_loop_limit"] < d["periodic_limit"]


@pytest.mark.heavy      # limits against simulated runs (~4 s); the README suite stays within its 3 minutes
def test_scheduled_damping_limits_match_the_simulator():
    """Issue 28 item 4: with controller.damping_schedule.kind = "zeta" the analysis
    said 0 N/m. Every path now linearises at the schedule's fixed point: the frozen
    loop finds its equilibrium (b_n = 2 zeta sqrt(m (k + k_e)) there), the periodic
    limit lies between the frozen minimum and maximum over the path and the
    simulated loop converges at 0.99x it and does not at 1.01x; the 1-D model (worst
    mass) is within 3 % below it (it is the conservative explanation)."""
    import math

    from tmtcontrol.stability.analysis import scenario_stiffness_limit
    from tmtcontrol.stability.first_contact import LoopRunner, periodic_decay
    from tmtcontrol.stability.periodic import PeriodicModel, periodic_limit
    from tmtcontrol.stability.wholeloop import whole_loop_limit

    sc = apply_overrides(paper_scenario(), [*CHEAP, "controller.damping_schedule.kind=zeta"])
    mdl = PeriodicModel(sc, compile=False)
    point = mdl.frozen.at(2e4, 0.0)
    assert point.residual < 1e-8
    assert point.s_eq[mdl.layout["b_n"]][0] == pytest.approx(2 * math.sqrt(1.0 * (100 + 2e4)), rel=1e-9)
    one_d = scenario_stiffness_limit(sc)
    lo, points = whole_loop_limit(sc, points=4, rtol=1e-3, model=mdl.frozen, guess=one_d)
    limit = periodic_limit(sc, model=mdl, bracket=(lo / 1.02, max(l for _, l in points) * 1.02))
    assert lo <= limit <= max(l for _, l in points) * 1.001
    assert 0.97 * limit < one_d < limit
    runner = LoopRunner(sc, compile=False)
    assert periodic_decay(runner, 0.99 * limit, 5) < 1.0
    assert periodic_decay(runner, 1.01 * limit, 5) >= 1.0


@pytest.mark.heavy
def test_simulate_quotes_the_first_contact_limit_in_the_bistable_region(paper_sim, tmp_path, capsys):
    """delta = -10 mm, k_e = 1.3e5 N/m: below the small-signal limit (1-D: 143,816
    N/m) but above the first-contact one (~1.2e5, bracketed by the simulations of
    test_first_contact_limit_at_minus_10_mm_within_2_percent_of_full_runs): the run
    locks into a limit cycle and exits 1; the line quotes the loop's limit (first
    contact) and labels the 1-D figure as small-signal, not a safe limit here."""
    import re

    from tmtcontrol.cli import main

    code = main(["simulate", "paper", "--out", str(tmp_path / "out"), "--no-plots",
                 "--set", "controller.x_e_error=-0.01", "--set", "environment.stiffness.values=[1.3e5]",
                 "--set", "trajectory.cycles=1"])
    err = capsys.readouterr().err
    assert code == 1
    m = re.search(r"the loop's limit ([\d,]+) N/m \(first contact; as tmtcontrol analyze --scenario\), "
                  r"1-D small-signal ([\d,]+) N/m \(not a safe limit here\)", err)
    assert m, err
    first, small = (float(g.replace(",", "")) for g in m.groups())
    assert small == pytest.approx(1.438e5, rel=2e-3)
    assert 1.15e5 < first < 1.25e5
    # regression (review 10): with the segment already in a limit cycle summary.json kept the 1-D figure
    # beside a line quoting the first-contact limit; it holds the figure the line quotes
    import json

    run = json.loads((tmp_path / "out" / "summary.json").read_text())["run"]
    assert f"{run['stiffness_limit']:,.0f}" == f"{first:,.0f}" and run["stiffness_limit_from"] == "first contact"
    # the docs quote these two figures (cli.md, simulation.md): they drift with what simulate prints
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1] / "docs"
    assert f"the loop's limit {first:,.0f} N/m (first contact" in (docs / "cli.md").read_text()
    text = " ".join((docs / "simulation.md").read_text().split())
    assert f"below the 1-D figure ({small:,.0f} N/m) but above the first-contact limit ({first:,.0f} N/m)" in text


def test_simulate_analyze_sweep_and_report_quote_the_one_deciding_limit(monkeypatch, tmp_path, capsys):
    """Issue 43, one limit said once: every command takes the scenario's limit from
    stability.limit.deciding_limit. With that function replaced by a stub of known,
    odd figures (a loop limit of 123,457 N/m from first contact, a 1-D figure of
    150,001 N/m above it), simulate's verdicts and message, analyze --scenario's
    table, the sweep's row and the report's analysis all show the stub's figure, and
    the 1-D one only labelled as small-signal: a command that computed a limit of its
    own (the 1-D one, or the first contact up to it, as before) would show another."""
    import re

    from tmtcontrol.cli import main
    from tmtcontrol.simulation.scenario import apply_overrides, dump_scenario, paper_scenario
    from tmtcontrol.stability import limit
    from tmtcontrol.stability.analysis import analyze_scenario
    from tmtcontrol.sweep import run
    from tmtcontrol.sweep.run import case_limits

    monkeypatch.setattr(run, "_LIMITS", {})           # the sweep's memo: this test's stub stays in it
    stub = limit.ScenarioLimit(123457.0, "first contact", 150001.0, 140000.0, (140000.0, 140000.14),
                               ((0.0, 140000.0), (2.0, 141000.0)), periodic=145000.0, first_contact=123457.0)
    calls = []
    monkeypatch.setattr(limit, "_deciding_limit", lambda sc, *a: calls.append(sc.name) or stub)
    monkeypatch.setattr(limit, "_one_d", lambda sc: 150001.0)
    # a run at 1.3e5 N/m: below the 1-D figure, above the stub's limit (a ramp from 1e4 reaches it)
    sets = ["environment.stiffness={kind='piecewise_linear', times=[0.0, 2.0], values=[1e4, 1.6e5]}",
            "trajectory.cycles=0.5"]
    code = main(["simulate", "paper", "--out", str(tmp_path / "out"), "--no-plots",
                 *[a for s in sets for a in ("--set", s)]])
    err = capsys.readouterr().err
    assert code == 1 and err.startswith("beyond_limit: segment 1"), err
    assert "above the loop's predicted limit 123,457 N/m (first contact)" in err
    assert "the loop's limit 123,457 N/m (first contact; as tmtcontrol analyze --scenario), 1-D small-signal " \
           "150,001 N/m (not a safe limit here)" in err
    assert len(calls) == 1                          # attached and quoted: computed once

    sc = apply_overrides(paper_scenario(), sets)
    (tmp_path / "sc.toml").write_text(dump_scenario(sc))
    assert main(["analyze", "--scenario", str(tmp_path / "sc.toml")]) == 1
    out = capsys.readouterr().out
    assert re.search(r"\nlimit +123457 N/m \(the smaller: first contact", out), out
    assert re.search(r"from first contact +123457 N/m", out) and re.search(r"along the path +145000 N/m", out)
    row = case_limits(sc)
    assert (row["predicted_limit"], row["predicted_limit_from"], row["small_signal_limit"]) == \
        (123457.0, "first contact", 150001.0)
    a = analyze_scenario(sc, limits=True)           # what the report's analysis section shows
    assert (a["limit"], a["limit_from"], a["whole_loop_limit"]) == (123457.0, "first contact", 140000.0)


@pytest.mark.heavy
def test_the_check_beyond_the_paper_passes_and_fails_when_the_analysis_drifts(monkeypatch):
    """tmtcontrol check's analysis-vs-simulation cross-check at m = 2, delay 2, a force
    filter, a mass error, fixed and scheduled damping (issue 28 item 7; the five bugs
    it guards are mutations in benchmarks/mutation_score.py). It must also fail when
    the analysis moves by 5 %: here the 1-D loop's model mass error is ignored."""
    import numpy as np

    from tmtcontrol.checks import loop
    from tmtcontrol.stability import lawloop

    ok = loop.check_extensions(np.random.default_rng(0))
    assert ok.passed and ok.residual == 0.0, ok.note
    real = lawloop.law_loop
    monkeypatch.setattr(lawloop, "law_loop", lambda *a, **kw: real(*a, **{**kw, "model_scale": 1.0}))
    bad = loop.check_extensions(np.random.default_rng(0))
    assert not bad.passed and "limit" in bad.note


# -- issue 33: stability survivors, each case stated ---------------------------------------------------------------

def test_analyze_scenario_keeps_the_scenario_x_e_error():
    """A scenario with x_e error +5 mm on a 1e4 N/m surface (penetration f_d/k_e = 1 mm
    < delta): TMT's compliance estimate is clipped and the steady force is
    k_eff (delta + f_d/k) = 99.01 x 0.105 = 10.396 N, not f_d (closed form, eq. 12)."""
    from tmtcontrol.stability.analysis import analysis_kwargs, analyze, scenario_parameters

    sc = apply_overrides(paper_scenario(), ["controller.x_e_error=0.005", "environment.stiffness.values=[1e4]"])
    kw = {**analysis_kwargs(scenario_parameters(sc)), "Ts": None}
    d = analyze(**kw, law_params=sc.controller.law)
    k_eff = 100 * 1e4 / (100 + 1e4)
    assert d["steady_state_force_x_e_error"] == pytest.approx(k_eff * (0.005 + 10 / 100), rel=1e-9)


def test_worst_steady_force_is_the_one_farthest_from_f_d_not_the_largest():
    """known law (assumed 5e3 N/m), delta = -1 mm, k_e in [2e3, 2e4]: eq. (11)'s force
    f_d k_eff(k_e)/k_eff(5e3) + k_eff(k_e) delta is 9.619 N at 2e3 (0.38 N off) and
    10.05 N at 2e4 (0.05 N off): the worst is the smaller one."""
    from tmtcontrol.stability.analysis import analyze

    k_eff = lambda ke: 100 * ke / (100 + ke)
    force = lambda ke: 10 * k_eff(ke) / k_eff(5e3) + k_eff(ke) * -0.001
    assert force(2e4) > 10 > force(2e3) and abs(force(2e3) - 10) > abs(force(2e4) - 10)
    d = analyze(1.0, 60.0, 100.0, k_e_min=2e3, k_e_max=2e4, law="known", x_e_error=-0.001)
    assert d["steady_state_force_x_e_error"] == pytest.approx(force(2e3), rel=1e-9)


def test_law_loop_default_kd_is_b_over_m():
    """m = 2 kg: the default K_D of the law loop is B/M = 30 1/s (eq. 9), so the loop
    equals the one with kd = 30 given and differs from kd = B = 60."""
    from tmtcontrol.control.laws import get_law
    from tmtcontrol.stability.lawloop import law_loop

    kw = dict(m=2.0, b=60.0, k=100.0, k_e=2e4, Ts=1e-3, m_p=3.5, settle=0.1)
    tmt = get_law("tmt")
    default, given, wrong = (law_loop(tmt, **kw, **extra).A for extra in ({}, {"kd": 30.0}, {"kd": 60.0}))
    assert np.array_equal(default, given)
    assert np.max(np.abs(default - wrong)) > 1e-3


def test_stiffness_margin_is_in_decades():
    """A stiffness ten times below the limit has a margin of exactly one decade
    (log10), not ln 10 = 2.303 nepers."""
    from tmtcontrol.stability.sampled import stiffness_margin

    limits, _ = stiffness_margin(1.0, 60.0, 100.0, 3.7, [1e-3], [1e4])
    _, margin = stiffness_margin(1.0, 60.0, 100.0, 3.7, [1e-3], [limits[0] / 10])
    assert margin[0, 0] == pytest.approx(1.0, rel=1e-12)


# -- the generated doc tables (benchmarks/bench_limits.py) ----------------------------------------------------------

def _bench():
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bench_limits.py"
    spec = importlib.util.spec_from_file_location("bench_limits", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _rows(table: str) -> list[list[str]]:
    return [[c.strip() for c in line.strip("|").split("|")] for line in table.splitlines()[2:]]


def test_doc_limit_tables_are_generated_and_meet_the_issue_goals():
    """The tables bench_limits.py wrote into the docs are there (no placeholder) and
    say what the issue asks: periodic within 1 % of the simulated limit in every case,
    the frozen minimum below it, first contact within 2 % of the simulated runs."""
    import pathlib

    bench = _bench()
    root = pathlib.Path(__file__).resolve().parents[1]
    blocks = {name: bench.block((root / page).read_text(), name) for name, page in bench.DOCS.items()}
    assert all(b and "(generated)" not in b for b in blocks.values()), blocks
    periodic = _rows(blocks["periodic"])
    assert [r[0] for r in periodic] == list(bench.PERIODIC_CASES)
    for r in periodic:
        one_d, frozen, per, sim = (float(v) for v in r[1:5])
        assert abs(per / sim - 1) < 0.01 and frozen < per, r
    first = _rows(blocks["first_contact"])
    assert [float(r[0]) for r in first] == [1e3 * d for d in bench.FIRST_CONTACT_DELTAS]
    for r in first:
        assert abs(float(r[3]) / float(r[4]) - 1) < 0.02, r
    laws = {r[0].strip("`"): float(r[2]) for r in _rows(blocks["laws"])}
    assert laws["tmt"] >= max(laws.values()) * 0.999          # choosing-a-law.md: tmt (with known) the largest


@pytest.mark.heavy
def test_doc_limit_tables_do_not_drift():
    """Regenerate every table (the whole benchmark, minutes) and compare with the docs."""
    import pathlib

    bench = _bench()
    root = pathlib.Path(__file__).resolve().parents[1]
    # the values only: the benchmark's timed rows compute each limit twice (warm, then timed)
    t = bench.tables(bench.periodic_rows(timed=False), bench.first_contact_rows(timed=False), bench.law_rows(),
                     bench.threshold_rows(), bench.integral_rows())
    for name, page in bench.DOCS.items():
        _assert_same_table(bench.block((root / page).read_text(), name), t[name], name)


def _cell_value(cell: str):
    try:
        return float(cell.replace("%", "").strip()), cell.strip().endswith("%")
    except ValueError:
        return None, False


# The cells whose reference is a bisection over a verdict that is not monotone in k_e: the
# scheduled-damping row's simulated limit (column 4) and the two percentages made from it.
# Measured on 2026-12-05 (decay ratio over five periods, LoopRunner, 1 kHz): 1.22 at 2.650e6
# N/m, 0.58-0.59 at 2.655e6-2.665e6, 1.75 at 2.670e6; so the bisection lands anywhere in that
# band when its bracket (the periodic limit x/ 1.05) moves by 1e-5: 2.643e6 on 2026-12-04 and
# 2.662e6 on 2026-12-05 from the same periodic limit to 4 digits. Compared to 1 % (the band's
# width; docs/theory.md states the two within 1 %) and 1 percentage point.
_BISECTED_OVER_A_NON_MONOTONE_VERDICT = {("periodic", "scheduled damping (zeta = 1)"): {4, 5, 6}}


def _assert_same_table(doc: str, generated: str, name: str) -> None:
    """The table in the docs is what the benchmark prints now: the same rows
    and words; numbers to 1e-3 relative (4 significant digits print them, and
    the scheduled-damping row's limit is where Newton shooting stalls at the
    rounding of one period, which moves by a few 1e-4 with the order of the
    floating-point operations, docs/theory.md) and percentages to 0.1
    percentage point (the same shift, printed as a difference of two limits);
    the cells of _BISECTED_OVER_A_NON_MONOTONE_VERDICT to 1 % and 1 point."""
    a, b = _rows(doc), _rows(generated)
    assert doc.splitlines()[:2] == generated.splitlines()[:2], name
    assert len(a) == len(b), (name, doc, generated)
    for ra, rb in zip(a, b):
        assert len(ra) == len(rb), (name, ra, rb)
        loose = _BISECTED_OVER_A_NON_MONOTONE_VERDICT.get((name, ra[0]), set())
        for j, (ca, cb) in enumerate(zip(ra, rb)):
            (va, pa), (vb, _) = _cell_value(ca), _cell_value(cb)
            if va is None or vb is None:
                assert ca == cb, (name, ra, rb)
            elif pa:
                assert abs(va - vb) <= (1.0 if j in loose else 0.1) + 1e-9, (name, ra, rb)
            else:
                assert va == pytest.approx(vb, rel=1e-2 if j in loose else 1e-3, abs=1e-12), (name, ra, rb)


def test_the_drift_comparison_catches_a_changed_number_and_a_changed_word():
    """The tolerant comparison still fails on what a drift is."""
    doc = "| case | k | d |\n|---|---|---|\n| a | 2.664e+06 | -0.19 % |"
    _assert_same_table(doc, doc.replace("2.664e+06", "2.665e+06").replace("-0.19", "-0.11"), "t")
    for bad in (doc.replace("2.664e+06", "2.67e+06"), doc.replace("-0.19", "-0.35"), doc.replace("| a |", "| b |"),
                doc + "\n| c | 1 | 1 % |"):
        with pytest.raises(AssertionError):
            _assert_same_table(doc, bad, "t")
    # the scheduled-damping row: its simulated limit and the percentages made from it to 1 % / 1 point,
    # every other cell of the row (and that column in every other row) as tightly as the rest
    head = "| case | 1-D | frozen | periodic | simulated | per vs sim | frozen vs sim |\n|---|---|---|---|---|---|---|\n"
    row = "| scheduled damping (zeta = 1) | 2.576e+06 | 2.617e+06 | 2.664e+06 | 2.643e+06 | +0.80 % | -0.99 % |"
    other = "| paper, 1 ms | 1.634e+05 | 1.637e+05 | 1.672e+05 | 1.672e+05 | +0.04 % | -2.10 % |"
    table = head + other + "\n" + row
    _assert_same_table(table, table.replace("2.643e+06", "2.662e+06").replace("+0.80", "+0.04")
                       .replace("-0.99", "-1.71"), "periodic")
    for bad in (table.replace("2.643e+06", "2.68e+06"), table.replace("+0.80", "-0.30"),
                table.replace("2.664e+06", "2.67e+06"), table.replace("2.576e+06", "2.58e+06"),
                table.replace("| 1.672e+05 | +0.04", "| 1.68e+05 | +0.04"), table.replace("-2.10", "-1.50")):
        with pytest.raises(AssertionError):
            _assert_same_table(table, bad, "periodic")


class _SyntheticRunner:
    """A stand-in for LoopRunner: the force f_d + a(t)/2 sin(2 pi 7 t) with a
    peak-to-peak swing ``a(t) = a0 rate**t`` (per second), so the verdict of
    first_contact.settles is known in closed form."""

    def __init__(self, a0, rate):
        self.scenario = paper_scenario()
        self.a0, self.rate, self.durations = a0, rate, []

    def run(self, k_e, duration):
        self.durations.append(duration)
        t = np.arange(int(round(duration / 1e-3))) * 1e-3
        return 10.0 + 0.5 * self.a0 * self.rate ** t * np.sin(2 * np.pi * 7 * t + 0.3)


@pytest.mark.parametrize("a0, rate, settled", [
    (20.0, 0.93, True),     # shrinks 7 %/s: a limit cycle to a 3 s watch (ratio 0.93 > 0.8), settled by 3 s more
    (40.0, 0.97, True),     # 3 %/s: below 0.8 of the first watch's swing after 9 s more (0.97**9 = 0.76)
    (40.0, 0.995, False),   # 0.5 %/s: still 0.90 after the longest watch (21 s): a limit cycle
    (20.0, 1.0, False),     # sustained: a limit cycle at once (not shrinking, no longer watch)
    (5.0, 1.0, False),      # sustained at 0.5 f_d peak to peak: above the 0.2 f_d floor, a limit cycle
    (20.0, 0.85, True),     # 15 %/s: 0.85 of the second before (a limit cycle to the first watch), settled 3 s on
    (1.0, 0.9, True),       # below 0.2 f_d: settled at the first watch
])
def test_settles_watches_a_shrinking_swing_longer(a0, rate, settled):
    """first_contact.settles (issue 43): a swing that still shrinks is
    watched 3, 9, then 21 s longer and judged against where the first watch
    ended; closed-form verdicts on a synthetic force of known decay."""
    from tmtcontrol.stability.first_contact import LONGEST_WATCH, SETTLE_TIME, settles

    r = _SyntheticRunner(a0, rate)
    run = settles(r, 1e5)
    assert run.settled is settled
    first = SETTLE_TIME                      # the paper starts on the surface: full force at once
    if a0 * rate ** first < 2.0:
        assert r.durations == [first]
    elif rate >= 1.0:
        assert r.durations == [first, first + 3.0]
    elif not settled:
        assert r.durations[-1] == first + LONGEST_WATCH
    else:
        # settled at the first longer watch at which the swing is below 0.8 of the first watch's
        extra = next(e for e in (3.0, 9.0, 21.0) if rate ** e < 0.8)
        assert r.durations == [first, *[x + first for x in (3.0, 9.0, 21.0) if x <= extra]]


class _PeriodicRunner:
    """A stand-in for LoopRunner along the path: the force is a smooth orbit
    (f_d + 0.5 sin, one path period) plus a deviation that changes by the
    factor ``rate(k_e)`` per path period (37 cycles per period), or, with
    ``nyquist``, an oscillation at half the sampling rate of constant
    amplitude that repeats exactly from period to period; ``drop`` pulls the
    force below zero in the last period. The decay ratio that
    first_contact.periodic_decay must return is known by construction."""

    def __init__(self, rate, nyquist=0.0, drop=False, waves=37, amplitude=0.3):
        self.scenario = apply_overrides(paper_scenario(), ["trajectory.period=0.5"])
        self.rate, self.nyquist, self.drop, self.waves, self.amplitude = rate, nyquist, drop, waves, amplitude
        self.stiffness = []

    def run(self, k_e, duration, stiffness=None):
        self.stiffness.append(stiffness)
        Ts, P = 1e-3, self.scenario.trajectory.period
        k = np.arange(int(round(duration / Ts)))
        t = k * Ts
        f = (10.0 + 0.5 * np.sin(2 * np.pi * t / P)
             + self.amplitude * self.rate(k_e) ** (t / P) * np.sin(2 * np.pi * self.waves * t / P))
        f += self.nyquist * (-1.0) ** k
        if self.drop:
            f[-10:] = -1.0
        return f


@pytest.mark.parametrize("r", [0.5, 0.9, 0.97, 1.2])
def test_periodic_decay_is_the_deviations_ratio_per_period(r):
    from tmtcontrol.stability.first_contact import periodic_decay

    assert periodic_decay(_PeriodicRunner(lambda k: r), 1e5, cycles=5) == pytest.approx(r, rel=1e-9)


def test_periodic_decay_runs_the_documented_protocol():
    """One path period at 0.95 k_e, then k_e with +-5 % on its first four
    samples (a broadband kick), for ``cycles`` periods."""
    from tmtcontrol.stability.first_contact import periodic_decay

    r = _PeriodicRunner(lambda k: 0.5)
    periodic_decay(r, 1e5, cycles=3)
    (k,) = r.stiffness
    N = 500                                                  # 0.5 s at 1 kHz
    assert k.shape == (4 * N,)
    np.testing.assert_array_equal(k[:N], 0.95e5)
    np.testing.assert_allclose(k[N:N + 4], 1e5 * np.array([1.05, 0.95, 1.05, 0.95]), rtol=1e-15)
    np.testing.assert_array_equal(k[N + 4:], 1e5)


def test_periodic_decay_ignores_rounding_and_reports_growth_beside_a_saturated_swing():
    """A deviation at the rounding level (1e-12 N, below 1e-9 f_d) that
    doubles each period is no deviation: 0, stable. A deviation growing 1.2x
    per period beside a saturated half-sampling-rate swing (repeating, so
    its second differences keep their size): the growth, 1.2, is reported,
    not just 'at least 1'."""
    from tmtcontrol.stability.first_contact import periodic_decay

    assert periodic_decay(_PeriodicRunner(lambda k: 2.0, waves=1, amplitude=1e-12), 1e5, cycles=5) == 0.0
    grows = periodic_decay(_PeriodicRunner(lambda k: 1.2, waves=1, nyquist=0.05), 1e5, cycles=5)
    assert grows == pytest.approx(1.2, rel=1e-6)


class _FloorRunner(_PeriodicRunner):
    """A deviation that shrinks 1000-fold per period down to a floor of
    rounding amplified along the path: 2e-8 N (above 1e-9 f_d), a different
    shape each period, twice as large in the last period as in the one
    before (the ratio of two floors is noise about 1; here 2). Seeded."""

    def run(self, k_e, duration, stiffness=None):
        f = super().run(k_e, duration, stiffness)
        P = int(round(self.scenario.trajectory.period / 1e-3))
        rng = np.random.default_rng(7)
        for p in range(len(f) // P):
            f[p * P:(p + 1) * P] += 2e-8 * (2.0 if p == len(f) // P - 1 else 1.0) * rng.standard_normal(P)
        return f


def test_periodic_decay_counts_a_floor_a_millionfold_below_the_kick_as_rounding():
    """Regression (the UR5 on the pipe's helix, issue 40): near its limit the
    loop is locally unstable where the normal mass is largest, so each period
    amplifies the step's rounding there to a floor above 1e-9 f_d, while the
    kick's deviation has decayed a millionfold. The floor's period-to-period
    ratio is noise (2 here), not a mode: the orbit attracts, 0."""
    from tmtcontrol.stability.first_contact import ROUNDING, periodic_decay

    assert ROUNDING == 1e-6
    # the stand-in's deviation starts at t = 0: 1 N in the first period at k_e, as the kick leaves on the pipe
    assert periodic_decay(_FloorRunner(lambda k: 1e-3, amplitude=1e3), 1e5, cycles=5) == 0.0
    # a deviation that grows from the same floor is no rounding: reported
    assert periodic_decay(_FloorRunner(lambda k: 1.5), 1e5, cycles=5) == pytest.approx(1.5, rel=1e-3)


def test_periodic_decay_sees_a_saturated_oscillation_and_a_lost_contact():
    """An oscillation at half the sampling rate that repeats every period
    cancels in the difference between periods (ratio (a) = 0) but not in the
    second differences: at least 1 (not decaying); a force that leaves the
    surface in the last period: inf."""
    from tmtcontrol.stability.first_contact import periodic_decay

    assert periodic_decay(_PeriodicRunner(lambda k: 0.5, nyquist=0.05), 1e5, cycles=5) >= 1.0
    assert periodic_decay(_PeriodicRunner(lambda k: 0.5, nyquist=1e-7), 1e5, cycles=5) < 1.0   # below 1e-3 f_d
    assert periodic_decay(_PeriodicRunner(lambda k: 0.5, drop=True), 1e5, cycles=5) == np.inf


def test_simulated_limit_bisects_to_where_the_decay_reaches_one():
    """The deviation's ratio per period is k_e / 1.23e5: a slow deviation
    (one wave per period, second differences below 1e-3 f_d) converges below
    1.23e5 N/m, and simulated_limit finds it to its rtol; a fast one (37
    waves) is taken as saturated once its in-period swing keeps SATURATED =
    0.98 of itself per period, so its limit is 0.98 x 1.23e5 (the rule's
    conservative side). A bracket whose low end does not converge or whose
    high end does is refused."""
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.first_contact import SATURATED, simulated_limit

    runner = _PeriodicRunner(lambda k: k / 1.23e5, waves=1)
    limit = simulated_limit(runner.scenario, 5e4, 3e5, rtol=1e-4, cycles=3, runner=runner)
    assert limit == pytest.approx(1.23e5, rel=1e-4)
    fast = _PeriodicRunner(lambda k: k / 1.23e5)
    assert simulated_limit(fast.scenario, 5e4, 3e5, rtol=1e-4, cycles=3, runner=fast) == \
        pytest.approx(SATURATED * 1.23e5, rel=1e-4)
    with pytest.raises(AnalysisError, match="k_lo"):
        simulated_limit(runner.scenario, 1.3e5, 3e5, runner=runner)
    with pytest.raises(AnalysisError, match="k_hi"):
        simulated_limit(runner.scenario, 5e4, 1.2e5, runner=runner)


class _ThresholdRunner:
    """The start settles below ``k_star`` (a swing that dies out at once) and
    locks into a sustained 20 N swing above it."""

    def __init__(self, k_star):
        self.scenario, self.k_star, self.asked = paper_scenario(), k_star, []

    def run(self, k_e, duration):
        self.asked.append(k_e)
        t = np.arange(int(round(duration / 1e-3))) * 1e-3
        swing = 0.0 if k_e < self.k_star else 10.0
        return 10.0 + swing * np.sin(2 * np.pi * 7 * t)


def test_the_first_contact_limit_does_not_depend_on_how_high_the_search_starts():
    """Issue 43: ``simulate`` searched up to the 1-D limit and ``analyze`` up
    to the periodic one, and quoted different first-contact limits for the
    same scenario (100,158 and 100,111 N/m on the UR5 at -10 mm). Bracketed
    on a fixed grid (powers of 1.25) before the bisection, the answer is the
    same float for any ``k_hi`` above the grid cell that holds it, and
    within rtol of the true boundary (1.003e5 N/m here, by construction)."""
    from tmtcontrol.stability.first_contact import GRID, first_contact_limit

    k_star = 1.003e5
    answers = {k_hi: first_contact_limit(None, k_hi, rtol=1e-4, runner=_ThresholdRunner(k_star))
               for k_hi in (1.19753e5, 1.21909e5, 1.4e5, 3e5)}
    assert len(set(answers.values())) == 1, answers
    limit = answers[1.4e5]
    assert k_star / (1 + 1e-4) <= limit < k_star
    assert GRID ** 51 < k_star < GRID ** 52                       # the bracket: two neighbours of the grid
    # above the small-signal limit the start settles: k_hi itself; below the floor (k_hi/64): 0
    assert first_contact_limit(None, 9e4, runner=_ThresholdRunner(k_star)) == 9e4
    assert first_contact_limit(None, 1.2e5, runner=_ThresholdRunner(1.0)) == 0.0


@pytest.mark.heavy          # 2.6-11 s on the 2026-12-07 machine (the README's command stays under 3 min)
def test_the_orbit_is_shot_to_the_tolerance_not_stopped_after_three_steps():
    """The CHEAP loop at 4.5e4 N/m (just past its limit) from the frozen
    start needs four Newton steps: after three the residual is still about
    1e-9, above the shooting tolerance (1e-10). The orbit returned is
    converged to that tolerance; the stall rule (stop when a step no longer
    halves the residual) is for rounding, not for slow starts."""
    from tmtcontrol.stability.periodic import PeriodicModel

    sc = apply_overrides(paper_scenario(), CHEAP)
    model = PeriodicModel(sc, compile=False)
    three = model.at(4.5e4, iters=3)
    assert three.residual > 1e-10                          # the case needs a fourth step
    # out of steps, the start, residual and monodromy returned are one iterate's (the start was
    # one Newton step past the residual and monodromy reported): one period from it, run again
    end, Phi, _, _ = model._period(three.s_orbit, model._inputs(4.5e4))
    d = model.dynamic
    again = float(np.max(np.abs(end - three.s_orbit)[d] / (1.0 + np.abs(three.s_orbit[d]))))
    assert again == pytest.approx(three.residual, rel=1e-6) and np.array_equal(Phi, three.monodromy)
    orbit = PeriodicModel(sc, compile=False).at(4.5e4)
    assert orbit.residual < 1e-10 and orbit.newton_iterations >= 4


class _AmplitudeRunner:
    """The smooth orbit plus a slow deviation of amplitude ``amps[j]`` in path
    period j + 1 (the first period, at 0.95 k_e, has none)."""

    def __init__(self, amps):
        self.scenario = apply_overrides(paper_scenario(), ["trajectory.period=0.5"])
        self.amps = amps

    def run(self, k_e, duration, stiffness=None):
        N = 500
        k = np.arange(int(round(duration / 1e-3)))
        a = np.r_[0.0, self.amps][np.minimum(k // N, len(self.amps))]
        return 10.0 + 0.5 * np.sin(2 * np.pi * k / N) + a * np.sin(2 * np.pi * k / N + 1.0)


def test_a_deviation_that_died_out_below_the_floor_is_no_growth():
    """The deviation falls from 2e-3 N to the rounding level (1e-10 N,
    below 1e-9 f_d) and its last two periods differ by a factor 5 at that
    level: what is left is rounding, the ratio is 0 (converged), not 5."""
    from tmtcontrol.stability.first_contact import periodic_decay

    runner = _AmplitudeRunner([1e-3, 3e-3, 1e-10, 2e-10, 7e-10])
    assert periodic_decay(runner, 1e5, cycles=4) == 0.0


@pytest.mark.parametrize("k_hi", [0.0, -1.0, float("inf"), float("nan")])
def test_first_contact_limit_refuses_a_search_top_that_is_not_a_stiffness(k_hi):
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.first_contact import first_contact_limit

    with pytest.raises(AnalysisError, match="k_hi: must be a finite stiffness > 0"):
        first_contact_limit(None, k_hi, runner=_ThresholdRunner(1e5))


def _stubbed(monkeypatch, deciding, one_d=150001.0):
    """stability.limit with its two computations replaced: ``deciding`` (a
    ScenarioLimit, or an exception to raise) and the 1-D figure; returns the
    list of scenarios the deciding limit was computed for."""
    from tmtcontrol.stability import limit

    calls = []

    def _deciding(sc, *a):
        calls.append(sc.name)
        if isinstance(deciding, Exception):
            raise deciding
        return deciding

    monkeypatch.setattr(limit, "_deciding_limit", _deciding)
    monkeypatch.setattr(limit, "_one_d", lambda sc: one_d)
    return calls


_STUB_ARGS = dict(small_signal=150001.0, whole_loop=140000.0, whole_loop_bracket=(140000.0, 140000.14),
                  whole_loop_points=((0.0, 140000.0),), periodic=145000.0, first_contact=123457.0)
_RAMP_130K = ["environment.stiffness={kind='piecewise_linear', times=[0.0, 2.0], values=[1e4, 1.3e5]}",
              "trajectory.cycles=0.5"]


@pytest.mark.parametrize("x_e_error, code", [(-0.01, 1), (0.0, 0), (1e-5, 0)])
def test_a_ramp_below_the_1d_figure_is_judged_by_the_deciding_limit_when_the_surface_is_in_error(
        monkeypatch, tmp_path, capsys, x_e_error, code):
    """Review of issue 43: with a surface-location error the start is bistable
    and the deciding (first-contact) limit lies below the 1-D figure (the
    paper at -10 mm: 119,656 against 143,816 N/m). A run that ramps to
    1.3e5 N/m, between the two, was called converged (exit 0) because the
    deciding limit was computed only above the 1-D figure, while analyze
    called 1.3e5 unstable. With the stub's figures (deciding 123,457, 1-D
    150,001 N/m) the ramp is beyond_limit with the error; without it, or
    with a positive error (the surface believed deeper: not bistable, the
    paper at +10 mm keeps the periodic orbit's limit above the 1-D figure;
    10 um here, whose force bias stays within the tolerance), no segment reaches the 1-D figure and the deciding limit is not
    computed."""
    from tmtcontrol.cli import main
    from tmtcontrol.stability import limit

    calls = _stubbed(monkeypatch, limit.ScenarioLimit(123457.0, "first contact", **_STUB_ARGS))
    argv = ["simulate", "paper", "--out", str(tmp_path / "out"), "--no-plots",
            "--set", f"controller.x_e_error={x_e_error}", *[a for s in _RAMP_130K for a in ("--set", s)]]
    assert main(argv) == code
    err = capsys.readouterr().err
    if code:
        assert err.startswith("beyond_limit: segment 1") and "predicted limit 123,457 N/m (first contact)" in err
        assert len(calls) == 1
    else:
        assert err == "" and calls == []


def test_the_sweep_falls_back_to_the_1d_figure_as_simulate_does_when_the_loops_limit_fails(monkeypatch, tmp_path,
                                                                                            capsys):
    """A deciding limit that raises AnalysisError: simulate judges against the
    1-D figure and says the loop's own limit failed; the sweep's row did not
    attach any limit (its case converged where simulate's was beyond_limit).
    Both now give the same verdict and source."""
    from tmtcontrol.cli import main
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.sweep import run
    from tmtcontrol.sweep.spec import sweep_from_dict

    monkeypatch.setattr(run, "_LIMITS", {})
    calls = _stubbed(monkeypatch, AnalysisError("the search found no bracket"), one_d=1.0e5)
    sets = ["environment.stiffness.values=[1.3e5]", "trajectory.cycles=0.5"]
    assert main(["simulate", "paper", "--out", str(tmp_path / "out"), "--no-plots",
                 *[a for s in sets for a in ("--set", s)]]) == 1
    err = capsys.readouterr().err
    assert "predicted limit 100,000 N/m (1-D small-signal; the loop's own limit failed: the search found no " \
           "bracket)" in err, err
    spec = sweep_from_dict({"grid": {"environment.stiffness.values": [[1.3e5]], "trajectory.cycles": [0.5]}})
    row = run.case_row(spec.base, spec.cases[0])
    assert row["limits_error"] == "the search found no bracket"
    assert row["verdict"] == "beyond_limit" and row["seg1_verdict"] == "beyond_limit"
    assert len(calls) == 2


def test_a_loop_unstable_at_its_smallest_stiffness_has_limit_zero_everywhere(monkeypatch, paper_sim):
    """The deciding limit 0 ("unstable at the smallest stiffness", e.g. a stiff
    contact damper) used to leave the run's verdicts alone, or attach the
    positive 1-D figure: every segment is now beyond it, from either source."""
    from tmtcontrol.simulation.metrics import segment_metrics
    from tmtcontrol.stability import limit

    res = paper_sim.run(paper_scenario().replace(trajectory=paper_scenario().trajectory.model_copy(
        update={"cycles": 0.5})))
    assert {s.verdict for s in segment_metrics(res)} == {"converged"}
    zero = limit.ScenarioLimit(0.0, "unstable at the smallest stiffness", **{**_STUB_ARGS, "small_signal": 0.0})
    for attached in (limit.with_stiffness_limit(res, zero),
                     (_stubbed(monkeypatch, zero, one_d=0.0), limit.with_stiffness_limit(res))[1]):
        assert attached.info["stiffness_limit"] == 0.0
        assert {s.verdict for s in segment_metrics(attached)} == {"beyond_limit"}


@pytest.mark.parametrize("stiffness, attached", [(1.3e5, True), (5e4, False)])
def test_the_mid_period_hold_is_judged_by_its_own_loops_limit_above_the_gate(monkeypatch, stiffness, attached):
    """The mid-period hold has no 1-D figure (its lead raises the limit): the
    zero-order hold's 1-D figure (stub: 1e5 N/m) is only the gate. Above it the
    deciding limit is computed and attached (it was computed for the message
    but never used for the verdicts); below it nothing is attached."""
    from tmtcontrol import Simulator
    from tmtcontrol.simulation.metrics import segment_metrics
    from tmtcontrol.stability import limit

    stub = limit.ScenarioLimit(1.2e5, "periodic orbit", **{**_STUB_ARGS, "small_signal": None})
    calls = _stubbed(monkeypatch, stub, one_d=1.0e5)
    sc = apply_overrides(paper_scenario(), ["controller.hold=mid_period", f"environment.stiffness.values=[{stiffness}]",
                                            "trajectory.cycles=0.5"])
    res = limit.with_stiffness_limit(Simulator(sc).run())
    assert ("stiffness_limit" in (res.info or {})) == attached and len(calls) == int(attached)
    if attached:
        assert res.info["stiffness_limit"] == 1.2e5
        assert segment_metrics(res)[0].verdict == "beyond_limit"

