"""docs/api.md runs as written (issue: docs that cannot rot).

Every ```python block of the page, in order, in one namespace, statement by
statement, in a fresh folder: a statement that fails names its block and
line. Heavy: the page builds a report, compiles the exported C and runs every
law (about a minute); ``.ci/run`` runs it after the default suite.
"""

import ast
import pathlib
import re

import pytest

PAGE = pathlib.Path(__file__).resolve().parents[1] / "docs" / "api.md"


def blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)


def test_the_page_has_code_and_every_block_parses():
    code = blocks()
    assert len(code) >= 5
    for i, block in enumerate(code, 1):
        ast.parse(block, filename=f"api.md block {i}")


@pytest.mark.heavy
def test_every_statement_of_api_md_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": "api_md"}
    for i, block in enumerate(blocks(), 1):
        for node in ast.parse(block).body:
            source = ast.get_source_segment(block, node)
            try:
                exec(compile(ast.Module([node], []), f"api.md block {i}", "exec"), namespace)
            except Exception as exc:           # noqa: BLE001 - the statement, not the exception, is the news
                pytest.fail(f"docs/api.md block {i}, line {node.lineno}: {source!r} raised "
                            f"{type(exc).__name__}: {exc}")
    assert (tmp_path / "review" / "report.html").is_file() and (tmp_path / "out" / "fig4_force.png").is_file()
