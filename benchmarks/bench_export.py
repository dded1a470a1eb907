"""Per-call time of the exported controller's tmt_step, with its accuracy beside it.

Run: python benchmarks/bench_export.py [--calls N]
Exports the paper controller without and with the inner loop (tmtcontrol
export [--inner-loop]), builds it with its own Makefile (gcc -O2
-ffp-contract=off, -Werror -pedantic), and runs ``replay --bench N`` (default
1e6 calls) over the paper run's logged measurements (the real mix of contact,
no contact and the switch between them): median, 99.9th percentile and
maximum of the per-call time (CLOCK_MONOTONIC around each call; the maximum
includes whatever preempted the process: this is not a real-time kernel).
Beside it, the replay's largest relative difference from the simulated
commands (the accuracy the time buys). Also prints the generated code's size.
Targets (issue #31), PUMA: median <= 2 us without the inner loop, <= 10 us with it.

``--scenario ur5`` (or ``panda``, or a scenario file of an arm with >= 6
joints) does the same for the 6-D task-frame controller of issue #30 over
that arm's built-in run (no target: printed for the record).
"""
import argparse
import os
import pathlib
import platform
import subprocess
import tempfile

os.environ.setdefault("TMTCONTROL_CACHE", tempfile.mkdtemp(prefix="tmt-bench-"))

import numpy as np  # noqa: E402

from tmtcontrol import load_scenario  # noqa: E402
from tmtcontrol.simulation.simulator import simulator_for  # noqa: E402
from tmtcontrol.export.generate import export_controller  # noqa: E402
from tmtcontrol.export.sil import read_commands, write_measurements  # noqa: E402

TARGETS_US = {False: 2.0, True: 10.0}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=1_000_000)
    ap.add_argument("--scenario", default="paper", help="paper (default), ur5, panda or a scenario file")
    args = ap.parse_args()
    sc = load_scenario(args.scenario)
    res = simulator_for(sc).run()
    n = res.q.shape[0]
    targets = TARGETS_US if n == 3 else {False: None, True: None}
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")),
               platform.processor())
    print(f"{sc.name} scenario ({n} joints), {args.calls:,} calls of tmt_step per variant; {cpu}")
    print(f"{'variant':<22}{'instr.':>8}{'work':>6}{'median us':>11}{'99.9% us':>10}{'max us':>9}"
          f"{'target':>8}{'replay rel. err':>17}")
    failed = False
    for inner in (False, True):
        folder = pathlib.Path(tempfile.mkdtemp(prefix="tmt-export-"))
        info = export_controller(sc, folder, inner)
        subprocess.run(["make", "-s", "replay"], cwd=folder, check=True)
        write_measurements(res, folder / "measurements.csv")
        subprocess.run(["./replay", "measurements.csv", "commands.csv"], cwd=folder, check=True)
        cmd = read_commands(folder / "commands.csv")
        x_c = np.vstack([cmd[f"x_c{i}"] for i in (1, 2, 3)])
        err = float(np.max(np.abs(x_c - res.command_task)) / np.max(np.abs(res.command_task)))
        if inner:
            tau = np.vstack([cmd[f"tau{i}"] for i in range(1, n + 1)])
            err = max(err, float(np.max(np.abs(tau - res.tau)) / np.max(np.abs(res.tau))))
        out = subprocess.run(["./replay", "--bench", str(args.calls), "measurements.csv"], cwd=folder, check=True,
                             capture_output=True, text=True).stdout
        # "tmt_step: N calls, median A us, 99.9% B us, max C us (inner loop: ...)"
        words = out.replace(",", "").split()
        median, p999, worst = (float(words[i + 1]) for i, w in enumerate(words) if w in ("median", "99.9%", "max"))
        target = targets[inner]
        ok = target is None or median <= target
        failed |= not ok
        label = "with inner loop" if inner else "without inner loop"
        print(f"{label:<22}{info['instructions']:>8}{info['sizes']['w']:>6}{median:>11.3f}{p999:>10.3f}"
              f"{worst:>9.1f}{'-' if target is None else '<= ' + format(target, 'g'):>8}{err:>17.1e}  "
              f"{'' if target is None else 'met' if ok else 'MISSED'}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
