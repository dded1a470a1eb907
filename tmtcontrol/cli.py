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

    p = sub.add_parser("analyze", help="stability and damping of the TMT error dynamics (eqs. 22, 25)")
    p.add_argument("--scenario", help="take m, b, k, f_d, the k_e range and Ts from a scenario's normal axis")
    p.add_argument("--m", type=float, help="impedance mass, kg")
    p.add_argument("--b", type=float, help="impedance damping, N s/m")
    p.add_argument("--k", type=float, help="impedance stiffness, N/m")
    p.add_argument("--fd", type=float, default=None, help="desired force, N (default 10)")
    p.add_argument("--ke", type=float, help="environment stiffness, N/m")
    p.add_argument("--ke-min", type=float, help="lower end of the stiffness range, N/m")
    p.add_argument("--ke-max", type=float, help="upper end of the stiffness range, N/m")
    p.add_argument("--ts", type=float, help="control period, s: adds the sampled-data analysis")
    p.add_argument("--mp", type=float, help="robot's effective mass along the normal, kg "
                   "(default: smallest along the paper path)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--plot", metavar="DIR", help="write root locus, damping, step and stability-region figures")
    p.set_defaults(func=_analyze)

    p = sub.add_parser("design", help="optimal normal-axis impedance over a stiffness range (IPOPT)")
    p.add_argument("--m", type=float, required=True, help="impedance mass, kg")
    p.add_argument("--k", type=float, required=True, help="impedance stiffness, N/m (initial guess with --optimize-k)")
    p.add_argument("--ke-min", type=float, required=True, help="lower end of the stiffness range, N/m")
    p.add_argument("--ke-max", type=float, required=True, help="upper end of the stiffness range, N/m")
    p.add_argument("--ts", type=float, required=True, help="control period, s")
    p.add_argument("--max-overshoot", type=float, required=True, help="first-contact force overshoot bound, percent")
    p.add_argument("--optimize-k", action="store_true", help="optimise k as well as b")
    p.add_argument("--fd", type=float, default=10.0, help="desired force, N (default 10)")
    p.add_argument("--mp", type=float, default=None, help="robot's effective normal mass, kg "
                   "(default: smallest along the paper path)")
    p.add_argument("--margin", type=float, default=2.0,
                   help="sampled stability required up to margin x k_e_max (default 2)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--plot", metavar="DIR", help="write the cost curve and responses")
    p.set_defaults(func=_design)

    p = sub.add_parser("check", help="symbolic checks of the paper's derivation on the implemented code")
    p.add_argument("--json", action="store_true", help="print a JSON list instead of the table")
    p.set_defaults(func=_check)

    p = sub.add_parser("report", help="stability report of a scenario: report.html and report.pdf")
    p.add_argument("scenario", nargs="?", default="paper", help="scenario TOML file or 'paper'")
    p.add_argument("--out", default="tmt-report", help="output folder (default ./tmt-report)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value (repeatable)")
    p.set_defaults(func=_report)

    p = sub.add_parser("scenario", help="print a built-in scenario as TOML")
    p.add_argument("name", nargs="?", default="paper", choices=["paper"])
    p.set_defaults(func=_scenario)
    return parser


def _load(args):
    from .simulation.scenario import apply_overrides, load_scenario

    sc = load_scenario(args.scenario)
    sets = list(getattr(args, "set", []) or [])
    if getattr(args, "integrator", None):
        sets.append(f"simulation.integrator={args.integrator}")
    return apply_overrides(sc, sets) if sets else sc


def _simulate(args) -> int:
    from .simulation.metrics import format_table, segment_metrics
    from .files import atomic_folder
    from .simulation.output import save_simulation
    from .simulation.simulator import Simulator

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


def _analyze(args) -> int:
    import json

    from .files import atomic_folder, jsonable
    from .stability import analysis_kwargs, analyze, format_analysis, scenario_parameters

    if args.scenario:
        from .simulation.scenario import load_scenario

        for flag in ("m", "b", "k", "fd", "ke", "ke_min", "ke_max", "ts", "mp"):
            if getattr(args, flag) is not None:
                raise UsageError(f"--{flag.replace('_', '-')}: not allowed with --scenario")
        kw = analysis_kwargs(scenario_parameters(load_scenario(args.scenario)))
    else:
        for flag in ("m", "b", "k"):
            if getattr(args, flag) is None:
                raise UsageError(f"--{flag}: required (or use --scenario)")
        if args.ke is not None and (args.ke_min is not None or args.ke_max is not None):
            raise UsageError("--ke: give either --ke or --ke-min/--ke-max, not both")
        if args.ke is None and (args.ke_min is None or args.ke_max is None):
            raise UsageError("--ke: required (or both --ke-min and --ke-max)")
        kw = dict(m=args.m, b=args.b, k=args.k, f_d=10.0 if args.fd is None else args.fd,
                  Ts=args.ts, m_p=args.mp)
        kw.update(dict(k_e=args.ke) if args.ke is not None else dict(k_e_min=args.ke_min, k_e_max=args.ke_max))
    result = analyze(**kw)
    if args.plot:
        from .stability.figures import save_analysis_figures

        with atomic_folder(args.plot) as tmp:
            save_analysis_figures(result, tmp)
    result.pop("systems")
    print(json.dumps(jsonable(result), indent=2) if args.json else format_analysis(result))
    return 0


def _design(args) -> int:
    import json

    from .stability.design import DesignSpec, design_impedance, format_design
    from .files import atomic_folder, jsonable
    from .stability import paper_effective_mass

    spec = DesignSpec(m=args.m, k=args.k, k_e_min=args.ke_min, k_e_max=args.ke_max, Ts=args.ts,
                      max_overshoot=args.max_overshoot, f_d=args.fd, optimize_k=args.optimize_k,
                      m_p=args.mp if args.mp is not None else paper_effective_mass(),
                      stiffness_margin=args.margin)
    result = design_impedance(spec)
    if args.plot:
        from .stability.figures import save_design_figures

        with atomic_folder(args.plot) as tmp:
            save_design_figures(result, tmp)
    print(json.dumps(jsonable(result.as_dict()), indent=2) if args.json else format_design(result))
    return 0


def _check(args) -> int:
    import json

    from .checks.derivations import format_checks, run_checks
    from .files import jsonable

    results = run_checks()
    if args.json:
        print(json.dumps(jsonable([r.as_dict() for r in results]), indent=2))
    else:
        print(format_checks(results))
    return 0 if all(r.passed for r in results) else 1


def _report(args) -> int:
    import time

    from .files import atomic_folder
    from .report import build_report, write_report

    sc = _load(args)
    t0 = time.perf_counter()

    def progress(i, n, name):
        print(f"[{i}/{n}] {name} ... ({time.perf_counter() - t0:.1f} s)", file=sys.stderr, flush=True)

    rep = build_report(sc, command_line="tmtcontrol " + " ".join(sys.argv[1:]), progress=progress)
    with atomic_folder(args.out) as tmp:
        write_report(rep, tmp)
    for v in rep.verdicts:
        print(f"{'PASS' if v.passed else 'FAIL'}  {v.name}: {v.evidence}")
    print(f"wrote {args.out}/report.html and report.pdf ({time.perf_counter() - t0:.1f} s)")
    return 0


def _scenario(args) -> int:
    from .simulation.scenario import dump_scenario, paper_scenario

    sys.stdout.write(dump_scenario(paper_scenario()))
    return 0


def main(argv: list[str] | None = None) -> int:
    from .simulation.simulator import SimulationError

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        return args.func(args)
    except (UsageError, ValueError) as exc:   # ScenarioError, AnalysisError, DesignError are ValueErrors
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
