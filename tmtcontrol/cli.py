"""The ``tmtcontrol`` command: argument parsing only; the work is in the library."""
from __future__ import annotations

import argparse
import sys

from . import __version__

__all__ = ["main"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="tmtcontrol",
        description="Force-tracking impedance control with the trajectory modification "
                    "technique (TMT): simulation, stability analysis, checks and reports.")
    parser.add_argument("--version", action="version", version=f"tmtcontrol {__version__}")
    parser.add_subparsers(dest="command", metavar="COMMAND")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
