"""Compiled rollouts: the cache, and the clean fallback to CasADi's VM."""
import casadi as ca
import numpy as np
import pytest

from tmtcontrol.simulation import rollout as codegen
from tmtcontrol.simulation.rollout import Rollout


def toy_step():
    s, u, p = ca.SX.sym("s", 2), ca.SX.sym("u", 1), ca.SX.sym("p", 1)
    return ca.Function("toy", [s, u, p], [ca.vertcat(s[0] + u, s[1] * p), ca.vertcat(s, u)],
                       ["s", "u", "p"], ["s_next", "log"])


P = 1.0005


def reference(n):
    # s0_k = running sum of the inputs, s1_k = P^k (the same multiplications
    # in the same order as the step, so equality is exact)
    U = np.arange(n, dtype=float)[None, :]
    return U, np.vstack([np.cumsum(U), np.cumprod(np.full(n, P))])


@pytest.mark.parametrize("n", [1, 7, 2500])     # shorter, longer than and not a multiple of a chunk
def test_compiled_rollout_matches_closed_form(n):
    U, S_ref = reference(n)
    r = Rollout(toy_step(), chunk=1000)
    assert r.how in ("compiled", "cached")
    S, L = r.run([0.0, 1.0], U, [P])
    np.testing.assert_array_equal(S, S_ref)
    np.testing.assert_array_equal(L[2], U[0])


def test_second_build_uses_the_cache():
    Rollout(toy_step())
    assert Rollout(toy_step()).how == "cached"


def test_no_compiler_falls_back_to_vm(monkeypatch):
    monkeypatch.setattr(codegen, "compiler", lambda: None)
    U, S_ref = reference(50)
    r = Rollout(toy_step())
    assert r.how == "vm"
    np.testing.assert_array_equal(r.run([0.0, 1.0], U, [P])[0], S_ref)


def test_failing_compiler_warns_and_falls_back(monkeypatch, tmp_path):
    monkeypatch.setattr(codegen, "compiler", lambda: "/bin/false")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    with pytest.warns(RuntimeWarning, match="virtual machine"):
        r = Rollout(toy_step())
    assert r.how == "vm"
    assert not list(tmp_path.glob("*.so"))          # nothing half-written in the cache
