"""Speed of `compare`: the paper scenario (16,000 steps) with all five laws.

Run: python benchmarks/bench_compare.py
Prints the cold time (empty compile cache: one compilation per law
structure), then the warm time of ``compare_laws`` (Simulator construction,
path, rollouts, metrics) and of writing the outputs without and with the two
overlay figures. Target (issue #12): warm compare <= 3 s plus figures.
"""
import os
import statistics
import tempfile
import time

os.environ["TMTCONTROL_CACHE"] = tempfile.mkdtemp(prefix="tmt-bench-")

from tmtcontrol import compare_laws, paper_scenario  # noqa: E402
from tmtcontrol.simulation.compare import save_comparison  # noqa: E402

sc = paper_scenario()
t0 = time.perf_counter()
cmp = compare_laws(sc)
cold = time.perf_counter() - t0
runs = []
for _ in range(3):
    t0 = time.perf_counter()
    cmp = compare_laws(sc)
    runs.append(time.perf_counter() - t0)
t0 = time.perf_counter()
save_comparison(cmp, tempfile.mkdtemp(), plots=False)
save_plain = time.perf_counter() - t0
t0 = time.perf_counter()
save_comparison(cmp, tempfile.mkdtemp(), plots=True)
save_figs = time.perf_counter() - t0
print(f"compare, {len(cmp.runs)} laws x {cmp.runs['tmt'].result.time.size} steps: cold {cold:.1f} s; "
      f"warm {statistics.median(runs):.2f} s (median of 3); write outputs {save_plain:.2f} s, "
      f"with figures {save_figs:.2f} s; all converged: {cmp.converged}")
