"""The one figure style of tmtcontrol (``tmtcontrol.mplstyle``): a colour-blind-
safe palette (Okabe & Ito), one font size scale, light grids. Every module that
writes figures draws inside :func:`styled`."""

from __future__ import annotations

import contextlib
import functools
import pathlib
import re

__all__ = ["STYLE", "styled", "fixed_layout", "margin_colorbar", "plain_log_labels"]

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


_SUPERSCRIPT = str.maketrans("0123456789-.", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻·")


@functools.cache
def _unicode_log_formatter():
    from matplotlib.ticker import LogFormatterSciNotation

    class UnicodeLogFormatter(LogFormatterSciNotation):
        """matplotlib's log-axis labels (which ticks, and 10^3 or 2x10^3)
        written with Unicode superscripts instead of mathtext."""

        def __call__(self, x, pos=None):
            label = super().__call__(x, pos)
            m = re.fullmatch(r"\$\\mathdefault\{(.*)\}\$", label)
            if not m:
                return label
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
