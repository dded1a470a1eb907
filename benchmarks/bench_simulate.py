"""Speed and accuracy of the paper scenario rollout (16 s at 1 kHz = 16,000 control steps).

Run: python benchmarks/bench_simulate.py
Prints, for the default (one RK4 step per period, refined 4x where the contact
switches on or off), the same without refinement, and a uniform 4 steps per
period: the first-run time including code generation and compilation (fresh
cache), the warm rollout time, microseconds per control step, the max contact
force difference from CVODES at tol 1e-12, and the ratio against a plain
reference run in the same process (the same per-step Function on CasADi's
virtual machine), so the numbers compare across machines.
Target (issue #14): warm rollout <= 15 ms at <= 1e-3 N.
"""
import os
import statistics
import tempfile
import time

os.environ["TMTCONTROL_CACHE"] = tempfile.mkdtemp(prefix="tmt-bench-")

import numpy as np  # noqa: E402

from tmtcontrol import Simulator, apply_overrides, paper_scenario  # noqa: E402

REFERENCE = Simulator(apply_overrides(paper_scenario(), ["simulation.integrator=cvodes",
                                                         "simulation.tol=1e-12"])).run().contact_force


def warm(sim, sc, repeat=7):
    result = sim.run(sc)
    U, P, s0, _ = sim._inputs(sc, result.path)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sim.rollout.run(s0, U, P)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), U.shape[1], (s0, U, P)


for label, sets in (("default (1 step, contact_refine 4)", []),
                    ("contact_refine 1", ["simulation.contact_refine=1"]),
                    ("uniform 4 steps", ["simulation.substeps=4", "simulation.contact_refine=1"])):
    sc = apply_overrides(paper_scenario(), sets)
    t0 = time.perf_counter()
    sim = Simulator(sc, compile=True)
    result = sim.run(sc)
    first = time.perf_counter() - t0
    err = float(np.abs(result.contact_force - REFERENCE).max())
    t_warm, n, (s0, U, P) = warm(sim, sc)
    vm = Simulator(sc, compile=False)
    t1 = time.perf_counter()
    vm.rollout.run(s0, U[:, :2000], P)
    t_vm = (time.perf_counter() - t1) / 2000 * n
    print(f"{label}: max |f_e - f_e(CVODES)| {err:.2g} N; first run {first:.2f} s ({sim.rollout.how}); "
          f"warm rollout {t_warm * 1e3:.1f} ms = {t_warm / n * 1e6:.2f} us/step; "
          f"CasADi VM reference {t_vm * 1e3:.0f} ms ({t_vm / n * 1e6:.1f} us/step), "
          f"speed-up {t_vm / t_warm:.0f}x")
