"""Compare every force-tracking law on the paper scenario, exactly and with a
surface-location error (the figures and table of docs/choosing-a-law.md).

Usage: python analysis/law_comparison.py [--out DIR] [--cycles N] [--x-e-error D]

Runs ``tmtcontrol.compare_laws`` on the paper scenario (stiffness 5e3 ->
2e4 -> 2e3 -> 1e4 N/m, 4 s each, 1 kHz) and on the same scenario with the
controller's surface estimate off by D (m, default 0.005: believed 5 mm
deeper than it is), each law with its documented default parameters. Writes
per case ``CASE_force.png`` and ``CASE_error.png`` (force of all laws; |f_e -
f_d| on a log axis), ``table.md`` (steady-state error = max |f_e - f_d| over
each segment's last quarter, and verdict, law x segment) and ``summary.json``,
and prints the table. Exit 1 if a law's run diverged.
"""
import json


from tmtcontrol import apply_overrides, compare_laws, paper_scenario
from tmtcontrol.drawing import save_figures
from tmtcontrol.files import OutputFolder
from tmtcontrol.simulation.figures import comparison_error_figure, comparison_force_figure
from tmtcontrol.studies import Parser, finite, positive, run


def main(argv=None):
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="analysis-output/law-comparison",
                    help="output folder (default analysis-output/law-comparison, ignored by git)")
    ap.add_argument("--cycles", type=positive(), default=4.0, help="path cycles of 4 s (default 4, the paper's)")
    ap.add_argument("--x-e-error", type=finite, default=0.005, help="surface-location error of the second case, m")
    args = ap.parse_args(argv)
    out = OutputFolder(args.out, "--out")          # checked before the runs
    base = apply_overrides(paper_scenario(), [f"trajectory.cycles={args.cycles}"])
    cases = {"paper": base,
             "x_e_error": apply_overrides(base, [f"controller.x_e_error={args.x_e_error}"])}
    with out:
        md, summary, diverged = [], {}, False
        for case, sc in cases.items():
            cmp = compare_laws(sc)
            save_figures(((f"{case}_force", comparison_force_figure), (f"{case}_error", comparison_error_figure)),
                         cmp, out.path, dpi=110)
            summary[case] = {"x_e_error_m": sc.controller.x_e_error, **cmp.summary()}
            nseg = max(len(r.segments) for r in cmp.runs.values())
            md.append(f"\n### {case} (x_e error {sc.controller.x_e_error * 1e3:g} mm)\n")
            md.append("| law | " + " | ".join(f"segment {i + 1}" for i in range(nseg)) + " | verdict |")
            md.append("|---" * (nseg + 2) + "|")
            for name, run in cmp.runs.items():
                diverged |= run.result is None
                cells = [f"{s.steady_state_error:.2g} N" for s in run.segments] or ["diverged"] * nseg
                md.append(f"| `{name}` | " + " | ".join(cells) + f" | {run.verdict} |")
        (out.path / "table.md").write_text("\n".join(md).lstrip() + "\n")
        (out.path / "summary.json").write_text(json.dumps(summary, indent=1, default=float,
                                                          allow_nan=False) + "\n")
        out.commit()
    print("\n".join(md))
    print(f"wrote {out.out}/")
    return 1 if diverged else 0


if __name__ == "__main__":
    raise SystemExit(run(main))
