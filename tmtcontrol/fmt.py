"""Numbers formatted by meaning, for the report's tables and the figures'
labels: significant digits, SI units, thousands separators, powers of ten for
the very small and the very large, and words for what a number cannot say
(non-finite, not applicable)."""

from __future__ import annotations

import math

__all__ = ["num", "qty", "pct", "ratio", "down", "value", "column", "against", "digits_apart", "text_table", "RESIDUE"]

_SUP = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_PREFIXED = {"s", "N", "m", "Hz"}          # units that read better with a prefix (ms, mN, mm, kHz)
_PREFIX = [(1e-9, "n"), (1e-6, "µ"), (1e-3, "m"), (1.0, ""), (1e3, "k")]
NBSP = "\u00a0"


def num(v, sig: int = 3, trim: bool = True) -> str:
    """``v`` to ``sig`` significant digits: 163,400 / 12.5 / 0.0312 /
    3.1 × 10⁻⁵; "–" for NaN or None, "∞" for infinity. ``trim=False`` keeps
    the trailing zeros (0.00210, 1.50: every cell of a column shows ``sig``
    digits)."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    v = float(v)
    if math.isnan(v):
        return "–"
    if math.isinf(v):
        return "∞" if v > 0 else "−∞"
    if v == 0:
        return "0"
    mag = math.floor(math.log10(abs(v)))
    if mag < -3 or mag >= 9:
        mant = v / 10 ** mag
        text = f"{mant:.{sig - 1}f}"
        text = text.rstrip("0").rstrip(".") if trim else text
        if text.lstrip("-").startswith("10"):                       # rounding carried into the next decade
            text, mag = f"{mant / 10:.{sig - 1}f}", mag + 1
            text = text.rstrip("0").rstrip(".") if trim else text
        return f"{text}{NBSP}×{NBSP}10{str(mag).translate(_SUP)}".replace("-", "−")
    decimals = sig - 1 - mag
    rounded = round(v, decimals)                  # negative decimals round to tens, hundreds, ...
    text = f"{rounded:,.{max(decimals, 0)}f}"
    if trim and "." in text:
        text = text.rstrip("0").rstrip(".")
    return text.replace("-", "−")


def qty(v, unit: str, sig: int = 3) -> str:
    """``v`` with its SI unit, a prefix for s, N, m and Hz (2 ms, 56 µN,
    1.2 kHz); compound units keep their base (163,400 N/m)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return num(v)
    if unit in _PREFIXED and v != 0:
        a = abs(float(v))
        for scale, prefix in reversed(_PREFIX):
            if a >= scale * 0.9995:
                return f"{num(v / scale, sig)}{NBSP}{prefix}{unit}"
        return f"{num(v, sig)}{NBSP}{unit}"
    return f"{num(v, sig)}{NBSP}{unit}" if unit and unit != "1" else num(v, sig)


def pct(v, sig: int = 3) -> str:
    """A percentage."""
    return num(v, sig) + ("" if v is None or not math.isfinite(float(v)) else NBSP + "%")


def down(v, sig: int = 3):
    """``v`` rounded towards zero to ``sig`` significant digits, for a limit
    shown rounded: 159,774 N/m reads 159,000, not 160,000 (review 47: the
    report rounded a stiffness limit up, a user's safe value above the
    computed one); ``v`` unchanged if None, 0 or not finite."""
    if v is None or isinstance(v, bool) or not math.isfinite(float(v)) or v == 0:
        return v
    step = 10.0 ** (math.floor(math.log10(abs(float(v)))) - sig + 1)
    if step == 0.0:                 # a subnormal v (review 48: 5e-324 divided by 10**-326 = 0)
        return v
    # the quotient rounded to 12 digits first: 0.29 / 0.01 is 28.999999999999996 in binary, not a step below
    return math.copysign(math.floor(round(abs(float(v)) / step, 12)) * step, float(v))


def ratio(v, sig: int = 3) -> str:
    """A factor such as a margin: 8.17×."""
    return num(v, sig) + ("" if v is None or not math.isfinite(float(v)) else "×")


def value(v, unit: str = "") -> str:
    """A scenario value of any type: numbers with units, tuples as lists,
    booleans as yes/no, strings as they are."""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (tuple, list)):
        inner = ", ".join(value(x) for x in v)
        return f"[{inner}]" + (f"{NBSP}{unit}" if unit and unit != "1" else "")
    if isinstance(v, (int, float)):
        return num(v, 4) + (f"{NBSP}{unit}" if unit and unit != "1" else "")
    return str(v)


RESIDUE = 1e-9
"""A value smaller than this fraction of its column's largest magnitude is
rounding residue (double precision carries about 1e-16 relative per
operation; a simulation of 1e4-1e5 steps leaves 1e-12 and less), and a
table prints it as 0: a switch jump of 9.81e-14 N beside jumps of 30 N is
the arithmetic, not a force."""


def column(values, unit: str = "", sig: int = 3, attach: bool = False,
           reference: float = 0.0) -> tuple[str, list[str]]:
    """One table column: ``(unit, cells)`` with a single unit for the whole
    column (for s, N, m and Hz the SI prefix of its largest magnitude: 0.500 s
    and 1.50 s, never 500 ms beside 1.5 s) and every cell to ``sig``
    significant digits, trailing zeros kept (0.00210 %, 0.00211 %).
    Non-finite values and None read as in :func:`num`. ``attach``: each
    number cell carries the column's unit (4.20 mN), for tables read on
    narrow screens where the header scrolls away. A value below
    :data:`RESIDUE` times the column's largest magnitude, or ``reference``
    (the size of the quantities it was computed from, for a column that may
    hold residue alone), prints as 0."""
    finite = [abs(float(v)) for v in values if v is not None and math.isfinite(float(v)) and v != 0]
    if finite:
        floor = RESIDUE * max(*finite, float(reference))
        values = [0.0 if v is not None and math.isfinite(float(v)) and abs(float(v)) < floor else v for v in values]
        finite = [a for a in finite if a >= floor]
    scale, prefix = 1.0, ""
    if unit in _PREFIXED and finite:
        top = max(finite)
        for s, p in reversed(_PREFIX):
            if top >= s * 0.9995:
                scale, prefix = s, p
                break
        else:
            scale, prefix = _PREFIX[0]
    cells = [num(v, sig) if v is None or not math.isfinite(float(v)) or v == 0
             else num(float(v) / scale, sig, trim=False) for v in values]
    if attach and unit and unit != "1":
        cells = [c if c in ("–", "∞", "−∞") else f"{c}{NBSP}{prefix}{unit}" for c in cells]
    return prefix + unit, cells


def digits_apart(v, bound, sig: int = 3, most: int = 6) -> int:
    """The fewest significant digits, from ``sig`` up to ``most``, at which
    ``v`` and ``bound`` print differently with :func:`num`: ``sig`` when they
    are equal or either is missing or not finite (no digit tells them apart),
    ``most`` when none up to it does."""
    if v is None or bound is None or not math.isfinite(float(v)) or float(v) == float(bound):
        return sig
    return next((d for d in range(sig, most + 1) if num(v, d) != num(bound, d)), most)


def against(v, bound, sig: int = 3) -> str:
    """``v`` to at least ``sig`` significant digits, more (up to 6) while it
    would print as ``bound`` without being equal to it: 4.995 beside a bound
    of 5 prints 4.995, not 5."""
    return num(v, digits_apart(v, bound, sig))


def text_table(columns: list[tuple[str, list[str]]], left: tuple[int, ...] = (-1,)) -> str:
    """A plain-text table for the terminal from ``(header, cells)`` columns:
    each column as wide as its widest entry, numbers right-aligned, the
    columns ``left`` (indices; by default the last, a verdict or a note)
    left-aligned; a rule under the header."""
    widths = [max([len(h), *(len(c) for c in cells)]) for h, cells in columns]
    n = max((len(cells) for _, cells in columns), default=0)

    def line(texts):
        lefts = {j % len(columns) for j in left}
        parts = [t.ljust(w) if j in lefts else t.rjust(w) for j, (t, w) in enumerate(zip(texts, widths))]
        return "  ".join(parts).rstrip()

    head = line([h for h, _ in columns])
    rows = [line([cells[i] if i < len(cells) else "" for _, cells in columns]) for i in range(n)]
    return "\n".join([head, "-" * len(head), *rows])
