"""Speed and agreement of the MuJoCo plant (docs/mujoco.md): 16 s at 1 kHz on the bundled arms.

Run: python benchmarks/bench_mujoco.py [--arms ur5,panda] [--contacts spring,contact]
Prints, per arm and MuJoCo contact model (the ideal spring, or MuJoCo's own
soft contact calibrated to k_e), the MuJoCo run's time (the controller on
CasADi's virtual machine, MuJoCo RK4 at 10 steps per period) beside the
built-in compiled run's, and beside the times the largest force difference
between the two plants, the same after the first second of each segment
(the transients left out), the largest per-segment steady-state difference
and the MuJoCo run's worst steady-state |f_e - f_d|. Target (the issue):
the UR5 under 15 s.
"""
import argparse
import time

import numpy as np

from tmtcontrol import Simulator, apply_overrides, load_scenario
from tmtcontrol.simulation.metrics import segment_metrics
from tmtcontrol.simulation.mujoco_plant import simulate_on_mujoco


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default="ur5,panda")
    ap.add_argument("--contacts", default="spring,contact")
    args = ap.parse_args(argv)
    for arm in args.arms.split(","):
        for contact in args.contacts.split(","):
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
            late = (mj.time % sc.trajectory.period) >= 1.0
            ours, theirs = segment_metrics(mj), segment_metrics(builtin)
            dss = max(abs(a.steady_state_error - b.steady_state_error) for a, b in zip(ours, theirs))
            worst = max(a.steady_state_error for a in ours)
            print(f"{arm} ({contact}): {mj.time.size} steps; MuJoCo plant {t_mj:.2f} s (run "
                  f"{mj.info['run_time_s']:.2f} s), built-in compiled {1e3 * t_builtin:.1f} ms; max |f_e(MuJoCo) - "
                  f"f_e(built-in)| {diff.max():.3g} N, after 1 s of each segment {diff[late].max():.2g} N, "
                  f"steady-state difference <= {dss:.2g} N, MuJoCo's worst steady-state |f_e - f_d| {worst:.2g} N")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
