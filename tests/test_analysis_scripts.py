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


BAD = [
    ("damping_comparison.py", ["--cycles", "0"], "--cycles"),
    ("paper_figures.py", ["--cycles", "-1"], "--cycles"),
    ("law_comparison.py", ["--x-e-error", "nan"], "--x-e-error"),
    ("noise.py", ["--sigmas", "0.1,abc"], "--sigmas"),
    ("noise.py", ["--sigmas", "0,0.1"], "--sigmas"),          # σ = 0 is the settling column's run, not a cell
    ("first_contact.py", ["--points", "0"], "--points"),      # wrote an empty study, exit 0
    ("first_contact.py", ["--gap", "nan"], "--gap"),
    ("sweep_example.py", ["--workers", "0"], "--workers"),
    ("transient_growth.py", ["--cycles", "1"], "--cycles"),
    ("regenerate_robots.py", ["--from", "no-such-folder"], "--from"),
]


@pytest.mark.parametrize("name, args, flag", BAD, ids=[f"{n}{' '.join(a)}" for n, a, _ in BAD])
def test_bad_input_to_a_study_is_one_line_naming_the_flag(name, args, flag, tmp_path):
    """Review 64: seven of the eight studies answered bad numbers with a Python traceback and exit 1
    (``first_contact.py --points 0`` wrote an empty study and exited 0). As tmtcontrol's commands: one
    line naming the flag, exit 2, nothing written."""
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "analysis" / name), "--out", str(out), *args],
                       capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert (r.returncode, len(r.stderr.splitlines())) == (2, 1), r.stderr
    assert r.stderr.startswith("error: ") and flag in r.stderr and not out.exists(), r.stderr


@pytest.mark.parametrize("name, args", [("paper_figures.py", ["--cycles", "0.05"]),
                                        ("regenerate_robots.py", ["--from", str(ROOT / "tmtcontrol" / "model" /
                                                                                 "data")])])
def test_a_study_never_overwrites_a_file_it_did_not_write(name, args, tmp_path):
    """Review 64: regenerate_robots.py wrote over a user's ur5.urdf in --out without a word; the other
    studies refused such a folder with a traceback. One line naming --out, exit 2, the file untouched."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "ur5.urdf").write_text("my own file\n")
    r = subprocess.run([sys.executable, str(ROOT / "analysis" / name), "--out", str(out), *args],
                       capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert (r.returncode, len(r.stderr.splitlines())) == (2, 1), r.stderr
    assert r.stderr.startswith("error: --out: ") and (out / "ur5.urdf").read_text() == "my own file\n"
    assert [p.name for p in out.iterdir()] == ["ur5.urdf"]


PAGE_TABLES = [("theory.md", "first_contact", "first-contact"), ("theory.md", "noise", "noise")]


@pytest.mark.parametrize("page, block, folder", PAGE_TABLES)
def test_the_pages_tables_are_the_ones_their_studies_wrote(page, block, folder):
    """Review 64: docs/theory.md's first-contact and noise tables had no drift test (a changed digit failed
    nothing). Each is now a marked block equal to the table.md its study wrote into docs/figures/ (whose
    fresh regeneration the heavy test below compares)."""
    text = (ROOT / "docs" / page).read_text()
    quoted = text.split(f"<!-- {block}:", 1)[1].split("-->\n", 1)[1].split(f"<!-- end {block} -->")[0]
    assert quoted == (ROOT / "docs" / "figures" / folder / "table.md").read_text()


@pytest.mark.heavy      # the studies at their documented sizes: ~5-25 s each
@pytest.mark.parametrize("name, folder", [("first_contact.py", "first-contact"), ("noise.py", "noise"),
                                          ("law_comparison.py", "law-comparison")])
def test_a_fresh_run_of_each_study_writes_the_published_table(name, folder, tmp_path):
    """Review 64: the published tables were compared with the table.md committed beside them, never with
    what the study prints today (a stale table.md and page passed together). A fresh run at the
    documented size writes the same table.md, character for character."""
    r = subprocess.run([sys.executable, str(ROOT / "analysis" / name), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out" / "table.md").read_text() == (ROOT / "docs" / "figures" / folder / "table.md").read_text()


@pytest.mark.heavy      # eight laws and treatments, a second each, twice
def test_the_noise_study_writes_json_without_nan_and_says_why_a_cell_is_empty(tmp_path):
    """Review 67: a run of one segment has no switch to settle after: the study wrote NaN into summary.json
    (not JSON; json.dumps's default= is never called for a float) and "nan" into its table. Null and a
    cell that says why."""
    import json

    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(ROOT / "analysis" / "noise.py"), "--out", str(out), "--cycles", "0.25",
                        "--sigmas", "0.1"], capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr

    def refuse(constant):
        raise AssertionError(f"{constant} in summary.json")

    rows = json.loads((out / "summary.json").read_text(), parse_constant=refuse)["rows"]
    assert rows["tmt"]["settling_s_without_noise"] is None
    assert "| – (no switch in the run) |" in (out / "table.md").read_text() and "nan" not in r.stdout
