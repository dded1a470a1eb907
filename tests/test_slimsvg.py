"""slim_svg draws what matplotlib's SVG draws: every drawing element keeps its
geometry, text and, by the CSS cascade of the original, every property."""
import io
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from tmtcontrol.report.slimsvg import PRESENTATION_ATTRIBUTES, slim_svg

SVG = "{http://www.w3.org/2000/svg}"
DRAWN = {SVG + t for t in ("path", "use", "text", "rect", "image", "line", "circle", "ellipse", "polygon",
                           "polyline")}
GROUP_EFFECTS = ("transform", "clip-path", "opacity", "mask", "filter")


def decls(text):
    return {k.strip(): v.strip() for k, _, v in (p.partition(":") for p in (text or "").split(";")) if _}


def drawing(svg_text):
    """Each drawing element in document order: (tag, own geometry, text, the
    properties the cascade gives it, the effects of its ancestors). The
    cascade: style attribute > the stylesheet's universal rule > presentation
    attribute, then inherited from the parent (every property, which only
    over-approximates: both versions are resolved the same way)."""
    root = ET.fromstring(svg_text)
    rule = {}
    for st in root.iter(SVG + "style"):
        body = st.text.strip()
        assert body.startswith("*{") and body.endswith("}"), body
        rule = decls(body[2:-1])
    out = []

    def own(el):
        return {**{k: v for k, v in el.attrib.items() if k in PRESENTATION_ATTRIBUTES}, **rule,
                **decls(el.get("style"))}

    def walk(el, inherited, effects):
        props = {**inherited, **own(el)}
        eff = [*effects, tuple(el.get(a) for a in GROUP_EFFECTS)] if any(el.get(a) for a in GROUP_EFFECTS) \
            else effects
        if el.tag in DRAWN:
            geometry = {k: v for k, v in el.attrib.items() if k not in PRESENTATION_ATTRIBUTES
                        and k not in ("id", "style")}
            out.append((el.tag, geometry, (el.text or "").strip(), props, tuple(eff[:-1] if el.get("transform")
                                                                                 else eff)))
        for child in el:
            if child.tag not in (SVG + "defs", SVG + "metadata", SVG + "style"):
                walk(child, props, eff)

    walk(root, {}, [])
    return out


def figure_svg():
    import matplotlib
    from matplotlib.figure import Figure

    matplotlib.use("Agg")
    from tmtcontrol.plotstyle import styled

    with styled():
        fig = Figure(figsize=(4, 3))
        ax1, ax2 = fig.subplots(2, 1)
        t = np.linspace(0, 1, 200)
        ax1.plot(t, np.sin(8 * t), label="sin")
        ax1.plot(t, np.cos(8 * t), "k--", lw=0.8, label="cos")
        ax1.legend()
        ax1.set(title="a title", ylabel="y (N)")
        ax2.semilogy(t, np.exp(5 * t), marker="o", markevery=20)
        ax2.fill_between(t, 1, 1 + t, alpha=0.3)
        ax2.text(0.5, 2, "text with  two spaces")
        buf = io.StringIO()
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def test_a_figure_draws_the_same_with_a_third_of_the_elements():
    text = figure_svg()
    slim = slim_svg(text)
    assert drawing(slim) == drawing(text)
    n_before, n_after = len(list(ET.fromstring(text).iter())), len(list(ET.fromstring(slim).iter()))
    assert n_after < 0.5 * n_before, (n_before, n_after)
    root = ET.fromstring(slim)
    assert not list(root.iter(SVG + "style")) and not list(root.iter(SVG + "metadata"))
    left_in_style = [decls(el.get("style")) for el in root.iter() if el.get("style")]
    assert all(not set(d) & PRESENTATION_ATTRIBUTES for d in left_in_style), left_in_style


def test_the_cascade_order_and_what_must_stay():
    """The style beats the rule, the rule beats an attribute; a group with a
    transform or a referenced id is kept; a non-presentation declaration
    stays in style."""
    text = """<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" viewBox="0 0 10 10">
      <defs><style type="text/css">*{stroke-linejoin: round; stroke-linecap: butt}</style>
        <path id="m1" d="M 0 0 L 1 1" style="stroke: #000"/></defs>
      <g id="plain"><g id="inner"><path d="M 0 0 L 5 5" stroke-linecap="square" style="stroke-width: 2"/></g></g>
      <g id="moved" transform="translate(1 1)"><path d="M 1 1 L 2 2" style="stroke-linecap: round"/></g>
      <g id="used"><use xlink:href="#m1" x="1" y="1"/></g>
      <use xlink:href="#used"/>
      <text x="1" y="1" style="white-space: pre; font-size: 8px">a  b</text>
    </svg>"""
    slim = slim_svg(text)
    root = ET.fromstring(slim)
    assert drawing(slim) == drawing(text)
    paths = {p.get("d"): p for p in root.iter(SVG + "path")}
    assert paths["M 0 0 L 5 5"].get("stroke-linecap") == "butt"       # the rule over the attribute
    assert paths["M 0 0 L 5 5"].get("stroke-width") == "2"
    assert paths["M 1 1 L 2 2"].get("stroke-linecap") == "round"      # the style over the rule
    ids = {g.get("id") for g in root.iter(SVG + "g")}
    assert ids == {"moved", "used"}                                    # plain and inner are gone
    txt = next(root.iter(SVG + "text"))
    assert txt.get("style") == "white-space: pre" and txt.get("font-size") == "8px" and txt.text == "a  b"


@pytest.mark.parametrize("text", [
    "<svg xmlns='http://www.w3.org/2000/svg'><style>path {fill: red}</style><g><path d='M 0 0'/></g></svg>",
    "<svg xmlns='http://www.w3.org/2000/svg'><style>*{fill: red}</style><style>*{stroke: red}</style></svg>",
    "<svg xmlns='http://www.w3.org/2000/svg'><style>*{fill: red; -webkit-x: 1}</style></svg>",
    "<svg xmlns='http://www.w3.org/2000/svg'><g><path d='M 0 0' style='fill: red !important'/></g></svg>",
    "not xml at all <",
])
def test_anything_else_is_returned_unchanged(text):
    assert slim_svg(text) == text
