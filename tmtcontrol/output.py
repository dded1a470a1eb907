"""Atomic output folders: write everything to a temporary sibling folder, then
rename it into place, so a failed run never leaves half-written output."""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
import shutil
import sys
import tempfile

import numpy as np

__all__ = ["atomic_folder", "versions", "jsonable", "write_json", "save_simulation"]


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


TIMESERIES_COLUMNS = (
    "time", "contact_force", "measured_force", "desired_force", "stiffness", "stiffness_estimate",
    "x", "y", "z", "x_ref", "y_ref", "z_ref", "x_cmd", "y_cmd", "z_cmd",
    "q1", "q2", "q3", "dq1", "dq2", "dq3", "tau1", "tau2", "tau3")
"""Columns of timeseries.csv (SI: s, N, N/m, m, rad, rad/s, N m)."""


def save_simulation(result, folder: str | pathlib.Path, plots: bool = True) -> dict:
    """Write ``timeseries.csv``, ``summary.json`` and (``plots``) the figures of
    a :class:`~tmtcontrol.SimulationResult` into ``folder``; return the summary."""
    from .metrics import segment_metrics
    from .scenario import scenario_to_dict

    folder = pathlib.Path(folder)
    r = result
    data = np.column_stack([r.time, r.contact_force, r.measured_force, r.desired_force, r.stiffness,
                            r.stiffness_estimate, r.position.T, r.reference_position.T,
                            r.command_position.T, r.q.T, r.dq.T, r.tau.T])
    np.savetxt(folder / "timeseries.csv", data, delimiter=",", fmt="%.9g",
               header=",".join(TIMESERIES_COLUMNS), comments="")
    segs = segment_metrics(result)
    summary = {
        "scenario": scenario_to_dict(r.scenario),
        "versions": versions(),
        "run": r.info,
        "path": {"condition_number_min": float(r.path.condition_number.min()),
                 "condition_number_max": r.path.max_condition},
        "segments": [s.as_dict() for s in segs],
    }
    if plots:
        from .plots import save_simulation_figures

        summary["figures"] = [p.name for p in save_simulation_figures(result, folder)]
    write_json(folder / "summary.json", summary)
    return summary
