"""Regenerate the paper's Figs. 3-5 (and a 3-D view of the path) from the package.

Usage: python analysis/paper_figures.py [--out DIR] [--cycles N]

Simulates the built-in paper scenario (section V: 3-link PUMA 560, circle on
a 45 deg plane, f_d = 10 N, stiffness stepping every 4 s cycle) and writes
fig3_stiffness.png, fig4_force.png, fig5_position.png and path3d.png plus the
per-segment table (segments.txt).
"""
import argparse
import pathlib

from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.simulation.metrics import format_table
from tmtcontrol.files import atomic_folder
from tmtcontrol.simulation.figures import save_simulation_figures


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="paper-figures")
    ap.add_argument("--cycles", type=float, default=4.0, help="cycles of 4 s (default 4)")
    args = ap.parse_args(argv)
    sc = apply_overrides(paper_scenario(), [f"trajectory.cycles={args.cycles}"])
    res = Simulator(sc).run()
    table = format_table(segment_metrics(res))
    with atomic_folder(args.out) as tmp:
        save_simulation_figures(res, tmp)
        (pathlib.Path(tmp) / "segments.txt").write_text(table + "\n")
    print(table)
    print(f"wrote {args.out}/")


if __name__ == "__main__":
    main()
