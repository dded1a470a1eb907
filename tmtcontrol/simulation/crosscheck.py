"""The built-in plant against MuJoCo's, segment by segment: the cross-check a reviewer reads.

:func:`crosscheck` runs a scenario twice with the same controller, on
tmtcontrol's plant (the compiled built-in run) and on MuJoCo's dynamics of
the same URDF (:func:`.mujoco_plant.simulate_on_mujoco`), and compares them:
per segment the steady-state force error, the peak force, the settling time
(2 % of f_d) and the verdict of each plant (the same rules, the arm's limits
included; the caller's ``prepare`` attaches the scenario's stiffness limit to
both runs, as ``simulate`` does), and the largest difference of the contact
force over the run and when it happened. The two *agree* when every
segment has the same verdict on both plants and their contact forces differ
by at most :func:`agreement_tolerance` at every sample of the segment's
steady-state window (its last quarter, where the steady-state error is
measured; two errors of the same size can be forces far apart, so the
forces themselves are compared): with the ideal spring
(``simulation.mujoco_contact = "spring"``) 1e-4 f_d and at least 1 mN
(1 mN at the paper's 10 N: the same spring on two integrations of the same
dynamics), with MuJoCo's own soft contact 5e-4 f_d and at least 5 mN
(:data:`CONTACT_AGREEMENT`, :data:`CONTACT_FLOOR`: the contact
differs from the spring by design, docs/mujoco.md, in its transients far
more than in the steady state; review 61: the scenario's
``controller.force_tolerance``, used before, let a forearm 1.1 % heavier in
MuJoCo's model, 9.4 mN apart, "agree"); a verdict computed, so
``tmtcontrol crosscheck`` exits 1 when they do not. A run that
diverges on one plant is a :class:`~.simulator.SimulationError` naming that
plant.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

__all__ = ["PlantComparison", "crosscheck", "agreement_tolerance", "format_crosscheck", "save_crosscheck"]

SPRING_AGREEMENT = 1e-4
"""With the ideal spring, the steady-state forces agree within this fraction of f_d ..."""

SPRING_FLOOR = 1e-3
"""... and never less than this (N): the plants' differences that remain (an
integration step's error on a curved part, a model error's gravity torque)
do not shrink with f_d (review 63: the pipe's 2,000 N/m segment is 1.01 mN
apart with MuJoCo's contact at f_d = 2 N as at 10 N)."""

CONTACT_AGREEMENT = 5e-4
"""With MuJoCo's own soft contact (``simulation.mujoco_contact = "contact"``),
the steady-state forces agree within this fraction of f_d. Measured on the
built-in scenarios (ur5 with each of the five laws, panda, ur5-pipe; the
nineteenth session): at most 1.01e-4 f_d (ur5-pipe at 2,000 N/m, whose
tangential motion MuJoCo's step resolves less finely, docs/mujoco.md), so 5x
that; a model 1.1 % off in one link's mass gives 9.4e-4 f_d and fails."""

CONTACT_FLOOR = 5e-3
"""With MuJoCo's own contact, never less than this (N): :data:`SPRING_FLOOR`'s
reason, the 1.01 mN measured 5x."""


def agreement_tolerance(scenario) -> float:
    """How far (N) the two plants' contact forces may differ over a segment's
    steady-state window and still agree (module docstring)."""
    f_d = scenario.controller.f_d
    if scenario.simulation.mujoco_contact == "spring":
        return max(SPRING_AGREEMENT * f_d, SPRING_FLOOR)
    return max(CONTACT_AGREEMENT * f_d, CONTACT_FLOOR)


@dataclass(frozen=True)
class PlantComparison:
    """``builtin`` and ``mujoco``: the two :class:`~.simulator.SimulationResult`;
    ``segments``: one dict per segment (start, end s; stiffness N/m; each
    plant's steady-state error N, peak force N, settling time s and verdict, and
    ``steady_force_difference`` N, the largest difference of the two forces over its
    steady-state window); ``max_force_difference`` (N) at ``time_of_max`` (s), over the
    whole run; ``agree`` (module docstring), against ``tolerance`` (N,
    :func:`agreement_tolerance`)."""
    builtin: object
    mujoco: object
    segments: tuple[dict, ...]
    max_force_difference: float
    time_of_max: float
    agree: bool
    tolerance: float

    def as_dict(self) -> dict:
        return {"agree": self.agree, "tolerance_N": self.tolerance,
                "max_force_difference_N": self.max_force_difference,
                "time_of_max_s": self.time_of_max, "segments": list(self.segments),
                "mujoco": self.mujoco.info}


def crosscheck(scenario, max_steps: int | None = None, prepare=None) -> PlantComparison:
    """Run ``scenario`` on both plants and compare them (module docstring).
    ``prepare(result) -> result``, if given, runs on each plant's result
    before its segments are judged (``tmtcontrol crosscheck`` and the report
    pass ``stability.limit.with_stiffness_limit``, so a segment beyond the
    loop's limit is ``beyond_limit`` on both plants, as in ``simulate``)."""
    from .metrics import STEADY_FRACTION, segment_metrics, segments
    from .mujoco_plant import simulate_on_mujoco
    from .simulator import SimulationError, Simulator

    runs = []
    for name, run in (("the built-in plant", lambda: Simulator(scenario).run(max_steps=max_steps)),
                      ("MuJoCo's plant", lambda: simulate_on_mujoco(scenario, max_steps=max_steps))):
        try:
            runs.append(run())
        except SimulationError as exc:
            raise SimulationError(f"on {name}: {exc}") from None
    builtin, other = runs
    if prepare is not None:
        builtin, other = prepare(builtin), prepare(other)
    tol = agreement_tolerance(scenario)
    rows = []
    for (i0, i1), a, b in zip(segments(builtin), segment_metrics(builtin), segment_metrics(other), strict=True):
        ss = i0 + int((i1 - i0) * (1 - STEADY_FRACTION))
        steady = float(np.max(np.abs(other.contact_force[ss:i1] - builtin.contact_force[ss:i1])))
        rows.append({"start": a.start, "end": a.end, "stiffness": a.stiffness,
                     "steady_state_error_builtin": a.steady_state_error,
                     "steady_state_error_mujoco": b.steady_state_error,
                     "peak_force_builtin": a.peak_force, "peak_force_mujoco": b.peak_force,
                     "settling_time_builtin": a.settling_time, "settling_time_mujoco": b.settling_time,
                     "verdict_builtin": a.verdict, "verdict_mujoco": b.verdict,
                     "steady_force_difference": steady,
                     "agree": a.verdict == b.verdict and steady <= tol})       # NaN: not agreeing
    diff = np.abs(other.contact_force - builtin.contact_force)
    k = int(np.argmax(diff))
    return PlantComparison(builtin, other, tuple(rows), float(diff[k]), float(builtin.time[k]),
                           all(r["agree"] for r in rows), tol)


def format_crosscheck(c: PlantComparison) -> str:
    """The per-segment table and the largest difference, as the command prints them."""
    from .. import fmt

    rows = c.segments

    def pair(name, key, unit):
        """The built-in and MuJoCo columns of ``key`` in one unit and to the
        same digits, so the two plants' figures read side by side."""
        unit, cells = fmt.column([r[f"{key}_builtin"] for r in rows] + [r[f"{key}_mujoco"] for r in rows], unit)
        return [(f"{name} {plant} ({unit})", cells[i * len(rows):(i + 1) * len(rows)])
                for i, plant in enumerate(("built-in", "MuJoCo"))]

    diff_unit, diff = fmt.column([r["steady_force_difference"] for r in rows], "N")
    table = fmt.text_table([
        ("segment", [str(i) for i in range(1, len(rows) + 1)]),
        ("t (s)", [f"{fmt.num(r['start'])}–{fmt.num(r['end'])}" for r in rows]),
        ("k_e (N/m)", [fmt.num(r["stiffness"], 4) for r in rows]),
        *pair("ss err", "steady_state_error", "N"),
        *pair("peak", "peak_force", "N"),
        *pair("settling", "settling_time", "s"),
        ("verdict built-in", [r["verdict_builtin"] for r in rows]),
        ("verdict MuJoCo", [r["verdict_mujoco"] for r in rows]),
        (f"steady |Δf| ({diff_unit})", diff),
        (f"agree (|Δf| <= {fmt.qty(c.tolerance, 'N')})", ["yes" if r["agree"] else "NO" for r in rows])])
    return (table + f"\nlargest |f_e(MuJoCo) - f_e(built-in)|: {fmt.qty(c.max_force_difference, 'N')} at "
            f"{c.time_of_max:.3f} s; the plants {'agree' if c.agree else 'DISAGREE'}").replace(fmt.NBSP, " ")


def save_crosscheck(c: PlantComparison, folder, plots: bool = True) -> dict:
    """Write ``crosscheck.json`` and (``plots``) ``crosscheck.png`` into ``folder``."""
    from ..drawing import save_figures
    from ..files import versions, write_json
    from .figures import crosscheck_figure

    folder = pathlib.Path(folder)
    summary = {**c.as_dict(), "versions": versions(("mujoco",))}
    if plots:
        summary["figures"] = [p.name for p in save_figures([("crosscheck", crosscheck_figure)], c, folder)]
    write_json(folder / "crosscheck.json", summary)
    return summary
