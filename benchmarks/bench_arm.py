"""Speed and accuracy of the 6-D loop: the UR5 and Panda scenarios (16 s at 1 kHz).

Run: python benchmarks/bench_arm.py
Prints, per arm: the first-run time including code generation and
compilation (fresh cache), the warm compiled rollout time, microseconds per
control step, the max contact force difference from CVODES at tol 1e-12 (the
same loop, adaptive), the largest steady-state force error and orientation
error of the four segments (last second of each), and the ratio against the
same per-step Function on CasADi's virtual machine in the same process.
Target (issue 30): a paper-length UR5 rollout <= 40 ms at <= 1e-3 N against
CVODES. (Not yet here: the ratio against the loop written with Pinocchio in
Python.)
"""
import os
import statistics
import tempfile
import time

os.environ["TMTCONTROL_CACHE"] = tempfile.mkdtemp(prefix="tmt-bench-")

import numpy as np  # noqa: E402

from tmtcontrol import PoseSimulator, apply_overrides, load_scenario  # noqa: E402

for name in ("ur5", "panda"):
    sc = load_scenario(name)
    t0 = time.perf_counter()
    sim = PoseSimulator(sc, compile=True)
    res = sim.run()
    first = time.perf_counter() - t0
    U, P, s0, t = sim.inputs()
    times = []
    for _ in range(5):
        t1 = time.perf_counter()
        sim.rollout.run(s0, U, P)
        times.append(time.perf_counter() - t1)
    warm = statistics.median(times)
    n = U.shape[1]
    vm = PoseSimulator(sc, compile=False)
    t1 = time.perf_counter()
    vm.rollout.run(s0, U[:, :1000], P)
    t_vm = (time.perf_counter() - t1) / 1000 * n
    ref = PoseSimulator(apply_overrides(sc, ["simulation.integrator=cvodes", "simulation.tol=1e-12"])).run()
    err = float(np.abs(res.contact_force - ref.contact_force).max())
    ss = max(float(np.abs(res.force_error[(t >= 4 * i + 3) & (t < 4 * i + 4)]).max()) for i in range(4))
    so = max(float(res.orientation_error_norm[(t >= 4 * i + 3) & (t < 4 * i + 4)].max()) for i in range(4))
    print(f"{name}: max |f_e - f_e(CVODES 1e-12)| {err:.2g} N; first run {first:.2f} s ({sim.rollout.how}); "
          f"warm rollout {warm * 1e3:.1f} ms = {warm / n * 1e6:.2f} us/step; CasADi VM {t_vm * 1e3:.0f} ms, "
          f"speed-up {t_vm / warm:.0f}x; steady state |f_e - f_d| <= {ss:.2g} N, orientation <= {so:.2g} rad")
