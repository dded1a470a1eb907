"""Speed and accuracy on curved parts (docs/surfaces.md): 16 s at 1 kHz, the plane beside each shape.

Run: python benchmarks/bench_surfaces.py [--repeat 3] [--record [FILE]]

Prints, per arm, the time of ``Simulator.run()`` of the compiled step on
the plane and on the curved part (best of --repeat warm runs, after a
first one), their ratio (issue 40's target: the UR5 pipe within 1.5x the
plane), the first run's time (building the loop and compiling its step,
or loading the library from the compile cache, and the run), and beside
the times the worst steady-state force error of the run and the force
ripple's sampling origin: the same run with either hold at 1 and 2 kHz
(with the zero-order hold the ripple halves with Ts, an effect of the
turning normal, not a modelling error; with the mid-period hold it
quarters).

Then prints the same figures as a Markdown table (:func:`markdown_table`).
``--record`` also writes them as JSON (default
``benchmarks/surfaces_results.json``) with the machine's CPU, core count,
host speed (``bench_all.host_speed``: 0.29 s on the quiet reference
machine) and the date; docs/surfaces.md quotes the recorded table
(``tests/test_curved_acceptance.py`` fails when the two differ). Nothing
here asserts a time: it measures, on a machine that may be busy.
"""
import argparse
import json
import os
import pathlib
import platform
import sys
import time

from tmtcontrol import Simulator, apply_overrides, load_scenario
from tmtcontrol.simulation.metrics import segment_metrics

HERE = pathlib.Path(__file__).resolve().parent
RECORD = HERE / "surfaces_results.json"

PAIRS = (("paper", "puma on a dome", ['environment.shape="sphere"', "environment.radius=0.3"]),
         ("ur5", "ur5-pipe", None), ("panda", "panda-bowl", None))
"""(plane scenario, curved part, the --set that makes it curved; None: a built-in curved scenario)."""


def _timed(sc, repeat):
    t0 = time.perf_counter()
    sim = Simulator(sc, compile=True)             # builds and compiles the step, or loads the cached library
    res = sim.run()
    first = time.perf_counter() - t0
    best = min(_once(sim) for _ in range(repeat))
    worst_ss = max(abs(m.steady_state_error) for m in segment_metrics(res))
    return first, best, worst_ss


def _once(sim):
    t0 = time.perf_counter()
    sim.run()
    return time.perf_counter() - t0


def measure(repeat: int, cycles: float) -> list[dict]:
    """One row per pair of :data:`PAIRS`; times in seconds, errors in N."""
    rows = []
    for plane_name, curved_name, sets in PAIRS:
        plane = apply_overrides(load_scenario(plane_name), [f"trajectory.cycles={cycles!r}"])
        curved = apply_overrides(load_scenario(plane_name if sets else curved_name),
                                 [*(sets or []), f"trajectory.cycles={cycles!r}"])
        fp, tp, ep = _timed(plane, repeat)
        fc, tc, ec = _timed(curved, repeat)
        ripple = {}
        for hold in ("zero_order", "mid_period"):
            for rate in (1000, 2000):
                other = apply_overrides(curved, [f"controller.rate={rate}", f'controller.hold="{hold}"'])
                ripple[f"{hold}_{rate}"] = max(m.steady_state_error for m in
                                               segment_metrics(Simulator(other, compile=False).run()))
        row = {"plane": plane_name, "curved": curved_name, "hold": curved.controller.hold,
               "steps": int(round(curved.duration / curved.controller.Ts)),
               "plane_run_s": tp, "curved_run_s": tc, "ratio": tc / tp,
               "plane_first_s": fp, "curved_first_s": fc,
               "plane_worst_steady_N": ep, "curved_worst_steady_N": ec, "ripple_N": ripple}
        rows.append(row)
        print(_line(row), flush=True)
    return rows


def _line(r: dict) -> str:
    rp = r["ripple_N"]
    lines = [f"{r['curved']} ({r['hold']} hold): run {1e3 * r['curved_run_s']:.1f} ms vs plane "
             f"{1e3 * r['plane_run_s']:.1f} ms ({r['ratio']:.2f}x); first run {r['curved_first_s']:.1f} s vs "
             f"{r['plane_first_s']:.1f} s; worst steady-state |f_e - f_d| {r['curved_worst_steady_N'] * 1e3:.3g} mN "
             f"(plane {r['plane_worst_steady_N'] * 1e3:.3g} mN)"]
    for hold in ("zero_order", "mid_period"):
        a, b = rp[f"{hold}_1000"], rp[f"{hold}_2000"]
        lines.append(f"    {hold} hold: {a * 1e3:.3g} mN at 1 kHz, {b * 1e3:.3g} mN at 2 kHz (ratio {a / b:.2f})")
    return "\n".join(lines)


def ratio_text(row: dict) -> str:
    """The ratio column as the table prints it."""
    return f"{row['ratio']:.2f}×"


def markdown_table(record: dict) -> str:
    """The recorded rows as the Markdown table docs/surfaces.md quotes."""
    lines = ["| part (plane beside it) | hold | plane run | curved run | ratio | first run plane / curved | "
             "worst steady-state \\|f_e − f_d\\| plane / curved | ripple 1 kHz / 2 kHz, zero-order hold | "
             "ripple 1 kHz / 2 kHz, mid-period hold |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in record["rows"]:
        rp = r["ripple_N"]
        lines.append(
            f"| {r['curved']} ({r['plane']}) | {r['hold'].replace('_', '-')} | {1e3 * r['plane_run_s']:.1f} ms | "
            f"{1e3 * r['curved_run_s']:.1f} ms | {ratio_text(r)} | {r['plane_first_s']:.1f} s / "
            f"{r['curved_first_s']:.1f} s | {_mN(r['plane_worst_steady_N'])} / {_mN(r['curved_worst_steady_N'])} | "
            f"{_mN(rp['zero_order_1000'])} / {_mN(rp['zero_order_2000'])} | "
            f"{_mN(rp['mid_period_1000'])} / {_mN(rp['mid_period_2000'])} |")
    m = record["machine"]
    lines.append("")
    lines.append(f"Recorded {m['date']} by `python benchmarks/bench_surfaces.py --record` ({m['steps']:,} steps of "
                 f"1 ms per run, best of {m['repeat']} warm runs) on {m['cpu']}, {m['cores']} cores, Python "
                 f"{m['python']}; host speed loop {m['host_speed_loop_s'][0]:.2f} s before and "
                 f"{m['host_speed_loop_s'][1]:.2f} s after (0.29 s when quiet).")
    return "\n".join(lines)


def _mN(v: float) -> str:
    return f"{v * 1e3:.3g} mN"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cycles", type=float, default=4.0, help="path periods per run (4: the paper's 16 s)")
    ap.add_argument("--record", nargs="?", const=str(RECORD), default=None, metavar="FILE",
                    help=f"write the figures as JSON (default {RECORD.relative_to(HERE.parent)})")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from bench_all import cpu, host_speed

    speed = [host_speed()]
    rows = measure(args.repeat, args.cycles)
    speed.append(host_speed())
    steps = {r["steps"] for r in rows}
    record = {"machine": {"cpu": cpu(), "cores": os.cpu_count(), "python": platform.python_version(),
                          "host_speed_loop_s": speed, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                          "repeat": args.repeat, "steps": steps.pop() if len(steps) == 1 else max(steps)},
              "rows": rows}
    print()
    print(markdown_table(record))
    if args.record:
        pathlib.Path(args.record).write_text(json.dumps(record, indent=2) + "\n")
        print(f"(JSON: {args.record})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
