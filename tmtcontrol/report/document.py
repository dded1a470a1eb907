"""The stability report as a document model: verdicts, sections of tables
and figures, reproducibility data. Built once by :func:`build_report` and
rendered by ``report.render`` to HTML and, from the same HTML, to PDF.

The top of the data path: it calls the checks (``checks``), the analysis
(``stability``: eq. 22 in continuous time, eq. 25, the sampled loop with
delay and x_e error, the whole-loop linearisation), the simulator and its
metrics, the law comparison, a small robustness sweep (``sweep``) and the
damping design (``stability.design``). Every verdict is computed with the
number behind it; a loop that is unstable shows "unstable" and its growth
rate, never an overshoot.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import io
import math
import shlex
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..files import versions
from ..plotstyle import plain_log_labels, styled
from ..simulation.scenario import Scenario, applicable_settings, dump_scenario
from .. import fmt

__all__ = ["Verdict", "Table", "FigureBlock", "Section", "Report", "build_report", "FORCE_TOLERANCE", "STAGES"]

FORCE_TOLERANCE = 0.01
"""The default of the tracking tolerance, N; the verdicts use the scenario's
own ``controller.force_tolerance``."""

STAGES = ("continuous-time analysis", "sampled-data analysis", "simulation", "law comparison", "robustness sweep",
          "design", "derivation checks")
"""The computing stages (writing HTML and PDF are stages of ``write_report``).
This process runs the simulation and the design; the others (the
derivation checks in groups) are tasks that a second process takes from the
start, this one taking its share when its own stages are done (see
:func:`_remote_tasks`). Progress reports the stages as they end, each with
its own computing time (the checks': their groups' sum)."""
SWEEP_POINTS = 6
SWEEP_CYCLES = 0.5
"""The report's robustness sweep: ``SWEEP_POINTS`` constant stiffnesses
x two control rates (:func:`sweep_axes`), each case 0.5 cycle of the
scenario's path."""


@dataclass(frozen=True)
class Verdict:
    """One computed verdict: ``value`` is the number it rests on, ``check``
    what was computed to get it."""
    name: str
    passed: bool
    value: str
    check: str

    @property
    def evidence(self) -> str:
        return f"{self.value} ({self.check})"


@dataclass(frozen=True)
class Table:
    """A table: header cells carry their units; ``caption`` says what it shows."""
    caption: str
    head: list[str]
    rows: list[list[str]]
    verdict_column: int | None = None      # cells "PASS"/"FAIL"/verdict words, styled with a symbol


@dataclass(frozen=True)
class FigureBlock:
    """A figure as SVG text with its caption and ``alt``, a description of
    what it draws for a reader who cannot see it (:func:`describe`)."""
    caption: str
    svg: str
    alt: str = ""


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass
class Section:
    key: str
    title: str
    blocks: list = field(default_factory=list)


@dataclass
class Report:
    """Everything the report shows."""
    scenario: Scenario
    command_line: str
    verdicts: list[Verdict] = field(default_factory=list)
    sections: list[Section] = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)          # raw results, for tests and the API

    @property
    def passed(self) -> bool:
        return all(v.passed for v in self.verdicts)

    def section(self, key: str) -> Section:
        return next(s for s in self.sections if s.key == key)


def svg(fig) -> str:
    """A Figure as SVG text (vector: crisp zoomed and printed), slimmed for
    drawing (:func:`~.slimsvg.slim_svg`)."""
    from .slimsvg import slim_svg

    buf = io.StringIO()
    with styled():
        plain_log_labels(fig).savefig(buf, format="svg", metadata={"Date": None})
    return slim_svg(buf.getvalue())


def describe(fig) -> str:
    """A text description of a matplotlib figure for the image's alt text
    (what it draws, not its caption): per panel its title, the quantities on
    its axes with their scales, and its named curves and markers."""
    parts = []
    for ax in fig.axes:
        if ax.get_label() == "<colorbar>":
            parts.append(f"a colour scale of {ax.get_ylabel() or ax.get_xlabel()}")
            continue
        # a panel sharing its x axis with the one below reads that one's label (review 15: "against index")
        x = ax.get_xlabel() or next((o.get_xlabel() for o in ax.get_shared_x_axes().get_siblings(ax)
                                     if o.get_xlabel()), "")
        y = ax.get_ylabel() or next((o.get_ylabel() for o in ax.get_shared_y_axes().get_siblings(ax)
                                     if o.get_ylabel()), "")
        if not (x or y) and (ax.images or not ax.axison):     # a picture (the arm drawn), not a chart
            # named by its title, else by the words drawn on it (the still's "drawn by MuJoCo", a text inside
            # the picture since review 53)
            name = ax.get_title() or "; ".join(t.get_text() for t in ax.texts if t.get_text())
            parts.append(f"{name}: an image" if name else "an image")
            continue
        if not (x or y or ax.get_title()):
            continue
        scale = lambda a: " (log scale)" if a.get_scale() == "log" else ""
        what = f"{y or 'value'}{scale(ax.yaxis)} against {x or 'index'}{scale(ax.xaxis)}"
        names = [t.get_text() for t in (ax.get_legend().get_texts() if ax.get_legend() else [])]
        names += [t.get_text() for leg in fig.legends for t in leg.get_texts()] if ax is fig.axes[0] else []
        names = list(dict.fromkeys(n for n in names if n and not n.startswith("_")))
        parts.append((f"{ax.get_title()}: " if ax.get_title() else "") + f"a chart of {what}"
                     + (f"; shown: {', '.join(names)}" if names else ""))
    return ("Chart. " + ". ".join(parts) + ".") if parts else "Chart."


def figure(caption: str, make: Callable, *args, **kw) -> FigureBlock:
    with styled():
        fig = make(*args, **kw)
    return FigureBlock(caption, svg(fig), describe(fig))


def provenance() -> dict:
    """When and from what the report was made: the date (UTC, ISO 8601) and
    the source, the git commit of the package's checkout if it is one (with
    "+ local changes" if its tracked files differ), else the package version."""
    import datetime
    import pathlib
    import subprocess

    from .. import __version__

    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    root = pathlib.Path(__file__).resolve().parents[2]
    source = f"tmtcontrol {__version__} (no git checkout)"
    try:
        run = lambda *a: subprocess.run(["git", "-C", str(root), *a], capture_output=True, text=True, timeout=5)
        head = run("rev-parse", "--short=12", "HEAD")
        if head.returncode == 0 and (root / ".git").exists():
            dirty = run("status", "--porcelain", "--untracked-files=no", "--", "tmtcontrol").stdout.strip()
            source = f"tmtcontrol {__version__}, git commit {head.stdout.strip()}" + (" + local changes" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return {"date": date, "source": source}


def _mark(passed: bool) -> str:
    return "PASS" if passed else "FAIL"


def _stiffness_points(p: dict) -> list[float]:
    pts = p["k_e_values"] or [p["k_e_min"], math.sqrt(p["k_e_min"] * p["k_e_max"]), p["k_e_max"]]
    return sorted({float(v) for v in pts})


def _response(a) -> tuple[str, str]:
    """Overshoot and settling of a continuous analysis, or 'unstable' with
    the growth rate."""
    growth = float(np.max(a.poles.real))
    if not a.bibo_stable:
        return f"unstable (grows as e^{fmt.num(growth)}·t)", "–"
    return fmt.pct(a.overshoot_pct), fmt.qty(a.settling_time, "s")


# -- stages --------------------------------------------------------------------------------

def _checks(rep: Report, checks: list):
    n_ok = sum(c.passed for c in checks)
    rep.verdicts.append(Verdict("Derivation checks pass", n_ok == len(checks), f"{n_ok}/{len(checks)} pass",
                                "the paper's equations, every law's claims, the loop and the scenario's arm, on the "
                                "running code"))
    rows = [[c.equation, c.name, c.claim + (f" Note: {c.note}" if c.note else ""), fmt.num(c.residual, 2),
             _mark(c.passed)] for c in checks]
    sec = Section("derivations", "Derivation checks", [
        Paragraph("Each check evaluates an equation of the paper (or a law's documented claim) on the code "
                  "that runs, against an independent computation; the residual is the largest relative "
                  "difference found. The last rows check the scenario's arm: its task-frame loop with the ideal "
                  "inner loop (model = plant) realises the command U and reduces to eq. (22) on the normal axis "
                  "(on an arm with 6 or more joints also: the null-space torque leaves the task alone and the "
                  "other axes follow their impedance; on one of 4 or 5 joints, the null-space torque)."),
        Table("Derivation checks", ["equation", "check", "claim", "residual", "verdict"], rows, verdict_column=4)])
    rep.data["checks"] = checks
    return sec


def _continuous(rep: Report, p: dict):
    from ..stability import analyze_continuous, analyze_range
    from ..stability import figures as sf

    m, b, k, f_d = p["m"], p["b"], p["k"], p["f_d"]
    points = _stiffness_points(p)
    rng = analyze_range(m, b, k, p["k_e_min"], max(p["k_e_max"], p["k_e_min"]), f_d)
    per_k = [analyze_continuous(m, b, k, ke, f_d) for ke in points]
    worst_re = max(float(np.max(a.poles.real)) for a in per_k + [rng.at_min, rng.at_max])
    stable = bool(rng.stable_for_all and all(a.bibo_stable for a in per_k))
    rep.verdicts.append(Verdict(
        "BIBO stable in continuous time (eq. 22)", stable,
        f"largest pole real part {fmt.qty(worst_re, '1/s')}",
        f"poles of eq. (22) over k_e ∈ [{fmt.qty(p['k_e_min'], 'N/m')}, {fmt.qty(p['k_e_max'], 'N/m')}]; "
        f"worst damping ratio {fmt.num(rng.worst_damping_ratio)}"))
    rows = []
    for a in per_k:
        over, settle = _response(a)
        rows.append([fmt.num(a.k_e), ", ".join(f"{fmt.num(z.real)}{'+' if z.imag >= 0 else '−'}"
                                               f"{fmt.num(abs(z.imag))}j" if abs(z.imag) > 0 else fmt.num(z.real)
                                               for z in a.poles),
                     fmt.num(a.natural_frequency), fmt.num(a.damping_ratio), over, settle,
                     fmt.num(a.critical_damping), _mark(a.bibo_stable)])
    lo, hi = p["k_e_min"], p["k_e_max"]
    sec = Section("continuous", "Continuous-time analysis (eqs. 22, 25)", [
        Paragraph(f"The force error dynamics of eq. (22), m ë + b ė + (k + k_e) e, with m = {fmt.qty(m, 'kg')}, "
                  f"b = {fmt.qty(b, 'N s/m')}, k = {fmt.qty(k, 'N/m')}, at each operating stiffness. "
                  "Eq. (25) is the damping for a critically damped response (b / b_crit is the damping ratio ζ)."),
        Table("Continuous-time force error dynamics per stiffness",
              ["k_e (N/m)", "poles (1/s)", "ω_n (rad/s)", "ζ", "overshoot", "settling 2 %", "b_crit eq. 25 (N s/m)",
               "BIBO stable"], rows, verdict_column=7),
        figure("Root locus of eq. (22) as k_e varies over the range (×/÷ 10), the operating range drawn thick.", sf.root_locus_figure, m, b, k,
               lo / 10, hi * 10, operating=(lo, hi)),
        figure("Damping ratio and natural frequency of eq. (22) against k_e, the operating range shaded.",
               sf.damping_figure, m, b, k, lo / 10, hi * 10, operating=(lo, hi)),
        figure("Force step responses of eq. (22) at the operating stiffnesses.", sf.step_figure, m, b, k, points, f_d)])
    rep.data["continuous"] = {"range": rng, "points": per_k}
    return sec


def _sampled(rep: Report, sc: Scenario, p: dict):
    from ..stability import analyze_scenario
    from ..stability import figures as sf
    from ..stability.analysis import closed_form_applies, scenario_stiffness_limit
    from ..stability.periodic import GROWTH_BOUND

    a = analyze_scenario(sc, limits=True)     # as `analyze --scenario`: the smaller of the limits decides
    limit_1d = a["max_stable_stiffness"]
    whole = a.get("whole_loop_limit")
    periodic, first = a.get("periodic_limit"), a.get("first_contact_limit")
    verdict_limit = a["limit"] if "limit" in a else whole if whole is not None else limit_1d
    margin = verdict_limit / p["k_e_max"]
    Ts = p["Ts"]
    noise = ""
    if a.get("free_axes_note"):             # unstable at every stiffness: no search ran (review 55)
        how = a["free_axes_note"]
    elif "limit" in a:
        path = "frozen-point minimum; the path period is not whole control periods" if "periodic_note" in a \
            else "monodromy over one period"
        how = (f"the smaller of the limit along the path ({path}) and the limit from first contact (the "
               f"scenario's own start): {a['limit_from']}")
        if a.get("periodic_set_by") == "transient growth":
            how += (f"; the limit along the path is where a perturbation grows more than {GROWTH_BOUND:.0e}-fold "
                    f"within a period (spectral radius {fmt.num(a['periodic_radius'])} there: the radius is no margin)")
        elif a.get("periodic_set_by") == "orbit lost":
            how += (f"; the limit along the path is where the periodic orbit is lost (spectral radius "
                    f"{fmt.num(a['periodic_radius'])} just below: the radius is no margin)")
        if a.get("periodic_set_by") in ("transient growth", "orbit lost"):
            noise = (f". The analysis is of the noise-free loop: near this limit the loop amplifies perturbations, "
                     f"sensor noise among them, up to {fmt.num(a['periodic_growth'])}-fold within a period, so the "
                     "margin is one of stability, not of the force's accuracy under noise at a stiffer surface "
                     "(simulate with the sensor's noise over several periods to see that)")
    elif whole is not None:
        how = f"whole-loop linearisation of the compiled step at {len(a.get('whole_loop_points', []))} path points"
    else:
        how = a["sampled_model"]
    rep.verdicts.append(Verdict(
        f"Stable in the sampled implementation (Ts = {fmt.qty(Ts, 's')})", bool(a["sampled_stable"]),
        f"largest stable stiffness {fmt.qty(fmt.down(verdict_limit), 'N/m')} vs k_e max "
        f"{fmt.qty(p['k_e_max'], 'N/m')} (margin {fmt.ratio(fmt.down(margin))})",
        how + f"; delay {sc.controller.delay_samples} samples, x_e error {fmt.qty(sc.controller.x_e_error, 'm')}"
        + noise))
    points_ = a.get("whole_loop_points", [])
    times = _cells([w["path_time"] for w in points_], "s")          # one unit for the column (not 0 s beside 500 ms)
    rows = [[times[i], fmt.num(fmt.down(w["limit"])), fmt.ratio(fmt.down(w["limit"] / p["k_e_max"]))]
            for i, w in enumerate(points_)]
    # the boundary against Ts: the same law loop at other rates
    closed_form = closed_form_applies(sc.controller.law.kind, sc.controller.delay_samples, sc.controller.x_e_error)
    Ts_grid = np.geomspace(Ts / 8, Ts * 8, 13 if closed_form else 5)
    limits = []
    for T in Ts_grid:           # closed form where it applies (ms per point), else the law loop (~1 s)
        lim = scenario_stiffness_limit(sc, dict(p, Ts=T, alpha=sc.sensor.pole(T)))
        limits.append(np.nan if lim is None else lim)
    points = [(Ts, ke, fmt.num(ke)) for ke in _stiffness_points(p)]
    # limits and margins rounded down (fmt.down): a rounded limit never reads above the computed one
    cell = lambda v: [fmt.num(fmt.down(v)), fmt.ratio(fmt.down(v / p["k_e_max"]))] if v is not None else ["–", "–"]
    # the 1-D model leaves out the mid-period hold and has no verdict for some laws: then it predicts nothing
    # for this loop (scenario_stiffness_limit is None at every rate above, no boundary in the figure) and is shown
    # for reference only (review 15: the pipe's 133,000 N/m row stood beside the loop's own 561,000-603,000 as if
    # it explained them)
    why_not_1d = None if not np.all(np.isnan(limits)) else (
        "it leaves out the mid-period hold" if sc.controller.hold == "mid_period" else
        "this law has no linear verdict")
    # the first-contact search stops at the limit along the path: a start that settles there is a lower bound
    # (review 15: the row read as a limit equal to the periodic one)
    ceiling = periodic if periodic is not None else whole
    at_least = lambda v: ([f"≥ {c}" for c in cell(v)] if v is not None and ceiling is not None and v >= ceiling
                          else cell(v))
    model_rows = [["whole-loop linearisation (frozen-point minimum over the path)", *cell(whole)],
                  [f"1-D: {a['sampled_model']}" + (f" (for reference only: {why_not_1d})" if why_not_1d else ""),
                   *cell(limit_1d)]]
    if "limit" in a:
        model_rows = [["along the moving path (" + ("frozen-point minimum: the path period is not whole control "
                                                    "periods" if "periodic_note" in a else
                                                    "periodic orbit, monodromy over one period") + ")",
                       *cell(periodic)],
                      ["from first contact (the scenario's own start settles below it)", *at_least(first)],
                      *model_rows,
                      [f"decisive: the smaller of the first two ({a['limit_from']})", *cell(a["limit"])]]
    blocks = [
        Paragraph("Models of the sampled loop, side by side. The whole-loop linearisation takes the compiled "
                  "step itself (robot, law, inner loop, delay, force filter) frozen at points of the path, finds "
                  "its fixed point and the largest stiffness for which the Jacobian's spectral radius stays "
                  "below 1: the conservative bound. Along the moving path, the product of the step's linear maps "
                  "over one period of the path (the monodromy) gives the limit of the loop as it is simulated. "
                  "From first contact, short simulations of the scenario's own start find the stiffness above "
                  "which it locks into a contact limit cycle (the small-force region of eq. (18)). The smaller "
                  "of these two decides the verdict, as in tmtcontrol analyze --scenario. The 1-D model is the "
                  "normal axis alone with the robot's effective mass, "
                  + ("which explains the limit: it falls with the control period, the delay, a force filter and "
                     "a surface located too shallow." if why_not_1d is None else
                     f"shown for reference only: it makes no prediction for this loop ({why_not_1d}), and the "
                     "figure below draws no boundary.")),
        Table("Sampled-data stability: the models", ["model", "largest stable k_e (N/m)", "margin over k_e max"],
              model_rows),
    ]
    blocks += _free_axes_blocks(a, sc)
    for note in ("periodic_note", "whole_loop_note"):          # what the analysis could not do on this scenario
        if note in a:
            blocks.append(Paragraph("Note: " + a[note] + "."))
    if rows:
        blocks.append(Table("Whole-loop stiffness limit along the path", ["path time", "largest stable k_e (N/m)",
                                                                          "margin over k_e max"], rows))
    blocks.append(figure(
        "Largest stable stiffness against the control period (1-D loop of the scenario's law, with its delay, "
        "filter and x_e error); the scenario's operating points and, at its Ts, the limit that decides the "
        "verdict (the models table's decisive row). "
        + ("The margin is the vertical distance to the boundary." if why_not_1d is None else
           f"No boundary is drawn: the 1-D model makes no prediction for this loop ({why_not_1d})."),
        sf.stiffness_limit_figure, Ts_grid, limits, points, (Ts, verdict_limit) if verdict_limit else None,
        label="1-D sampled loop", mark="deciding limit at the scenario's Ts"))
    blocks += _normal_mass_blocks(rep, sc, p)
    # python-control's state-space objects cannot be pickled (python-control#1162), and this stage may run in
    # the second process: the numbers only (analyze_scenario(sc)["systems"] rebuilds the systems)
    rep.data["sampled"] = {key: v for key, v in a.items() if key != "systems"}
    return Section("sampled", "Sampled-data analysis", blocks)


def _free_axes_blocks(a: dict, sc: Scenario) -> list:
    """The axes without contact force (``analyze``'s ``free_axes``,
    ``stability.onedim.free_axes``): each one's gains and the spectral radius
    of its sampled loop, which no stiffness changes, so one above 1 makes the
    loop unstable whatever the contact's limits say."""
    free = a.get("free_axes") or []
    if not free:
        return []
    s = sc.robot.model_mass_scale
    rows = [[ax["axis"], fmt.num(ax["kd"]), fmt.num(ax["kp"]), fmt.num(ax["spectral_radius"], 6),
             _mark(ax["spectral_radius"] < 1.0)] for ax in free]
    scale = "" if s == 1.0 else f", times the controller model's mass scale {fmt.num(s)} at the arm"
    return [Paragraph(
        "The axes that meet no contact force (the tangential ones, on a 6-D task the rotational ones, on a "
        "redundant arm the null-space posture) each close a held PD loop on a double integrator, with the "
        f"control period, the computation delay and the hold{scale}. No stiffness changes them, so an axis whose "
        "spectral radius is 1 or more makes the loop unstable at every stiffness, whatever the limits above "
        + ("say: " + a["free_axes_note"] + "." if a.get("free_axes_note") else "say; here every one is below 1.")),
        Table("Sampled-data stability: the axes without contact force",
              ["axis", "K_D (1/s)", "K_P (1/s²)", "spectral radius", "stable"], rows, verdict_column=4)]


def _normal_mass_blocks(rep: Report, sc: Scenario, p: dict) -> list:
    """The arm's effective normal mass along the path, which the 1-D limit and
    the design use (their m_p: the largest, the worst case)."""
    from ..simulation.simulator import path_of, robot_of
    from ..stability import figures as sf
    from ..stability.onedim import normal_masses

    robot = robot_of(sc)
    t, masses = path_of(robot, sc).t, np.asarray(normal_masses(sc), float)
    rep.data["normal_mass"] = {"t": t, "m_p": masses}
    return [Paragraph(
        f"The {robot.name}'s effective mass along the surface normal, m_p = 1/(nᵀ J_v M⁻¹ J_vᵀ n) at "
        f"{masses.size} poses of the path (J_v the linear rows of the Jacobian, M the joint-space inertia of "
        f"eq. 1), ranges over {fmt.qty(masses.min(), 'kg')}–{fmt.qty(masses.max(), 'kg')}; the 1-D model and the "
        f"damping design take the largest, {fmt.qty(masses.max(), 'kg')} (the sampled limit falls as m_p "
        "grows)."),
        figure(f"Effective normal mass m_p of the {robot.name} along one period of the path, with its largest "
               "value, the 1-D model's and the design's worst case.", sf.normal_mass_figure, t, masses, robot.name)]


def _constant_columns_out(caption: str, head: list[str], rows: list[list[str]], verdict_column: int | None,
                          columns: tuple[int, ...]) -> Table:
    """A :class:`Table` without those of ``columns`` whose every row holds the
    same cell (a column that never changes tells nothing row by row): each
    one is said once in the caption instead."""
    drop = [j for j in columns if len(rows) > 1 and len({r[j] for r in rows}) == 1]
    said = "; ".join(f"{head[j]}: {rows[0][j]} in every row" for j in drop)
    keep = [j for j in range(len(head)) if j not in drop]
    vc = None if verdict_column is None else keep.index(verdict_column)
    return Table(caption + (f" ({said})" if said else ""), [head[j] for j in keep],
                 [[r[j] for j in keep] for r in rows], verdict_column=vc)


def _cells(values, unit: str, sig: int = 3) -> list[str]:
    """One column's cells: one unit (and SI prefix) for the column, ``sig``
    significant digits in every cell (:func:`~tmtcontrol.fmt.column`)."""
    return fmt.column(values, unit, sig, attach=True)[1]


def _segment_rows(segs) -> list[list[str]]:
    """The per-segment table's rows, each column in one unit."""
    # an overshoot means nothing for a loop that does not settle; one over the arm's limits whose force converged
    # settles (review 21: segment 4 of the UR5 read "- (over limit)" while the law comparison gave its 100 %)
    settled = [(s.tracking_verdict or s.verdict) == "converged" for s in segs]
    over = _cells([s.overshoot_pct if ok else None for s, ok in zip(segs, settled)], "%")
    over = [o if ok else f"– ({s.verdict.replace('_', ' ')})" for o, s, ok in zip(over, segs, settled)]
    lost = _cells([s.contact_lost_time if s.contact_lost_time > 0 else None for s in segs], "s")
    lost = [c if s.contact_lost_time > 0 else "no" for c, s in zip(lost, segs)]
    # a first segment's jump is the force at its first sample: residue when the tool starts on the surface, shown 0
    # beside the forces the run holds, as simulate's table does (review 53: "3.47 x 10^-4 nN" on the Panda's bowl)
    peak = max((s.peak_force for s in segs if math.isfinite(s.peak_force)), default=0.0)
    jumps = fmt.column([s.switch_jump for s in segs], "N", 3, attach=True, reference=peak)[1]
    cols = [_cells([s.stiffness for s in segs], "", 4), jumps, over, lost,
            _cells([s.settling_time for s in segs], "s"), _cells([s.steady_state_error for s in segs], "N"),
            _cells([s.tangential_rms for s in segs], "m")]
    return [[str(i), f"{fmt.num(s.start)}–{fmt.num(s.end)}", *(c[i - 1] for c in cols), s.verdict]
            for i, s in enumerate(segs, 1)]


def _orientation_cause(seg, res, sc: Scenario) -> str:
    """What failed a 6-D segment's tracking when the force did not: its orientation error or its tool
    axis against the part's normal beyond ``controller.orientation_tolerance`` (review 53: the line said
    the force tracking failed, beside a force 650x within its tolerance); "" otherwise."""
    tol = sc.controller.orientation_tolerance
    # the union of segment_metrics' three orientation rules (e_o alone; e_o or the tilt plus the chart's normal
    # error): one of them failed the segment exactly when this holds
    if getattr(res, "orientation_error", None) is None or not (
            max(seg.orientation_error, seg.normal_tilt) + seg.chart_normal_error > tol):
        return ""
    return (f" (the tool's orientation, not the force: error {fmt.qty(seg.orientation_error, 'rad')}, axis "
            f"{fmt.qty(seg.normal_tilt, 'rad')} off the part's normal, against controller.orientation_tolerance "
            f"{fmt.qty(tol, 'rad')})")


def _simulation(rep: Report, sc: Scenario, p: dict):
    from ..simulation import figures as simf
    from ..simulation.metrics import FIRST_CONTACT_WINDOW, first_contact, orientation_transient, segment_metrics
    from ..simulation.simulator import simulator_for
    from ..simulation.simulator import SimulationError

    sim = simulator_for(sc)       # one loop for every arm; the task (3 or 6 axes) is the robot's
    blocks = []
    try:
        res = sim.run()
    except SimulationError as exc:
        rep.verdicts.append(Verdict("Force tracking within tolerance (simulation)", False, "diverged", str(exc)))
        rep.data["simulation"] = {"result": None, "error": str(exc), "segments": []}
        return Section("simulation", "Simulation", [Paragraph(f"The simulation diverged: {exc}")]), sim, None
    from ..stability.analysis import with_stiffness_limit

    res = with_stiffness_limit(res)           # a segment beyond the deciding limit is not stable
    _stop_without_contact(sc, res)
    segs = segment_metrics(res)
    worst = max(s.steady_state_error for s in segs)
    # the scenario's own tolerance judges the run (the segment verdicts use it too, plus the sensor noise)
    tol = sc.controller.force_tolerance
    # the tracking alone: a segment over the arm's limits only fails the limits' own line (below)
    bad = [i for i, s in enumerate(segs, 1) if (s.tracking_verdict or s.verdict) != "converged"]
    ok = bool(worst <= segs[0].tolerance and not bad)
    over = [i for i, s in enumerate(segs, 1) if s.verdict == "over_limit" and i not in bad]
    rep.verdicts.append(Verdict(
        "Force tracking within tolerance (simulation)", ok,
        f"worst steady-state |f_e − f_d| {fmt.qty(worst, 'N')} (tolerance {fmt.qty(tol, 'N')})",
        f"{len(segs)} segment{'s' if len(segs) > 1 else ''} simulated, "
        + ("; ".join(f"segment {i} {segs[i - 1].tracking_verdict or segs[i - 1].verdict}"
                     + _orientation_cause(segs[i - 1], res, sc) for i in bad)
           + " (not converged)" if bad else "every segment's force converged")
        + (f"; over the arm's limits (judged below): segment{'s' if len(over) > 1 else ''} "
           f"{', '.join(map(str, over))}" if over else "")))
    fc = first_contact(res)
    blocks.append(Paragraph(
        f"{fmt.qty(res.time[-1] + res.Ts, 's')} of the closed loop at {fmt.qty(1 / res.Ts, 'Hz')}, compiled, "
        "integrated with RK4 (refined where the contact switches on or off). Per segment: the switch jump is "
        "the force step the stiffness change causes on the current penetration (no controller can avoid it); "
        "the overshoot is the controller's own, after the jump (after a jump above f_d, how far the force then "
        "falls below f_d: 100 % is a contact lost, for the time in the next column). A segment 'converged' "
        "when its last quarter settles within the ripple band. The steady-state error, the tangential RMS "
        "and a 6-D arm's orientation error (against its command) and tool axis off the part's normal (at the "
        "tool point) are taken over each segment's last quarter; the last two are judged against "
        "controller.orientation_tolerance. Segment 1 starts the run: its jump is the force at its first "
        "sample."))
    head, rows = ["segment", "time (s)", "k_e (N/m)", "switch jump", "overshoot", "contact lost", "settling 2 %",
                  "steady-state |f_e − f_d|", "tangential RMS (last quarter)", "verdict"], _segment_rows(segs)
    if getattr(res, "orientation_error", None) is not None:     # a 6-D task: the orientation is judged too
        head[-1:-1] = ["orientation error", "tool axis off the part's normal"]
        for r, c, t in zip(rows, _cells([s.orientation_error for s in segs], "rad"),
                           _cells([s.normal_tilt for s in segs], "rad")):
            r[-1:-1] = [c, t]
    blocks.append(Table("Per-segment metrics", head, rows, verdict_column=len(head) - 1))
    if why := [f"segment {i} ({s.verdict.replace('_', ' ')}): {s.reason}" for i, s in enumerate(segs, 1)
               if s.verdict != "converged"]:
        # each verdict's reason as simulate prints it (review 65: a height map's chart error failed the
        # tracking verdict and the report never said why)
        blocks.append(Paragraph("Why: " + "; ".join(why) + "."))
    blocks += _limit_blocks(rep, res)
    k_touch = float(res.stiffness[0] if fc.time is None else np.interp(fc.time, res.time, res.stiffness))
    blocks.append(Table(f"First contact in the simulation (the full loop, at k_e = {fmt.num(k_touch, 4)} N/m; the "
                        "design section's first-contact overshoot is the 1-D sampled loop's, over the whole range)",
                        ["touch at", "peak force", "peak / f_d",
                         f"bounces within {fmt.qty(FIRST_CONTACT_WINDOW, 's')}" if fc.whole_window else
                         f"bounces within {fmt.qty(fc.window, 's')} (its segment's end)"],
                        [[fmt.qty(fc.time, "s") if fc.time is not None else "never", fmt.qty(fc.peak_force, "N"),
                          fmt.ratio(fc.peak_ratio), str(fc.bounces)]]))
    blocks += [
        figure("Contact force and desired force over the run (Fig. 4 of the paper), full scale.",
               simf.force_figure, res),
        figure("The force just after each segment start, zoomed: switch jump, then the controller's response.",
               simf.switch_figure, res),
        figure("Tracking errors: |f_e − f_d| (log scale) and the tangential position error within the surface.",
               simf.tracking_error_figure, res),
        figure("Environment stiffness and the TMT estimate f_e/(x − x_e) (Fig. 3).", simf.stiffness_figure, res),
        figure(f"Tool point X ({res.tool}) against "
               "the desired path on the surface (Fig. 5); the controller's reference X_r lies inside the surface by "
               "design (eq. 18) and is not drawn.", simf.position_figure, res)]
    if getattr(res, "orientation_error", None) is not None:      # a 6-D task: the tool orientation is held too
        # review 21: the run's last quarter holds a stiffness switch on the paper's profile, whose transient the
        # run's figure is; each segment's last quarter is the settled hold (the segment table's column)
        settled = max(s.orientation_error for s in segs)
        worst = float(np.max(res.orientation_error_norm[res.time >= 0.75 * res.time[-1]]))
        blocks.append(Paragraph(
            f"The tool orientation is held by the rotational axes of the 6-D task (eq. 6 with the rotational "
            f"impedance, the rotation-vector error log(R_c R^T)): the angle between the tool and its command is "
            f"at most {fmt.qty(settled, 'rad')} over the last quarter of every segment (the segment table), and "
            f"{fmt.qty(worst, 'rad')} over the last quarter of the run, with the transients of any stiffness "
            f"switch in it; over the whole run at most {fmt.qty(max(s.peak_orientation_error for s in segs), 'rad')}"
            + (f" (within a segment: {tilted})" if (tilted := orientation_transient(
                segs, sc.controller.orientation_tolerance)) else "") + "."))
        blocks.append(figure("Tool orientation error: the angle between the tool orientation and its command "
                             "(log scale).", simf.orientation_figure, res))
    if getattr(res, "posture_drift", None) is not None:          # a redundant arm: the null space is free to move
        drift = ", ".join(f"{j + 1}: {fmt.qty(d, 'rad')}" for j, d in enumerate(res.posture_drift))
        blocks.append(Paragraph(
            f"The arm is redundant for the task: the null-space posture task (robot.posture_kp, robot.posture_kd) "
            f"holds the remaining freedom near the start pose. The path returns to its start every period, so "
            f"the joints would too; how far each has drifted after whole periods (joint: largest |q(kT) − q(0)|): "
            f"{drift}."))
    from ..simulation.animation import still_figure
    from ..simulation.geometry import surface_of

    flat = ("; MuJoCo has no solid for this part and draws it as its tangent plane at the path's centre"
            if surface_of(res.scenario).primitive() is None else "")       # review 28: a flat plate "on the sphere"
    from ..simulation.simulator import robot_of

    arm = robot_of(res.scenario)
    blocks.append(figure(f"The arm ({arm.name}, {len(arm.joint_names)} joints to {arm.tip}) at the end of the run "
                         f"on the {res.traces.surface_name}, the contact force as an arrow: the last frame of simulate "
                         f"--animate (drawn by MuJoCo's renderer where it can render, else by matplotlib{flat}).",
                         still_figure, res))
    rep.data["simulation"] = {"result": res, "error": None, "segments": segs, "first_contact": fc}
    return Section("simulation", "Simulation", blocks), sim, res


def _stop_without_contact(sc: Scenario, res) -> None:
    """Raise :class:`stability.limit.NoContact` when the run never touches
    the part and the loop holds no contact at any stiffness (the deciding
    limit's own test; kept in the result cache, computed here only for a
    run without a touch): the law comparison, the design and the sweep have
    no stiffness limit to compare against, and the report stopped with that
    error in its fifth stage after the first four had run (24 s for the
    paper's loop, minutes on a 6-D arm). Any other failure of the limit is
    the sampled-data section's to report."""
    from ..simulation.metrics import touching
    from ..stability.continuous import AnalysisError
    from ..stability.limit import NoContact, deciding_limit

    if touching(res.contact_force, sc.controller.f_d).any():
        return
    try:
        deciding_limit(sc)
    except NoContact:
        raise
    except AnalysisError:
        return


def _limit_blocks(rep: Report, res) -> list:
    """The arm's torque, rate and joint-position use against its limits
    (:mod:`tmtcontrol.simulation.limits`): a table per joint, and a verdict
    when the robot or the scenario states any limit (a bound nobody set is
    not judged)."""
    use = res.limit_use() if getattr(res, "limits", None) is not None else None
    if use is None:
        return []
    L = use.limits
    judged = [k for k, on in (("torque", np.any(np.isfinite(L.tau_max))), ("rate", np.any(np.isfinite(L.dq_max))),
                              ("joint", np.any(np.isfinite(L.q_min) | np.isfinite(L.q_max)))) if on]
    if not judged:
        peaks = ", ".join(fmt.qty(v, "N m") for v in use.peak_torque)
        return [Paragraph(f"The robot states no torque, rate or joint limits (the paper's PUMA parameter set has "
                          f"none), so none is judged; peak |tau| per joint {peaks}. Set robot.tau_max and "
                          "robot.dq_max to judge the run against the drives.")]

    def pct(x):          # review 53: a margin of -1.9e-6 read "-0.0 %"; 3 significant digits tell its sign
        return "none" if not np.isfinite(x) else fmt.pct(100 * x)

    rows = [[f"{j + 1} ({L.names[j]})", fmt.qty(use.peak_torque[j], L.unit("torque", j)),
             # a stated limit to 4 digits (review 53: the Panda's 2.175 rad/s read 2.17)
             fmt.qty(L.tau_max[j], L.unit("torque", j), 4) if np.isfinite(L.tau_max[j]) else "none",
             pct(use.torque_margin[j]), fmt.qty(use.peak_rate[j], L.unit("rate", j)),
             fmt.qty(L.dq_max[j], L.unit("rate", j), 4) if np.isfinite(L.dq_max[j]) else "none",
             pct(use.rate_margin[j]),
             fmt.qty(use.position_margin[j], L.unit("position", j)) if np.isfinite(use.position_margin[j]) else "none"]
            for j in range(len(L.names))]
    head = ["joint", "peak |tau|", "tau_max", "torque margin", "peak |dq|", "dq_max", "rate margin",
            "to the nearest joint end"]
    if L.saturate:
        head.append("on the torque clip")
        for r, s in zip(rows, use.saturated):
            r.append(fmt.qty(s, "s"))
    rep.verdicts.append(Verdict(                      # named after the limits judged (a PUMA with only tau_max)
        f"Within the arm's {' and '.join([', '.join(judged[:-1]), judged[-1]] if len(judged) > 1 else judged)} "
        "limits (simulation)", use.ok,
        f"least torque margin {pct(float(np.min(use.torque_margin)))}, least rate margin "
        f"{pct(float(np.min(use.rate_margin)))}" + (f"; {use.summary()}" if not use.ok else ""),
        f"every sample of the run against the limits less robot.limit_margin = {L.margin:g}"
        + ("; the drive clips the torque (robot.saturate)" if L.saturate else "")))
    from ..simulation.figures import limit_use_figure

    return [Table("The arm's limits over the run: peaks, limits and the margin left (1 − peak/limit)", head, rows),
            figure("Joint torques and rates as fractions of their limits over the run (joints with a stated "
                   "limit); above the dashed line (1 − robot.limit_margin) a drive faults or clips.",
                   limit_use_figure, res)]


def _worst(values) -> float:
    """The largest of ``values``; NaN if any is NaN (undefined, or never
    reached: the worst, not skipped as Python's ``max`` skips a NaN that
    does not come first)."""
    values = [float(v) for v in values]
    return math.nan if any(math.isnan(v) for v in values) else max(values)


def _worst_settling(segs) -> str:
    """The longest 2 % settling time; "never" if a segment does not settle
    (its settling time is NaN, which must not be skipped as the smallest)."""
    t = _worst(s.settling_time for s in segs)
    return "never" if math.isnan(t) else fmt.qty(t, "s")


def _comparison(rep: Report, sc: Scenario):
    from ..simulation import figures as simf
    from ..simulation.compare import compare_laws

    from ..stability.limit import with_stiffness_limit

    # each law's run judged against its loop's limit, as `tmtcontrol compare` judges it (review 60: a segment
    # beyond the limit read "off target" here and "beyond the limit" in the simulation's table)
    cmp = compare_laws(sc, prepare=with_stiffness_limit)
    runs = [(name + (" (scenario's)" if name == sc.controller.law.kind else ""), run) for name, run in cmp.runs.items()]
    ok = [run.result is not None for _, run in runs]
    def worst_of(name):
        # NaN (a segment that never settles, an overshoot withheld) is the worst, never skipped: Python's max
        # drops a NaN that is not first (review 15: the known law's "worst settling 233 ms" hid a segment
        # that never settles)
        return [_worst([getattr(s, name) for s in run.segments]) if good else None
                for (_, run), good in zip(runs, ok)]

    worst, settle = worst_of("steady_state_error"), worst_of("settling_time")
    err = _cells(worst, "N")
    over = _cells(worst_of("overshoot_pct"), "%")
    settling = _cells([None if t is None or math.isnan(t) else t for t in settle], "s")
    tang = _cells(worst_of("tangential_rms"), "m")
    rows, over_limit = [], []
    for i, (label, run) in enumerate(runs):
        if run.result is None:
            rows.append([label, "–", "no", "–", "–", "–", "diverged"])
            continue
        if run.verdict == "over_limit":
            over_limit.append(label)
        # the force tracking's verdict (review 21: over_limit, which outranks off_target, hid the known law's
        # wrong force on the UR5 behind the same "over a limit" as every other law's)
        rows.append([label, err[i], "yes" if worst[i] <= sc.controller.force_tolerance else "no", over[i],
                     "never" if math.isnan(settle[i]) else settling[i], tang[i], run.tracking_verdict])
    rep.data["comparison"] = cmp
    every = len(over_limit) == len(rows)
    limits = ("" if not over_limit else
              f" The verdict is the force tracking's; {'every law' if every else ', '.join(over_limit)} also "
              f"{'exceeds' if every or len(over_limit) == 1 else 'exceed'} the arm's limits (over_limit), judged "
              "as for the scenario's own run.")
    return Section("comparison", "Law comparison", [
        Paragraph("Every registered force-tracking law on the same scenario, each with its documented default "
                  "parameters (the scenario's own law with the scenario's). Worst values over the segments. "
                  "The verdict says whether the loop settles; whether it settles on f_d is the tolerance "
                  f"column (the scenario's tracking tolerance, {fmt.qty(sc.controller.force_tolerance, 'N')})."
                  + limits),
        _constant_columns_out(
            "Force-tracking laws on this scenario",
            ["law", "worst steady-state error", f"within {fmt.qty(sc.controller.force_tolerance, 'N')}",
             "worst overshoot", "worst settling 2 %", "worst tangential RMS", "verdict"], rows, 6, (3, 4)),
        figure("Contact force of every law.", simf.comparison_force_figure, cmp),
        figure("Force error of every law (log scale).", simf.comparison_error_figure, cmp)])


def _independent_plant(rep: Report, sc: Scenario):
    """The scenario on MuJoCo's dynamics of the same URDF against the
    built-in plant (``simulation.crosscheck``): per segment each plant's
    steady-state error and verdict, both force traces, the largest
    difference; the verdict "the plants agree" (issue 41's report section,
    ``report --plant mujoco``)."""
    from ..simulation.crosscheck import crosscheck
    from ..simulation.figures import crosscheck_figure
    from ..stability.analysis import with_stiffness_limit

    memo: dict = {}
    c = crosscheck(sc, prepare=lambda r: with_stiffness_limit(r, memo=memo))     # simulate's verdicts
    info = c.mujoco.info
    rows = [[str(i), f"{fmt.num(r['start'])}–{fmt.num(r['end'])}", fmt.num(r["stiffness"], 4),
             fmt.qty(r["steady_state_error_builtin"], "N"), fmt.qty(r["steady_state_error_mujoco"], "N"),
             f"{fmt.qty(r['peak_force_builtin'], 'N')} / {fmt.qty(r['peak_force_mujoco'], 'N')}",
             f"{fmt.qty(r['settling_time_builtin'], 's')} / {fmt.qty(r['settling_time_mujoco'], 's')}",
             r["verdict_builtin"], r["verdict_mujoco"], fmt.qty(r["steady_force_difference"], "N"),
             "PASS" if r["agree"] else "FAIL"]
            for i, r in enumerate(c.segments, 1)]
    # what the agreement is judged on first (review 63: the row quoted the run's largest difference, a first
    # contact's transient, the same size on a passing run as on a failing one)
    worst = max(range(len(c.segments)), key=lambda i: c.segments[i]["steady_force_difference"])
    value = (f"largest steady-state force difference {fmt.qty(c.segments[worst]['steady_force_difference'], 'N')} "
             f"(segment {worst + 1}; tolerance {fmt.qty(c.tolerance, 'N')}), over the whole run "
             f"{fmt.qty(c.max_force_difference, 'N')} at {c.time_of_max:.3f} s")
    rep.verdicts.append(Verdict("The built-in and MuJoCo plants agree", c.agree, value,
                                "simulation.crosscheck (same verdicts, the forces over each segment's steady-state "
                                f"window within {fmt.qty(c.tolerance, 'N')})"))
    rep.data["crosscheck"] = c.as_dict()
    return Section("mujoco", "Independent plant: MuJoCo", [
        Paragraph(f"The scenario's controller against MuJoCo {info.get('mujoco', '')}'s dynamics of the same URDF "
                  f"({info['plant'][len('mujoco ('):-1]}; {info['integrator']}), judged by the same rules as the "
                  "built-in run. The plants agree when every segment has the same verdict on both and their "
                  "contact forces over its steady-state window (the last quarter) differ by at most "
                  f"{fmt.qty(c.tolerance, 'N')} "
                  "(docs/mujoco.md). " + value[0].upper() + value[1:] + "."),
        Table("Segments on both plants", ["segment", "t (s)", "k_e (N/m)", "steady-state error, built-in",
                                          "steady-state error, MuJoCo", "peak force, built-in / MuJoCo",
                                          "settling 2 %, built-in / MuJoCo", "verdict, built-in",
                                          "verdict, MuJoCo", "steady-state |Δf|", "agree"], rows,
              verdict_column=10),
        figure("Contact force on the built-in plant and on MuJoCo's.", crosscheck_figure, c)])


def _round2(v: float) -> float:
    """``v`` to two significant digits (axis values a reader can quote)."""
    return float(f"{v:.2g}")


def sweep_axes(sc: Scenario, p: dict, loop_limit=None) -> tuple[list[float], list[float], str]:
    """The report sweep's axes, from the scenario: its control rate and half
    of it (Hz; the slower side is where stability is lost), and
    :data:`SWEEP_POINTS` constant stiffnesses (N/m, two significant digits)
    evenly spaced in log from half its smallest k_e to twice the larger of
    its largest k_e and the 1-D small-signal limit at its rate (the
    boundary is inside the map whenever the analysis finds one; the 1-D
    small-signal figure sizes the map, the cases' own deciding limits draw
    its line). Without a 1-D prediction (the mid-period hold) the loop's own
    deciding limit sizes it instead: ``loop_limit``, N/m or a function
    giving it (called only then; review 21: the pipe's map ended at 200,000
    N/m, below its 603,000 N/m limit); without either (a law without a linear
    verdict, a limit that could not be computed), ten times its largest
    k_e. The third item says which rule sized it, for the report's text."""
    from ..stability.analysis import scenario_stiffness_limit

    rate = 1.0 / p["Ts"]
    try:
        limit = scenario_stiffness_limit(sc, p)
    except Exception:                 # no linear verdict for this law: the range's neighbourhood only
        limit = None
    predicted = limit is not None and math.isfinite(limit)
    rule = "half the scenario's smallest stiffness to twice the larger of its largest and the 1-D small-signal limit"
    if not predicted:
        limit = loop_limit() if callable(loop_limit) else loop_limit
        predicted = limit is not None and math.isfinite(limit) and limit > 0
        rule = ("half the scenario's smallest stiffness to twice the larger of its largest and the loop's own "
                "deciding limit (the 1-D model gives no prediction for this loop)" if predicted else
                "half the scenario's smallest stiffness to ten times its largest: neither the 1-D model nor the "
                "loop's analysis gives a prediction for this loop")
    top = max(p["k_e_max"], limit if predicted else p["k_e_max"] * 5)
    lo, hi = p["k_e_min"] / 2, 2 * top
    stiffness = sorted({_round2(v) for v in np.geomspace(lo, hi, SWEEP_POINTS)})
    return stiffness, [rate, rate / 2], rule


def _loop_limit(sc: Scenario) -> float | None:
    """The scenario's deciding limit (N/m; ``stability.limit.deciding_limit``,
    kept in the result cache: the sampled-data section reads it again), None
    where it cannot be computed."""
    from ..stability.continuous import AnalysisError
    from ..stability.limit import deciding_limit

    try:
        lim = deciding_limit(sc)
    except AnalysisError:
        return None
    return None if lim is None else float(lim.limit)


def _sweep(rep: Report, sc: Scenario, p: dict):
    from ..sweep import sweep_prediction, axis_labels, run_sweep, sweep_summary
    from ..sweep.figures import sweep_map_figure
    from ..simulation.scenario import apply_overrides, scenario_to_dict
    from ..sweep.spec import sweep_from_dict

    cycles = min(sc.trajectory.cycles, SWEEP_CYCLES)
    stiffness, rates, rule = sweep_axes(sc, p, loop_limit=lambda: _loop_limit(sc))
    spec = sweep_from_dict({"grid": {"environment.stiffness.values": [[v] for v in stiffness],
                                     "controller.rate": rates}})
    # the axes on this scenario (shortened)
    spec = dataclasses.replace(spec, base=scenario_to_dict(apply_overrides(sc, [f"trajectory.cycles={cycles!r}"])))
    df = run_sweep(spec)
    pred = sweep_prediction(spec, df)
    counts = {v: n for v, n in sweep_summary(spec, df, pred)["verdicts"].items() if n}
    rows = []
    for rate in rates:
        d = df[df["controller.rate"] == rate]
        errs = _cells(list(d["max_steady_error"]), "N")
        for (_, r), err in zip(d.iterrows(), errs):
            rows.append([f"{fmt.num(rate, 4)}{fmt.NBSP}Hz", fmt.num(r["environment.stiffness.values"]), err,
                         r["verdict"]])
    rep.data["sweep"] = {"frame": df, "predicted": pred, "stiffness": stiffness, "rates": rates}
    return Section("sweep", "Robustness sweep", [
        Paragraph(f"{len(df)} simulations of {fmt.qty(cycles * sc.trajectory.period, 's')} each: constant "
                  f"stiffness from {fmt.qty(stiffness[0], 'N/m')} to {fmt.qty(stiffness[-1], 'N/m')} ({rule}) × "
                  f"the scenario's control rate {fmt.qty(rates[0], 'Hz')} and half of it, everything else as in "
                  "the scenario. Verdicts: "
                  + ", ".join(f"{n} {v}" for v, n in counts.items()) + ". The dashed line is the deciding limit at each rate "
                  "(as analyze --scenario prints it: the smallest of the cases' own at that rate); a simulated "
                  "verdict on the wrong side of it would show a model error. "
                  "Larger sweeps: tmtcontrol sweep (see the Robustness sweeps page)."),
        Table("Sweep cases", ["control rate", "k_e (N/m)", "worst steady-state error", "verdict"], rows,
              verdict_column=3),
        figure("Sweep map: verdict (marker) and steady-state error (colour) over stiffness and control rate, with "
               "the deciding stability limit.", sweep_map_figure, df, list(spec.axes[:2]), pred, units=spec.units,
               labels=axis_labels(spec))])


def _design(rep: Report, sc: Scenario, p: dict, sim, res):
    from ..simulation.metrics import segment_metrics
    from ..simulation.simulator import SimulationError
    from ..stability import figures as sf
    from ..simulation.metrics import VERDICTS
    from ..stability.limit import with_stiffness_limit
    from ..stability.design import (DesignError, DesignInfeasible, check_impedance, damping_alternatives,
                                    design_impedance, scenario_design_spec, with_scenario_loop)

    if not p["k_e_max"] > p["k_e_min"]:
        return Section("design", "Damping design", [Paragraph("A single stiffness: no range to design over.")])
    # as tmtcontrol design --scenario: the path's largest effective normal mass, the scenario's overshoot
    # requirement (else the design's default target, not a verdict)
    spec = scenario_design_spec(sc, p)
    stated = sc.requirements.first_contact_overshoot
    # the scenario's own damping is judged only against a bound the scenario states; the optimum is a proposal
    b_run = sc.impedance.b[0]
    info = []
    if sc.controller.damping_schedule.kind == "off":
        own = check_impedance(spec, b_run, p["k"])
        where = (f"first-contact overshoot of the 1-D sampled loop (the path's largest normal mass "
                 f"{fmt.qty(spec.m_p, 'kg')}) at k_e = {fmt.num(own.worst_stiffness, 4)} N/m, the worst of 60 "
                 f"stiffnesses over the range")
        # review 60: the 1-D loop past its own limit has no overshoot to quote (it grows), and under the
        # mid-period hold it is not the run's loop: neither is a verdict on the scenario's damping
        unstable = own.sampled_limit < spec.k_e_max
        if stated is not None and (unstable or sc.controller.hold != "zero_order"):
            why = (f"the 1-D sampled loop is unstable above {fmt.num(fmt.down(own.sampled_limit, 4), 4)} N/m, inside "
                   f"the range (to {fmt.num(spec.k_e_max, 4)} N/m): it grows there, no overshoot to compare"
                   if unstable else
                   f"the design's 1-D sampled loop has the zero-order hold, the run the "
                   f"{sc.controller.hold.replace('_', '-')} one")
            info.append(Paragraph(
                f"requirements.first_contact_overshoot ({fmt.num(stated)} %) is not judged for the scenario's "
                f"damping b = {fmt.qty(b_run, 'N s/m', 4)}: {why}. The simulation section shows the run's own first "
                "contact."))
        elif stated is not None:
            rep.verdicts.append(Verdict(
                f"Scenario's damping within requirements.first_contact_overshoot (b = {fmt.qty(b_run, 'N s/m', 4)})",
                own.passed, f"{where}: {fmt.against(own.worst_overshoot, spec.max_overshoot)} % "
                f"(requirement {fmt.num(spec.max_overshoot)} %, stated by the scenario)",
                "the scenario's b on the sampled loop" + ("" if own.passed else "; violated: "
                                                          + "; ".join(own.violations))))
        else:
            info.append(Paragraph(
                f"The scenario's damping b = {fmt.qty(b_run, 'N s/m', 4)}: {where}, "
                f"{fmt.num(own.worst_overshoot, 3)} %. Not judged: the scenario states no "
                "requirements.first_contact_overshoot (the paper claims stability and f_e → f_d, which the "
                "verdicts above judge, not an overshoot bound)."))
        rep.data["design_check"] = own
    try:
        d = design_impedance(spec)
    except (DesignError, DesignInfeasible) as exc:
        return Section("design", "Damping design", [Paragraph(f"No design meets the bounds: {exc}")])
    # verified on the scenario's own loop as `tmtcontrol design --scenario` does (review 60: a proposal that
    # diverged under the mid-period hold stood as meeting the bound)
    d = with_scenario_loop(sc, d)
    if d.violations:
        info.append(Paragraph(
            f"The proposed b = {fmt.qty(d.b, 'N s/m', 4)} fails its verification on this scenario's loop: "
            + "; ".join(d.violations) + " (as tmtcontrol design --scenario, which exits 1 on it). Do not use it "
            "as is."))
    bound = spec.max_overshoot
    rows = [["optimal (IPOPT)", fmt.num(d.b, 4), fmt.num(d.objective), f"{fmt.against(d.worst_overshoot, bound)} %"],
            ["eq. (25) at k_e max", fmt.num(d.baseline_b, 4), fmt.num(d.baseline_objective), "0 % (continuous)"]]
    if "design_check" in rep.data:
        own = rep.data["design_check"]
        # review 28: under the mid-period hold this row is the 1-D zero-order loop's, not the run's
        rows.append(["the scenario's b" + (" (its 1-D zero-order-hold loop; the run has the mid-period hold)"
                                           if sc.controller.hold == "mid_period" else " (as run)"),
                     fmt.num(own.b, 4), "–",
                     f"{fmt.against(own.worst_overshoot, bound)} %"])
    sim_rows = []
    if res is not None:
        for name, alt in damping_alternatives(sc, d).items():
            try:
                segs = segment_metrics(with_stiffness_limit(sim.run(alt)))      # as the simulation's (review 60)
            except SimulationError:
                sim_rows.append([name, "–", "–", "diverged"])
                continue
            verdict = max((s.verdict for s in segs), key=VERDICTS.index)
            sim_rows.append([name, _worst(s.overshoot_pct for s in segs), _worst(s.steady_state_error for s in segs),
                             verdict])
    # each number column in one unit, to the same significant digits (0.00210 % beside 0.00211 %)
    over = _cells([r[1] if r[3] != "diverged" else None for r in sim_rows], "%")
    err = _cells([r[2] if r[3] != "diverged" else None for r in sim_rows], "N")
    sim_rows = [[r[0], over[i], err[i], r[3]] if r[3] != "diverged" else r for i, r in enumerate(sim_rows)]
    blocks = [
        *info,
        Paragraph("The normal-axis damping b chosen to minimise the worst-case integral squared force error "
                  f"of the sampled loop over the stiffness range, with first-contact overshoot at most "
                  f"{fmt.num(spec.max_overshoot)} % ("
                  + ("the scenario's requirements.first_contact_overshoot" if stated is not None
                     else "the design's default target; set requirements.first_contact_overshoot to state your own")
                  + "), against eq. (25)'s critical damping at the stiffest surface. The design's overshoot is that "
                  "of the first-contact response of the 1-D sampled loop; the simulated overshoot is the "
                  "controller's after each stiffness switch on the full robot (the per-segment metric of the "
                  "simulation), a different transient."),
        Table("Damping designs", ["design", "b (N s/m)", "worst-case ISE (N² s)", "worst first-contact overshoot"],
              rows)]
    if sim_rows:
        blocks.append(_constant_columns_out("The designs simulated on this scenario",
                                            ["damping", "worst overshoot after a switch", "worst steady-state error",
                                             "verdict"], sim_rows, 3, (1,)))
    blocks.append(figure("Worst-case cost against b, the optimum and the eq. (25) design marked; below, the worst "
                         f"first-contact overshoot of the sampled loop against b and its {fmt.num(spec.max_overshoot)} % "
                         "bound: the shaded b break it, which is why the optimum lies right of the cost's minimum.",
                         sf.design_cost_figure, d))
    rep.data["design"] = d
    return Section("design", "Damping design", blocks)


def _scenario_section(sc: Scenario) -> Section:
    from ..simulation.simulator import robot_of, robot_task

    robot = robot_of(sc)
    task = robot_task(robot)
    rows = [[r.key, "unset" if r.value is None else fmt.value(r.value), r.unit or "–", r.meaning or "chosen kind"]
            for r in applicable_settings(sc, task)]
    return Section("scenario", "Scenario", [
        # the arm as it runs (review 62: a UR5 cut at wrist_1_link read "ur5" everywhere but one settings row)
        Paragraph(f"The arm: {robot.name}, {task.n} actuated joints from {robot.base} to {robot.tip} "
                  f"(the tool's {task.words}). The keys that apply to this scenario's options (SI units)."),
        Table("Scenario settings", ["key", "value", "unit", "meaning"], rows)])


def _repro(rep: Report, formats: tuple[str, ...]) -> Section:
    from ..simulation.simulator import robot_of

    sc = rep.scenario
    # python's among them; the renderers of the formats written and the URDF parser where a URDF was read
    # (review 60: WeasyPrint's version sets the PDF's layout; review 63: none of them for what did not run),
    # MuJoCo's where its plant ran
    used = ("jinja2", *(("weasyprint",) if "pdf" in formats else ()),
            *(("urdfdom-py",) if robot_of(sc).urdf is not None else ()),
            *(("mujoco",) if "crosscheck" in rep.data else ()))
    made = rep.data.get("provenance") or provenance()
    rows = [["date", made["date"]], ["source", made["source"]], ["command", rep.command_line],
            ["scenario SHA-256 (its TOML)", hashlib.sha256(dump_scenario(sc).encode()).hexdigest()],
            ["sensor noise seed", str(sc.sensor.seed) if sc.sensor.noise_std > 0 else "no noise"],
            ["derivation check seed", "2024"],
            *[[k, "not installed" if v is None else str(v)] for k, v in versions(used).items()],
            *[[f"stage: {k}", fmt.qty(v, "s")] for k, v in rep.timings.items()]]
    return Section("reproducibility", "Reproducibility", [
        Paragraph("Run the command with the same package versions to reproduce every number; the scenario's "
                  "TOML (tmtcontrol scenario) hashes to the value below."),
        Table("Reproducibility", ["item", "value"], rows)])


def _one_blas_thread():
    """The report's linear algebra is on small matrices, where BLAS threads
    only cost: with two processes busy, spinning BLAS threads on 2 cores made
    the sampled stage 3x slower. One thread per process, for the block
    (:func:`tmtcontrol.processes.blas_threads_limited`)."""
    from ..processes import blas_threads_limited

    return blas_threads_limited()


_CONTROL_TASKS = ("sampled-data analysis", "checks: loop", "checks: derivations", "continuous-time analysis")
"""The tasks that use python-control, longest first (0.8 s to 0.3 s here).
Importing it takes ~0.8 s; only the second process does."""


def _remote_tasks(sc: Scenario | None = None) -> list[str]:
    """Work that needs nothing from this process' stages, in the order the
    second process takes it: first :data:`_CONTROL_TASKS`, then the others
    (one check group per law, the scenario's arm model and its loop, ~0.1 s each, the law
    comparison, the sweep)
    shortest first. This process runs its own stages, then takes tasks last
    first (the longest of the others first; see :func:`_claim`), but none of
    :data:`_CONTROL_TASKS`: it never imports python-control. The two meet
    among the short tasks, so they end within about one of each other."""
    from ..checks import check_groups

    short = [f"checks: {g}" for g in check_groups(sc) if g.startswith("law: ") or g in ("model", "arm")]
    return [*_CONTROL_TASKS, *short, "law comparison", "robustness sweep"]


_PRELOAD = ("matplotlib.figure", "matplotlib.backends.backend_svg", "tmtcontrol.stability.analysis",
            "tmtcontrol.stability.design", "tmtcontrol.stability.figures", "tmtcontrol.simulation.compare",
            "tmtcontrol.simulation.figures", "tmtcontrol.sweep", "tmtcontrol.sweep.figures",
            "tmtcontrol.checks.derivations", "tmtcontrol.checks.laws", "tmtcontrol.checks.loop",
            "tmtcontrol.report.slimsvg")
"""Modules both processes need, imported before the second one is forked so
that it inherits them (not python-control: only the second process uses it)."""

_TASKS: dict[str, Callable] = {
    "continuous-time analysis": lambda rep, sc, p: _continuous(rep, p),
    "sampled-data analysis": lambda rep, sc, p: _sampled(rep, sc, p),
    "law comparison": lambda rep, sc, p: _comparison(rep, sc),
    "robustness sweep": lambda rep, sc, p: _sweep(rep, sc, p),
}


def _on_own(sc: Scenario, stage: Callable, *args):
    """Run ``stage(report, *args)`` on a report of its own: its return value,
    the verdicts it added and its data (merged by the caller, whichever
    process ran it)."""
    own = Report(sc, "")
    return stage(own, *args), own.verdicts, own.data


def _task(name: str, sc: Scenario, p: dict):
    """Run one of :func:`_remote_tasks` (in either process) on the scenario
    ``sc`` with its analysis parameters ``p``: its output (a section, or a
    check group's results), verdicts, data and time."""
    from ..checks import kept_check_group

    t0 = time.perf_counter()
    if name.startswith("checks: "):
        output, verdicts, data = kept_check_group(name.removeprefix("checks: "), scenario=sc), [], {}
    else:
        output, verdicts, data = _on_own(sc, _TASKS[name], sc, p)
    return output, verdicts, data, time.perf_counter() - t0


_SHARED: dict = {}
"""In each process: ``claims``, the shared ``[first, end)`` of the tasks not
yet taken (a process-shared array with its lock), and ``tasks``, their names;
set by the pool's initializer."""


def _share(claims, tasks) -> None:
    """The second process' initializer: it dies with this one, even one
    killed by SIGKILL, and has one BLAS thread for its lifetime
    (:func:`tmtcontrol.processes.worker_init`; this process holds
    :func:`_one_blas_thread` around the stages; setting it per task cost
    12 ms each, threadpoolctl scanning the loaded libraries); then the
    claims."""
    from ..processes import worker_init

    worker_init()
    _SHARED.update(claims=claims, tasks=tasks)


def _claim(claims, last: bool = False, floor: int = 0) -> int | None:
    """Take the first (or, ``last``, the last) task nobody has taken: its
    index in the task list, or None if none is left (with ``last``, also if
    the last one left has an index below ``floor``)."""
    with claims.get_lock():
        first, end = claims[0], claims[1]
        if first >= end or (last and end - 1 < floor):
            return None
        if last:
            claims[1] = end - 1
            return end - 1
        claims[0] = first + 1
        return first


def _pull(sc: Scenario, p: dict):
    """In the second process: run the next task nobody has taken, if any;
    ``(name, output)`` or None."""
    i = _claim(_SHARED["claims"])
    return None if i is None else (_SHARED["tasks"][i], _task(_SHARED["tasks"][i], sc, p))


@contextlib.contextmanager
def frozen_gc():
    """For the block, the objects alive now are out of the cyclic garbage
    collector's reach (``gc.freeze``; ``gc.unfreeze`` after, which also
    returns anything frozen earlier: tmtcontrol freezes only here and, for
    good, at the command line's exit). A report's imports and results live
    until it is written: walking them again at every full collection cost
    0.3-0.5 s per process. Before a fork it is also what the ``gc``
    documentation advises (the child's collections do not write to the
    parent's pages)."""
    import gc

    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextlib.contextmanager
def _background(sc: Scenario | None = None):
    """A second process for :func:`_remote_tasks`, and the claims both
    processes take them by: on Linux forked after :data:`_PRELOAD` is
    imported (it inherits the imports and ends without an interpreter
    teardown), elsewhere a fresh interpreter; a thread if processes are
    unavailable. The imports are frozen out of the collector's reach
    (:func:`frozen_gc`) until the block ends."""
    import concurrent.futures
    import importlib
    import multiprocessing

    for module in _PRELOAD:
        importlib.import_module(module)
    linux_fork = sys.platform.startswith("linux") and "fork" in multiprocessing.get_all_start_methods()
    ctx = multiprocessing.get_context("fork" if linux_fork else "spawn")
    tasks = _remote_tasks(sc)
    claims = ctx.Array("i", [0, len(tasks)])
    with frozen_gc():
        try:
            pool = concurrent.futures.ProcessPoolExecutor(1, mp_context=ctx, initializer=_share,
                                                          initargs=(claims, tasks))
        except (OSError, ImportError, NotImplementedError):
            pool = concurrent.futures.ThreadPoolExecutor(1, initializer=_share, initargs=(claims, tasks))
        try:
            yield pool, claims, tasks
        except BaseException:       # Ctrl-C, SIGTERM, an error: the second process' task is not wanted
            _stop_workers(pool)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


STOP_GRACE = 1.0
"""Seconds the second process is given to end its task after SIGTERM (its
handler stops the task with KeyboardInterrupt, so a build folder is cleaned
up and a compiler is killed) before SIGKILL."""


def _stop_workers(pool) -> None:
    """End the second process of ``pool`` now (SIGTERM, then SIGKILL after
    :data:`STOP_GRACE` s), instead of waiting for its task: a Ctrl-C to
    ``report``'s own process waited for the task it was running (up to a
    minute on a cold compile cache). Nothing for a thread pool."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    deadline = time.monotonic() + STOP_GRACE
    for proc in procs:
        proc.join(max(0.0, deadline - time.monotonic()))
        if proc.is_alive():
            proc.kill()
            proc.join()


def _stages(rep: Report, sc: Scenario, p: dict, background, out: dict, verdicts: dict, say: Callable,
            prepare: Callable | None) -> None:
    """Run the stages: the second process takes the remote tasks in order,
    one when it is free, while this one runs the simulation and then the
    design (which simulates its alternatives with the simulation's compiled
    simulator); then this one takes what is left, last first, after calling
    ``prepare()``. Each stage is reported as it ends, with its own time; its
    verdicts go to ``verdicts[stage]``, its data to ``rep.data``."""
    import concurrent.futures

    from ..processes import signals_held

    pool, claims, tasks = background
    with signals_held():            # the second process forks at the first submit; Ctrl-C waits for its handler
        pulls = [pool.submit(_pull, sc, p) for _ in tasks]      # each takes a task when it starts
    done = 0

    def finished(name, seconds):
        nonlocal done
        done += 1
        rep.timings[name] = seconds
        say(done, len(STAGES), name, seconds)

    t0 = time.perf_counter()
    (out["simulation"], sim, res), verdicts["simulation"], data = _on_own(sc, _simulation, sc, p)
    rep.data.update(data)
    finished("simulation", time.perf_counter() - t0)
    t0 = time.perf_counter()
    out["design"], verdicts["design"], data = _on_own(sc, _design, sc, p, sim, res)
    rep.data.update(data)
    finished("design", time.perf_counter() - t0)

    results = {}
    from ..checks import check_groups

    groups = [f"checks: {g}" for g in check_groups(sc)]     # all_checks' order, whoever runs them

    def arrived(task):
        if task in groups:
            if all(g in results for g in groups):
                finished("derivation checks", sum(results[g][3] for g in groups))
        else:
            finished(task, results[task][3])

    if prepare is not None:                 # the caller's work, shared out like the rest
        prepare()
    # what nobody has taken, last first, short of the tasks that use python-control
    while (i := _claim(claims, last=True, floor=len(_CONTROL_TASKS))) is not None:
        results[tasks[i]] = _task(tasks[i], sc, p)
        arrived(tasks[i])
    for f in concurrent.futures.as_completed(pulls):
        if (taken := f.result()) is not None:
            results[taken[0]] = taken[1]
            arrived(taken[0])
    for task in tasks:                              # in a fixed order, whichever process ran them
        output, task_verdicts, data, _ = results[task]
        rep.data.update(data)
        if task not in groups:
            out[task], verdicts[task] = output, task_verdicts
    out["derivation checks"], verdicts["derivation checks"], data = _on_own(
        sc, _checks, [r for g in groups for r in results[g][0]])
    rep.data.update(data)


_VERDICT_ORDER = ("derivation checks", "continuous-time analysis", "sampled-data analysis", "simulation", "design",
                  "law comparison", "robustness sweep", "independent plant")
"""The order of the verdict summary: by stage, whichever process ran it."""


def build_report(scenario: Scenario, command_line: str = "", progress: Callable | None = None,
                 prepare: Callable | None = None, plant: str = "builtin") -> Report:
    """Run every stage for ``scenario`` and collect the document.

    ``progress(i, n, name, seconds)`` is called as each stage ends, with the
    stage's own time. ``prepare()`` (optional) is called once, when this
    process has run its own stages and before it takes its share of the
    second one's tasks: the caller's preparation for writing (such as
    importing the PDF renderer), done while the other process computes.
    ``plant="mujoco"``: one more stage, "independent plant", the scenario
    on MuJoCo's dynamics against the built-in plant (a section and a
    verdict; the MuJoCo extra must be installed)."""
    from ..stability import scenario_parameters

    if plant not in ("builtin", "mujoco"):             # refused before anything is computed
        raise ValueError(f"plant: expected 'builtin' or 'mujoco', got {plant!r}")
    from ..stability.analysis import check_linear_verdict

    check_linear_verdict(scenario)              # review 72: the sampled-data stage refused it after four others
    rep = Report(scenario, command_line or shlex.join(sys.argv))
    rep.data["provenance"] = provenance()
    # every stage counts the independent plant's among n (the eighteenth session: with MuJoCo the first
    # seven said n = 7 and the last 8 of 8)
    n = len(STAGES) + (plant == "mujoco")
    say = (lambda i, _n, name, s: progress(i, n, name, s)) if progress else (lambda *a: None)
    p = scenario_parameters(scenario)
    rep.data["parameters"] = p
    out: dict = {}
    verdicts: dict = {}
    with _background(scenario) as background, _one_blas_thread():
        _stages(rep, scenario, p, background, out, verdicts, say, prepare)
    extra = []
    if plant == "mujoco":
        t0 = time.perf_counter()
        section, verdicts["independent plant"], data = _on_own(scenario, _independent_plant, scenario)
        rep.data.update(data)
        extra = [section]
        rep.timings["independent plant"] = time.perf_counter() - t0
        say(n, n, "independent plant", rep.timings["independent plant"])
    rep.verdicts = [v for stage in sorted(verdicts, key=_VERDICT_ORDER.index) for v in verdicts[stage]]
    summary = Section("summary", "Verdict summary", [Table(
        "Verdicts", ["verdict", "result", "number", "computed by"],
        [[v.name, _mark(v.passed), v.value, v.check] for v in rep.verdicts], verdict_column=1)])
    rep.sections = [summary, _scenario_section(scenario), out["derivation checks"], out["continuous-time analysis"],
                    out["sampled-data analysis"], out["simulation"], out["law comparison"], out["robustness sweep"],
                    out["design"], *extra]
    return rep


def finish(rep: Report, formats: tuple[str, ...] | str) -> None:
    """Add the reproducibility section (after the timings are known), naming
    the renderers of ``formats``, the formats being written (one format may
    be given as a string: review 67, "pdf" read as the letters p, d, f)."""
    formats = (formats,) if isinstance(formats, str) else tuple(formats)
    rep.sections = [s for s in rep.sections if s.key != "reproducibility"] + [_repro(rep, formats)]
