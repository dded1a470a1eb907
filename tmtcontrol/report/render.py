"""Rendering of the report document: HTML from a Jinja2 template with one
stylesheet for screen and print, and the PDF from that same HTML by
WeasyPrint (tables with header rows repeated on each page and "(continued)"
above a table's continuation, numbered tables and figures with captions, a
table of contents with page numbers, page numbers, the section in the
running header, A4 pages, tagged for accessibility).

The HTML is one self-contained file: the stylesheet inline, figures as SVG
data URIs, no scripts and no external references.
"""

from __future__ import annotations

import base64
import pathlib
import re
from importlib import resources

from .document import FigureBlock, Paragraph, Report, Table

__all__ = ["render_html", "render_pdf", "prepare_writing", "FORMATS", "RendererUnavailable"]

FORMATS = ("html", "pdf")


class RendererUnavailable(ValueError):
    """A format's renderer cannot be loaded: for the PDF, WeasyPrint or the
    system libraries it loads at import (Pango, HarfBuzz; see docs/install.md)."""


_VERDICT = {"PASS": ("pass", "✔ PASS"), "FAIL": ("fail", "✘ FAIL"), "converged": ("pass", "✔ converged"),
            "off_target": ("warn", "◐ off target"),
            "over_limit": ("fail", "✘ over a limit"), "beyond_limit": ("fail", "✘ beyond the limit"),
            "limit_cycle": ("warn", "◐ limit cycle"), "diverged": ("fail", "✘ diverged")}


def _template_text(name: str) -> str:
    return resources.files(__package__).joinpath("templates", name).read_text(encoding="utf-8")


def _blocks(rep: Report) -> list[dict]:
    """Sections as plain dicts for the template, tables and figures numbered
    in reading order."""
    n_tab = n_fig = 0
    out = []
    for s in rep.sections:
        blocks = []
        for b in s.blocks:
            if isinstance(b, Paragraph):
                blocks.append({"kind": "p", "text": b.text})
            elif isinstance(b, Table):
                n_tab += 1
                blocks.append({"kind": "table", "number": n_tab, "caption": b.caption, "head": b.head,
                               "rows": b.rows, "verdict_column": b.verdict_column})
            elif isinstance(b, FigureBlock):
                n_fig += 1
                src = "data:image/svg+xml;base64," + base64.b64encode(b.svg.encode()).decode()
                blocks.append({"kind": "figure", "number": n_fig, "caption": b.caption, "src": src,
                               "alt": b.alt or f"Figure {n_fig}"})
        out.append({"key": s.key, "title": s.title, "blocks": blocks})
    return out


def _head_cell(text: str):
    """A header cell, its unit in parentheses kept on one line (no break inside "(N s/m)")."""
    import markupsafe

    m = re.match(r"^(.*?)(\s*)(\([^()]*\))$", text)
    if not m:
        return markupsafe.escape(text)
    return markupsafe.Markup("{}{}<span class=\"unit\">{}</span>").format(m.group(1), m.group(2), m.group(3))


def render_html(rep: Report) -> str:
    """The report as one self-contained HTML document."""
    import jinja2

    from .. import __version__

    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=False)
    tpl = env.from_string(_template_text("report.html.j2"))
    from .document import provenance

    made = rep.data.get("provenance") or provenance()
    return tpl.render(rep=rep, sections=_blocks(rep), css=_template_text("report.css"), version=__version__, made=made,
                      n_pass=sum(v.passed for v in rep.verdicts),
                      mark=lambda ok: "✔ PASS" if ok else "✘ FAIL",
                      head_cell=_head_cell, verdict_class=lambda c: _VERDICT.get(c, ("", c))[0],
                      verdict_text=lambda c: _VERDICT.get(c, ("", c))[1])


def prepare_writing(formats=FORMATS) -> None:
    """Import the renderers ``formats`` need (WeasyPrint alone takes ~0.5 s),
    for example as :func:`~.document.build_report`'s ``prepare``, while its
    second process computes."""
    import jinja2  # noqa: F401

    if "pdf" in formats:
        _weasyprint()


def _weasyprint():
    """WeasyPrint, or :class:`RendererUnavailable` in one line if it (or a
    system library it opens at import, such as Pango) cannot be loaded."""
    try:
        import weasyprint
    except (ImportError, OSError) as exc:
        why = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise RendererUnavailable(f"--format pdf: WeasyPrint did not load ({why}); install its system libraries "
                                  "(docs/install.md) or write only the HTML with --format html") from None
    return weasyprint


def render_pdf(html: str, path: str | pathlib.Path) -> None:
    """The PDF of ``html`` (the same document, laid out by WeasyPrint for A4 print)."""
    import logging

    weasyprint = _weasyprint()
    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    logging.getLogger("fontTools").setLevel(logging.ERROR)
    # a tagged PDF (headings, tables, figures with their alt text in the structure tree: screen readers,
    # reflow) where WeasyPrint supports it (pdf_tags, WeasyPrint >= 60)
    weasyprint.HTML(string=html, base_url=None).write_pdf(str(path), pdf_tags=True)
