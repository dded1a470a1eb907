"""Regenerate the paper's Figs. 3-5 (and a 3-D view of the path) from the package.

Usage: python analysis/paper_figures.py [--out DIR] [--cycles N]

Simulates the built-in paper scenario (section V: 3-link PUMA 560, circle on
a 45 deg plane, f_d = 10 N, stiffness stepping every 4 s cycle) and writes
fig3_stiffness.png, fig4_force.png, fig5_position.png and path3d.png plus the
per-segment table (segments.txt).
"""
from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.simulation.metrics import format_table
from tmtcontrol.files import OutputFolder
from tmtcontrol.simulation.figures import save_simulation_figures
from tmtcontrol.studies import Parser, positive, run


def main(argv=None):
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="analysis-output/paper-figures",
                    help="output folder (default analysis-output/paper-figures, ignored by git)")
    ap.add_argument("--cycles", type=positive(), default=4.0, help="cycles of 4 s (default 4)")
    args = ap.parse_args(argv)
    sc = apply_overrides(paper_scenario(), [f"trajectory.cycles={args.cycles}"])
    with OutputFolder(args.out, "--out") as out:          # checked before the run
        res = Simulator(sc).run()
        table = format_table(segment_metrics(res))
        save_simulation_figures(res, out.path)
        (out.path / "segments.txt").write_text(table + "\n")
        out.commit()
    print(table)
    print(f"wrote {args.out}/")


if __name__ == "__main__":
    raise SystemExit(run(main))
