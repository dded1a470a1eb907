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
from ..plotstyle import fixed_layout, legend_below, legend_margin, margin_colorbar

__all__ = ["stiffness_limit_figure", "root_locus_figure", "damping_figure", "step_figure", "stability_region_figure",
           "save_analysis_figures", "design_cost_figure", "design_response_figure",
           "save_design_figures"]


# -- stability analysis figures ----------------------------------------------------

def period_ticks(axis) -> None:
    """A log control-period axis labelled at 1, 2 and 5 of each decade in
    plain units (0.2 ms, 0.5 ms, 1 ms), so a span under two decades still
    carries several labelled ticks."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    from ..fmt import qty

    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda x, _: qty(x, "s")))
    axis.set_minor_formatter(NullFormatter())


def root_locus_figure(m, b, k, k_e_min, k_e_max, operating: tuple[float, float] | None = None) -> Figure:
    """Poles of eq. (22) as k_e sweeps [k_e_min, k_e_max] (python-control
    root_locus_map); ``operating``: the scenario's stiffness range (N/m),
    drawn as a thick stretch of the locus."""
    from .continuous import stiffness_sweep

    sw = stiffness_sweep(m, b, k, np.geomspace(k_e_min, k_e_max, 200))
    fig = Figure(figsize=(6, 4.7))
    ax = fig.add_subplot()
    loci = sw["loci"]
    for j in range(loci.shape[1]):
        ax.plot(loci[:, j].real, loci[:, j].imag, "-", lw=1.2, color="C0")
    if operating is not None:
        on = sw["k_e"] <= operating[1] * (1 + 1e-9)
        on &= sw["k_e"] >= operating[0] * (1 - 1e-9)
        lo, hi = operating
        for j in range(loci.shape[1]):
            ax.plot(loci[on, j].real, loci[on, j].imag, "-", lw=5, color="C2", alpha=0.6, solid_capstyle="butt",
                    label=f"operating range {num(lo)}–{num(hi)} N/m" if j == 0 else None)
    ax.plot(loci[0].real, loci[0].imag, "o", color="C1", label=f"k_e = {num(k_e_min)} N/m")
    ax.plot(loci[-1].real, loci[-1].imag, "x", color="C3", ms=9, label=f"k_e = {num(k_e_max)} N/m")
    ax.axvline(0, color="k", lw=0.8)
    ax.set(xlabel="Re (1/s)", ylabel="Im (rad/s)", title="Root locus of eq. (22) in k_e")
    n = len(ax.get_legend_handles_labels()[1])
    legend_below(fig, ax, ncol=3)
    ax.grid(True, alpha=0.3)
    return fixed_layout(fig, bottom=legend_margin(n, 3))


def damping_figure(m, b, k, k_e_min, k_e_max, operating: tuple[float, float] | None = None) -> Figure:
    """Damping ratio and natural frequency of eq. (22) against k_e;
    ``operating``: the scenario's stiffness range (N/m), shaded."""
    from .continuous import stiffness_sweep

    sw = stiffness_sweep(m, b, k, np.geomspace(k_e_min, k_e_max, 200))
    fig = Figure(figsize=(6.5, 4.8))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ax1.semilogx(sw["k_e"], sw["damping_ratio"])
    ax1.axhline(1.0, color="k", ls="--", lw=0.8, label="critical (eq. 25)")
    ax1.set(ylabel="damping ratio", title="Damping and natural frequency versus k_e")
    ax2.semilogx(sw["k_e"], sw["natural_frequency"])
    ax2.set(xlabel="k_e (N/m)", ylabel="natural frequency (rad/s)")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        if operating is not None:
            ax.axvspan(*operating, color="C2", alpha=0.18, lw=0,
                       label=f"operating range {num(operating[0])}–{num(operating[1])} N/m" if ax is ax1 else None)
    legend_below(fig, ax1, ncol=2)
    return fixed_layout(fig, bottom=legend_margin(len(ax1.get_legend_handles_labels()[1]), 2))


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
    from .sampled import stability_region, stiffness_margin

    Ts_grid, k_e_grid = np.asarray(Ts_grid, float), np.asarray(k_e_grid, float)
    limits, margin = stiffness_margin(m, b, k, m_p, Ts_grid, k_e_grid, **kw)
    margin = np.clip(margin, -2.0, 2.0)                 # a limit of 0 or inf: the ends of the scale
    rho = stability_region(m, b, k, m_p, Ts_grid, k_e_grid, **kw)
    T, K = np.meshgrid(Ts_grid, k_e_grid)
    fig = Figure(figsize=(6.5, 4.9))
    ax = fig.add_subplot()
    cs = ax.contourf(T, K, margin, levels=np.linspace(-2.0, 2.0, 17), cmap="RdBu")  # ColorBrewer: colour-blind safe
    finite = np.isfinite(limits) & (limits > 0)
    ax.plot(Ts_grid[finite], limits[finite], "k", lw=2, label="largest stable k_e")
    ax.contour(T, K, rho, levels=[1.0], colors="0.15", linewidths=1.2, linestyles=":")
    ax.plot([], [], ls=":", color="0.15", label="spectral radius = 1 (grid)")
    for i, (Ts, ke, label) in enumerate(points):
        ax.plot(Ts, ke, "o", color="k", mfc="white", label="operating points" if i == 0 else None)
        ax.annotate(label, (Ts, ke), textcoords="offset points", xytext=(5, -3), fontsize=7)
    ax.set(xscale="log", yscale="log", xlabel="control period Ts", ylabel="stiffness k_e (N/m)",
           ylim=(k_e_grid[0], k_e_grid[-1]), title=f"Sampled-data stability margin, m_p = {num(m_p)} kg")
    period_ticks(ax.xaxis)
    legend_below(fig, ax, ncol=3)
    margin_colorbar(fixed_layout(fig, right=1.3, bottom=legend_margin(len(ax.get_legend_handles_labels()[1]), 3)),
                    ax, cs, label="stiffness margin log10(limit / k_e)", ticks=np.arange(-2, 3))
    return fig


def stiffness_limit_figure(Ts_grid, limits, points=(), whole_loop=None, label="1-D sampled loop",
                           mark="whole-loop limit at the scenario's Ts") -> Figure:
    """The largest stable stiffness against the control period (log-log):
    ``limits`` (N/m) at ``Ts_grid`` (s) as the boundary, the unstable side
    hatched, the operating points ``[(Ts, k_e, label), ...]`` and the
    limit ``(Ts, k_e)`` at the scenario's period labelled ``mark`` (the
    report marks the one that decides its verdict). Distance to the
    boundary is the margin, readable at any Ts. Where no period has a limit
    (all NaN), neither boundary nor hatch is drawn or listed in the legend."""
    fig = Figure(figsize=(6.5, 4.6))
    ax = fig.add_subplot()
    Ts_grid, limits = np.asarray(Ts_grid, float), np.asarray(limits, float)
    # a period where no stiffness is stable (limit 0) or the analysis found none (NaN) has no point on a log axis
    limits = np.where(np.isfinite(limits) & (limits > 0), limits, np.nan)
    known = limits[np.isfinite(limits)]
    values = [*known, *(p[1] for p in points), *([whole_loop[1]] if whole_loop is not None else [])]
    top = max(values) * 20
    if known.size:      # no limit anywhere (a loop the model makes no prediction for): no boundary in the legend
        ax.plot(Ts_grid, limits, lw=1.8, label=f"largest stable k_e ({label})")
        ax.fill_between(Ts_grid, limits, top, facecolor="none", hatch="///", edgecolor="0.6", lw=0,
                        label="unstable")
    for i, (Ts, ke, text) in enumerate(points):
        ax.plot(Ts, ke, "o", color="C1", label="operating points" if i == 0 else None)
        ax.annotate(text, (Ts, ke), textcoords="offset points", xytext=(5, -3), fontsize=7)
    if whole_loop is not None:
        ax.plot(*whole_loop, "D", color="C2", ms=7, label=mark)
    ax.set(xscale="log", yscale="log", xlabel="control period Ts", ylabel="stiffness k_e (N/m)",
           ylim=(min(values) / 3, top),
           title="Sampled-data stability boundary")
    period_ticks(ax.xaxis)
    legend_below(fig, ax, ncol=2)
    return fixed_layout(fig, bottom=legend_margin(len(ax.get_legend_handles_labels()[1]), 2))


def normal_mass_figure(t, masses, arm: str = "") -> Figure:
    """The arm's effective mass along the surface normal, ``1/(n^T J_v M^-1
    J_v^T n)`` (kg), at the checked path poses against the path time (s): the
    m_p of the 1-D sampled loop (eq. 22 with the robot), whose largest value
    the 1-D limit and the design take as the worst case."""
    fig = Figure(figsize=(6.5, 3.4))
    ax = fig.add_subplot()
    t, masses = np.asarray(t, float), np.asarray(masses, float)
    ax.plot(t, masses, "o-", ms=3, lw=1.4, label="effective normal mass m_p")
    ax.axhline(masses.max(), color="C1", lw=1, ls="--", label=f"largest, {num(masses.max(), 3)} kg (the worst case)")
    ax.set(xlabel="path time (s)", ylabel="m_p (kg)", ylim=(0, masses.max() * 1.15),
           title="Effective normal mass along the path" + (f" of the {arm}" if arm else ""))
    legend_below(fig, ax, ncol=2)
    return fixed_layout(fig, bottom=legend_margin(2, 2))


def save_analysis_figures(d: dict, folder: str | pathlib.Path) -> list[pathlib.Path]:
    """Figures for an :func:`~tmtcontrol.stability.analyze` result: root locus,
    damping versus k_e, step responses and (with Ts) the stability region."""
    m, b, k, f_d = d["m"], d["b"], d["k"], d["f_d"]
    lo, hi = (d["k_e_min"], d["k_e_max"]) if "k_e_min" in d else (d["k_e"], d["k_e"])
    span_lo, span_hi = lo / 10, hi * 10
    makers = [("root_locus", lambda _: root_locus_figure(m, b, k, span_lo, span_hi, operating=(lo, hi))),
              ("damping_vs_stiffness", lambda _: damping_figure(m, b, k, span_lo, span_hi, operating=(lo, hi))),
              ("step_responses", lambda _: step_figure(m, b, k, sorted({lo, np.sqrt(lo * hi), hi}), f_d))]
    if "Ts" in d:
        Ts = d["Ts"]
        pts = [(Ts, ke, num(ke)) for ke in sorted({lo, hi})]
        # the worst-case (largest) effective mass, as the printed limit, the docs and design use
        def region(_):
            fig = stability_region_figure(
                m, b, k, max(d["m_p"]), np.geomspace(Ts / 10, Ts * 10, 41),
                np.geomspace(span_lo, max(span_hi, 10 * d["max_stable_stiffness"])
                             if np.isfinite(d["max_stable_stiffness"]) else span_hi, 81), pts)
            if d.get("delay") or d.get("x_e_error"):     # the printed limit is the law's loop with them
                ax = fig.axes[0]
                ax.set_title(ax.get_title() + "\n1-D closed form without the delay and x_e error "
                             "(the printed limit includes them)", fontsize="small")
            return fig

        makers.append(("stability_region", region))
    return save_figures(makers, d, folder, dpi=110)


# -- design figures ------------------------------------------------------------------------

def _worst_sampled_overshoot(spec, bs, k) -> np.ndarray:
    """The worst first-contact overshoot (percent) of the sampled loop over
    the design's stiffness grid, for each damping in ``bs`` (the constraint
    the design is held to; ``inf`` where the response does not stay finite)."""
    from .design import _contact_response, _overshoot_horizon

    bs = np.asarray(bs, float)
    worst = np.zeros(bs.size)
    for ke in spec.stiffness_grid:
        F = _contact_response(spec, ke, max(_overshoot_horizon(spec.m, k, ke), 20 * spec.Ts))
        with np.errstate(all="ignore"):
            f = np.array(F.map(bs.size)(bs[None, :], np.full((1, bs.size), k)))
        # one response per b: a column output maps to one column per b, a row output to one row block per b
        f = f.T if F.size_out(0)[1] == 1 else f.reshape(bs.size, -1)
        over = np.where(np.all(np.isfinite(f), axis=1), np.maximum(f.max(axis=1) / spec.f_d - 1.0, 0.0) * 100, np.inf)
        worst = np.maximum(worst, over)
    return worst


def design_cost_figure(result) -> Figure:
    """Worst-case cost J against b (fixed k), with the optimum and the eq. (25)
    baseline, above the constraint that places the optimum: the worst
    first-contact overshoot of the sampled loop against b, its bound, and the
    dampings that break it shaded in both panels."""
    from .design import _objective

    spec = result.spec
    bs = np.geomspace(max(spec.b_bounds[0], result.b / 20), min(spec.b_bounds[1], result.b * 20), 120)
    J = [_objective(spec, b, result.k) for b in bs]
    over = _worst_sampled_overshoot(spec, bs, result.k)
    bad = over > spec.max_overshoot
    fig = Figure(figsize=(6.5, 5.4))
    ax, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=(3, 2))
    ax.loglog(bs, J, label=f"worst-case J (k = {num(result.k)} N/m)")
    ax.plot(result.b, result.objective, "o", label=f"optimal b = {num(result.b, 4)} N s/m")
    ax.plot(result.baseline_b, result.baseline_objective, "s", label=f"eq. (25) b = {num(result.baseline_b, 4)} N s/m")
    ax2.semilogx(bs, np.minimum(over, 1e3), color="C2", label="worst first-contact overshoot (sampled loop)")
    ax2.axhline(spec.max_overshoot, color="k", ls="--", lw=1, label=f"bound {num(spec.max_overshoot)} %")
    ax2.plot(result.b, result.worst_overshoot, "o", color="C1")
    for a in (ax, ax2):
        edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(int), 0]))
        for i, (lo, hi) in enumerate(zip(edges[::2], edges[1::2])):
            a.axvspan(bs[lo], bs[min(hi, bs.size - 1)], color="0.85", zorder=0,
                      label=f"overshoot > {num(spec.max_overshoot)} %: infeasible" if i == 0 and a is ax else None)
        a.grid(True, which="both", alpha=0.3)
    ax2.set_ylim(0, max(3 * spec.max_overshoot, 1.0))
    ax.set(ylabel="J (N² s)", title="Robust damping design: cost and the overshoot bound")
    ax2.set(xlabel="b (N s/m)", ylabel="overshoot (%)")
    handles, labels = [], []
    for a in (ax, ax2):
        h, lab = a.get_legend_handles_labels()
        handles += h
        labels += lab
    legend_below(fig, ax, ncol=2, handles=handles, labels=labels)
    return fixed_layout(fig, bottom=legend_margin(len(labels), 2))


def design_response_figure(result) -> Figure:
    """First-contact force responses of the sampled loop (the model the
    overshoot bound applies to: the TMT loop at Ts with its delay and filter,
    drawn at its samples) at k_e_min and k_e_max, optimal vs the eq. (25)
    baseline, with the bound."""
    from .design import _contact_response, _overshoot_horizon

    s = result.spec
    fig = Figure(figsize=(6.5, 4.6))
    ax = fig.add_subplot()
    for b, k, name, ls in ((result.b, result.k, "optimal", "-"), (result.baseline_b, s.k, "eq. (25)", "--")):
        for ke in (s.k_e_min, s.k_e_max):
            f = np.ravel(np.array(_contact_response(s, ke, max(_overshoot_horizon(s.m, k, ke), 20 * s.Ts))(b, k)))
            t = s.Ts * np.arange(1, f.size + 1)
            ax.step(t, f, ls, where="post", label=f"{name} b = {num(b, 4)} N s/m, k_e = {num(ke)} N/m")
    ax.axhline(s.f_d * (1 + s.max_overshoot / 100), color="k", lw=0.8, ls=":",
               label=f"overshoot bound {num(s.max_overshoot)} %")
    ax.set(xlabel="time after first contact (s)", ylabel="f_e (N)",
           title=f"First-contact force response, sampled loop (Ts = {num(s.Ts * 1e3)} ms)")
    ax.grid(True, alpha=0.3)
    legend_below(fig, ax, ncol=2)
    return fixed_layout(fig, bottom=legend_margin(5, 2))


def save_design_figures(result, folder) -> list[pathlib.Path]:
    """Write design_cost.png and design_responses.png."""
    return save_figures((("design_cost", design_cost_figure), ("design_responses", design_response_figure)),
                        result, folder, dpi=110)
