"""The user guide: every page is in the mkdocs nav, every nav entry exists,
relative links resolve, and the README links the guide."""
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def nav_files():
    text = (ROOT / "mkdocs.yml").read_text()
    return re.findall(r":\s*([\w./-]+\.md)\s*$", text, flags=re.M)


def test_nav_matches_pages():
    pages = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert set(nav_files()) == pages


def test_relative_links_resolve():
    for page in list((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]:
        for target in re.findall(r"\]\(([^)#:]+\.md)(?:#[^)]*)?\)", page.read_text()):
            assert (page.parent / target).exists(), f"{page.name} -> {target}"


def _anchors(page: pathlib.Path) -> set[str]:
    """The ids of ``page``'s headings as the guide's builder makes them: mkdocs renders with
    Python-Markdown, whose toc extension slugifies a heading's rendered text (``slugify``, the
    library's own) and numbers repeats ``_1``, ``_2``, ..."""
    from markdown.extensions.toc import slugify

    out, fenced = set(), False
    for line in page.read_text().splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif not fenced and (m := re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)):
            text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(1))         # a link renders as its text
            slug = slugify(re.sub(r"[`*_]", "", text), "-")
            n, base = 0, slug
            while slug in out:
                n += 1
                slug = f"{base}_{n}"
            out.add(slug)
    return out


def test_every_anchor_a_link_names_exists():
    """Review 51: four links named headings renamed since (``deploy.md#on-a-6-d-arm-ur5-panda-your-urdf``
    from three pages, ``cli.md#analyze``), which ``mkdocs build`` reported and no test did. Every
    ``page.md#anchor`` and ``#anchor`` link of the guide and the README names a heading's id."""
    broken = []
    for page in sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]:
        for target, anchor in re.findall(r"\]\(([^)#:\s]*?\.md)?#([^)\s]+)\)", page.read_text()):
            if anchor not in _anchors(page.parent / target if target else page):
                broken.append(f"{page.name} -> {target}#{anchor}")
    assert broken == []


def test_readme_links_the_guide_and_quickstart_contract():
    readme = (ROOT / "README.md").read_text()
    assert "docs/index.md" in readme
    assert "pip install . && tmtcontrol simulate" in readme
    assert "pip install '.[test]' && pytest" in readme


def test_cli_reference_lists_every_command():
    from tmtcontrol.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    text = (ROOT / "docs" / "cli.md").read_text()
    for name in sub.choices:
        assert f"`tmtcontrol {name}" in text, name


def test_scenario_reference_is_generated_from_the_schema():
    import pathlib

    from tmtcontrol.simulation.scenario import scenario_reference

    text = (pathlib.Path(__file__).parents[1] / "docs" / "scenario.md").read_text()
    block = text.split("do not edit -->\n")[1].split("<!-- end of generated reference -->")[0]
    assert block == scenario_reference()


def test_api_package_map_lists_every_module_and_only_those():
    """docs/api.md's package map against the package: a module added, renamed
    or removed without the map fails (the law and scenario packages are listed
    as one entry each)."""
    pkg = ROOT / "tmtcontrol"
    grouped = ("control.laws", "simulation.scenario")
    actual = set()
    for f in pkg.rglob("*.py"):
        name = ".".join(f.relative_to(pkg).with_suffix("").parts)
        if name.endswith("__init__"):
            continue
        actual.add(next((g for g in grouped if name.startswith(g + ".")), name))
    text = (ROOT / "docs" / "api.md").read_text().split("## Package map", 1)[1]
    listed = set(re.findall(r"^\| `([\w.]+)` \|", text, flags=re.M))
    assert listed == actual, (sorted(actual - listed), sorted(listed - actual))


def _bench_report():
    from conftest import load_benchmark

    return load_benchmark("bench_report")


def test_speed_page_quotes_the_recorded_report_benchmark():
    """docs/speed.md's table of issue 42's targets is the one benchmarks/bench_report.py
    printed and recorded (benchmarks/report_results.json): a new record, or an edited
    figure on the page, fails here until the two agree."""
    import json

    bench = _bench_report()
    record = json.loads((ROOT / "benchmarks" / "report_results.json").read_text())
    table = bench.markdown_table(record)
    assert table in (ROOT / "docs" / "speed.md").read_text()
    # the comparison the rows print: a changed figure is found, the same figures are not
    assert bench.compared(["PASS  limit 163,417 N/m"], ["PASS  limit 163,417 N/m"]).endswith("record 0")
    assert "1e-06" in bench.compared(["PASS  limit 100,000.1 N/m"], ["PASS  limit 100,000 N/m"])
    assert bench.compared(["PASS  a"], ["FAIL  a"]).startswith("changed")


def test_sweep_throughput_quoted_is_the_recorded_benchmark():
    """docs/sweeps.md and docs/speed.md quote benchmarks/bench_sweep.py's paragraph of its
    recorded run (benchmarks/sweep_results.json; regenerate with ``python
    benchmarks/bench_sweep.py``): a new record, or an edited figure, fails here until they agree.
    The record itself says the three engines gave identical rows."""
    import json

    from conftest import load_benchmark

    bench = load_benchmark("bench_sweep")
    record = json.loads((ROOT / "benchmarks" / "sweep_results.json").read_text())
    assert record["identical"] is True and record["cases"] >= 1000
    text = bench.paragraph(record)
    for page in ("sweeps.md", "speed.md"):
        assert text in (ROOT / "docs" / page).read_text(), page
    # the paragraph shows the figures it is given: a changed rate is a changed paragraph
    changed = json.loads(json.dumps(record))
    changed["puma560"]["2 workers"] *= 1.01
    assert bench.paragraph(changed) != text


def test_the_reference_states_each_elements_bounds_that_the_schema_enforces():
    """Review 23: docs/scenario.md gave the range "–" for impedance.m, b, k, kd, kp and the rotational
    gains (fixed-length or optional tuples), which the schema bounds (impedance.m = [2e4, 1, 1]:
    "must be <= 10000"). Each bound the reference states now, the schema refuses just past it and
    accepts at it."""
    import re

    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.simulation.scenario import ScenarioError, scenario_reference

    text = scenario_reference()
    section = text[text.index("**[impedance]**"):]
    checked = 0
    for key in ("m", "b", "k", "kd", "kp", "m_rot", "b_rot", "k_rot"):
        row = next(line for line in section.splitlines() if line.startswith(f"| `{key}` |"))
        for op, bound in re.findall(r"each (≥|>|≤) ([0-9.e+-]+)", row):
            bound = float(bound)
            past = {"≥": bound - 1e-6 * max(1.0, abs(bound)), ">": bound,
                    "≤": bound * (1 + 1e-6)}[op]
            with pytest.raises(ScenarioError, match=rf"^impedance\.{key}"):
                apply_overrides(paper_scenario(), [f"impedance.{key}=[{past!r}, 1.0, 1.0]"])
            if op != ">":
                apply_overrides(paper_scenario(), [f"impedance.{key}=[{bound!r}, 1.0, 1.0]"])
            checked += 1
    assert checked >= 11          # m and k two bounds each, b two, kd, kp and the three rotational ones


def test_the_reference_states_optional_bounds_and_the_laws_units():
    """Review 51: ``requirements.first_contact_overshoot`` showed range "–" though 0 <= x <= 1000 is
    enforced (an optional bounded number's bounds sit inside its union), and the laws' parameters
    showed unit "–" beside "N" or "N/m" in their own meaning. Each bound the schema enforces on an
    optional number is in its row; a row whose meaning ends in a unit names it in the unit column."""
    from tmtcontrol.simulation.scenario import scenario_reference

    rows = [r.split(" | ") for r in scenario_reference().splitlines() if r.startswith("| `")]
    overshoot = next(r for r in rows if r[0] == "| `first_contact_overshoot`")
    assert overshoot[3] == "≥ 0, ≤ 1000"
    unit = re.compile(r", (N/m|N|m/\(N s\))(?: \|)?$")
    with_unit = [(r[1], m.group(1)) for r in rows if (m := unit.search(r[-1].split(";")[0]))]
    assert len(with_unit) >= 9 and all(shown == said for shown, said in with_unit), with_unit


def test_the_force_filters_quoted_response_is_its_own():
    """docs/scenario.md quotes the discrete filter's -3 dB points and its gain at the Nyquist
    frequency (review 22): recomputed here from the package's pole, |H| = (1 - a)/|1 - a e^(-jw)|,
    on a 0.0025 Hz grid, and the cut-off above which it never falls 3 dB, (1 - a)/(1 + a) = 1/sqrt 2."""
    import numpy as np
    from scipy.optimize import brentq

    from tmtcontrol.simulation.scenario import SensorSettings

    text = " ".join((ROOT / "docs" / "scenario.md").read_text().split())
    Ts = 1e-3
    pole = lambda fc: SensorSettings(filter_cutoff=fc).pole(Ts)
    f = np.linspace(1.0, 500.0, 200_000)

    def gain_db(fc):
        a = pole(fc)
        return 20 * np.log10((1 - a) / np.abs(1 - a * np.exp(-2j * np.pi * f * Ts)))

    corner = lambda fc: f[np.argmax(gain_db(fc) <= -10 * np.log10(2))]
    assert f"({corner(100.0):.1f} Hz for 100 Hz at 1 kHz, {corner(200.0):.1f} Hz for 200 Hz;" in text
    edge = brentq(lambda fc: (1 - pole(fc)) / (1 + pole(fc)) - 2 ** -0.5, 100.0, 499.0) / 500.0
    assert f"from {edge:.3f} of the Nyquist frequency up it never falls 3 dB: {gain_db(300.0)[-1]:.2f} dB" in text


def test_design_example_on_the_page_is_what_design_prints(capsys):
    """docs/design.md quotes the output of its example command: the block
    below the command line must be what the command prints now (it went stale
    when the limits came to be rounded down, review 47)."""
    from tmtcontrol.cli import main

    text = (ROOT / "docs" / "design.md").read_text()
    cmd = "tmtcontrol design --m 1 --k 100 --ke-min 2000 --ke-max 20000 --ts 0.001 --max-overshoot 5"
    block = text.split(f"    $ {cmd}\n")[1].split("\n\n")[0]
    quoted = [line[4:] for line in block.splitlines()]
    assert main(cmd.split()[1:]) == 0
    assert capsys.readouterr().out.splitlines() == quoted


def _is_heavy(node) -> bool:
    """Whether a decorator list or a module's ``pytestmark`` names ``pytest.mark.heavy``."""
    import ast

    return any("mark.heavy" in ast.unparse(d) and "pytest.param" not in ast.unparse(d) for d in node)


def test_every_command_keeps_a_test_in_the_readmes_command():
    """docs/testing.md's table: every CLI command has a test in the README's
    `pytest` (not behind the heavy marker, which only .ci/run's second step
    runs), and each test it names exists in the file it names."""
    import ast

    from tmtcontrol.cli import build_parser

    text = (ROOT / "docs" / "testing.md").read_text()
    table = text.split("| command | test in the README's command |")[1].split("\n\n")[0]
    rows = re.findall(r"^\| `([^`]+)` \| `([^`]+)` \|$", table, flags=re.M)
    assert len(rows) == table.count("\n| `")
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) <= {command.split()[0] for command, _ in rows}
    for command, node_id in rows:
        path, name = node_id.split("::")
        tree = ast.parse((ROOT / path).read_text())
        marks = [n.value for n in tree.body if isinstance(n, ast.Assign)
                 and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in n.targets)]
        assert not _is_heavy(marks), path
        fn = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name), None)
        assert fn is not None, node_id
        assert not _is_heavy(fn.decorator_list), f"{node_id} is behind the heavy marker ({command})"
