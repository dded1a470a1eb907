"""Robustness sweeps: thousands of simulations over the uncertainty a user will meet
(stiffness, surface error, noise, model error, rate, delay, law), on local
worker processes or a Dask cluster, with results in Parquet (see docs/sweeps.md)."""

from __future__ import annotations

import pathlib
import re
import sys
import time

from ..files import OutputFolder, write_json
from .run import REFUSED, PartialFolder, Progress, case_row, check_dask, limits_by_default, run_cases
from .spec import EXAMPLE, Case, Sweep, SweepError, check_sweep_robots, load_sweep, sweep_from_dict

__all__ = ["Sweep", "Case", "SweepError", "load_sweep", "sweep_from_dict", "run_sweep", "save_sweep",
           "sweep_summary", "boundary_lines", "axis_labels", "EXAMPLE", "case_row"]


def run_sweep(sweep: Sweep, workers: int = 1, dask: str | None = None, max_steps: int | None = None,
              progress: bool = False, limits: bool | None = None):
    """Run every case in memory and return a pandas DataFrame, one row per
    case (for notebooks; ``tmtcontrol sweep`` writes the same rows to
    ``results.parquet``). ``limits``: each case's own predicted stiffness
    limits (``sweep.run.case_limits``); None: on unless a random axis makes
    every case a new analysis (``sweep.run.limits_by_default``)."""
    import pandas as pd

    rows: list[dict] = []
    prog = Progress(len(sweep.cases)) if progress else None
    try:
        run_cases(sweep, sweep.cases, rows.extend, workers, dask, max_steps, prog, limits)
    finally:
        if prog is not None:
            prog.close()
    return pd.DataFrame(sorted(rows, key=lambda r: r["case"]))


def _facet_axis(sweep: Sweep, df) -> str | None:
    """The third axis, when it is a grid axis with two to four values: the map
    gets one panel per value (random draws are overlaid, not split)."""
    if len(sweep.axes) < 3 or sweep.axes[2] not in sweep.grid:
        return None
    third = sweep.axes[2]
    return third if 2 <= df[third].nunique() <= 4 else None


def sweep_prediction(sweep: Sweep, df) -> dict | None:
    """The analysis' stiffness limit per value of the other map axis (and of
    the facet axis: keys are then ``(other, facet)`` pairs), when the stiffness
    is one of the first two axes and the law has a linear verdict: the
    smallest ``predicted_limit`` of the group's cases (each its deciding limit,
    ``stability.limit.deciding_limit``, with its own drawn values) when the
    rows have it (no line for a group whose analyses all failed: its rows'
    ``limits_error`` says why), else (``sweep --limits off``) the 1-D
    small-signal limit of the group's first case (the map labels it so)."""
    from ..stability.analysis import scenario_stiffness_limit

    axes = sweep.axes[:2]
    key = "environment.stiffness.values"
    if key not in axes:
        return None
    other = next((a for a in axes if a != key), None)
    facet = _facet_axis(sweep, df)
    by = [a for a in (other, facet) if a is not None]
    groups = [((), df)] if not by else [((k,) if not isinstance(k, tuple) else k, g)
                                        for k, g in df.groupby(by if len(by) > 1 else by[0], sort=True)]
    out = {}
    for k, g in groups:
        if "predicted_limit" in g:      # the cases' own limits: a group whose analyses all failed has no line
            if g["predicted_limit"].notna().any():
                out[k[0] if len(k) == 1 else (k if k else None)] = float(g["predicted_limit"].min())
            continue
        case = sweep.cases[int(g["case"].iloc[0])]
        try:
            limit = scenario_stiffness_limit(sweep.scenario(case))
        except Exception:           # an analysis that does not apply (e.g. no linear verdict)
            limit = None
        if limit is not None:
            out[k[0] if len(k) == 1 else (k if k else None)] = float(limit)
    return out or None


def sweep_summary(sweep: Sweep, df, predicted: dict | None = None) -> dict:
    """Counts per verdict, the five worst cases and the boundary found along
    :func:`boundary_axis` (per combination of the other grid axes), with the
    SI unit of each axis and figure (``units``)."""
    import numpy as np

    from ..simulation.metrics import VERDICTS

    counts = {v: int((df["verdict"] == v).sum()) for v in (*VERDICTS, REFUSED)}
    order = df.assign(_e=df["max_steady_error"].astype(float).fillna(np.inf)).sort_values("_e", ascending=False)
    worst = [{k: (None if isinstance(v, float) and not np.isfinite(v) else v)
              for k, v in row.items() if k in ("case", "verdict", "max_steady_error", *sweep.axes)}
             for row in order.head(5).drop(columns="_e").to_dict("records")]
    boundary = []
    axes = sweep.axes
    first = boundary_axis(sweep)
    # one boundary per combination of the other grid axes (random axes are draws, not settings to split by)
    others = [a for a in axes if a != first and a in sweep.grid and a in df]
    groups = [((), df)] if not others else [((k,) if len(others) == 1 else k, g)
                                            for k, g in df.groupby(others if len(others) > 1 else others[0],
                                                                   sort=True)]
    for values, g in (groups if first is not None else []):
        try:
            xs = sorted(set(g[first]))
        except TypeError:
            break
        last_ok = first_bad = None
        for x in xs:
            if (g.loc[g[first] == x, "verdict"] == "converged").all() and first_bad is None:
                last_ok = x
            elif first_bad is None:
                first_bad = x
        boundary.append({**{a: _plain(v) for a, v in zip(others, values)},
                         f"largest {first} with every case converged": _plain(last_ok),
                         f"smallest {first} with a case not converged": _plain(first_bad)})
    out = {"cases": int(len(df)), "axes": axes, "verdicts": counts, "worst": worst, "boundary": boundary,
           # SI units of the axes (and so of the boundary values) and of the numbers quoted
           "units": {**sweep.units, "max_steady_error": "N", "predicted_stiffness_limit": "N/m"}}
    if predicted:
        # which limit it is (review 31: the 1-D figure under --limits off had the deciding limit's name alone)
        out["predicted_stiffness_limit_from"] = (
            "deciding limit (the group's smallest, as analyze --scenario prints it)" if "predicted_limit" in df
            else "1-D small-signal limit of the group's first case (sweep --limits off)")
        out["predicted_stiffness_limit"] = [{"value": list(k) if isinstance(k, tuple) else k, "limit": v}
                                            for k, v in predicted.items()]
    return out


def _number(v) -> bool:
    """A value with an order: a number, or a list of one number (a one-segment stiffness profile)."""
    if isinstance(v, (list, tuple)) and len(v) == 1:
        v = v[0]
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def boundary_axis(sweep: Sweep) -> str | None:
    """The axis the boundary is found along: the first grid axis with more
    than one value, all numbers, else the random axis if there is only one
    (with more than one sample); None when every axis holds one value
    (review 31: a one-valued ``trajectory.cycles`` grid axis was blamed, "not
    converged from the smallest, 0.5", for what random draws of the
    stiffness did), only names vary (review 40: arms sorted by their names
    gave "converged up to arm4.urdf, not from panda" beside a converged ur5)
    or several random axes vary together (review 68: a failure drawn by the
    x_e error was blamed on the noise drawn beside it, "not converged from
    the smallest, 0.1438 N", beside a converged case at 0.1846 N)."""
    several = [a for a, v in sweep.grid.items() if len(v) > 1 and all(_number(x) for x in v)]
    several += [a for a in sweep.random if sweep.samples > 1 and len(sweep.random) == 1]
    return several[0] if several else None


def _plain(v):
    """A NumPy scalar as the Python number it holds (for JSON and printing)."""
    return v.item() if hasattr(v, "item") else v


def axis_labels(sweep: Sweep) -> dict[str, str]:
    """Each axis' description from the scenario schema (its meaning up to the
    first ';', ':' or '(': "control rate 1/Ts"), the key where it has none, for
    figure labels (the unit comes from :attr:`Sweep.units`)."""
    from ..simulation.scenario import applicable_settings

    try:
        first = next(iter(sweep.cases))
    except StopIteration:
        return {a: a for a in sweep.axes}
    rows = {r.key: r.meaning for r in applicable_settings(sweep.scenario(first))}
    return {a: re.split(r"[;:]| \(", rows.get(a) or a)[0].strip() or a for a in sweep.axes}


def boundary_lines(sweep: Sweep, summary: dict) -> list[str]:
    """The summary's boundaries as lines for the terminal, one per
    combination of the other grid axes, numbers formatted with their units
    (``fmt.qty``): "boundary at controller.rate = 1 kHz,
    controller.delay_samples = 0: environment.stiffness.values converged up
    to 106,000 N/m, not from 150,000 N/m"."""
    from .. import fmt

    units = sweep.units
    first = boundary_axis(sweep)

    def show(key, v):
        if v is None:
            return "–"
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            unit = units.get(key, "")
            return fmt.num(v, 4) + (f" {unit}" if unit else "")
        if isinstance(v, (list, tuple)) and len(v) == 1:
            return show(key, v[0])
        return str(v)

    ok_key = f"largest {first} with every case converged"
    bad_key = f"smallest {first} with a case not converged"
    lines = []
    split = [k for k in (summary["boundary"][0] if summary["boundary"] else {}) if k not in (ok_key, bad_key)
             and len({repr(b[k]) for b in summary["boundary"]}) > 1]     # an axis with one value splits nothing
    for b in summary["boundary"]:
        where = ", ".join(f"{k} = {show(k, b[k])}" for k in split)
        ok, bad = b[ok_key], b[bad_key]
        if ok is None and bad is None:
            what = "no case"
        elif bad is None:
            what = f"every case converged (up to {show(first, ok)})"
        elif ok is None:
            what = f"not converged from the smallest, {show(first, bad)}"
        else:
            what = f"converged up to {show(first, ok)}, not from {show(first, bad)}"
        lines.append(f"boundary{' at ' + where if where else ''}: {first} {what}")
    return lines


def save_sweep(sweep: Sweep, out: str | pathlib.Path, workers: int = 1, dask: str | None = None,
               resume: bool = False, plots: bool = True, max_steps: int | None = None,
               command_line: str = "", limits: bool | None = None, checked=None) -> dict:
    """Run the sweep into ``out``: finished chunks go to ``OUT.partial/`` as
    they complete; at the end ``results.parquet``, ``summary.json`` and the
    figures are committed to ``out`` (replaced atomically) and the partial
    folder is removed. Returns the summary. A case whose arm or per-joint
    settings do not fit it is refused before anything is written
    (:func:`.spec.check_sweep_robots`). ``checked()``, if given, is called
    once every input check has passed, before the plan is printed (the
    command line prints its notes there: a refused sweep prints its one
    line only)."""
    import pyarrow.parquet as pq

    check_dask(dask)                               # a scheduler address that answers nothing: refused first
    check_sweep_robots(sweep)
    folder = OutputFolder(out, "--out")            # checked before anything runs
    with folder:
        why = None
        if limits is None:
            limits, why = limits_by_default(sweep)
        partial = PartialFolder(pathlib.Path(out).resolve(), sweep, resume,
                                {"limits": bool(limits), "max_steps": max_steps})
        done = partial.done()
        if checked is not None:
            checked()
        todo = sweep.cases.without(done)           # a view: the cases are generated as they run
        if dask in (None, "local"):                # never more processes than cases (review 59: "6 workers" for 2)
            workers = max(1, min(workers, len(todo)))
        if resume and partial.fresh:               # review 31: said, not a silent fresh run
            print(f"sweep: --resume: no interrupted sweep in {partial.path}; running every case", file=sys.stderr,
                  flush=True)
        print(sweep.plan(len(todo), workers, limits), file=sys.stderr, flush=True)
        if why is not None:
            print(why, file=sys.stderr, flush=True)
        prog = Progress(len(sweep.cases), len(done))
        t0 = time.perf_counter()
        try:
            if todo:
                run_cases(sweep, todo, partial.write, workers, dask, max_steps, prog, limits)
        except BaseException:
            if partial.fresh and not partial.parts():   # no case finished (no scheduler, an early Ctrl-C)
                partial.remove()
            raise
        finally:
            prog.close()
        table = partial.table()
        pq.write_table(table, folder.path / "results.parquet")
        df = table.to_pandas()
        predicted = sweep_prediction(sweep, df)
        summary = sweep_summary(sweep, df, predicted)
        summary.update({"run": {"workers": workers, "engine": dask or "local", "seconds": time.perf_counter() - t0,
                                "resumed_cases": len(done), "command": command_line,
                                # without them a case's verdict is its run's alone (docs/sweeps.md)
                                "limits": bool(limits), "verdicts_against_the_loops_limit": bool(limits)},
                        "sweep": {"grid": sweep.grid, "random": sweep.random, "samples": sweep.samples,
                                  "seed": sweep.seed, "fingerprint": sweep.fingerprint}})
        if plots:
            from ..drawing import save_figures
            from .figures import law_distribution_figure, sweep_map_figure

            facet = _facet_axis(sweep, df)
            labels = axis_labels(sweep)
            makers = [("sweep_map", lambda d: sweep_map_figure(d, sweep.axes, predicted, facet, sweep.units,
                                                               labels))]
            if "controller.law" in sweep.axes:
                makers.append(("law_distribution", law_distribution_figure))
            summary["figures"] = [p.name for p in save_figures(makers, df, folder.path)]
        write_json(folder.path / "summary.json", summary)
        folder.commit()
    partial.remove()
    return summary
