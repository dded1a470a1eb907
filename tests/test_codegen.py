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


def test_a_structurally_zero_output_entry_is_a_zero_in_the_compiled_rollout():
    """Regression (the mid-period hold's periodic analysis): a step whose
    output has a structurally zero entry (here s_next[1], like a monodromy
    row of a state that is a constant) compiled into the chunk's C wrote only
    the stored entries, so every column after the first was shifted: the
    states of the second chunk were garbage. The compiled run equals the
    closed form exactly, across a chunk boundary."""
    s, u, p = ca.SX.sym("s", 3), ca.SX.sym("u", 1), ca.SX.sym("p", 1)
    s_next = ca.vertcat(s[0] + u, ca.SX(1, 1), s[2] * p)
    assert not ca.Function("f", [s, u, p], [s_next]).sparsity_out(0).is_dense()
    step = ca.Function("toy_sparse", [s, u, p], [s_next, ca.vertcat(s, u)], ["s", "u", "p"], ["s_next", "log"])
    U, S_ref = reference(25)
    r = Rollout(step, chunk=10)
    assert r.how in ("compiled", "cached")
    S, _ = r.run([0.0, 5.0, 1.0], U, [P])
    np.testing.assert_array_equal(S, np.vstack([S_ref[0], np.zeros(25), S_ref[1]]))


def test_second_build_uses_the_cache():
    Rollout(toy_step())
    assert Rollout(toy_step()).how == "cached"


def test_no_compiler_falls_back_to_vm(monkeypatch, tmp_path):
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))       # nothing cached either
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


# -- a damaged or unwritable cache never crashes the process (issue #11) -------------------

def SMALL():
    """The paper scenario with one RK4 substep: a smaller step, so the compile tests compile faster."""
    from tmtcontrol import apply_overrides, paper_scenario

    return apply_overrides(paper_scenario(), ["simulation.substeps=1"])


def _cached_lib(folder):
    return next(p for p in folder.iterdir() if p.suffix == ".so")


def _simulate_in(tmp, cache, name):
    import os
    import subprocess
    import sys

    env = {**os.environ, "TMTCONTROL_CACHE": str(cache)}
    return subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "simulate", "--no-plots", "--out",
                           str(tmp / name), "--set", "trajectory.cycles=2.6",    # 10,400 steps: compiled
                           "--set", "simulation.substeps=1"],                     # a smaller step compiles faster
                          capture_output=True, text=True, env=env)


@pytest.fixture(scope="module")
def first_compile(tmp_path_factory):
    """One fresh process compiling into an empty cache; the damage tests copy it."""
    tmp = tmp_path_factory.mktemp("first")
    first = _simulate_in(tmp, tmp / "cache", "a")
    assert first.returncode == 0 and "(compiled)" in first.stdout, first.stderr
    return tmp


@pytest.mark.heavy
@pytest.mark.parametrize("damage", ["truncate_4096", "truncate_0", "flip_byte"])
def test_damaged_cached_library_is_rebuilt_not_loaded(tmp_path, damage, first_compile):
    # as in real life, the damage (a crash or a full disk during a write) is met by a new process
    import shutil

    shutil.copytree(first_compile / "cache", tmp_path / "cache")
    lib = _cached_lib(tmp_path / "cache")
    data = lib.read_bytes()
    lib.write_bytes({"truncate_4096": data[:4096], "truncate_0": b"",
                     "flip_byte": data[:100] + bytes([data[100] ^ 0xFF]) + data[101:]}[damage])
    second = _simulate_in(tmp_path, tmp_path / "cache", "b")
    assert second.returncode == 0, second.stderr           # no SIGBUS (exit 135), no traceback
    assert "is damaged; rebuilding it" in second.stderr and "(rebuilt)" in second.stdout
    assert (first_compile / "a" / "timeseries.csv").read_bytes() == (tmp_path / "b" / "timeseries.csv").read_bytes()
    third = _simulate_in(tmp_path, tmp_path / "cache", "c")
    assert third.returncode == 0 and "(cached)" in third.stdout and third.stderr == ""


# heavy (docs/testing.md's 2 s rule): 2.0-2.7 s in the README command's run of the nineteenth session
@pytest.mark.heavy
def test_unwritable_cache_compiles_privately_and_says_so(monkeypatch, tmp_path):
    from tmtcontrol import Simulator

    import tempfile

    blocker = tmp_path / "file"
    blocker.write_text("x")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(blocker / "cache"))      # below a regular file
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))           # its per-user fallback: fresh, here
    with pytest.warns(RuntimeWarning, match="cannot write the compile cache .* TMTCONTROL_CACHE"):
        sim = Simulator(SMALL(), compile=True)
    assert sim.rollout.how == "compiled" and not str(sim.rollout.library).startswith(str(blocker))


# heavy (docs/testing.md's 2 s rule): 2.0-2.7 s in the README command's run of the nineteenth session
@pytest.mark.heavy
def test_no_compiler_uses_a_valid_cached_library(monkeypatch, tmp_path):
    from tmtcontrol import Simulator

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    Simulator(SMALL(), compile=True)
    monkeypatch.setattr(codegen, "compiler", lambda: None)
    assert Simulator(SMALL()).rollout.how == "cached"


def test_a_cached_library_is_used_without_building_the_step():
    built = []

    def make():
        built.append(1)
        return toy_step()

    U, S_ref = reference(2500)
    first = Rollout(make, structure=("toy", "toy-structure-v1"))
    assert first.how in ("compiled", "cached")
    second = Rollout(make, structure=("toy", "toy-structure-v1"))
    n_built = len(built)
    S, L = second.run([0.0, 1.0], U, [P])
    assert second.how == "cached" and len(built) == n_built        # nothing built for the cached run
    assert (second.ns, second.nu, second.np, second.nl) == (2, 1, 1, 3)   # read from the library
    np.testing.assert_array_equal(S, S_ref)
    # another structure key is another library
    assert Rollout(make, structure=("toy", "toy-structure-v2"), compile="auto").how == "vm"
    with pytest.raises(ValueError, match="structure: required"):
        Rollout(make)


def test_simulator_structure_key_covers_every_structural_setting():
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.control.laws import get_law
    from tmtcontrol.simulation.simulator import structure_key

    sc = paper_scenario()
    tmt = get_law("tmt")
    base = structure_key(sc, tmt)
    changed = ["robot.armature=false", "robot.friction=true", "robot.model_mass_scale=1.1",
               "robot.compensate_friction=true", "simulation.substeps=2", "simulation.contact_refine=2",
               "controller.delay_samples=1", "simulation.integrator=\"cvodes\""]
    keys = {structure_key(apply_overrides(sc, [c]), tmt) for c in changed}
    assert base not in keys and len(keys) == len(changed)
    # numbers are inputs, not structure
    assert structure_key(apply_overrides(sc, ["controller.f_d=5", "impedance.b=[80, 60, 60]"]), tmt) == base
    # a law declared outside the package is keyed by the step's serialisation instead
    import dataclasses
    outside = dataclasses.replace(tmt, update=lambda y, p, s: tmt.update(y, p, s))
    assert structure_key(sc, outside) is None


@pytest.mark.parametrize("operations,level", [(4_655, "-O3"), (14_718, "-O3"), (18_606, "-O3"), (19_999, "-O3"),
                                              (20_000, "-O1"), (27_372, "-O1"), (29_647, "-O1"), (359_633, "-O1")])
def test_the_optimisation_level_follows_the_measured_sizes(operations, level):
    """rollout.O1_FROM (benchmarks/bench_compile_flags.py, docs/speed.md): the simulated
    steps of the PUMA (4,655 operations of generated C) and the UR5 (18,606) and the UR5's
    tangent step (14,718) keep -O3; the Panda's step (29,647) and tangent step (27,372) are
    compiled at -O1, in a third to half the time of -O3."""
    assert codegen.optimisation_level(operations) == level


def test_a_step_compiled_at_o1_computes_what_o3_and_the_vm_compute(monkeypatch, tmp_path):
    """The level reaches the compiler, and does not change a result: -ffp-contract=off and
    no fast-math flag, so -O1 gives the closed form (the same operations in the same
    order) bit for bit, as -O3 does (test_compiled_rollout_matches_closed_form)."""
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "O1_FROM", 1)               # the toy step's 3 operations: -O1
    seen = []
    real = codegen.run_compiler
    monkeypatch.setattr(codegen, "run_compiler", lambda args, *a, **k: seen.append(args) or real(args, *a, **k))
    U, S_ref = reference(2500)
    r = Rollout(toy_step(), chunk=1000)
    assert r.how == "compiled" and len(seen) == 1
    assert "-O1" in seen[0] and "-O3" not in seen[0]
    np.testing.assert_array_equal(r.run([0.0, 1.0], U, [P])[0], S_ref)


def test_compile_together_runs_the_pending_compilers_side_by_side(monkeypatch, tmp_path):
    """rollout.compile_together (issue 42: the law comparison's five loops, the periodic analysis's
    tangent step beside the scenario's step): the compilers of two pending rollouts run at the same
    time (each waits at a barrier for the other; one after the other, the first would wait out the
    barrier's timeout, its compile fail with a warning and its rollout stay on the virtual machine),
    each builds its own library, and each run equals the closed form bit for bit, as a rollout
    compiled alone does (test_compiled_rollout_matches_closed_form)."""
    import threading

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    both = threading.Barrier(2, timeout=30)
    real = codegen.run_compiler

    def compiler_run(args, *a, **k):
        both.wait()
        return real(args, *a, **k)

    monkeypatch.setattr(codegen, "run_compiler", compiler_run)
    a, b = Rollout(toy_step(), compile="auto", chunk=1000), Rollout(toy_step(), compile="auto", chunk=400)
    assert a.how == b.how == "vm"                                    # nothing cached: pending
    codegen.compile_together([a, b], codegen.COMPILE_AFTER + 1, threads=2)
    assert a.how == b.how == "compiled" and a.library != b.library
    U, S_ref = reference(2500)
    for r in (a, b):
        np.testing.assert_array_equal(r.run([0.0, 1.0], U, [P])[0], S_ref)


def test_compile_together_leaves_alone_what_a_run_would_not_compile(monkeypatch, tmp_path):
    """A run of fewer periods than COMPILE_AFTER stays on the virtual machine (compile="auto"),
    and so does every rollout given to compile_together for such a run, or with one thread (each
    then compiles when its own run needs it)."""
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    monkeypatch.setattr(codegen, "run_compiler", lambda *a, **k: pytest.fail("nothing to compile"))
    rollouts = [Rollout(toy_step(), compile="auto", chunk=c) for c in (1000, 400)]
    codegen.compile_together(rollouts, codegen.COMPILE_AFTER - 1, threads=2)
    codegen.compile_together(rollouts, codegen.COMPILE_AFTER + 1, threads=1)
    assert [r.how for r in rollouts] == ["vm", "vm"]


def test_compile_together_compiles_a_rollout_listed_twice_once_and_warns_here(monkeypatch, tmp_path):
    """Review 30: a rollout listed twice was compiled by one thread and then found "cached" by the
    other (its ``how`` said cached for a library built just now); and a failed compile warned from
    the worker thread (the warning's file: concurrent/futures/thread.py). Now each rollout once,
    ``how`` "compiled"; a failure is a RuntimeWarning at the caller's line, in the rollouts' order,
    and that rollout runs on the virtual machine with the right result."""
    import subprocess
    import warnings

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    calls = []
    real = codegen.run_compiler
    monkeypatch.setattr(codegen, "run_compiler", lambda args, *a, **k: calls.append(args) or real(args, *a, **k))
    a, b = Rollout(toy_step(), compile="auto", chunk=1000), Rollout(toy_step(), compile="auto", chunk=400)
    codegen.compile_together([a, a, b], codegen.COMPILE_AFTER + 1, threads=2)
    assert (a.how, b.how, len(calls)) == ("compiled", "compiled", 2)

    def failing(args, *a, **k):
        raise subprocess.CalledProcessError(1, args, b"", b"boom")

    monkeypatch.setattr(codegen, "run_compiler", failing)
    c, d = Rollout(toy_step(), compile="auto", chunk=300), Rollout(toy_step(), compile="auto", chunk=200)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        codegen.compile_together([c, d], codegen.COMPILE_AFTER + 1, threads=2)
    assert [w.category for w in seen] == [RuntimeWarning, RuntimeWarning]
    assert all(w.filename == __file__ for w in seen), [w.filename for w in seen]
    assert ["toy_chunk" in str(w.message) and "virtual machine" in str(w.message) for w in seen] == [True, True]
    U, S_ref = reference(50)
    for r in (c, d):
        assert r.how == "vm"
        np.testing.assert_array_equal(r.run([0.0, 1.0], U, [P])[0], S_ref)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_run_with_inputs_of_the_wrong_size_is_refused_naming_them(compiled):
    """Review 30: the compiled chunk reads exactly ns states, nu inputs and np parameters a period;
    a p of one number where the step takes two was read past its end (uninitialised memory in
    the log), three shifted from period to period, a longer s0 was cut silently, where the virtual
    machine broadcast or raised. Both paths now refuse, naming the argument; 0 periods too."""
    s, u, p = ca.SX.sym("s", 1), ca.SX.sym("u", 1), ca.SX.sym("p", 2)
    step = ca.Function("toy_p2", [s, u, p], [s + u * p[0], p], ["s", "u", "p"], ["s_next", "log"])
    r = Rollout(step, compile=compiled, chunk=4)
    assert r.how == ("vm" if not compiled else r.how)
    U = np.zeros((1, 6))
    for s0, UU, pp, name in (([0.0], U, [5.0], "p"), ([0.0], U, [5.0, 6.0, 7.0], "p"),
                             ([0.0, 1.0], U, [5.0, 6.0], "s0"), ([0.0], np.zeros((2, 3)), [5.0, 6.0], "U"),
                             ([0.0], np.zeros((1, 0)), [5.0, 6.0], "U")):
        with pytest.raises(ValueError, match=f"^{name}: "):
            r.run(s0, UU, pp)
    S, L = r.run([1.0], np.ones(6), [2.0, 3.0])          # one input row may come as a 1-D array
    np.testing.assert_array_equal(S, [[3.0, 5.0, 7.0, 9.0, 11.0, 13.0]])
    np.testing.assert_array_equal(L, [[2.0] * 6, [3.0] * 6])


def test_the_compile_lock_excludes_another_holder_until_released(monkeypatch, tmp_path):
    """cache.compile_lock: while a block holds it, another open file of the same
    lock cannot take it (flock conflicts between open files, as between
    processes); released at the block's end; a holder that never lets go is
    waited for only ``wait`` seconds, then the block runs anyway."""
    import fcntl
    import os

    from tmtcontrol.cache import compile_lock

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    name = "toy_chunk_" + "0" * 20 + ".so"
    with compile_lock(name):
        fd = os.open(tmp_path / "locks" / f"{name}.lock", os.O_RDWR)
        with pytest.raises(BlockingIOError):
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)            # free once the block ended
    os.close(fd)
    assert not (tmp_path / "locks").exists()                 # and its file removed: nothing left behind
    (tmp_path / "locks").mkdir()
    fd = os.open(tmp_path / "locks" / f"{name}.lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)                           # a holder that never lets go
    ran = []
    with compile_lock(name, wait=0.2):
        ran.append(True)
    assert ran == [True]
    os.close(fd)


def test_a_library_stored_while_waiting_for_the_lock_is_loaded_not_compiled_again(monkeypatch, tmp_path):
    """Two processes needing the same step at once (a report's two processes, a
    sweep's workers): the second waits at the compile lock, then looks in the
    cache again and loads what the first stored. Here the "first process" is a
    Rollout of the same structure that compiles while the second holds its
    place at the lock: the compiler runs once, and the second's library is the
    first's."""
    from tmtcontrol import cache

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    runs = []
    real_compiler, real_lock = codegen.run_compiler, cache.compile_lock
    monkeypatch.setattr(codegen, "run_compiler", lambda *a, **k: runs.append(1) or real_compiler(*a, **k))
    structure = ("toy_locked", "toy step, lock test")
    first = []

    import contextlib

    @contextlib.contextmanager
    def lock_taken_after_another_build(name, wait=None):
        if not first:                          # the other process builds while this one waits
            monkeypatch.setattr(cache, "compile_lock", real_lock)
            first.append(Rollout(toy_step(), structure=structure))
        with real_lock(name, wait):
            yield

    monkeypatch.setattr(cache, "compile_lock", lock_taken_after_another_build)
    second = Rollout(toy_step(), structure=structure)
    assert first[0].how == "compiled" and second.how == "cached" and runs == [1]
    assert second.library == first[0].library
    U, S_ref = reference(30)
    np.testing.assert_array_equal(second.run([0.0, 1.0], U, [P])[0], S_ref)


def test_compile_together_follows_the_runs_own_threshold_counting_the_steps_run(monkeypatch, tmp_path):
    """Review 35's survivors: a run of exactly COMPILE_AFTER periods stays on the virtual machine
    (run's own rule: compile once more than COMPILE_AFTER have run), so compile_together for such a
    run compiles nothing; and the periods a rollout has already run count: after 9,990 on the
    virtual machine, 20 more cross the threshold, and both rollouts are compiled ahead."""
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    a, b = Rollout(toy_step(), compile="auto", chunk=1000), Rollout(toy_step(), compile="auto", chunk=400)
    codegen.compile_together([a, b], codegen.COMPILE_AFTER, threads=2)
    assert (a.how, b.how) == ("vm", "vm")
    U, S_ref = reference(codegen.COMPILE_AFTER - 10)
    for r in (a, b):
        np.testing.assert_array_equal(r.run([0.0, 1.0], U, [P])[0], S_ref)     # 9,990 periods: still the VM
        assert r.how == "vm"
    codegen.compile_together([a, b], 20, threads=2)
    assert (a.how, b.how) == ("compiled", "compiled")
