"""Worker-process lifetime: workers that die with their parent, one BLAS
thread per process, and Ctrl-C that never lands in a finalizer.

tmtcontrol starts worker processes in two places: ``tmtcontrol sweep
--workers N`` (a :class:`concurrent.futures.ProcessPoolExecutor`) and the
report's second process (:mod:`tmtcontrol.report.document`). Both call
:func:`worker_init` first thing in the child:

* **They die with their parent.** If the parent is killed by a signal it
  cannot catch (``kill -9``, the OOM killer, a CI hard timeout), nothing tells
  a pool worker to stop: it would stay blocked on its task pipe for ever,
  holding the terminal's stdout and stderr open (so ``tmtcontrol sweep ... |
  tee log`` and ``subprocess.communicate`` hang). On Linux the child asks the
  kernel for SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``), then
  checks that the parent is still the one that started it (it may have died
  between the fork and the ``prctl``). On every platform (the portable
  fallback, and a second guard on Linux) a daemon thread waits on
  :func:`multiprocessing.parent_process`'s sentinel, which becomes ready when
  the parent ends (the read end of a pipe whose write end the parent holds,
  and with fork also the workers forked after this one, which end the same
  way first; on Windows the parent's process handle), and then ends the worker with
  ``os._exit(1)``. Caveat of ``PR_SET_PDEATHSIG``: the signal follows the
  *thread* that forked the child; tmtcontrol forks its workers from the main
  thread, so it follows the process.
* **One BLAS/OpenMP thread per process** (:func:`one_blas_thread`, by
  threadpoolctl): the numerical work is many small problems (3x3 and 8x8
  matrices), where BLAS threads only spin (issue #27 measured a sweep on a
  busy 2-core host at 30.2 s with the default threads and 9.0 s with
  ``OPENBLAS_NUM_THREADS=1``; ``benchmarks/bench_threads.py`` measures it on
  yours). The command line also sets those variables for libraries it loads
  later (:func:`blas_env_defaults`).

The C compiler (:func:`run_compiler`, every compile tmtcontrol runs) dies with
tmtcontrol too, and leaves no temporaries: ``cc`` forks ``cc1`` and ``as``,
which a ``PR_SET_PDEATHSIG`` of ``cc`` would not reach (the setting is not
inherited across fork), so the compiler runs under a small supervisor (a
bare ``python -I -S``) that leads a process group of its own, asks for
SIGTERM when tmtcontrol dies (and polls its parent, the portable guard) and
then kills the whole group; tmtcontrol itself kills the group at once when
it is interrupted (Ctrl-C, SIGTERM, a timeout). The compiler's ``TMPDIR`` is
the build folder's ``tmp/`` (:func:`tmtcontrol.cache.new_build_folder`),
removed with it, or, after a SIGKILL, by the next compile.

:func:`defer_in_finalizers` wraps the command line's SIGINT/SIGTERM handlers so
that a signal arriving while a weakref callback or a ``__del__`` runs is not
raised there (Python would print "Exception ignored in ..." and drop it): it is
recorded and delivered again a moment later, outside the finalizer.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading

__all__ = ["worker_init", "die_with_parent", "one_blas_thread", "defer_in_finalizers", "blas_threads_limited",
           "blas_env_defaults", "signals_held", "run_compiler", "THREAD_VARIABLES", "PDEATHSIG"]

PDEATHSIG = signal.SIGKILL if hasattr(signal, "SIGKILL") else None
"""The signal a Linux worker gets when its parent dies (a worker holds no
files of its own: the parent writes every output, so nothing needs cleaning)."""

_PR_SET_PDEATHSIG = 1          # <linux/prctl.h>


def worker_init(blas_limit: bool = True) -> None:
    """First thing in a worker process: :func:`die_with_parent`, quiet
    signals (:func:`_worker_signal`), and with ``blas_limit`` one BLAS/OpenMP
    thread for the process' lifetime."""
    import multiprocessing

    if multiprocessing.parent_process() is not None and threading.current_thread() is threading.main_thread():
        for signum in _HELD:
            signal.signal(signum, _worker_signal)
        if hasattr(signal, "pthread_sigmask"):       # held by the parent while it forked (signals_held)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)
    die_with_parent()
    if blas_limit:
        one_blas_thread()


_PACKAGE = os.path.dirname(os.path.abspath(__file__))
_HELD = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT and SIGTERM (blocked, not lost) in this thread for the
    block: start worker processes inside it. A Ctrl-C while they fork then
    reaches each child only after :func:`worker_init` has installed its own
    handler (a forked child inherits the blocked mask and the parent's
    Python handler, which would raise in the middle of its start-up), and
    reaches this process as the block ends. No-op where ``pthread_sigmask``
    is missing (Windows) or outside the main thread."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _worker_signal(signum, frame):
    """A worker's SIGINT/SIGTERM (Ctrl-C reaches every process of the
    command): inside a task (tmtcontrol's code on the stack) it stops the
    task with KeyboardInterrupt, which the pool hands back to the parent as
    the task's outcome. Anywhere else (starting, waiting for a task), where
    a worker that raised would print its own traceback, SIGINT is ignored
    (the parent handles the interruption and stops the pool) and SIGTERM
    ends the worker at once, quietly (a pool terminates its idle workers so
    when one of them crashed, and then waits for them). The walk stops at the
    process' own start (a forked child's stack goes on into the parent's
    frames as they were at the fork)."""
    while frame is not None and frame.f_code.co_name not in ("_process_worker", "_bootstrap"):
        name = os.path.abspath(frame.f_code.co_filename)
        if name.startswith(_PACKAGE + os.sep) and name != os.path.abspath(__file__):
            raise KeyboardInterrupt
        frame = frame.f_back
    if signum != signal.SIGINT:
        os._exit(128 + int(signum))


def die_with_parent() -> bool:
    """Make this process (a :mod:`multiprocessing` child) end when its parent
    ends, however the parent ends. Returns True if the Linux kernel signal
    was set (False elsewhere, where only the watchdog thread acts). Does
    nothing outside a multiprocessing child."""
    import multiprocessing

    parent = multiprocessing.parent_process()
    if parent is None:
        return False
    armed = _set_pdeathsig()
    if armed and os.getppid() != parent.pid:    # the parent died before the prctl: nobody will signal
        os._exit(1)
    threading.Thread(target=_watch, args=(parent,), name="tmtcontrol-parent-watchdog", daemon=True).start()
    return armed


def _set_pdeathsig() -> bool:
    if not sys.platform.startswith("linux") or PDEATHSIG is None:
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(PDEATHSIG), 0, 0, 0) == 0
    except (OSError, AttributeError):         # no prctl (an unusual libc): the watchdog remains
        return False


def _watch(parent) -> None:
    """The portable fallback: wait for the parent's sentinel, then end."""
    try:
        parent.join()          # returns when the parent's end of the pipe closes (or its handle is signalled)
    except Exception:         # pragma: no cover - a closed sentinel: the process is going anyway
        return
    os._exit(1)


_PINNED: list[int] = []     # the pid of a process pinned for its lifetime (a forked child starts unpinned)


def one_blas_thread():
    """Limit BLAS and OpenMP to one thread in this process (threadpoolctl)
    and return the limiter (its ``restore_original_limits()`` undoes it; as
    a context manager it undoes it on exit). tmtcontrol's linear algebra is on
    small matrices, where more threads only cost; with two processes busy on
    2 cores, spinning BLAS threads made the report's sampled stage 3x
    slower. Libraries loaded later in the process start with one thread
    too (:func:`blas_env_defaults`)."""
    from threadpoolctl import threadpool_limits

    blas_env_defaults()
    limiter = threadpool_limits(limits=1)
    _PINNED[:] = [os.getpid()]
    return limiter


THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
"""The variables BLAS, OpenMP and friends read when they are loaded."""


def blas_env_defaults() -> None:
    """Set each of :data:`THREAD_VARIABLES` to 1 unless the user set it: a
    library loaded after this call (NumPy's OpenBLAS, imported lazily by each
    command) starts with one thread, at no cost now (threadpoolctl can only
    limit libraries already loaded). The command line calls this first
    thing; a user's own value wins."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


@contextlib.contextmanager
def blas_threads_limited():
    """One BLAS/OpenMP thread for a block, the original limits restored after;
    nothing to do in a process already pinned for its lifetime (a worker
    after :func:`worker_init`)."""
    if _PINNED == [os.getpid()]:
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


_FINALIZER_FILES = ("weakref.py", "_weakrefset.py")


def _in_finalizer(frame) -> bool:
    """True if ``frame`` (the one a signal interrupted) is a weakref
    callback, a ``weakref.finalize`` callback or a ``__del__`` method, or is
    called from one: an exception raised there is printed as "Exception
    ignored" and lost."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or os.path.basename(code.co_filename) in _FINALIZER_FILES:
            return True
        frame = frame.f_back
    return False


def _redeliver(signum, handler) -> None:
    """Deliver ``signum`` to the main thread again, if ``handler`` still
    handles it (not once the command has restored the previous handlers)."""
    import _thread

    if signal.getsignal(signum) is handler:
        _thread.interrupt_main(signum)


def defer_in_finalizers(signums=(signal.SIGINT, signal.SIGTERM), retry: float = 0.02) -> None:
    """Wrap the Python handlers of ``signums`` (those installed by
    :func:`tmtcontrol.files.install_signal_handlers`): a signal that
    interrupts a finalizer is handed to the handler (so it is recorded for
    :func:`tmtcontrol.files.check_interrupt`) but its exception is held back,
    and the signal is delivered again ``retry`` seconds later, until it lands
    outside a finalizer. Main thread only."""
    for signum in signums:
        handler = signal.getsignal(signum)
        if callable(handler) and not getattr(handler, "_defers_finalizers", False):
            signal.signal(signum, _deferring(handler, retry))


def _deferring(handler, retry: float):
    """``handler``, held back inside finalizers (see :func:`defer_in_finalizers`)."""

    def deferring(sig, frame):
        if not _in_finalizer(frame):
            return handler(sig, frame)
        try:
            handler(sig, frame)             # records it; its exception must not escape here
        except BaseException:
            pass
        timer = threading.Timer(retry, _redeliver, args=(sig, deferring))
        timer.daemon = True
        timer.start()

    deferring._defers_finalizers = True
    return deferring


_SUPERVISOR = r"""
import os, signal, subprocess, sys
parent = int(sys.argv[1])
def end(*_):
    os.killpg(0, signal.SIGKILL)         # the compiler, its cc1/as, and this supervisor
for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
    signal.signal(s, end)
if sys.platform.startswith("linux"):
    import ctypes
    try:
        ctypes.CDLL(None).prctl(1, int(signal.SIGTERM), 0, 0, 0)     # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
if os.getppid() != parent:               # tmtcontrol died before the prctl
    end()
child = subprocess.Popen(sys.argv[2:])
while True:
    try:
        rc = child.wait(0.2)
        break
    except subprocess.TimeoutExpired:
        if os.getppid() != parent:       # the portable guard: tmtcontrol has gone
            end()
sys.exit(rc if rc >= 0 else 128 - rc)
"""
"""The compiler's supervisor (see the module docstring): ``python -I -S -c
_SUPERVISOR PARENT_PID CC ARGS...``, started as the leader of a new session."""


def threads_for_side_by_side(limit: int = 2) -> int:
    """Threads for work that runs side by side in this process (the periodic
    analysis's tangent rollouts, compiles of several loops): the usable cores
    up to ``limit``, and 1 in a worker process (a sweep's or the report's: the
    cores are shared out by process already)."""
    import multiprocessing

    if multiprocessing.parent_process() is not None:
        return 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(limit, cores))


def run_compiler(args: list[str], tmpdir: str | os.PathLike, timeout: float = 600.0, check: bool = True,
                 text: bool = False) -> subprocess.CompletedProcess:
    """Run the C compiler ``args`` (``[cc, flags..., file, "-o", lib]``) to the
    end, its output captured (bytes, or str with ``text``), with ``TMPDIR``
    (and ``TMP``, ``TEMP``) set to ``tmpdir`` (a build folder's ``tmp/``,
    :func:`tmtcontrol.cache.new_build_folder`); with ``check``, raise
    :class:`subprocess.CalledProcessError` if it fails.
    :class:`subprocess.TimeoutExpired` after ``timeout`` seconds. However
    this call ends early (Ctrl-C, SIGTERM under the command line's handlers,
    a timeout), the compiler and every process it started are killed before
    the exception goes on; if tmtcontrol itself is killed (SIGKILL), its
    supervisor kills them (see the module docstring). Where process groups
    are missing (Windows), a plain :func:`subprocess.run`."""
    tmp = os.fspath(tmpdir)
    env = {**os.environ, "TMPDIR": tmp, "TMP": tmp, "TEMP": tmp}
    args = [os.fspath(a) for a in args]
    if os.name != "posix" or not sys.executable:         # pragma: no cover - no process groups, no interpreter
        return subprocess.run(args, check=check, capture_output=True, timeout=timeout, env=env, text=text)
    proc = subprocess.Popen([sys.executable, "-I", "-S", "-c", _SUPERVISOR, str(os.getpid()), *args],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                            start_new_session=True, text=text)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:
        _kill_group(proc)
        raise
    finally:
        for stream in (proc.stdout, proc.stderr):
            stream.close()
    if check and proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, args, out, err)
    return subprocess.CompletedProcess(args, proc.returncode, out, err)


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the process group ``proc`` leads (its pid: a new session), then
    reap ``proc`` (until then its pid, the group's id, cannot be reused)."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    proc.wait()
