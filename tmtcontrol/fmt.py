"""Numbers formatted by meaning, for the report's tables and the figures'
labels: significant digits, SI units, thousands separators, powers of ten for
the very small and the very large, and words for what a number cannot say
(non-finite, not applicable)."""

from __future__ import annotations

import math

__all__ = ["num", "qty", "pct", "ratio", "value"]

_SUP = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_PREFIXED = {"s", "N", "m", "Hz"}          # units that read better with a prefix (ms, mN, mm, kHz)
_PREFIX = [(1e-9, "n"), (1e-6, "µ"), (1e-3, "m"), (1.0, ""), (1e3, "k")]
NBSP = "\u00a0"


def num(v, sig: int = 3) -> str:
    """``v`` to ``sig`` significant digits: 163,400 / 12.5 / 0.0312 /
    3.1 × 10⁻⁵; "–" for NaN or None, "∞" for infinity."""
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
        text = f"{mant:.{sig - 1}f}".rstrip("0").rstrip(".")
        if text in ("10", "-10"):                       # rounding carried into the next decade
            text, mag = text[:-1], mag + 1
        return f"{text}{NBSP}×{NBSP}10{str(mag).translate(_SUP)}".replace("-", "−")
    decimals = sig - 1 - mag
    rounded = round(v, decimals)                  # negative decimals round to tens, hundreds, ...
    text = f"{rounded:,.{max(decimals, 0)}f}"
    if "." in text:
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
