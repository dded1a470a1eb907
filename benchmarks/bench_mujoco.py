"""Speed and agreement of the MuJoCo plant (docs/mujoco.md): 16 s at 1 kHz on the bundled arms.

Run: python benchmarks/bench_mujoco.py [--arms ur5,panda] [--contacts spring,contact] [--record [--json FILE]]

Prints, per arm and MuJoCo contact model (the ideal spring, or MuJoCo's own
soft contact calibrated to k_e), the MuJoCo run's time (the controller on
CasADi's virtual machine, MuJoCo RK4 at 10 steps per period) beside the
built-in compiled run's, PASS or FAIL against issue 41's target (the UR5's
16 s run under :data:`TARGETS` s; the Panda has none), and beside the times
the accuracy: the largest force difference between the two plants and
when, the same after the first second of each segment (the transients left
out), the largest force difference over each segment's steady-state window
(its last quarter, sample by sample), the largest difference of the
per-segment steady-state errors, and the MuJoCo run's worst steady-state
|f_e - f_d|. The machine's load average (1 min) and host speed
(``bench_all.host_speed``: 0.29 s when quiet) before and after are printed
beside them: a loaded machine makes the times, not the forces, worse. Exits
1 when a row with a target FAILs it.

The force figures are deterministic (the same on any run of the same
versions); the times are not. ``--record`` writes the rows as JSON
(``--json``, default ``benchmarks/mujoco_results.json``); docs/mujoco.md
quotes :func:`markdown_table` of that record, and
``tests/test_mujoco_docs.py`` fails when the two differ.
"""
import argparse
import json
import os
import pathlib
import platform
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_all import cpu, host_speed  # noqa: E402

TARGETS = {"ur5": 15.0}
"""Seconds a 16 s, 1 kHz MuJoCo run may take (issue 41: the UR5)."""

NAMES = {"ur5": "UR5", "panda": "Panda", "spring": "spring", "contact": "MuJoCo"}


def measure(arm: str, contact: str) -> dict:
    """One row: ``arm``'s bundled scenario with ``simulation.mujoco_contact = contact`` on both plants."""
    from tmtcontrol import Simulator, apply_overrides, load_scenario
    from tmtcontrol.simulation.metrics import STEADY_FRACTION, segment_metrics
    from tmtcontrol.simulation.mujoco_plant import simulate_on_mujoco

    sc = apply_overrides(load_scenario(arm), [f'simulation.mujoco_contact="{contact}"'])
    sim = Simulator(sc)
    sim.run()                                           # compiled and warm
    t0 = time.perf_counter()
    builtin = sim.run()
    t_builtin = time.perf_counter() - t0
    t0 = time.perf_counter()
    mj = simulate_on_mujoco(sc)
    t_mj = time.perf_counter() - t0
    diff = np.abs(mj.contact_force - builtin.contact_force)
    ours, theirs = segment_metrics(mj), segment_metrics(builtin)
    after_1s = np.zeros(diff.size, dtype=bool)
    steady = []
    for m in ours:
        i = np.flatnonzero((mj.time >= m.start - 1e-9) & (mj.time < m.end - 1e-9))
        after_1s[i[mj.time[i] >= m.start + 1.0]] = True
        steady.append(float(diff[i[int(i.size * (1 - STEADY_FRACTION)):]].max()))
    target = TARGETS.get(arm)
    return {"arm": arm, "contact": contact, "steps": int(mj.time.size), "mujoco_s": t_mj,
            "mujoco_run_s": float(mj.info["run_time_s"]), "builtin_s": t_builtin, "target_s": target,
            "passed": None if target is None else bool(t_mj <= target),
            "max_force_difference_N": float(diff.max()), "max_at_s": float(mj.time[int(diff.argmax())]),
            "after_1s_N": float(diff[after_1s].max()), "steady_window_difference_N": max(steady),
            "steady_state_difference_N": max(abs(a.steady_state_error - b.steady_state_error)
                                              for a, b in zip(ours, theirs, strict=True)),
            "worst_steady_state_error_mujoco_N": max(a.steady_state_error for a in ours),
            "same_verdicts": all(a.verdict == b.verdict for a, b in zip(ours, theirs, strict=True))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default="ur5,panda")
    ap.add_argument("--contacts", default="spring,contact")
    ap.add_argument("--record", action="store_true", help="write the rows as JSON (--json) for docs/mujoco.md")
    ap.add_argument("--json", default=str(HERE / "mujoco_results.json"))
    args = ap.parse_args(argv)
    import mujoco

    load, speed = [os.getloadavg()[0]], [host_speed()]
    print(f"load average (1 min) {load[0]:.2f} on {os.cpu_count()} cores, host speed loop {speed[0]:.2f} s "
          "(0.29 s when quiet)", flush=True)
    rows = []
    for arm in args.arms.split(","):
        for contact in args.contacts.split(","):
            rows.append(measure(arm, contact))
            print(_line(rows[-1]), flush=True)
    load.append(os.getloadavg()[0])
    speed.append(host_speed())
    record = {"machine": {"cpu": cpu(), "cores": os.cpu_count(), "python": platform.python_version(),
                          "mujoco": mujoco.__version__, "load_average_1min": load, "host_speed_loop_s": speed,
                          "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())},
              "rows": rows}
    print(f"load average (1 min) {load[1]:.2f} after, host speed loop {speed[1]:.2f} s after")
    if args.record:
        pathlib.Path(args.json).write_text(json.dumps(record, indent=2) + "\n")
        print(f"recorded {args.json}")
    print()
    print(markdown_table(record))
    return 0 if all(r["passed"] is not False for r in rows) else 1


def _t(seconds: float) -> str:
    return f"{1e3 * seconds:.0f} ms" if seconds < 1 else f"{seconds:.1f} s"


def _n(newtons: float) -> str:
    """Two significant digits: 0.036 N, 2.5 N; below 10 mN as 1.2e-5 N."""
    if newtons >= 0.01 or newtons == 0:
        return f"{newtons:.2g} N"
    mantissa, exponent = f"{newtons:.1e}".split("e")
    return f"{mantissa}e{int(exponent)} N"


def _verdict(r) -> str:
    return "–" if r["target_s"] is None else f"{'PASS' if r['passed'] else 'FAIL'} (≤ {r['target_s']:g} s)"


def _line(r) -> str:
    return (f"{NAMES[r['arm']]} ({NAMES[r['contact']]} contact): {r['steps']} steps; MuJoCo plant {_t(r['mujoco_s'])} "
            f"(run {_t(r['mujoco_run_s'])}) {_verdict(r)}, built-in compiled {_t(r['builtin_s'])}; max |f_e(MuJoCo) - "
            f"f_e(built-in)| {_n(r['max_force_difference_N'])} at {r['max_at_s']:.3f} s, after 1 s of each segment "
            f"{_n(r['after_1s_N'])}, over each steady-state window {_n(r['steady_window_difference_N'])}; "
            f"steady-state errors differ by <= {_n(r['steady_state_difference_N'])}; MuJoCo's worst steady-state "
            f"|f_e - f_d| {_n(r['worst_steady_state_error_mujoco_N'])}; verdicts "
            f"{'the same' if r['same_verdicts'] else 'DIFFER'}")


def markdown_table(record: dict) -> str:
    """The recorded rows as the Markdown table docs/mujoco.md quotes."""
    lines = [("| arm | contact | MuJoCo plant | target | built-in (compiled) | max force difference (at) | "
              "after 1 s of each segment | steady-state window | steady-state error difference |"),
             "|---|---|---|---|---|---|---|---|---|"]
    for r in record["rows"]:
        lines.append(f"| {NAMES[r['arm']]} | {NAMES[r['contact']]} | {_t(r['mujoco_s'])} | {_verdict(r)} | "
                     f"{_t(r['builtin_s'])} | {_n(r['max_force_difference_N'])} ({r['max_at_s']:.3f} s) | "
                     f"{_n(r['after_1s_N'])} | {_n(r['steady_window_difference_N'])} | "
                     f"{_n(r['steady_state_difference_N'])} |")
    m = record["machine"]
    lines.append("")
    lines.append(f"Recorded {m['date']} with MuJoCo {m['mujoco']} on {m['cpu']}, {m['cores']} cores, Python "
                 f"{m['python']}; load average (1 min) {m['load_average_1min'][0]:.2f} before and "
                 f"{m['load_average_1min'][1]:.2f} after, host speed loop {m['host_speed_loop_s'][0]:.2f} s and "
                 f"{m['host_speed_loop_s'][1]:.2f} s (0.29 s when quiet).")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
