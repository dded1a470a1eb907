"""The one figure style of tmtcontrol (``tmtcontrol.mplstyle``): a colour-blind-
safe palette (Okabe & Ito), one font size scale, light grids. Every module that
writes figures draws inside :func:`styled`."""

from __future__ import annotations

import contextlib
import functools
import pathlib
import re

__all__ = ["STYLE", "styled", "fixed_layout", "margin_colorbar", "plain_log_labels", "legend_below", "legend_margin", "LEGEND_ROW"]

STYLE = pathlib.Path(__file__).with_name("tmtcontrol.mplstyle")

@contextlib.contextmanager
def styled():
    """Create and save figures inside this context to get the house style."""
    import matplotlib.style

    with matplotlib.style.context(STYLE):
        yield


def fixed_layout(fig, left: float = 0.7, right: float = 0.15, bottom: float = 0.48, top: float = 0.32,
                 hgap: float = 0.25, wgap: float = 0.2):
    """Place the axes with fixed margins and gaps (inches; for tick labels,
    axis labels and a title in the house font sizes) instead of matplotlib's
    constrained layout, which measures every text of a figure and costs
    about half of its drawing time. Returns ``fig``."""
    w, h = fig.get_size_inches()
    grid = fig.axes[0].get_subplotspec().get_gridspec() if fig.axes else None
    rows, cols = (grid.nrows, grid.ncols) if grid is not None else (1, 1)
    height = (h - bottom - top - (rows - 1) * hgap) / rows
    width = (w - left - right - (cols - 1) * wgap) / cols
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        hspace=hgap / height, wspace=wgap / width)
    return fig


def margin_colorbar(fig, ax, mappable, **kw):
    """A colour bar for ``mappable`` in the right margin beside ``ax``, after
    :func:`fixed_layout` left about 1.3 in there (``kw``: ``Figure.colorbar``'s)."""
    w, _ = fig.get_size_inches()
    box = ax.get_position()
    return fig.colorbar(mappable, cax=fig.add_axes((box.x1 + 0.15 / w, box.y0, 0.14 / w, box.height)), **kw)


LEGEND_ROW = 0.2
"""Height of one legend row under the axes, inches (:func:`legend_below`)."""


def legend_below(fig, ax=None, ncol: int = 4, handles=None, labels=None):
    """The legend of ``ax`` (default: the figure's first axes) in the
    figure's bottom margin, under the x label, so it never covers data.
    Lay the figure out with ``fixed_layout(fig, bottom=legend_margin(n,
    ncol))``. Returns the legend."""
    ax = ax or fig.axes[0]
    if handles is None:
        handles, labels = ax.get_legend_handles_labels()
    return fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=ncol,
                      fontsize="small", frameon=False, borderaxespad=0.2)


def legend_margin(entries: int, ncol: int = 4, bottom: float = 0.48) -> float:
    """The bottom margin (inches) for :func:`legend_below` with ``entries``
    in ``ncol`` columns under an x label that needs ``bottom``."""
    return bottom + LEGEND_ROW * -(-entries // ncol) + 0.08


_SUPERSCRIPT = str.maketrans("0123456789-.", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻·")


@functools.cache
def _unicode_log_formatter():
    from matplotlib.ticker import LogFormatterSciNotation

    class UnicodeLogFormatter(LogFormatterSciNotation):
        """matplotlib's log-axis labels (which ticks, and 10^3 or 2x10^3)
        written with Unicode superscripts instead of mathtext; on an axis of
        at most three decades between 0.001 and 10⁶ as plain numbers
        (``fmt.num``: 6,000, 0.02)."""

        def __call__(self, x, pos=None):
            label = super().__call__(x, pos)
            m = re.fullmatch(r"\$\\mathdefault\{(.*)\}\$", label)
            if not m:
                return label
            lo, hi = sorted(abs(v) for v in self.axis.get_view_interval()) if self.axis is not None else (x, x)
            if lo >= 1e-3 and hi < 1e6 and hi <= 1e3 * lo:    # a few ordinary decades: 6,000, not 6×10³
                from .fmt import num

                return num(x)
            body = m.group(1).replace(r"\times", "×")
            return re.sub(r"\^\{([^}]*)\}", lambda e: e.group(1).translate(_SUPERSCRIPT), body)

    return UnicodeLogFormatter


def plain_log_labels(fig):
    """Give the log axes of ``fig`` the same tick labels as plain text
    (10³, 2×10³): matplotlib writes them as mathtext, whose parser costs about
    20 ms per distinct label (most of a report's figure time). Formatters set
    by the figure itself are kept. Returns ``fig``."""
    from matplotlib.ticker import LogFormatterSciNotation

    cls = _unicode_log_formatter()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for get, set_ in ((axis.get_major_formatter, axis.set_major_formatter),
                              (axis.get_minor_formatter, axis.set_minor_formatter)):
                old = get()
                if type(old) is LogFormatterSciNotation:
                    set_(cls(base=getattr(old, "_base", 10.0), labelOnlyBase=old.labelOnlyBase,
                             minor_thresholds=old.minor_thresholds, linthresh=getattr(old, "_linthresh", None)))
    return fig
