"""What a study script built on tmtcontrol shares: its flags' number checks and exit codes.

The scripts in analysis/ (and a user's own) parse their flags with
:class:`Parser` and the types below and run ``raise SystemExit(run(main))``,
so that, as tmtcontrol's own commands: bad input is one line naming the flag
and the problem, exit code 2, nothing written (a refused ``--out`` included);
a computed verdict that fails exits 1 with its line; the study's own exit
code otherwise (review 64: seven of the eight studies answered a bad number
with a traceback).
"""
import argparse
import math
import sys

from .files import VerdictFailed

__all__ = ["Parser", "positive", "finite", "numbers", "run"]


class Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line (no usage dump): a
    ``ValueError`` that :func:`run` prints."""

    def error(self, message):
        raise ValueError(f"{self.prog}: {message}")


def positive(kind=float):
    """An argparse type: a finite number above 0 (``kind`` float or int)."""
    what = "a whole number" if kind is int else "a number"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"must be above 0 and finite, got {text!r}")
        return value

    parse.__name__ = f"positive {kind.__name__}"
    return parse


def finite(text: str) -> float:
    """An argparse type: a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def numbers(text: str) -> list[float]:
    """An argparse type: distinct finite numbers above 0, separated by commas."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas, got {text!r}") from None
    if not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected finite numbers above 0, got {text!r}")
    if len(set(values)) != len(values):
        raise argparse.ArgumentTypeError(f"each value once, got {text!r}")
    return values


def run(main, argv=None) -> int:
    """``main(argv)``'s exit code (None: 0); a ``ValueError`` (bad input:
    the parser's, a scenario key's, a refused output folder's) is one line
    on stderr and exit 2; a failed computed verdict one line and exit 1."""
    try:
        return main(argv) or 0
    except VerdictFailed as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
