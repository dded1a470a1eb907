"""Accuracy and speed of the stiffness limits (issue 28): along the moving path
(``stability.periodic``, the monodromy) and from first contact
(``stability.first_contact``), each beside the limit found by bisection in the
simulator, with its error and the time each analysis takes.

Run:  python benchmarks/bench_limits.py                 # print the tables and times
      python benchmarks/bench_limits.py --write-docs    # also rewrite the generated tables in docs/

The tables in docs/theory.md, docs/laws.md and docs/choosing-a-law.md between
``<!-- bench_limits: NAME -->`` and ``<!-- end bench_limits -->`` are this
script's output (times excluded: they depend on the machine);
tests/test_limits.py (heavy) regenerates them and fails when they drift.

Simulated references (stability.first_contact):
* small signal: the largest constant k_e at which the compiled loop, started
  near its periodic orbit (one period at 0.95 k_e, then k_e with a kick),
  converges, judged by the decay of the difference between path periods;
  bisection to 0.1 %;
* first contact: the largest constant k_e from which the scenario's own
  16 s run ends settled rather than in a limit cycle (last second against
  the one before); bisection to 0.1 %.
The first run of each structure compiles the monodromy step (~15 s) and the
simulated step (~3 s); times below are for warm caches (each analysis run
twice, the second timed).
"""
from __future__ import annotations

import argparse
import math
import pathlib
import re
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]

PERIODIC_CASES = {
    "paper, 1 ms": [],
    "2 ms": ["controller.rate=500"],
    "4 ms": ["controller.rate=250"],
    "delay 1 sample": ["controller.delay_samples=1"],
    "delay 2 samples": ["controller.delay_samples=2"],
    "force filter 100 Hz": ["sensor.filter_cutoff=100"],
    "M = 2, B = 120, K = 200": ["impedance.m=[2,1,1]", "impedance.b=[120,20,20]", "impedance.k=[200,100,100]"],
    "scheduled damping (zeta = 1)": ["controller.damping_schedule.kind=zeta"],
}

FIRST_CONTACT_DELTAS = (-0.002, -0.005, -0.01)

LAWS = ("tmt", "known", "integral", "adaptive_damping")


def _timed(fn, timed: bool = True):
    """``(fn(), seconds)``: the second of two calls timed (the first warms the compiled libraries and
    built steps); without ``timed`` one call and no time (NaN), as the drift test needs the values only."""
    if not timed:
        return fn(), math.nan
    fn()                                   # warm: compiled libraries, built steps
    t0 = time.perf_counter()
    value = fn()
    return value, time.perf_counter() - t0


def periodic_rows(timed: bool = True) -> list[dict]:
    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.stability.analysis import scenario_stiffness_limit
    from tmtcontrol.stability.first_contact import LoopRunner, simulated_limit
    from tmtcontrol.stability.periodic import PeriodicModel, periodic_limit
    from tmtcontrol.stability.wholeloop import whole_loop_limit

    rows = []
    for name, over in PERIODIC_CASES.items():
        sc = apply_overrides(paper_scenario(), over)
        one_d = scenario_stiffness_limit(sc)
        mdl = PeriodicModel(sc, compile=True)
        (frozen, points), t_frozen = _timed(lambda: whole_loop_limit(sc, points=8, rtol=1e-4, model=mdl.frozen,
                                                                      guess=one_d), timed)
        bracket = (frozen / 1.02, max(l for _, l in points) * 1.02)
        periodic, t_periodic = _timed(lambda: periodic_limit(sc, model=mdl, bracket=bracket), timed)
        t_mono = _timed(lambda: mdl.at(0.999 * periodic))[1] if timed else math.nan
        simulated = simulated_limit(sc, periodic / 1.05, periodic * 1.05, rtol=1e-3,
                                    runner=LoopRunner(sc, compile=True))
        rows.append({"case": name, "one_d": one_d, "frozen": frozen, "periodic": periodic, "simulated": simulated,
                     "t_frozen": t_frozen, "t_periodic": t_periodic, "t_monodromy": t_mono})
    return rows


def _settles_long(runner, k_e: float) -> bool:
    from tmtcontrol.stability.first_contact import LIMIT_CYCLE_AMPLITUDE, LIMIT_CYCLE_DECAY

    sc = runner.scenario
    n = int(round(1.0 / sc.controller.Ts))
    f = runner.run(k_e, 16.0)
    last, before = np.ptp(f[-n:]), np.ptp(f[-2 * n:-n])
    return not (last >= LIMIT_CYCLE_AMPLITUDE * sc.controller.f_d and last >= LIMIT_CYCLE_DECAY * before)


def first_contact_rows(timed: bool = True) -> list[dict]:
    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.stability.analysis import scenario_stiffness_limit
    from tmtcontrol.stability.first_contact import LoopRunner, first_contact_limit
    from tmtcontrol.stability.periodic import periodic_limit

    rows = []
    for delta in FIRST_CONTACT_DELTAS:
        sc = apply_overrides(paper_scenario(), [f"controller.x_e_error={delta}"])
        one_d = scenario_stiffness_limit(sc)
        periodic = periodic_limit(sc)
        runner = LoopRunner(sc, compile=True)
        first, t_first = _timed(lambda: first_contact_limit(sc, periodic, runner=runner), timed)
        lo, hi = first / 1.1, min(first * 1.1, periodic)
        while not _settles_long(runner, lo):
            lo /= 1.1
        if _settles_long(runner, hi):
            hi = periodic
        while hi / lo > 1.001:
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if _settles_long(runner, mid) else (lo, mid)
        rows.append({"delta": delta, "one_d": one_d, "periodic": periodic, "first_contact": first,
                     "simulated": math.sqrt(lo * hi), "t_first_contact": t_first})
    return rows


THRESHOLD_CASES = {
    "force_threshold 0.5 N (default)": [],
    "force_threshold 1 N": ["controller.law.force_threshold=1.0"],
    "force_threshold 2 N": ["controller.law.force_threshold=2.0"],
    "force_threshold 4 N": ["controller.law.force_threshold=4.0"],
    "guarded approach from 5 mm": ["trajectory.approach_gap=0.005"],
}


def threshold_rows(delta: float = -0.01) -> list[dict]:
    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.stability.first_contact import LoopRunner, first_contact_limit
    from tmtcontrol.stability.periodic import periodic_limit

    base = apply_overrides(paper_scenario(), [f"controller.x_e_error={delta}"])
    periodic = periodic_limit(base)
    rows = []
    for name, over in THRESHOLD_CASES.items():
        sc = apply_overrides(base, over)
        first = first_contact_limit(sc, periodic, runner=LoopRunner(sc, compile=True))
        rows.append({"case": name, "periodic": periodic, "first_contact": first})
    return rows


INTEGRAL_GAINS = (0.02, 0.03, 0.05, 0.1)


def integral_rows() -> list[dict]:
    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.stability.analysis import scenario_stiffness_limit

    return [{"k_i": k_i, "one_d": scenario_stiffness_limit(apply_overrides(
        paper_scenario(), ["controller.law=integral", f"controller.law.k_i={k_i}"]))} for k_i in INTEGRAL_GAINS]


def law_rows() -> list[dict]:
    from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
    from tmtcontrol.stability.analysis import scenario_stiffness_limit
    from tmtcontrol.stability.first_contact import LoopRunner, simulated_limit
    from tmtcontrol.stability.periodic import periodic_limit

    rows = []
    for law in LAWS:
        sc = apply_overrides(paper_scenario(), [f"controller.law={law}"])
        periodic = periodic_limit(sc)
        rows.append({"law": law, "one_d": scenario_stiffness_limit(sc), "periodic": periodic,
                     "simulated": simulated_limit(sc, periodic / 1.05, periodic * 1.05, rtol=1e-3,
                                                  runner=LoopRunner(sc, compile=True))})
    return rows


def _g(x: float) -> str:
    return f"{x:.4g}"


def _pct(a: float, b: float) -> str:
    return f"{100 * (a / b - 1):+.2f} %"


def tables(periodic: list[dict], first: list[dict], laws: list[dict], threshold: list[dict],
           integral: list[dict]) -> dict[str, str]:
    """The generated doc tables (markdown), by name."""
    t = {"integral": "\n".join(["| k_i (m/(N s)) | " + " | ".join(f"{r['k_i']:g}" for r in integral) + " |",
                                 "|---|" + "---|" * len(integral),
                                 "| 1-D limit (N/m) | " + " | ".join(_g(r["one_d"]) for r in integral) + " |"])}
    lines = ["| start | from first contact | small signal (periodic) | first contact / small signal |",
             "|---|---|---|---|"]
    for r in threshold:
        lines.append(f"| {r['case']} | {_g(r['first_contact'])} | {_g(r['periodic'])} | "
                     f"{r['first_contact'] / r['periodic']:.3f} |")
    t["threshold"] = "\n".join(lines)
    lines = ["| case | 1-D, worst mass | whole loop, min over path | along the path (periodic) | simulated | "
             "periodic vs simulated | min over path vs simulated |", "|---|---|---|---|---|---|---|"]
    for r in periodic:
        lines.append(f"| {r['case']} | {_g(r['one_d'])} | {_g(r['frozen'])} | {_g(r['periodic'])} | "
                     f"{_g(r['simulated'])} | {_pct(r['periodic'], r['simulated'])} | "
                     f"{_pct(r['frozen'], r['simulated'])} |")
    t["periodic"] = "\n".join(lines)
    lines = ["| x_e error δ (mm) | 1-D small signal | along the path (periodic) | from first contact | "
             "simulated from the start (16 s) | first contact vs simulated | small signal vs simulated |",
             "|---|---|---|---|---|---|---|"]
    for r in first:
        lines.append(f"| {1e3 * r['delta']:g} | {_g(r['one_d'])} | {_g(r['periodic'])} | {_g(r['first_contact'])} | "
                     f"{_g(r['simulated'])} | {_pct(r['first_contact'], r['simulated'])} | "
                     f"{_pct(r['one_d'], r['simulated'])} |")
    t["first_contact"] = "\n".join(lines)
    lines = ["| law | 1-D, worst mass | along the path (periodic) | simulated |", "|---|---|---|---|"]
    for r in laws:
        lines.append(f"| `{r['law']}` | {_g(r['one_d'])} | {_g(r['periodic'])} | {_g(r['simulated'])} |")
    t["laws"] = "\n".join(lines)
    return t


DOCS = {"periodic": "docs/theory.md", "first_contact": "docs/theory.md", "threshold": "docs/theory.md",
        "laws": "docs/laws.md", "integral": "docs/laws.md"}


def block(text: str, name: str) -> str | None:
    """The generated block ``name`` of a doc page's text (None if absent)."""
    m = re.search(rf"<!-- bench_limits: {name} -->\n(.*?)\n<!-- end bench_limits -->", text, flags=re.S)
    return m.group(1) if m else None


def write_docs(t: dict[str, str]) -> None:
    for name, page in DOCS.items():
        path = ROOT / page
        text = path.read_text()
        old = block(text, name)
        if old is None:
            raise SystemExit(f"{page}: no '<!-- bench_limits: {name} -->' block")
        path.write_text(text.replace(f"<!-- bench_limits: {name} -->\n{old}\n",
                                     f"<!-- bench_limits: {name} -->\n{t[name]}\n"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--write-docs", action="store_true", help="rewrite the generated tables in docs/")
    ap.add_argument("--keep", type=pathlib.Path, help="JSON file keeping each finished part (a rerun skips it)")
    a = ap.parse_args(argv)
    import json

    kept = json.loads(a.keep.read_text()) if a.keep and a.keep.exists() else {}

    def part(name, fn):
        if name not in kept:
            kept[name] = fn()
            if a.keep:
                a.keep.write_text(json.dumps(kept))
        return kept[name]

    periodic, first = part("periodic", periodic_rows), part("first_contact", first_contact_rows)
    laws, threshold = part("laws", law_rows), part("threshold", threshold_rows)
    t = tables(periodic, first, laws, threshold, part("integral", integral_rows))
    for name in DOCS:
        print(t[name], "\n")
    print("times (warm): frozen-point limit (8 points) / periodic limit (brentq) / orbit and monodromy at 0.999x the "
          "limit (Newton shooting, 2-4 rollouts of one period)")
    for r in periodic:
        print(f"  {r['case']:32} {r['t_frozen']:6.2f} s / {r['t_periodic']:6.2f} s / {1e3 * r['t_monodromy']:6.1f} ms")
    print("times (warm): first-contact limit (bisection on 3 s runs)")
    for r in first:
        print(f"  delta {1e3 * r['delta']:+5.0f} mm  {r['t_first_contact']:6.2f} s")
    if a.write_docs:
        write_docs(t)
    return 0


if __name__ == "__main__":
    sys.exit(main())
