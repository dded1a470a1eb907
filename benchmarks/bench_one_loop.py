"""The one closed loop against the two loop families it replaced: per-segment results, traces and limits.

Runs the same scenarios with this checkout and with a reference commit (default
48d3a50, the last commit with the PUMA loop and the 6-D loop apart), each in
its own process on its own source tree (a ``git worktree`` of the reference in
a temporary folder, removed afterwards), and prints for each scenario the
largest difference of the force trace (N) and of every per-segment metric
(relative), and the paper scenario's ``analyze`` limits (relative). The issue's
bounds: the PUMA within 1e-12 relative, the UR5 and the Panda within 1e-9 N.

    python benchmarks/bench_one_loop.py [--reference COMMIT] [--no-analyze] [--speed]

``--speed`` also runs ``bench_simulate.py`` and ``bench_arm.py`` of both trees
alternately (the issue: within 5 % of the reference in the same run).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
VARIANTS = {
    "paper": ("paper", []),
    "paper_delay": ("paper", ["controller.delay_samples=2", "controller.x_e_error=-0.002"]),
    "paper_guard": ("paper", ["trajectory.approach_gap=0.005", "controller.law=integral"]),
    "paper_sched": ("paper", ['controller.damping_schedule.kind="zeta"', "sensor.noise_std=0.05",
                              "robot.model_mass_scale=0.9"]),
    "ur5": ("ur5", []),
    "ur5_delay": ("ur5", ["controller.delay_samples=1", "controller.law=rls"]),
    "panda": ("panda", []),
}
SERIES = ("contact_force", "q", "tau", "position")


def capture(out: pathlib.Path, analyze: bool) -> None:
    """Run every variant with the tmtcontrol on sys.path; write traces, metrics and limits into ``out``."""
    try:                                   # the one loop
        from tmtcontrol.simulation.simulator import simulator_for
    except ImportError:                    # the reference: the 6-D family picked the loop
        from tmtcontrol.simulation.posesim import simulator_for
    from tmtcontrol.simulation.metrics import segment_metrics
    from tmtcontrol.simulation.scenario import apply_overrides, load_scenario

    for name, (base, sets) in VARIANTS.items():
        sc = apply_overrides(load_scenario(base), sets) if sets else load_scenario(base)
        res = simulator_for(sc).run()
        np.savez(out / f"{name}.npz", **{k: getattr(res, k) for k in SERIES})
        (out / f"{name}.json").write_text(json.dumps([dataclasses.asdict(m) for m in segment_metrics(res)],
                                                     default=str))
    if analyze:
        from tmtcontrol.stability.analysis import analyze_scenario

        (out / "analyze.json").write_text(json.dumps(analyze_scenario(load_scenario("paper"), limits=True),
                                                     default=str))


def _numbers(x, path=""):
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _numbers(v, f"{path}.{k}")
    elif isinstance(x, list):
        for i, v in enumerate(x):
            yield from _numbers(v, f"{path}[{i}]")
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        yield path, float(x)


ADDED_METRICS = ("torque_margin", "rate_margin", "position_margin", "orientation_error", "normal_tilt",
                 "chart_force_error", "chart_normal_error", "window", "clip_time", "peak_orientation_error")
"""Per-segment metrics the reference commit does not have."""


def worst_relative(a, b) -> tuple[float, str]:
    A, B = dict(_numbers(a)), dict(_numbers(b))
    # metrics added since the reference (the limits' margins, the orientation error) have nothing to compare
    new = {k for k in A.keys() ^ B.keys() if k.rsplit(".", 1)[-1] in ADDED_METRICS}
    A, B = ({k: v for k, v in X.items() if k not in new} for X in (A, B))
    assert A.keys() == B.keys(), sorted(A.keys() ^ B.keys())[:5]
    out = (0.0, "")
    for k, x in A.items():
        y = B[k]
        if x != y and not (np.isnan(x) and np.isnan(y)):
            r = abs(x - y) / max(abs(x), 1e-300)
            out = max(out, (r, k))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reference", default="48d3a50")
    ap.add_argument("--no-analyze", action="store_true")
    ap.add_argument("--speed", action="store_true", help="also run bench_simulate.py and bench_arm.py of both "
                    "trees, alternately, and print both")
    ap.add_argument("--capture", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.capture:
        capture(pathlib.Path(args.capture), not args.no_analyze)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        ref_tree = tmp / "reference-tree"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(ref_tree), args.reference],
                       check=True, capture_output=True)
        try:
            for label, tree in (("reference", ref_tree), ("current", ROOT)):
                (tmp / label).mkdir()
                env = {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
                subprocess.run([sys.executable, str(pathlib.Path(__file__).resolve()), "--capture", str(tmp / label),
                                *(["--no-analyze"] if args.no_analyze else [])], env=env, check=True, cwd=tree)
            if args.speed:
                speed = _speed(ref_tree)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(ref_tree)],
                           capture_output=True)
        print(f"{'scenario':<12} {'force max |diff| (N)':>22} {'joints (rad)':>13} {'worst metric (rel)':>19}  metric")
        for name in VARIANTS:
            A, B = np.load(tmp / "reference" / f"{name}.npz"), np.load(tmp / "current" / f"{name}.npz")
            df = float(np.max(np.abs(A["contact_force"] - B["contact_force"])))
            dq = float(np.max(np.abs(A["q"] - B["q"])))
            r, k = worst_relative(json.loads((tmp / "reference" / f"{name}.json").read_text()),
                                  json.loads((tmp / "current" / f"{name}.json").read_text()))
            print(f"{name:<12} {df:>22.3g} {dq:>13.3g} {r:>19.3g}  {k}")
        if not args.no_analyze:
            r, k = worst_relative(json.loads((tmp / "reference" / "analyze.json").read_text()),
                                  json.loads((tmp / "current" / "analyze.json").read_text()))
            print(f"analyze paper: worst relative difference {r:.3g} ({k or 'none'})")
        if args.speed:
            print(speed)
    return 0


def _speed(ref_tree: pathlib.Path) -> str:
    """The speed benchmarks of both trees, each tree's own script on its own
    code, run alternately (reference, current, reference, current) so a load
    change on the machine hits both; their outputs, labelled."""
    out = []
    for script in ("bench_simulate.py", "bench_arm.py"):
        for round_ in (1, 2):
            for label, tree in (("reference", ref_tree), ("current", ROOT)):
                env = {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
                extra = ["--json", os.devnull] if script == "bench_arm.py" else []   # not the docs' quiet run
                r = subprocess.run([sys.executable, str(tree / "benchmarks" / script), *extra], env=env, cwd=tree,
                                   capture_output=True, text=True)
                out.append(f"--- {script}, {label} (round {round_}), exit {r.returncode} ---\n{r.stdout.strip()}")
    return "\n".join(out)


if __name__ == "__main__":
    sys.exit(main())
