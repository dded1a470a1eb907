"""The periodic analysis's tangent-linear step (``closedloop.build_tangent``),
built piece by piece (the controller's side and the plant's right-hand side,
each an SX Function with its own directional derivative, the Runge-Kutta
stages calling the plant's), against the forward derivative of the whole
fused step (``casadi.jtimes`` on :func:`build_step`'s one SX Function, the
construction it replaced): the same arithmetic, so equal to rounding (the
pieces evaluate the same operations; 1e-12 relative allows for CasADi
ordering a sum differently), and the Jacobian columns against central
differences of the simulated step."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from tmtcontrol.simulation.rollout import O1_FROM, operations, optimisation_level
from tmtcontrol.simulation.scenario import apply_overrides, load_scenario
from tmtcontrol.stability.periodic import PeriodicModel


def _fused_tangent(loop, dynamic):
    step = loop.build_step(contact_refine=1)
    s, u, p = step.sx_in()
    s_next, log = step(s, u, p)
    idx = dynamic.tolist()
    v = ca.SX.sym("v", len(idx))
    direction = ca.SX.zeros(s.numel())
    direction[idx] = v
    Av = ca.jtimes(s_next, s, direction)[idx]
    return ca.Function("fused", [ca.vertcat(s, v), u, p], [ca.vertcat(s_next, Av), log[loop.f_e]])


@pytest.mark.heavy
@pytest.mark.parametrize("name,overrides", [
    ("paper", []),
    ("paper", ["controller.delay_samples=1", "controller.hold=\"mid_period\"", "simulation.substeps=2"]),
    ("ur5-pipe", []),
])
def test_the_tangent_step_is_the_fused_steps_forward_derivative(name, overrides):
    sc = apply_overrides(load_scenario(name), overrides)
    mdl = PeriodicModel(sc, compile=False)
    loop, dyn = mdl.frozen.loop, mdl.dynamic
    pieces, fused = loop.build_tangent(dyn), _fused_tangent(loop, dyn)
    s = mdl._start(5000.0)
    U = mdl._inputs(5000.0)
    rng = np.random.default_rng(7)
    for j in (0, dyn.size // 2, dyn.size - 1):
        x = np.r_[s + 1e-4 * rng.standard_normal(s.size) * np.isin(np.arange(s.size), dyn),
                  np.eye(1, dyn.size, j).ravel()]
        for col in (0, U.shape[1] // 3):
            a = [np.asarray(o).ravel() for o in pieces(x, U[:, col], mdl.P)]
            b = [np.asarray(o).ravel() for o in fused(x, U[:, col], mdl.P)]
            for ai, bi in zip(a, b):
                np.testing.assert_allclose(ai, bi, rtol=1e-12, atol=1e-12 * np.max(np.abs(bi)))
    # a column of A against central differences of the simulated (refinement-free) step; h = 1e-6 of
    # a state of order 1: the difference's truncation ~h^2 and rounding ~1e-16/h, so 1e-6 relative
    step = loop.build_step(contact_refine=1)
    ns, j, h = s.size, int(dyn[1]), 1e-6
    e = np.zeros(ns)
    e[j] = h
    fd = (np.asarray(step(s + e, U[:, 0], mdl.P)[0]).ravel() - np.asarray(step(s - e, U[:, 0], mdl.P)[0]).ravel())
    Av = np.asarray(pieces(np.r_[s, np.eye(1, dyn.size, 1).ravel()], U[:, 0], mdl.P)[0]).ravel()[ns:]
    np.testing.assert_allclose(Av, (fd / (2 * h))[dyn], rtol=1e-6, atol=1e-6 * np.max(np.abs(Av)))


def test_the_generated_codes_operations_count_each_called_function_once():
    """rollout.operations counts the assignments of the generated C: a called
    Function's code once however often called, whether an MX call, a map or
    a conditional's branch calls it (review 36: the switch's branches, the
    contact refinement's plant step, were not counted), and two different
    Functions of the same name both."""
    x = ca.SX.sym("x", 2)
    big = ca.Function("big", [x], [ca.sin(ca.cos(x) * x) * ca.exp(x) + x ** 3])
    small = ca.Function("small", [x], [2 * x])
    y = ca.MX.sym("y", 2)
    n = operations(big)
    assert n >= 8 and operations(small) >= 2
    once = ca.Function("once", [y], [big(y)])
    thrice = ca.Function("thrice", [y], [big(big(y)) + big(y)])
    assert operations(once) == operations(thrice) == n
    assert operations(ca.Function("mapped", [y], [ca.sum2(big.map(4)(ca.repmat(y, 1, 4)))])) == n
    switch = ca.Function.conditional("switch", [small], big)
    c = ca.MX.sym("c")
    assert operations(ca.Function("chooses", [c, y], [switch(c, y)])) == n + operations(small)
    other = ca.Function("big", [x], [x * x])          # another Function with the same name
    assert operations(ca.Function("both", [y], [big(y) + other(y)])) == n + operations(other)


@pytest.mark.heavy
@pytest.mark.parametrize("name", ["paper", "panda"])
def test_the_tangent_step_is_compiled_at_the_level_of_its_pieces_size(name):
    """The Panda's pieces (27,372 operations in all) are compiled at -O1, the PUMA's (3,880)
    at -O3: the level rule (rollout.O1_FROM) sees the generated code's size, not the
    wrapping MX Function's few call instructions (which alone would pick -O3 everywhere)."""
    mdl = PeriodicModel(load_scenario(name), compile=False)
    fn = mdl.rollout.step
    assert fn.n_instructions() < 200
    expected = "-O1" if name == "panda" else "-O3"
    assert (operations(fn) >= O1_FROM) == (name == "panda")
    assert optimisation_level(operations(fn)) == expected


def test_one_compiled_period_is_the_rollouts_first_period_and_the_virtual_machines():
    """Rollout.once calls the library's single period: the same numbers as the
    first column of a run and as CasADi's virtual machine (bit for bit: the
    same operations, -ffp-contract=off), and wrong sizes are refused, not read
    past (as Rollout.run, review 30)."""
    from tmtcontrol.simulation.rollout import Rollout

    s, u, p = ca.SX.sym("s", 2), ca.SX.sym("u", 1), ca.SX.sym("p", 1)
    step = ca.Function("toy_once", [s, u, p], [ca.vertcat(s[0] * u + ca.sin(s[1]), s[1] * p), ca.vertcat(s, u)],
                       ["s", "u", "p"], ["s_next", "log"])
    r = Rollout(step, compile=True)
    assert r.how in ("compiled", "cached")
    s0, u0, p0 = np.array([0.3, -1.7]), np.array([1.25]), np.array([0.999])
    S, L = r.run(s0, u0[:, None], p0)
    a, b = r.once(s0, u0, p0)
    vm = [np.ravel(np.array(o)) for o in step(s0, u0, p0)]
    assert np.array_equal(a, S[:, 0]) and np.array_equal(b, L[:, 0])
    assert np.array_equal(a, vm[0]) and np.array_equal(b, vm[1])
    assert np.array_equal(a, [0.3 * 1.25 + np.sin(-1.7), -1.7 * 0.999])
    for bad in ((s0[:1], u0, p0), (s0, np.r_[u0, 1.0], p0), (s0, u0, np.r_[p0, 1.0])):
        with pytest.raises(ValueError, match="the step takes"):
            r.once(*bad)


@pytest.mark.parametrize("name,overrides", [
    # heavy (docs/testing.md's 2 s rule): 2.5 s on 2026-12-07's machine
    pytest.param("paper", ["controller.delay_samples=1"], marks=pytest.mark.heavy),
    # heavy: compiles the pipe's tangent step with the hold (4 s) and runs the virtual machine's Jacobians
    pytest.param("ur5-pipe", ["controller.hold=\"mid_period\""], marks=pytest.mark.heavy),
])
def test_the_frozen_loops_jacobian_from_the_compiled_tangent_step_is_casadis(name, overrides):
    """WholeLoopModel with a compiled tangent step (the deciding limit's: its
    Jacobians are the tangent's columns) against the same model on CasADi's
    Jacobian (the virtual machine, MX forward sweeps through the step with the
    contact refinement): at a fixed point in contact the same matrix to
    rounding (1e-10 of its largest entry: two AD paths, the fixed points
    found by Newton to 1e-11), the same spectral radius to 1e-9, and the
    same frozen-point limit (bisected to 1e-4, so equal decisions)."""
    from tmtcontrol.stability.wholeloop import WholeLoopModel, whole_loop_limit

    sc = apply_overrides(load_scenario(name), overrides)
    plain, fast = WholeLoopModel(sc), WholeLoopModel(sc)
    fast.tangent = PeriodicModel(sc, compile=True).rollout
    assert fast.tangent.how in ("compiled", "cached")
    k_e = 2e4 if name == "paper" else 2e5
    for t in (0.0, 0.7):
        a, b = plain.at(k_e, t), fast.at(k_e, t)
        np.testing.assert_allclose(b.A, a.A, rtol=0, atol=1e-10 * np.max(np.abs(a.A)))
        assert abs(b.spectral_radius - a.spectral_radius) < 1e-9
        assert b.f_eq == pytest.approx(a.f_eq, rel=1e-9)
    if name == "paper":
        assert whole_loop_limit(sc, points=2, model=WholeLoopModel(sc))[0] == \
            whole_loop_limit(sc, points=2, model=fast)[0]


def test_the_pandas_simulated_step_is_sized_with_its_contact_refinement():
    """Review 36: the simulated step's contact refinement (a conditional whose
    branch is the coarse plant step, in the generated C) counted 0, so the
    Panda's step (29,647 operations with it, 16,534 without) was compiled at
    -O3 in 9 s instead of -O1 in 3.5 s; the UR5's (18,606) stays at -O3."""
    from tmtcontrol.simulation.simulator import Simulator

    sizes = {name: operations(Simulator(load_scenario(name), compile=False).step) for name in ("ur5", "panda")}
    assert sizes["panda"] >= O1_FROM > sizes["ur5"]
    assert optimisation_level(sizes["panda"]) == "-O1" and optimisation_level(sizes["ur5"]) == "-O3"


def test_the_periodic_search_alone_starts_from_the_band_of_the_smallest_stiffness(monkeypatch):
    """Review 36: periodic_limit without a bracket searched the frozen loop's
    limit on a log grid from 10 N/m when the 1-D guess did not bracket it
    (ur5-pipe with a 2-sample delay), where the equilibrium, f_d/k_e = 1 m
    deep, is outside the workspace: AnalysisError. It now searches the band
    that holds the scenario's smallest stiffness, as the deciding limit does
    (after the fix that scenario's periodic limit is 35,368 N/m)."""
    from tmtcontrol.stability import periodic, wholeloop
    from tmtcontrol.stability.onedim import scenario_parameters

    seen = {}

    class Stop(Exception):
        pass

    def record(scenario, **kw):
        seen.update(kw)
        raise Stop

    monkeypatch.setattr(wholeloop, "whole_loop_limit", record)
    sc = load_scenario("paper")
    with pytest.raises(Stop):
        periodic.periodic_limit(sc, model=PeriodicModel(sc, compile=False))
    assert seen["within"] == scenario_parameters(sc)["k_e_min"] == 2000.0          # the paper's softest segment
