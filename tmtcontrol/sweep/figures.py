"""Sweep figures: the stability/accuracy map over the first two axes, and the
distribution of the main metrics per law when the law is an axis."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

__all__ = ["sweep_map_figure", "law_distribution_figure", "VERDICT_STYLE"]

VERDICT_STYLE = {"converged": ("o", "#0072B2"), "limit_cycle": ("^", "#E69F00"), "diverged": ("X", "#D55E00")}
"""Marker and colour per verdict (Okabe-Ito palette; the marker alone tells them apart in grey)."""


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in values)


def sweep_map_figure(df, axes: list[str], predicted: dict | None = None) -> Figure:
    """Verdict (marker) and worst steady-state error (colour, N) over the
    first two axes (the first axis against the error if there is one axis);
    ``predicted``: ``{other-axis value or None: stiffness limit (N/m)}`` drawn
    as the analysis' boundary when the stiffness is an axis."""
    fig = Figure(figsize=(7, 4.6), layout="constrained")
    ax = fig.add_subplot()
    x_key = axes[0]
    y_key = axes[1] if len(axes) > 1 else "max_steady_error"
    x, y = df[x_key].to_numpy(), df[y_key].to_numpy()
    err = np.clip(df["max_steady_error"].to_numpy(dtype=float), 1e-6, 1e3)
    import matplotlib as mpl

    norm = mpl.colors.LogNorm(vmin=max(err.min(), 1e-6), vmax=max(err.max(), 1e-5))
    sc = None
    for verdict, (marker, colour) in VERDICT_STYLE.items():
        m = (df["verdict"] == verdict).to_numpy()
        if m.any():
            sc = ax.scatter(x[m], y[m], c=err[m], cmap="viridis", norm=norm, marker=marker, s=46,
                            edgecolors=colour, linewidths=1.4, label=f"{verdict} ({int(m.sum())})")
    if sc is not None:
        fig.colorbar(sc, ax=ax, label="worst steady-state |f_e - f_d| (N)")
    if _numeric(x) and np.all(np.asarray(x, float) > 0) and np.ptp(np.asarray(x, float)) > 0 and \
            np.max(x) / np.min(x) > 20:
        ax.set_xscale("log")
    if y_key == "max_steady_error" or (_numeric(y) and np.all(np.asarray(y, float) > 0) and np.ptp(
            np.asarray(y, float)) > 0 and np.max(y) / np.min(y) > 20):
        ax.set_yscale("log")
    if predicted:
        if x_key == "environment.stiffness.values":
            ys = sorted(v for v in predicted if v is not None)
            if ys and _numeric(ys):
                ax.plot([predicted[v] for v in ys], ys, "k--", lw=1.2, label="predicted limit (analysis)")
            elif None in predicted:
                ax.axvline(predicted[None], color="k", ls="--", lw=1.2, label="predicted limit (analysis)")
        elif y_key == "environment.stiffness.values":
            xs = sorted(v for v in predicted if v is not None)
            if xs and _numeric(xs):
                ax.plot(xs, [predicted[v] for v in xs], "k--", lw=1.2, label="predicted limit (analysis)")
            elif None in predicted:
                ax.axhline(predicted[None], color="k", ls="--", lw=1.2, label="predicted limit (analysis)")
    ax.set(xlabel=x_key, ylabel=y_key if y_key != "max_steady_error" else "worst steady-state error (N)",
           title="Sweep: verdict (marker) and accuracy (colour)")
    ax.legend(fontsize="small")
    ax.grid(True, which="both", alpha=0.3)
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
