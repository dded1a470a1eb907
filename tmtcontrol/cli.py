"""The ``tmtcontrol`` command: argument parsing only; the work is in the library.

Exit codes: 0 success, 1 a failed check or a diverged simulation, 2 bad input
(one line on stderr naming the field and the problem, nothing written).
"""
from __future__ import annotations

import argparse
import sys

from . import __version__

__all__ = ["main"]


class UsageError(Exception):
    """Bad command-line input (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        raise UsageError(f"{self.prog}: {message}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="tmtcontrol",
        description="Force-tracking impedance control with the trajectory modification "
                    "technique (TMT): simulation, stability analysis, checks and reports.")
    parser.add_argument("--version", action="version", version=f"tmtcontrol {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("simulate", help="simulate a scenario (default: the paper's section V)")
    p.add_argument("scenario", nargs="?", default="paper", help="scenario TOML file or 'paper'")
    p.add_argument("--out", default="tmt-results", help="output folder (default ./tmt-results)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value, e.g. controller.f_d=5 (repeatable)")
    p.add_argument("--integrator", choices=["fixed", "cvodes"],
                   help="fixed-step compiled RK4 (default) or adaptive CVODES reference")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.set_defaults(func=_simulate)

    p = sub.add_parser("scenario", help="print a built-in scenario as TOML")
    p.add_argument("name", nargs="?", default="paper", choices=["paper"])
    p.set_defaults(func=_scenario)
    return parser


def _load(args):
    from .scenario import apply_overrides, load_scenario

    sc = load_scenario(args.scenario)
    sets = list(getattr(args, "set", []) or [])
    if getattr(args, "integrator", None):
        sets.append(f"simulation.integrator={args.integrator}")
    return apply_overrides(sc, sets) if sets else sc


def _simulate(args) -> int:
    from .metrics import format_table, segment_metrics
    from .output import atomic_folder, save_simulation
    from .simulate import Simulator

    sc = _load(args)
    res = Simulator(sc).run()
    with atomic_folder(args.out) as tmp:
        save_simulation(res, tmp, plots=not args.no_plots)
    print(f"scenario {sc.name!r}: {res.time.size} steps of {sc.controller.Ts * 1e3:g} ms, "
          f"{sc.simulation.integrator} integrator ({res.info['code']}), "
          f"path cond(J) {res.path.condition_number.min():.2f}-{res.path.max_condition:.2f}")
    print(format_table(segment_metrics(res)))
    print(f"wrote {args.out}/")
    return 0


def _scenario(args) -> int:
    from .scenario import dump_scenario, paper_scenario

    sys.stdout.write(dump_scenario(paper_scenario()))
    return 0


def main(argv: list[str] | None = None) -> int:
    from .scenario import ScenarioError
    from .simulate import SimulationError

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        return args.func(args)
    except (UsageError, ScenarioError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
