"""Simulation outputs: ``timeseries.csv``, ``summary.json`` and the figures."""

from __future__ import annotations

import pathlib

import numpy as np

from ..files import versions, write_json

__all__ = ["TIMESERIES_COLUMNS", "save_simulation", "write_timeseries"]


TIMESERIES_COLUMNS = (
    "time", "contact_force", "measured_force", "desired_force", "stiffness", "stiffness_estimate",
    "x", "y", "z", "x_ref", "y_ref", "z_ref", "x_cmd", "y_cmd", "z_cmd",
    "q1", "q2", "q3", "dq1", "dq2", "dq3", "tau1", "tau2", "tau3")
"""Columns of timeseries.csv (SI: s, N, N/m, m, rad, rad/s, N m)."""


def write_timeseries(result, path: str | pathlib.Path) -> None:
    """Write the :data:`TIMESERIES_COLUMNS` of a result as CSV."""
    r = result
    data = np.column_stack([r.time, r.contact_force, r.measured_force, r.desired_force, r.stiffness,
                            r.stiffness_estimate, r.position.T, r.reference_position.T,
                            r.command_position.T, r.q.T, r.dq.T, r.tau.T])
    row = ",".join(["%.9g"] * data.shape[1])          # as np.savetxt(fmt="%.9g"), a third faster
    with open(path, "w", newline="\n") as fh:
        fh.write(",".join(TIMESERIES_COLUMNS) + "\n")
        fh.write("\n".join([row % tuple(r) for r in data.tolist()]))
        fh.write("\n")


def save_simulation(result, folder: str | pathlib.Path, plots: bool = True) -> dict:
    """Write ``timeseries.csv``, ``summary.json`` and (``plots``) the figures of
    a :class:`~tmtcontrol.SimulationResult` into ``folder``; return the summary."""
    from .metrics import first_contact, segment_metrics
    from .scenario import scenario_to_dict

    folder = pathlib.Path(folder)
    r = result
    write_timeseries(r, folder / "timeseries.csv")
    segs = segment_metrics(result)
    summary = {
        "scenario": scenario_to_dict(r.scenario),
        "versions": versions(),
        "run": r.info,
        "path": {"condition_number_min": float(r.path.condition_number.min()),
                 "condition_number_max": r.path.max_condition},
        "segments": [s.as_dict() for s in segs],
        "first_contact": first_contact(result).as_dict(),
    }
    if plots:
        from .figures import save_simulation_figures

        summary["figures"] = [p.name for p in save_simulation_figures(result, folder)]
    write_json(folder / "summary.json", summary)
    return summary
