"""Several force-tracking laws on the same scenario, side by side.

:func:`compare_laws` runs one scenario once per law (each law with the
scenario's parameters if it is the scenario's law, otherwise its documented
defaults) and returns a :class:`Comparison`: per law the simulation result,
the per-segment metrics and verdicts (``metrics``), or the divergence.
``save_comparison`` writes ``summary.json`` (``{"laws": {NAME: {"segments":
[...]}}}``), ``<law>/timeseries.csv`` and the overlay figures. Units SI.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass, field
from functools import cached_property

from ..control.laws import get_law, laws
from .limits import LimitUse
from .metrics import VERDICTS, SegmentMetrics, segment_metrics
from .scenario import Scenario, scenario_to_dict
from .simulator import SimulationError, SimulationResult, check_run_size

__all__ = ["check_law_names", "LawRun", "Comparison", "compare_laws", "with_law", "save_comparison", "format_comparison"]


@dataclass(frozen=True)
class LawRun:
    """One law on the scenario: its scenario, result and segment metrics, or
    ``error`` (the divergence message) with ``result = None``."""
    law: str
    scenario: Scenario
    result: SimulationResult | None
    segments: list[SegmentMetrics] = field(default_factory=list)
    error: str | None = None

    @property
    def verdict(self) -> str:
        """``diverged`` if the run blew up, else the worst segment verdict."""
        if self.result is None:
            return "diverged"
        return max((s.verdict for s in self.segments), key=VERDICTS.index, default="converged")

    @property
    def tracking_verdict(self) -> str:
        """As :attr:`verdict`, of the force tracking alone (each segment's
        ``tracking_verdict``: the arm's limits left out)."""
        if self.result is None:
            return "diverged"
        return max((s.tracking_verdict or s.verdict for s in self.segments), key=VERDICTS.index,
                   default="converged")

    @cached_property
    def limit_use(self) -> LimitUse | None:
        """How near the arm's limits this law's run came (:meth:`.SimulationResult.limit_use`),
        None when the run diverged or the scenario declares no limits."""
        return self.result.limit_use() if self.result is not None else None

    def on_clip(self) -> str:
        """The joints whose torque sat on its clip (``robot.saturate``) in
        this law's run and for how long, in words ("" when none did, or the
        run diverged)."""
        return self.limit_use.on_clip() if self.limit_use is not None else ""

    def as_dict(self) -> dict:
        out = {"law": self.scenario.controller.law.model_dump(), "verdict": self.verdict, "error": self.error,
               "segments": [s.as_dict() for s in self.segments]}
        if self.limit_use is not None:
            out["limits"] = self.limit_use.as_dict()       # as simulate's summary.json (review 62: compare had none)
        return out


@dataclass(frozen=True)
class Comparison:
    """Results of :func:`compare_laws`, by law name in the order asked."""
    scenario: Scenario
    runs: dict[str, LawRun]

    @property
    def converged(self) -> bool:
        return all(r.verdict == "converged" for r in self.runs.values())

    def summary(self) -> dict:
        return {"scenario": scenario_to_dict(self.scenario),
                "laws": {name: run.as_dict() for name, run in self.runs.items()}}


def with_law(scenario: Scenario, name: str) -> Scenario:
    """``scenario`` run with law ``name``: its own parameters if it is the
    scenario's law, the law's documented defaults otherwise."""
    law = get_law(name)
    if scenario.controller.law.kind == name:
        return scenario
    ctl = scenario.controller.model_copy(update={"law": law.parameters()})
    return scenario.model_copy(update={"controller": ctl})


def check_law_names(names) -> list[str]:
    """``names`` as a list if every one is a registered law, listed once;
    else ValueError naming the offending name (review 58: a string was read
    letter by letter as "unknown law 't', 'm', 't'", an empty list compared
    nothing)."""
    if isinstance(names, str):
        raise ValueError(f"expected a list of law names, got the string {names!r} (write [{names!r}])")
    names = list(names)
    if not names:
        raise ValueError("no law named (give one or more, or None for every registered law)")
    known = laws()
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown law {', '.join(repr(n) for n in unknown)} (known: {', '.join(known)})")
    if len(set(names)) != len(names):
        raise ValueError(f"a law is listed twice ({', '.join(names)})")
    return names


def compare_laws(scenario: Scenario, names: list[str] | tuple[str, ...] | None = None, *,
                 max_steps: int | None = None, prepare=None) -> Comparison:
    """Run ``scenario`` once per law (default: every registered law);
    ``prepare(result) -> result``, if given, runs on each result before its
    segments are judged (the CLI attaches the law's predicted stiffness
    limit there, ``stability.analysis.with_stiffness_limit``).

    Returns a :class:`Comparison`; a law whose run diverges is kept with
    ``error`` set rather than raising. Unknown law names raise ValueError
    naming them before anything runs."""
    from .rollout import compile_together
    from .simulator import simulator_for    # one loop for every arm

    names = list(laws()) if names is None else check_law_names(names)
    check_run_size(scenario, max_steps)
    runs = {}
    scenarios = {n: with_law(scenario, n) for n in names}
    sims = {n: simulator_for(sc) for n, sc in scenarios.items()}
    # each law is a loop of its own: their steps compile side by side (issue 42: the Panda's five, 30 s in turn)
    compile_together([sim.rollout for sim in sims.values()], int(round(scenario.duration / scenario.controller.Ts)))
    for n in names:
        sc = scenarios[n]
        try:
            res = sims[n].run(sc, max_steps=max_steps)
        except SimulationError as exc:
            runs[n] = LawRun(n, sc, None, [], str(exc))
            continue
        if prepare is not None:
            res = prepare(res)
        runs[n] = LawRun(n, sc, res, segment_metrics(res))
    return Comparison(scenario, runs)


def format_comparison(cmp: Comparison) -> str:
    """One table, law x segment: steady-state error (max over the last
    quarter), peak, settling to 0.01 N, tangential RMS, the tracking
    tolerance the verdict used, verdict; one unit
    per column (in its header), the same significant digits down a column
    (``fmt.column``)."""
    from .. import fmt

    rows = [(name, i, s) for name, run in cmp.runs.items() for i, s in enumerate(run.segments, 1)]

    def col(name, values, unit, sig=3, nan="–"):        # review 71: "never" was the blank of every column
        unit, cells = fmt.column(list(values) + [None] * n_bad, unit, sig)
        cells = [nan if c == "–" else c for c in cells[:len(rows)]] + [""] * n_bad
        return (f"{name} ({unit})" if unit else name, cells)

    bad = [(name, run.error) for name, run in cmp.runs.items() if run.result is None]
    n_bad = len(bad)
    return fmt.text_table([
        ("law", [name if i == 1 else "" for name, i, _ in rows] + [name for name, _ in bad]),
        ("seg", [str(i) for _, i, _ in rows] + ["–"] * n_bad),
        col("k_e", (s.stiffness for *_, s in rows), "N/m", 4),
        col("ss err", (s.steady_state_error for *_, s in rows), "N"),
        col("peak", (s.peak_force for *_, s in rows), "N"),
        col("settle 10 mN", (s.settling_time_10mN for *_, s in rows), "s", nan="never"),
        col("tang RMS", (s.tangential_rms for *_, s in rows), "m"),
        col("tol", (s.tolerance for *_, s in rows), "N"),
        ("verdict", [s.verdict for *_, s in rows] + [f"diverged: {err}" for _, err in bad])], left=(0, -1))


def save_comparison(cmp: Comparison, folder: str | pathlib.Path, plots: bool = True) -> dict:
    """Write ``summary.json``, ``<law>/timeseries.csv`` and (``plots``) the
    overlay figures into ``folder``; return the summary."""
    from ..files import versions, write_json
    from .output import write_timeseries

    folder = pathlib.Path(folder)
    summary = cmp.summary()
    summary["versions"] = versions()
    for name, run in cmp.runs.items():
        if run.result is not None:
            (folder / name).mkdir()
            write_timeseries(run.result, folder / name / "timeseries.csv")
            summary["laws"][name]["timeseries"] = f"{name}/timeseries.csv"
    if plots:
        from .figures import save_comparison_figures

        summary["figures"] = [p.name for p in save_comparison_figures(cmp, folder)]
    write_json(folder / "summary.json", summary)
    return summary
