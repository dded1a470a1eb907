"""Throughput of `tmtcontrol sweep`: paper-length cases (16 s at 1 kHz) per second.

Run: python benchmarks/bench_sweep.py [--cases N]   (default 1000)
The compiled step is built once before timing (warm). Each case draws its
noise level, so no two cases are alike. Prints cases/s for 1 and 2 local
workers and for a Dask LocalCluster of 2 workers, and checks that the three
give identical rows. Target (issue #15): 1,000 cases in <= 30 s on 2 cores.
"""
import argparse
import time
import tomllib

from tmtcontrol import Simulator, paper_scenario
from tmtcontrol.sweep import run_sweep, sweep_from_dict


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=1000)
    args = ap.parse_args()
    sweep = sweep_from_dict(tomllib.loads(f"""
    [random]
    samples = {args.cases}
    seed = 7
    "sensor.noise_std" = {{ uniform = [0.0, 0.1] }}
    """))
    Simulator(paper_scenario()).run()            # compile (or load) the paper step: warm runs below
    frames = {}
    for label, kw in (("1 worker", dict(workers=1)), ("2 workers", dict(workers=2)),
                      ("dask local, 2 workers", dict(workers=2, dask="local"))):
        t0 = time.perf_counter()
        frames[label] = run_sweep(sweep, **kw).drop(columns="run_time_s")
        dt = time.perf_counter() - t0
        print(f"{label:>22}: {args.cases} cases in {dt:.1f} s = {args.cases / dt:.1f} cases/s "
              f"(1,000 cases: {1000 * dt / args.cases:.0f} s)")
    same = all(f.equals(frames["1 worker"]) for f in frames.values())
    print(f"identical rows on every engine: {same}")


if __name__ == "__main__":      # Dask and process pools may start fresh interpreters
    main()
