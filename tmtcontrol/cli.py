"""The ``tmtcontrol`` command: argument parsing only; the work is in the library.

Exit codes: 0 success; 1 a computed verdict failed (a check, an unstable
analysis, an infeasible or unverified design, a diverged or non-converged
simulation); 2 bad input (one line on stderr naming the key or flag and the
problem, nothing written); 3 the results could not be saved (a full disk, or
the output folder changed during the run; one line, the previous output
intact); 130 Ctrl-C, 143 SIGTERM (one line, nothing left behind).
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import os
import shlex
import sys

from . import __version__

__all__ = ["main", "run", "build_parser"]


class UsageError(ValueError):
    """Bad command-line input (exit code 2)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        raise UsageError(f"{self.prog}: {message}")

    def _print_message(self, message, file=None):
        # argparse ignores a failed write: --help or --version into a full disk exited 0 with nothing shown;
        # the OSError now reaches main, whose one line and exit 3 every other failed output write gets
        if message:
            file = sys.stderr if file is None else file
            file.write(message)
            file.flush()


_RAW = argparse.RawDescriptionHelpFormatter


def _add_scenario_args(p, out_default: str):
    p.add_argument("scenario", nargs="?", default="paper", help="scenario TOML file, or a built-in: 'paper' (default), 'ur5', 'panda', 'ur5-pipe', 'panda-bowl'")
    p.add_argument("--out", default=out_default,
                   help=f"output folder (default ./{out_default}); an existing folder is replaced only "
                        "if tmtcontrol wrote it")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value, e.g. controller.f_d=5 (repeatable; TOML syntax)")
    p.add_argument("--max-steps", type=int, default=None, metavar="N",
                   help="refuse runs of more than N control steps (default 1,000,000)")


def _add_scenario_set(p) -> None:
    """``--set`` for a command whose scenario is optional (``--scenario``)."""
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="with --scenario: override a scenario value, e.g. controller.x_e_error=0.005 (repeatable; "
                        "TOML syntax)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="tmtcontrol",
        description="Force-tracking impedance control with the trajectory modification "
                    "technique (TMT): simulation, stability analysis, checks and reports. SI units.")
    parser.add_argument("--version", action="version", version=f"tmtcontrol {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser("simulate", help="simulate a scenario (default: the paper's section V)",
                       formatter_class=_RAW, epilog="example:\n  tmtcontrol simulate paper --set controller.f_d=5 --out run1")
    _add_scenario_args(p, "tmt-results")
    p.add_argument("--integrator", choices=["fixed", "cvodes"],
                   help="fixed-step compiled RK4 (default) or adaptive CVODES reference")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--controller", metavar="DIR", help="software in the loop: compile the C controller exported "
                   "to DIR (tmtcontrol export --inner-loop) and run it in place of the built-in one")
    p.add_argument("--plant", choices=["builtin", "mujoco"], default="builtin",
                   help="the arm's dynamics: tmtcontrol's (default) or MuJoCo's model of the same URDF with the "
                        "ideal spring contact (an independent check of eq. 1 in the loop) or, with "
                        "--set simulation.mujoco_contact=\"contact\", MuJoCo's own contact calibrated to k_e "
                        "(needs the mujoco extra)")
    p.add_argument("--animate", action="store_true",
                   help="also write animation.gif: the arm doing the task on the surface, the force on it "
                        "(10 frames per simulated second, real time); drawn by MuJoCo's renderer where it can "
                        "render (MUJOCO_GL=egl or osmesa, an arm with a URDF), else by matplotlib")
    p.set_defaults(func=_simulate)

    p = sub.add_parser("compare", help="run one scenario with several force-tracking laws, side by side",
                       formatter_class=_RAW,
                       description="Each law runs with its parameters from the scenario if it is the scenario's "
                                   "law, otherwise its documented defaults.\n"
                                   "Exit 1 if any law has a segment that did not converge.",
                       epilog="example:\n  tmtcontrol compare paper --laws tmt,integral --set controller.x_e_error=0.005")
    _add_scenario_args(p, "tmt-compare")
    p.add_argument("--laws", default=None, metavar="A,B,...",
                   help="comma-separated law names (default: all registered laws)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.set_defaults(func=_compare)

    p = sub.add_parser("crosscheck", help="the scenario on tmtcontrol's plant and on MuJoCo's, segment by segment",
                       formatter_class=_RAW,
                       description="Runs the scenario's controller on the built-in plant and on MuJoCo's dynamics of "
                                   "the same URDF (simulation.mujoco_contact:\nthe ideal spring, or MuJoCo's own "
                                   "contact), and compares each segment's verdict and contact force. Exit 1 if the\n"
                                   "plants disagree: a verdict differs, or the two forces differ over a segment's "
                                   "steady-state window (its last\nquarter) by more than 1e-4 f_d (at least 1 mN) with the "
                                   "spring, 5e-4 f_d (at least 5 mN) with MuJoCo's\ncontact. Needs the mujoco extra "
                                   "and an arm with a URDF.",
                       epilog="example:\n  tmtcontrol crosscheck ur5 --out ur5-crosscheck")
    _add_scenario_args(p, "tmt-crosscheck")
    p.add_argument("--no-plots", action="store_true", help="skip the figure")
    p.set_defaults(func=_crosscheck)

    p = sub.add_parser(
        "analyze", help="stability and damping of the TMT error dynamics (eqs. 22, 25)",
        formatter_class=_RAW,
        description="Give either --scenario, or --m, --b, --k (required) with --ke or both --ke-min and --ke-max.\n"
                    "--ts adds the sampled-data analysis. Exit 1 if any verdict is 'unstable'.",
        epilog="examples:\n  tmtcontrol analyze --m 1 --b 60 --k 100 --ke-min 2000 --ke-max 20000 --ts 0.001\n"
               "  tmtcontrol analyze --scenario paper --plot figs")
    p.add_argument("--scenario", help="take m, b, k, f_d, the k_e range, Ts and the path's masses from a scenario")
    p.add_argument("--m", type=float, help="impedance mass, kg (required without --scenario)")
    p.add_argument("--b", type=float, help="impedance damping, N s/m (required without --scenario)")
    p.add_argument("--k", type=float, help="impedance stiffness, N/m (required without --scenario)")
    p.add_argument("--fd", type=float, default=None, help="desired force, N (default 10)")
    p.add_argument("--ke", type=float, help="environment stiffness, N/m")
    p.add_argument("--ke-min", type=float, help="lower end of the stiffness range, N/m")
    p.add_argument("--ke-max", type=float, help="upper end of the stiffness range, N/m")
    p.add_argument("--ts", type=float, help="control period, s: adds the sampled-data analysis")
    p.add_argument("--mp", type=float, help="robot's effective mass along the normal, kg, with --ts "
                   "(default: both extremes along the paper path)")
    p.add_argument("--delay", type=int, help="computation delay, samples, with --ts (default 0)")
    p.add_argument("--x-e-error", type=float, help="surface-location error, m: the controller's estimate minus "
                   "the true surface (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--plot", metavar="DIR", help="write root locus, damping, step and stability-region figures to DIR")
    _add_scenario_set(p)
    p.set_defaults(func=_analyze)

    p = sub.add_parser(
        "design", help="optimal normal-axis impedance over a stiffness range (IPOPT)", formatter_class=_RAW,
        description="Give either --scenario (m, k, the k_e range, Ts, f_d, delay, force filter and the path's\n"
                    "largest effective normal mass from the scenario; flags given override them; overshoot bound\n"
                    "the scenario's requirements.first_contact_overshoot, else 5 %, unless --max-overshoot), or all\n"
                    "of --m, --k, --ke-min, --ke-max, --ts, --max-overshoot.\n"
                    "Exit 1 if the specification is infeasible or the design fails its own verification.",
        epilog="examples:\n"
               "  tmtcontrol design --m 1 --k 100 --ke-min 2000 --ke-max 20000 --ts 0.001 --max-overshoot 5\n"
               "  tmtcontrol design --scenario ur5")
    p.add_argument("--scenario", metavar="NAME|FILE", help="take the specification from a scenario (paper, ur5, "
                   "panda or a TOML file); for its arm the largest effective normal mass along the checked path")
    p.add_argument("--m", type=float, help="impedance mass, kg (required without --scenario)")
    p.add_argument("--k", type=float,
                   help="impedance stiffness, N/m (required without --scenario; initial guess with --optimize-k)")
    p.add_argument("--ke-min", type=float, help="lower end of the stiffness range, N/m (required without --scenario)")
    p.add_argument("--ke-max", type=float, help="upper end of the stiffness range, N/m (required without --scenario)")
    p.add_argument("--ts", type=float, help="control period, s (required without --scenario)")
    p.add_argument("--max-overshoot", type=float,
                   help="first-contact force overshoot bound, percent (required without --scenario; with it "
                        "default the scenario's requirements.first_contact_overshoot, else 5)")
    p.add_argument("--optimize-k", action="store_true", help="optimise k as well as b")
    p.add_argument("--fd", type=float, default=None, help="desired force, N (default 10, or the scenario's)")
    p.add_argument("--mp", type=float, default=None, help="robot's effective normal mass, kg "
                   "(default: largest along the paper path, or the scenario's path: the worst case)")
    p.add_argument("--margin", type=float, default=2.0,
                   help="sampled stability required up to margin x k_e_max (default 2)")
    p.add_argument("--delay", type=int, default=None, help="computation delay, samples (default 0, or the scenario's)")
    p.add_argument("--filter-hz", type=float, default=None,
                   help="first-order force-filter cut-off, Hz (default 0: no filter, or the scenario's)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.add_argument("--plot", metavar="DIR", help="write the cost curve and responses to DIR")
    _add_scenario_set(p)
    p.set_defaults(func=_design)

    p = sub.add_parser("check", help="symbolic checks of the paper's derivation on the implemented code")
    p.add_argument("--scenario", metavar="NAME|FILE", help="also check the task-frame loop of this scenario's arm "
                   "with the ideal inner loop (paper, ur5, panda or a TOML file)")
    p.add_argument("--json", action="store_true", help="print a JSON list instead of the table")
    _add_scenario_set(p)
    p.set_defaults(func=_check)

    p = sub.add_parser("sweep", help="many simulations over grids and random draws of scenario keys",
                       formatter_class=_RAW,
                       description="Runs every case of a sweep file (see `tmtcontrol sweep --example`) and writes\n"
                                   "results.parquet, summary.json and figures to --out. Finished cases are kept in\n"
                                   "OUT.partial/ as they complete; --resume runs only the missing ones.\n"
                                   "Exit 1 if any case did not converge.",
                       epilog="examples:\n  tmtcontrol sweep --example > robust.toml\n"
                              "  tmtcontrol sweep robust.toml --workers 2\n"
                              "  tmtcontrol sweep robust.toml --dask tcp://scheduler:8786 --resume")
    p.add_argument("sweep", nargs="?", help="sweep TOML file")
    p.add_argument("--out", default="tmt-sweep", help="output folder (default tmt-sweep)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1: this process)")
    p.add_argument("--dask", metavar="local|ADDRESS", help="run on Dask: 'local' starts a LocalCluster of "
                   "--workers processes; an address (tcp://host:port) uses a running scheduler")
    p.add_argument("--resume", action="store_true", help="continue an interrupted sweep of the same file")
    p.add_argument("--example", action="store_true", help="print a commented example sweep file and exit")
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("--limits", choices=("auto", "on", "off"), default="auto",
                   help="each case's deciding stiffness limit, as analyze --scenario prints it (predicted_limit, with "
                   "the small-signal, periodic and first-contact columns), which its verdicts use; auto "
                   "(default): on unless a random axis makes every case a new analysis")
    p.add_argument("--max-steps", type=int, default=None, metavar="N",
                   help="refuse cases longer than N control steps (default 1,000,000)")
    p.add_argument("--max-cases", type=int, default=100_000, metavar="N",
                   help="refuse sweeps of more than N cases, before generating any (default 100,000)")
    p.set_defaults(func=_sweep)

    p = sub.add_parser("report", help="stability report of a scenario: report.html and report.pdf",
                       formatter_class=_RAW,
                       description="Runs the checks, the analysis, the simulation and the design for one scenario.\n"
                                   "Exit 1 if any verdict is FAIL.",
                       epilog="example:\n  tmtcontrol report paper --out review")
    _add_scenario_args(p, "tmt-report")
    p.add_argument("--format", default="html,pdf", metavar="html,pdf",
                   help="which files to write: html, pdf or both (default: html,pdf)")
    p.add_argument("--plant", choices=["builtin", "mujoco"], default="builtin",
                   help="mujoco: add a section with the scenario on MuJoCo's dynamics against the built-in plant "
                        "(its contact model: simulation.mujoco_contact; needs the mujoco extra)")
    p.set_defaults(func=_report)

    p = sub.add_parser("robot", help="load an arm (puma560, ur5, panda or a URDF file), print its chain and "
                       "check its model (identities, Pinocchio); exit 1 if a check fails",
                       epilog="examples:\n  tmtcontrol robot ur5\n  tmtcontrol robot my_arm.urdf --tip tool0")
    p.add_argument("source", metavar="NAME|FILE", help="puma560, ur5, panda, or the path of a .urdf file")
    p.add_argument("--tip", help="tip link or frame (default: the bundled arm's, or the file's single leaf link)")
    p.add_argument("--base", help="base link fixed to the world (default: the root link)")
    p.add_argument("--joints", help="comma-separated actuated joints (default: every movable joint base to tip)")
    p.add_argument("--samples", type=int, default=20, help="random states checked (default: 20)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random states (default: 0)")
    p.add_argument("--against", choices=["mujoco"], action="append", default=[],
                   help="also compare M, the bias, fk and the tip Jacobian with MuJoCo's model of the same URDF "
                        "(needs the mujoco extra)")
    p.set_defaults(func=_robot)

    p = sub.add_parser("export", help="the scenario's controller as a C99 library for a real-time loop",
                       formatter_class=_RAW,
                       description="Writes tmt_controller.h/.c and tmt_controller_gen.c/.h (generated by CasADi from\n"
                                   "the simulated controller; --prefix renames tmt), a Makefile, example_loop.c,\n"
                                   "replay.c, README.md and export.json to --out.",
                       epilog="examples:\n  tmtcontrol export paper --out tmt-c\n"
                              "  tmtcontrol export paper --inner-loop --out tmt-c && tmtcontrol simulate paper --controller tmt-c")
    p.add_argument("scenario", nargs="?", default="paper", help="scenario TOML file, or a built-in: 'paper' (default), 'ur5', 'panda', 'ur5-pipe', 'panda-bowl'")
    p.add_argument("--out", default="tmt-export",
                   help="output folder (default ./tmt-export); an existing folder is replaced only if tmtcontrol wrote it")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario value, e.g. controller.f_d=5 (repeatable; TOML syntax)")
    p.add_argument("--inner-loop", action="store_true",
                   help="also compute the joint torques of eqs. (5)-(6) (for a torque-controlled robot)")
    p.add_argument("--prefix", default="tmt", metavar="NAME",
                   help="prefix of every C name: NAME_controller.h/.c, NAME_step, NAME_params, NAME_N_COMMAND ... "
                        "(default: tmt); two exports with different prefixes link into one program")
    p.set_defaults(func=_export)

    p = sub.add_parser("cache", help="the compile cache: where it is and its size (--info), or empty it (--clear)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--info", action="store_true", help="print the cache folder, its libraries and size (default)")
    g.add_argument("--clear", action="store_true", help="remove the libraries tmtcontrol put in the cache")
    p.set_defaults(func=_cache)

    p = sub.add_parser("scenario", help="print a built-in scenario as TOML, or the scenario JSON Schema")
    p.add_argument("name", nargs="?", default="paper", choices=["paper", "ur5", "panda", "ur5-pipe", "panda-bowl"])  # tests: == BUILTIN_ARMS
    p.add_argument("--schema", action="store_true", help="print the JSON Schema of scenario files")
    p.set_defaults(func=_scenario)
    return parser


def _load(args):
    from .simulation.scenario import apply_overrides, load_scenario

    sc = load_scenario(args.scenario)
    sets = list(getattr(args, "set", []) or [])
    if getattr(args, "integrator", None):
        sets.append(f"simulation.integrator={args.integrator}")
    return _noted(apply_overrides(sc, sets) if sets else sc)


def _load_named(args):
    """The scenario ``args.scenario`` (a file or a built-in) with ``args.set``'s
    overrides, its :func:`_noted` lines held; ``--set`` without ``--scenario``
    (a flags-only form, which has no scenario to override) is refused."""
    from .simulation.scenario import apply_overrides, load_scenario

    if args.scenario is None:
        if args.set:
            raise UsageError("--set: overrides a scenario's value; give --scenario too")
        return None
    sc = load_scenario(args.scenario)
    return _noted(apply_overrides(sc, args.set) if args.set else sc)


def _noted(sc):
    """``sc``, its values that read like a unit mistake held by :func:`_hold_notes`
    (an arm's too: a URDF file's lengths or limits, review 69)."""
    from .model.robot import unit_notes_of

    def arm():                  # loaded for a user's URDF only (the simulator's import is not a warm run's cost)
        from .simulation.simulator import robot_of

        return robot_of(sc)

    _hold_notes(sc.environment.unit_notes() + sc.controller.unit_notes() + unit_notes_of(sc.robot.model, arm))
    return sc


_NOTES: list[str] = []
"""Notes held until the command's input checks have passed: a refused input
prints its one line only (a note beside it would be a second line)."""


def _hold_notes(notes) -> None:
    """Hold ``notes`` (one line each) for :func:`_print_notes`."""
    _NOTES.extend(notes)


def _print_notes() -> None:
    """Print the held notes on stderr, once: where a command's checks end (its
    output folder accepted, its arm loaded), or as :func:`main` returns."""
    while _NOTES:
        print(f"note: {_NOTES.pop(0)}", file=sys.stderr, flush=True)


def _simulate(args) -> int:
    from .drawing import FigureWorkers
    from .simulation.output import FIGURE_MODULE

    if args.animate:        # before anything imports MuJoCo: its offscreen renderer without a window
        from .simulation.mujoco_render import prefer_headless_gl

        prefer_headless_gl()

    # matplotlib is imported by the figure processes while this one loads CasADi and simulates
    with FigureWorkers(FIGURE_MODULE, processes=0 if args.no_plots else 2) as workers:
        return _simulate_with(args, workers)


def _simulate_with(args, workers) -> int:
    from . import fmt
    from .files import OutputFolder
    from .simulation.metrics import first_contact, format_table, orientation_transient, segment_metrics
    from .simulation.output import save_simulation
    from .simulation.simulator import simulator_for
    from .simulation.simulator import check_run_size
    from .stability.analysis import with_stiffness_limit

    sc = _load(args)
    check_run_size(sc, args.max_steps)
    controller = None
    if args.plant != "mujoco" and (unused := sc.simulation.mujoco_only()):
        _hold_notes([f"{', '.join(unused)}: for --plant mujoco only; the built-in plant ignores "
                     f"{'it' if len(unused) == 1 else 'them'}"])
    if args.plant == "mujoco":
        if getattr(args, "integrator", None):
            raise UsageError("--integrator: the MuJoCo plant integrates with MuJoCo's RK4 (10 steps per control "
                             "period); --integrator chooses the built-in plant's")
        _mujoco_ready(sc, "--plant mujoco")
        if unused := sc.simulation.builtin_only():
            _hold_notes([f"{', '.join(unused)}: for the built-in plant only; the MuJoCo plant integrates with "
                         f"MuJoCo's RK4 and ignores {'it' if len(unused) == 1 else 'them'}"])
            sc = sc.replace(simulation=sc.simulation.on_mujoco())     # ignored in the summary and limit too
    if args.controller is not None:            # compiled (or refused) before anything is written
        from .export.sil import CompiledController

        controller = CompiledController(args.controller, flag="--controller", scenario=sc, isolated=True)
        import os

        here, ctl = os.path.realpath(args.out), os.path.realpath(args.controller)
        if ctl == here or ctl.startswith(here + os.sep):
            raise UsageError(f"--out: {args.out} holds the --controller folder {args.controller}; the run would "
                             "replace the exported controller: choose another folder (nothing was written)")
    with OutputFolder(args.out, "--out") as out:
        _print_notes()
        if controller is not None:              # the exported C, against the built-in plant or MuJoCo's
            from .export.sil import simulate_with_controller

            res = simulate_with_controller(sc, controller, max_steps=args.max_steps, plant=args.plant)
        elif args.plant == "mujoco":
            from .simulation.mujoco_plant import simulate_on_mujoco

            res = simulate_on_mujoco(sc, max_steps=args.max_steps)
        else:
            res = simulator_for(sc).run(max_steps=args.max_steps)
        memo: dict = {}                           # the deciding limit, computed once for the run and its message
        # a segment beyond the loop's limit is not stable; a failing one's line quotes the limit summary.json holds
        res = with_stiffness_limit(res, memo=memo, quote=True)
        # without figures the second core is free for half of the CSV
        save_simulation(res, out.path, plots=not args.no_plots, workers=workers,
                        csv_processes=2 if args.no_plots else 1)
        drawn = None
        if args.animate:
            from .simulation.animation import write_animation

            drawn = write_animation(res, out.path / "animation.gif")
        out.commit()
    print(f"scenario {sc.name!r}: {res.time.size} steps of {sc.controller.Ts * 1e3:g} ms, "
          + (f"plant {res.info['plant']}, {res.info['integrator']} ({res.info['code']}), " if "plant" in res.info
             else f"{sc.simulation.integrator} integrator ({res.info['code']}), ")
          + f"path cond(J) {res.path.condition_number.min():.2f}-{res.path.max_condition:.2f}")
    if drawn is not None:
        print("animation.gif drawn by " + ("MuJoCo's renderer" if drawn.renderer == "mujoco" else
                                            f"matplotlib ({drawn.why})"))
    segs = segment_metrics(res)
    print(format_table(segs))
    fc = first_contact(res)
    if fc.time is None:
        print("first contact: never (the run does not touch the surface)")
    else:
        # the next second, or what is left of the contact's segment (a 10 ms run read "in the next second")
        when = "the next second" if fc.whole_window else f"the {fmt.qty(fc.window, 's')} left of its segment"
        print(f"first contact at {fc.time:.3f} s: peak {fmt.qty(fc.peak_force, 'N')} = {fmt.num(fc.peak_ratio)} f_d, "
              f"{fc.bounces} bounce(s) in {when}")
    if (use := res.limit_use()) is not None and (clipped := use.on_clip()):
        # review 43: a converged run on the clip said so only in summary.json
        print(f"note: the torque sat on its clip (robot.saturate): {clipped}; the run's torques are within tau_max "
              "only because the loop clips them, as the drive must")
    if tilted := orientation_transient(segs, sc.controller.orientation_tolerance):
        # review 62: a tool five times its orientation tolerance off mid-segment, every segment converged
        print(f"note: the tool's orientation error within a segment: {tilted}")
    print(f"wrote {out.out}/")
    return _verdict_exit(sc, segs, memo)


def _export(args) -> int:
    from .export.generate import check_prefix, export_controller
    from .files import OutputFolder

    check_prefix(args.prefix)
    sc = _load(args)
    with OutputFolder(args.out, "--out") as out:
        _print_notes()
        info = export_controller(sc, out.path, inner_loop=args.inner_loop, prefix=args.prefix)
        out.commit()
    delay = f"delay {info['delay']} samples" + (" (none in the code: no torques to hold without --inner-loop)"
                                                  if info["delay"] != info["delay_in_code"] else "")
    print(f"scenario {sc.name!r}: law {info['law']}, {delay}, inner loop "
          f"{'yes' if info['inner_loop'] else 'no'}; {info['instructions']} generated instructions, "
          f"{info['sizes']['w']} work doubles")
    print(f"wrote {out.out}/ (make -C {out.out} builds the library, replay and example_loop)")
    return 0


def _compare(args) -> int:
    from .control.laws import laws
    from .files import OutputFolder
    from .simulation.compare import check_law_names, compare_laws, format_comparison, save_comparison
    from .simulation.simulator import check_run_size

    sc = _load(args)
    if args.laws is None:
        names = list(laws())
    else:
        try:
            names = check_law_names(n.strip() for n in args.laws.split(","))
        except ValueError as exc:
            raise UsageError(f"--laws: {exc}") from None
    check_run_size(sc, args.max_steps)
    with OutputFolder(args.out, "--out") as out:
        _print_notes()
        from .stability.analysis import with_stiffness_limit

        cmp = compare_laws(sc, names, max_steps=args.max_steps, prepare=with_stiffness_limit)
        save_comparison(cmp, out.path, plots=not args.no_plots)
        out.commit()
    print(f"scenario {sc.name!r}, {len(names)} laws")
    print(format_comparison(cmp))
    for n, r in cmp.runs.items():
        if clipped := r.on_clip():
            # review 62: simulate says so whatever the verdict; compare said nothing of a converged law's clip
            print(f"note: law {n}: the torque sat on its clip (robot.saturate): {clipped}")
    print(f"wrote {out.out}/")
    from .fmt import num

    bad = [(n, i, s) for n, r in cmp.runs.items() for i, s in enumerate(r.segments, 1) if s.verdict != "converged"]
    for n, r in cmp.runs.items():
        if r.result is None:
            print(f"diverged: law {n}: {r.error}", file=sys.stderr)
    for n, i, s in bad:
        print(f"{s.verdict}: law {n}, segment {i} ({s.start:g}-{s.end:g} s), k_e = {num(s.stiffness, 4)} N/m; "
              f"{s.reason}", file=sys.stderr)
    return 0 if cmp.converged else 1


def _mujoco_ready(sc, flag: str) -> None:
    """Refuse (one line, exit 2, before anything is written) a MuJoCo run that cannot be made."""
    from .model.against_mujoco import MujocoMissing, mujoco_model
    from .simulation.simulator import robot_of

    try:
        mujoco_model(robot_of(sc))
    except (MujocoMissing, NotImplementedError) as exc:
        raise UsageError(f"{flag}: {exc}") from None
    from .simulation.geometry import surface_of
    from .simulation.mujoco_plant import check_contact
    from .simulation.simulator import robot_task

    check_contact(sc, surface_of(sc))          # ScenarioError: one line naming the key
    task = robot_task(robot_of(sc))
    if sc.simulation.mujoco_contact == "contact" and not task.rotational:
        # review 63: on a position task the tool's orientation is free, so MuJoCo's spherical tip touches the part
        # off the tool point (r (1 - cos theta) deeper): the 4-joint UR5 read 5.5 mN apart from the built-in plant
        _hold_notes([f'simulation.mujoco_contact = "contact" on a position task ({task.n} '
                     f"joints): MuJoCo touches with the tool's spherical tip (robot.tool_radius = "
                     f"{sc.robot.tool_radius:g} m), whose point on the part is the tool point only while the tool "
                     "is normal to it, and this task leaves the orientation free: the two plants differ by the "
                     "tip's geometry too (the spring contact, the default, acts at the tool point)"])


def _crosscheck(args) -> int:
    from .files import OutputFolder
    from .simulation.crosscheck import crosscheck, format_crosscheck, save_crosscheck
    from .simulation.simulator import check_run_size

    sc = _load(args)
    check_run_size(sc, args.max_steps)
    _mujoco_ready(sc, "crosscheck")
    from .stability.analysis import with_stiffness_limit

    memo: dict = {}
    with OutputFolder(args.out, "--out") as out:
        _print_notes()
        # the same verdicts as simulate: a segment beyond the loop's limit is beyond_limit on both plants
        c = crosscheck(sc, max_steps=args.max_steps, prepare=lambda r: with_stiffness_limit(r, memo=memo))
        save_crosscheck(c, out.path, plots=not args.no_plots)
        out.commit()
    print(f"scenario {sc.name!r}: the built-in plant and MuJoCo ({c.mujoco.info['code']}, "
          f"{c.mujoco.info['plant'][len('mujoco ('):-1]})")
    print(format_crosscheck(c))
    print(f"wrote {out.out}/")
    return 0 if c.agree else 1


def _verdict_exit(sc, segs, memo: dict | None = None) -> int:
    """1 (with one line per failing segment on stderr: its verdict, the
    scenario's deciding limit, ``stability.limit.deciding_limit``, and why)
    if any segment is not ``converged``."""
    bad = [(i, s) for i, s in enumerate(segs, 1) if s.verdict != "converged"]
    if not bad:
        return 0
    for i, s in bad:                # a limit crossed: the joint, not the stiffness, is the news
        if s.verdict == "over_limit":
            print(f"over_limit: segment {i} ({s.start:g}-{s.end:g} s): {s.reason}", file=sys.stderr)
    bad = [(i, s) for i, s in bad if s.verdict != "over_limit"]
    if not bad:
        return 1
    from .fmt import num
    from .stability.analysis import deciding_limit
    from .stability.continuous import AnalysisError
    from .stability.limit import NoContact
    from .stability.onedim import unstable_free_axis

    free = unstable_free_axis(sc)          # said in each reason; the whole loop's search would only agree
    try:
        lim = None if free is not None else deciding_limit(sc, memo=memo)
    except NoContact as exc:               # not a failure: there is no limit (its message says so)
        lim = str(exc).splitlines()[0]
    except AnalysisError as exc:
        lim = f"the loop's limit could not be computed ({str(exc).splitlines()[0]})"
    else:
        lim = ("limit 0 N/m (an axis without contact is unstable; see the reason)" if free is not None else
               lim.describe() if lim is not None and lim.limit > 0 else
               "the loop is unstable at the scenario's smallest stiffness (tmtcontrol analyze --scenario)"
               if lim is not None else "no linear prediction (a law without a linear verdict)")
    for i, s in bad:
        print(f"{s.verdict}: segment {i} ({s.start:g}-{s.end:g} s), k_e = {num(s.stiffness, 4)} N/m, {lim}; {s.reason}",
              file=sys.stderr)
    return 1


def _analyze(args) -> int:
    import json

    from .files import OutputFolder, jsonable
    from .stability import analyze, analyze_scenario, format_analysis

    flags = ("m", "b", "k", "fd", "ke", "ke_min", "ke_max", "ts", "mp", "delay", "x_e_error")
    sc = _load_named(args)
    if sc is not None:
        for flag in flags:
            if getattr(args, flag) is not None:
                raise UsageError(f"--{flag.replace('_', '-')}: not allowed with --scenario (set it in the scenario, "
                                 "or with --set)")
        run = lambda: analyze_scenario(sc, limits=True)
    else:
        for flag in ("m", "b", "k"):
            if getattr(args, flag) is None:
                raise UsageError(f"--{flag}: required (or use --scenario)")
        if args.ke is not None and (args.ke_min is not None or args.ke_max is not None):
            raise UsageError("--ke: give either --ke or --ke-min/--ke-max, not both")
        if args.ke is None and (args.ke_min is None or args.ke_max is None):
            raise UsageError("--ke: required (or both --ke-min and --ke-max)")
        for flag in ("mp", "delay"):
            if getattr(args, flag) is not None and args.ts is None:
                raise UsageError(f"--{flag}: only used by the sampled-data analysis; give --ts too")
        _check_numbers(args)
        kw = dict(m=args.m, b=args.b, k=args.k, f_d=10.0 if args.fd is None else args.fd,
                  Ts=args.ts, m_p=args.mp, delay=args.delay or 0,
                  x_e_error=0.0 if args.x_e_error is None else args.x_e_error)
        kw.update(dict(k_e=args.ke) if args.ke is not None else dict(k_e_min=args.ke_min, k_e_max=args.ke_max))
        run = lambda: _flags_named(analyze, **kw)
    out = OutputFolder(args.plot, "--plot") if args.plot is not None else None
    with out if out is not None else contextlib.nullcontext():
        _print_notes()
        result = run()
        if out is not None:
            from .stability.figures import save_analysis_figures

            save_analysis_figures(result, out.path)
            out.commit()
    result.pop("systems")
    print(json.dumps(jsonable(result), indent=2) if args.json else format_analysis(result))
    stable = (result["bibo_stable"] and result.get("stable_for_all", True) and result.get("sampled_stable", True)
              and result.get("law_stable", True))      # the law's own loop (review 22: UNSTABLE printed, exit 0)
    if result.get("in_contact") is False:               # review 34: no contact (it exited 0)
        print("no contact: the tool stays off the surface; see the contact line above", file=sys.stderr)
        return 1
    if not stable:
        print("unstable: see the verdicts above", file=sys.stderr)
    return 0 if stable else 1


def _check_numbers(args) -> None:
    """Every given number the scenario schema bounds, with the schema's range and message."""
    from .simulation.scenario import check_filter_cutoff, check_period, check_setting

    for flag, key in (("m", "impedance.m"), ("b", "impedance.b"), ("k", "impedance.k"), ("fd", "controller.f_d"),
                      ("ke", "environment.stiffness.values"), ("ke_min", "environment.stiffness.values"),
                      ("ke_max", "environment.stiffness.values"), ("delay", "controller.delay_samples"),
                      ("x_e_error", "controller.x_e_error")):
        if getattr(args, flag, None) is not None:
            check_setting(f"--{flag.replace('_', '-')}", key, getattr(args, flag))
    mp = getattr(args, "mp", None)
    if mp is not None and not 1e-3 <= mp <= 1e4:     # the impedance mass's range (review 13: 1e-100 overflowed)
        raise UsageError(f"--mp: must be >= 0.001 and <= 10000 (the effective normal mass, kg), got {mp:g}")
    if getattr(args, "ts", None) is not None:
        check_period("--ts", args.ts)
        if getattr(args, "filter_hz", None) is not None:
            check_filter_cutoff("--filter-hz", args.filter_hz, args.ts)


_FLAGS = {"m": "--m", "b": "--b", "k": "--k", "f_d": "--fd", "k_e": "--ke", "k_e_min": "--ke-min",
          "k_e_max": "--ke-max", "Ts": "--ts", "m_p": "--mp", "delay": "--delay", "x_e_error": "--x-e-error",
          "max_overshoot": "--max-overshoot", "stiffness_margin": "--margin"}


def _flags_named(fn, **kw):
    """``fn(**kw)``; a bad-input error (``ValueError``) whose message starts with
    one of its argument names (``m_p: must be > 0``) names the flag instead."""
    try:
        return fn(**kw)
    except ValueError as exc:
        name, sep, rest = str(exc).partition(": ")
        if sep and name in kw and name in _FLAGS:
            raise UsageError(f"{_FLAGS[name]}: {rest}") from None
        raise


def _filter_pole(cutoff: float, Ts: float) -> float:
    from .simulation.scenario import filter_pole

    return filter_pole(cutoff, Ts)


def _design(args) -> int:
    import json

    from .files import OutputFolder, jsonable
    from .stability import paper_effective_mass
    from .stability.design import DesignSpec, design_impedance, format_design

    _check_numbers(args)
    sc = _load_named(args)
    if sc is not None:
        from .stability.design import scenario_design_spec

        Ts = args.ts if args.ts is not None else sc.controller.Ts
        if args.filter_hz is not None:
            _check_numbers(argparse.Namespace(ts=Ts, filter_hz=args.filter_hz))
        spec = _flags_named(scenario_design_spec, scenario=sc, m=args.m, k=args.k, k_e_min=args.ke_min,
                            k_e_max=args.ke_max, Ts=args.ts, max_overshoot=args.max_overshoot, f_d=args.fd,
                            optimize_k=args.optimize_k, m_p=args.mp, stiffness_margin=args.margin, delay=args.delay,
                            alpha=None if args.filter_hz is None else _filter_pole(args.filter_hz, Ts))
    else:
        for flag in ("m", "k", "ke_min", "ke_max", "ts", "max_overshoot"):
            if getattr(args, flag) is None:
                raise UsageError(f"--{flag.replace('_', '-')}: required (or use --scenario)")
        spec = _flags_named(DesignSpec, m=args.m, k=args.k, k_e_min=args.ke_min, k_e_max=args.ke_max, Ts=args.ts,
                            max_overshoot=args.max_overshoot, f_d=10.0 if args.fd is None else args.fd,
                            optimize_k=args.optimize_k,
                            m_p=args.mp if args.mp is not None else paper_effective_mass(worst=True),
                            stiffness_margin=args.margin, delay=args.delay or 0,
                            alpha=_filter_pole(args.filter_hz or 0.0, args.ts))
    out = OutputFolder(args.plot, "--plot") if args.plot is not None else None
    from .files import check_interrupt

    with out if out is not None else contextlib.nullcontext():
        _print_notes()
        result = design_impedance(spec)
        if sc is not None:
            from .stability.design import with_scenario_loop

            result = with_scenario_loop(sc, result)
        text = json.dumps(jsonable(result.as_dict()), indent=2) if args.json else format_design(result)
        violations = result.violations
        # a Ctrl-C that CasADi turned into a failed evaluation (the verification's sampled loops) is an
        # interruption, not a design that failed its check
        check_interrupt()
        if out is not None:
            from .stability.figures import save_design_figures

            save_design_figures(result, out.path)
            out.commit()
    print(text)
    if violations:
        print(f"design failed its verification: {'; '.join(violations)}", file=sys.stderr)
        return 1
    return 0


def _check(args) -> int:
    import json

    from .checks import all_checks
    from .checks.derivations import format_checks
    from .files import jsonable

    sc = _load_named(args)
    if sc is not None:
        from .simulation.simulator import robot_of

        robot_of(sc)                        # an arm that cannot be loaded: one line, exit 2, before any check
        _print_notes()
    results = all_checks(scenario=sc)
    if args.json:
        print(json.dumps(jsonable([r.as_dict() for r in results]), indent=2))
    else:
        print(format_checks(results))
    return 0 if all(r.passed for r in results) else 1


def _sweep(args) -> int:
    if args.example:
        from .sweep.spec import EXAMPLE

        print(EXAMPLE, end="")
        return 0
    if args.sweep is None:
        raise UsageError("SWEEP: a sweep file is required (tmtcontrol sweep --example prints one)")
    if args.workers < 1:
        raise UsageError(f"--workers: must be >= 1, got {args.workers}")
    import os

    cpus = os.cpu_count() or 1
    if args.workers > 4 * cpus:          # each worker is a process of ~150 MB: a huge count is a fork bomb
        raise UsageError(f"--workers: at most {4 * cpus} (4 per CPU, {cpus} CPUs here), got {args.workers}")
    if args.dask is not None and not (args.dask == "local" or "://" in args.dask):
        raise UsageError(f"--dask: expected 'local' or a scheduler address like tcp://host:8786, got {args.dask!r}")
    from .sweep import load_sweep, save_sweep
    from .sweep.spec import check_sweep_size

    sweep = load_sweep(args.sweep, max_cases=args.max_cases)
    _hold_notes(sweep.unit_notes())
    check_sweep_size(sweep, args.max_steps)
    try:
        summary = save_sweep(sweep, args.out, workers=args.workers, dask=args.dask, resume=args.resume,
                             plots=not args.no_plots, max_steps=args.max_steps,
                             limits={"auto": None, "on": True, "off": False}[args.limits],
                             command_line=shlex.join(["tmtcontrol", *sys.argv[1:]]), checked=_print_notes)
    except KeyboardInterrupt as exc:      # finished cases stay in OUT.partial/: say so, and how to go on
        from .sweep.run import kept_note

        exc.kept = kept_note(args.out)
        raise
    counts = summary["verdicts"]
    print(f"{summary['cases']} cases over {', '.join(summary['axes'])}: "
          + ", ".join(f"{n} {v}" for v, n in counts.items()) + f" ({summary['run']['seconds']:.1f} s)")
    from .sweep import boundary_lines

    for line in boundary_lines(sweep, summary):
        print(line)
    print(f"wrote {args.out}/")
    bad = summary["cases"] - counts["converged"]
    if bad:
        print(f"not converged: {bad} of {summary['cases']} cases (see summary.json 'worst')", file=sys.stderr)
    return 1 if bad else 0


def _report(args) -> int:
    import time

    from .simulation.mujoco_render import prefer_headless_gl

    prefer_headless_gl()            # the simulation section's still of the arm, by MuJoCo where it can render

    from .files import OutputFolder
    from .report import STAGES, RendererUnavailable, build_report, prepare_writing, write_report, writing_stages
    from .simulation.simulator import check_run_size

    formats = _formats(args.format)
    sc = _load(args)
    check_run_size(sc, args.max_steps)
    if args.plant == "mujoco":
        _mujoco_ready(sc, "--plant mujoco")
    no_pdf = None
    if "pdf" in formats:            # the PDF engine is loaded first: its absence is known before anything is computed
        try:
            prepare_writing(("pdf",))
        except RendererUnavailable as exc:
            if formats == ("pdf",):
                raise                                        # nothing else was asked for: bad input, exit 2
            no_pdf = str(exc)
            formats = tuple(f for f in formats if f != "pdf")
            # the warning is printed once --out is accepted (a refused --out is its one line)
    t0 = time.perf_counter()
    computing = len(STAGES) + (args.plant == "mujoco")
    n = computing + writing_stages(formats)

    def stage(i, name, seconds):
        print(f"[{i}/{n}] {name}: {seconds:.1f} s", file=sys.stderr, flush=True)

    with OutputFolder(args.out, "--out") as out:    # checked before anything is computed
        _print_notes()
        if no_pdf is not None:
            print(f"warning: {no_pdf}; writing report.html only", file=sys.stderr, flush=True)
        rep = build_report(sc, command_line=shlex.join(["tmtcontrol", *sys.argv[1:]]),
                           progress=lambda i, _n, name, s: stage(i, name, s),
                           prepare=lambda: prepare_writing(formats), plant=args.plant)
        done = iter(range(computing + 1, n + 1))
        files = write_report(rep, out.path, formats, progress=lambda name, s: stage(next(done), name, s))
        out.commit()
    for v in rep.verdicts:
        print(f"{'PASS' if v.passed else 'FAIL'}  {v.name}: {v.evidence}")
    print(f"wrote {' and '.join(str(out.out / f.name) for f in files)} ({time.perf_counter() - t0:.1f} s)")
    if no_pdf is not None:
        print("error: report.pdf was not written (WeasyPrint did not load; see the warning above)", file=sys.stderr)
    return 0 if rep.passed and no_pdf is None else 1


def _formats(text: str) -> tuple[str, ...]:
    from .report import FORMATS

    names = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in names if f not in FORMATS]
    if bad or not names:
        raise UsageError(f"--format: expected a comma-separated list of {', '.join(FORMATS)}, got {text!r}")
    return tuple(f for f in FORMATS if f in names)


def _robot(args) -> int:
    from .model.robot import load_robot
    from .model.urdf import ChainError
    from .model.verify import check_robot, describe

    if args.seed < 0:
        raise UsageError(f"--seed: must be >= 0, got {args.seed}")
    if not 1 <= args.samples <= 100_000:
        raise UsageError(f"--samples: must be between 1 and 100,000, got {args.samples}")
    for flag, value in (("--tip", args.tip), ("--base", args.base)):
        if value is not None and not value.strip():
            raise UsageError(f"{flag}: expected a link name, got {value!r}")
    joints = None
    if args.joints is not None:
        joints = [j.strip() for j in args.joints.split(",")]
        if not all(joints):
            raise UsageError(f"--joints: expected joint names separated by commas, got {args.joints!r}")
    try:
        robot = load_robot(args.source, tip=args.tip, base=args.base, joints=joints)
    except ChainError as exc:      # the file is fine; the flag is at fault
        raise UsageError(f"--{exc.key}: {exc}") from None
    _hold_notes(robot.unit_notes())        # before the checks that a unit mistake would fail (review 69)
    _print_notes()
    check = check_robot(robot, samples=args.samples, seed=args.seed)
    if "mujoco" in args.against:
        import dataclasses

        from .model.against_mujoco import MujocoMissing, check_against_mujoco

        try:
            mj = check_against_mujoco(robot, samples=args.samples, seed=args.seed)
        except (MujocoMissing, NotImplementedError) as exc:
            raise UsageError(f"--against mujoco: {exc}") from None
        check = dataclasses.replace(check, identities=check.identities + mj.identities,
                                    reference=f"{check.reference}; {mj.reference}")
    print(describe(robot, check))
    return 0 if check.ok else 1


def _cache(args) -> int:
    from .cache import cache_info, clear_cache, format_cache_info

    if args.clear:
        done = clear_cache()
        print(f"removed {done['libraries']} compiled librar{'y' if done['libraries'] == 1 else 'ies'} and "
              f"{done['results']} analysis result{'' if done['results'] == 1 else 's'} "
              f"({done['bytes'] / 2**20:,.1f} MiB)")
    else:
        print(format_cache_info(cache_info()))
    return 0


def _scenario(args) -> int:
    import json

    from .simulation.scenario import dump_scenario, load_scenario, scenario_json_schema

    if args.schema:
        print(json.dumps(scenario_json_schema(), indent=2))
    else:
        sys.stdout.write(dump_scenario(load_scenario(args.name)))
    return 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` for the command line: ``warning: MESSAGE`` on one
    line (Python's default adds the file, line and source line of the caller)."""
    text = " ".join(str(message).split()).removeprefix("tmtcontrol: ")
    print(f"warning: {text}", file=sys.stderr if file is None else file)


def _interrupted_by(exc: BaseException) -> int | None:
    """The exit code of the signal behind ``exc`` (an :class:`Interrupted` or
    KeyboardInterrupt in its cause or context chain, or a signal the
    handlers recorded), else None."""
    from .files import Interrupted, check_interrupt

    seen, e = set(), exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, Interrupted):
            return e.exit_code
        if isinstance(e, KeyboardInterrupt):
            return 130
        e = e.__cause__ or e.__context__
    try:
        check_interrupt()
    except Interrupted as pending:
        return pending.exit_code
    return None


_STREAM_ERRORS = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC), errno.EIO, errno.EFBIG, errno.EPIPE)
"""Errors of a write to the standard output or error (a full disk behind
``> file``, ``/dev/full``; a pipe whose reader has gone, ``| head -1``,
review 51: a traceback and exit 1): every file tmtcontrol writes itself is
staged and reports its own (:class:`.files.OutputNotSaved`)."""


def _stream_failed(exc: OSError) -> int:
    """One line for a failed write to the standard output (review 13: ``scenario paper > file`` on a full
    disk ended in a traceback), the folders committed before it named; exit 3, as for a file not saved."""
    from .files import NOT_SAVED_EXIT, committed_outputs

    done = committed_outputs()
    try:
        print(f"error: writing the standard output: {exc.strerror}; what it shows is incomplete"
              + (f" ({' and '.join(done)} was written in full)" if done else ""), file=sys.stderr)
    except OSError:
        pass                                           # the standard error fails too: the exit code says it
    return NOT_SAVED_EXIT


def _kept(exc: BaseException) -> str:
    """What an interrupted command leaves: the exception's own account
    (``kept``: a sweep's finished cases), else the output folders it had
    committed before the signal came (complete: a commit is atomic; review
    13: a Ctrl-C while simulate printed its results said "nothing was
    written" of the folder it had just replaced), else nothing."""
    files = sys.modules.get(f"{__package__}.files")      # not imported yet: a Ctrl-C during the first imports
    done = files.committed_outputs() if files is not None else []
    return getattr(exc, "kept", None) or (f"{' and '.join(done)} had been written in full before it" if done
                                          else "nothing was written")


def main(argv: list[str] | None = None) -> int:
    import threading

    from .files import (NOT_SAVED_EXIT, Interrupted, OutputNotSaved, VerdictFailed, committed_outputs,
                        install_signal_handlers, restore_signal_handlers, staging_removed_on_exit)
    from .processes import defer_in_finalizers

    import warnings

    shown = warnings.showwarning
    warnings.showwarning = _one_line_warning          # a warning is one line on stderr, like an error
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = install_signal_handlers()
        defer_in_finalizers()          # never raised inside a weakref callback or __del__
    parser = build_parser()
    committed_outputs(reset=True)
    _NOTES.clear()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        with staging_removed_on_exit():
            code = args.func(args)
        _print_notes()
        return code
    except ValueError as exc:   # UsageError, ScenarioError, AnalysisError, DesignError, OutputError
        _NOTES.clear()          # a refusal is its one line (a note printed before its checks passed stays)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except Interrupted as exc:
        print(f"interrupted ({'SIGTERM' if exc.exit_code == 143 else 'Ctrl-C'}): {_kept(exc)}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt as exc:
        print(f"interrupted (Ctrl-C): {_kept(exc)}", file=sys.stderr)
        return 130
    except SystemError as exc:
        # a signal's exception raised inside a C extension's call (CasADi checks for Ctrl-C while it
        # evaluates): Python reports "returned a result with an exception set", the signal's as its cause
        code = _interrupted_by(exc)
        if code is None:
            raise
        print(f"interrupted ({'SIGTERM' if code == 143 else 'Ctrl-C'}): {_kept(exc)}", file=sys.stderr)
        return code
    except VerdictFailed as exc:   # computed verdicts (diverged simulation, infeasible design): exit 1
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except OutputNotSaved as exc:  # a full disk, or the target changed during the run: exit 3
        print(f"error: {exc}", file=sys.stderr)
        return NOT_SAVED_EXIT
    except OSError as exc:
        if exc.filename is not None or exc.errno not in _STREAM_ERRORS:
            raise
        return _stream_failed(exc)
    finally:
        warnings.showwarning = shown
        if previous is not None:
            restore_signal_handlers(previous)


def run() -> None:
    """The console script: :func:`main`, then exit with its code. Before the
    interpreter's teardown every live object is moved out of the garbage
    collector's reach (``gc.freeze``): its final collection would walk them
    all, 0.2-0.6 s after python-control, matplotlib and WeasyPrint are
    loaded, to free memory the process is about to return anyway. Every file
    is closed by then and atexit handlers still run. Ctrl-C before
    :func:`main` has installed its handlers (during the first imports) is
    one line and exit code 130 too. BLAS and OpenMP libraries start with
    one thread (tmtcontrol's matrices are small; a user's
    ``OPENBLAS_NUM_THREADS`` etc. wins)."""
    import gc

    try:
        from .processes import blas_env_defaults

        blas_env_defaults()
        code = main()
    except KeyboardInterrupt:
        print(f"interrupted (Ctrl-C): {_kept(KeyboardInterrupt())}", file=sys.stderr)
        code = 130
    try:
        sys.stdout.flush()
    except OSError as exc:                         # what the command printed did not all reach a full disk
        code = _stream_failed(exc) if code == 0 else code
        sys.stdout = open(os.devnull, "w")         # the interpreter's own final flush would fail again
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    run()
