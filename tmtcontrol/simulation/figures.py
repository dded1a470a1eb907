"""Figures: reproductions of the paper's Figs. 3-5 and a 3-D view of the path.

Built on ``matplotlib.figure.Figure`` directly (no pyplot, no GUI backend),
so they work headless and in tests. Each function returns the Figure;
:func:`save_simulation_figures` writes Figs. 3-5 and the path as PNG. Those
four take a :class:`~tmtcontrol.SimulationResult` or its
:class:`~.traces.SimulationTraces`; this module imports nothing of the
simulator, so a process with only matplotlib loaded can draw them.
"""

from __future__ import annotations

import pathlib
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from ..drawing import save_figures
from ..plotstyle import fixed_layout, legend_below, legend_margin
from .output import simulation_figures
from .traces import SimulationTraces

if TYPE_CHECKING:
    from .simulator import SimulationResult

__all__ = ["stiffness_figure", "force_figure", "switch_figure", "tracking_error_figure", "position_figure",
           "path_figure",
           "desired_path", "save_simulation_figures", "comparison_force_figure", "comparison_error_figure",
           "save_comparison_figures", "envelope", "limit_use_figure", "crosscheck_figure"]

DRAW_POINTS = 1200
"""Buckets per time-series line: more than a figure has pixels across."""


def envelope(t: np.ndarray, y: np.ndarray, buckets: int = DRAW_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """A long series reduced for drawing: per bucket of consecutive samples,
    its minimum and maximum in time order, so every peak and dip stays
    visible (a line drawn through them covers the same pixels as the full
    series). NaN samples are dropped within a bucket; series shorter than
    ``2 buckets`` are returned unchanged."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    n = y.size
    if n <= 2 * buckets:
        return t, y
    edges = np.linspace(0, n, buckets + 1).astype(int)
    starts, sizes = edges[:-1], np.diff(edges)
    bucket = np.repeat(np.arange(buckets), sizes)
    finite = np.isfinite(y)

    def first_where(values, extreme):
        """Per bucket, the first sample holding the bucket's extreme (its first
        sample if the bucket has no finite value)."""
        hit = np.flatnonzero(values == np.repeat(extreme, sizes))
        _, first = np.unique(bucket[hit], return_index=True)
        return hit[first]

    lo_vals, hi_vals = np.where(finite, y, np.inf), np.where(finite, y, -np.inf)
    i = first_where(lo_vals, np.minimum.reduceat(lo_vals, starts))
    j = first_where(hi_vals, np.maximum.reduceat(hi_vals, starts))
    pairs = np.sort(np.column_stack([i, j]), axis=1)
    keep = np.ones(pairs.shape, dtype=bool)
    keep[:, 1] = pairs[:, 1] != pairs[:, 0]
    idx = pairs[keep]                                  # row-major: time order
    return t[idx], np.where(finite[idx], y[idx], np.nan)


def _traces(res: SimulationResult | SimulationTraces) -> SimulationTraces:
    return res if isinstance(res, SimulationTraces) else res.traces


def stiffness_figure(res: SimulationResult | SimulationTraces) -> Figure:
    """Fig. 3: the environment stiffness k_e(t) and the TMT estimate f_e/(x - x_e)."""
    fig = Figure(figsize=(7, 3.2))
    ax = fig.add_subplot()
    ax.plot(*envelope(res.time, res.stiffness), label="true k_e")
    ax.plot(*envelope(res.time, res.stiffness_estimate), "--", lw=1, label="TMT estimate f_e/(x − x_e)")
    ax.set(xlabel="time (s)", ylabel="stiffness (N/m)", title="Environment stiffness (Fig. 3)")
    ax.set_yscale("log")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return fixed_layout(fig)


def force_figure(res: SimulationResult | SimulationTraces) -> Figure:
    """Fig. 4: contact force against the desired force."""
    fig = Figure(figsize=(7, 3.2))
    ax = fig.add_subplot()
    ax.plot(*envelope(res.time, res.contact_force), label="f_e")
    ax.plot(*envelope(res.time, res.desired_force), "k--", lw=1, label="f_d")
    ax.set(xlabel="time (s)", ylabel="normal force (N)", title="Force tracking (Fig. 4)")
    # every peak visible, and f_d; 1 N where both stay at 0 (review 72: a run that never touches set
    # ylim(0, 0), a warning on the command's output); switch_figure zooms in
    top = max(float(np.max(res.contact_force)), float(np.max(res.desired_force))) or 1.0
    ax.set_ylim(-0.05 * top, 1.08 * top)
    ax.legend()
    ax.grid(True, alpha=0.3)
    return fixed_layout(fig)


def switch_figure(res: SimulationResult, window: float = 0.4) -> Figure:
    """The force around each segment start (a stiffness switch or a new
    cycle), one panel each, from 0.05 s before to ``window`` after: the jump
    and the controller's response at a readable scale."""
    from .metrics import segments

    starts = [a for a, _ in segments(res)][1:] or [0]
    f_d = res.scenario.controller.f_d
    fig = Figure(figsize=(7, 2.4))
    axes = fig.subplots(1, len(starts), sharey=True, squeeze=False)[0]
    for ax, i0 in zip(axes, starts):
        t0 = res.time[i0]
        m = (res.time >= t0 - 0.05) & (res.time <= t0 + window)
        ax.plot(res.time[m] - t0, res.contact_force[m], label="f_e")
        ax.plot(res.time[m] - t0, res.desired_force[m], "k--", lw=1, label="f_d")
        ax.set_title(f"t = {t0:g} s, k_e = {res.stiffness[i0]:,.0f} N/m", fontsize="small")
        ax.set_xlabel("time after switch (s)")
    axes[0].set_ylabel("force (N)")
    axes[0].legend(fontsize="small")
    lo = min(0.0, float(np.min(res.contact_force)))
    axes[0].set_ylim(lo - 0.05 * f_d, max(2.2 * f_d, 1.05 * float(np.max(
        [res.contact_force[max(i - 50, 0):i + int(window / res.Ts)].max() for i in starts]))))
    return fixed_layout(fig, wgap=0.12)


def tracking_error_figure(res: SimulationResult) -> Figure:
    """The tracking errors: |f_e - f_d| on a log axis, and the tangential
    position error (distance from X to X_r within the surface plane, mm);
    X_r itself lies inside the surface (eq. 18), so X against X_r in the
    normal direction is not an error."""
    fig = Figure(figsize=(7, 4.2))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    err = np.abs(res.contact_force - res.desired_force)
    ax1.plot(*envelope(res.time, np.maximum(err, 1e-7)), lw=1)
    ax1.set_yscale("log")
    ax1.set(ylabel="|f_e − f_d| (N)", title="Tracking errors")
    tang = np.linalg.norm(res.position_task[1:] - res.reference_task[1:], axis=0) * 1e3
    ax2.plot(*envelope(res.time, tang), lw=1, color="C2")
    ax2.set(xlabel="time (s)", ylabel="tangential error (mm)")
    return fixed_layout(fig)


def desired_path(res: SimulationResult | SimulationTraces) -> np.ndarray:
    """The desired path X_d (3, N), m: the reference X_r moved along the
    surface normal onto the surface plane (X_r lies inside the surface by
    the TMT's modification, eq. 18; X_d is the circle on the surface that
    the paper's Fig. 5 plots the path against)."""
    tr = _traces(res)
    if tr.desired_position is not None:
        return tr.desired_position
    n = tr.surface_frame[:, 0]
    depth = n @ (tr.reference_position - tr.center[:, None])
    return tr.reference_position - np.outer(n, depth)


def position_figure(res: SimulationResult | SimulationTraces) -> Figure:
    """Fig. 5: x, y, z of the tool point (the tip frame's origin) against the desired path X_d on the
    surface (:func:`desired_path`, base frame), the legend under the axes."""
    fig = Figure(figsize=(7, 5.7))
    axes = fig.subplots(3, 1, sharex=True)
    xd = desired_path(res)
    for i, (ax, name) in enumerate(zip(axes, "xyz")):
        ax.plot(*envelope(res.time, res.position[i]), label=f"X, {_traces(res).tool}")
        ax.plot(*envelope(res.time, xd[i]), "k--", lw=1, label="desired path X_d (on the surface)")
        ax.set_ylabel(f"{name} (m)")
        ax.grid(True, alpha=0.3)
    axes[0].set_title("Position tracking (Fig. 5)")
    axes[-1].set_xlabel("time (s)")
    legend_below(fig, axes[0], ncol=2)
    return fixed_layout(fig, bottom=legend_margin(2, 2))


def path_figure(res: SimulationResult | SimulationTraces) -> Figure:
    """3-D view of the tool point's path on the surface plane, against the
    desired path X_d on the surface (not the reference X_r, which lies inside
    the surface by eq. 18's modification)."""
    res = _traces(res)
    fig = Figure(figsize=(6, 5.5))
    ax = fig.add_subplot(projection="3d")
    if res.surface_mesh is not None:
        ax.plot_surface(*res.surface_mesh, alpha=0.2, color="tab:gray")
    else:
        R, c, r = res.surface_frame, res.center, 1.4 * res.radius
        u, v = np.meshgrid(np.linspace(-r, r, 2), np.linspace(-r, r, 2))
        plane = c[:, None, None] + R[:, 1, None, None] * u + R[:, 2, None, None] * v
        ax.plot_surface(*plane, alpha=0.2, color="tab:gray")
    stride = max(1, res.time.size // (2 * DRAW_POINTS))     # a smooth curve: every stride-th sample
    ax.plot(*res.position[:, ::stride], lw=1.5, label=f"X, {res.tool}")
    ax.plot(*desired_path(res)[:, ::stride], "k--", lw=0.8, label="desired path X_d (on the surface)")
    ax.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title=f"Path on the {res.surface_name}")
    # under the axes: in the 3-D axes' corner it covered the title (review 65)
    legend_below(fig, ax, ncol=1)
    return fixed_layout(fig, left=0.05, right=0.05, bottom=legend_margin(2, 1, bottom=0.05), top=0.3)


def orientation_figure(res: SimulationResult | SimulationTraces) -> Figure:
    """6-D arms: the angle between the tool orientation and its command (mrad)."""
    res = _traces(res)
    fig = Figure(figsize=(7, 3.2))
    ax = fig.add_subplot()
    t, a = envelope(res.time, 1e3 * res.orientation_error)
    ax.plot(t, np.maximum(a, 1e-9), label="|log(R_c R^T)|")
    ax.set(xlabel="time (s)", ylabel="orientation error (mrad)", title="Tool orientation error")
    ax.set_yscale("log")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return fixed_layout(fig)


def limit_use_figure(res: SimulationResult) -> Figure:
    """The arm's limits over the run: per joint with a stated limit, |tau| /
    tau_max and |dq| / dq_max against time (the judged bound, 1 - the margin,
    dashed): a curve above it is an excursion (``over_limit``)."""
    L = res.limits
    fig = Figure(figsize=(7, 5.2))
    axes = fig.subplots(2, 1, sharex=True)
    for ax, series, limit, what in ((axes[0], res.tau, L.tau_max, "|tau| / tau_max"),
                                    (axes[1], res.dq, L.dq_max, "|dq| / dq_max")):
        for j in np.flatnonzero(np.isfinite(limit)):
            ax.plot(*envelope(res.time, np.abs(series[j]) / limit[j]), lw=1, label=f"{j + 1} ({L.names[j]})")
        ax.axhline(1.0 - L.margin, color="k", ls="--", lw=1, label="judged limit")
        ax.set(ylabel=what, ylim=(0, None))
        ax.grid(True, alpha=0.3)
    axes[0].set(title="Joint torques and rates against the arm's limits")
    axes[1].set(xlabel="time (s)")
    legend_below(fig, axes[1], ncol=4)
    return fixed_layout(fig, bottom=legend_margin(len(axes[1].get_legend_handles_labels()[1]), 4))


def crosscheck_figure(c) -> Figure:
    """The contact force on tmtcontrol's plant and on MuJoCo's
    (:mod:`.crosscheck`), and their difference below."""
    fig = Figure(figsize=(7, 5.2))
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    a, b = c.builtin, c.mujoco
    top.plot(*envelope(a.time, a.contact_force), lw=1.2, label="built-in plant")
    top.plot(*envelope(b.time, b.contact_force), lw=1.0, ls="--", label="MuJoCo plant")
    top.plot(a.time, a.desired_force, "k:", lw=0.8, label="f_d")
    top.set(ylabel="contact force (N)", title="The same controller on two plants")
    bottom.plot(*envelope(a.time, b.contact_force - a.contact_force), lw=1.0, color="C3")
    bottom.set(xlabel="time (s)", ylabel="MuJoCo − built-in (N)")
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    legend_below(fig, bottom, 3, *top.get_legend_handles_labels())
    return fixed_layout(fig, bottom=legend_margin(3, 3))


def save_simulation_figures(res: SimulationResult | SimulationTraces,
                            folder: str | pathlib.Path) -> list[pathlib.Path]:
    """Write fig3_stiffness.png, fig4_force.png, fig5_position.png and path3d.png
    (and orientation_error.png for a 6-D arm) into ``folder``, which must
    exist, replacing files of those names there and touching nothing else
    (as matplotlib's ``savefig``: the Python API writes where it is told;
    the commands' output folders are what protect a user's files)."""
    tr = _traces(res)
    return save_figures([(name, globals()[make]) for name, make in simulation_figures(tr)], tr, folder)


_LAW_STYLES = (("-", "o"), ("--", "s"), (":", "^"), ("-.", "D"), ((0, (5, 1, 1, 1)), "v"), ((0, (1, 2)), "P"))
"""Line style and marker per law, in the comparison's order: with colour,
line and marker differing, a curve drawn over an identical one stays visible."""


def _law_curves(ax, cmp, series, floor: float | None = None) -> list[str]:
    """Draw ``series(result)`` of every law of ``cmp``: the scenario's own law
    first with a thick line, each other with its own dash pattern and markers
    (staggered, so a curve identical to another still shows its markers); a
    law whose series lies within 1 % (of the larger peak) of an earlier one's
    says so in its label. Returns the labels."""
    own = cmp.scenario.controller.law.kind
    order = sorted((n for n, r in cmp.runs.items() if r.result is not None), key=lambda n: n != own)
    drawn: dict[str, np.ndarray] = {}
    labels = []
    for i, name in enumerate(order):
        res = cmp.runs[name].result
        y = series(res)
        # within 1 % of the larger peak: one curve at the figure's scale
        same = next((other for other, z in drawn.items() if z.shape == y.shape
                     and np.max(np.abs(z - y)) <= 0.01 * max(np.max(np.abs(z)), np.max(np.abs(y)))), None)
        drawn[name] = y
        label = name + (" (scenario's)" if name == own else "") + (f" (within 1 % of {same})" if same else "")
        ls, marker = _LAW_STYLES[i % len(_LAW_STYLES)]
        t, v = envelope(res.time, np.maximum(y, floor) if floor is not None else y)
        step = max(len(t) // 12, 1)
        ax.plot(t, v, ls=ls, lw=2.6 if name == own else 1.1, marker=marker, ms=5, mfc="none",
                markevery=(i * step // len(order), step), label=label, zorder=2 if name == own else 3)
        labels.append(label)
    return labels


def comparison_force_figure(cmp) -> Figure:
    """Contact force of every law of a :class:`~.compare.Comparison` against f_d
    (each law its own line style and markers; the legend under the axes)."""
    fig = Figure(figsize=(7, 3.8))
    ax = fig.add_subplot()
    runs = [r for r in cmp.runs.values() if r.result is not None]
    labels = _law_curves(ax, cmp, lambda res: res.contact_force)
    if runs:
        f_d = runs[0].result.scenario.controller.f_d
        time = runs[0].result.time
        peak = max(float(np.max(r.result.contact_force)) for r in runs)
        ax.plot(time[[0, -1]], [f_d, f_d], "k--", lw=0.8, label="f_d")
        top = max(min(peak, 6 * f_d), f_d)           # f_d visible where no law touches (review 72)
        ax.set_ylim(-0.05 * top, 1.1 * top)
    ax.set(xlabel="time (s)", ylabel="normal force f_e (N)", title="Force tracking, all laws")
    ax.grid(True, alpha=0.3)
    legend_below(fig, ax, ncol=3)
    return fixed_layout(fig, bottom=legend_margin(len(labels) + 1, 3))


def comparison_error_figure(cmp) -> Figure:
    """|f_e - f_d| of every law on a log axis (floor 1e-6 N), with the 0.01 N
    band (each law its own line style and markers; the legend under the axes)."""
    fig = Figure(figsize=(7, 3.8))
    ax = fig.add_subplot()
    labels = _law_curves(ax, cmp, lambda res: np.abs(res.force_error), floor=1e-6)
    ax.set_yscale("log")
    ax.axhline(0.01, color="k", ls=":", lw=0.8, label="0.01 N")
    ax.set(xlabel="time (s)", ylabel="|f_e − f_d| (N)", title="Force error, all laws")
    ax.grid(True, which="both", alpha=0.3)
    legend_below(fig, ax, ncol=3)
    return fixed_layout(fig, bottom=legend_margin(len(labels) + 1, 3))


def save_comparison_figures(cmp, folder: str | pathlib.Path) -> list[pathlib.Path]:
    """Write compare_force.png and compare_error.png."""
    return save_figures((("compare_force", comparison_force_figure), ("compare_error", comparison_error_figure)),
                        cmp, folder)
