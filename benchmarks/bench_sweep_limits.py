"""Cost of each sweep case's own predicted limits (issue 28): seconds per case with
and without them (``run_sweep(limits=...)``, one process, warm compile cache), on a
small sweep of the paper loop over stiffness x surface-location error, and for a
sweep that draws the x_e error at random (every case a new small-signal analysis).

    python benchmarks/bench_sweep_limits.py
"""

import time

from tmtcontrol.sweep import run_sweep, sweep_from_dict

GRID = {"grid": {"environment.stiffness.values": [[2e4], [5e4], [1e5], [1.3e5]],
                 "controller.x_e_error": [0.0, -0.002, -0.005, -0.01]}}
RANDOM = {"grid": {"environment.stiffness.values": [[1e5]]},
          "random": {"samples": 4, "seed": 1, "controller.x_e_error": {"uniform": [-0.01, 0.0]}}}


def per_case(spec: dict, limits: bool) -> float:
    sweep = sweep_from_dict(spec)
    run_sweep(sweep_from_dict({"grid": {"environment.stiffness.values": [[1e4]]}}), limits=limits)   # warm up
    t0 = time.perf_counter()
    df = run_sweep(sweep, limits=limits)
    return (time.perf_counter() - t0) / len(df)


if __name__ == "__main__":
    for name, spec in (("grid 4 stiffness x 4 x_e_error", GRID), ("random x_e_error, 4 draws", RANDOM)):
        off, on = per_case(spec, False), per_case(spec, True)
        print(f"{name:32s} without limits {off:.3f} s/case, with limits {on:.3f} s/case (+{on - off:.3f} s)")
