"""Output folders that never destroy a user's files; JSON helpers; versions.

Every command that writes goes through :class:`OutputFolder`:

* the target is checked, and a private staging folder created beside it,
  **before** anything is computed, so an unwritable target (``/proc/x``, a
  path below a regular file, a read-only folder) fails at once;
* the outputs are written into the staging folder, together with a manifest
  :data:`MANIFEST` naming every file written;
* on success the staging folder replaces the target in one rename. An existing
  target is replaced only if it is empty or a previous tmtcontrol output (it
  holds a manifest and nothing that the manifest does not list); anything else
  is refused, naming the flag (``--out``, ``--plot``), with nothing touched;
* on any error, Ctrl-C or SIGTERM the staging folder is removed.

Errors are :class:`OutputError` (a ``ValueError``: exit code 2 in the CLI).
"""

from __future__ import annotations

import errno
import json
import os
import pathlib
import shutil
import signal
import sys
import tempfile


__all__ = ["MANIFEST", "OutputError", "OutputFolder", "Interrupted", "VerdictFailed", "install_signal_handlers",
           "check_interrupt", "versions", "jsonable", "write_json"]

MANIFEST = ".tmtcontrol-output.json"
"""The file that marks a folder as written by tmtcontrol, listing its files."""


class OutputError(ValueError):
    """An output target that cannot or must not be written; names the flag."""


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


def _handler(signum, frame):
    _pending.append(signum)
    raise Interrupted(signum)


def install_signal_handlers() -> None:
    """SIGINT and SIGTERM raise :class:`Interrupted` and are remembered, so a
    library that swallows the exception (CasADi stops IPOPT on Ctrl-C and
    reports a solver failure) can be followed by :func:`check_interrupt`."""
    _pending.clear()
    signal.signal(signal.SIGINT, _handler)
    signal.signal(signal.SIGTERM, _handler)


def check_interrupt() -> None:
    """Raise :class:`Interrupted` if a signal arrived since the handlers were installed."""
    if _pending:
        raise Interrupted(_pending[-1])


def _listing(folder: pathlib.Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


def _manifest_files(folder: pathlib.Path) -> set[str] | None:
    """Files listed by ``folder``'s manifest, or None if it has no valid one."""
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("written_by") != "tmtcontrol":
        return None
    files = data.get("files")
    return set(files) if isinstance(files, list) and all(isinstance(f, str) for f in files) else None


def _replaceable(out: pathlib.Path, flag: str) -> None:
    """Raise unless ``out`` may be replaced as a whole (absent, empty, or a
    previous tmtcontrol output holding only the files it wrote)."""
    if not out.exists() and not out.is_symlink():
        return
    if out.is_symlink() or not out.is_dir():
        raise OutputError(f"{flag}: {out} exists and is not a folder; choose a new folder name")
    try:
        names = _listing(out)
    except OSError as exc:
        raise OutputError(f"{flag}: cannot read {out} ({exc.strerror})") from None
    if not names:
        return
    listed = _manifest_files(out)
    if listed is None:
        raise OutputError(f"{flag}: {out} is a folder that tmtcontrol did not write and is not empty; "
                          "choose a new or empty folder (nothing was written)")
    foreign = sorted(names - listed - {MANIFEST})
    if foreign:
        shown = ", ".join(foreign[:3]) + (" ..." if len(foreign) > 3 else "")
        raise OutputError(f"{flag}: {out} holds files tmtcontrol did not write ({shown}); "
                          "move them or choose another folder (nothing was written)")


class OutputFolder:
    """A staging folder that becomes ``out`` on :meth:`commit`.

    Create it before computing anything: the constructor checks the target and
    makes the staging folder, raising :class:`OutputError` naming ``flag``.
    Use as a context manager; leaving it by an exception removes the staging
    folder and leaves ``out`` as it was.

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
        self.out = pathlib.Path(os.path.abspath(os.path.expanduser(str(out))))
        if self.out.parent == self.out:
            raise OutputError(f"{flag}: {self.out} is a file system root; name a folder inside it")
        _replaceable(self.out, flag)
        parent = self.out.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self.path = pathlib.Path(tempfile.mkdtemp(prefix=f".{self.out.name}.tmt-", dir=parent))
        except OSError as exc:
            raise OutputError(f"{flag}: cannot write {self.out} "
                              f"({exc.strerror or exc.__class__.__name__})") from None
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(self.path, 0o777 & ~umask)   # mkdtemp makes 0700; the result is an ordinary folder
        self.committed = False

    def __enter__(self) -> "OutputFolder":
        return self

    def __exit__(self, exc_type, exc, tb):
        if not self.committed:
            self.discard()
        return False

    def discard(self) -> None:
        """Remove the staging folder (the target is untouched)."""
        shutil.rmtree(self.path, ignore_errors=True)

    def commit(self, command: str = "") -> pathlib.Path:
        """Write the manifest and rename the staging folder onto the target.

        Another process may commit the same target at the same moment: the
        target is re-checked and moved aside before each rename attempt.
        A signal that arrived meanwhile (even one a compiled library
        swallowed) stops the commit: an interrupted run is never a result."""
        from . import __version__

        check_interrupt()
        files = sorted(_listing(self.path))
        (self.path / MANIFEST).write_text(json.dumps(
            {"written_by": "tmtcontrol", "version": __version__, "command": command or " ".join(sys.argv),
             "files": files}, indent=2) + "\n", encoding="utf-8")
        for _ in range(20):
            _replaceable(self.out, self.flag)
            old = None
            try:
                if self.out.exists():
                    old = pathlib.Path(tempfile.mkdtemp(prefix=f".{self.out.name}.old-", dir=self.out.parent))
                    os.replace(self.out, old / "previous")
                os.replace(self.path, self.out)
            except FileNotFoundError:
                continue                      # another process moved it first: check again
            except OSError as exc:
                if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                    continue                  # another process committed in between: check again
                raise OutputError(f"{self.flag}: cannot write {self.out} ({exc.strerror})") from None
            finally:
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
            self.committed = True
            return self.out
        raise OutputError(f"{self.flag}: {self.out} keeps changing (another process is writing it)")


def versions() -> dict:
    """Versions of Python and of the packages a result depends on: the loaded
    module's own version if it is imported, else the installed metadata
    (importing python-control only to ask would take ~1 s)."""
    from importlib.metadata import PackageNotFoundError, version

    from . import __version__

    out = {"tmtcontrol": __version__, "python": sys.version.split()[0]}
    for name in ("casadi", "control", "numpy", "scipy", "matplotlib", "pydantic"):
        try:
            out[name] = getattr(sys.modules.get(name), "__version__", None) or version(name)
        except PackageNotFoundError:  # pragma: no cover
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
    """JSON with NaN/inf written as null and NumPy types converted."""
    pathlib.Path(path).write_text(json.dumps(jsonable(obj), indent=2) + "\n", encoding="utf-8")
