"""Stability report: derivation checks, continuous and sampled-data stability,
design comparison and simulation of one scenario, as self-contained HTML and PDF.

The top of the data path: it calls the checks (``derivations``), the analysis
(``stability``, eqs. 22/25 and the sampled loop), the design (``design``),
the simulator and the figures (``plots``), and renders

* ``report.html``: one file, figures inline as data-URI PNG, no scripts, no
  external references (readable offline in any browser);
* ``report.pdf``: the same sections, written with matplotlib's PDF backend
  (TrueType fonts, so the text is searchable and extractable).

Every verdict at the top is PASS or FAIL with the number behind it.
"""

from __future__ import annotations

import base64
import hashlib
import html
import io
import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from matplotlib.figure import Figure

from ..checks import all_checks
from ..files import versions
from ..simulation import figures as sim_figures
from ..simulation.metrics import segment_metrics
from ..simulation.scenario import Scenario, dump_scenario, scenario_to_dict
from ..simulation.simulator import SimulationError, Simulator
from ..stability import figures as stab_figures
from ..stability.design import DesignError, DesignInfeasible, DesignSpec, damping_alternatives, design_impedance
from ..stability import (analysis_kwargs, analyze, analyze_continuous, analyze_range, scenario_parameters,
                        spectral_radius, switch_response)

__all__ = ["Verdict", "Report", "build_report", "write_report", "FORCE_TOLERANCE"]

FORCE_TOLERANCE = 0.01
"""Steady-state force tolerance of the tracking verdict, N."""

STAGES = ("derivation checks", "continuous-time stability", "sampled-data stability", "simulation",
          "design comparison", "figures")


@dataclass(frozen=True)
class Verdict:
    name: str
    passed: bool
    evidence: str


@dataclass
class Report:
    """Everything a report shows (numbers, tables, figures)."""
    scenario: Scenario
    command_line: str
    verdicts: list[Verdict] = field(default_factory=list)
    sections: dict = field(default_factory=dict)
    figures: dict = field(default_factory=dict)     # name -> (title, Figure)
    timings: dict = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        return all(v.passed for v in self.verdicts)


def _stiffness_points(p: dict) -> list[float]:
    pts = p["k_e_values"] or [p["k_e_min"], math.sqrt(p["k_e_min"] * p["k_e_max"]), p["k_e_max"]]
    return sorted({float(v) for v in pts})


def build_report(scenario: Scenario, command_line: str = "", progress: Callable | None = None) -> Report:
    """Run every stage for ``scenario`` and collect the results."""
    rep = Report(scenario, command_line or " ".join(sys.argv))
    say = progress or (lambda *a: None)
    p = scenario_parameters(scenario)
    m, b, k, f_d, Ts = p["m"], p["b"], p["k"], p["f_d"], p["Ts"]
    masses = (p["m_p_min"], p["m_p_max"])
    points = _stiffness_points(p)
    kw = {"kd": p["kd"], "kp": p["kp"], "alpha": p["alpha"], "d_e": p["d_e"], "law": p["law"]}

    def stage(i):
        say(i + 1, len(STAGES), STAGES[i])
        return time.perf_counter()

    # 1. derivation checks
    t0 = stage(0)
    checks = all_checks()
    rep.sections["checks"] = checks
    n_ok = sum(c.passed for c in checks)
    rep.verdicts.append(Verdict("Derivation checks passed", n_ok == len(checks),
                                f"{n_ok}/{len(checks)} checks pass"))
    rep.timings["checks"] = time.perf_counter() - t0

    # 2. continuous time over the range (eqs. 22, 25)
    t0 = stage(1)
    rng = analyze_range(m, b, k, p["k_e_min"], max(p["k_e_max"], p["k_e_min"]), f_d)
    per_k = [analyze_continuous(m, b, k, ke, f_d) for ke in points]
    rep.sections["continuous"] = {"range": rng, "points": per_k}
    worst_re = max(float(np.max(a.poles.real)) for a in per_k + [rng.at_min, rng.at_max])
    rep.verdicts.append(Verdict(
        "BIBO stable in continuous time (eq. 22)", bool(rng.stable_for_all and all(a.bibo_stable for a in per_k)),
        f"largest pole real part {worst_re:.4g} 1/s over k_e in [{p['k_e_min']:.4g}, {p['k_e_max']:.4g}] N/m; "
        f"worst damping ratio {rng.worst_damping_ratio:.3g}"))
    rep.timings["continuous"] = time.perf_counter() - t0

    # 3. sampled data at Ts
    t0 = stage(2)
    a = analyze(**analysis_kwargs(p))          # the verdict `tmtcontrol analyze` gives
    limit = a["max_stable_stiffness"]
    rho = {ke: max(spectral_radius(m, b, k, ke, Ts, mp, **kw) for mp in masses) for ke in points}
    rep.sections["sampled"] = {"limit": limit, "rho": rho, "masses": masses, "Ts": Ts}
    margin = limit / p["k_e_max"] if p["k_e_max"] > 0 else float("inf")
    rep.verdicts.append(Verdict(
        f"Stable in the sampled implementation at Ts = {Ts:g} s", a["sampled_stable"],
        f"largest stable stiffness {limit:.4g} N/m vs k_e_max {p['k_e_max']:.4g} N/m (margin {margin:.3g}x); "
        f"max spectral radius over the range {a['spectral_radius']:.6f}"))
    rep.timings["sampled"] = time.perf_counter() - t0

    # 4. simulation
    t0 = stage(3)
    sim = Simulator(scenario)
    try:
        res = sim.run()
        segs = segment_metrics(res)
        worst = max(s.max_steady_error for s in segs)
        lost = any(s.contact_lost_steady for s in segs)
        ok = bool(worst <= FORCE_TOLERANCE and not lost)
        evidence = (f"worst steady-state |f_e - f_d| = {worst:.3g} N (tolerance {FORCE_TOLERANCE:g} N)"
                    + ("; contact lost in steady state" if lost else ""))
        rep.sections["simulation"] = {"result": res, "segments": segs, "error": None}
    except SimulationError as exc:
        res, segs, ok, evidence = None, [], False, str(exc)
        rep.sections["simulation"] = {"result": None, "segments": [], "error": str(exc)}
    rep.verdicts.append(Verdict("Force tracking within tolerance (simulation)", ok, evidence))
    # predicted (sampled model) vs simulated switch metrics
    pred = []   # only piecewise-constant profiles have switches to predict
    if res is not None and len(segs) > 1 and scenario.environment.stiffness.kind == "piecewise_constant":
        for i in range(1, len(segs)):
            k_old, k_new = segs[i - 1].stiffness, segs[i].stiffness
            if k_old == k_new:
                continue
            sw = switch_response(m, b, k, k_old, k_new, Ts, masses[0], f_d=f_d,
                                 duration=segs[i].end - segs[i].start, **kw)
            pred.append({"segment": i + 1, "k_old": k_old, "k_new": k_new,
                         "pred_overshoot": sw["overshoot_pct"], "sim_overshoot": segs[i].overshoot_pct,
                         "pred_settling": sw["settling_time"], "sim_settling": segs[i].settling_time,
                         "contact_lost": sw["contact_lost"]})
    rep.sections["prediction"] = pred
    rep.timings["simulation"] = time.perf_counter() - t0

    # 5. design comparison
    t0 = stage(4)
    design = {"error": None}
    if p["k_e_max"] > p["k_e_min"]:
        try:
            d = design_impedance(DesignSpec(m=m, k=k, k_e_min=p["k_e_min"], k_e_max=p["k_e_max"], Ts=Ts,
                                            max_overshoot=5.0, f_d=f_d, m_p=masses[0]))
            design["result"] = d
            comp = {}
            if res is not None:
                for name, sc in damping_alternatives(scenario, d).items():
                    try:
                        comp[name] = segment_metrics(sim.run(sc))
                    except SimulationError as exc:
                        comp[name] = str(exc)
            design["simulated"] = comp
        except (DesignError, DesignInfeasible) as exc:
            design["error"] = str(exc)
    else:
        design["error"] = "single stiffness: no range to design over"
    rep.sections["design"] = design
    rep.timings["design"] = time.perf_counter() - t0

    # 6. figures
    t0 = stage(5)
    lo, hi = p["k_e_min"], p["k_e_max"]
    rep.figures["root_locus"] = ("Root locus of eq. (22) in k_e", stab_figures.root_locus_figure(m, b, k, lo / 10, hi * 10))
    rep.figures["damping"] = ("Damping ratio and natural frequency versus k_e",
                              stab_figures.damping_figure(m, b, k, lo / 10, hi * 10))
    rep.figures["steps"] = ("Force step responses of eq. (22)", stab_figures.step_figure(m, b, k, points, f_d))
    top = max(10 * hi, 2 * limit) if math.isfinite(limit) and limit > 0 else 100 * hi
    rep.figures["region"] = ("Sampled-data stability region with the scenario's operating points",
                             stab_figures.stability_region_figure(m, b, k, masses[0], np.geomspace(Ts / 10, Ts * 10, 21),
                                                           np.geomspace(lo / 10, top, 21),
                                                           [(Ts, ke, f"{ke:.3g}") for ke in points], **kw))
    if res is not None:
        rep.figures["fig3"] = ("Environment stiffness and TMT estimate (Fig. 3)", sim_figures.stiffness_figure(res))
        rep.figures["fig4"] = ("Force tracking (Fig. 4)", sim_figures.force_figure(res))
        rep.figures["fig5"] = ("Position tracking (Fig. 5)", sim_figures.position_figure(res))
        rep.figures["path"] = ("Path on the tilted plane", sim_figures.path_figure(res))
    if "result" in design:
        rep.figures["design"] = ("Robust damping design: cost against b", stab_figures.design_cost_figure(design["result"]))
    rep.timings["figures"] = time.perf_counter() - t0
    rep.sections["parameters"] = p
    return rep


# -- rendering ---------------------------------------------------------------------------------

def _fmt(v) -> str:
    if isinstance(v, float):
        return "–" if not math.isfinite(v) else f"{v:.4g}"
    return str(v)


def _tables(rep: Report) -> dict[str, tuple[str, list[str], list[list[str]]]]:
    """Section tables as (title, header, rows) of strings, shared by HTML and PDF."""
    t = {}
    t["verdicts"] = ("Verdict summary", ["verdict", "result", "evidence"],
                     [[v.name, "PASS" if v.passed else "FAIL", v.evidence] for v in rep.verdicts])
    flat = []

    def walk(prefix, d):
        for key, val in d.items():
            if isinstance(val, dict):
                walk(f"{prefix}{key}.", val)
            else:
                flat.append([f"{prefix}{key}", _fmt(val) if not isinstance(val, list) else str(val)])

    walk("", scenario_to_dict(rep.scenario))
    t["scenario"] = ("Scenario and parameters", ["key", "value"], flat)
    t["checks"] = ("Derivation checks", ["equation", "check", "claim", "residual", "verdict"],
                   [[c.equation, c.name, c.claim + (f" NOTE: {c.note}" if c.note else ""), f"{c.residual:.2e}",
                     "PASS" if c.passed else "FAIL"] for c in rep.sections["checks"]])
    cont = rep.sections["continuous"]
    p = rep.sections["parameters"]
    t["continuous"] = ("Continuous-time stability per stiffness (eq. 22) and critical damping (eq. 25)",
                       ["k_e (N/m)", "poles (1/s)", "omega_n (rad/s)", "zeta", "overshoot %", "settling (s)",
                        "b_crit eq. 25 (N s/m)", "b / b_crit", "BIBO"],
                       [[_fmt(a.k_e), ", ".join(f"{z.real:.4g}{z.imag:+.4g}j" for z in a.poles),
                         _fmt(a.natural_frequency), _fmt(a.damping_ratio), _fmt(a.overshoot_pct),
                         _fmt(a.settling_time), _fmt(a.critical_damping), _fmt(p["b"] / a.critical_damping),
                         "yes" if a.bibo_stable else "NO"] for a in cont["points"]])
    smp = rep.sections["sampled"]
    t["sampled"] = (f"Sampled-data stability at Ts = {smp['Ts']:g} s "
                    f"(effective normal mass {smp['masses'][0]:.4g}-{smp['masses'][1]:.4g} kg)",
                    ["k_e (N/m)", "spectral radius", "stable"],
                    [[_fmt(ke), f"{r:.6f}", "yes" if r < 1 else "NO"] for ke, r in smp["rho"].items()]
                    + [["largest stable k_e", _fmt(smp["limit"]), ""]])
    sim = rep.sections["simulation"]
    if sim["error"]:
        t["segments"] = ("Simulation", ["result"], [[sim["error"]]])
    else:
        t["segments"] = ("Simulation: per-segment metrics",
                         ["segment", "t (s)", "k_e (N/m)", "ss error (N)", "peak (N)", "overshoot %",
                          "settling 2 % (s)", "tangential RMS (mm)", "contact lost"],
                         [[str(i), f"{s.start:g}-{s.end:g}", _fmt(s.stiffness), f"{s.steady_state_error:.3g}",
                           _fmt(s.peak_force), _fmt(s.overshoot_pct), _fmt(s.settling_time),
                           f"{s.tangential_rms * 1e3:.4f}", "yes" if s.contact_lost_steady else "no"]
                          for i, s in enumerate(sim["segments"], 1)])
    pred = rep.sections["prediction"]
    t["prediction"] = ("Predicted (sampled model) versus simulated stiffness switches",
                       ["segment", "k_e switch (N/m)", "overshoot % pred / sim", "settling (s) pred / sim",
                        "settling diff %", "contact lost (pred)"],
                       [[str(r["segment"]), f"{r['k_old']:.4g} -> {r['k_new']:.4g}",
                         f"{r['pred_overshoot']:.3f} / {r['sim_overshoot']:.3f}",
                         f"{_fmt(r['pred_settling'])} / {_fmt(r['sim_settling'])}",
                         _fmt(100 * abs(r["pred_settling"] - r["sim_settling"]) / r["sim_settling"])
                         if r["sim_settling"] else "–", "yes" if r["contact_lost"] else "no"] for r in pred]
                       or [["–", "no stiffness switch", "", "", "", ""]])
    des = rep.sections["design"]
    if des.get("error"):
        t["design"] = ("Design comparison", ["result"], [[des["error"]]])
    else:
        d = des["result"]
        rows = [["optimal (IPOPT)", _fmt(d.b), _fmt(d.k), _fmt(d.objective), _fmt(d.worst_overshoot)],
                ["eq. (25) worst case", _fmt(d.baseline_b), _fmt(d.spec.k), _fmt(d.baseline_objective), "0"]]
        t["design"] = ("Design comparison (worst-case ISE over the range; 5 % overshoot bound)",
                       ["design", "b (N s/m)", "k (N/m)", "worst-case J (N^2 s)", "worst overshoot %"], rows)
        sim_rows = []
        for name, segs in des.get("simulated", {}).items():
            if isinstance(segs, str):
                sim_rows.append([name, segs])
            else:
                sim_rows.append([name, "; ".join(f"{s.overshoot_pct:.3g} % / {_fmt(s.settling_time)} s"
                                                 for s in segs)])
        t["design_sim"] = ("Simulated on the scenario: overshoot / 2 % settling per segment",
                           ["controller", "per segment"], sim_rows)
    v = versions()
    t["repro"] = ("Reproducibility", ["item", "value"],
                  [["command", rep.command_line],
                   ["scenario SHA-256", hashlib.sha256(dump_scenario(rep.scenario).encode()).hexdigest()],
                   *[[f"version {k}", str(val)] for k, val in v.items()],
                   *[[f"time {k} (s)", f"{val:.2f}"] for k, val in rep.timings.items()]])
    return t


_CSS = """body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#222}table{border-collapse:collapse;margin:.8em 0;font-size:.9em}td,th{border:1px solid #ccc;
padding:.3em .6em;text-align:left;vertical-align:top}th{background:#f2f2f2}.PASS{color:#fff;background:#2a8a3a;
font-weight:bold}.FAIL{color:#fff;background:#c0392b;font-weight:bold}img{max-width:100%;border:1px solid #eee}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}code{background:#f5f5f5;padding:0 .2em}"""

_SECTION_FIGS = {"continuous": ["root_locus", "damping", "steps"], "sampled": ["region"],
                 "segments": ["fig3", "fig4", "fig5", "path"], "design": ["design"]}
_ORDER = [("summary", ["verdicts"]), ("scenario", ["scenario"]), ("derivations", ["checks"]),
          ("continuous", ["continuous"]), ("sampled", ["sampled"]), ("simulation", ["segments"]),
          ("prediction", ["prediction"]), ("design", ["design", "design_sim"]), ("reproducibility", ["repro"])]
_TITLES = {"summary": "Verdicts", "scenario": "Scenario and parameters", "derivations": "Derivation checks",
           "continuous": "Continuous-time stability", "sampled": "Sampled-data stability",
           "simulation": "Simulation", "prediction": "Predicted versus simulated overshoot and settling",
           "design": "Design comparison", "reproducibility": "Reproducibility"}


def _png_data_uri(fig: Figure) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def render_html(rep: Report) -> str:
    """The report as one self-contained HTML document."""
    tables = _tables(rep)
    e = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>TMT stability report: {e(rep.scenario.name)}</title>", f"<style>{_CSS}</style></head><body>",
           f"<h1>TMT force-control stability report: scenario <code>{e(rep.scenario.name)}</code></h1>",
           f"<p>Overall: <span class=\"{'PASS' if rep.passed else 'FAIL'}\">{'PASS' if rep.passed else 'FAIL'}</span> "
           "— position-based impedance control with the trajectory modification technique (TMT).</p>"]
    for sec, keys in _ORDER:
        out.append(f'<section id="{sec}"><h2>{e(_TITLES[sec])}</h2>')
        for key in keys:
            if key not in tables:
                continue
            title, head, rows = tables[key]
            if len(keys) > 1 or title != _TITLES[sec]:
                out.append(f"<h3>{e(title)}</h3>")
            out.append("<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in head) + "</tr>")
            for row in rows:
                cells = []
                for c in row:
                    cls = f' class="{c}"' if c in ("PASS", "FAIL") else ""
                    cells.append(f"<td{cls}>{e(c)}</td>")
                out.append("<tr>" + "".join(cells) + "</tr>")
            out.append("</table>")
            for fig_key in _SECTION_FIGS.get(key, []):
                if fig_key in rep.figures:
                    cap, fig = rep.figures[fig_key]
                    out.append(f'<figure><img alt="{e(cap)}" src="{_png_data_uri(fig)}">'
                               f"<figcaption>{e(cap)}</figcaption></figure>")
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out)


def _wrap(text: str, width: int) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width) or [""]


def _text_pages(pdf, title: str, lines: list[str], per_page: int = 62):
    for start in range(0, max(len(lines), 1), per_page):
        fig = Figure(figsize=(8.27, 11.69))
        fig.text(0.06, 0.96, title + (" (continued)" if start else ""), fontsize=13, weight="bold", va="top")
        fig.text(0.06, 0.93, "\n".join(lines[start:start + per_page]), fontsize=7.2, family="monospace", va="top")
        pdf.savefig(fig)


def _summary_page(pdf, rep: Report):
    fig = Figure(figsize=(8.27, 11.69))
    fig.text(0.06, 0.95, "TMT force-control stability report", fontsize=18, weight="bold", va="top")
    fig.text(0.06, 0.915, f"Scenario: {rep.scenario.name}    Overall: {'PASS' if rep.passed else 'FAIL'}",
             fontsize=12, va="top")
    y = 0.86
    for v in rep.verdicts:
        color = "#2a8a3a" if v.passed else "#c0392b"
        fig.text(0.06, y, "PASS" if v.passed else "FAIL", fontsize=12, weight="bold", color="white", va="top",
                 bbox={"facecolor": color, "edgecolor": color, "pad": 3})
        fig.text(0.16, y, v.name, fontsize=11, weight="bold", va="top")
        fig.text(0.16, y - 0.022, "\n".join(_wrap(v.evidence, 95)), fontsize=8.5, va="top")
        y -= 0.075
    fig.text(0.06, y - 0.01, "Sections: scenario and parameters; derivation checks; continuous-time stability; "
             "sampled-data stability;\nsimulation (Figs. 3-5); predicted versus simulated switches; design "
             "comparison; reproducibility.", fontsize=8.5, va="top", color="#444")
    pdf.savefig(fig)


def render_pdf(rep: Report, path) -> None:
    """The report as a PDF (text pages and figure pages)."""
    import matplotlib
    from matplotlib.backends.backend_pdf import PdfPages

    tables = _tables(rep)
    with matplotlib.rc_context({"pdf.fonttype": 42}), PdfPages(path, metadata={
            "Title": f"TMT stability report: {rep.scenario.name}", "Creator": "tmtcontrol"}) as pdf:
        for sec, keys in _ORDER:
            if sec == "summary":
                _summary_page(pdf, rep)
                continue
            lines = []
            for key in keys:
                if key not in tables:
                    continue
                title, head, rows = tables[key]
                lines.append(title)
                lines.append("-" * min(len(title), 110))
                for row in rows:
                    text = " | ".join(row)
                    lines += _wrap(text, 118)
                lines.append("")
            _text_pages(pdf, _TITLES[sec], lines)
            for key in keys:
                for fig_key in _SECTION_FIGS.get(key, []):
                    if fig_key in rep.figures:
                        pdf.savefig(rep.figures[fig_key][1])


def write_report(rep: Report, folder) -> None:
    """Write ``report.html`` and ``report.pdf`` into ``folder``."""
    import pathlib

    folder = pathlib.Path(folder)
    (folder / "report.html").write_text(render_html(rep), encoding="utf-8")
    render_pdf(rep, folder / "report.pdf")
