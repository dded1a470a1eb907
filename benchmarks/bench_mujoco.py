"""Speed and agreement of the MuJoCo plant (docs/mujoco.md): 16 s at 1 kHz on the bundled arms.

Run: python benchmarks/bench_mujoco.py [--arms ur5,panda]
Prints, per arm, the MuJoCo run's time (the controller on CasADi's virtual
machine, MuJoCo RK4 at 10 steps per period) beside the built-in compiled
run's, and beside the times the largest force difference between the two
plants and the largest per-segment steady-state difference. Target (the
issue): the UR5 under 15 s.
"""
import argparse
import time

import numpy as np

from tmtcontrol import Simulator, load_scenario
from tmtcontrol.simulation.metrics import segment_metrics
from tmtcontrol.simulation.mujoco_plant import simulate_on_mujoco


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default="ur5,panda")
    args = ap.parse_args(argv)
    for arm in args.arms.split(","):
        sc = load_scenario(arm)
        sim = Simulator(sc)
        sim.run()                                           # compiled and warm
        t0 = time.perf_counter()
        builtin = sim.run()
        t_builtin = time.perf_counter() - t0
        t0 = time.perf_counter()
        mj = simulate_on_mujoco(sc)
        t_mj = time.perf_counter() - t0
        df = float(np.max(np.abs(mj.contact_force - builtin.contact_force)))
        dss = max(abs(a.steady_state_error - b.steady_state_error)
                  for a, b in zip(segment_metrics(mj), segment_metrics(builtin)))
        print(f"{arm}: {mj.time.size} steps; MuJoCo plant {t_mj:.2f} s (run {mj.info['run_time_s']:.2f} s), "
              f"built-in compiled {1e3 * t_builtin:.1f} ms; max |f_e(MuJoCo) - f_e(built-in)| {df:.3g} N, "
              f"steady-state difference <= {dss:.2g} N")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
