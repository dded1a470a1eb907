"""Worker-process lifetime and interruption (issues #32 items 1 and 5, #27 items 3, 6 and 16):
workers die with a parent killed by SIGKILL, a Dask address with no scheduler is refused in one
line, a signal never raises inside a finalizer, an interrupted sweep says what it kept, Ctrl-C
during the imports is one line, and workers run with one BLAS thread.

Every test that runs the command line starts it in a session of its own (a kill cannot reach
pytest) and synchronises on the lines it prints, never on a sleep; the only waits are bounded
polls for something that must happen (a process gone, a pipe at EOF)."""
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

LINUX = sys.platform.startswith("linux")
ENV = {**os.environ, "MPLBACKEND": "Agg", "PYTHONUNBUFFERED": "1"}

LONG_SWEEP = """
scenario = "paper"
[grid]
"environment.stiffness.values" = [[5000.0], [6000.0], [7000.0], [8000.0]]
"trajectory.cycles" = [200.0]
"""
"""Four cases long enough (200 path cycles each) that the workers are still busy when the
parent is killed right after it says they run."""


def _children() -> dict[int, list[int]]:
    """Every process' children, from /proc."""
    kids: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = pathlib.Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        kids.setdefault(ppid, []).append(int(entry))
    return kids


def _descendants(pid: int) -> set[int]:
    kids, out, todo = _children(), set(), [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for its parent counts as gone)."""
    try:
        return pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _wait_for_line(stream, needle: str, limit: int = 200) -> list[str]:
    """Read lines until one contains ``needle``; the lines read (fails at EOF)."""
    lines = []
    for _ in range(limit):
        line = stream.readline()
        if not line:
            pytest.fail(f"EOF before {needle!r}; got:\n{''.join(lines)}")
        lines.append(line)
        if needle in line:
            return lines
    pytest.fail(f"no {needle!r} in {limit} lines:\n{''.join(lines)}")


def _survivors_after(pids: set[int], seconds: float) -> set[int]:
    """The processes of ``pids`` still alive after polling for at most ``seconds``
    (a generous bound: the expected time is milliseconds)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end and any(_alive(p) for p in pids):
        time.sleep(0.05)
    return {p for p in pids if _alive(p)}


def _kill_all(proc, pids: set[int]) -> None:
    """Clean-up after a test: SIGKILL ``pids`` and what ``proc`` still has below it
    (those already gone are skipped), then ``proc`` itself."""
    for p in pids | _descendants(proc.pid):
        try:
            os.kill(p, signal.SIGKILL)
        except ProcessLookupError:
            pass
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def _sigkill_leaves_no_orphan(args: list[str], cwd, needle: str) -> None:
    """Start ``tmtcontrol ARGS``, wait for the line ``needle`` on stderr, collect the
    descendants, SIGKILL the parent alone, then poll (at most 10 s, a generous bound: the
    expected time is milliseconds) until no descendant runs and stdout is at EOF."""
    proc = subprocess.Popen([sys.executable, "-m", "tmtcontrol.cli", *args], cwd=cwd, env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    survivors: set[int] = set()
    try:
        _wait_for_line(proc.stderr, needle)
        workers = _descendants(proc.pid)
        assert workers, "the command started no worker process"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        survivors = _survivors_after(workers, 10.0)
        assert not survivors, f"worker processes outlived their parent: {sorted(survivors)}"
        # every holder of the pipe is gone: reading reaches EOF (what `| tee` and communicate() wait for)
        assert proc.stdout.read() is not None and proc.stderr.read() is not None
    finally:
        _kill_all(proc, survivors)
        proc.stdout.close()
        proc.stderr.close()


@pytest.mark.skipif(not LINUX, reason="reads the process tree from /proc")
def test_sweep_workers_die_when_the_parent_is_killed(tmp_path):
    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    _sigkill_leaves_no_orphan(["sweep", "s.toml", "--workers", "2", "--out", "o", "--no-plots"], tmp_path,
                              "running on 2 worker processes")


@pytest.mark.heavy
@pytest.mark.skipif(not LINUX, reason="reads the process tree from /proc")
def test_report_worker_dies_when_the_parent_is_killed(tmp_path):
    # the second process is forked before the first stage; killed after the first stage's line
    _sigkill_leaves_no_orphan(["report", "paper", "--format", "html", "--out", "r"], tmp_path, "[1/")


def test_dask_address_with_no_scheduler_is_refused_in_one_line_leaving_nothing(tmp_path):
    import socket

    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    with socket.socket() as s:          # a port nobody listens on: bound, never listening
        s.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
        r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "sweep", "s.toml", "--dask", address,
                            "--out", "o"], cwd=tmp_path, env=ENV, capture_output=True, text=True)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0] == f"error: --dask {address}: no scheduler answered (connection refused)"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]        # no o/, no o.partial/, no staging


def test_check_dask_accepts_a_listening_port_and_names_bad_addresses():
    import socket

    from tmtcontrol.sweep.run import SchedulerUnavailable, check_dask

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        check_dask(f"tcp://127.0.0.1:{s.getsockname()[1]}")        # answers: no error
    check_dask("local")
    check_dask(None)
    with pytest.raises(SchedulerUnavailable, match=r"^--dask tcp://127\.0\.0\.1:x: not a host:port address$"):
        check_dask("tcp://127.0.0.1:x")


@pytest.mark.parametrize("sends", [b"", b"HTTP/1.1 400 Bad Request\r\n\r\n"])
def test_a_port_that_is_no_dask_scheduler_is_refused_not_waited_on(sends):
    """Review 59: a port that accepted the connection and never spoke held the
    Dask client past its 10 s timeout for as long as the port stayed open (90 s
    and counting); one that speaks another protocol is no scheduler either. The
    scheduler is asked who it is over Dask's protocol within the timeout (a
    short one here: the silent port never answers, whatever the machine's
    speed)."""
    import socket
    import threading

    from tmtcontrol.sweep.run import SchedulerUnavailable, identify_scheduler

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        held = []

        def serve():
            c, _ = s.accept()
            held.append(c)
            if sends:
                c.sendall(sends)
                c.close()

        threading.Thread(target=serve, daemon=True).start()
        address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
        with pytest.raises(SchedulerUnavailable, match=rf"^--dask {address}: no Dask scheduler answered within 0.5 s"
                                                       rf"|^--dask {address}: not a Dask scheduler"):
            identify_scheduler(address, seconds=0.5)
        for c in held:
            c.close()


@pytest.mark.heavy
def test_a_running_scheduler_is_identified_and_a_workers_address_refused():
    """The other side of the test above, on a real Dask cluster (TCP): its
    scheduler answers as one; its worker's address is refused naming what it
    is. Heavy: a cluster starts (about 3 s)."""
    from dask.distributed import LocalCluster

    from tmtcontrol.sweep.run import SchedulerUnavailable, identify_scheduler

    with LocalCluster(n_workers=1, processes=False, protocol="tcp", dashboard_address=None) as cluster:
        identify_scheduler(cluster.scheduler_address)
        (worker,) = cluster.scheduler_info["workers"]
        with pytest.raises(SchedulerUnavailable, match=r"not a Dask scheduler \(it answered as Worker; give the "):
            identify_scheduler(worker)


def _ctrl_c_after(args: list[str], cwd, needle: str) -> tuple[int, list[str]]:
    """Start ``tmtcontrol ARGS``, wait for ``needle`` on stderr, send SIGINT to the whole
    process group (what a terminal's Ctrl-C does); the exit code and the stderr lines after."""
    proc = subprocess.Popen([sys.executable, "-m", "tmtcontrol.cli", *args], cwd=cwd, env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        _wait_for_line(proc.stderr, needle)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return proc.returncode, err.strip().splitlines()


def test_ctrl_c_on_a_local_sweep_before_any_case_finished_is_one_line_and_leaves_nothing(tmp_path):
    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    code, lines = _ctrl_c_after(["sweep", "s.toml", "--workers", "2", "--out", "o", "--no-plots"], tmp_path,
                                "running on 2 worker processes")
    assert code == 130 and lines == ["interrupted (Ctrl-C): nothing was written"], lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]          # the fresh o.partial/ removed too


def test_ctrl_c_on_a_sweep_with_finished_cases_says_where_they_are_kept(tmp_path):
    from tmtcontrol.sweep import load_sweep
    from tmtcontrol.sweep.run import PartialFolder

    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    sweep = load_sweep(tmp_path / "s.toml")
    partial = PartialFolder(tmp_path / "o", sweep, resume=False)          # as a run that finished case 0
    partial.write([{"case": 0, "verdict": "converged"}])
    code, lines = _ctrl_c_after(["sweep", "s.toml", "--workers", "2", "--out", "o", "--no-plots", "--resume"],
                                tmp_path, "3 cases running on 2 worker processes")
    assert code == 130 and lines == [f"interrupted (Ctrl-C): 1 finished case kept in {tmp_path / 'o.partial'}/; "
                                     "run the same command with --resume to continue"], lines
    assert sorted(p.name for p in (tmp_path / "o.partial").iterdir()) == ["part-0000000.parquet", "sweep.json"]
    assert not (tmp_path / "o").exists()


@pytest.mark.heavy      # a Dask cluster started and interrupted (~5 s); the README suite stays within its 3 minutes
def test_ctrl_c_on_a_dask_sweep_is_one_line(tmp_path):
    # a LocalCluster of one worker process; the terminal's SIGINT reaches the worker too
    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    code, lines = _ctrl_c_after(["sweep", "s.toml", "--dask", "local", "--workers", "1", "--out", "o",
                                 "--no-plots"], tmp_path, "running on Dask")
    assert code == 130 and lines == ["interrupted (Ctrl-C): nothing was written"], lines
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


FINALIZER_SCRIPT = """
import signal, sys, time, weakref
from tmtcontrol.cli import main
from tmtcontrol import files, processes

files.install_signal_handlers()
if sys.argv[1] == "deferred":
    processes.defer_in_finalizers()

class Key:
    pass

d = weakref.WeakKeyDictionary()
fired = []
k = Key()
weakref.finalize(k, lambda: (fired.append(1), signal.raise_signal(signal.SIGINT)))
d[k] = 1
try:
    del k                       # the finalizer runs here and the signal arrives inside it
    for _ in range(200):        # later, outside the finalizer: the deferred signal lands here (a bound, not a timing)
        time.sleep(0.01)
    print("not interrupted", fired)
except files.Interrupted:
    print("interrupted outside the finalizer", fired)
"""


# "plain" (the handler alone, the bug shown) is heavy by docs/testing.md's 2 s rule: 2.1 s on 2026-12-07's machine
@pytest.mark.parametrize("mode", ["deferred", pytest.param("plain", marks=pytest.mark.heavy)])
def test_a_signal_inside_a_finalizer_is_raised_after_it_not_inside_it(mode):
    r = subprocess.run([sys.executable, "-c", FINALIZER_SCRIPT, mode], capture_output=True, text=True, env=ENV)
    if mode == "deferred":
        assert r.stdout.strip() == "interrupted outside the finalizer [1]" and r.stderr == "", r.stderr
    else:        # the handler alone: Python prints "Exception ignored" and the Ctrl-C is lost (the bug)
        assert "Exception ignored" in r.stderr and r.stdout.strip() == "not interrupted [1]"


IMPORT_SCRIPT = """
import importlib.abc, signal, sys

# a terminal's Python: Ctrl-C raises KeyboardInterrupt (a test runner's worker may hand its child an
# ignored SIGINT, which Python keeps; then the signal below would do nothing and the test prove nothing)
signal.signal(signal.SIGINT, signal.default_int_handler)

class CtrlCDuringImport(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name == "tmtcontrol.files":          # main()'s first import, before its handlers exist
            signal.raise_signal(signal.SIGINT)
        return None

import tmtcontrol.cli
sys.meta_path.insert(0, CtrlCDuringImport())
sys.argv = ["tmtcontrol", "check"]
tmtcontrol.cli.run()
"""


def test_ctrl_c_during_the_first_imports_is_one_line_and_exit_130():
    r = subprocess.run([sys.executable, "-c", IMPORT_SCRIPT], capture_output=True, text=True, env=ENV)
    assert r.returncode == 130 and r.stderr.strip().splitlines() == ["interrupted (Ctrl-C): nothing was written"], \
        r.stderr


def _threads_probe(base, cases, max_steps=None, *options):
    """Stands in for run_chunk in the worker: each case's row carries the BLAS/OpenMP thread counts."""
    from threadpoolctl import threadpool_info

    return [{"case": c.index, "threads": [i["num_threads"] for i in threadpool_info()]} for c in cases]


def _plain_probe():
    from threadpoolctl import threadpool_info

    return [i["num_threads"] for i in threadpool_info()]


def test_sweep_workers_run_with_one_blas_thread(tmp_path, monkeypatch):
    import concurrent.futures

    import numpy  # noqa: F401  (its BLAS loaded here, inherited by the forked workers)

    from tmtcontrol.sweep import load_sweep
    from tmtcontrol.sweep import run as sweep_run

    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    sweep = load_sweep(tmp_path / "s.toml")
    monkeypatch.setattr(sweep_run, "run_chunk", _threads_probe)
    rows: list[dict] = []
    sweep_run.run_cases(sweep, list(sweep.cases), rows.extend, workers=2)
    assert sorted(r["case"] for r in rows) == [0, 1, 2, 3]
    assert all(r["threads"] and set(r["threads"]) == {1} for r in rows), rows
    from tmtcontrol.processes import THREAD_VARIABLES

    if (os.cpu_count() or 1) > 1 and not any(v in os.environ for v in THREAD_VARIABLES):
        # the control: a plain worker on this machine has more than one
        with concurrent.futures.ProcessPoolExecutor(1) as pool:
            assert max(pool.submit(_plain_probe).result()) > 1


@pytest.mark.heavy
@pytest.mark.skipif(not LINUX, reason="reads the process tree from /proc")
def test_dask_local_cluster_workers_die_when_the_parent_is_killed(tmp_path):
    # Dask's own watchdog (each worker watches its nanny, which lives in the command's process)
    (tmp_path / "s.toml").write_text(LONG_SWEEP)
    _sigkill_leaves_no_orphan(["sweep", "s.toml", "--dask", "local", "--workers", "2", "--out", "o", "--no-plots"],
                              tmp_path, "running on Dask")


def _sigterm_idle_sibling_then_return_pid():
    return os.getpid()


def test_an_idle_worker_ends_on_sigterm_and_ignores_sigint():
    # a pool terminates its idle workers (SIGTERM) when one crashed, then joins them: they must end;
    # the terminal's Ctrl-C (SIGINT) outside a task is the parent's to handle
    import concurrent.futures
    import multiprocessing

    from tmtcontrol.processes import worker_init

    ctx = multiprocessing.get_context("fork")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx, initializer=worker_init,
                                                initargs=(False,)) as pool:
        pid = pool.submit(_sigterm_idle_sibling_then_return_pid).result()     # now idle, waiting for a task
        os.kill(pid, signal.SIGINT)
        assert pool.submit(_sigterm_idle_sibling_then_return_pid).result() == pid    # still there, still working
        proc = next(iter(pool._processes.values()))
        os.kill(pid, signal.SIGTERM)
        # the pool's own manager thread joins a worker that died, and the two threads' waitpid race: the one
        # that loses gets ECHILD and reads no exit code until the winner stores it (a failure under load,
        # 2026-12-06), so wait for the code to be stored; a bound, not a timing: expected at once
        deadline = time.monotonic() + 30
        while proc.exitcode is None and time.monotonic() < deadline:
            proc.join(timeout=0.05)
        assert proc.exitcode == 128 + signal.SIGTERM


WATCHDOG_SCRIPT = """
import concurrent.futures, multiprocessing, os, sys
from tmtcontrol import processes
processes._set_pdeathsig = lambda: False     # as on a platform without PR_SET_PDEATHSIG: the watchdog alone
with concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context(sys.argv[1]),
                                            initializer=processes.worker_init, initargs=(False,)) as pool:
    print(pool.submit(os.getpid).result(), flush=True)
    sys.stdin.read()                          # until killed
"""


@pytest.mark.skipif(not LINUX, reason="reads the process tree from /proc")
def test_the_portable_watchdog_alone_ends_a_worker_whose_parent_was_killed():
    # fork: the worker holds a copy of the parent's end of its task pipe, so without the watchdog (or the
    # kernel's signal) it waits for ever (a spawned worker sees EOF on that pipe and ends by itself)
    method = "fork"
    proc = subprocess.Popen([sys.executable, "-c", WATCHDOG_SCRIPT, method], env=ENV, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, start_new_session=True)
    survivors: set[int] = set()
    try:
        worker = int(proc.stdout.readline())
        assert _alive(worker)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        survivors = _survivors_after({worker}, 10.0)
        assert not survivors, "the worker outlived its parent"
    finally:
        _kill_all(proc, survivors)
        proc.stdin.close()
        proc.stdout.close()


def _pdeathsig() -> int:
    import ctypes

    value = ctypes.c_int(-1)
    assert ctypes.CDLL(None).prctl(2, ctypes.byref(value), 0, 0, 0) == 0      # PR_GET_PDEATHSIG
    return value.value


@pytest.mark.skipif(not LINUX, reason="PR_SET_PDEATHSIG is Linux's")
def test_a_worker_asks_the_kernel_for_sigkill_when_its_parent_dies():
    import concurrent.futures
    import multiprocessing

    from tmtcontrol.processes import worker_init

    ctx = multiprocessing.get_context("fork")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx, initializer=worker_init,
                                                initargs=(False,)) as pool:
        assert pool.submit(_pdeathsig).result() == signal.SIGKILL
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx) as pool:      # the control: unset by default
        assert pool.submit(_pdeathsig).result() == 0
