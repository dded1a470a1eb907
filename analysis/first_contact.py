"""First contact from a gap: the impact peak with and without the guarded approach
(the figure and table of docs/theory.md, "First contact").

Usage: python analysis/first_contact.py [--out DIR] [--gap D] [--points N]

For N surface stiffnesses from 2e3 to 1e5 N/m, the paper's TMT loop starts D
metres (default 0.005) above the surface and runs 2 s: once with the law from
the start (controller.approach_speed = 0: eq. 18's f_e = 0 branch drives the
reference f_d/k = 0.1 m beyond the surface) and once with the guarded
approach (10 mm/s until 1 N is measured, then f_d ramped over 0.25 s).
Writes ``first_contact.png`` (peak force / f_d against k_e), ``table.md``
and ``summary.json``, and prints the table. Exit 1 if a guarded run peaks
above 1.5 f_d or does not converge.
"""
import json

import numpy as np
from matplotlib.figure import Figure

from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.files import OutputFolder
from tmtcontrol.plotstyle import plain_log_labels, styled
from tmtcontrol.simulation.metrics import first_contact
from tmtcontrol.studies import Parser, positive, run


def _stiffness(k_e: float) -> str:
    """``k_e`` (N/m) to 3 significant digits as the page writes it: 2e3, 1.41e4."""
    return f"{k_e:.3g}".replace("e+0", "e").replace("e+", "e")


def main(argv=None):
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="analysis-output/first-contact",
                    help="output folder (default analysis-output/first-contact, ignored by git)")
    ap.add_argument("--gap", type=positive(), default=0.005, help="start this far above the surface, m")
    ap.add_argument("--points", type=positive(int), default=7, help="stiffnesses from 2e3 to 1e5 N/m (default 7)")
    args = ap.parse_args(argv)
    out = OutputFolder(args.out, "--out")
    base = apply_overrides(paper_scenario(), ["trajectory.cycles=0.5", f"trajectory.approach_gap={args.gap}"])
    sim = Simulator(base)
    rows, bad = [], False
    for k_e in np.geomspace(2e3, 1e5, args.points):
        row = {"k_e": float(k_e)}
        for label, speed in (("law", 0.0), ("guarded", base.controller.approach_speed)):
            sc = apply_overrides(base, [f"environment.stiffness.values=[{k_e}]",
                                        f"controller.approach_speed={speed}"])
            res = sim.run(sc)
            fc, seg = first_contact(res), segment_metrics(res)[0]
            row[label] = {**fc.as_dict(), "verdict": seg.verdict}
        bad |= row["guarded"]["peak_ratio"] > 1.5 or row["guarded"]["verdict"] != "converged"
        rows.append(row)
    md = ["| k_e (N/m) | law alone: peak/f_d | bounces | guarded: peak/f_d | bounces | contact at (s) |",
          "|---|---|---|---|---|---|"]
    md += [f"| {_stiffness(r['k_e'])} | {r['law']['peak_ratio']:.2f} | {r['law']['bounces']} | "
           f"{r['guarded']['peak_ratio']:.2f} | {r['guarded']['bounces']} | {r['guarded']['time']:.3f} |"
           for r in rows]
    with styled():                                      # the package's one figure style
        fig = Figure(figsize=(6, 3.4), layout="constrained")
        ax = fig.add_subplot()
        ks = [r["k_e"] for r in rows]
        ax.semilogx(ks, [r["law"]["peak_ratio"] for r in rows], "o-", label="law from the start (eq. 18)")
        ax.semilogx(ks, [r["guarded"]["peak_ratio"] for r in rows], "s-", label="guarded approach")
        ax.axhline(1.5, color="k", ls=":", lw=0.8, label="1.5 f_d")
        ax.set(xlabel="surface stiffness k_e (N/m)", ylabel="first-contact peak / f_d",
               title=f"First contact from a {args.gap * 1e3:g} mm gap")
        ax.legend(fontsize="small")
        ax.grid(True, which="both", alpha=0.3)
    with out, styled():
        plain_log_labels(fig).savefig(out.path / "first_contact.png", dpi=110)
        (out.path / "table.md").write_text("\n".join(md) + "\n")
        (out.path / "summary.json").write_text(json.dumps({"gap_m": args.gap, "runs": rows}, indent=1) + "\n")
        out.commit()
    print("\n".join(md))
    print(f"wrote {out.out}/")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(run(main))
