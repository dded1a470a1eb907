"""The compile cache (the simulation's rollouts, the robots' model functions) and the
C compiler that fills it: where compiled libraries live, how they are written (staged, fsync'ed, renamed, verified),
found, pruned, described and cleared (``tmtcontrol cache --info/--clear``).

* The cache is ``$TMTCONTROL_CACHE`` if set, else ``$XDG_CACHE_HOME/tmtcontrol``
  (``~/.cache/tmtcontrol``).
* A library ``NAME_chunk_KEY.so`` has a sidecar ``NAME_chunk_KEY.json`` with
  its size and SHA-256, written after it; a library that does not match its
  sidecar is rebuilt, never loaded. A write that fails (a full disk) removes
  its staged ``.NAME.so.PID.tmp`` files: nothing partial is left.
* An unwritable cache falls back to one folder per user,
  ``$TMPDIR/tmtcontrol-cache-UID`` (mode 0700, owned by the user, else not
  used), reused by every run instead of a new folder each time.
* After each new library the folder is pruned: libraries unused for
  :data:`MAX_AGE_DAYS` days go, then the least recently used until the
  libraries take at most :data:`MAX_BYTES`; staged files older than an hour
  (a killed write) go too, and so do this user's build folders whose
  owner process has ended (:func:`build_folder`) and the temporary folders
  of older versions (``$TMPDIR/tmtcontrol-cg-*``, ``-robot-*``, ``-sil-*``,
  ``-lib-*``) older than a day. Loading a library marks it used (its mtime).
* Every compile (a rollout, a robot's Functions, an exported controller)
  builds in a private folder :func:`build_folder` makes under the cache
  (``CACHE/build/tmtcontrol-build-KIND-PID-START-*``, the compiler's own
  temporaries in its ``tmp/``), removed when the build ends or the process
  exits; one whose owner was killed (SIGKILL) is removed by the next compile,
  by :func:`prune_temporary` and by ``tmtcontrol cache --clear``. Only when
  no cache folder can be used (the disk holding it has less than
  :data:`BUILD_MIN_FREE` free, or neither it nor the fallback can be
  written) is a build folder made in the temporary folder, removed the same way.
* Analysis results (the deciding stiffness limit of a scenario, the damping design, the report's check rows;
  ``stability.limit``) are kept as ``results/result_HASH.json`` in the
  cache (:func:`store_result`, :func:`load_result`): each file holds its
  full key (the package's sources, the arm's and the surface's content, the
  scenario's every value, the numerical libraries' versions), checked on
  reading, so a changed input is a new key and a damaged file is ignored
  and recomputed. At most :data:`MAX_RESULTS` are kept (least recently used
  go first, and any unused for :data:`MAX_AGE_DAYS` days); ``cache --clear``
  removes them.
* A compile takes a lock on its library's name first (:func:`compile_lock`:
  ``locks/NAME.so.lock``, ``flock``, removed when released), and looks in
  the cache again once it holds it: two processes that need the same step at once (a report's two
  processes, a sweep's workers, the test suite's) compile it once, the
  second loading what the first stored. A lock held longer than the
  compiler's own time limit is not waited for. An analysis result is
  computed under the same kind of lock (:func:`result_lock`), so a report's
  two processes needing one limit compute it once.
* Only files named as tmtcontrol names them are ever removed; anything else in
  the folder is left alone.

Standard library only: ``tmtcontrol cache`` starts without CasADi or NumPy.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import json
import os
import pathlib
import re
import shutil
import stat
import tempfile
import time

__all__ = ["MAX_BYTES", "MAX_AGE_DAYS", "MAX_RESULTS", "LOCK_WAIT", "compile_lock", "result_lock", "load_result", "store_result", "compiler", "cache_dir", "fallback_dir", "cache_folders", "find", "verify", "store",
           "write_staged", "mark_used", "prune", "prune_results", "prune_temporary", "build_folder", "new_build_folder",
           "remove_build_folder", "cache_info", "clear_cache", "format_cache_info"]

MAX_BYTES = 200 * 2**20
"""The compiled libraries kept in one cache folder take at most 200 MiB
(a library of the paper's closed loop takes about 0.1 MiB)."""

MAX_AGE_DAYS = 90
"""A library not used for 90 days is removed (an old CasADi version, old sources)."""

MAX_RESULTS = 20_000
"""Analysis results kept in one cache folder (a few kilobytes each): a
sweep with a random axis stores two per case family (its deciding limit
and the 1-D small-signal limit that seeds it), so 10,000 families."""

_STALE_TMP_SECONDS = 3600
_LOCK = re.compile(r"([A-Za-z0-9_]+_chunk_[0-9a-f]{20}\.so|result_[0-9a-f]{40})\.lock")
LOCK_WAIT = 600.0
"""Seconds a compile waits for another process' compile of the same library
(the compiler's own time limit) before compiling it itself."""
_RESULT = re.compile(r"result_[0-9a-f]{40}\.json")
_RESULT_STAGED = re.compile(r"\.result_[0-9a-f]{40}\.json\.[0-9]+\.tmp")
_LIBRARY = re.compile(r"[A-Za-z0-9_]+_chunk_[0-9a-f]{20}\.so")
_SIDECAR = re.compile(r"[A-Za-z0-9_]+_chunk_[0-9a-f]{20}\.json")
_STAGED = re.compile(r"\.[A-Za-z0-9_]+_chunk_[0-9a-f]{20}\.(so|json)\.[0-9]+\.tmp")


def compiler() -> str | None:
    """The C compiler to use (``$CC``, else cc/gcc/clang on PATH), or None."""
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def cache_dir() -> pathlib.Path:
    """The folder holding compiled libraries."""
    env = os.environ.get("TMTCONTROL_CACHE")
    if env:
        return pathlib.Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return pathlib.Path(base) / "tmtcontrol"


def _user() -> str:
    return str(os.getuid()) if hasattr(os, "getuid") else re.sub(r"\W", "_", os.environ.get("USERNAME", "user"))


def fallback_dir() -> pathlib.Path:
    """The per-user folder used when :func:`cache_dir` cannot be written."""
    return pathlib.Path(tempfile.gettempdir()) / f"tmtcontrol-cache-{_user()}"


def _private(folder: pathlib.Path) -> bool:
    """A real folder (not a link) owned by this user that nobody else can write:
    libraries are loaded from it, so in a shared /tmp nothing else will do."""
    try:
        st = os.lstat(folder)
    except OSError:
        return False
    owner_ok = not hasattr(os, "getuid") or st.st_uid == os.getuid()
    return stat.S_ISDIR(st.st_mode) and owner_ok and not st.st_mode & 0o022


def fallback_cache(create: bool = True) -> pathlib.Path | None:
    """:func:`fallback_dir`, created 0700 if needed, if it is safe to use; else None."""
    folder = fallback_dir()
    if create:
        try:
            folder.mkdir(mode=0o700)
        except FileExistsError:
            pass
        except OSError:
            return None
    return folder if _private(folder) else None


def cache_folders() -> list[pathlib.Path]:
    """The folders searched for a library: the cache, then the per-user
    fallback if it exists and is safe."""
    out = [cache_dir()]
    fb = fallback_cache(create=False)
    if fb is not None and fb != out[0]:
        out.append(fb)
    return out


def find(name: str) -> pathlib.Path | None:
    """The first ``folder/name`` that exists among :func:`cache_folders`."""
    for folder in cache_folders():
        if (folder / name).exists():
            return folder / name
    return None


def _digest(path: pathlib.Path) -> dict:
    data = path.read_bytes()
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _sidecar(lib: pathlib.Path) -> pathlib.Path:
    return lib.with_suffix(".json")


def verify(lib: pathlib.Path) -> bool:
    """The library matches the size and checksum recorded when it was written."""
    try:
        return json.loads(_sidecar(lib).read_text()) == _digest(lib)
    except (OSError, ValueError):
        return False


def store(built: pathlib.Path, lib: pathlib.Path) -> None:
    """Copy ``built`` into the cache as ``lib``, with its sidecar (size and
    SHA-256), by :func:`write_staged`: a full disk leaves nothing partial."""
    write_staged([(lib, built.read_bytes()), (_sidecar(lib), json.dumps(_digest(built)).encode())])


def write_staged(files: list[tuple[pathlib.Path, bytes]]) -> None:
    """Write each ``(path, data)``: all are staged as ``.NAME.PID.tmp`` and
    fsync'ed first, then renamed in order (put the checksum last, so a crash
    between leaves an unverifiable file, which is rebuilt). If anything fails
    (a full disk, a signal), every staged file is removed and the error
    raised: nothing partial is left."""
    for path, _ in files:
        path.parent.mkdir(parents=True, exist_ok=True)
    staged = []
    try:
        for target, data in files:
            tmp = target.parent / f".{target.name}.{os.getpid()}.tmp"
            staged.append((tmp, target))
            with open(tmp, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        for tmp, target in staged:
            os.replace(tmp, target)
    except BaseException:
        for tmp, _ in staged:
            try:
                tmp.unlink()
            except OSError:
                pass
        raise


@contextlib.contextmanager
def compile_lock(name: str, wait: float | None = None):
    """A block that holds the compile lock of library ``name`` (an exclusive
    ``flock`` on ``CACHE/locks/NAME.lock``): another process compiling the
    same library waits at its own lock, then finds it in the cache. Polled
    every 50 ms for at most ``wait`` s (default :data:`LOCK_WAIT`), after
    which the block runs without the lock (a stopped holder does not stop
    this run); without ``fcntl`` (not POSIX) or a writable cache, it runs
    without one. Ctrl-C while waiting ends the wait."""
    wait = LOCK_WAIT if wait is None else wait
    try:
        import fcntl
    except ImportError:
        fcntl = None
    fd = None
    folder = cache_dir() / "locks"
    path = folder / f"{name}.lock"
    if fcntl is not None and _LOCK.fullmatch(path.name):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
        except OSError:
            fd = None
    try:
        if fd is not None:
            deadline = time.monotonic() + wait
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        break
                    time.sleep(0.05)
                except OSError:
                    break
        yield
    finally:
        if fd is not None:
            # nothing left behind (a full disk's cache stays empty): the file, then the folder if empty.
            # A process already waiting on this file takes it next; one arriving now makes a new file:
            # both then look in the cache again, so at worst a library is compiled twice, as without a lock
            with contextlib.suppress(OSError):
                path.unlink()
            os.close(fd)                    # releases the lock
            with contextlib.suppress(OSError):
                folder.rmdir()


def result_lock(kind: str, key: str, wait: float | None = None):
    """:func:`compile_lock` for the result of ``kind`` under ``key``
    (``locks/result_HASH.lock``): a process about to compute a result another
    is computing waits, then reads it (:func:`load_result`)."""
    return compile_lock(_result_name(kind, key).removesuffix(".json"), wait)


def _result_name(kind: str, key: str) -> str:
    return "result_" + hashlib.sha256(f"{kind}\0{key}".encode()).hexdigest()[:40] + ".json"


def load_result(kind: str, key: str) -> dict | None:
    """The result of ``kind`` stored under ``key`` (:func:`store_result`), or
    None: not stored, or a file that is damaged or holds another key (a
    hash collision) is no result. Marks it used."""
    name = _result_name(kind, key)
    for folder in cache_folders():
        path = folder / "results" / name
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError, UnicodeDecodeError):
            continue
        if isinstance(data, dict) and data.get("kind") == kind and data.get("key") == key \
                and isinstance(data.get("value"), dict):
            mark_used(path)
            return data["value"]
    return None


def store_result(kind: str, key: str, value: dict) -> bool:
    """Keep ``value`` (JSON-serialisable) as the result of ``kind`` under
    ``key`` in the cache, by :func:`write_staged`, then prune the results
    (:func:`prune_results`). A cache that cannot be written (read-only, a
    full disk) keeps nothing: the result is recomputed next time. Returns
    whether it was stored."""
    folder = cache_dir() / "results"
    try:
        write_staged([(folder / _result_name(kind, key),
                       json.dumps({"kind": kind, "key": key, "value": value}).encode())])
    except OSError:
        return False
    prune_results(folder)
    return True


def results_enabled() -> bool:
    """Whether analysis results are kept (``TMTCONTROL_RESULT_CACHE``, default
    on; ``0``, ``off``, ``no`` or ``false`` turns it off)."""
    return os.environ.get("TMTCONTROL_RESULT_CACHE", "1").strip().lower() not in ("0", "off", "no", "false")


def kept_result(kind: str, key: str | None, compute, dump, load):
    """``compute()``, kept in the results under ``(kind, key)``: read if
    stored (``load(stored dict)``; a stored value ``load`` refuses with
    TypeError, ValueError or KeyError, another layout, is computed again),
    else computed under :func:`result_lock` (a process that needs it while
    another computes it waits, then reads it) and stored as ``dump(value)``
    (a JSON-serialisable dict; ``dump`` may return None: not kept). Without a
    ``key`` or with :func:`results_enabled` false it is just ``compute()``."""
    if key is None or not results_enabled():
        return compute()

    def stored():
        found = load_result(kind, key)
        try:
            return None if found is None else load(found)
        except (TypeError, ValueError, KeyError):
            return None

    if (value := stored()) is not None:
        return value
    with result_lock(kind, key):
        if (value := stored()) is not None:
            return value
        value = compute()
        if (data := dump(value)) is not None:
            store_result(kind, key, data)
    return value


_DIGEST: list[str] = []


def package_digest() -> str:
    """SHA-256 of the package's Python sources (computed once per process):
    any change of the code gives new cache keys."""
    if not _DIGEST:
        root = pathlib.Path(__file__).resolve().parent
        h = hashlib.sha256()
        for f in sorted(root.rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
        _DIGEST.append(h.hexdigest())
    return _DIGEST[0]


def _results(folder: pathlib.Path) -> list[tuple[pathlib.Path, float]]:
    """``(result file, last use)`` of the results in ``folder``."""
    out = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return out
    for e in entries:
        if _RESULT.fullmatch(e.name) and e.is_file(follow_symlinks=False):
            try:
                out.append((pathlib.Path(e.path), e.stat(follow_symlinks=False).st_mtime))
            except OSError:
                continue
    return out


def prune_results(folder: pathlib.Path, max_results: int | None = None, max_age_days: float | None = None,
                  now: float | None = None) -> int:
    """Remove from a results ``folder`` the results unused for
    ``max_age_days`` (default :data:`MAX_AGE_DAYS`), then the least recently
    used beyond ``max_results`` (default :data:`MAX_RESULTS`), and staged
    results older than an hour; returns how many results went."""
    max_results = MAX_RESULTS if max_results is None else max_results
    max_age = (MAX_AGE_DAYS if max_age_days is None else max_age_days) * 86400.0
    now = time.time() if now is None else now
    _remove_stale_staged(folder, _RESULT_STAGED, now)
    removed = 0
    for i, (path, used) in enumerate(sorted(_results(folder), key=lambda t: t[1], reverse=True)):
        if i >= max_results or now - used > max_age:
            try:
                path.unlink()
                removed += 1
            except OSError:
                pass
    return removed


def mark_used(lib: pathlib.Path) -> None:
    """Record that ``lib`` was used now (its mtime), for :func:`prune`; a
    read-only cache is left as it is."""
    try:
        os.utime(lib)
    except OSError:
        pass


def _libraries(folder: pathlib.Path) -> list[tuple[pathlib.Path, int, float]]:
    """``(library, bytes with its sidecar, last use)`` of tmtcontrol's libraries in ``folder``."""
    out = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return out
    names = {e.name for e in entries}
    for e in entries:
        if not _LIBRARY.fullmatch(e.name) or not e.is_file(follow_symlinks=False):
            continue
        try:
            st = e.stat(follow_symlinks=False)
        except OSError:
            continue
        size = st.st_size
        side = e.name[:-3] + ".json"
        if side in names:
            try:
                size += os.lstat(os.path.join(folder, side)).st_size
            except OSError:
                pass
        out.append((pathlib.Path(e.path), size, st.st_mtime))
    return out


def _remove_library(lib: pathlib.Path) -> None:
    for p in (lib, _sidecar(lib)):
        try:
            p.unlink()
        except FileNotFoundError:
            pass


def prune(folder: pathlib.Path, keep: tuple[pathlib.Path, ...] = (), max_bytes: int | None = None,
          max_age_days: float | None = None, now: float | None = None) -> list[pathlib.Path]:
    """Remove from ``folder`` staged files older than an hour, libraries
    unused for ``max_age_days`` (default :data:`MAX_AGE_DAYS`), then the least
    recently used until the rest take at most ``max_bytes`` (default
    :data:`MAX_BYTES`); never a library in ``keep``, nor a sidecar whose
    library stays, nor any file tmtcontrol does not name. Returns the
    libraries removed."""
    max_bytes = MAX_BYTES if max_bytes is None else max_bytes
    max_age = (MAX_AGE_DAYS if max_age_days is None else max_age_days) * 86400.0
    now = time.time() if now is None else now
    keep = {pathlib.Path(k).resolve() for k in keep}
    _remove_stale_staged(folder, _STAGED, now)
    removed = []
    libs = sorted(_libraries(folder), key=lambda t: t[2], reverse=True)      # most recently used first
    total, full = 0, False
    for lib, size, used in libs:
        full = full or total + size > max_bytes           # from here on, every older library goes
        if lib.resolve() not in keep and (now - used > max_age or full):
            try:
                _remove_library(lib)
                removed.append(lib)
            except OSError:
                total += size
            continue
        total += size
    return removed


_BUILD_LITTER = re.compile(r"tmtcontrol-(cg|lib|robot|sil)-[A-Za-z0-9_]+")
"""Temporary folders of older versions, which built in the temporary folder
itself: ``tmtcontrol-cg-*`` (a rollout), ``-robot-*`` (a robot's Functions),
``-sil-*`` (an exported controller, kept for the run) and ``-lib-*`` (a
private library of a run with an unwritable cache)."""

_BUILD = re.compile(r"tmtcontrol-build-[a-z]+-([0-9]+)-([0-9]+)-[A-Za-z0-9_]+")
"""A build folder of :func:`new_build_folder`: its owner's pid and start time."""

_LIVE: dict[pathlib.Path, int] = {}
"""The build folders this process made and has not removed, with the pid that
made them (removed at its exit; a forked child inherits the record, not the folders)."""


def _start_time(pid: int) -> int:
    """The process' start time (clock ticks since boot, from /proc), or 0 where unknown."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return int(fh.read().rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return 0


def _owner_alive(pid: int, start: int) -> bool:
    """The process ``pid`` started at ``start`` still runs (a reused pid is not it)."""
    if start and os.path.isdir("/proc/self"):
        return _start_time(pid) == start
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _build_roots() -> list[pathlib.Path]:
    """The folders holding build folders (besides the temporary folder, the
    last resort): ``CACHE/build`` and the per-user fallback's ``build``."""
    roots = [cache_dir() / "build"]
    fb = fallback_cache(create=False)
    if fb is not None:
        roots.append(fb / "build")
    return roots


def new_build_folder(kind: str) -> pathlib.Path:
    """A new private (0700) build folder for a compile of ``kind`` (a short
    lower-case word: ``"cg"``, ``"robot"``, ``"sil"``), with an empty
    ``tmp/`` for the compiler's temporaries (:func:`tmtcontrol.processes.run_compiler`).
    It is made under the cache (``CACHE/build``), else the per-user fallback,
    else the temporary folder, and named after this process (pid and start
    time), so that once this process has ended it is recognised as stale and
    removed (:func:`prune_temporary`). Removed by :func:`remove_build_folder`
    or, at the latest, when the interpreter exits; use :func:`build_folder`
    for a build whose products are not needed after a block. Earlier build
    folders whose owner has ended are removed first."""
    if not re.fullmatch(r"[a-z]+", kind):
        raise ValueError(f"kind: expected lower-case letters, got {kind!r}")
    _prune_build_folders()
    prefix = f"tmtcontrol-build-{kind}-{os.getpid()}-{_start_time(os.getpid())}-"
    # a full disk under the cache: build in the temporary folder (the library is then not cached);
    # an unwritable cache: the per-user fallback, made only if needed
    full = _free_bytes(cache_dir()) < BUILD_MIN_FREE
    path = None if full else _make_in(cache_dir() / "build", prefix)
    if path is None and not full and (fallback := fallback_cache()) is not None:
        path = _make_in(fallback / "build", prefix)
    if path is None:                                # no usable cache folder: the temporary folder
        path = pathlib.Path(tempfile.mkdtemp(prefix=prefix))
    _LIVE[path] = os.getpid()
    (path / "tmp").mkdir(mode=0o700)
    return path


BUILD_MIN_FREE = 64 * 2**20
"""Free space (bytes) the disk holding the cache needs for a build folder
there (the generated C of a 7-joint arm's step takes a few MiB, the
compiler's temporaries as much again); with less, the build runs in the
temporary folder and the library is not cached (a warning says so)."""


def _free_bytes(folder: pathlib.Path) -> float:
    """Free bytes for this user on the disk holding ``folder`` (its nearest
    existing parent); infinite where that cannot be read or the file system
    has no blocks (``/proc``: not a disk, so not full)."""
    for f in (folder, *folder.parents):
        try:
            st = os.statvfs(f)
        except FileNotFoundError:
            continue
        except (OSError, AttributeError):
            return float("inf")
        return st.f_bavail * st.f_frsize if st.f_blocks else float("inf")
    return float("inf")


def _make_in(root: pathlib.Path, prefix: str) -> pathlib.Path | None:
    """A new folder in ``root`` (made 0700 if needed; None if it is not private
    or cannot be written). Retried when another process removed ``root``,
    empty, between the two steps."""
    for _ in range(3):
        try:
            root.mkdir(mode=0o700, parents=True, exist_ok=True)
            if not _private(root):
                return None
            return pathlib.Path(tempfile.mkdtemp(prefix=prefix, dir=root))
        except FileNotFoundError:
            continue
        except OSError:
            return None
    return None


def _remove_tree(path: pathlib.Path) -> None:
    """Remove a build folder, then its ``build`` root if that is now empty."""
    shutil.rmtree(path, ignore_errors=True)
    if path.parent in _build_roots():
        try:
            path.parent.rmdir()
        except OSError:
            pass


def remove_build_folder(path: pathlib.Path) -> None:
    """Remove a build folder made by :func:`new_build_folder` (and only such a folder)."""
    path = pathlib.Path(path)
    if not _BUILD.fullmatch(path.name):
        raise ValueError(f"{path} is not a tmtcontrol build folder")
    _remove_tree(path)
    _LIVE.pop(path, None)


@atexit.register
def _remove_live() -> None:
    """At exit, this process' build folders (a library loaded from one has done its work)."""
    for path, pid in sorted(_LIVE.items()):
        if pid == os.getpid():
            _remove_tree(path)
    _LIVE.clear()


@contextlib.contextmanager
def build_folder(kind: str):
    """A block with a new build folder (:func:`new_build_folder`), removed when
    the block ends, however it ends (an error, Ctrl-C, SIGTERM under the
    command line's handlers); a library loaded from it keeps working."""
    path = new_build_folder(kind)
    try:
        yield path
    finally:
        remove_build_folder(path)


def _prune_build_folders() -> int:
    """Remove this user's build folders whose owner process has ended."""
    removed = 0
    for root in [*_build_roots(), pathlib.Path(tempfile.gettempdir())]:
        try:
            entries = list(os.scandir(root))
        except OSError:
            continue
        for e in entries:
            m = _BUILD.fullmatch(e.name)
            if m is None or _owner_alive(int(m.group(1)), int(m.group(2))):
                continue
            try:
                st = e.stat(follow_symlinks=False)
            except OSError:
                continue
            if stat.S_ISDIR(st.st_mode) and (not hasattr(os, "getuid") or st.st_uid == os.getuid()):
                _remove_tree(pathlib.Path(e.path))
                removed += 1
    return removed


def prune_temporary(max_age_days: float = 1.0, now: float | None = None) -> int:
    """Remove this user's compile litter: build folders whose owner has ended
    (:func:`new_build_folder`, whatever their age), and the temporary folders
    of older versions (see :data:`_BUILD_LITTER`) older than
    ``max_age_days`` (a build takes minutes at most; a library already loaded
    keeps working without its file). Returns how many."""
    now = time.time() if now is None else now
    removed = _prune_build_folders()
    try:
        entries = list(os.scandir(tempfile.gettempdir()))
    except OSError:
        return removed
    for e in entries:
        if not _BUILD_LITTER.fullmatch(e.name):
            continue
        try:
            st = e.stat(follow_symlinks=False)
        except OSError:
            continue
        mine = not hasattr(os, "getuid") or st.st_uid == os.getuid()
        if stat.S_ISDIR(st.st_mode) and mine and now - st.st_mtime > max_age_days * 86400.0:
            shutil.rmtree(e.path, ignore_errors=True)
            removed += 1
    return removed


def cache_info() -> dict:
    """Path, number of libraries and their size (bytes, sidecars included)
    of the cache and of the per-user fallback if it exists."""
    out = []
    for folder in cache_folders():
        libs = _libraries(folder)
        results = _results(folder / "results")
        size = sum(s for _, s, _ in libs)
        for path, _ in results:
            try:
                size += path.stat().st_size
            except OSError:
                pass
        entry = {"path": str(folder), "libraries": len(libs), "results": len(results), "bytes": size}
        if folder.exists() and not folder.is_dir():
            entry["problem"] = "not a folder"
        out.append(entry)
    return {"folders": out, "max_bytes": MAX_BYTES, "max_results": MAX_RESULTS, "max_age_days": MAX_AGE_DAYS}


def _remove_named(folder: pathlib.Path, names: tuple, counted=None) -> tuple[int, int]:
    """Remove the files in ``folder`` whose names match one of ``names``
    (compiled patterns); ``(how many matched counted, bytes removed)``."""
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return 0, 0
    count = size = 0
    for e in entries:
        if not any(p.fullmatch(e.name) for p in names) or not e.is_file(follow_symlinks=False):
            continue
        try:
            n = e.stat(follow_symlinks=False).st_size
            os.unlink(e.path)
        except FileNotFoundError:
            continue
        count += counted is not None and counted.fullmatch(e.name) is not None
        size += n
    return count, size


def _remove_stale_staged(folder: pathlib.Path, staged, now: float) -> None:
    """Remove the staged files (``staged``: their name pattern) in ``folder``
    older than an hour: a write that was killed."""
    try:
        for e in os.scandir(folder):
            if staged.fullmatch(e.name) and e.is_file(follow_symlinks=False) \
                    and now - e.stat(follow_symlinks=False).st_mtime > _STALE_TMP_SECONDS:
                pathlib.Path(e.path).unlink(missing_ok=True)
    except OSError:
        pass


def clear_cache() -> dict:
    """Remove every file tmtcontrol put in its cache folders (libraries,
    sidecars, staged files), the build folders of ended processes and the
    temporary folders of older versions (:func:`prune_temporary`, whatever
    their age); anything else stays (a running build keeps its folder).
    Returns the counts."""
    prune_temporary(max_age_days=0.0)
    count = size = results = 0
    for folder in cache_folders():
        n, b = _remove_named(folder, (_LIBRARY, _SIDECAR, _STAGED), counted=_LIBRARY)
        count, size = count + n, size + b
        _remove_named(folder / "locks", (_LOCK,))
        n, b = _remove_named(folder / "results", (_RESULT, _RESULT_STAGED), counted=_RESULT)
        results, size = results + n, size + b
    return {"libraries": count, "results": results, "bytes": size}


def _mib(n: int) -> str:
    return f"{n / 2**20:,.1f} MiB"


def format_cache_info(info: dict) -> str:
    """The lines ``tmtcontrol cache --info`` prints."""
    lines = []
    for i, f in enumerate(info["folders"]):
        label = "cache" if i == 0 else "fallback (the cache was not writable)"
        if f.get("problem"):
            lines.append(f"{label}: {f['path']}: {f['problem']}: nothing is cached there; compiled code goes to "
                         "the per-user fallback")
            continue
        lines.append(f"{label}: {f['path']}: {f['libraries']} librar{'y' if f['libraries'] == 1 else 'ies'}, "
                     f"{f.get('results', 0)} analysis result{'' if f.get('results', 0) == 1 else 's'}, "
                     f"{_mib(f['bytes'])}")
    lines.append(f"bound: {_mib(info['max_bytes'])} of libraries and {info.get('max_results', MAX_RESULTS):,} results "
                 f"per folder, anything unused for {info['max_age_days']} days removed (least recently used first)")
    return "\n".join(lines)
