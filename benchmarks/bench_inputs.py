"""Refusing inputs too large to run (issue #27 items 2 and 4): how fast, with how much memory.

Run: python benchmarks/bench_inputs.py
Each input is given to the `tmtcontrol` command in a fresh process: a 1000 x 1000 x
1000 grid, `samples = 1000000000`, a `linspace` of 1e9 values (refused by
`--max-cases`), a 2 GiB sparse scenario file, a FIFO and /dev/zero (refused before
reading). Prints the wall time of the whole command (interpreter start and imports
included) and its peak resident memory, beside the exit code and the one line it
printed. Target: each refused with exit 2 in well under a second and about the
memory of the interpreter with tmtcontrol's imports (before issue #27: 4 GiB in
under a minute, or a read that never ends).
"""
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

SWEEPS = {
    "1000 x 1000 x 1000 grid": '[grid]\n"controller.f_d" = { linspace = [1, 2, 1000] }\n'
                               '"sensor.noise_std" = { linspace = [0, 0.1, 1000] }\n'
                               '"trajectory.radius" = { linspace = [0, 0.1, 1000] }\n',
    "samples = 1e9": '[random]\nsamples = 1000000000\n"sensor.noise_std" = { uniform = [0, 0.1] }\n',
    "linspace n = 1e9": '[grid]\n"controller.f_d" = { linspace = [1, 2, 1000000000] }\n',
}


def _run(args: list[str]) -> tuple[float, float, int, str]:
    """Wall time (s), peak RSS of the child (MiB), exit code, last stderr line."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", *args], capture_output=True, text=True, timeout=600)
    dt = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    line = (r.stderr.strip().splitlines() or [""])[-1]
    return dt, max(peak, before) / 1024, r.returncode, line


def main():
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        cases = []
        for name, text in SWEEPS.items():
            path = tmp / f"{len(cases)}.toml"
            path.write_text(text)
            cases.append((name, ["sweep", str(path), "--out", str(tmp / "o")]))
        big = tmp / "big.toml"
        with open(big, "wb") as fh:
            fh.truncate(2 * 2**30)
        cases.append(("2 GiB scenario file", ["simulate", str(big), "--out", str(tmp / "o")]))
        os.mkfifo(tmp / "fifo")
        cases.append(("FIFO as the scenario", ["simulate", str(tmp / "fifo"), "--out", str(tmp / "o")]))
        cases.append(("/dev/zero as the scenario", ["simulate", "/dev/zero", "--out", str(tmp / "o")]))
        print(f"{'input':>28}  {'exit':>4}  {'wall s':>6}  {'peak MiB*':>9}  line")
        for name, args in cases:
            dt, peak, code, line = _run(args)
            print(f"{name:>28}  {code:>4}  {dt:6.2f}  {peak:9.0f}  {line[:110]}")
        print("* the largest peak resident memory of any child so far (getrusage), an upper bound for each")


if __name__ == "__main__":
    main()
