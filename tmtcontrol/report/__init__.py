"""The stability report: every stage of the data path for one scenario, as a
document model (``document``) rendered to HTML and PDF (``render``)."""

from __future__ import annotations

import pathlib
import time
from typing import Callable

from .document import FORCE_TOLERANCE, STAGES, Report, Verdict, build_report, finish, frozen_gc
from .render import FORMATS, RendererUnavailable, prepare_writing, render_html, render_pdf

__all__ = ["Verdict", "Report", "build_report", "write_report", "render_html", "render_pdf", "FORCE_TOLERANCE",
           "STAGES", "FORMATS", "writing_stages", "prepare_writing", "RendererUnavailable"]


def writing_stages(formats=FORMATS) -> int:
    """How many stages :func:`write_report` reports: the HTML always, then the PDF."""
    return 1 + ("pdf" in formats)


def write_report(rep: Report, folder, formats=FORMATS, progress: Callable | None = None) -> list[pathlib.Path]:
    """Write ``report.html`` and/or ``report.pdf`` into ``folder`` (the PDF is
    laid out from the same HTML, rendered even when only the PDF is asked
    for). ``progress(name, seconds)`` is called after each of the
    :func:`writing_stages`. Returns the files written."""
    folder = pathlib.Path(folder)
    say = progress or (lambda *a: None)
    finish(rep, formats)
    t0 = time.perf_counter()
    html = render_html(rep)
    written = []
    stage = "writing HTML" if "html" in formats else "rendering HTML"     # the PDF is laid out from it
    if "html" in formats:
        path = folder / "report.html"
        path.write_text(html, encoding="utf-8")
        written.append(path)
    rep.timings[stage] = time.perf_counter() - t0
    say(stage, rep.timings[stage])
    if "pdf" in formats:
        t0 = time.perf_counter()
        path = folder / "report.pdf"
        with frozen_gc():           # the document and its results live on: the layout's collections skip them
            render_pdf(html, path)
        written.append(path)
        rep.timings["writing PDF"] = time.perf_counter() - t0
        say("writing PDF", rep.timings["writing PDF"])
    return written
