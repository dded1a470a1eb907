"""Every row of the speed table (issue #14), with the accuracy beside the time.

Run: python benchmarks/bench_all.py [--json FILE] [--skip-suite]

Rows (median of repeats, this machine, warm compile cache unless said):

* paper rollout (16,000 steps, default settings) and its max contact-force
  difference from CVODES at tol 1e-12;
* ``Simulator.run()`` overhead beyond the rollout;
* ``tmtcontrol simulate`` warm, warm ``--no-plots``, and cold (empty cache);
* ``tmtcontrol report paper`` warm;
* ``tmtcontrol design`` (the docs' example) warm;
* ``pytest`` (the README's command, 2 workers) unless ``--skip-suite``.

Prints a table and writes the same rows as JSON (``--json``, default
``benchmarks/results.json``) with the machine's CPU and core count. No row
asserts anything: the targets are beside the figures for a person to read.

On a shared machine the same work takes up to 1.5x longer in a busy hour.
The host's speed is printed before and after the rows: the time of a fixed
CPU-bound Python loop (0.29 s on the reference machine when it is quiet),
so a reader can tell a slow host from a slow change.
"""
import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
TARGETS = {"rollout": 0.015, "run_overhead": 0.005, "simulate": 0.8, "simulate_no_plots": 0.4,
           "simulate_cold": 2.5, "report": 6.0, "design": 1.5, "pytest": 120.0}
DESIGN_ARGS = ["design", "--m", "1", "--k", "100", "--ke-min", "2000", "--ke-max", "20000", "--ts", "0.001",
               "--max-overshoot", "5"]


def cpu() -> str:
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def host_speed() -> float:
    """Seconds for a fixed CPU-bound pure-Python loop (the host's speed now)."""
    t0 = time.perf_counter()
    total = 0
    for i in range(6_000_000):
        total += i * i
    return time.perf_counter() - t0


def pdf_font_subsetter() -> str:
    """Which library WeasyPrint subsets the PDF's fonts with here (HarfBuzz-Subset
    is a system library, docs/install.md; without it fontTools does, slower)."""
    try:
        from weasyprint.text.ffi import harfbuzz_subset
    except (ImportError, OSError) as exc:
        return f"none: WeasyPrint does not load ({type(exc).__name__})"
    return "HarfBuzz-Subset" if harfbuzz_subset is not None else "fontTools (libharfbuzz-subset0 not found)"


def median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def command(args, env=None, cwd=None):
    """Wall time of one ``tmtcontrol`` command in a fresh interpreter (as a user runs it)."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *args], capture_output=True, text=True,
                       env=env, cwd=cwd)
    dt = time.perf_counter() - t0
    if r.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(args)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return dt


def rollout_rows(rows):
    import numpy as np

    from tmtcontrol import Simulator, apply_overrides, paper_scenario

    sc = paper_scenario()
    sim = Simulator(sc, compile=True)        # compiled (or loaded) now, not after 10,000 steps
    res = sim.run()
    U, P, s0, _ = sim._inputs(sc, res.path)
    t_roll = median_time(lambda: sim.rollout.run(s0, U, P), 15)
    # the overhead of each run() beyond its own rollout (run_time_s, timed inside run()): the
    # difference of two medians taken apart would carry the host's noise between them
    overheads = []
    for _ in range(15):
        t0 = time.perf_counter()
        r = sim.run()
        overheads.append(time.perf_counter() - t0 - r.info["run_time_s"])
    t_overhead = statistics.median(overheads)
    ref = Simulator(apply_overrides(sc, ["simulation.integrator=cvodes", "simulation.tol=1e-12"])).run()
    err = float(np.abs(res.contact_force - ref.contact_force).max())
    rows.append({"row": "rollout", "what": "paper rollout, 16,000 steps, default settings", "seconds": t_roll,
                 "accuracy": f"max |f_e - f_e(CVODES 1e-12)| = {err:.2g} N (target <= 1e-3 N)",
                 "max_force_error_N": err})
    rows.append({"row": "run_overhead", "what": "Simulator.run() beyond the rollout", "seconds": t_overhead})


def main():
    import compileall

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", default=str(HERE / "results.json"))
    ap.add_argument("--skip-suite", action="store_true", help="do not time the test suite (2 minutes)")
    args = ap.parse_args()
    # as installed by pip, which compiles the bytecode (an editable checkout run
    # with PYTHONDONTWRITEBYTECODE would otherwise compile every module each run)
    compileall.compile_dir(str(ROOT / "tmtcontrol"), quiet=1)
    speed_before = host_speed()
    rows = []
    rollout_rows(rows)
    with tempfile.TemporaryDirectory(prefix="tmt-bench-") as tmp:
        tmp = pathlib.Path(tmp)
        cold_env = dict(os.environ, TMTCONTROL_CACHE=str(tmp / "empty-cache"), MPLBACKEND="Agg")
        warm_env = dict(os.environ, MPLBACKEND="Agg")
        command(["simulate", "--out", str(tmp / "w0")], env=warm_env)     # fill the user's cache
        rows.append({"row": "simulate", "what": "tmtcontrol simulate, warm", "seconds": statistics.median(
            command(["simulate", "--out", str(tmp / f"w{i}")], env=warm_env) for i in range(1, 6))})
        rows.append({"row": "simulate_no_plots", "what": "tmtcontrol simulate --no-plots, warm",
                     "seconds": statistics.median(command(["simulate", "--no-plots", "--out", str(tmp / f"n{i}")],
                                                          env=warm_env) for i in range(5))})
        rows.append({"row": "simulate_cold", "what": "tmtcontrol simulate, empty compile cache",
                     "seconds": command(["simulate", "--out", str(tmp / "cold")], env=cold_env)})
        command(["report", "paper", "--out", str(tmp / "r0")], env=warm_env)
        rows.append({"row": "report", "what": "tmtcontrol report paper, warm", "seconds": statistics.median(
            command(["report", "paper", "--out", str(tmp / f"r{i}")], env=warm_env) for i in range(1, 4))})
        rows.append({"row": "design", "what": "tmtcontrol " + " ".join(DESIGN_ARGS), "seconds": statistics.median(
            command(DESIGN_ARGS, env=warm_env) for _ in range(3))})
    if not args.skip_suite:
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2"], cwd=ROOT, capture_output=True,
                           text=True, env=dict(os.environ, MPLBACKEND="Agg"))
        rows.append({"row": "pytest", "what": "pytest -n 2 (the whole suite)", "seconds": time.perf_counter() - t0,
                     "accuracy": r.stdout.strip().splitlines()[-1] if r.stdout.strip() else f"exit {r.returncode}"})
    for row in rows:
        row["target_s"] = TARGETS[row["row"]]
    speed = [speed_before, host_speed()]
    out = {"machine": {"cpu": cpu(), "cores": os.cpu_count(), "python": platform.python_version(),
                       "host_speed_loop_s": speed, "pdf_font_subsetter": pdf_font_subsetter()}, "rows": rows}
    pathlib.Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    print(f"{out['machine']['cpu']}, {out['machine']['cores']} cores, Python {out['machine']['python']}; "
          f"host speed (fixed loop, 0.29 s when quiet): {speed[0]:.2f} s before, {speed[1]:.2f} s after; "
          f"PDF fonts subset by {out['machine']['pdf_font_subsetter']}")
    print(f"{'what':<58} {'time':>10} {'target':>9}  note")
    for row in rows:
        t = row["seconds"]
        shown = f"{t * 1e3:.1f} ms" if t < 1 else f"{t:.2f} s"
        target = row["target_s"]
        tshown = f"{target * 1e3:.0f} ms" if target < 1 else f"{target:g} s"
        print(f"{row['what']:<58} {shown:>10} {tshown:>9}  {row.get('accuracy', '')}")
    print(f"(JSON: {args.json})")


if __name__ == "__main__":
    main()
