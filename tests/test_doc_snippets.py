"""The Python in the docs runs as written (issue: docs that cannot rot).

Every page's ```python blocks, in order, in one namespace, statement by
statement, in a fresh folder holding a copy of ``docs/`` (pages read the
bundled sweep file) and in a process of their own (a page may register a
law). A statement that fails names its page, block and line. Heavy: the
pages build a report, compile the exported C and run every law (about a
minute and a half); ``.ci/run`` runs them after the default suite.
"""

import ast
import pathlib
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs"
PAGES = sorted(p.name for p in DOCS.glob("*.md") if "```python" in p.read_text())

RUNNER = textwrap.dedent('''
    import ast, json, sys, traceback
    blocks = json.load(sys.stdin)
    ns = {"__name__": "doc_page"}
    for i, block in enumerate(blocks, 1):
        for node in ast.parse(block).body:
            try:
                exec(compile(ast.Module([node], []), f"block {i}", "exec"), ns)
            except Exception as exc:
                src = ast.get_source_segment(block, node)
                print(f"block {i}, line {node.lineno}: {src!r} raised {type(exc).__name__}: {exc}", file=sys.stderr)
                sys.exit(1)
''')


def blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), flags=re.S)


def test_the_pages_with_python_are_the_known_ones_and_every_block_parses():
    assert PAGES == ["api.md", "laws.md", "robots.md", "simulation.md", "sweeps.md"]
    for page in PAGES:
        for i, block in enumerate(blocks(page), 1):
            ast.parse(block, filename=f"{page} block {i}")


@pytest.mark.heavy
@pytest.mark.parametrize("page", PAGES)
def test_every_statement_of_the_page_runs(page, tmp_path):
    import json
    import os

    shutil.copytree(DOCS, tmp_path / "docs")
    r = subprocess.run([sys.executable, "-c", RUNNER], input=json.dumps(blocks(page)), capture_output=True,
                       text=True, cwd=tmp_path, env={**os.environ, "MPLBACKEND": "Agg"}, timeout=900)
    assert r.returncode == 0, f"docs/{page}: {r.stderr.strip().splitlines()[-1:]}"
    if page == "api.md":
        assert (tmp_path / "review" / "report.html").is_file() and (tmp_path / "out" / "fig4_force.png").is_file()
