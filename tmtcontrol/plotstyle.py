"""The one figure style of tmtcontrol (``tmtcontrol.mplstyle``): a colour-blind-
safe palette (Okabe & Ito), one font size scale, light grids. Every module that
writes figures draws inside :func:`styled`."""

from __future__ import annotations

import contextlib
import pathlib

__all__ = ["STYLE", "styled"]

STYLE = pathlib.Path(__file__).with_name("tmtcontrol.mplstyle")

@contextlib.contextmanager
def styled():
    """Create and save figures inside this context to get the house style."""
    import matplotlib.style

    with matplotlib.style.context(STYLE):
        yield
