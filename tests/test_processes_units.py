"""Small pieces of tmtcontrol.processes, each against what it promises
(found missing by the mutation sample of issue 43)."""
import gc
import os
import warnings

import pytest

from tmtcontrol import processes


def _blas_threads():
    from threadpoolctl import threadpool_info

    return [lib["num_threads"] for lib in threadpool_info() if lib.get("user_api") in ("blas", "openmp")]


def test_blas_threads_limited_holds_one_thread_in_the_block_and_restores_after(monkeypatch):
    import numpy  # noqa: F401  (its BLAS is what is limited)
    from threadpoolctl import threadpool_limits

    monkeypatch.setattr(processes, "_PINNED", [])
    with threadpool_limits(limits=2):                 # a process running two BLAS threads
        before = _blas_threads()
        if not before or max(before) < 2:
            pytest.fail(f"no BLAS library with two threads to limit here: {before}")
        with processes.blas_threads_limited():
            assert set(_blas_threads()) == {1}
        assert _blas_threads() == before


def test_a_pinned_process_is_not_limited_again(monkeypatch):
    """In a worker pinned for its lifetime (one_blas_thread), the block does
    nothing: threadpoolctl is not asked again (it costs a scan of the loaded
    libraries, 12 ms, per block)."""
    import threadpoolctl

    def refuse(*a, **k):
        raise AssertionError("threadpool_limits called in a pinned process")

    monkeypatch.setattr(processes, "_PINNED", [os.getpid()])
    monkeypatch.setattr(threadpoolctl, "threadpool_limits", refuse)
    with processes.blas_threads_limited():
        pass
    monkeypatch.setattr(processes, "_PINNED", [os.getpid() + 1])      # another process' pin: limited here
    with pytest.raises(AssertionError, match="pinned"):
        with processes.blas_threads_limited():
            pass


def test_run_compiler_closes_its_pipes_when_it_ends_early(tmp_path):
    """A compile that ends early (here its timeout; Ctrl-C goes the same way)
    kills the compiler and closes its output pipes (communicate() closes
    them only when it reads to the end): no ResourceWarning for an unclosed
    file once the exception is gone."""
    import subprocess

    (tmp_path / "tmp").mkdir()
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", ResourceWarning)
        with pytest.raises(subprocess.TimeoutExpired) as excinfo:
            processes.run_compiler(["sleep", "30"], tmp_path / "tmp", timeout=0.3)
        del excinfo
        gc.collect()
    assert not [w for w in seen if issubclass(w.category, ResourceWarning)], [str(w.message) for w in seen]


def test_without_process_groups_the_compiler_runs_plainly(tmp_path, monkeypatch):
    """Where process groups are missing (``os.name`` other than posix: Windows)
    run_compiler is a plain subprocess.run with the same TMPDIR; on POSIX it
    runs the compiler under its supervisor (a new session)."""
    import subprocess

    calls = []
    real_run = subprocess.run

    def run(args, **kw):
        calls.append((list(args), kw.get("env", {}).get("TMPDIR")))
        return real_run(args, **kw)

    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(subprocess, "run", run)
    processes.run_compiler(["true"], tmp_path / "tmp")
    assert calls == []                                     # POSIX: the supervisor, not subprocess.run
    monkeypatch.setattr(processes.os, "name", "nt")
    processes.run_compiler(["true"], tmp_path / "tmp")
    assert calls == [(["true"], str(tmp_path / "tmp"))]


def test_side_by_side_threads_are_one_in_a_worker_and_on_one_core(monkeypatch):
    """Review 35: processes.threads_for_side_by_side (the periodic analysis's threads, the compiles
    side by side) is 1 in a worker process (the cores are shared out by process already) and with
    one usable core, up to 2 otherwise."""
    import multiprocessing
    import os

    from tmtcontrol.processes import threads_for_side_by_side

    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(1) as pool:
        assert pool.apply(threads_for_side_by_side) == 1
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    assert threads_for_side_by_side() == 1
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    assert threads_for_side_by_side() == 2 and threads_for_side_by_side(limit=3) == 3
