"""Figures of the stability analysis (root locus, damping, step responses,
sampled stability region) and of the impedance design (cost curve, responses).

Built on ``matplotlib.figure.Figure`` directly (no pyplot), so they work headless.
"""

from __future__ import annotations

import pathlib

import numpy as np
from matplotlib.figure import Figure

from ..drawing import save_figures
from ..fmt import num
from ..plotstyle import fixed_layout, margin_colorbar

__all__ = ["stiffness_limit_figure", "root_locus_figure", "damping_figure", "step_figure", "stability_region_figure",
           "save_analysis_figures", "design_cost_figure", "design_response_figure",
           "save_design_figures"]


# -- stability analysis figures ----------------------------------------------------

def root_locus_figure(m, b, k, k_e_min, k_e_max) -> Figure:
    """Poles of eq. (22) as k_e sweeps [k_e_min, k_e_max] (python-control root_locus_map)."""
    from .continuous import stiffness_sweep

    sw = stiffness_sweep(m, b, k, np.geomspace(k_e_min, k_e_max, 200))
    fig = Figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    loci = sw["loci"]
    for j in range(loci.shape[1]):
        ax.plot(loci[:, j].real, loci[:, j].imag, "-", lw=1.5)
    ax.plot(loci[0].real, loci[0].imag, "o", label=f"k_e = {num(k_e_min)} N/m")
    ax.plot(loci[-1].real, loci[-1].imag, "x", ms=9, label=f"k_e = {num(k_e_max)} N/m")
    ax.axvline(0, color="k", lw=0.8)
    ax.set(xlabel="Re (1/s)", ylabel="Im (rad/s)", title="Root locus of eq. (22) in k_e")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return fixed_layout(fig)


def damping_figure(m, b, k, k_e_min, k_e_max) -> Figure:
    """Damping ratio and natural frequency of eq. (22) against k_e."""
    from .continuous import stiffness_sweep

    sw = stiffness_sweep(m, b, k, np.geomspace(k_e_min, k_e_max, 200))
    fig = Figure(figsize=(6.5, 4.5))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.semilogx(sw["k_e"], sw["damping_ratio"])
    ax1.axhline(1.0, color="k", ls="--", lw=0.8, label="critical (eq. 25)")
    ax1.set(ylabel="damping ratio", title="Damping and natural frequency versus k_e")
    ax1.legend()
    ax2.semilogx(sw["k_e"], sw["natural_frequency"])
    ax2.set(xlabel="k_e (N/m)", ylabel="natural frequency (rad/s)")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
    return fixed_layout(fig)


def step_figure(m, b, k, stiffnesses, f_d=10.0) -> Figure:
    """Force step responses of eq. (22) for several stiffnesses."""
    import control as ct

    from .continuous import tmt_error_tf

    fig = Figure(figsize=(6.5, 4))
    ax = fig.add_subplot()
    for ke in stiffnesses:
        resp = ct.step_response(tmt_error_tf(m, b, k, ke) * f_d)
        ax.plot(resp.time, np.squeeze(resp.outputs), label=f"k_e = {num(ke)} N/m")
    ax.axhline(f_d, color="k", ls="--", lw=0.8)
    ax.set(xlabel="time (s)", ylabel="f_e (N)", title="Force step response, eq. (22)")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return fixed_layout(fig)


def stability_region_figure(m, b, k, m_p, Ts_grid, k_e_grid, points=(), **kw) -> Figure:
    """Sampled-data stability over (Ts, k_e), drawn as the distance to the
    boundary: the stiffness margin log10(limit(Ts) / k_e) in colour (decades;
    blue stable, red unstable), the boundary limit(Ts)
    (:func:`~.sampled.stiffness_margin`) and the operating
    points ``[(Ts, k_e, label), ...]``. The spectral radius itself is no
    margin: on the stable side it is often the impedance filter's slow pole
    (so with the paper's gains), which no k_e moves. Its rho = 1 contour on
    the same grid is drawn too (dotted): it lies on the boundary unless the
    loop turns stable again at a larger k_e, which the margin could not show."""
    from matplotlib.ticker import NullFormatter

    from .sampled import stability_region, stiffness_margin

    Ts_grid, k_e_grid = np.asarray(Ts_grid, float), np.asarray(k_e_grid, float)
    limits, margin = stiffness_margin(m, b, k, m_p, Ts_grid, k_e_grid, **kw)
    margin = np.clip(margin, -2.0, 2.0)                 # a limit of 0 or inf: the ends of the scale
    rho = stability_region(m, b, k, m_p, Ts_grid, k_e_grid, **kw)
    T, K = np.meshgrid(Ts_grid, k_e_grid)
    fig = Figure(figsize=(6.5, 4.6))
    ax = fig.add_subplot()
    cs = ax.contourf(T, K, margin, levels=np.linspace(-2.0, 2.0, 17), cmap="RdBu")  # ColorBrewer: colour-blind safe
    finite = np.isfinite(limits) & (limits > 0)
    ax.plot(Ts_grid[finite], limits[finite], "k", lw=2, label="largest stable k_e")
    ax.contour(T, K, rho, levels=[1.0], colors="0.15", linewidths=1.2, linestyles=":")
    ax.plot([], [], ls=":", color="0.15", label="spectral radius = 1 (grid)")
    for i, (Ts, ke, label) in enumerate(points):
        ax.plot(Ts, ke, "o", color="k", mfc="white", label="operating points" if i == 0 else None)
        ax.annotate(label, (Ts, ke), textcoords="offset points", xytext=(5, -3), fontsize=7)
    ax.set(xscale="log", yscale="log", xlabel="control period Ts (s)", ylabel="stiffness k_e (N/m)",
           ylim=(k_e_grid[0], k_e_grid[-1]), title=f"Sampled-data stability margin, m_p = {num(m_p)} kg")
    ax.xaxis.set_minor_formatter(NullFormatter())     # over two decades the minor labels overlap
    ax.legend(loc="lower left", fontsize="small")
    margin_colorbar(fixed_layout(fig, right=1.3), ax, cs, label="stiffness margin log10(limit / k_e)",
                    ticks=np.arange(-2, 3))
    return fig


def stiffness_limit_figure(Ts_grid, limits, points=(), whole_loop=None, label="1-D sampled loop") -> Figure:
    """The largest stable stiffness against the control period (log-log):
    ``limits`` (N/m) at ``Ts_grid`` (s) as the boundary, the unstable side
    hatched, the operating points ``[(Ts, k_e, label), ...]`` and the
    whole-loop limit ``(Ts, k_e)`` at the scenario's period. Distance to the
    boundary is the margin, readable at any Ts."""
    fig = Figure(figsize=(6.5, 4.2))
    ax = fig.add_subplot()
    Ts_grid, limits = np.asarray(Ts_grid, float), np.asarray(limits, float)
    ax.plot(Ts_grid, limits, lw=1.8, label=f"largest stable k_e ({label})")
    top = max(limits.max(), *(p[1] for p in points)) * 20 if points else limits.max() * 20
    ax.fill_between(Ts_grid, limits, top, facecolor="none", hatch="///", edgecolor="0.6", lw=0,
                    label="unstable")
    for i, (Ts, ke, text) in enumerate(points):
        ax.plot(Ts, ke, "o", color="C1", label="operating points" if i == 0 else None)
        ax.annotate(text, (Ts, ke), textcoords="offset points", xytext=(5, -3), fontsize=7)
    if whole_loop is not None:
        ax.plot(*whole_loop, "D", color="C2", ms=7, label="whole-loop limit at the scenario's Ts")
    ax.set(xscale="log", yscale="log", xlabel="control period Ts (s)", ylabel="stiffness k_e (N/m)",
           ylim=(min(limits.min(), *(p[1] for p in points)) / 3 if points else limits.min() / 3, top),
           title="Sampled-data stability boundary")
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())     # over two decades the minor labels overlap
    ax.legend(loc="lower left", fontsize="small")
    return fixed_layout(fig)


def save_analysis_figures(d: dict, folder: str | pathlib.Path) -> list[pathlib.Path]:
    """Figures for an :func:`~tmtcontrol.stability.analyze` result: root locus,
    damping versus k_e, step responses and (with Ts) the stability region."""
    m, b, k, f_d = d["m"], d["b"], d["k"], d["f_d"]
    lo, hi = (d["k_e_min"], d["k_e_max"]) if "k_e_min" in d else (d["k_e"], d["k_e"])
    span_lo, span_hi = lo / 10, hi * 10
    makers = [("root_locus", lambda _: root_locus_figure(m, b, k, span_lo, span_hi)),
              ("damping_vs_stiffness", lambda _: damping_figure(m, b, k, span_lo, span_hi)),
              ("step_responses", lambda _: step_figure(m, b, k, sorted({lo, np.sqrt(lo * hi), hi}), f_d))]
    if "Ts" in d:
        Ts = d["Ts"]
        pts = [(Ts, ke, num(ke)) for ke in sorted({lo, hi})]
        makers.append(("stability_region", lambda _: stability_region_figure(
            m, b, k, min(d["m_p"]), np.geomspace(Ts / 10, Ts * 10, 41),
            np.geomspace(span_lo, max(span_hi, 10 * d["max_stable_stiffness"])
                         if np.isfinite(d["max_stable_stiffness"]) else span_hi, 81), pts)))
    return save_figures(makers, d, folder, dpi=110)


# -- design figures ------------------------------------------------------------------------

def design_cost_figure(result) -> Figure:
    """Worst-case cost J against b (fixed k), with the optimum and the eq. (25) baseline."""
    from .design import _objective

    spec = result.spec
    bs = np.geomspace(max(spec.b_bounds[0], result.b / 20), min(spec.b_bounds[1], result.b * 20), 120)
    J = [_objective(spec, b, result.k) for b in bs]
    fig = Figure(figsize=(6.5, 4.2))
    ax = fig.add_subplot()
    ax.loglog(bs, J, label=f"worst-case J (k = {result.k:.4g} N/m)")
    ax.plot(result.b, result.objective, "o", label=f"optimal b = {result.b:.4g}")
    ax.plot(result.baseline_b, result.baseline_objective, "s", label=f"eq. (25) b = {result.baseline_b:.4g}")
    ax.set(xlabel="b (N s/m)", ylabel="J (N² s)", title="Robust damping design")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return fixed_layout(fig)


def design_response_figure(result) -> Figure:
    """First-contact force responses (eq. 22) at k_e_min and k_e_max, optimal vs baseline."""
    import control as ct

    from .continuous import tmt_error_tf

    s = result.spec
    fig = Figure(figsize=(6.5, 4.2))
    ax = fig.add_subplot()
    for b, k, name, ls in ((result.b, result.k, "optimal", "-"), (result.baseline_b, s.k, "eq. (25)", "--")):
        for ke in (s.k_e_min, s.k_e_max):
            r = ct.step_response(tmt_error_tf(s.m, b, k, ke) * s.f_d)
            ax.plot(r.time, np.squeeze(r.outputs), ls, label=f"{name}, k_e = {ke:.3g}")
    ax.axhline(s.f_d * (1 + s.max_overshoot / 100), color="k", lw=0.8, ls=":", label="overshoot bound")
    ax.set(xlabel="time (s)", ylabel="f_e (N)", title="First-contact force response, eq. (22)")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    return fixed_layout(fig)


def save_design_figures(result, folder) -> list[pathlib.Path]:
    """Write design_cost.png and design_responses.png."""
    return save_figures((("design_cost", design_cost_figure), ("design_responses", design_response_figure)),
                        result, folder, dpi=110)
