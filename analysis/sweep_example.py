"""The worked example of docs/sweeps.md: what `tmtcontrol sweep` prints for
docs/sweeps/paper-gains.toml, its exit code and its map (the page quotes them).

Usage: python analysis/sweep_example.py [--out DIR] [--workers N] [--points N] [--cycles C] [--rates R,...]

Runs ``tmtcontrol sweep docs/sweeps/paper-gains.toml --workers N`` (with
``--points``/``--cycles``/``--rates`` other than the file's 12 stiffnesses, 1
cycle and 4 control rates, a smaller copy of it, for a quick look) and writes ``output.txt`` (stdout, the
run time replaced by "T", then "exit code: N"), ``sweep_map.png`` and
``summary.json``. Regenerate the page's figure and quote with
``--out docs/figures/sweep-example`` (the defaults); tests/test_presentation.py
checks that docs/sweeps.md quotes output.txt and (heavy) that a fresh run
prints the same.
"""
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

from tmtcontrol.files import OutputFolder
from tmtcontrol.studies import Parser, numbers, positive
from tmtcontrol.studies import run as run_study

ROOT = pathlib.Path(__file__).resolve().parents[1]
SWEEP = ROOT / "docs" / "sweeps" / "paper-gains.toml"


def sweep_text(points: int = 12, cycles: float = 1.0, rates: list[float] | None = None) -> str:
    """The example's sweep file, with ``points`` stiffnesses, ``cycles`` per case and
    ``rates`` (Hz; None: the file's four)."""
    text = SWEEP.read_text()
    text = re.sub(r"geomspace = \[1e3, 3e5, \d+\]", f"geomspace = [1e3, 3e5, {points}]", text)
    if rates is not None:
        text, n = re.subn(r'"controller.rate" = \[[^\]]*\]', f'"controller.rate" = {[float(r) for r in rates]!r}', text)
        assert n == 1, "the example's controller.rate axis is not where it was"
    return re.sub(r'"trajectory.cycles" = \[[\d.]+\]', f'"trajectory.cycles" = [{cycles!r}]', text)


def run(points: int = 12, cycles: float = 1.0, workers: int = 2,
        rates: list[float] | None = None) -> tuple[str, int, pathlib.Path]:
    """Run the example; ``(stdout with the run time as T, exit code, folder with its outputs)``."""
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="sweep-example-"))
    (tmp / "paper-gains.toml").write_text(sweep_text(points, cycles, rates))
    r = subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "sweep", "paper-gains.toml", "--out", "out",
                        "--workers", str(workers)], capture_output=True, text=True, cwd=tmp)
    if r.returncode not in (0, 1):
        shutil.rmtree(tmp, ignore_errors=True)          # review 64: a failed sweep left its folder behind
        raise SystemExit(f"sweep failed (exit {r.returncode}): {r.stderr.strip().splitlines()[-1:]}")
    stdout = re.sub(r"\(\d+\.\d s\)", "(T s)", r.stdout).replace("wrote out/", "wrote paper-gains/")
    return stdout, r.returncode, tmp


def main(argv=None):
    ap = Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="analysis-output/sweep-example",
                    help="output folder (default analysis-output/sweep-example, ignored by git; "
                         "docs/figures/sweep-example for the page)")
    ap.add_argument("--workers", type=positive(int), default=2, help="worker processes (default 2)")
    ap.add_argument("--points", type=positive(int), default=12,
                    help="stiffnesses from 1e3 to 3e5 N/m (default 12, the file's)")
    ap.add_argument("--cycles", type=positive(), default=1.0, help="path cycles per case (default 1, the file's)")
    ap.add_argument("--rates", type=numbers, default=None,
                    help="control rates, Hz, comma-separated (default the file's 2000,1000,500,250)")
    args = ap.parse_args(argv)
    out = OutputFolder(args.out, "--out")
    stdout, code, tmp = run(args.points, args.cycles, args.workers, args.rates)
    try:
        with out:
            (out.path / "output.txt").write_text(stdout + f"exit code: {code}\n")
            for name in ("sweep_map.png", "summary.json"):
                shutil.copy(tmp / "out" / name, out.path / name)
            out.commit()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(stdout + f"exit code: {code}")
    print(f"wrote {out.out}/")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_study(main))
