"""A signal during a compile, a full disk while caching, and build folders (issue 43): the C
compiler and everything it started die with tmtcontrol (SIGINT, SIGTERM and SIGKILL of the
main process alone), its temporaries are cleaned (at once, or after a SIGKILL by the next
compile and ``cache --clear``), an interrupted compile ends the command in one line with exit
130/143, a full disk leaves no staged ``.tmp`` file, and build folders live under the cache,
never in the temporary folder, and go when their owner has gone.

The slow compile is a fake ``cc`` written by the test: a shell script that leaves a temporary
``ccFAKE.s`` in ``$TMPDIR`` (as gcc does) and then waits for a child named ``cc1`` (a link to
``sleep 600``). The tests wait until that ``cc1`` runs (polling /proc), then signal, then poll
with generous bounds for what must happen: nothing depends on the machine's speed."""
import errno
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import pytest

from test_processes import _alive, _descendants
from test_processes import _kill_all as _reap

LINUX = sys.platform.startswith("linux")
pytestmark = pytest.mark.skipif(not LINUX or shutil.which("sleep") is None,
                                reason="reads the process tree from /proc; the fake compiler needs sh and sleep")

FAKE_CC = """#!/bin/sh
: > "$TMPDIR/ccFAKE.s"
"$(dirname "$0")/cc1" 600 &
wait
"""


@pytest.fixture
def fake_cc(tmp_path):
    """The environment of a command whose compiler hangs in ``cc1`` (cache and TMPDIR in tmp_path)."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    (bin_ / "cc1").symlink_to(shutil.which("sleep"))
    (bin_ / "cc").write_text(FAKE_CC)
    (bin_ / "cc").chmod(0o755)
    (tmp_path / "tmp").mkdir()
    return {**os.environ, "MPLBACKEND": "Agg", "PYTHONUNBUFFERED": "1", "CC": str(bin_ / "cc"),
            "TMPDIR": str(tmp_path / "tmp"), "TMTCONTROL_CACHE": str(tmp_path / "cache")}


def _comm(pid: int) -> str:
    try:
        return pathlib.Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _pgid(pid: int) -> int | None:
    try:
        return os.getpgid(pid)
    except OSError:
        return None


def _compiler_processes(root: int) -> set[int]:
    """The descendants of ``root`` in the process group of its ``cc1`` (the supervisor,
    ``cc`` and ``cc1``), once a ``cc1`` runs; else the empty set."""
    below = _descendants(root)
    groups = {_pgid(p) for p in below if _comm(p) == "cc1"} - {None}
    return {p for p in below if _pgid(p) in groups}


def _wait_for_cc1(proc: subprocess.Popen, limit: float = 180.0) -> set[int]:
    """Poll until ``proc`` has a ``cc1`` descendant (generous: a cold start imports CasADi and
    builds the step first); its compiler processes."""
    end = time.monotonic() + limit
    while time.monotonic() < end:
        found = _compiler_processes(proc.pid)
        if any(_comm(p) == "cc1" for p in found):
            return found
        if proc.poll() is not None:
            pytest.fail(f"the command ended (rc {proc.returncode}) before compiling: {proc.stderr.read()}")
        time.sleep(0.02)
    pytest.fail(f"no cc1 after {limit} s")


def _wait_gone(pids: set[int], limit: float = 10.0) -> set[int]:
    """Poll (at most ``limit`` s; the expected time is milliseconds) until none of ``pids``
    runs; those still running."""
    end = time.monotonic() + limit
    while time.monotonic() < end and any(_alive(p) for p in pids):
        time.sleep(0.02)
    return {p for p in pids if _alive(p)}


def _build_folders(tmp_path: pathlib.Path) -> list[pathlib.Path]:
    return sorted(p for p in tmp_path.rglob("tmtcontrol-build-*") if p.is_dir())


def _simulate(tmp_path, env) -> subprocess.Popen:
    """``tmtcontrol simulate paper`` on a cold cache, in a session of its own (a signal to it
    cannot reach pytest, and it is sent to the main process alone)."""
    return subprocess.Popen([sys.executable, "-m", "tmtcontrol.cli", "simulate", "paper", "--no-plots",
                             "--out", str(tmp_path / "out")], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _kill_all(proc, pids):
    _reap(proc, pids)
    proc.stdout.close()
    proc.stderr.close()


@pytest.mark.parametrize("signum, code, word", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")])
def test_a_signal_during_a_compile_kills_the_compiler_and_ends_in_one_line(tmp_path, fake_cc, signum, code, word):
    """SIGINT/SIGTERM to tmtcontrol alone while ``cc1`` runs: the command ends with the one
    interruption line and its exit code (within 10 s, against a compile that would take 600 s;
    2 s expected), no compiler process survives, and the compiler's temporary, the generated C
    and the build folder are gone; nothing is left in the temporary folder nor in --out."""
    proc = _simulate(tmp_path, fake_cc)
    pids: set[int] = set()
    try:
        pids = _wait_for_cc1(proc)
        assert list(tmp_path.rglob("ccFAKE.s")), "the fake compiler wrote no temporary"
        os.kill(proc.pid, signum)
        try:
            rc = proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            pytest.fail("the command did not stop within 10 s of the signal")
        err = proc.stderr.read()
        assert rc == code, err
        assert err.strip().splitlines() == [f"interrupted ({word}): nothing was written"], err
        assert not _wait_gone(pids), "compiler processes outlived the interrupted command"
        assert not list(tmp_path.rglob("ccFAKE.s"))
        assert _build_folders(tmp_path) == []
        assert not list(tmp_path.rglob("*.c"))
        assert list((tmp_path / "tmp").iterdir()) == []
        assert not (tmp_path / "out").exists()
    finally:
        _kill_all(proc, pids)


def test_sigkill_during_a_compile_kills_the_compiler_and_its_temporaries_go_next_time(tmp_path, fake_cc):
    """SIGKILL of tmtcontrol alone while ``cc1`` runs: every compiler process dies at once
    (not after the compile), the compiler's temporaries are inside the dead process' build
    folder under the cache (not in $TMPDIR), and ``tmtcontrol cache --clear`` removes it."""
    proc = _simulate(tmp_path, fake_cc)
    pids: set[int] = set()
    try:
        pids = _wait_for_cc1(proc)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        assert not _wait_gone(pids), "compiler processes outlived tmtcontrol's SIGKILL"
        left = _build_folders(tmp_path)
        assert len(left) == 1 and left[0].parent == tmp_path / "cache" / "build", left
        assert list(left[0].rglob("ccFAKE.s")), "the compiler's temporaries were not in the build folder"
        assert list((tmp_path / "tmp").iterdir()) == []
        out = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "cache", "--clear"], env=fake_cc,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert _build_folders(tmp_path) == []
        assert not list(tmp_path.rglob("ccFAKE.s"))
    finally:
        _kill_all(proc, pids)


def test_run_compiler_kills_the_group_on_keyboard_interrupt(tmp_path, fake_cc, monkeypatch):
    """In-process: SIGINT to the main thread once ``cc1`` runs leaves :func:`run_compiler`
    as KeyboardInterrupt at once (not at its 300 s timeout), after every process of the
    compiler has ended."""
    import threading

    from tmtcontrol.processes import run_compiler

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("the SIGINT goes to the main thread, which must be the one running the test")
    seen: set[int] = set()
    sent: list[float] = []
    main = threading.main_thread().ident

    def interrupt_once_cc1_runs():
        end = time.monotonic() + 60.0
        while time.monotonic() < end:
            found = _compiler_processes(os.getpid())
            if any(_comm(p) == "cc1" for p in found):
                seen.update(found)
                sent.append(time.monotonic())
                signal.pthread_kill(main, signal.SIGINT)
                return
            time.sleep(0.02)

    monkeypatch.setenv("TMPDIR", fake_cc["TMPDIR"])
    # a terminal's Python: SIGINT raises KeyboardInterrupt. A test run started in the background
    # of a script (`pytest &`: the shell ignores SIGINT for it, and Python keeps an inherited
    # SIG_IGN) would otherwise drop the signal and wait out the 300 s timeout, proving nothing.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        watcher = threading.Thread(target=interrupt_once_cc1_runs, daemon=True)
        watcher.start()
        with pytest.raises(KeyboardInterrupt):
            run_compiler([fake_cc["CC"], "x.c"], tmp_path / "tmp", timeout=300.0)
        watcher.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert seen, "no cc1 was seen"
    assert time.monotonic() - sent[0] < 60.0, "the interrupt waited for the compiler"
    assert not _wait_gone(seen), "compiler processes outlived the interrupt"


def test_run_compiler_reports_a_failed_compile_with_its_output(tmp_path):
    from tmtcontrol.processes import run_compiler

    script = tmp_path / "badcc"
    script.write_text('#!/bin/sh\necho "x.c:1: error: nope" >&2\necho "$TMPDIR" \nexit 1\n')
    script.chmod(0o755)
    with pytest.raises(subprocess.CalledProcessError) as info:
        run_compiler([str(script)], tmp_path)
    assert info.value.returncode == 1 and b"error: nope" in info.value.stderr
    assert info.value.stdout.decode().strip() == str(tmp_path)      # the compiler's TMPDIR


# -- build folders --------------------------------------------------------------------------
@pytest.fixture
def cache_env(tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path / "cache"))
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    return tmp_path


def test_a_build_folder_is_private_under_the_cache_and_goes_however_the_block_ends(cache_env):
    from tmtcontrol import cache

    for exc in (None, RuntimeError, KeyboardInterrupt):
        with pytest.raises(exc) if exc else _nothing():
            with cache.build_folder("cg") as build:
                assert build.parent == cache_env / "cache" / "build"
                assert (build / "tmp").is_dir() and build.stat().st_mode & 0o077 == 0
                (build / "tmp" / "ccX.s").write_text("temporary")
                if exc:
                    raise exc
        assert not build.exists()
    assert list((cache_env / "cache").iterdir()) == []       # the empty build root goes too
    assert list((cache_env / "tmp").iterdir()) == []


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _dead_pid_and_start() -> tuple[int, int]:
    """The pid and start time of a process that has ended."""
    from tmtcontrol import cache

    proc = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    start = cache._start_time(proc.pid)
    proc.communicate(b"")
    return proc.pid, start


def test_stale_build_folders_of_ended_processes_go_and_nothing_else(cache_env):
    """A build folder whose owner has ended (its pid gone, or the pid reused by another
    process: another start time) is removed by the next build, by prune_temporary and by
    clear_cache, whatever its age; this process' own, a folder of another name and a file
    of the build name stay; old versions' tmtcontrol-sil-*/-robot-* folders go after a day
    (clear_cache: at once)."""
    from tmtcontrol import cache

    root = cache_env / "cache" / "build"
    root.mkdir(parents=True, mode=0o700)
    pid, start = _dead_pid_and_start()
    me, my_start = os.getpid(), cache._start_time(os.getpid())
    dead = root / f"tmtcontrol-build-sil-{pid}-{start}-abc"
    reused = root / f"tmtcontrol-build-cg-{me}-{my_start + 1}-abc"
    in_tmp = cache_env / "tmp" / f"tmtcontrol-build-robot-{pid}-{start}-xyz"
    live = root / f"tmtcontrol-build-cg-{me}-{my_start}-mine"
    other = root / "tmtcontrol-build-cg-notapid"
    for d in (dead, reused, in_tmp, live, other):
        (d / "tmp").mkdir(parents=True)
        (d / "tmp" / "ccX.o").write_text("x")
    plain = root / f"tmtcontrol-build-cg-{pid}-{start}-file"
    plain.write_text("not a folder")
    fresh = cache_env / "tmp" / "tmtcontrol-sil-fresh"
    old = cache_env / "tmp" / "tmtcontrol-robot-old"
    for d in (fresh, old):
        d.mkdir()
    os.utime(old, (time.time() - 2 * 86400,) * 2)

    assert cache.prune_temporary() == 4
    assert sorted(root.iterdir()) == sorted([live, other, plain])
    assert sorted((cache_env / "tmp").iterdir()) == [fresh]
    cache.clear_cache()
    assert sorted(root.iterdir()) == sorted([live, other, plain]) and not fresh.exists()

    dead.mkdir()
    with cache.build_folder("cg"):                 # the next build cleans up first
        assert not dead.exists() and live.exists()


def test_a_build_folder_left_open_goes_when_the_process_exits(tmp_path):
    """new_build_folder (a build whose library is used for the rest of the run, as the SIL's
    is) is removed at the interpreter's exit, also when SIGTERM under the command line's
    handlers ends it; a forked child's exit does not remove its parent's folder."""
    env = {**os.environ, "TMTCONTROL_CACHE": str(tmp_path / "cache")}
    code = """
import os, signal, sys
from tmtcontrol import cache, files
files.install_signal_handlers()
b = cache.new_build_folder("sil")
(b / "lib.so").write_text("x")
pid = os.fork()
if pid == 0:
    sys.exit(0)                                # a normal exit of a forked child: atexit runs
os.waitpid(pid, 0)
print(b, "exists" if b.exists() else "gone", flush=True)
if sys.argv[1] == "term":
    os.kill(os.getpid(), signal.SIGTERM)
"""
    for how in ("exit", "term"):
        out = subprocess.run([sys.executable, "-c", code, how], env=env, capture_output=True, text=True, timeout=120)
        path, state = out.stdout.split()
        assert state == "exists", "a forked child removed its parent's build folder"
        assert not pathlib.Path(path).exists(), (how, out.stderr)
        assert pathlib.Path(path).parent == tmp_path / "cache" / "build"


def test_an_unwritable_cache_builds_in_the_private_fallback_not_in_tmp(cache_env, monkeypatch):
    from tmtcontrol import cache

    monkeypatch.setenv("TMTCONTROL_CACHE", "/proc/no-such-cache")
    with cache.build_folder("cg") as build:
        assert build.parent == cache.fallback_dir() / "build"
    assert list(cache.fallback_dir().iterdir()) == []
    cache.fallback_dir().rmdir()
    cache.fallback_dir().write_text("not a folder")          # no fallback either: the last resort
    with cache.build_folder("cg") as build:
        assert build.parent == cache_env / "tmp" and build.stat().st_mode & 0o077 == 0
    assert [p.name for p in (cache_env / "tmp").iterdir()] == [cache.fallback_dir().name]


def test_a_nearly_full_cache_disk_builds_in_the_temporary_folder_not_the_fallback(cache_env, monkeypatch):
    """Below BUILD_MIN_FREE free on the cache's disk the build folder is made in
    the temporary folder (a compile there would fail for lack of space); the
    per-user fallback, meant for an unwritable cache, is not made. At exactly
    the minimum the cache is used."""
    from tmtcontrol import cache

    free = {"bytes": cache.BUILD_MIN_FREE - 1}
    monkeypatch.setattr(cache, "_free_bytes", lambda folder: free["bytes"])
    with cache.build_folder("cg") as build:
        assert build.parent == cache_env / "tmp"
    assert list((cache_env / "tmp").iterdir()) == []
    free["bytes"] = cache.BUILD_MIN_FREE
    with cache.build_folder("cg") as build:
        assert build.parent == cache_env / "cache" / "build"


def test_free_bytes_of_a_missing_folder_is_its_disks_and_proc_is_not_full(tmp_path):
    from tmtcontrol import cache

    st = os.statvfs(tmp_path)
    assert cache._free_bytes(tmp_path / "a" / "b") == pytest.approx(st.f_bavail * st.f_frsize, rel=0.01)
    assert cache._free_bytes(pathlib.Path("/proc/no-such-cache")) == float("inf")


# -- a full disk while caching ----------------------------------------------------------------
def _enospc_on_fsync(monkeypatch, after: int = 0):
    """os.fsync raises ENOSPC from its ``after``-th call on (0: the first)."""
    from tmtcontrol import cache

    calls = []
    real = os.fsync

    def fsync(fd):
        calls.append(fd)
        if len(calls) > after:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd)

    monkeypatch.setattr(cache.os, "fsync", fsync)
    return calls


@pytest.mark.parametrize("after", [0, 1])
def test_a_full_disk_while_writing_staged_files_leaves_no_tmp(tmp_path, monkeypatch, after):
    """ENOSPC on the data's fsync or on its checksum's: the error is raised, no staged
    .tmp file and no target are left."""
    from tmtcontrol import cache

    calls = _enospc_on_fsync(monkeypatch, after)
    target = tmp_path / "robots" / "arm_0123.casadi"
    with pytest.raises(OSError) as info:
        cache.write_staged([(target, b"data" * 1000), (target.with_name(target.name + ".sha256"), b"ff")])
    assert info.value.errno == errno.ENOSPC and len(calls) == after + 1
    assert list((tmp_path / "robots").iterdir()) == []


PENDULUM = """<robot name="pend">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0.3 0 0"/><mass value="2.0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool"/>
  <joint name="j0" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/></joint>
  <joint name="t" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
</robot>"""


def test_a_full_disk_while_caching_a_robot_leaves_no_tmp(cache_env, monkeypatch):
    """ENOSPC while a URDF robot's serialized Functions are cached: the robot still loads
    (built, not cached) and the robots' cache folder holds no staged .tmp file."""
    from tmtcontrol.model.robot import load_robot

    path = cache_env / "pend.urdf"
    path.write_text(PENDULUM)
    calls = _enospc_on_fsync(monkeypatch)
    robot = load_robot(path)
    assert calls, "nothing was cached"
    assert robot.n == 1
    left = [p.name for p in (cache_env / "cache").rglob("*") if p.is_file()]
    assert [n for n in left if n.endswith(".tmp")] == [] and not any(n.endswith(".casadi") for n in left), left


def test_run_compiler_without_check_returns_the_failure_as_text(tmp_path):
    """``check=False, text=True``: the drop-in for a caller that reads the return code and
    the first line of stderr itself (the SIL's compile_export)."""
    from tmtcontrol.processes import run_compiler

    script = tmp_path / "badcc"
    script.write_text('#!/bin/sh\necho "x.c:1: error: nope" >&2\nexit 3\n')
    script.chmod(0o755)
    out = run_compiler([script], tmp_path, check=False, text=True)
    assert out.returncode == 3 and out.stderr == "x.c:1: error: nope\n"


def test_a_robot_compiled_with_an_unwritable_cache_leaves_nothing_in_tmp(cache_env, monkeypatch):
    """The robot's compiled dynamics with a cache that cannot be written: built in the
    per-user fallback's build folder, loaded from there and correct after the folder is
    gone; no tmtcontrol-lib-* (the old per-run copy) nor any build folder stays."""
    import numpy as np

    from tmtcontrol import cache
    from tmtcontrol.model.robot import load_robot

    if cache.compiler() is None:
        pytest.skip("no C compiler")
    (cache_env / "not-a-folder").write_text("")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(cache_env / "not-a-folder" / "cache"))
    path = cache_env / "pend.urdf"
    path.write_text(PENDULUM)
    robot = load_robot(path, cache=False)
    fn = robot.dynamics(compiled=True)
    assert fn.is_a("External")
    M, n = fn([0.4], [0.0])
    assert abs(float(M) - (0.01 + 2.0 * 0.09)) < 1e-12
    assert np.allclose(M.full(), robot.dynamics(compiled=False)([0.4], [0.0])[0].full(), rtol=0, atol=1e-15)
    assert [p.name for p in (cache_env / "tmp").iterdir()] == [cache.fallback_dir().name]
    assert list(cache.fallback_dir().iterdir()) == []


@pytest.mark.heavy
def test_simulate_with_an_exported_controller_leaves_nothing_in_the_temporary_folder(tmp_path):
    """Issue: every `simulate --controller` left a tmtcontrol-sil-* build folder in $TMPDIR that
    neither pruning nor `cache --clear` removed. The SIL library is now built in a private build
    folder under the cache, removed when the command ends: $TMPDIR stays empty and the cache's
    build folder holds nothing once the command is over."""
    import os
    import subprocess
    import sys

    tmp, cache = tmp_path / "tmp", tmp_path / "cache"
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp), "TMTCONTROL_CACHE": str(cache), "MPLBACKEND": "Agg"}
    run = lambda *a: subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *a], env=env, capture_output=True,
                                    text=True, timeout=600)
    r = run("export", "paper", "--inner-loop", "--out", str(tmp_path / "ctrl"))
    assert r.returncode == 0, r.stderr
    r = run("simulate", "paper", "--controller", str(tmp_path / "ctrl"), "--set", "trajectory.cycles=0.25",
            "--no-plots", "--out", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(tmp)) == []
    build = cache / "build"
    assert not build.exists() or sorted(os.listdir(build)) == []


_REMOTE_HANGS = '''
import os, sys, time
import tmtcontrol.report.document as _doc

def _hanging_pull(sc, p):
    print(f"remote task started {os.getpid()}", file=sys.stderr, flush=True)
    while True:
        time.sleep(1.0)

_doc._pull = _hanging_pull
'''


def test_ctrl_c_to_report_alone_does_not_wait_for_its_second_process(tmp_path):
    """Issue 43: ``report`` runs part of its stages in a second process; a
    SIGINT to the main process alone (not the terminal's group) waited for
    the task that process was running, up to a minute on a cold cache. Here
    its task never ends (a sitecustomize replaces the task runner by one that
    sleeps forever): the command must still end with the one interruption
    line and exit 130, the second process gone (SIGTERM, then SIGKILL after
    STOP_GRACE s), nothing written. Bounded by 60 s against a task that never
    ends; about 1-2 s expected."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(_REMOTE_HANGS)
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONUNBUFFERED": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")]))}
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "tmtcontrol.cli", "report", "paper", "--format", "html",
                             "--out", str(out)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    child = None
    try:
        for line in proc.stderr:
            if line.startswith("remote task started "):
                child = int(line.split()[-1])
                break
        assert child is not None, "the second process never started its task"
        os.kill(proc.pid, signal.SIGINT)
        try:
            rc = proc.wait(timeout=60.0)
        except subprocess.TimeoutExpired:
            pytest.fail("report did not stop within 60 s of SIGINT: it waits for its second process' task")
        err = proc.stderr.read()
        assert rc == 130, err
        assert err.strip().splitlines()[-1] == "interrupted (Ctrl-C): nothing was written", err
        assert not _alive(child), "the second process outlived the interrupted report"
        assert not out.exists()
    finally:
        _kill_all(proc, {child} - {None})
