"""Speed of the paper scenario rollout (16 s at 1 kHz = 16,000 control steps).

Run: python benchmarks/bench_simulate.py
Prints, for the default (4 RK4 sub-steps) and the fast setting (1 sub-step):
first-run time including code generation and compilation (fresh cache), the
warm rollout time, microseconds per control step, and the ratio against a
plain reference run in the same process — the same per-step Function
evaluated on CasADi's virtual machine — so the numbers compare across machines.
Targets (issue #3): warm rollout <= 15 ms, first run <= 3 s.
"""
import os
import statistics
import tempfile
import time

os.environ["TMTCONTROL_CACHE"] = tempfile.mkdtemp(prefix="tmt-bench-")

from tmtcontrol import Simulator, apply_overrides, paper_scenario  # noqa: E402


def warm(sim, sc, repeat=7):
    result = sim.run(sc)
    U, P, s0, _ = sim._inputs(sc, result.path)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        sim.rollout.run(s0, U, P)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), U.shape[1], (s0, U, P)


for label, sets in (("default, 4 sub-steps", []), ("fast, 1 sub-step", ["simulation.substeps=1"])):
    sc = apply_overrides(paper_scenario(), sets)
    t0 = time.perf_counter()
    sim = Simulator(sc)
    sim.run(sc)
    first = time.perf_counter() - t0
    t_warm, n, (s0, U, P) = warm(sim, sc)
    vm = Simulator(sc, compile=False)
    t1 = time.perf_counter()
    vm.rollout.run(s0, U[:, :2000], P)
    t_vm = (time.perf_counter() - t1) / 2000 * n
    print(f"{label}: first run {first:.2f} s ({sim.rollout.how}); warm rollout "
          f"{t_warm * 1e3:.1f} ms = {t_warm / n * 1e6:.2f} us/step; "
          f"CasADi VM reference {t_vm * 1e3:.0f} ms ({t_vm / n * 1e6:.1f} us/step), "
          f"speed-up {t_vm / t_warm:.0f}x")
