"""Output folders and files: atomic, and never destructive of a user's files;
JSON helpers and the versions recorded beside every result."""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import shutil
import sys
import tempfile

import numpy as np

__all__ = ["atomic_folder", "versions", "jsonable", "write_json"]


@contextlib.contextmanager
def atomic_folder(out: str | pathlib.Path):
    """Yield a temporary folder; on success it replaces ``out`` (whose old
    content, if any, is removed only after the new one is in place)."""
    out = pathlib.Path(out).resolve()
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out: {out} exists and is not a folder")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)   # mkdtemp makes 0700; the result is an ordinary folder
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        os.replace(out, old)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def versions() -> dict:
    """Versions of Python and of the packages a result depends on (read from
    the installed metadata: importing python-control alone takes ~1 s)."""
    from importlib.metadata import PackageNotFoundError, version

    from . import __version__

    out = {"tmtcontrol": __version__, "python": sys.version.split()[0]}
    for name in ("casadi", "control", "numpy", "scipy", "matplotlib"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:  # pragma: no cover
            out[name] = None
    return out


def jsonable(obj):
    """``obj`` with NumPy types converted and NaN/inf as None, for ``json.dumps``."""
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj


def write_json(path: str | pathlib.Path, obj) -> None:
    """JSON with NaN/inf written as null and NumPy types converted."""
    pathlib.Path(path).write_text(json.dumps(jsonable(obj), indent=2) + "\n")
