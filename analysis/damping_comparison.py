"""Compare normal-axis damping strategies on the paper's stiffness profile.

Usage: python analysis/damping_comparison.py [--out DIR] [--cycles N] [--write-docs]

Four controllers, all with TMT, M = 1, K = 100 on the paper scenario
(stiffness 5e3 -> 2e4 -> 2e3 -> 1e4 N/m, one value per 4 s cycle):

* ``scenario b = 60``: the paper's fixed B = 60 N s/m;
* ``eq. (25) worst case b = ...``: eq. (25) for the worst case, b = 2 sqrt(m (k + k_e_max));
* ``optimal b = ...``: the robust design of tmtcontrol.stability.design (5 % overshoot bound, Ts = 1 ms);
* ``scheduled (zeta = 1)``: b follows eq. (25) online from the TMT estimate.

Writes comparison.csv / comparison.md (overshoot and 2 % settling time per
segment) and a force plot, and prints the table. ``--write-docs`` also
rewrites the table in docs/design.md between ``<!-- damping_comparison -->``
and ``<!-- end damping_comparison -->`` (tests/test_design.py checks that the
page holds what this script prints).
"""
import csv
import pathlib
import re

import numpy as np
from matplotlib.figure import Figure

from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
from tmtcontrol.stability.design import DesignSpec, damping_alternatives, design_impedance
from tmtcontrol.files import OutputFolder
from tmtcontrol.plotstyle import styled
from tmtcontrol.stability import scenario_parameters
from tmtcontrol.studies import Parser, positive, run

ROOT = pathlib.Path(__file__).resolve().parents[1]


def strategies(cycles):
    base = apply_overrides(paper_scenario(), [f"trajectory.cycles={cycles}"])
    p = scenario_parameters(paper_scenario())
    opt = design_impedance(DesignSpec(m=1.0, k=100.0, k_e_min=p["k_e_min"], k_e_max=p["k_e_max"], Ts=1e-3,
                                      max_overshoot=5.0, m_p=p["m_p_min"]))
    return damping_alternatives(base, opt)      # the paper's B = 60 is the scenario's own b


def runs_for(cycles) -> dict:
    """``{controller: (SimulationResult, segment metrics)}`` of :func:`strategies`."""
    runs = {}
    sim = None
    for name, sc in strategies(cycles).items():
        sim = sim or Simulator(sc)          # one compiled loop: b and the schedule are inputs
        res = sim.run(sc)
        runs[name] = (res, segment_metrics(res))
    return runs


def docs_table(runs) -> str:
    """docs/design.md's table: per controller (its normal-axis b where fixed) and segment, the overshoot
    (segment_metrics' overshoot_pct: the peak after the switch's own jump, docs/simulation.md), the 2 %
    settling time and the smallest force (contact lost at 0)."""
    md = ["| controller | segment (k_e, N/m) | overshoot % | 2 % settling (s) | min force (N) |",
          "|---|---|---|---|---|"]
    for name, (_, segs) in runs.items():
        for i, s in enumerate(segs, 1):
            label = name if i == 1 else ""
            where = f"{i} ({s.stiffness:.0e}".replace("e+0", "e") + (", first contact)" if i == 1 else ")")
            settle = f"{s.settling_time:.3f}" if np.isfinite(s.settling_time) else "never"
            low = f"{s.min_force:.3g}" + (" (contact lost)" if s.min_force <= 0 and i > 1 else "")
            md.append(f"| {label} | {where} | {s.overshoot_pct:.3g} | {settle} | {low} |")
    return "\n".join(md)


def write_docs(text: str) -> None:
    page = ROOT / "docs" / "design.md"
    new, n = re.subn(r"(<!-- damping_comparison -->\n)(?:.*?\n)?(<!-- end damping_comparison -->)",
                     lambda m: m.group(1) + text + "\n" + m.group(2), page.read_text(), flags=re.S)
    if n != 1:
        raise SystemExit("docs/design.md: no <!-- damping_comparison --> block")
    page.write_text(new)


def main(argv=None):
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="analysis-output/damping-comparison",
                    help="output folder (default analysis-output/damping-comparison, ignored by git)")
    ap.add_argument("--cycles", type=positive(), default=4.0, help="path cycles of 4 s (default 4)")
    ap.add_argument("--write-docs", action="store_true", help="also rewrite the table in docs/design.md")
    args = ap.parse_args(argv)
    out = OutputFolder(args.out, "--out")     # checked before the runs
    runs = runs_for(args.cycles)
    rows = []
    for name, (_, segs) in runs.items():
        for i, s in enumerate(segs, 1):
            rows.append({"controller": name, "segment": i, "k_e": s.stiffness,
                         "overshoot_pct": round(s.overshoot_pct, 2),
                         "settling_time_s": round(s.settling_time, 4) if np.isfinite(s.settling_time) else None,
                         "min_force_N": round(s.min_force, 3), "steady_error_N": s.steady_state_error})
    md = ["| controller | segment | k_e (N/m) | overshoot % | settling 2 % (s) | min force (N) |",
          "|---|---|---|---|---|---|"]
    md += [f"| {r['controller']} | {r['segment']} | {r['k_e']:.4g} | {r['overshoot_pct']} | "
           f"{r['settling_time_s']} | {r['min_force_N']} |" for r in rows]
    if args.write_docs:
        write_docs(docs_table(runs))
    with styled():                                      # the package's one figure style
        fig = Figure(figsize=(8, 4.5), layout="constrained")
        ax = fig.add_subplot()
        for name, (res, _) in runs.items():
            ax.plot(res.time, res.contact_force, lw=1, label=name)
        ax.axhline(10.0, color="k", ls="--", lw=0.8)
        ax.set(xlabel="time (s)", ylabel="f_e (N)", ylim=(-1, 25), title="Damping strategies on the paper profile")
        ax.legend(fontsize=8)
    with out:
        tmp = out.path
        with (tmp / "comparison.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        (tmp / "comparison.md").write_text("\n".join(md) + "\n")
        with styled():
            fig.savefig(tmp / "force_comparison.png", dpi=110)
        out.commit()
    print("\n".join(md))
    print(f"wrote {args.out}/")


if __name__ == "__main__":
    raise SystemExit(run(main))
