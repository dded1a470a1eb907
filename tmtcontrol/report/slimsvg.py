"""Matplotlib's SVG rewritten to draw the same with a third of the elements.

Matplotlib writes every artist in a ``<g id=...>`` of its own (a tick is
eight elements, three of which draw), styles each element with a ``style``
attribute and adds one universal CSS rule, ``*{stroke-linejoin: round;
stroke-linecap: butt}``. WeasyPrint, which lays out the PDF report, parses
every ``style`` attribute with its CSS tokenizer and matches every element
against the rule: about half of the PDF's painting time. :func:`slim_svg`
applies the cascade once, here:

- the rule's declarations and each element's ``style`` become presentation
  attributes (the style over the rule over an existing attribute, as CSS
  orders them); declarations that are not presentation attributes stay in
  ``style``;
- groups with nothing of their own (no attribute but an unreferenced id)
  are replaced by their children, which carry every property themselves;
- the RDF ``<metadata>`` block is dropped.

The result draws the same in WeasyPrint and in browsers (tested element by
element against the cascade of the original). An SVG whose stylesheet is
anything but that one universal rule, or with ``!important``, is returned
unchanged.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

__all__ = ["slim_svg", "PRESENTATION_ATTRIBUTES"]

_SVG = "http://www.w3.org/2000/svg"
_XLINK = "http://www.w3.org/1999/xlink"
_G, _STYLE, _METADATA = f"{{{_SVG}}}g", f"{{{_SVG}}}style", f"{{{_SVG}}}metadata"

PRESENTATION_ATTRIBUTES = frozenset((
    "alignment-baseline", "baseline-shift", "clip-path", "clip-rule", "color", "color-interpolation",
    "color-interpolation-filters", "display", "dominant-baseline", "fill", "fill-opacity", "fill-rule", "filter",
    "flood-color", "flood-opacity", "font-family", "font-size", "font-size-adjust", "font-stretch", "font-style",
    "font-variant", "font-weight", "image-rendering", "letter-spacing", "lighting-color", "marker-end",
    "marker-mid", "marker-start", "mask", "opacity", "overflow", "shape-rendering", "stop-color",
    "stop-opacity", "stroke", "stroke-dasharray", "stroke-dashoffset", "stroke-linecap", "stroke-linejoin",
    "stroke-miterlimit", "stroke-opacity", "stroke-width", "text-anchor", "text-decoration", "text-rendering",
    "visibility", "word-spacing", "writing-mode"))
"""The properties SVG 1.1 also accepts as attributes (section 6.4)."""

_UNIVERSAL_RULE = re.compile(r"\s*\*\s*\{([^{}]*)\}\s*")
_REFERENCE = re.compile(r"url\(#([^)]+)\)|^#(.+)$")


def _declarations(text: str) -> dict[str, str]:
    out = {}
    for part in text.split(";"):
        name, colon, value = part.partition(":")
        if colon:
            out[name.strip()] = value.strip()
    return out


def _referenced_ids(root) -> set[str]:
    ids = set()
    for el in root.iter():
        for value in el.attrib.values():
            for m in _REFERENCE.finditer(value):
                ids.add(m.group(1) or m.group(2))
    return ids


def _flatten(parent, keep: set[str], rule: dict[str, str]) -> None:
    """Replace each plain group under ``parent`` by its children, depth first."""
    children = []
    for child in parent:
        _flatten(child, keep, rule)
        plain = (child.tag == _G and child.get("id") not in keep
                 and all(k == "id" or rule.get(k) == v for k, v in child.attrib.items()))
        children.extend(list(child) if plain else [child])
    parent[:] = children


def slim_svg(text: str) -> str:
    """``text`` (an SVG written by matplotlib) with its cascade applied and
    its plain groups removed; unchanged if its stylesheet is not the single
    universal rule matplotlib writes."""
    if "!important" in text:             # a cascade this function does not apply
        return text
    ET.register_namespace("", _SVG)       # serialise as matplotlib does: SVG the default namespace,
    ET.register_namespace("xlink", _XLINK)   # xlink: for href
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return text
    rule: dict[str, str] = {}
    for parent in list(root.iter()):
        for child in list(parent):
            if child.tag == _METADATA:
                parent.remove(child)
            elif child.tag == _STYLE:
                m = _UNIVERSAL_RULE.fullmatch(child.text or "")
                if m is None or rule:
                    return text
                rule = _declarations(m.group(1))
                if not set(rule) <= PRESENTATION_ATTRIBUTES:
                    return text
                parent.remove(child)
    for el in root.iter():
        own = _declarations(el.attrib.pop("style", ""))
        for name, value in {**rule, **own}.items():           # the style over the rule over an attribute
            if name in PRESENTATION_ATTRIBUTES:
                el.set(name, value)
        rest = "; ".join(f"{k}: {v}" for k, v in own.items() if k not in PRESENTATION_ATTRIBUTES)
        if rest:
            el.set("style", rest)
    _flatten(root, _referenced_ids(root), rule)
    return ET.tostring(root, encoding="unicode")
