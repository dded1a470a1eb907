"""BLAS threads and sweep time: `tmtcontrol sweep` with one BLAS/OpenMP thread
per process (what tmtcontrol does, tmtcontrol.processes) and with the
libraries' default thread count (one per core), on this machine.

Run: python benchmarks/bench_threads.py [--cases N] [--workers W ...] [--repeat R]
(defaults: 60 cases over a stiffness grid and noise draws, 1 and 2 workers,
best of 2). Each run is a fresh `tmtcontrol sweep` process writing results,
summary (with the predicted stiffness limits) and figures; a warm-up run
compiles the step first. "default threads" is the same command with
tmtcontrol's limit switched off (its helpers replaced by no-ops before the
command starts; OPENBLAS_NUM_THREADS etc. unset), as before issue #27 item 16.
Prints each time, the ratio, and whether both wrote identical results (the
limit changes the speed, never a number). The issue measured 30.2 s -> 9.0 s
on a busy 2-core host; the gain depends on how busy the cores are, so the
figures are printed, not asserted.
"""
import argparse
import os
import pathlib
import subprocess
import sys
import tempfile
import time

from tmtcontrol.processes import THREAD_VARIABLES

NO_LIMIT = """
import contextlib, sys
from tmtcontrol import processes
from tmtcontrol.sweep import run as sweep_run
processes.blas_env_defaults = lambda: None
processes.one_blas_thread = lambda: None
sweep_run.one_blas_thread = lambda: None
sweep_run.blas_threads_limited = contextlib.nullcontext
from tmtcontrol.cli import run
sys.argv = ["tmtcontrol", *sys.argv[1:]]
run()
"""


def _sweep_file(folder: pathlib.Path, cases: int) -> pathlib.Path:
    grid = [2000.0 * 1.5 ** i for i in range(6)]
    path = folder / "threads.toml"
    path.write_text(f"""scenario = "paper"
[grid]
"environment.stiffness.values" = {[[g] for g in grid]}
[random]
samples = {max(1, cases // len(grid))}
seed = 7
"sensor.noise_std" = {{ uniform = [0.0, 0.1] }}
""")
    return path


def _run(limit: bool, args: list[str], cwd) -> float:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    env.setdefault("MPLBACKEND", "Agg")
    cmd = [sys.executable, "-m", "tmtcontrol.cli", *args] if limit else [sys.executable, "-c", NO_LIMIT, *args]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    dt = time.perf_counter() - t0
    if r.returncode not in (0, 1):
        sys.exit(f"the sweep failed ({r.returncode}): {r.stderr.strip()}")
    return dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=60)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    preset = [v for v in THREAD_VARIABLES if v in os.environ]
    if preset:
        print(f"note: {', '.join(preset)} removed from the runs' environment")
    import pyarrow.parquet as pq

    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        spec = _sweep_file(tmp, args.cases)
        _run(True, ["sweep", str(spec), "--out", "warm", "--no-plots"], tmp)      # compile once
        print(f"{os.cpu_count()} CPUs; {args.cases // 6 * 6} cases of 16 s at 1 kHz, results, summary and figures")
        for workers in args.workers:
            best = {}
            for label, limit in (("one BLAS thread", True), ("default threads", False)) * args.repeat:
                out = f"{'one' if limit else 'default'}-{workers}"
                dt = _run(limit, ["sweep", str(spec), "--workers", str(workers), "--out", out], tmp)
                best[label] = min(best.get(label, float("inf")), dt)
            tables = [pq.read_table(tmp / f"{k}-{workers}" / "results.parquet").drop(["run_time_s"])
                      for k in ("one", "default")]
            for label, dt in best.items():
                print(f"{workers} worker(s), {label:>15}: {dt:.2f} s (best of {args.repeat})")
            print(f"{workers} worker(s): default threads / one thread = "
                  f"{best['default threads'] / best['one BLAS thread']:.2f}x; "
                  f"identical results: {tables[0].equals(tables[1])}")


if __name__ == "__main__":
    main()
