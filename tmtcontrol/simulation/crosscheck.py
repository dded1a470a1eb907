"""The built-in plant against MuJoCo's, segment by segment: the cross-check a reviewer reads.

:func:`crosscheck` runs a scenario twice with the same controller, on
tmtcontrol's plant (the compiled built-in run) and on MuJoCo's dynamics of
the same URDF (:func:`.mujoco_plant.simulate_on_mujoco`), and compares them:
per segment the steady-state force error and the verdict of each plant (the
same rules, the arm's limits included), and the largest difference of the
contact force over the run and when it happened. The two *agree* when every
segment has the same verdict on both plants and their steady-state errors
differ by at most the scenario's ``controller.force_tolerance`` (a
difference the verdicts could not see anyway); a verdict computed, so
``tmtcontrol crosscheck`` exits 1 when they do not.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

__all__ = ["PlantComparison", "crosscheck", "format_crosscheck", "save_crosscheck"]


@dataclass(frozen=True)
class PlantComparison:
    """``builtin`` and ``mujoco``: the two :class:`~.simulator.SimulationResult`;
    ``segments``: one dict per segment (start, end s; stiffness N/m; each
    plant's steady-state error N and verdict); ``max_force_difference`` (N)
    at ``time_of_max`` (s); ``agree`` (module docstring)."""
    builtin: object
    mujoco: object
    segments: tuple[dict, ...]
    max_force_difference: float
    time_of_max: float
    agree: bool

    def as_dict(self) -> dict:
        return {"agree": self.agree, "max_force_difference_N": self.max_force_difference,
                "time_of_max_s": self.time_of_max, "segments": list(self.segments),
                "mujoco": self.mujoco.info}


def crosscheck(scenario, max_steps: int | None = None) -> PlantComparison:
    """Run ``scenario`` on both plants and compare them (module docstring)."""
    from .metrics import segment_metrics
    from .mujoco_plant import simulate_on_mujoco
    from .simulator import Simulator

    builtin = Simulator(scenario).run(max_steps=max_steps)
    other = simulate_on_mujoco(scenario, max_steps=max_steps)
    tol = scenario.controller.force_tolerance
    rows = []
    for a, b in zip(segment_metrics(builtin), segment_metrics(other), strict=True):
        rows.append({"start": a.start, "end": a.end, "stiffness": a.stiffness,
                     "steady_state_error_builtin": a.steady_state_error,
                     "steady_state_error_mujoco": b.steady_state_error,
                     "verdict_builtin": a.verdict, "verdict_mujoco": b.verdict,
                     "agree": a.verdict == b.verdict and abs(a.steady_state_error - b.steady_state_error) <= tol})
    diff = np.abs(other.contact_force - builtin.contact_force)
    k = int(np.argmax(diff))
    return PlantComparison(builtin, other, tuple(rows), float(diff[k]), float(builtin.time[k]),
                           all(r["agree"] for r in rows))


def format_crosscheck(c: PlantComparison) -> str:
    """The per-segment table and the largest difference, as the command prints them."""
    from .. import fmt

    rows = c.segments
    table = fmt.text_table([
        ("segment", [str(i) for i in range(1, len(rows) + 1)]),
        ("t (s)", [f"{fmt.num(r['start'])}–{fmt.num(r['end'])}" for r in rows]),
        ("k_e (N/m)", [fmt.num(r["stiffness"], 4) for r in rows]),
        ("ss err built-in", [fmt.qty(r["steady_state_error_builtin"], "N") for r in rows]),
        ("ss err MuJoCo", [fmt.qty(r["steady_state_error_mujoco"], "N") for r in rows]),
        ("verdict built-in", [r["verdict_builtin"] for r in rows]),
        ("verdict MuJoCo", [r["verdict_mujoco"] for r in rows]),
        ("agree", ["yes" if r["agree"] else "NO" for r in rows])])
    return (table + f"\nlargest |f_e(MuJoCo) - f_e(built-in)|: {fmt.qty(c.max_force_difference, 'N')} at "
            f"{c.time_of_max:.3f} s; the plants {'agree' if c.agree else 'DISAGREE'}").replace(fmt.NBSP, " ")


def save_crosscheck(c: PlantComparison, folder, plots: bool = True) -> dict:
    """Write ``crosscheck.json`` and (``plots``) ``crosscheck.png`` into ``folder``."""
    from ..drawing import save_figures
    from ..files import versions, write_json
    from .figures import crosscheck_figure

    folder = pathlib.Path(folder)
    summary = {**c.as_dict(), "versions": versions()}
    if plots:
        summary["figures"] = [p.name for p in save_figures([("crosscheck", crosscheck_figure)], c, folder)]
    write_json(folder / "crosscheck.json", summary)
    return summary
