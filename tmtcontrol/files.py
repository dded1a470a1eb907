"""Output folders that never destroy a user's files; JSON helpers; versions.

Every command that writes goes through :class:`OutputFolder`:

* the target is checked, and a private staging folder ``.NAME.tmt-*``
  created beside it, **before** anything is computed, so an unwritable target
  (``/proc/x``, a path below a regular file, a read-only folder) fails at once;
* the outputs are written into the staging folder; on commit a manifest
  :data:`MANIFEST` records every file written, in every sub-folder, with its
  size and SHA-256;
* on success the staging folder replaces the target in one rename. An existing
  target is replaced only if it is empty or a previous tmtcontrol output whose
  files are exactly those its manifest lists, unchanged (no other file or
  folder anywhere, hidden ones included; no symbolic link). Anything else is
  refused, naming the flag (``--out``, ``--plot``) and the first file that is
  not tmtcontrol's, with nothing touched. The target is checked again at
  commit, so a file saved into it during the run is never deleted;
* the check, the staging folder's creation and the commit hold an exclusive
  lock (``flock``) on the parent folder, so concurrent runs into one target
  commit one after the other (the last one wins);
* on any error, Ctrl-C or SIGTERM the staging folder is removed, and so are
  the parent folders the run created. Staging folders left by a killed run
  (their owner process, recorded beside it, is gone) are removed by the next run
  into the same target.

Errors: :class:`OutputError` (a ``ValueError``: bad input, exit code 2 in the
CLI) for a target that must not or cannot be written; :class:`OutputNotSaved`
(exit code 3) when the results were computed but could not be saved: the disk
is full, or the target changed during the run.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import pathlib
import re
import shutil
import signal
import socket
import sys
import tempfile

try:                                  # POSIX; elsewhere commits are not serialised
    import fcntl
except ImportError:                   # pragma: no cover
    fcntl = None


__all__ = ["MANIFEST", "MANIFEST_FORMAT", "NOT_SAVED_EXIT", "OutputError", "OutputNotSaved", "OutputFolder",
           "Interrupted", "VerdictFailed", "install_signal_handlers", "restore_signal_handlers", "check_interrupt",
           "versions", "jsonable", "write_json", "disk_full", "committed_outputs"]

MANIFEST = ".tmtcontrol-output.json"
"""The file that marks a folder as written by tmtcontrol, listing its files."""

MANIFEST_FORMAT = "tmtcontrol-output/2"
"""The manifest's ``format``: only a manifest with this signature (and
``"written_by": "tmtcontrol"``) makes a folder replaceable. Version 1 (before
0.x: top-level names, no hashes) cannot show whether a file was changed, so a
folder it describes counts as foreign."""

NOT_SAVED_EXIT = 3
"""The CLI's exit code for :class:`OutputNotSaved`."""

_OWNER = ".owner"
"""Beside a staging folder ``.NAME.tmt-XXXX`` while it is being written, as
``.NAME.tmt-XXXX.owner``: the owner process (host, boot, pid, start time), so
a later run can tell a live staging folder from the litter of a killed one.
Outside the folder, so the outputs never see it; removed with the folder or
after the commit."""


class OutputError(ValueError):
    """An output target that cannot or must not be written; names the flag."""


class OutputNotSaved(RuntimeError):
    """The results were computed but could not be saved (a full disk, or the
    target changed during the run): the staging folder is removed and the
    target left as it was. The CLI prints the one-line message and exits
    :data:`NOT_SAVED_EXIT` (3): not bad input (2), not a failed verdict (1)."""


class VerdictFailed(RuntimeError):
    """A computed verdict failed (a diverged simulation, an infeasible
    design): the CLI prints the message on one line and exits 1. Lives here,
    with the other exit-code exceptions, so the CLI can catch it without
    importing the analysis stack."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (SIGINT) or SIGTERM; ``exit_code`` is 130 or 143."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__()
        self.signum = signum
        self.exit_code = 128 + int(signum)


_pending: list[int] = []
_deferring: list[int] = []


def _handler(signum, frame):
    _pending.append(signum)
    if not _deferring:
        raise Interrupted(signum)


def install_signal_handlers() -> tuple:
    """SIGINT and SIGTERM raise :class:`Interrupted` and are remembered, so a
    library that swallows the exception (CasADi stops IPOPT on Ctrl-C and
    reports a solver failure) can be followed by :func:`check_interrupt`.
    Main thread only; returns the previous handlers for
    :func:`restore_signal_handlers`."""
    previous = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    _pending.clear()
    signal.signal(signal.SIGINT, _handler)
    signal.signal(signal.SIGTERM, _handler)
    return previous


def restore_signal_handlers(previous: tuple) -> None:
    """Put back the handlers :func:`install_signal_handlers` replaced and
    forget the signals it remembered (they were acted on), so a later
    :class:`OutputFolder` in the same process is not stopped by them."""
    signal.signal(signal.SIGINT, previous[0])
    signal.signal(signal.SIGTERM, previous[1])
    _pending.clear()


def check_interrupt() -> None:
    """Raise :class:`Interrupted` if a signal arrived since the handlers were installed."""
    if _pending:
        raise Interrupted(_pending[-1])


@contextlib.contextmanager
def _signals_deferred():
    """A block that runs whole: a signal arriving meanwhile is remembered and
    raised just after it (a staging folder is never made without its name
    being recorded; a commit never leaves the previous output moved aside
    with the new one discarded). This is done by the handlers of
    :func:`install_signal_handlers` (the command line's), so it holds
    whichever thread the kernel hands the signal to (a BLAS thread, a
    watchdog). Blocking the signals in this thread instead would not: the
    kernel would hand them to another thread, to be acted on whenever that
    thread next runs, possibly after the block. Under other handlers (a
    library caller's KeyboardInterrupt) a signal is raised where it lands;
    the command line's net (:func:`staging_removed_on_exit`) is not there
    either."""
    _deferring.append(1)
    try:
        yield
    finally:
        _deferring.pop()
    check_interrupt()


_unsaved: set[pathlib.Path] = set()
"""The staging folders this process made and has neither committed nor removed."""

_committed: list[str] = []
"""The output folders this process has committed (as the user named them),
in order: what a Ctrl-C after a commit must not call "nothing was written"."""


def committed_outputs(reset: bool = False) -> list[str]:
    """The output folders committed so far (:data:`_committed`); ``reset``
    empties the record (each command line starts from none)."""
    out = list(_committed)
    if reset:
        _committed.clear()
    return out


@contextlib.contextmanager
def staging_removed_on_exit():
    """Remove, when the block ends (however it ends), every staging folder
    made inside it and not committed: the net under :class:`OutputFolder`'s
    own clean-up for a signal that lands between the constructor's return and
    ``with`` (the CLI runs each command inside it). Folders made before the
    block are left alone."""
    before = set(_unsaved)
    try:
        yield
    finally:
        for path in sorted(_unsaved - before):
            _remove_staging(path)


def _remove_staging(path: pathlib.Path) -> None:
    """Remove a staging folder and its owner record; forget it."""
    shutil.rmtree(path, ignore_errors=True)
    try:
        _owner_file(path).unlink(missing_ok=True)
    except OSError:
        pass
    _unsaved.discard(path)


# -- what is in a folder ----------------------------------------------------------

def _walk(folder: pathlib.Path, prefix: str = ""):
    """``(relative path, kind)`` of everything below ``folder``, sorted, links
    not followed; kind is ``dir``, ``file``, ``link`` or ``other``."""
    with os.scandir(folder) as it:
        entries = sorted(it, key=lambda e: e.name)
    for e in entries:
        rel = prefix + e.name
        if e.is_symlink():
            yield rel, "link"
        elif e.is_dir(follow_symlinks=False):
            yield rel, "dir"
            yield from _walk(pathlib.Path(e.path), rel + "/")
        elif e.is_file(follow_symlinks=False):
            yield rel, "file"
        else:
            yield rel, "other"


def _sha256(path: pathlib.Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return h.hexdigest()


_HEX64 = re.compile(r"[0-9a-f]{64}")


def _read_manifest(folder: pathlib.Path) -> tuple[dict | None, str]:
    """``(manifest, "")`` for tmtcontrol's own manifest (format
    :data:`MANIFEST_FORMAT`), else ``(None, why)``."""
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None, "is a folder tmtcontrol did not write and is not empty"
    if not isinstance(data, dict) or data.get("written_by") != "tmtcontrol":
        return None, "is a folder tmtcontrol did not write and is not empty"
    if data.get("format") != MANIFEST_FORMAT:
        return None, ("was written by an older tmtcontrol whose manifest cannot show whether its files were "
                      "changed; delete it yourself if it holds nothing of yours")
    files, folders = data.get("files"), data.get("folders")
    ok = (isinstance(files, dict) and isinstance(folders, list) and all(isinstance(f, str) for f in folders)
          and all(isinstance(k, str) and isinstance(v, dict) and isinstance(v.get("size"), int)
                  and isinstance(v.get("sha256"), str) and _HEX64.fullmatch(v["sha256"])
                  for k, v in files.items()))
    if not ok:
        return None, "holds a damaged tmtcontrol manifest, so its files cannot be checked"
    return data, ""


def _foreign(out: pathlib.Path, shown: str) -> str | None:
    """None if ``out`` may be replaced as a whole (absent, empty, or a previous
    tmtcontrol output holding exactly the files its manifest lists, unchanged),
    else the reason, naming the first offending path as ``shown/...``."""
    if not os.path.lexists(out):
        return None
    if out.is_symlink():
        return f"{shown} is a symbolic link (tmtcontrol replaces only a folder it wrote, never a link)"
    if not out.is_dir():
        return f"{shown} exists and is not a folder"
    try:
        if not any(out.iterdir()):
            return None
        manifest, why = _read_manifest(out)
        if manifest is None:
            return f"{shown} {why}"
        files, folders = manifest["files"], set(manifest["folders"])
        for rel, kind in _walk(out):
            path = f"{shown.rstrip('/')}/{rel}"
            if rel == MANIFEST:
                continue
            if kind == "link":
                return f"{path} is a symbolic link tmtcontrol did not write"
            if kind == "dir":
                if rel not in folders:
                    return f"{path}/ is a folder tmtcontrol did not write"
            elif kind != "file" or rel not in files:
                return f"{path} is not a file tmtcontrol wrote"
            else:
                entry = files[rel]
                if (out / rel).stat().st_size != entry["size"] or _sha256(out / rel) != entry["sha256"]:
                    return f"{path} was changed after tmtcontrol wrote it"
    except OSError as exc:
        if disk_full(exc):
            raise
        return f"{shown} cannot be read ({exc.strerror or exc}), so it cannot be checked"
    return None


def _manifest_of(folder: pathlib.Path, command: str) -> dict:
    from . import __version__

    files, folders = {}, []
    for rel, kind in _walk(folder):
        if rel == MANIFEST:
            continue
        if kind == "dir":
            folders.append(rel)
        elif kind == "file":
            files[rel] = {"size": (folder / rel).stat().st_size, "sha256": _sha256(folder / rel)}
        else:                         # never written by tmtcontrol's writers
            raise OutputError(f"{rel}: a {kind} in the output; tmtcontrol writes only files and folders")
    return {"written_by": "tmtcontrol", "format": MANIFEST_FORMAT, "version": __version__,
            "command": command or " ".join(sys.argv), "folders": folders, "files": files}


# -- who owns a staging folder ------------------------------------------------------

def _proc_stat(pid: int) -> tuple[str, str] | None:
    """``(state, start time in clock ticks since boot)`` from /proc, or None."""
    try:
        fields = pathlib.Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return fields[0], fields[19]
    except (OSError, IndexError):
        return None


def _boot_id() -> str | None:
    try:
        return pathlib.Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return None


def _owner_record() -> dict:
    st = _proc_stat(os.getpid())
    return {"host": socket.gethostname(), "boot": _boot_id(), "pid": os.getpid(), "start": st and st[1]}


def _owner_gone(record) -> bool:
    """True only when the process that made a staging folder is certainly gone:
    same host, and another boot, or no such process, or a zombie, or a
    different process under the same pid (its start time differs)."""
    if not isinstance(record, dict) or record.get("host") != socket.gethostname():
        return False
    boot = _boot_id()
    if record.get("boot") and boot and record["boot"] != boot:
        return True
    pid = record.get("pid")
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:           # alive, another user's
        pass
    st = _proc_stat(pid)
    if st is None:
        return False
    return st[0] == "Z" or (record.get("start") is not None and st[1] != record["start"])


def _owner_file(staging: pathlib.Path) -> pathlib.Path:
    return staging.with_name(staging.name + _OWNER)


def _write_owner(staging: pathlib.Path) -> None:
    _owner_file(staging).write_text(json.dumps(_owner_record()), encoding="utf-8")


def _clean_stale(parent: pathlib.Path, name: str) -> None:
    """Remove ``.NAME.tmt-*`` staging folders beside the target whose owner is
    gone, and ``.NAME.tmt-*.old`` folders (a previous output moved aside by a
    commit) whose staging folder no longer exists."""
    prefix = _staging_prefix(name)
    try:
        entries = [p for p in parent.iterdir() if p.name.startswith(prefix)]
    except OSError:
        return
    for p in entries:
        if p.name.endswith(_OWNER):
            if not p.is_symlink() and p.is_file() and not os.path.lexists(p.with_name(p.name[:-len(_OWNER)])):
                p.unlink(missing_ok=True)             # its folder is gone (committed or removed)
            continue
        if p.is_symlink() or not p.is_dir():
            continue
        if p.name.endswith(".old"):
            stale = not os.path.lexists(p.with_name(p.name[:-4]))
        else:
            try:
                stale = _owner_gone(json.loads(_owner_file(p).read_text(encoding="utf-8")))
            except (OSError, ValueError):
                stale = False         # no record: it cannot be told from a live one
        if stale:
            shutil.rmtree(p, ignore_errors=True)
            _owner_file(p).unlink(missing_ok=True)


def _staging_prefix(name: str) -> str:
    """``.NAME.tmt-``, the prefix of the staging folders of the target ``NAME``;
    a name longer than 200 bytes is cut and a hash of it added, so the staging
    folder's name (8 random characters, ``.old``, ``.owner`` added) stays within
    the 255 bytes a file name may have."""
    raw = os.fsencode(name)
    if len(raw) > 200:
        name = raw[:180].decode("utf-8", "ignore") + "~" + hashlib.sha256(raw).hexdigest()[:12]
    return f".{name}.tmt-"


@contextlib.contextmanager
def _locked(folder: pathlib.Path):
    """An exclusive ``flock`` on ``folder`` itself (no lock file left behind);
    where the file system cannot lock a folder, unlocked."""
    fd = None
    if fcntl is not None:
        try:
            fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:
            pass
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)


def disk_full(exc: BaseException) -> str | None:
    """If ``exc`` (or an exception it was raised from) is a full disk or an
    exceeded quota (ENOSPC, EDQUOT, also when a library or a worker process
    only kept the message), its message, else None."""
    texts = [os.strerror(errno.ENOSPC), os.strerror(getattr(errno, "EDQUOT", errno.ENOSPC))]
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", None)):
            return exc.strerror or texts[0]
        text = str(exc)
        for t in texts:
            if t in text:
                return t
        exc = exc.__cause__ or exc.__context__
    return None


def _file_on_the_way(path: pathlib.Path) -> pathlib.Path | None:
    """The first of ``path``'s parents that exists and is not a folder (the
    reason "File exists" or "Not a directory" alone would hide), else None."""
    for parent in reversed(path.parents):
        if parent.exists() and not parent.is_dir():
            return parent
    return None


class OutputFolder:
    """A staging folder that becomes ``out`` on :meth:`commit`.

    Create it before computing anything: the constructor checks the target and
    makes the staging folder, raising :class:`OutputError` naming ``flag``.
    Use as a context manager; leaving it by an exception removes the staging
    folder and leaves ``out`` as it was; a full disk is then reported as
    :class:`OutputNotSaved`.

    Examples
    --------
    >>> with OutputFolder("results", "--out") as folder:   # doctest: +SKIP
    ...     (folder.path / "a.txt").write_text("x")
    ...     folder.commit()
    """

    def __init__(self, out: str | os.PathLike, flag: str = "--out"):
        if out is None or not str(out).strip():
            raise OutputError(f"{flag}: empty path; name the output folder")
        self.flag = flag
        self.shown = str(out)
        self.out = pathlib.Path(os.path.abspath(os.path.expanduser(str(out))))
        self.committed = False
        self.path = None
        if self.out.parent == self.out:
            raise OutputError(f"{flag}: {self.out} is a file system root; name a folder inside it")
        try:
            here = os.path.realpath(os.getcwd())
        except OSError:                # the shell's folder was removed: nothing to protect
            here = None
        there = os.path.realpath(self.out)
        if here is not None and os.path.isdir(self.out) and (here == there or here.startswith(there + os.sep)):
            # replacing it would leave the shell (and any program) in a removed folder
            raise OutputError(f"{flag}: {self.shown} is the current folder or holds it; name a new folder "
                              "inside it (nothing was written)")
        if len(os.fsencode(self.out.name)) > 255:   # NAME_MAX: refused now, not when the results are ready
            raise OutputError(f"{flag}: cannot write {self.out} ({os.strerror(errno.ENAMETOOLONG)})")
        parent = self.out.parent
        self._made = []               # parent folders this run creates, deepest first
        p = parent
        while not os.path.lexists(p) and p.parent != p:
            self._made.append(p)
            p = p.parent
        try:
            for _ in range(5):        # a concurrent failed run may remove a parent it made just now
                try:
                    parent.mkdir(parents=True, exist_ok=True)
                    with _locked(parent):
                        reason = _foreign(self.out, self.shown)
                        if reason:
                            raise OutputError(f"{flag}: {reason}; choose another folder or move it "
                                              "(nothing was written)")
                        _clean_stale(parent, self.out.name)
                        with _signals_deferred():    # raised once the folder is known and recorded
                            self.path = pathlib.Path(tempfile.mkdtemp(prefix=_staging_prefix(self.out.name),
                                                                      dir=parent))
                            _unsaved.add(self.path)
                            umask = os.umask(0)
                            os.umask(umask)
                            os.chmod(self.path, 0o777 & ~umask)   # mkdtemp makes 0700; the result is ordinary
                            _write_owner(self.path)
                    break
                except FileNotFoundError:
                    if self.path is not None or os.path.isdir(parent):
                        raise
            else:
                raise OutputError(f"{flag}: cannot create {parent} (it keeps disappearing)")
        except OSError as exc:
            self.discard()
            if disk_full(exc):
                raise OutputNotSaved(self._full_message(exc)) from None
            blocker = _file_on_the_way(pathlib.Path(self.out))
            reason = f"{blocker} is not a folder" if blocker else exc.strerror or exc.__class__.__name__
            raise OutputError(f"{flag}: cannot write {self.out} ({reason})") from None
        except BaseException:
            self.discard()
            raise

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, exc_type, exc, tb):
        if not self.committed:
            self.discard()
            if exc is not None and not isinstance(exc, (KeyboardInterrupt, OutputNotSaved)) and disk_full(exc):
                raise OutputNotSaved(self._full_message(exc)) from None
        return False

    def _full_message(self, exc) -> str:
        where = self.shown
        name = getattr(exc, "filename", None)
        if isinstance(name, (str, os.PathLike)) and self.path is not None \
                and not os.path.abspath(name).startswith(str(self.path) + os.sep) \
                and os.path.abspath(name) != str(self.path):
            where = f"{self.shown} ({os.path.dirname(os.fspath(name)) or '.'} is full)"
        return (f"{self.flag}: no space left on the disk holding {where} ({disk_full(exc)}); free some space "
                f"and run again (the results were not saved; {self.shown} was left as it was)")

    def discard(self) -> None:
        """Remove the staging folder and the parent folders this run created
        (if they are empty); the target is untouched."""
        if self.path is not None:
            _remove_staging(self.path)
        for p in self._made:
            try:
                p.rmdir()
            except OSError:
                break

    def commit(self, command: str = "") -> pathlib.Path:
        """Write the manifest and rename the staging folder onto the target.

        Under the parent folder's lock the target is checked again (a file a
        user saved into it during the run makes it foreign:
        :class:`OutputNotSaved`), moved aside, replaced and the old copy
        removed. A signal that arrived before (even one a compiled library
        swallowed) stops the commit: an interrupted run is never a result."""
        check_interrupt()
        manifest = _manifest_of(self.path, command)
        (self.path / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
        parent = self.out.parent
        with _locked(parent):
            for _ in range(20):
                reason = _foreign(self.out, self.shown)
                if reason:
                    raise OutputNotSaved(f"{self.flag}: {self.shown} changed during the run: {reason}; the results "
                                         f"were not saved and {self.shown} was left as it was")
                aside = pathlib.Path(f"{self.path}.old")
                try:
                    with _signals_deferred():
                        try:
                            if os.path.lexists(self.out):
                                os.replace(self.out, aside)
                            os.replace(self.path, self.out)
                        except OSError as exc:
                            if os.path.lexists(aside) and not os.path.lexists(self.out):
                                os.replace(aside, self.out)          # put the previous output back
                            if exc.errno in (errno.ENOENT, errno.ENOTEMPTY, errno.EEXIST):
                                continue          # another (unlocked) writer changed it meanwhile: check again
                            if disk_full(exc):
                                raise
                            raise OutputNotSaved(f"{self.flag}: cannot write {self.shown} ({exc.strerror}); the "
                                                 "results were not saved") from None
                        self.committed = True
                        _committed.append(self.shown)
                        _unsaved.discard(self.path)
                finally:
                    if self.committed:        # also when a deferred signal is raised just now
                        _owner_file(self.path).unlink(missing_ok=True)
                        shutil.rmtree(aside, ignore_errors=True)
                return self.out
        raise OutputNotSaved(f"{self.flag}: {self.shown} keeps changing (another program is writing it); "
                             "the results were not saved")


def versions(more: tuple[str, ...] = ()) -> dict:
    """Versions of Python and of the packages a result depends on: the loaded
    module's own version if it is imported, else the installed metadata
    (importing python-control only to ask would take ~1 s). ``more``: further
    distributions by their PyPI name (the report's renderers, the URDF
    parser, MuJoCo), None where one is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    from . import __version__

    out = {"tmtcontrol": __version__, "python": sys.version.split()[0]}
    for name in ("casadi", "control", "numpy", "scipy", "matplotlib", "pydantic", *more):
        try:
            out[name] = getattr(sys.modules.get(name), "__version__", None) or version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


def jsonable(obj):
    """``obj`` with NumPy types converted and NaN/inf as None, for ``json.dumps``."""
    import numpy as np        # here, not at the top: the command line starts without NumPy

    def convert(obj):
        if isinstance(obj, dict):
            return {k: convert(v) for k, v in obj.items()}
        if isinstance(obj, (list, tuple)):
            return [convert(v) for v in obj]
        if isinstance(obj, (np.floating, float)):
            return float(obj) if np.isfinite(obj) else None
        if isinstance(obj, np.integer):
            return int(obj)
        if isinstance(obj, np.bool_):
            return bool(obj)
        if isinstance(obj, np.ndarray):
            return convert(obj.tolist())
        return obj

    return convert(obj)


def write_json(path: str | pathlib.Path, obj) -> None:
    """Strict JSON (RFC 8259): NumPy types converted, every NaN, +inf and -inf
    written as ``null`` (:func:`jsonable`); a non-finite number that reaches
    the encoder some other way raises ``ValueError`` rather than writing the
    invalid tokens ``NaN`` or ``Infinity``."""
    text = json.dumps(jsonable(obj), indent=2, allow_nan=False)
    pathlib.Path(path).write_text(text + "\n", encoding="utf-8")
