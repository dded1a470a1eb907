"""Simulation outputs: ``timeseries.csv``, ``summary.json`` and the figures."""

from __future__ import annotations

import contextlib
import pathlib

from ..drawing import can_fork
from ..files import versions, write_json

__all__ = ["TIMESERIES_COLUMNS", "SIMULATION_FIGURES", "FIGURE_MODULE", "save_simulation", "write_timeseries",
           "timeseries_columns", "simulation_figures"]


TIMESERIES_COLUMNS = (
    "time", "contact_force", "measured_force", "desired_force", "stiffness", "stiffness_estimate",
    "x", "y", "z", "x_ref", "y_ref", "z_ref", "x_cmd", "y_cmd", "z_cmd",
    "q1", "q2", "q3", "dq1", "dq2", "dq3", "tau1", "tau2", "tau3")
"""Columns of timeseries.csv (SI: s, N, N/m, m, rad, rad/s, N m) for the 3-joint PUMA."""


def simulation_figures(traces) -> tuple:
    """The figures of a run: :data:`SIMULATION_FIGURES`, and for a 6-D arm
    (traces with an orientation error) ``orientation_error`` (the angle
    between the tool and its command)."""
    return SIMULATION_FIGURES + ((("orientation_error", "orientation_figure"),)
                                 if getattr(traces, "orientation_error", None) is not None else ())


def timeseries_columns(n: int = 3, orientation: bool = False) -> tuple[str, ...]:
    """Columns of timeseries.csv for an arm with ``n`` joints; a 6-D run
    (``orientation``) adds the orientation error e_o on the task axes (rad):
    ``e_n, e_1, e_2``."""
    joints = tuple(f"{a}{i}" for a in ("q", "dq", "tau") for i in range(1, n + 1))
    return TIMESERIES_COLUMNS[:15] + joints + (("e_n", "e_1", "e_2") if orientation else ())

FIGURE_MODULE = "tmtcontrol.simulation.figures"
SIMULATION_FIGURES = (("fig5_position", "position_figure"), ("fig3_stiffness", "stiffness_figure"),
                      ("path3d", "path_figure"), ("fig4_force", "force_figure"))
"""The figures of a run: (file name, function of :data:`FIGURE_MODULE`),
longest to draw first, so that two processes sharing them end together."""


def write_timeseries(result, path: str | pathlib.Path, processes: int = 1) -> None:
    """Write the :data:`TIMESERIES_COLUMNS` of a result as CSV.

    ``processes=2`` formats the second half of the rows in a forked process
    (Linux; elsewhere, or if it fails, here): the same file in a little more
    than half the time. Made for the command line, whose other core is idle
    with ``--no-plots``; forking a process that runs threads of its own (a
    notebook, a server) is unsafe: keep the default there."""
    import numpy as np        # here: the command line reads FIGURE_MODULE before NumPy is loaded

    if isinstance(processes, bool) or processes not in (1, 2):
        raise ValueError(f"processes: 1 or 2, got {processes!r}")
    r = result
    data = np.column_stack([r.time, r.contact_force, r.measured_force, r.desired_force, r.stiffness,
                            r.stiffness_estimate, r.position.T, r.reference_position.T,
                            r.command_position.T, r.q.T, r.dq.T, r.tau.T]
                           + ([r.orientation_error.T] if getattr(r, "orientation_error", None) is not None else []))
    columns = timeseries_columns(r.q.shape[0], getattr(r, "orientation_error", None) is not None)
    row = ",".join(["%.9g"] * data.shape[1])
    if processes == 2 and data.shape[0] > 1:
        half = data.shape[0] // 2
        with _formatted_elsewhere(data[half:], row) as second_half:
            text = (_rows(data[:half], row) + "\n").encode() + second_half()
    else:
        text = (_rows(data, row) + "\n").encode()
    with open(path, "wb") as fh:
        fh.write((",".join(columns) + "\n").encode())
        fh.write(text)


def _rows(data, row: str) -> str:
    """``row % values`` for every row, joined by newlines: ``np.savetxt(fmt=...)``'s
    text (tested), in one formatting call over every row (a fifth faster than
    row by row, which was already faster than savetxt)."""
    return "\n".join([row] * data.shape[0]) % tuple(data.ravel().tolist())


@contextlib.contextmanager
def _formatted_elsewhere(data, row: str):
    """Format ``data``'s rows (each line ended by a newline) in a forked
    process while the block runs; yields a function that returns their bytes
    (formatted here if the process failed). The process is killed and reaped
    when the block ends, however it ends."""
    import os
    import signal

    from ..drawing import read_all, write_all

    def here() -> bytes:
        return (_rows(data, row) + "\n").encode()

    if not can_fork():
        yield here
        return
    r, w = os.pipe()
    try:
        pid = os.fork()
    except OSError:                          # no process to spare: all of it here
        os.close(r)
        os.close(w)
        yield here
        return
    if pid == 0:                                             # pragma: no cover - runs in the child
        code = 1
        try:
            os.close(r)
            write_all(w, here())
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    status = None

    def result() -> bytes:
        nonlocal status
        text = read_all(r)
        status = os.waitpid(pid, 0)[1]
        return text if status == 0 else here()

    try:
        yield result
    finally:
        os.close(r)
        if status is None:                   # the block ended early: the child has no reader now
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)


def save_simulation(result, folder: str | pathlib.Path, plots: bool = True, workers=None,
                    csv_processes: int = 1) -> dict:
    """Write ``timeseries.csv``, ``summary.json`` and (``plots``) the figures of
    a :class:`~tmtcontrol.SimulationResult` into ``folder``; return the summary.

    ``workers``: a :class:`~tmtcontrol.drawing.FigureWorkers` for
    :data:`FIGURE_MODULE`, started before the run, draws the figures while
    this process writes the tables; without it they are drawn here.
    ``csv_processes``: see :func:`write_timeseries`."""
    from ..drawing import FigureWorkers
    from .geometry import surface_of
    from .metrics import first_contact, segment_metrics
    from .scenario import scenario_to_dict

    folder = pathlib.Path(folder)
    r = result
    drawing = None
    if plots:
        traces = r.traces
        drawing = (workers or FigureWorkers(FIGURE_MODULE, processes=0)).draw(simulation_figures(traces), traces,
                                                                              folder)
    with contextlib.ExitStack() as stack:
        if drawing is not None:
            stack.callback(drawing.cancel)          # on any error: no worker writes into folder after it
        write_timeseries(r, folder / "timeseries.csv", processes=csv_processes)
        segs = segment_metrics(r)
        summary = {
            "scenario": scenario_to_dict(r.scenario),
            # the part the run touched: a height map's digest beside its file's name (review 65: two runs of one
            # file rewritten between them had identical summaries)
            "surface": surface_of(r.scenario).key,
            "versions": versions(),
            "run": r.info,
            "path": {"condition_number_min": float(r.path.condition_number.min()),
                     "condition_number_max": r.path.max_condition},
            "segments": [s.as_dict() for s in segs],
            "first_contact": first_contact(r).as_dict(),
        }
        if r.limits is not None:        # the arm's torque, rate and joint margins (simulation.limits)
            summary["limits"] = r.limit_use().as_dict()
        if r.posture_drift is not None:     # a redundant arm: how far the null space let the joints wander (rad)
            summary["posture_drift"] = dict(zip(r.limits.names, map(float, r.posture_drift)))
        if drawing is not None:
            summary["figures"] = [p.name for p in drawing.result()]
        write_json(folder / "summary.json", summary)
    return summary
