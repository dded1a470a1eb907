"""The stability report: sections in order, verdicts with the numbers of the
tables behind them, numbered figures and tables with captions, only the
scenario keys that apply, a self-contained HTML and a paginated PDF made
from it, FAIL where a configuration fails, formatting by meaning."""
import html as htmllib
import math
import re
import subprocess
import sys

import pytest

import pypdf  # in the "test" extra

from tmtcontrol.report.document import Table

SECTIONS = ["summary", "scenario", "derivations", "continuous", "sampled", "simulation", "comparison", "sweep",
            "design", "reproducibility"]


def make_report(out, *args):
    return subprocess.run([sys.executable, "-m", "tmtcontrol.cli", "report", *args, "--out", str(out)],
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def paper_report(run_once):
    out, r = run_once("paper-report", lambda out: make_report(out, "paper"))
    # the paper claims a stable loop whose force converges, and the report judges that: it passes (exit 0);
    # the 54.8 % first-contact overshoot of b = 60 N s/m is shown, not judged (no requirement stated)
    assert r.returncode == 0, r.stderr
    return out, r


@pytest.fixture(scope="module")
def unstable_report(run_once):
    # Ts = 5 ms cannot hold 5e4 N/m with the paper gains (limit ~3.2e4 N/m)
    out, r = run_once("unstable-report", lambda out: make_report(
        out, "paper", "--set", "controller.rate=200", "--set", "environment.stiffness.values=[5e3, 5e4]",
        "--set", "trajectory.cycles=2", "--format", "html"))
    assert r.returncode == 1, r.stderr       # a report with a FAIL verdict exits 1
    return out, r


def section(html: str, key: str) -> str:
    return html.split(f'<section id="{key}">')[1].split("</section>")[0]


def tables(html: str) -> list[tuple[str, list[str], list[list[str]]]]:
    """(caption, header cells, body rows) of every table, text unescaped."""
    def text(cell):
        return htmllib.unescape(re.sub(r"<[^>]+>", "", cell)).strip()

    out = []
    for t in re.findall(r"<table.*?</table>", html, flags=re.S):
        cap = text(re.search(r"<caption>(.*?)</caption>", t, flags=re.S).group(1))
        head = [text(c) for c in re.findall(r"<th[^>]*>(.*?)</th>", t, flags=re.S)]
        body = t.split("<tbody>")[1]
        rows = [[text(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", row, flags=re.S)]
                for row in re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)]
        out.append((cap, head, rows))
    return out


def table(html: str, caption_part: str):
    return next(t for t in tables(html) if caption_part in t[0])


def number(text: str) -> float:
    """The first number in ``text`` as the report prints it (thousands
    separators, a minus sign, SI prefixes of N)."""
    m = re.search(r"([−-]?[\d,]+(?:\.\d+)?)\s*(µN|mN|N)?", text)
    scale = {"µN": 1e-6, "mN": 1e-3, "N": 1.0, None: 1.0}[m.group(2)]
    return float(m.group(1).replace(",", "").replace("−", "-")) * scale


@pytest.mark.heavy
def test_progress_by_stage_with_stage_times(paper_report):
    _, r = paper_report
    stages = re.findall(r"^\[(\d)/(\d)\] ([a-zA-Z -]+): (\d+\.\d) s$", r.stderr, flags=re.M)
    assert [int(s[0]) for s in stages] == list(range(1, 10)) and {s[1] for s in stages} == {"9"}
    assert [s[2] for s in stages][-2:] == ["writing HTML", "writing PDF"]
    assert "derivation checks" in [s[2] for s in stages]


@pytest.mark.heavy
def test_sections_in_order_with_a_contents_list(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    assert re.findall(r'<section id="(\w+)"', html) == SECTIONS
    toc = html.split('<nav class="toc"')[1].split("</nav>")[0]
    assert re.findall(r'href="#(\w+)"', toc) == SECTIONS


@pytest.mark.heavy
def test_verdicts_carry_the_numbers_of_the_tables(paper_report):
    out, r = paper_report
    html = (out / "report.html").read_text()
    _, head, rows = table(section(html, "summary"), "Verdicts")
    assert head == ["verdict", "result", "number", "computed by"]
    verdicts = {row[0]: row for row in rows}
    assert [row[1] for row in rows] == ["✔ PASS"] * 4 and r.stdout.count("PASS ") == 4
    # in the order of the stages behind them, whichever process ran each stage; no overshoot verdict: the
    # paper scenario states no requirements.first_contact_overshoot, and the PUMA no limits
    assert [row[0] for row in rows] == ["Derivation checks pass", "BIBO stable in continuous time (eq. 22)",
                                        "Stable in the sampled implementation (Ts = 1\xa0ms)",
                                        "Force tracking within tolerance (simulation)"]
    design = section(html, "design")
    assert "54.8 %" in design and "Not judged" in design and "requirements.first_contact_overshoot" in design
    # derivation checks: n/N = the PASS rows of the checks table
    _, _, check_rows = table(section(html, "derivations"), "Derivation checks")
    n = len(check_rows)
    assert n > 13 and verdicts["Derivation checks pass"][2] == f"{n}/{n} pass"
    # sampled (issue 28): the verdict's limit is the models table's decisive row, the smaller of the limit
    # along the path and the one from first contact, shown beside the frozen-point minimum and the 1-D limit
    _, _, models = table(section(html, "sampled"), "the models")
    row = lambda start: number(next(r for r in models if r[0].startswith(start))[1])
    whole, periodic, first = row("whole-loop"), row("along the moving path (periodic orbit"), row("from first")
    sampled = next(v for k, v in verdicts.items() if k.startswith("Stable in the sampled"))
    assert number(sampled[2].split("largest stable stiffness")[1]) == row("decisive") == min(periodic, first)
    assert "limit from first contact" in sampled[3] and "monodromy" in sampled[3]
    assert 1.5e5 < whole < 1.8e5                      # measured 1.636e5 N/m (1 kHz, paper gains)
    # the simulated limit is 1.672e5 N/m (issue 28: the frozen minimum 2.2 % below it, the periodic one within
    # 1 %, tested against bisection in tests/test_limits.py); x_e error 0: the start settles up to it
    assert whole < periodic and periodic == pytest.approx(1.672e5, rel=0.01) and first == periodic
    assert 1.5e5 < row("1-D") < 1.8e5
    # tracking: the verdict's worst error is the largest of the segment table's
    _, seg_head, segs = table(section(html, "simulation"), "Per-segment metrics")
    col = seg_head.index("steady-state |f_e − f_d|")
    worst = max(number(row[col]) for row in segs)
    track = verdicts["Force tracking within tolerance (simulation)"][2]
    assert number(track.split("|f_e − f_d|")[1]) == pytest.approx(worst, rel=1e-9)
    assert len(segs) == 4 and all(row[-1] == "✔ converged" for row in segs)


@pytest.mark.heavy
def test_segment_table_shows_the_contact_lost_behind_a_100_percent_overshoot(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    _, head, segs = table(section(html, "simulation"), "Per-segment metrics")
    lost, over = head.index("contact lost"), head.index("overshoot")
    # the switches up (5e3 -> 2e4 and 2e3 -> 1e4 N/m) overshoot the penetration: the force falls to
    # zero for a while; the first segment starts at zero force (x = x_e) and is not a loss
    assert [row[lost] != "no" for row in segs] == [False, True, False, True]
    assert all((number(row[over]) == 100.0) == (row[lost] != "no") for row in segs)
    assert all(row[lost].endswith("ms") for row in segs if row[lost] != "no")
    # review 15: the RMS over a whole segment is 3.6-11.4 um, over its last quarter 3.26 um: the column says which
    assert "tangential RMS (last quarter)" in head


@pytest.mark.heavy
def test_law_comparison_says_which_laws_settle_on_f_d(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    _, head, rows = table(section(html, "comparison"), "Force-tracking laws")
    err, within = head.index("worst steady-state error"), head.index("within 10\xa0mN")
    assert len(rows) == 5 and all((row[within] == "yes") == (number(row[err]) <= 0.01) for row in rows)
    by_law = {row[0].split()[0]: row for row in rows}
    # "known" settles (converged) on the force its nominal k_e gives, not on f_d (eqs. 11-12)
    assert by_law["known"][within] == "no" and by_law["known"][-1] == "◐ off target"
    assert by_law["tmt"][within] == "yes"
    # review 15: the known law ends segment 3 (2,000 N/m) at 9.714 N, 2.9 % off f_d, never inside the 2 % band
    # (its own compare line: "settle 10 mN: never"); the column said 233 ms, segment 2's, as Python's max
    # skipped the NaN after it
    settle = head.index("worst settling 2 %")
    assert by_law["known"][settle] == "never" and by_law["tmt"][settle] != "never"


@pytest.mark.heavy
def test_design_tables_name_which_overshoot(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    assert "worst first-contact overshoot" in table(section(html, "design"), "Damping designs")[1]
    assert "worst overshoot after a switch" in table(section(html, "design"), "designs simulated")[1]


@pytest.mark.heavy
def test_reproducibility_lists_each_item_once(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    rows = table(section(html, "reproducibility"), "Reproducibility")[2]
    items = [row[0].lower() for row in rows]
    assert len(items) == len(set(items)) and "python" in items and "casadi" in items
    # review 60: the renderers that lay out the report are named with their installed versions (read here from
    # the distributions' metadata); review 63: the URDF parser only where a URDF was read (not the PUMA's),
    # MuJoCo only where its plant ran (not here)
    from importlib.metadata import version
    given = {row[0]: row[1] for row in rows}
    for dist in ("jinja2", "weasyprint"):
        assert given[dist] == version(dist), dist
    assert "mujoco" not in given and "urdfdom-py" not in given


@pytest.mark.parametrize("name, formats, listed, absent", [
    ("ur5", ("html",), ("jinja2", "urdfdom-py"), ("weasyprint", "mujoco")),
    ("paper", ("html", "pdf"), ("jinja2", "weasyprint"), ("urdfdom-py", "mujoco")),
    ("paper", "pdf", ("jinja2", "weasyprint"), ("urdfdom-py", "mujoco")),      # review 67: read as p, d, f
])
def test_reproducibility_names_what_made_this_report(name, formats, listed, absent):
    """Review 63 (6b): the reproducibility table listed the URDF parser for the PUMA (no URDF is read) and
    WeasyPrint for an HTML-only report (no PDF is laid out). Each is named where it ran, with its installed
    version."""
    from importlib.metadata import version

    from tmtcontrol import load_scenario
    from tmtcontrol.report.document import Report, finish

    rep = Report(load_scenario(name), "test")
    finish(rep, formats)
    (tab,) = [b for b in rep.sections[-1].blocks if isinstance(b, Table)]
    rows = dict(tab.rows)
    for dist in listed:
        assert rows[dist] == version(dist), dist
    assert not set(absent) & set(rows), rows


@pytest.mark.heavy
def test_unset_optional_keys_read_unset_not_none(paper_report):
    """Review 60: robot.tau_max and the other optional keys left unset printed Python's ``None`` in the scenario
    table; the meaning column says what the default is."""
    html = (paper_report[0] / "report.html").read_text()
    rows = table(section(html, "scenario"), "Scenario settings")[2]
    assert not [r for r in rows if r[1] == "None"]
    assert {r[0]: r[1] for r in rows}["robot.tau_max"] == "unset"


@pytest.mark.heavy
def test_every_figure_is_numbered_with_a_caption_and_inline_svg(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    figures = re.findall(r"<figure[^>]*>(.*?)</figure>", html, flags=re.S)
    # continuous 3, sampled 2 (the arm's normal mass, the limit against Ts), simulation 6 (the arm's still
    # included), law comparison 2, sweep 1, design 1 (the PUMA states no limits: no limits figure)
    assert len(figures) == 15
    assert len(re.findall(r"<img ", html)) == len(figures)          # no image outside a figure
    for i, f in enumerate(figures, 1):
        assert 'src="data:image/svg+xml;base64,' in f
        cap = re.search(r"<figcaption>(.*?)</figcaption>", f, flags=re.S).group(1)
        assert f"Figure {i}." in cap and len(re.sub(r"<[^>]+>", "", cap)) > 30
    caps = [c for c, _, _ in tables(html)]
    assert all(re.match(r"Table \d+\. \S", c) for c in caps)
    assert [int(re.match(r"Table (\d+)", c).group(1)) for c in caps] == list(range(1, len(caps) + 1))
    # self-contained: no scripts, no external references
    assert not re.search(r"https?://|<script|<link|@import|url\(", html)
    assert not re.search(r'(src|href)="(?!data:|#)', html)


@pytest.mark.heavy
def test_scenario_table_lists_only_applicable_keys_with_units(paper_report):
    html = (paper_report[0] / "report.html").read_text()
    _, head, rows = table(section(html, "scenario"), "Scenario settings")
    assert head == ["key", "value", "unit", "meaning"]
    keys = {row[0]: row for row in rows}
    for absent in ("controller.approach_speed", "controller.contact_threshold", "controller.force_ramp",
                   "sensor.seed", "simulation.tol", "environment.stiffness.mean", "controller.law.k_i",
                   # review 15: the PUMA's position-only task has no orientation and no posture task
                   "impedance.m_rot", "controller.orientation_tolerance", "trajectory.tool_spin_deg",
                   "robot.posture_kp"):
        assert absent not in keys
    assert keys["controller.rate"][1:3] == ["1,000", "Hz"]
    assert keys["environment.stiffness.values"][1:3] == ["[5,000, 20,000, 2,000, 10,000]", "N/m"]
    assert keys["controller.law.min_stiffness"][2] == "N/m"


def test_applicable_settings_follow_the_options():
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.simulation.scenario import applicable_settings

    keys = {r.key for r in applicable_settings(apply_overrides(paper_scenario(), [
        "trajectory.approach_gap=0.005", "sensor.noise_std=0.1", "simulation.integrator=\"cvodes\"",
        "controller.law=\"integral\"", "environment.stiffness.kind=\"sinusoidal\""]))}
    assert {"controller.approach_speed", "controller.force_ramp", "sensor.seed", "simulation.tol",
            "controller.law.k_i", "environment.stiffness.amplitude"} <= keys
    assert not {"simulation.substeps", "controller.law.min_stiffness", "environment.stiffness.values"} & keys


def test_applicable_settings_follow_the_arms_task():
    """Review 15: the report's table listed a 6-D arm's orientation keys and a redundant arm's posture keys
    for the 3-joint PUMA. With the arm's task, they apply only where the task has them: 3 joints (position
    only) neither, 6 joints (6-D, square) the orientation's, 7 joints (redundant) both; without a task, all."""
    from tmtcontrol import paper_scenario
    from tmtcontrol.model.robot import Task
    from tmtcontrol.simulation.scenario import applicable_settings

    rot, post = {"impedance.k_rot", "controller.orientation_tolerance", "trajectory.tool_spin_deg"}, \
        {"robot.posture_kp", "robot.posture_kd"}
    sc = paper_scenario()
    for task, want in ((Task(3, 3), set()), (Task(6, 6), rot), (Task(7, 6), rot | post), (None, rot | post)):
        keys = {r.key for r in applicable_settings(sc, task)}
        assert keys & (rot | post) == want, task


@pytest.mark.heavy
def test_pdf_is_the_same_document_paginated(paper_report):
    out = paper_report[0]
    html = (out / "report.html").read_text()
    reader = pypdf.PdfReader(str(out / "report.pdf"))
    n = len(reader.pages)
    assert n >= 10
    assert len({(round(float(p.mediabox.width)), round(float(p.mediabox.height))) for p in reader.pages}) == 1
    assert round(float(reader.pages[0].mediabox.width)) == 595          # A4
    pages = [p.extract_text() for p in reader.pages]
    for i, text in enumerate(pages, 1):
        assert f"Page {i} of {n}" in text
    text = re.sub(r"\s+", " ", "\n".join(pages))
    assert "Overall: ✔ PASS" in pages[0]        # the paper judged on what it claims (no requirement stated)
    # the contents list carries page numbers
    assert re.search(r"Simulation \.{5,} \d+", text)
    # every table's header row and caption, every figure's numbered caption
    caps = [cap for cap, _, _ in tables(html)]
    for i, (cap, head, _) in enumerate(tables(html)):
        label = cap.split(".")[0] + "."
        assert label in text
        # the header row follows the caption, in order (white space ignored: cells wrap, and the
        # PDF's text has plain spaces where the HTML has no-break ones, as in "10 mN")
        after = text.split(label, 1)[1]
        segment = after.split(caps[i + 1].split(".")[0] + ".", 1)[0] if i + 1 < len(caps) else after
        assert re.sub(r"\s", "", "".join(head)) in re.sub(r"\s", "", segment), (label, head)
    n_fig = len(re.findall(r"<figure", html))
    for i in range(1, n_fig + 1):
        assert f"Figure {i}." in text


@pytest.mark.heavy   # a second whole report (28 s), as the paper report's tests: CI's heavy step
def test_unstable_configuration_fails_with_growth_not_overshoot(unstable_report):
    out, r = unstable_report
    html = (out / "report.html").read_text()
    assert not (out / "report.pdf").exists()                   # --format html
    verdicts = {row[0]: row for row in table(section(html, "summary"), "Verdicts")[2]}
    sampled = next(v for k, v in verdicts.items() if k.startswith("Stable in the sampled"))
    assert sampled[1] == "✘ FAIL" and verdicts["Force tracking within tolerance (simulation)"][1] == "✘ FAIL"
    # the continuous proof still holds: that is the point of the sampled analysis
    assert verdicts["BIBO stable in continuous time (eq. 22)"][1] == "✔ PASS"
    limit = number(sampled[2].split("largest stable stiffness")[1])
    assert 2.5e4 < limit < 4e4                                  # measured ~3.2e4 N/m at 200 Hz
    _, head, segs = table(section(html, "simulation"), "Per-segment metrics")
    unsettled = [row for row in segs if row[-1] in ("✘ diverged", "◐ limit cycle")]
    assert unsettled and all(row[head.index("overshoot")].startswith("– (") for row in unsettled)
    assert "FAIL  Stable in the sampled implementation" in r.stdout


def test_bad_input_exit_2_nothing_written(tmp_path):
    out = tmp_path / "o"
    for args, key in ((["--set", "controller.rate=-1"], "controller.rate"), (["--format", "html,docx"], "--format")):
        r = make_report(out, "paper", *args)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert key in r.stderr and not out.exists()
    assert list(tmp_path.iterdir()) == []


class _NoPango:
    """A meta-path finder under which ``import weasyprint`` fails as it does
    on a machine without Pango: OSError from cffi's dlopen, at import."""

    def find_spec(self, name, path=None, target=None):
        import importlib.util

        return importlib.util.spec_from_loader(name, self) if name == "weasyprint" else None

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        raise OSError("cannot load library 'libpango-1.0-0': libpango-1.0-0: cannot open shared object file\n"
                      "Additionally, ctypes.util.find_library() did not manage to locate it")


def test_pdf_without_weasyprints_libraries_is_one_clear_error(monkeypatch, tmp_path):
    from tmtcontrol.report import RendererUnavailable, prepare_writing, render_pdf

    monkeypatch.delitem(sys.modules, "weasyprint", raising=False)
    monkeypatch.setattr(sys, "meta_path", [_NoPango(), *sys.meta_path])
    prepare_writing(("html",))                       # the HTML needs no PDF engine
    for call in (lambda: prepare_writing(("html", "pdf")), lambda: render_pdf("<p>x</p>", tmp_path / "r.pdf")):
        with pytest.raises(RendererUnavailable) as err:
            call()
        msg = str(err.value)
        assert "\n" not in msg and msg.startswith("--format pdf:") and "libpango-1.0-0" in msg
        assert "docs/install.md" in msg and "--format html" in msg
    assert isinstance(err.value, ValueError)          # the command line's one-line exit 2
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value, sig, text", [
    (163559.0, 3, "164,000"), (12.5, 3, "12.5"), (0.0312, 3, "0.0312"), (3.14159e-5, 2, "3.1\u00a0×\u00a010⁻⁵"),
    (-30.0, 3, "−30"), (1e10, 3, "1\u00a0×\u00a010¹⁰"), (9.996e-4, 3, "1\u00a0×\u00a010⁻³"), (0.0, 3, "0"),
    (float("nan"), 3, "–"), (float("inf"), 3, "∞"), (1234, 3, "1,234")])
def test_numbers_formatted_by_meaning(value, sig, text):
    from tmtcontrol.fmt import num

    assert num(value, sig) == text


@pytest.mark.parametrize("value, unit, text", [
    (0.001, "s", "1\u00a0ms"), (1.63e-4, "N", "163\u00a0µN"), (0.01, "N", "10\u00a0mN"), (1000.0, "Hz", "1\u00a0kHz"),
    (163559.0, "N/m", "164,000\u00a0N/m"), (2.5, "1", "2.5"), (float("nan"), "s", "–")])
def test_quantities_with_si_prefixes(value, unit, text):
    from tmtcontrol.fmt import qty

    assert qty(value, unit) == text


def test_an_unstable_continuous_loop_shows_its_growth_rate():
    from tmtcontrol.report.document import _response
    from tmtcontrol.stability import analyze_continuous

    stable = analyze_continuous(1.0, 60.0, 100.0, 2e4, 10.0)
    over, settle = _response(stable)
    assert over.endswith("%") and settle.endswith("s")
    unstable = stable.__class__(**{**stable.__dict__, "bibo_stable": False,
                                   "poles": stable.poles * -1, "overshoot_pct": 1e72})
    over, settle = _response(unstable)
    growth = float(max(unstable.poles.real))
    assert over.startswith("unstable") and f"{growth:.0f}" in over and "%" not in over and settle == "–"
    assert math.isfinite(growth) and growth > 0


def test_the_worst_of_a_column_is_nan_when_any_segment_is():
    from tmtcontrol.report.document import _worst

    nan = float("nan")
    assert _worst([0.2, nan, 0.1]) != _worst([0.2, nan, 0.1]) and _worst([nan, 0.2]) != _worst([nan, 0.2])
    assert _worst([0.2, 0.3, 0.1]) == 0.3


def test_worst_settling_counts_a_segment_that_never_settles():
    from types import SimpleNamespace

    from tmtcontrol.report.document import _worst_settling

    assert _worst_settling([SimpleNamespace(settling_time=0.12), SimpleNamespace(settling_time=0.3)]) == "300\u00a0ms"
    assert _worst_settling([SimpleNamespace(settling_time=0.12), SimpleNamespace(settling_time=float("nan"))]) \
        == "never"


@pytest.mark.parametrize("formats, files, stages", [
    (("pdf",), ["report.pdf"], ["rendering HTML", "writing PDF"]),
    (("html",), ["report.html"], ["writing HTML"]),
    (("html", "pdf"), ["report.html", "report.pdf"], ["writing HTML", "writing PDF"])])
def test_writing_stages_match_the_formats(tmp_path, formats, files, stages):
    # the command numbers its stages with writing_stages(): every call must be counted
    from tmtcontrol import paper_scenario
    from tmtcontrol.report import Report, write_report, writing_stages

    seen = []
    written = write_report(Report(paper_scenario(), "test"), tmp_path, formats,
                           progress=lambda name, s: seen.append(name))
    assert seen == stages and len(seen) == writing_stages(formats)
    assert sorted(p.name for p in written) == sorted(p.name for p in tmp_path.iterdir()) == files


# -- verdicts both ways, on the stage functions ---------------------------------------------

def _stage_report(*overrides):
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import Report
    from tmtcontrol.stability import scenario_parameters

    sc = apply_overrides(paper_scenario(), list(overrides))
    return Report(sc, "test"), sc, scenario_parameters(sc)


@pytest.mark.parametrize("failing", [0, 1])
def test_checks_verdict_fails_when_a_check_fails(failing):
    from tmtcontrol.checks.derivations import CheckResult
    from tmtcontrol.report.document import _checks

    rep, _, _ = _stage_report()
    results = [CheckResult(f"check {i}", "eq. (1)", "claim", "method", 0.0, i >= failing, 1e-9, "")
               for i in range(3)]
    _checks(rep, results)
    (v,) = rep.verdicts
    assert v.name == "Derivation checks pass" and v.passed is (failing == 0)
    assert v.value == f"{3 - failing}/3 pass"


def test_force_verdict_fails_on_a_converged_but_biased_run():
    # the known law with k_e assumed 50 % high converges f_d (1 - k_eff(5e3)/k_eff(7.5e3))
    # = 0.065 N off f_d (eqs. 11-12): above the 0.01 N tolerance, so the verdict fails
    # with that number (steady state within 2e-3 N, as in test_simulate)
    from tmtcontrol.control.laws.tmt import k_eff
    from tmtcontrol import fmt
    from tmtcontrol.report.document import FORCE_TOLERANCE, _simulation

    assert FORCE_TOLERANCE == 0.01
    rep, sc, p = _stage_report("controller.law=known", "controller.law.assumed_stiffness=7500",
                               "trajectory.cycles=1", "environment.stiffness.values=[5e3]")
    _simulation(rep, sc, p)
    (v,) = rep.verdicts
    assert not v.passed and "segment 1 off_target" in v.check
    worst = rep.data["simulation"]["segments"][0].steady_state_error
    assert worst == pytest.approx(10 * (1 - k_eff(100, 5e3) / k_eff(100, 7.5e3)), abs=2e-3)
    assert v.value.startswith(f"worst steady-state |f_e − f_d| {fmt.qty(worst, 'N')}")


def test_force_verdict_passes_on_the_paper_law():
    from tmtcontrol.report.document import _simulation

    rep, sc, p = _stage_report("trajectory.cycles=1", "environment.stiffness.values=[5e3]")
    section, _, _ = _simulation(rep, sc, p)
    assert rep.verdicts[0].passed
    (fc,) = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("First contact")]
    assert fc.head[-1] == "bounces within 1\u00a0s"        # a 4 s segment: the whole second


def test_the_first_contact_table_says_how_much_of_the_second_a_short_run_covers():
    """The eighteenth session: a run shorter than the first contact's 1 s
    window counted its bounces over what was left (39 ms of a 40 ms run) under
    the header "bounces within 1 s"."""
    from tmtcontrol.report.document import _simulation

    rep, sc, p = _stage_report("trajectory.cycles=0.01", "environment.stiffness.values=[5e3]")
    section, _, _ = _simulation(rep, sc, p)
    (fc,) = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("First contact")]
    assert fc.head[-1] == "bounces within 39\u00a0ms (its segment's end)"   # touch at 1 ms, last step 39-40 ms


def test_a_diverging_simulation_fails_its_verdict_and_says_where():
    # K_P Ts^2 = 100 >> 4: the sampled inner loop is unstable (as in test_simulate)
    from tmtcontrol.report.document import _simulation

    rep, sc, p = _stage_report("controller.rate=100", "trajectory.cycles=1", "impedance.k=[1e6, 1e6, 1e6]")
    section, _, res = _simulation(rep, sc, p)
    (v,) = rep.verdicts
    assert res is None and not v.passed and v.value == "diverged" and "diverged at t = " in v.check
    assert "The simulation diverged" in section.blocks[0].text


@pytest.mark.parametrize("b, stable", [(0.0, False), (60.0, True)])
def test_continuous_verdict_both_ways(b, stable):
    # b = 0: eq. (22)'s poles sit on the imaginary axis (not BIBO stable) for every k_e
    from tmtcontrol.report.document import _continuous

    rep, _, p = _stage_report(f"impedance.b=[{b}, 60, 60]")
    _continuous(rep, p)
    (v,) = rep.verdicts
    assert v.name == "BIBO stable in continuous time (eq. 22)" and v.passed is stable
    assert v.value == f"largest pole real part {fmt_qty(-b / 2, '1/s')}"      # Re p = -b/(2m), m = 1 kg


def fmt_qty(x, unit):
    from tmtcontrol import fmt

    return fmt.qty(x, unit)


def test_claims_hand_out_every_task_once_from_both_ends():
    """The two report processes take tasks from the front (the second) and
    the back (this one) of one shared range: every task exactly once,
    whatever the interleaving, then None for both."""
    import multiprocessing
    import random

    from tmtcontrol.report.document import _claim

    for seed in range(20):
        rng = random.Random(seed)
        claims = multiprocessing.Array("i", [0, 5])
        taken = []
        while (i := _claim(claims, last=rng.random() < 0.5)) is not None:
            taken.append(i)
        assert sorted(taken) == [0, 1, 2, 3, 4]
        assert _claim(claims) is None and _claim(claims, last=True) is None


def test_this_process_leaves_the_tasks_below_the_floor_to_the_other():
    """This process takes last first but none below ``floor`` (the tasks that
    use python-control); the other takes first first until none is left:
    every task exactly once, this one's all at or above the floor."""
    import multiprocessing
    import random

    from tmtcontrol.report.document import _claim

    for seed in range(20):
        rng = random.Random(seed)
        claims = multiprocessing.Array("i", [0, 7])
        front, back, back_done = [], [], False
        while True:
            if not back_done and rng.random() < 0.5:
                i = _claim(claims, last=True, floor=3)
                back_done = i is None
                back += [] if i is None else [i]
            elif (i := _claim(claims)) is not None:
                front.append(i)
            else:
                break
        assert sorted(front + back) == list(range(7)) and all(i >= 3 for i in back)
        assert _claim(claims, last=True, floor=3) is None


def _blas_threads():
    from threadpoolctl import threadpool_info

    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})


def test_both_report_processes_compute_with_one_blas_thread():
    """The report's matrices are small: BLAS threads on two busy processes
    made the sampled stage 3x slower, so each process uses one, this one
    within the stages and the second for its life."""
    import threadpoolctl

    from tmtcontrol.report.document import _background, _one_blas_thread

    if not [i for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]:
        pytest.fail("no BLAS library found by threadpoolctl")
    import multiprocessing

    from tmtcontrol.report.document import _share

    with threadpoolctl.threadpool_limits(limits=2):           # not 1 to begin with, so the test can fail
        assert _blas_threads() == [2]
        with _background() as (pool, _, _), _one_blas_thread():
            assert pool.submit(_blas_threads).result() == [1]
            assert _blas_threads() == [1]
        assert _blas_threads() == [2]
        # the second process' initializer sets it itself (a spawned process inherits nothing)
        _share(multiprocessing.Array("i", [0, 0]), [])
        assert _blas_threads() == [1]


@pytest.mark.heavy
def test_the_report_ran_each_task_once_and_every_check_group(paper_report):
    out, _ = paper_report
    html = (out / "report.html").read_text()
    from tmtcontrol.checks import all_checks
    from tmtcontrol.simulation.scenario import load_scenario

    expected = [r.name for r in all_checks(scenario=load_scenario("paper"))]   # every group (the arm's last)
    assert [row[1] for row in table(section(html, "derivations"), "Derivation checks")[2]] == expected
    for key in ("comparison", "sweep"):
        assert section(html, key).count("<table") == 1


def test_unknown_check_group_is_refused():
    from tmtcontrol.checks import run_check_group

    with pytest.raises(ValueError, match="group: expected one of derivations, law: tmt, .*, loop"):
        run_check_group("everything")
    with pytest.raises(ValueError, match="got 'law: nosuch'"):
        run_check_group("law: nosuch")


def test_the_sweep_says_which_rule_sized_its_stiffness_range():
    """Regression (review 15): the sweep's text said its range reached twice the 1-D small-signal limit
    on a loop the 1-D model does not predict (the mid-period hold: scenario_stiffness_limit is None), where
    the code took ten times the largest stiffness. The rule returned is the one applied: paper 2 x 163,417
    -> 330,000 N/m (two digits); with the hold, 10 x 20,000 = 200,000 N/m."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import sweep_axes
    from tmtcontrol.stability import scenario_parameters

    sc = paper_scenario()
    stiffness, _, rule = sweep_axes(sc, scenario_parameters(sc))
    assert stiffness[-1] == 330000.0 and "1-D small-signal limit" in rule
    held = apply_overrides(sc, ['controller.hold="mid_period"'])
    stiffness, _, rule = sweep_axes(held, scenario_parameters(held))
    assert stiffness[-1] == 200000.0 and "ten times its largest" in rule and "neither the 1-D model nor" in rule
    # review 21: the loop's own deciding limit sizes it where the 1-D model predicts nothing (the pipe's map ended
    # at 200,000 N/m below its 603,000 N/m limit): 2 x 603,000 -> 1,200,000 N/m (two digits)
    stiffness, _, rule = sweep_axes(held, scenario_parameters(held), loop_limit=lambda: 603e3)
    assert stiffness[-1] == 1.2e6 and "the loop's own deciding limit" in rule
    assert sweep_axes(sc, scenario_parameters(sc), loop_limit=lambda: 1 / 0)[0][-1] == 330000.0   # not called


@pytest.mark.heavy   # the loop's periodic and first-contact limits (5 s)
def test_the_sampled_section_shows_the_1d_model_for_reference_where_it_predicts_nothing():
    """Regression (review 15): on a loop with the mid-period hold, which the 1-D model leaves out, the
    models table showed its limit (163,000 N/m beside the loop's own 645,000) with no caveat, and the text
    said it "explains the limit"; the first-contact row, which stops its search at the periodic limit,
    read as a limit equal to it. Now the 1-D row is "for reference only", the text and the figure say it
    predicts nothing, and a first contact that settles at the ceiling reads "≥"."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import Paragraph, Report, Table, _sampled
    from tmtcontrol.stability import scenario_parameters

    sc = apply_overrides(paper_scenario(), ['controller.hold="mid_period"', "trajectory.cycles=1"])
    sec = _sampled(Report(sc, ""), sc, scenario_parameters(sc))
    text = next(b for b in sec.blocks if isinstance(b, Paragraph)).text
    assert "explains the limit" not in text and "for reference only" in text
    rows = {r[0].split(" (")[0]: r for r in next(b for b in sec.blocks if isinstance(b, Table)).rows}
    one_d = next(r for k, r in rows.items() if k.startswith("1-D"))
    assert "for reference only: it leaves out the mid-period hold" in one_d[0]
    assert rows["from first contact"][1].startswith("≥ ")


@pytest.mark.heavy   # the damping design (IPOPT) on the mid-period loop, 3-10 s
def test_the_design_tables_scenario_row_says_which_loop_it_judged(hold="mid_period"):
    """Review 28 (its label untested until now): the design table's row for the scenario's own b is
    the 1-D zero-order-hold loop's; under the mid-period hold the run's loop differs, and the label
    says so (under the zero-order hold it reads "as run")."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import Report, Table, _design
    from tmtcontrol.stability import scenario_parameters

    sc = apply_overrides(paper_scenario(), [f'controller.hold="{hold}"'])          # its four stiffnesses
    sec = _design(Report(sc, ""), sc, scenario_parameters(sc), None, None)
    rows = [r for b in sec.blocks if isinstance(b, Table) for r in b.rows if r[0].startswith("the scenario's b")]
    assert [r[0] for r in rows] == ["the scenario's b" + (" (its 1-D zero-order-hold loop; the run has the "
                                                          "mid-period hold)" if hold == "mid_period" else " (as run)")]


def test_alt_text_reads_a_shared_axis_and_calls_a_picture_an_image():
    """Regression (review 15): panels sharing the x axis of the one below were described "against
    index" (only the bottom one carries the label), and the drawn arm's frame (an image, axes off) "a
    chart of value against index"."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tmtcontrol.report.document import describe

    fig, (a, b) = plt.subplots(2, 1, sharex=True)
    a.plot([0, 1], [0, 1])
    a.set_ylabel("force (N)")
    b.plot([0, 1], [1, 0])
    b.set_ylabel("depth (m)")
    b.set_xlabel("time (s)")
    assert describe(fig) == "Chart. a chart of force (N) against time (s). a chart of depth (m) against time (s)."
    fig2, c = plt.subplots()
    c.imshow([[0.0, 1.0], [1.0, 0.0]])
    c.set_axis_off()
    c.set_title("the arm at t = 0 s")
    assert describe(fig2) == "Chart. the arm at t = 0 s: an image."
    plt.close("all")


# heavy (docs/testing.md's 2 s rule): 2.0-2.7 s in the README command's run of the nineteenth session
@pytest.mark.heavy
def test_the_law_comparison_verdict_is_the_force_trackings_when_a_law_is_over_a_limit(monkeypatch):
    """Regression (review 21): on the UR5 every law is over the shoulder's torque limit, and
    over_limit outranks off_target, so the table's verdict read "over a limit" for all five
    and hid that the known law settles 286 mN off f_d. The column is now the force
    tracking's verdict (each segment's tracking_verdict), and the paragraph says which laws
    are over a limit. Here the paper's comparison (short) with its segments marked over a
    limit: known off_target, tmt converged."""
    import dataclasses

    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report import document
    from tmtcontrol.simulation import compare as comparemod

    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=2.0"])
    real = comparemod.compare_laws(sc)

    def over(run):
        segs = [dataclasses.replace(sg, tracking_verdict=sg.verdict, verdict="over_limit") for sg in run.segments]
        return dataclasses.replace(run, segments=segs)

    fake = dataclasses.replace(real, runs={name: over(run) for name, run in real.runs.items()})
    assert all(run.verdict == "over_limit" for run in fake.runs.values())
    monkeypatch.setattr(comparemod, "compare_laws", lambda scenario, prepare=None: fake)
    sec = document._comparison(document.Report(sc, ""), sc)
    tab = next(b for b in sec.blocks if isinstance(b, document.Table))
    verdict = {row[0].split()[0]: row[-1] for row in tab.rows}
    assert verdict["known"] == "off_target" and verdict["tmt"] == "converged"
    text = " ".join(b.text for b in sec.blocks if isinstance(b, document.Paragraph))
    assert "every law also exceeds the arm's limits (over_limit)" in text


def test_a_segment_over_a_limit_whose_force_converged_shows_its_overshoot():
    """Regression (review 21): the per-segment table printed "- (over limit)" for the UR5's
    segment 4, whose force converged (its tracking verdict), though the law comparison gave
    its 100 % overshoot; a segment whose force does not settle still shows none."""
    import dataclasses

    from tmtcontrol import Simulator, apply_overrides, paper_scenario, segment_metrics
    from tmtcontrol.report.document import _segment_rows

    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=2.0"])
    segs = segment_metrics(Simulator(sc, compile=False).run(sc))
    over = [dataclasses.replace(segs[0], verdict="over_limit", tracking_verdict="converged"),
            dataclasses.replace(segs[1], verdict="over_limit", tracking_verdict="limit_cycle")]
    rows = _segment_rows(over)
    assert rows[0][4].endswith("%") and float(rows[0][4].split()[0].replace("\u2009", "")) == pytest.approx(
        segs[0].overshoot_pct, rel=1e-2)
    assert rows[1][4] == "– (over limit)" and rows[0][-1] == rows[1][-1] == "over_limit"


def test_applicable_settings_leave_out_the_plane_point_on_a_curved_part():
    """Review 21: the pipe's table listed environment.point, which a curved
    part refuses (it touches its tangent plane at trajectory.center); a plane
    keeps it."""
    from tmtcontrol.simulation.scenario import applicable_settings, arm_scenario

    assert "environment.point" not in {r.key for r in applicable_settings(arm_scenario("ur5-pipe"))}
    assert "environment.point" in {r.key for r in applicable_settings(arm_scenario("ur5"))}


def test_applicable_settings_leave_out_a_spheres_keys_on_a_height_map_and_an_unset_normal(tmp_path):
    """Review 25: the table listed environment.radius and environment.side (None) for a height
    map, which refuses them ("not used by shape = 'heightmap'"), and environment.normal None
    beside the paper's tilt_deg. A sphere keeps radius and side, the UR5 its normal."""
    from tmtcontrol.simulation.scenario import applicable_settings, apply_overrides, arm_scenario, paper_scenario

    (tmp_path / "flat.csv").write_text("\n".join([",".join(["0.0"] * 9)] * 9) + "\n")
    keys = lambda sc: {r.key for r in applicable_settings(sc)}
    sphere = apply_overrides(paper_scenario(), ["environment.shape=sphere", "environment.radius=0.3"])
    assert {"environment.radius", "environment.side"} <= keys(sphere)
    # review 28: the default side that ran, not "None"
    assert next(r.value for r in applicable_settings(sphere) if r.key == "environment.side") == "outside"
    assert "environment.normal" not in keys(paper_scenario()) and "environment.tilt_deg" in keys(paper_scenario())
    assert "environment.normal" in keys(arm_scenario("ur5"))
    flat = apply_overrides(paper_scenario(), ["environment.shape=heightmap", "environment.grid_spacing=0.05",
                                              f"environment.heightmap='{tmp_path / 'flat.csv'}'"])
    assert "environment.heightmap" in keys(flat)
    assert not {"environment.radius", "environment.side"} & keys(flat)


# heavy (docs/testing.md's 2 s rule): 2.0-2.7 s in the README command's run of the nineteenth session
@pytest.mark.heavy
def test_the_force_verdict_names_each_failing_segment_by_its_own_verdict():
    """The eighteenth session's mutation run: ``segs[i - 1]`` as ``segs[i % 1]``
    (every failing segment given segment 1's verdict) survived. The known law
    assuming 7,500 N/m: segment 1 on 7,500 N/m converges, segment 2 on 5,000
    N/m converges 0.065 N off f_d (eqs. 11-12): off_target, and named so."""
    from tmtcontrol.report.document import _simulation

    rep, sc, p = _stage_report("controller.law=known", "controller.law.assumed_stiffness=7500",
                               "trajectory.cycles=2", "environment.stiffness.values=[7500, 5000]")
    _simulation(rep, sc, p)
    (v,) = rep.verdicts
    segs = rep.data["simulation"]["segments"]
    assert [s.verdict for s in segs] == ["converged", "off_target"]          # the premise
    assert not v.passed and "segment 2 off_target" in v.check and "segment 1" not in v.check, v.check


@pytest.mark.heavy   # the damping design (IPOPT), 3-10 s
@pytest.mark.parametrize("bound, passed", [(60.0, True), (5.0, False)])
def test_a_stated_overshoot_requirement_is_a_verdict_on_the_scenarios_damping(bound, passed):
    """The eighteenth session's mutation run: the verdict line of a scenario
    that states requirements.first_contact_overshoot was never built by a test
    (``+`` as ``*`` there, a TypeError, survived). The paper's b = 60 N s/m
    overshoots 54.8 % at first contact on its range (test_report's fixture):
    within a 60 % bound, not within 5 %, whose violation is named."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import Report, _design
    from tmtcontrol.stability import scenario_parameters

    sc = apply_overrides(paper_scenario(), [f"requirements.first_contact_overshoot={bound}"])
    rep = Report(sc, "")
    _design(rep, sc, scenario_parameters(sc), None, None)
    (v,) = [v for v in rep.verdicts if v.name.startswith("Scenario's damping within requirements")]
    assert v.passed is passed
    assert v.check == "the scenario's b on the sampled loop" if passed else \
        v.check.startswith("the scenario's b on the sampled loop; violated: "), v.check


@pytest.mark.heavy
def test_the_sweep_section_says_how_long_each_case_runs(paper_report):
    """The eighteenth session's mutation run: ``cycles * period`` as
    ``cycles // period`` (0 s) survived. The paper's cases run
    SWEEP_CYCLES = 0.5 of its 4 s period: 2 s each, 2 rates x the stiffness
    points."""
    from tmtcontrol.report.document import SWEEP_CYCLES

    text = htmllib.unescape(re.sub(r"<[^>]+>", "", section((paper_report[0] / "report.html").read_text(), "sweep")))
    n = int(re.search(r"(\d+) simulations of ", text).group(1))
    assert SWEEP_CYCLES * 4.0 == 2.0 and f"{n} simulations of 2\xa0s each: constant stiffness" in text, text[:300]


def test_every_stage_counts_the_independent_plants_among_the_total(monkeypatch):
    """The eighteenth session's mutation run: ``len(STAGES) + 1`` as
    ``len(STAGES) ** 1`` in the independent plant's progress call survived
    (no test ran it); reading it showed the computing stages said n = 7 and
    the last one 8 of 8. With the stages' work stubbed: 1..8 of 8 with MuJoCo,
    1..7 of 7 without, and an unknown plant refused before any stage runs."""
    import contextlib

    from tmtcontrol import paper_scenario
    from tmtcontrol.report import document
    from tmtcontrol.report.document import STAGES, Section

    def stages(rep, sc, p, background, out, verdicts, say, prepare):
        for i, name in enumerate(STAGES, 1):
            out[name] = Section(name, name, [])
            say(i, len(STAGES), name, 0.0)

    monkeypatch.setattr(document, "_stages", stages)
    monkeypatch.setattr(document, "_background", lambda sc=None: contextlib.nullcontext((None, None, [])))
    monkeypatch.setattr(document, "_on_own", lambda sc, stage, *a: (Section("plant", "plant", []), [], {}))
    for plant, n in (("mujoco", len(STAGES) + 1), ("builtin", len(STAGES))):
        seen = []
        document.build_report(paper_scenario(), "test", progress=lambda *a: seen.append(a[:3]), plant=plant)
        assert seen == [(i, n, name) for i, name in enumerate([*STAGES, "independent plant"][:n], 1)], seen
    seen = []
    with pytest.raises(ValueError, match=r"^plant: expected 'builtin' or 'mujoco', got 'nope'$"):
        document.build_report(paper_scenario(), "test", progress=lambda *a: seen.append(a), plant="nope")
    assert seen == []


def test_a_table_of_many_columns_fits_the_pdf_page(tmp_path):
    """Review 60: on a 6-D arm the per-segment table (13 columns) ran past the
    PDF page's right edge and its verdict column was invisible in print. A
    table of ten or more columns is set smaller with wrapping cells: every
    character of it lies within the page (A4, 595.3 pt wide)."""
    from tmtcontrol import paper_scenario
    from tmtcontrol.report import Report, write_report
    from tmtcontrol.report.document import Section, Table

    # panda-bowl's table as the report wrote it (review 60), its cells' spaces non-breaking as _cells makes them
    head = ["segment", "time (s)", "k_e (N/m)", "switch jump", "overshoot", "contact lost", "settling 2 %",
            "steady-state |f_e − f_d|", "tangential RMS (last quarter)", "orientation error",
            "tool axis off the part's normal", "verdict"]
    row = ["2", "4–8", "20,000", "30.0 N", "100 %", "16.0 ms", "167 ms", "7.66 µN", "59.5 nm", "2.10 × 10⁻⁷ rad",
           "2.00 × 10⁻⁷ rad", "over_limit"]
    rows = [[c.replace(" ", "\u00a0") for c in row]] * 4
    rep = Report(paper_scenario(), "test")
    rep.sections = [Section("simulation", "Simulation", [Table("Per-segment metrics", head, rows, 11)])]
    (pdf,) = write_report(rep, tmp_path, ("pdf",))
    page = pypdf.PdfReader(pdf).pages[0]
    width, xs = float(page.mediabox.width), []
    # the text's x on the page: its matrix times the current transformation
    page.extract_text(visitor_text=lambda text, cm, tm, font, size: xs.append((tm[4] * cm[0] + tm[5] * cm[2] + cm[4],
                                                                               text)) if text.strip() else None)
    # every piece starts inside the right margin (15 mm = 42.5 pt), the verdict included
    assert any("over" in t for _, t in xs) and max(x for x, _ in xs) < width - 42.5, max(xs)


def test_the_report_records_a_command_line_that_runs_pasted(tmp_path, monkeypatch):
    """Review 60: the reproducibility table's command joined the arguments
    with spaces, and ``--set controller.part_offset=[0, 0, 0]`` pasted back
    was "unrecognized arguments: 0, 0]"; it is shell-quoted (shlex.join)."""
    import shlex
    import sys

    from tmtcontrol import report
    from tmtcontrol.cli import main

    seen = {}

    class Done:
        verdicts, passed = [], True

    def build(sc, command_line="", progress=None, prepare=None, plant="builtin"):
        seen["line"] = command_line
        return Done()

    argv = ["report", "paper", "--out", str(tmp_path / "r"), "--format", "html", "--set",
            "controller.part_offset=[0, 0, 0]"]
    monkeypatch.setattr(sys, "argv", ["tmtcontrol", *argv])
    monkeypatch.setattr(report, "build_report", build)
    monkeypatch.setattr(report, "write_report", lambda rep, folder, fmts, progress=None: [])
    assert main(argv) == 0
    assert shlex.split(seen["line"]) == ["tmtcontrol", *argv], seen["line"]


def test_the_law_comparison_judges_each_law_against_its_loops_limit(monkeypatch):
    """Review 60: the report's law comparison ran compare_laws without the
    stiffness limit that ``tmtcontrol compare`` attaches, so a segment beyond
    the limit read "off target" there and "beyond the limit" in the
    simulation's table; it passes the same ``prepare``."""
    from tmtcontrol import paper_scenario
    from tmtcontrol.report.document import Report, _comparison
    from tmtcontrol.simulation import compare as comparemod
    from tmtcontrol.stability.limit import with_stiffness_limit

    seen = {}

    def fake(scenario, prepare=None):
        seen["prepare"] = prepare
        raise RuntimeError("stop here")

    monkeypatch.setattr(comparemod, "compare_laws", fake)
    with pytest.raises(RuntimeError, match="stop here"):
        _comparison(Report(paper_scenario(), ""), paper_scenario())
    assert seen["prepare"] is with_stiffness_limit


@pytest.mark.heavy   # the damping design (IPOPT) and, with the hold, the scenario loop's frozen limit
@pytest.mark.parametrize("sets, why", [
    (['controller.hold="mid_period"'], "the design's 1-D sampled loop has the zero-order hold, the run the mid-period"),
    (["environment.stiffness.values=[5000, 200000]"], "the 1-D sampled loop is unstable above 163,400 N/m, inside "
                                                      "the range (to 200,000 N/m)")])
def test_a_stated_overshoot_is_not_judged_on_a_1d_loop_that_is_not_the_runs(sets, why):
    """Review 60: the requirement's verdict quoted the 1-D zero-order-hold
    loop's overshoot for a mid-period run (1,377 % where the run's first
    contact overshoots 81 %) and an "overshoot" of 1.24e9 % where the 1-D loop
    is unstable; neither is a verdict now, the paragraph says why."""
    from tmtcontrol import apply_overrides, paper_scenario
    from tmtcontrol.report.document import Paragraph, Report, _design
    from tmtcontrol.stability import scenario_parameters

    sc = apply_overrides(paper_scenario(), [*sets, "requirements.first_contact_overshoot=60"])
    rep = Report(sc, "")
    sec = _design(rep, sc, scenario_parameters(sc), None, None)
    assert not [v for v in rep.verdicts if v.name.startswith("Scenario's damping within requirements")]
    text = " ".join(b.text for b in sec.blocks if isinstance(b, Paragraph))
    assert "requirements.first_contact_overshoot (60 %) is not judged" in text and why in text, text


@pytest.mark.heavy   # the damping design (IPOPT), 2-8 s
def test_a_proposed_design_that_fails_on_the_scenarios_loop_says_so(monkeypatch):
    """Review 60: the report's proposed b was verified on the 1-D model only;
    on ur5-pipe at 640,000 N/m (mid-period hold) it diverged, the table
    showed it as meeting the bound and `design --scenario` exited 1 on it. The
    report runs the same verification (stability.design.with_scenario_loop,
    here made to find the scenario's loop unstable from k_e_min) and says the
    proposal fails it, naming the violation."""
    import dataclasses

    from tmtcontrol import paper_scenario
    from tmtcontrol.report.document import Paragraph, Report, _design
    from tmtcontrol.stability import design as designmod
    from tmtcontrol.stability import scenario_parameters

    monkeypatch.setattr(designmod, "with_scenario_loop", lambda sc, r: dataclasses.replace(
        r, info={**r.info, "scenario_loop_limit": 0.0, "scenario_hold": "mid-period"}))
    sc = paper_scenario()
    sec = _design(Report(sc, ""), sc, scenario_parameters(sc), None, None)
    text = " ".join(b.text for b in sec.blocks if isinstance(b, Paragraph))
    assert "fails its verification on this scenario's loop: " in text and "Do not use it as is." in text, text


@pytest.mark.heavy      # a report's start (its second process forked) and the frozen loop's limit search: ~5 s
def test_a_loop_that_never_touches_the_part_stops_the_report_before_its_stages(tmp_path):
    """The controller believing the surface 0.15 m beyond where it is, with
    the command f_d/K = 0.1 m past that belief, never touches the part at
    any stiffness: there is no limit for the law comparison, the design or
    the sweep to use. The report stopped with the analysis' error in its
    fifth stage, after four stages had run (24 s for the paper's loop); it
    now stops at the simulation that found no touch, before reporting any
    stage: one line naming the key, exit 2, nothing written."""
    out = tmp_path / "o"
    r = make_report(out, "paper", "--set", "controller.x_e_error=-0.15", "--set", "trajectory.cycles=1")
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: controller.x_e_error: ") \
        and "holds no contact at any stiffness" in lines[0], r.stderr
    assert "[1/" not in r.stdout + r.stderr            # no stage was reported finished (progress: stderr)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_a_law_without_a_linear_verdict_is_refused_before_any_stage(tmp_path):
    """Review 72: ``report --set controller.law.kind="rls"`` ran four stages (simulation, design,
    the sweep, the continuous analysis) before the sampled-data stage refused the law: refused at
    once, one line naming the key, exit 2, nothing written."""
    out = tmp_path / "o"
    r = make_report(out, "paper", "--set", 'controller.law.kind="rls"', "--format", "html")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("error: controller.law.kind: 'rls' has no linear stability verdict"), lines
    assert not out.exists() and list(tmp_path.iterdir()) == []
