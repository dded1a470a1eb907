"""Compile flags chosen by measurement (issue 42): compile time and run time of
the compiled steps at each optimisation level, with the results' difference.

For each scenario, two Functions that ``simulation.rollout.Rollout`` compiles:
the simulated closed-loop step (``step``, with the scenario's contact
refinement, as ``simulate`` compiles it) and the periodic analysis's
tangent-linear step (``tangent``: the step and its Jacobian times one
direction, ``simulation.closedloop.build_tangent``: the controller's side and
the plant's right-hand side each with its own directional derivative, the
operations counted as the generated C holds them, ``rollout.operations``). Each is
compiled at every level of ``--levels`` (the other flags of
``rollout._FLAGS`` kept) into a fresh cache, then one path period's monodromy
(one tangent rollout per dynamic state) or 16 s (the step) is run five
times; the table prints the compile time, the median run time,
the Function's size and the largest difference of the outputs from -O3
(0 expected: ``-ffp-contract=off`` and no fast-math flag, so every level
computes the same IEEE arithmetic).

    python benchmarks/bench_compile_flags.py [--scenarios paper,ur5,panda] [--levels -O3,-O2,-O1,-O0]

The level ``rollout`` picks by size (``rollout.optimisation_level``) is
marked in the last column.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np


def _one(name: str, levels: list[str]) -> list[dict]:
    from tmtcontrol.simulation import rollout as ro
    from tmtcontrol.simulation.scenario import load_scenario
    from tmtcontrol.stability.periodic import PeriodicModel

    sc = load_scenario(name)
    mdl = PeriodicModel(sc, compile=False)
    loop = mdl.frozen.loop
    k_e = 5000.0                       # N/m: the paper's first segment, stable on every bundled arm
    U = mdl._inputs(k_e)
    nd = mdl.dynamic.size
    s0 = np.r_[mdl._start(k_e), np.eye(1, nd, 0).ravel()]
    sim_U, sim_P, sim_s0, _ = loop.inputs(sc, loop.path(sc))
    cases = {
        "step": (loop.step, sim_s0, sim_U, sim_P, 1),       # as simulated: with the contact refinement
        "tangent": (loop.build_tangent(mdl.dynamic), s0, U, mdl.P, nd),       # nd rollouts: the monodromy
    }
    rows = []
    for fn_name, (fn, x0, UU, PP, reps) in cases.items():
        ref = None
        for level in levels:
            ro.LEVEL = level                # in the cache key: each level is its own library
            t0 = time.perf_counter()
            r = ro.Rollout(fn, compile=True)
            t_compile = time.perf_counter() - t0
            times = []
            for _ in range(5):
                t0 = time.perf_counter()
                for _ in range(reps):
                    S, L = r.run(x0, UU, PP)
                times.append(time.perf_counter() - t0)
            out = np.r_[S[:, -1], np.ravel(L)]
            if ref is None:
                ref = out
            diff = float(np.max(np.abs(out - ref))) if np.all(np.isfinite(out)) else float("nan")
            rows.append({"scenario": name, "function": fn_name, "ops": ro.operations(fn), "level": level,
                         "compile_s": t_compile, "run_s": statistics.median(times), "samples": UU.shape[1],
                         "diff": diff, "chosen": _chosen(ro, ro.operations(fn)) == level})
    ro.LEVEL = None
    return rows


def _chosen(ro, operations: int) -> str:
    level, ro.LEVEL = ro.LEVEL, None
    try:
        return ro.optimisation_level(operations)
    finally:
        ro.LEVEL = level


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="paper,ur5,panda")
    ap.add_argument("--levels", default="-O3,-O2,-O1,-O0")
    a = ap.parse_args(argv)
    levels = a.levels.split(",")
    if levels[0] != "-O3":
        levels.insert(0, "-O3")            # the reference of the difference column
    print(f"{'scenario':8s} {'function':10s} {'operations':>10s} {'level':>5s} {'compile (s)':>11s} "
          f"{'run (ms)':>9s} {'samples':>7s} {'diff from -O3':>13s}  chosen")
    with tempfile.TemporaryDirectory() as cache:
        os.environ["TMTCONTROL_CACHE"] = cache         # every build is a cold compile
        for name in a.scenarios.split(","):
            for r in _one(name, levels):
                print(f"{r['scenario']:8s} {r['function']:10s} {r['ops']:>10,d} {r['level']:>5s} "
                      f"{r['compile_s']:11.2f} {r['run_s'] * 1e3:9.1f} {r['samples']:>7d} {r['diff']:13.3g}  "
                      + ("<-" if r["chosen"] else ""), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
