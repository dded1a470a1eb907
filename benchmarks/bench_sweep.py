"""Throughput of `tmtcontrol sweep`: paper-length cases (16 s at 1 kHz) per second.

Run: python benchmarks/bench_sweep.py [--cases N] [--arm-cases N] [--json FILE]   (defaults 1000, 64,
benchmarks/sweep_results.json); ``--markdown FILE`` prints the paragraph
docs/sweeps.md and docs/speed.md quote from a JSON written before (a test
fails when they differ).
The compiled step is built once before timing (warm). Each case draws its
noise level, so no two cases are alike. Prints cases/s for 1 and 2 local
workers and for a Dask LocalCluster of 2 workers on the PUMA's paper
scenario, and checks that the three give identical rows; then the same sweep
(``--arm-cases`` draws) on the UR5 scenario (the 6-D loop, issue 30) with 1
and 2 local workers, and the two arms' 2-worker throughput side by side with
the workers' start-up apart (:func:`marginal_rate`: a short sweep is mostly
start-up; the PUMA's over up to 400 cases), and the host's speed
(``bench_all.host_speed``) before and after, since a shared machine's speed
varies from day to day.
Target (issue #15): 1,000 PUMA cases in <= 30 s on 2 cores. The 2-worker
figures also go into the arm speed table (``bench_arm.py`` calls
:func:`marginal_rate`).
"""
import argparse
import datetime
import json
import os
import pathlib
import sys
import time
import tomllib

from tmtcontrol.sweep import run_sweep, sweep_from_dict


def noise_sweep(scenario: str, cases: int):
    """``cases`` runs of ``scenario`` (a built-in name), each with its own noise level in [0, 0.1] N."""
    return sweep_from_dict(tomllib.loads(f"""
    scenario = "{scenario}"
    [random]
    samples = {cases}
    seed = 7
    "sensor.noise_std" = {{ uniform = [0.0, 0.1] }}
    """))


def warm(scenario: str) -> None:
    """Compile (or load) the scenario's step and compute (or load) its case family's limits, so
    the timed sweeps below run warm (the first sweep would otherwise carry the analysis)."""
    from tmtcontrol import load_scenario
    from tmtcontrol.simulation.simulator import simulator_for

    simulator_for(load_scenario(scenario)).run()
    run_sweep(noise_sweep(scenario, 1), workers=1)


def throughput(scenario: str, cases: int, workers: int = 2, dask: str | None = None):
    """``(seconds, table)``: one sweep of :func:`noise_sweep` on ``workers`` local workers
    (fresh worker processes: their start-up is part of the time)."""
    sweep = noise_sweep(scenario, cases)
    t0 = time.perf_counter()
    frame = run_sweep(sweep, workers=workers, dask=dask).drop(columns="run_time_s")
    return time.perf_counter() - t0, frame


def marginal_rate(scenario: str, cases: int, workers: int = 2, base: int = 16):
    """``(cases/s, start-up s)`` on ``workers`` local workers, start-up apart: sweeps of ``base``
    and ``base + cases`` cases, the rate ``cases / (t_large - t_small)`` and the start-up
    ``t_small - base / rate`` (fresh worker processes, loading the compiled step, the scenario's
    path check and each worker's memoised stability analysis), which a short sweep would
    otherwise count as per-case time. The short sweep runs twice and the faster counts: a
    start-up slowed by another process would otherwise inflate the rate."""
    t_small = min(throughput(scenario, base, workers)[0] for _ in range(2))
    t_large, _ = throughput(scenario, base + cases, workers)
    rate = cases / (t_large - t_small)
    return rate, t_small - base / rate


def paragraph(doc: dict) -> str:
    """The throughput paragraph the docs quote, from a JSON written by :func:`main`."""
    p, u = doc["puma560"], doc["ur5"]
    side = doc["two_workers_startup_apart"]
    return (f"Throughput (`python benchmarks/bench_sweep.py`, paper-length cases, 16 s at 1 kHz, warm; "
            f"recorded {doc['date']} on {doc['cpu']}, {doc['cores']} cores, load average "
            f"{doc['load_before']:.1f} before and {doc['load_after']:.1f} after, host speed loop "
            f"{doc['host_speed_loop_s'][0]:.2f} s before and {doc['host_speed_loop_s'][1]:.2f} s after, "
            f"`bench_all.host_speed`, 0.29 s on the quiet reference machine): the PUMA "
            f"{p['1 worker'] :.1f} cases/s on 1 worker, {p['2 workers']:.1f} on 2 workers "
            f"({doc['cases']:,} cases in {doc['cases'] / p['2 workers']:.1f} s), "
            f"{p['dask local, 2 workers']:.1f} on a 2-worker Dask LocalCluster, each with its workers' "
            f"start-up; identical rows on every engine: {'yes' if doc['identical'] else 'NO'}. The UR5 "
            f"(the 6-D loop, {doc['arm_cases']} cases): {u['1 worker']:.1f} cases/s on 1 worker, "
            f"{u['2 workers']:.1f} on 2. On 2 workers with the start-up apart: the PUMA "
            f"{side['puma560'][0]:.1f} cases/s (start-up {side['puma560'][1]:.1f} s), the UR5 "
            f"{side['ur5'][0]:.1f} (start-up {side['ur5'][1]:.1f} s), against issue 42's target of 150 "
            f"PUMA cases/s.")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=1000, help="PUMA (paper scenario) cases")
    ap.add_argument("--arm-cases", type=int, default=64, help="UR5 scenario cases")
    ap.add_argument("--json", default=str(pathlib.Path(__file__).parent / "sweep_results.json"))
    ap.add_argument("--markdown", metavar="JSON", help="print the docs paragraph of a JSON written before and exit")
    args = ap.parse_args()
    if args.markdown:
        print(paragraph(json.loads(pathlib.Path(args.markdown).read_text())))
        return
    from bench_all import cpu, host_speed

    load_before = os.getloadavg()[0]
    speed = [host_speed()]
    warm("paper")
    frames, rates = {}, {"puma560": {}, "ur5": {}}
    for label, kw in (("1 worker", dict(workers=1)), ("2 workers", dict(workers=2)),
                      ("dask local, 2 workers", dict(workers=2, dask="local"))):
        dt, frames[label] = throughput("paper", args.cases, **kw)
        rates["puma560"][label] = args.cases / dt
        print(f"puma560 {label:>22}: {args.cases} cases in {dt:.1f} s = {args.cases / dt:.1f} cases/s "
              f"(1,000 cases: {1000 * dt / args.cases:.0f} s)", flush=True)
    same = all(f.equals(frames["1 worker"]) for f in frames.values())
    print(f"identical rows on every engine: {same}")
    warm("ur5")
    for label, w in (("1 worker", 1), ("2 workers", 2)):
        dt, _ = throughput("ur5", args.arm_cases, workers=w)
        rates["ur5"][label] = args.arm_cases / dt
        print(f"ur5     {label:>22}: {args.arm_cases} cases in {dt:.1f} s = {args.arm_cases / dt:.1f} cases/s",
              flush=True)
    # the PUMA's marginal rate over up to 400 cases (64 took 0.4 s: its figure was the timer's noise)
    side = {arm: marginal_rate(sc, n) for arm, sc, n in (("puma560", "paper", min(args.cases, 400)),
                                                          ("ur5", "ur5", args.arm_cases))}
    print("2 workers, paper-length cases/s after the workers' start-up (sweeps of 16 and 16 + N cases): "
          + ", ".join(f"{arm} {r:.1f} (start-up {s0:.1f} s)" for arm, (r, s0) in side.items()))
    speed.append(host_speed())
    doc = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "cpu": cpu(),
           "cores": os.cpu_count(), "python": sys.version.split()[0], "load_before": load_before,
           "load_after": os.getloadavg()[0], "cases": args.cases, "arm_cases": args.arm_cases, "identical": same,
           "host_speed_loop_s": speed, **rates, "two_workers_startup_apart": side}
    pathlib.Path(args.json).write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {args.json}")
    print(paragraph(doc))


if __name__ == "__main__":      # Dask and process pools may start fresh interpreters
    main()
