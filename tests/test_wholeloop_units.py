"""The frozen-point (whole-loop) analysis' parts one at a time (stability.wholeloop): its Newton
iterations, the state names of its Jacobian, the seed of its inverse kinematics, the 1-D guess and the
bracketing guess of its limit. Review 42 (mutation testing with benchmarks/mutation_tool.py, seed 5): six
of eight sampled mutants of the module survived its test files, the relaxed fallback and the bisection
hiding each; each test here fails with its mutant applied (named in the test)."""
import math

import numpy as np
import pytest

from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
from tmtcontrol.stability import wholeloop as wl

# a short path (1 s circle) at 250 Hz, as tests/test_limits.py's cheap model
CHEAP = ["controller.rate=250", "trajectory.period=1.0"]
K_E = 2e4


@pytest.fixture(scope="module")
def model():
    return wl.WholeLoopModel(apply_overrides(paper_scenario(), CHEAP))


def _perturbed(model, seed):
    """The equilibrium's state at K_E with its dynamic states moved by 1e-6 relative, and the inputs."""
    w = model.at(K_E, 0.0)
    u = np.r_[model._u(0, K_E), model.P]
    d = model.dynamic
    s = w.s_eq.copy()
    rng = np.random.default_rng(seed)
    s[d] = s[d] * (1 + 1e-6 * rng.standard_normal(d.size)) + 1e-9 * rng.standard_normal(d.size)
    return w, s, u


def test_newton_returns_to_the_equilibrium_from_a_nearby_start(model):
    """Mutant: the stopping test max(|r| / (1 + |s|)) < tol as max(|r| - (1 + |s|)) < tol, true at once (Newton
    never stepped; the relaxed fallback still found stable equilibria). From the paper's equilibrium perturbed
    by 1e-6 (its residual above 1e-9), Newton's residual falls below 1e-10 and the state returns to 1e-9
    relative."""
    w, s, u = _perturbed(model, 0)
    assert float(np.max(np.abs(model._residual(s, u)))) > 1e-9
    out, res = model._newton(s, u)
    d = model.dynamic
    assert res < 1e-10
    assert np.max(np.abs(out[d] - w.s_eq[d]) / (1 + np.abs(w.s_eq[d]))) < 1e-9


def test_the_damped_newton_halves_a_step_that_does_not_lower_the_residual(model, monkeypatch):
    """Mutant: the halving step / 2 as step & 2 (a TypeError no test reached). The first full step's trial is
    made to look 1e6 times worse, so the step is halved once; the damped Newton still converges (1e-10)."""
    _, s, u = _perturbed(model, 1)
    real, calls = model._residual, []

    def residual(x, uu):
        calls.append(1)
        r = real(x, uu)
        return r * 1e6 if len(calls) == 2 else r      # call 1: the start's; call 2: the first full step's trial

    monkeypatch.setattr(model, "_residual", residual)
    _, res = model._newton(s, u, damped=True)
    assert len(calls) > 3 and res < 1e-10


def test_the_jacobians_states_are_named_one_each_the_laws_last(model):
    """Mutant: the names built over range(stop | start) for range(stop - start) (82 names for 10 states)."""
    w = model.at(K_E, 0.0)
    d = wl.dynamic_states(model.layout)
    assert w.A.shape == (d.size, d.size) and len(w.states) == d.size == len(set(w.states))
    assert w.states[:2] == ("q[0]", "q[1]")
    if model.law.states:
        assert w.states[-len(model.law.states):] == tuple(model.law.states)


@pytest.mark.parametrize("path_time", [0.25, 0.5, 0.75])
def test_the_inverse_kinematics_starts_from_the_paths_pose_at_that_time(model, monkeypatch, path_time):
    """Mutant: the seed's column round(t % period - period N) for round(t % period / period N) (a pose from
    elsewhere on the circle; the solver usually converged anyway). The seed's tool point is within a quarter of
    the path's span of the target (measured: within 1.3 mm; the mutant's 0.14-0.20 m)."""
    loop, calls = model.loop, []
    real = loop.joints_at
    monkeypatch.setattr(loop, "joints_at", lambda point, seed=None, scenario=None: calls.append(
        (np.array(point, float), np.array(seed, float))) or real(point, seed, scenario))
    model.at(K_E, path_time)
    target, seed = calls[0]
    pts = np.array([loop.tool_position(q) for q in model.path.q.T])
    span = max(np.linalg.norm(a - b) for a in pts[::5] for b in pts[::5])
    assert span > 0.01 and np.linalg.norm(loop.tool_position(seed) - target) < 0.25 * span


def test_the_one_d_guess_uses_the_schedules_damping_over_the_mass(monkeypatch):
    """Mutant: kd = b // m for b / m under a zeta damping schedule (283 for 283.55 at 2e4 N/m: Newton reaches the
    same point from either guess, so only the guess shows it). 1e-12: the same float expression."""
    sc = apply_overrides(paper_scenario(), [*CHEAP, "controller.damping_schedule.kind=zeta"])
    seen, real = [], wl.law_loop
    monkeypatch.setattr(wl, "law_loop", lambda *a, **kw: seen.append(kw) or real(*a, **kw))
    mdl = wl.WholeLoopModel(sc)
    mdl.at(K_E, 0.0)
    b, m = wl.equilibrium_damping(mdl.scenario, K_E), float(mdl.scenario.impedance.m[0])
    assert seen[0]["b"] == pytest.approx(b, rel=1e-12) and seen[0]["kd"] == pytest.approx(b / m, rel=1e-12)


def test_a_guess_that_brackets_the_limit_is_used(model, monkeypatch):
    """Mutant: the bracket's test not stable(guess * 1.25) as not stable(guess / 1.25) (never true: every point
    searched the 19-point grid; the same limit, more work). With the guess at the limit itself one path point
    costs at most the bracket's two ends and ceil(log2(ln 1.25^2 / ln(1 + rtol))) bisections (15 at 1e-4), and
    the limits agree to 2 rtol."""
    sc, rtol = model.scenario, 1e-4
    free, _ = wl.whole_loop_limit(sc, points=1, rtol=rtol, model=model)
    calls, real = [], model.at
    monkeypatch.setattr(model, "at", lambda k_e, path_time=0.0: calls.append(k_e) or real(k_e, path_time))
    guided, _ = wl.whole_loop_limit(sc, points=1, rtol=rtol, model=model, guess=free)
    assert len(calls) <= 2 + math.ceil(math.log2(math.log(1.25 ** 2) / math.log(1 + rtol)))
    assert abs(guided / free - 1) < 2 * rtol


def test_a_run_shorter_than_its_path_period_freezes_each_point_at_its_own_path_time(model):
    """Review 56: with trajectory.cycles = 0.5 the frozen points in the path's second half took the
    inputs of its first (their index wrapped modulo the run's samples, not the period's), so `analyze`
    printed 171,044 N/m at 3.0 s for 163,674 and a frozen minimum 1.2 % high. The model of a half
    run is the whole run's at every path time: its equilibrium and spectral radius equal to Newton's
    tolerance (1e-9; the shared fixture's Newton starts from the points it solved before)."""
    half = wl.WholeLoopModel(apply_overrides(paper_scenario(), [*CHEAP, "trajectory.cycles=0.5"]))
    for path_time in (0.0, 0.25, 0.6, 0.875):
        a, b = half.at(K_E, path_time), model.at(K_E, path_time)
        assert a.path_time == b.path_time == pytest.approx(path_time, abs=2.5e-3)     # the nearest 4 ms sample
        assert a.spectral_radius == pytest.approx(b.spectral_radius, rel=1e-9, abs=0)
        assert np.allclose(a.s_eq, b.s_eq, rtol=1e-9, atol=1e-12)
