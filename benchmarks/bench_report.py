"""Issue 42's speed targets, with the accuracy beside each time: the report on each arm, its analyses, simulate.

Run: python benchmarks/bench_report.py [--arms paper,ur5,panda] [--repeat N] [--json FILE]

Rows (a fresh interpreter per command, as a user runs it; ``cold`` = an empty
compile cache, ``TMTCONTROL_CACHE`` pointed at a new folder; ``warm`` = the
median of ``--repeat`` runs after one that filled the cache):

* ``tmtcontrol report ARM`` cold and warm, for each of ``--arms``; the
  accuracy beside it: the report's verdict lines (``PASS``/``FAIL`` with
  their evidence: limits, errors) cold against warm, which must be equal,
  and against the previous run recorded in the JSON file (the limits'
  difference from "today's values"), and its slowest stage;
* ``tmtcontrol analyze --scenario ur5`` cold (when ``ur5`` is among the
  arms), its deciding limit beside it against the previous record;
* ``tmtcontrol simulate`` (the paper) cold and warm.

The sweep's throughput has its own script (``bench_sweep.py``; the limits'
cost in ``bench_sweep_limits.py``). Prints a table of the figures against
the targets of issue 42 and writes the rows as JSON (``--json``, default
``benchmarks/report_results.json``) with the machine's CPU, core count and
host speed (``bench_all.host_speed``: 0.29 s on the quiet reference
machine); docs/speed.md quotes the recorded table
(``tests/test_docs.py`` fails when the two differ). No row asserts
anything: the targets are for a person to read. A cold report of the Panda
takes minutes: run the arms you need.
"""
import argparse
import compileall
import json
import os
import pathlib
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_all import cpu, host_speed  # noqa: E402

TARGETS = {("report", "paper"): (6.0, 30.0), ("report", "ur5"): (10.0, 60.0), ("report", "panda"): (10.0, 60.0),
           ("analyze", "ur5"): (None, 20.0), ("simulate", "paper"): (0.5, 2.5)}
"""(warm, cold) targets in seconds (issue 42)."""


def run(args, env):
    """``(seconds, stdout, stderr)`` of one ``tmtcontrol`` command in a fresh interpreter."""
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *args], capture_output=True, text=True, env=env)
    dt = time.perf_counter() - t0
    if r.returncode not in (0, 1):
        raise SystemExit(f"tmtcontrol {' '.join(args)} failed ({r.returncode}): {r.stderr.strip()[-400:]}")
    return dt, r.stdout, r.stderr


def verdict_lines(stdout: str) -> list[str]:
    """The report's verdict lines (``PASS  name: evidence``), which carry its figures."""
    return [line for line in stdout.splitlines() if line.startswith(("PASS  ", "FAIL  "))]


def slowest_stage(stderr: str) -> str:
    """The report's slowest stage from its progress lines (``[i/n] name: 1.2 s``)."""
    stages = [(float(m.group(2)), m.group(1)) for m in re.finditer(r"^\[\d+/\d+\] (.+): ([\d.]+) s$", stderr, re.M)]
    return f"{max(stages)[1]} {max(stages)[0]:.1f} s" if stages else ""


def deciding_limit_line(stdout: str) -> str:
    """``analyze --scenario``'s deciding limit line (``limit  123456 N/m (...)``)."""
    m = re.search(r"^limit +([\d.]+) N/m", stdout, re.M)
    return m.group(0) if m else ""


def compared(now: list[str], before: list[str] | None) -> str:
    """How figures printed now differ from the previous record: the largest
    relative difference of the numbers in the lines, pairwise."""
    if before is None:
        return "no previous record"
    if len(now) != len(before):
        return f"{len(now)} lines against {len(before)} recorded"
    num = re.compile(r"-?\d[\d,]*\.?\d*(?:e[-+]?\d+)?")
    worst = 0.0
    for a, b in zip(now, before):
        xa, xb = num.findall(a), num.findall(b)
        if len(xa) != len(xb) or num.sub("#", a) != num.sub("#", b):
            return f"changed: {a!r} (was {b!r})"
        for u, v in zip(xa, xb):
            u, v = float(u.replace(",", "")), float(v.replace(",", ""))
            worst = max(worst, abs(u - v) / max(abs(v), 1e-300) if v else abs(u))
    return f"largest relative difference from the record {worst:.1g}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--arms", default="paper,ur5,panda", help="comma-separated: paper, ur5, panda")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs per row (median)")
    ap.add_argument("--json", default=str(HERE / "report_results.json"))
    args = ap.parse_args()
    arms = [a.strip() for a in args.arms.split(",") if a.strip()]
    # as installed by pip, which compiles the bytecode (an editable checkout run with
    # PYTHONDONTWRITEBYTECODE would compile every module in every run: 0.1 s of simulate's)
    compileall.compile_dir(str(HERE.parent / "tmtcontrol"), quiet=1)
    path = pathlib.Path(args.json)
    before = {(r["command"], r["arm"]): r for r in json.loads(path.read_text())["rows"]} if path.exists() else {}
    speed = [host_speed()]
    rows = []
    with tempfile.TemporaryDirectory(prefix="tmt-bench-report-") as tmp:
        tmp = pathlib.Path(tmp)
        base = dict(os.environ, MPLBACKEND="Agg")
        fresh = iter(range(1_000_000))

        def cold_env():
            return dict(base, TMTCONTROL_CACHE=str(tmp / f"cache{next(fresh)}"))

        def timed(command, arm, argv, figures):
            """One row: cold once (an empty cache, kept for the warm runs), then warm."""
            env = cold_env()
            t_cold, out, err = run(argv(0), env)
            cold_figures = figures(out)
            warm = [run(argv(i), env) for i in range(1, args.repeat + 1)] if TARGETS[(command, arm)][0] else []
            warm_figures = figures(warm[-1][1]) if warm else cold_figures
            old = before.get((command, arm))
            row = {"command": command, "arm": arm, "cold_s": t_cold,
                   "warm_s": statistics.median(w[0] for w in warm) if warm else None,
                   "target_warm_s": TARGETS[(command, arm)][0], "target_cold_s": TARGETS[(command, arm)][1],
                   "figures": warm_figures, "cold_equals_warm": cold_figures == warm_figures,
                   "against_record": compared(warm_figures, None if old is None else old["figures"]),
                   "slowest_stage": slowest_stage(err) if command == "report" else "",
                   "slowest_stage_warm": slowest_stage(warm[-1][2]) if command == "report" and warm else ""}
            rows.append(row)
            print(_line(row), flush=True)

        print(f"{'command':<34} {'cold':>8} {'target':>7} {'warm':>8} {'target':>7}  accuracy", flush=True)
        if "paper" in arms:
            timed("simulate", "paper", lambda i: ["simulate", "--out", str(tmp / f"sim{i}")],
                  lambda out: [line for line in out.splitlines() if line.strip()[:1].isdigit()])
        for arm in arms:
            timed("report", arm, lambda i, arm=arm: ["report", arm, "--out", str(tmp / f"report-{arm}{i}")],
                  verdict_lines)
        if "ur5" in arms:
            timed("analyze", "ur5", lambda i: ["analyze", "--scenario", "ur5"],
                  lambda out: [deciding_limit_line(out)])
    speed.append(host_speed())
    out = {"machine": {"cpu": cpu(), "cores": os.cpu_count(), "python": platform.python_version(),
                       "host_speed_loop_s": speed, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())},
           "rows": rows}
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"{out['machine']['cpu']}, {out['machine']['cores']} cores, Python {out['machine']['python']}; host speed "
          f"(fixed loop, 0.29 s when quiet): {speed[0]:.2f} s before, {speed[1]:.2f} s after (JSON: {path})")
    print()
    print(markdown_table(out))


def _s(v):
    return "–" if v is None else f"{v:.2f} s" if v < 10 else f"{v:.0f} s"


def _line(row) -> str:
    what = f"{row['command']} {row['arm']}"
    acc = ("cold = warm" if row["cold_equals_warm"] else "COLD != WARM") + "; " + row["against_record"]
    if row["slowest_stage"]:
        acc += f"; slowest stage cold: {row['slowest_stage']}, warm: {row['slowest_stage_warm']}"
    return (f"{what:<34} {_s(row['cold_s']):>8} {_s(row['target_cold_s']):>7} {_s(row['warm_s']):>8} "
            f"{_s(row['target_warm_s']):>7}  {acc}")


def markdown_table(record: dict) -> str:
    """The recorded rows as the Markdown table docs/speed.md quotes."""
    lines = ["| command | cold | target | warm | target | figures cold = warm | slowest stage cold / warm |",
             "|---|---|---|---|---|---|---|"]
    for r in record["rows"]:
        lines.append(f"| `tmtcontrol {r['command']} {r['arm'] if r['command'] != 'analyze' else '--scenario ur5'}` "
                     f"| {_s(r['cold_s'])} | ≤ {_s(r['target_cold_s'])} | {_s(r['warm_s'])} | "
                     + (f"≤ {_s(r['target_warm_s'])}" if r["target_warm_s"] else "–")
                     + f" | {'yes' if r['cold_equals_warm'] else 'no'} | "
                     + (f"{r['slowest_stage']} / {r['slowest_stage_warm']}" if r["slowest_stage"] else "–") + " |")
    m = record["machine"]
    lines.append("")
    lines.append(f"Recorded {m['date']} on {m['cpu']}, {m['cores']} cores, Python {m['python']}; host speed loop "
                 f"{m['host_speed_loop_s'][0]:.2f} s before and {m['host_speed_loop_s'][1]:.2f} s after "
                 "(0.29 s when quiet).")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
