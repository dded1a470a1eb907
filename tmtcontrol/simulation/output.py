"""Simulation outputs: ``timeseries.csv``, ``summary.json`` and the figures."""

from __future__ import annotations

import contextlib
import pathlib

from ..files import versions, write_json

__all__ = ["TIMESERIES_COLUMNS", "SIMULATION_FIGURES", "FIGURE_MODULE", "save_simulation", "write_timeseries"]


TIMESERIES_COLUMNS = (
    "time", "contact_force", "measured_force", "desired_force", "stiffness", "stiffness_estimate",
    "x", "y", "z", "x_ref", "y_ref", "z_ref", "x_cmd", "y_cmd", "z_cmd",
    "q1", "q2", "q3", "dq1", "dq2", "dq3", "tau1", "tau2", "tau3")
"""Columns of timeseries.csv (SI: s, N, N/m, m, rad, rad/s, N m)."""

FIGURE_MODULE = "tmtcontrol.simulation.figures"
SIMULATION_FIGURES = (("fig5_position", "position_figure"), ("fig3_stiffness", "stiffness_figure"),
                      ("path3d", "path_figure"), ("fig4_force", "force_figure"))
"""The figures of a run: (file name, function of :data:`FIGURE_MODULE`),
longest to draw first, so that two processes sharing them end together."""


def write_timeseries(result, path: str | pathlib.Path) -> None:
    """Write the :data:`TIMESERIES_COLUMNS` of a result as CSV."""
    import numpy as np        # here: the command line reads FIGURE_MODULE before NumPy is loaded

    r = result
    data = np.column_stack([r.time, r.contact_force, r.measured_force, r.desired_force, r.stiffness,
                            r.stiffness_estimate, r.position.T, r.reference_position.T,
                            r.command_position.T, r.q.T, r.dq.T, r.tau.T])
    row = ",".join(["%.9g"] * data.shape[1])
    # np.savetxt(fmt="%.9g")'s text (tested), in one formatting call over every row: a fifth
    # faster than row by row, which was already faster than savetxt
    body = "\n".join([row] * data.shape[0]) % tuple(data.ravel().tolist())
    with open(path, "w", newline="\n") as fh:
        fh.write(",".join(TIMESERIES_COLUMNS) + "\n")
        fh.write(body)
        fh.write("\n")


def save_simulation(result, folder: str | pathlib.Path, plots: bool = True, workers=None) -> dict:
    """Write ``timeseries.csv``, ``summary.json`` and (``plots``) the figures of
    a :class:`~tmtcontrol.SimulationResult` into ``folder``; return the summary.

    ``workers``: a :class:`~tmtcontrol.drawing.FigureWorkers` for
    :data:`FIGURE_MODULE`, started before the run, draws the figures while
    this process writes the tables; without it they are drawn here."""
    from ..drawing import FigureWorkers
    from .metrics import first_contact, segment_metrics
    from .scenario import scenario_to_dict

    folder = pathlib.Path(folder)
    r = result
    drawing = None
    if plots:
        drawing = (workers or FigureWorkers(FIGURE_MODULE, processes=0)).draw(SIMULATION_FIGURES, r.traces, folder)
    with contextlib.ExitStack() as stack:
        if drawing is not None:
            stack.callback(drawing.cancel)          # on any error: no worker writes into folder after it
        write_timeseries(r, folder / "timeseries.csv")
        segs = segment_metrics(r)
        summary = {
            "scenario": scenario_to_dict(r.scenario),
            "versions": versions(),
            "run": r.info,
            "path": {"condition_number_min": float(r.path.condition_number.min()),
                     "condition_number_max": r.path.max_condition},
            "segments": [s.as_dict() for s in segs],
            "first_contact": first_contact(r).as_dict(),
        }
        if drawing is not None:
            summary["figures"] = [p.name for p in drawing.result()]
        write_json(folder / "summary.json", summary)
    return summary
