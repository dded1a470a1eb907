"""Sweep figures: the stability/accuracy map over the first two axes, and the
distribution of the main metrics per law when the law is an axis."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..plotstyle import fixed_layout, legend_below, legend_margin, margin_colorbar

__all__ = ["sweep_map_figure", "law_distribution_figure", "VERDICT_STYLE"]

VERDICT_STYLE = {"converged": ("o", "#0072B2"), "off_target": ("s", "#CC79A7"), "over_limit": ("D", "#000000"),
                 "beyond_limit": ("v", "#56B4E9"), "limit_cycle": ("^", "#E69F00"),
                 "diverged": ("X", "#D55E00"), "refused": ("x", "#999999")}
"""Marker and colour per verdict (Okabe-Ito palette; the marker alone tells them apart in grey)."""


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in values)


def _log_axis(values) -> bool:
    """A positive numeric axis spanning a factor of 4 or more (two octaves,
    such as 250-2,000 Hz; any decade) is drawn logarithmic: evenly spaced
    grid values (geomspace, doubling rates) then fill it evenly."""
    return bool(_numeric(values) and np.all(np.asarray(values, float) > 0)
                and np.max(values) / np.min(values) >= 4)


def _grid_ticks(axis, values) -> None:
    """A log axis with at most eight distinct grid values: ticks at those
    values, labelled as plain numbers (250, 500, 1,000, 2,000)."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter, NullLocator

    from ..fmt import num

    distinct = sorted({float(v) for v in values})
    if len(distinct) <= 8:
        axis.set_major_locator(FixedLocator(distinct))
        axis.set_major_formatter(FuncFormatter(lambda v, _: num(v)))
        axis.set_minor_locator(NullLocator())
        axis.set_minor_formatter(NullFormatter())


def sweep_map_figure(df, axes: list[str], predicted: dict | None = None, facet: str | None = None,
                     units: dict[str, str] | None = None, labels: dict[str, str] | None = None) -> Figure:
    """Verdict (marker) and worst steady-state error (colour, N) over the
    first two axes (the first axis against the error if there is one axis),
    one panel per value of ``facet`` (the third axis) if given;
    ``predicted``: the analysis' stiffness limit (N/m) per value of the other
    axis (keys ``(other, facet)`` with a facet), drawn as the predicted
    boundary when the stiffness is one of the two axes; ``units``: each
    axis' unit for its label (:attr:`~.spec.Sweep.units`); ``labels``: each
    axis' description from the scenario schema (:func:`~tmtcontrol.sweep.axis_labels`),
    used instead of its key. A numeric axis spanning a factor of 4 or more
    (so any decade) is logarithmic; the legend sits under the axes."""
    import matplotlib as mpl

    def label(key):
        unit = (units or {}).get(key, "")
        name = (labels or {}).get(key) or key
        return f"{name} ({unit})" if unit else name

    panels = [(None, df)] if facet is None else list(df.groupby(facet, sort=True))
    fig = Figure(figsize=(7 if facet is None else 4.2 * len(panels) + 1.2, 4.6))
    err_all = np.clip(df["max_steady_error"].to_numpy(dtype=float), 1e-6, 1e3)
    err_all = err_all[np.isfinite(err_all)] if np.isfinite(err_all).any() else np.array([1e-6])   # NaN: refused
    norm = mpl.colors.LogNorm(vmin=max(np.min(err_all), 1e-6), vmax=max(np.max(err_all), 1e-5))
    x_key = axes[0]
    y_key = axes[1] if len(axes) > 1 else "max_steady_error"
    measured = df["max_steady_error"].to_numpy(dtype=float)
    measured = measured[np.isfinite(measured) & (measured > 0)]
    floor = float(measured.min()) / 3 if measured.size else 1e-6        # under every measured error
    sc = None
    ax0 = None
    for j, (fv, d) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), j + 1, sharex=ax0, sharey=ax0)
        ax0 = ax0 or ax
        x, y = d[x_key].to_numpy(), d[y_key].to_numpy()
        if y_key == "max_steady_error":     # a refused case has no error: drawn along the bottom (review 70)
            y = y.astype(float).copy()
            y[(d["verdict"] == "refused").to_numpy()] = floor
        err = np.clip(d["max_steady_error"].to_numpy(dtype=float), 1e-6, 1e3)
        for verdict, (marker, colour) in VERDICT_STYLE.items():
            m = (d["verdict"] == verdict).to_numpy()
            if m.any() and verdict == "refused":        # never run: no error to colour by
                ax.scatter(x[m], y[m], color=colour, marker=marker, s=46, linewidths=1.4,
                           label=f"{verdict} ({int(m.sum())})")
            elif m.any():
                sc = ax.scatter(x[m], y[m], c=err[m], cmap="viridis", norm=norm, marker=marker, s=46,
                                edgecolors=colour, linewidths=1.4, label=f"{verdict} ({int(m.sum())})")
        if predicted:
            pts = {(k[0] if isinstance(k, tuple) else k): v for k, v in predicted.items()
                   if facet is None or (isinstance(k, tuple) and k[-1] == fv)}
            others = sorted(v for v in pts if v is not None)
            # without the cases' own limits (sweep --limits off) the line is the 1-D small-signal figure
            line = dict(color="k", ls="--", lw=1.2, label="predicted limit (analysis)" if "predicted_limit" in df
                        else "1-D small-signal limit (sweep --limits off)")
            if x_key == "environment.stiffness.values":
                if others and _numeric(others):
                    ax.plot([pts[v] for v in others], others, **line)
                elif None in pts:
                    ax.axvline(pts[None], **line)
            elif y_key == "environment.stiffness.values":
                if others and _numeric(others):
                    ax.plot(others, [pts[v] for v in others], **line)
                elif None in pts:
                    ax.axhline(pts[None], **line)
        if j == 0:
            xs, ys = df[x_key].to_numpy(), df[y_key].to_numpy()
            if _log_axis(xs):
                ax.set_xscale("log")
                _grid_ticks(ax.xaxis, xs)
            if y_key == "max_steady_error":
                ax.set_yscale("log")
            elif _log_axis(ys):
                ax.set_yscale("log")
                _grid_ticks(ax.yaxis, ys)
        ax.set(xlabel=label(x_key), ylabel=(label(y_key) if y_key != "max_steady_error" else "worst steady-state "
                                            "error (N)") if j == 0 else "",
               title=f"{(labels or {}).get(facet) or facet} = {fv}{' ' + units[facet] if (units or {}).get(facet) else ''}"
               if facet else "Sweep: verdict (marker), accuracy (colour)")
        ax.grid(True, which="both", alpha=0.3)
        if j > 0:
            ax.tick_params(labelleft=False)         # shared with the first panel
    if facet:
        fig.suptitle("Sweep: verdict (marker) and accuracy (colour)")
    # fixed margins (constrained layout measured every text: half the figure's time), the colour
    # bar in the right margin beside the last panel
    handles = {}
    for ax in fig.axes:                         # one entry per verdict over the panels
        for h, n in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(n.rsplit(" (", 1)[0] if n.rsplit(" (", 1)[0] in VERDICT_STYLE else n, h)
    counts = {v: int((df["verdict"] == v).sum()) for v in VERDICT_STYLE}
    entries = [(h, f"{n} ({counts[n]})" if n in counts else n) for n, h in handles.items()]
    if entries:
        legend_below(fig, fig.axes[0], ncol=4, handles=[h for h, _ in entries], labels=[t for _, t in entries])
    fixed_layout(fig, right=1.25 if sc is not None else 0.15, top=0.6 if facet else 0.32,
                 bottom=legend_margin(len(entries), 4) if entries else 0.48)
    if sc is not None:
        margin_colorbar(fig, fig.axes[-1], sc, label="worst steady-state |f_e - f_d| (N)")
    return fig


def law_distribution_figure(df) -> Figure:
    """Worst steady-state error and first-contact peak per law (box plots)."""
    fig = Figure(figsize=(7.5, 3.6), layout="constrained")
    laws = sorted(df["controller.law"].unique())
    for i, (col, label, log) in enumerate((("max_steady_error", "worst steady-state error (N)", True),
                                            ("first_contact_ratio", "first-contact peak / f_d", False))):
        ax = fig.add_subplot(1, 2, i + 1)
        data = [np.clip(df.loc[df["controller.law"] == law, col].dropna().to_numpy(dtype=float), 1e-6, None)
                for law in laws]
        ax.boxplot(data, tick_labels=laws)
        if log:
            ax.set_yscale("log")
        ax.set(ylabel=label)
        ax.tick_params(axis="x", labelrotation=30)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle("Distribution over the sweep, per law")
    return fig
