"""Every script in analysis/ runs (smoke level, small sizes)."""
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

SCRIPTS = {
    "paper_figures.py": ["--cycles", "0.5"],
    "damping_comparison.py": ["--cycles", "0.5"],
    "law_comparison.py": ["--cycles", "0.25"],
    "first_contact.py": ["--points", "2"],
    "noise.py": ["--cycles", "0.5", "--sigmas", "0.2"],
    "regenerate_robots.py": ["--from", str(ROOT / "tmtcontrol" / "model" / "data")],
    "sweep_example.py": ["--points", "2", "--cycles", "0.25", "--workers", "1", "--rates", "1000"],
    "transient_growth.py": ["--cycles", "2"],
}


def test_every_script_is_listed():
    assert {p.name for p in (ROOT / "analysis").glob("*.py")} == set(SCRIPTS)


HEAVY = {"damping_comparison.py", "sweep_example.py", "transient_growth.py", "law_comparison.py", "noise.py"}
"""Scripts run by the heavy step, which .ci/run also runs (the damping comparison: ~7 s; the sweep example:
~7 s; the transient growth's two periodic searches: ~12 s; the noise study: 2.4 s)."""


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.heavy) if n in HEAVY else n for n in sorted(SCRIPTS)])
def test_script_runs(name, tmp_path):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "analysis" / name), "--out", str(out), *SCRIPTS[name]],
                       capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    produced = list(out.iterdir())
    assert produced and all(p.stat().st_size > 0 for p in produced)
