"""Speed and accuracy of the 6-D loop: the UR5 and Panda scenarios (16 s at 1 kHz), beside the PUMA.

Run: python benchmarks/bench_arm.py [--json FILE] [--sweep-cases N]
     python benchmarks/bench_arm.py --markdown FILE   (the table of a JSON written before; runs nothing)

Prints, per arm: the first-run time including code generation and
compilation (fresh cache), the warm compiled rollout time (median of 5),
microseconds per control step, the max contact force difference from CVODES
at tol 1e-12 (the same loop, adaptive), the largest steady-state force error
and orientation error of the four segments (last second of each), and the
ratio against the same per-step Function on CasADi's virtual machine in the
same process (1,000 steps, scaled); then the same closed loop written with
Pinocchio in Python (``benchmarks/pinocchio_loop.py``: Pinocchio's ABA per
RK4 stage, the controller in NumPy) over the whole 16 s once, its time, its
ratio to the warm compiled rollout and its max contact-force difference from
it (the two integrate the same equations: rounding only); then the sweep
throughput on 2 local workers with their start-up apart
(``bench_sweep.marginal_rate``: sweeps of 16 and 16 + ``--sweep-cases``
paper-length cases, each its own noise level, as ``tmtcontrol sweep`` runs
them, predicted limits included). The
PUMA row is the paper scenario (its 3-joint position-only loop: no Pinocchio
loop is written for it).

Writes the same figures as JSON (``--json``, default
``benchmarks/arm_results.json``) with the date, CPU, core count and the load
average before and after (the machine is shared: times vary with it);
``docs/robots.md``'s speed table is :func:`markdown_table` of the committed
JSON (tests/test_pinocchio_loop.py checks it). Nothing asserts a time.
Target (issue 30): a paper-length UR5 rollout <= 40 ms at <= 1e-3 N against
CVODES.
"""
import argparse
import datetime
import json
import os
import pathlib
import statistics
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
TARGET_UR5_S, TARGET_N = 0.040, 1e-3


def _steady(series, t):
    """The largest |series| over the last second of each of the four 4-s segments."""
    import numpy as np

    return max(float(np.abs(series[(t >= 4 * i + 3) & (t < 4 * i + 4)]).max()) for i in range(4))


def arm_row(name: str) -> dict:
    import numpy as np
    import pinocchio as pin
    from pinocchio_loop import PinocchioLoop

    from tmtcontrol import Simulator, apply_overrides, load_scenario
    from tmtcontrol.simulation.simulator import robot_of

    sc = load_scenario(name)
    Sim = Simulator if name == "paper" else Simulator
    t0 = time.perf_counter()
    sim = Sim(sc, compile=True)
    res = sim.run()
    first = time.perf_counter() - t0
    U, P, s0, t = sim._inputs(sc, res.path) if name == "paper" else sim.inputs()
    times = []
    for _ in range(5):
        t1 = time.perf_counter()
        sim.rollout.run(s0, U, P)
        times.append(time.perf_counter() - t1)
    warm = statistics.median(times)
    n = U.shape[1]
    vm = Sim(sc, compile=False)
    vm.rollout.step     # built before the clock starts (on first use): the time per step, not the build x 16
    t1 = time.perf_counter()
    vm.rollout.run(s0, U[:, :1000], P)
    t_vm = (time.perf_counter() - t1) / 1000 * n
    ref = Sim(apply_overrides(sc, ["simulation.integrator=cvodes", "simulation.tol=1e-12"])).run()
    err = float(np.abs(res.contact_force - ref.contact_force).max())
    row = {"arm": "puma560" if name == "paper" else name, "scenario": name, "joints": int(sim.plant.n)
           if name != "paper" else 3, "steps": int(n), "first_run_s": first, "how": sim.rollout.how,
           "rollout_s": warm, "us_per_step": warm / n * 1e6, "vm_s": t_vm, "cvodes_error_N": err,
           "steady_force_error_N": _steady(res.force_error, t)}
    line = (f"{row['arm']}: max |f_e - f_e(CVODES 1e-12)| {err:.2g} N; first run {first:.2f} s ({sim.rollout.how}); "
            f"warm rollout {warm * 1e3:.1f} ms = {warm / n * 1e6:.2f} us/step; CasADi VM {t_vm * 1e3:.0f} ms, "
            f"speed-up {t_vm / warm:.0f}x; steady state |f_e - f_d| <= {row['steady_force_error_N']:.2g} N")
    if name != "paper":
        row["steady_orientation_error_rad"] = so = _steady(res.orientation_error_norm, t)
        line += f", orientation <= {so:.2g} rad"
        t1 = time.perf_counter()
        py = PinocchioLoop(sc, robot_of(sc)).run(U, P, s0)
        t_py = time.perf_counter() - t1
        row.update(pinocchio=pin.__version__, pinocchio_s=t_py, pinocchio_ratio=t_py / warm,
                   pinocchio_difference_N=float(np.abs(py.contact_force - res.contact_force).max()))
        line += (f"\n{row['arm']}: Pinocchio {pin.__version__} in Python, the same loop over all {n} steps: "
                 f"{t_py:.2f} s = {t_py / n * 1e6:.0f} us/step, {t_py / warm:.0f}x the compiled rollout; "
                 f"max |f_e - f_e(compiled)| {row['pinocchio_difference_N']:.2g} N")
    print(line, flush=True)
    return row


def markdown_table(doc: dict) -> str:
    """The speed table of docs/robots.md from a JSON written by this script."""
    def t(s):
        return f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s"

    lines = ["| arm (scenario) | compiled rollout, 16 s at 1 kHz | per step | max \\|f_e − f_e(CVODES 1e-12)\\| "
             "| first run (compiling) | the loop in Python with Pinocchio | ratio "
             "| sweep on 2 workers (start-up apart) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        py = ("not written (3-joint position-only loop)", "–")
        if "pinocchio_s" in r:
            py = (f"{t(r['pinocchio_s'])} (force within {r['pinocchio_difference_N']:.1g} N)",
                  f"{r['pinocchio_ratio']:.0f}x")
        lines.append(f"| {r['arm']} ({r['scenario']}) | {t(r['rollout_s'])} | {r['us_per_step']:.2f} µs "
                     f"| {r['cvodes_error_N']:.2g} N | {t(r['first_run_s'])} | {py[0]} | {py[1]} "
                     f"| {r['sweep_cases_per_s']:.1f} cases/s (start-up {r['sweep_startup_s']:.1f} s) |")
    lines.append("")
    lines.append(f"Measured {doc['date']} on {doc['cpu']} ({doc['cores']} cores), load average "
                 f"{doc['load_before']:.1f} before and {doc['load_after']:.1f} after the run "
                 f"(Pinocchio {doc['pinocchio']}; target: UR5 rollout ≤ {TARGET_UR5_S * 1e3:.0f} ms at "
                 f"≤ {TARGET_N:g} N).")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=str(HERE / "arm_results.json"))
    ap.add_argument("--sweep-cases", type=int, default=64)
    ap.add_argument("--markdown", metavar="JSON", help="print the docs table of a JSON written before and exit")
    args = ap.parse_args()
    if args.markdown:
        print(markdown_table(json.loads(pathlib.Path(args.markdown).read_text())), end="")
        return
    from bench_all import cpu
    from bench_sweep import marginal_rate

    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="tmt-bench-arm-") as cache:
        os.environ["TMTCONTROL_CACHE"] = cache            # fresh: the first run compiles
        rows = [arm_row(name) for name in ("paper", "ur5", "panda")]
        for row in rows:
            row["sweep_cases_per_s"], row["sweep_startup_s"] = marginal_rate(row["scenario"], args.sweep_cases)
            print(f"{row['arm']}: sweep on 2 workers, {row['sweep_cases_per_s']:.1f} paper-length cases/s after "
                  f"a start-up of {row['sweep_startup_s']:.1f} s (sweeps of 16 and {16 + args.sweep_cases} "
                  "cases)", flush=True)
    import pinocchio as pin

    doc = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "cpu": cpu(),
           "cores": os.cpu_count(), "python": sys.version.split()[0], "pinocchio": pin.__version__,
           "load_before": load_before, "load_after": os.getloadavg()[0], "sweep_cases": args.sweep_cases,
           "rows": rows}
    ur5 = next(r for r in rows if r["arm"] == "ur5")
    print(f"target: UR5 rollout {ur5['rollout_s'] * 1e3:.1f} ms (<= {TARGET_UR5_S * 1e3:.0f} ms) at "
          f"{ur5['cvodes_error_N']:.2g} N (<= {TARGET_N:g} N); load average {doc['load_before']:.1f} -> "
          f"{doc['load_after']:.1f}")
    pathlib.Path(args.json).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":      # the sweep's process pools may start fresh interpreters
    main()
