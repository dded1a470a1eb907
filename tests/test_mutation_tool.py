"""benchmarks/mutation_tool.py (the Cosmic Ray mutation benchmark, not run in CI): its module -> tests
map names files that exist, its equivalent-mutant list parses and points into mapped modules, its 95 %
interval agrees with SciPy's, and docs/testing.md shows the table of the committed results."""
import importlib.util
import json
import pathlib
import sys

import pytest
from scipy.stats import binomtest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tool():
    spec = importlib.util.spec_from_file_location("mutation_tool", ROOT / "benchmarks" / "mutation_tool.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # its dataclass looks its module up there
    spec.loader.exec_module(mod)
    return mod


def test_every_mapped_module_and_test_file_exists(tool):
    for module, tests in tool.TESTS.items():
        assert (ROOT / module).exists(), module
        assert tool.module_files(module), module
        assert tests and all((ROOT / t).is_file() for t in tests), (module, tests)


def test_the_issue_modules_are_all_mapped(tool):
    for module in ["tmtcontrol/files.py", "tmtcontrol/simulation/metrics.py", "tmtcontrol/simulation/scenario",
                   "tmtcontrol/control/laws", "tmtcontrol/stability/analysis.py", "tmtcontrol/stability/sampled.py",
                   "tmtcontrol/stability/lawloop.py", "tmtcontrol/sweep/spec.py"]:
        assert module in tool.TESTS, module


def test_equivalent_list_parses_and_names_mapped_files(tool):
    entries = tool.load_equivalents()
    mapped = {f for module in tool.TESTS for f in tool.module_files(module)}
    for key, entry in entries.items():
        file = key.split(":")[0]
        assert file in mapped, key
        assert entry["line"] <= len((ROOT / file).read_text().splitlines()), key
        assert len(entry["reason"]) > 10, key


def test_equivalent_list_refuses_an_entry_without_a_reason(tool, tmp_path):
    bad = tmp_path / "eq.toml"
    bad.write_text('[[mutant]]\nfile = "tmtcontrol/files.py"\noperator = "core/AddNot"\noccurrence = 1\nline = 3\n')
    with pytest.raises(ValueError, match="lacks reason"):
        tool.load_equivalents(bad)


@pytest.mark.parametrize("k,n", [(0, 10), (7, 10), (10, 10), (19, 20), (1, 3)])
def test_wilson_interval_matches_scipy(tool, k, n):
    # SciPy's binomtest(...).proportion_ci(method="wilson") is an independent implementation; it uses
    # z = 1.959964 where the script rounds to 1.96, which moves the bounds by less than 1e-4
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    lo, hi = tool.wilson(k, n)
    assert lo == pytest.approx(ci.low, abs=1e-4) and hi == pytest.approx(ci.high, abs=1e-4)


@pytest.mark.parametrize("results", ["mutation_tool_results.json", "mutation_tool_results_seed2.json",
                                     "mutation_tool_results_seed3.json", "mutation_tool_results_seed3_all.json",
                                     "mutation_tool_results_seed4.json", "mutation_tool_results_seed5.json",
                                     "mutation_tool_results_seed6.json", "mutation_tool_results_seed7.json",
                                     "mutation_tool_results_seed8.json", "mutation_tool_results_seed9.json",
                                     "mutation_tool_results_seed10.json", "mutation_tool_results_seed11.json",
                                     "mutation_tool_results_seed12.json", "mutation_tool_results_seed13.json",
                                     "mutation_tool_results_seed14.json"])
def test_docs_table_is_the_committed_run(tool, results):
    doc = json.loads((ROOT / "benchmarks" / results).read_text())
    assert tool.markdown_table(doc) in (ROOT / "docs" / "testing.md").read_text()


def _doc(modules, sample=22, seed=3, **outcomes):
    rows = [dict(module=m, mutants=100, run=len(outcomes.get(m, ()))) for m in modules]
    mutants = [dict(module=m, id=f"{m}:op:{i}", outcome=o) for m in modules for i, o in enumerate(outcomes.get(m, ()))]
    return dict(tool="cosmic-ray 8.7", sample=sample, seed=seed, full_suite=True, timeout=600.0,
                deselected={}, modules=rows, mutants=mutants)


def test_module_row_counts_its_own_mutants_and_gives_the_wilson_interval(tool):
    doc = _doc(["tmtcontrol/files.py", "tmtcontrol/export"],
               **{"tmtcontrol/files.py": ["killed"] * 21 + ["survived", "equivalent"],
                  "tmtcontrol/export": ["survived"] * 3})
    row = tool._module_row(doc["modules"][0], doc["mutants"])
    assert (row["killed"], row["survived"], row["equivalent"], row["incompetent"]) == (21, 1, 1, 0)
    assert row["score"] == pytest.approx(21 / 22)      # equivalents are out of the score
    assert row["ci95"] == list(tool.wilson(21, 22))
    # 22 of 22 is the smallest all-killed sample whose 95 % lower bound reaches the issue's 85 %
    assert tool.wilson(22, 22)[0] >= 0.85 > tool.wilson(21, 21)[0]


def test_merge_keeps_each_run_and_refuses_mixed_samples_or_a_module_twice(tool):
    a = _doc(["tmtcontrol/export"], **{"tmtcontrol/export": ["killed"]})
    b = _doc(["tmtcontrol/files.py"], **{"tmtcontrol/files.py": ["killed", "survived"]})
    merged = tool.merge_results([a, b])
    assert [r["module"] for r in merged["modules"]] == ["tmtcontrol/files.py", "tmtcontrol/export"]  # TESTS order
    assert len(merged["mutants"]) == 3 and merged["seed"] == 3
    with pytest.raises(ValueError, match="seed"):
        tool.merge_results([a, _doc(["tmtcontrol/files.py"], seed=4)])
    with pytest.raises(ValueError, match="tmtcontrol/export is measured in more than one file"):
        tool.merge_results([a, a])


def test_a_larger_draw_starts_with_the_smaller_one_so_a_top_up_keeps_the_sample(tool):
    # --recheck tops a sample up past its equivalent mutants by drawing further along the same seeded
    # order (up to 3 * sample + 10 further); that is sound only if the first k of a draw of k + j are the
    # draw of k, for every module size and every j (random.sample switches algorithm with k against n:
    # the draw of 22 + 76 from 683 mutants was another order, which --recheck caught in the fourth run)
    for size in (30, 683, 2280):
        population = [tool.Mutant("m", "f.py", "core/AddNot", i, i) for i in range(size)]
        for k in (6, 20, 22):
            for j in (17, 3 * 22 + 10, size):
                assert tool.draw(population, 3, "m", k + j)[:k] == tool.draw(population, 3, "m", k), (size, k, j)


def test_a_sample_of_22_is_the_one_random_sample_drew_for_the_earlier_runs(tool):
    # the recorded runs drew with random.sample; on modules of more than 277 mutants (all of them) a
    # sample of 22 is drawn index by index, as draw does, so their samples are still drawn the same
    import random

    for size in (683, 717, 2280):
        population = [tool.Mutant("m", "f.py", "core/AddNot", i, i) for i in range(size)]
        for seed in (1, 2, 3):
            assert tool.draw(population, seed, "m", 22) == random.Random(f"{seed}:m").sample(population, 22)


def test_a_draw_larger_than_the_module_is_the_whole_module(tool):
    population = [tool.Mutant("m", "f.py", "core/AddNot", i, i) for i in range(5)]
    assert sorted(tool.draw(population, 3, "m", 22), key=lambda m: m.occurrence) == population


def test_the_test_that_killed_a_mutant_is_read_from_pytests_summary(tool):
    # a whole-suite kill is confirmed by running this test alone with the mutant; parametrised ids keep
    # their brackets, the message after " - " is not part of the id
    tail = ("FAILED tests/test_outputs.py::test_interrupt_exits_cleanly_and_leaves_nothing[15-143] - assert 1 == 143"
            "\n1 failed, 616 passed in 218.16s (0:03:38)")
    assert tool._failed_test(tail) == "tests/test_outputs.py::test_interrupt_exits_cleanly_and_leaves_nothing[15-143]"
    assert tool._failed_test("ERROR tests/test_export.py::test_x - TypeError\n1 error") == "tests/test_export.py::test_x"
    assert tool._failed_test("1 failed in 2.0s") is None


def test_the_module_stage_and_the_reruns_select_the_heavy_tests(tool, monkeypatch):
    """The unmutated baseline, the module stage and a whole-suite kill's rerun alone select every
    mark (CI runs the heavy tests: one that fails on a mutant kills it); pyproject's addopts
    deselect the heavy tests unless a later -m selects them, which pytest lets override."""
    import types

    calls = []

    def fake_run(cmd, **kw):
        calls.append(cmd)
        fails = len(calls) >= 3                                 # the whole suite and the rerun alone fail
        return types.SimpleNamespace(returncode=int(fails), stdout="",
                                     stderr="FAILED tests/test_x.py::test_y - boom\n1 failed" if fails else "")

    monkeypatch.setattr(tool.subprocess, "run", fake_run)
    node = "tests/test_design.py::test_optimum_is_constrained_and_beats_baseline"
    assert tool._failing(ROOT, [node], {}, 60) == []
    m = tool.Mutant("m", "tmtcontrol/fmt.py", "core/NumberReplacer", 0, 1)
    monkeypatch.setattr(tool, "_mutated", lambda root, mutant: __import__("contextlib").nullcontext(("a", "b")))
    monkeypatch.setattr(tool, "only_annotations", lambda old, new: False)
    monkeypatch.setattr(tool, "_unified", lambda mutant, old, new: "")
    rec = tool._judge(ROOT, m, {}, [node], {}, 60, full=True)
    assert rec["outcome"] == "killed" and rec["confirmed"] and len(calls) == 4
    assert calls[3][-1] == "tests/test_x.py::test_y"
    for cmd in (calls[0], calls[1], calls[3]):                    # baseline, module stage, the rerun alone
        i = len(cmd) - 1 - cmd[::-1].index("-m")
        assert cmd[i + 1] == "", cmd
    assert "-m" not in calls[2][calls[2].index("pytest"):]          # the whole-suite stage: the README's command


def test_the_interval_is_shown_rounded_outward(tool):
    # 21 of 21 bound the score at 84.5 %: shown as 84 (the goal is a lower bound of 85 %), not 85
    assert tool._ci(tool.wilson(21, 21)) == "84-100 %"
    assert tool._ci(tool.wilson(22, 22)) == "85-100 %" and tool._ci((0.25, 0.75)) == "25-75 %"


FUTURE = "from __future__ import annotations\n"
PLAIN = "def f(x: int | None = None, *a: str, k: float | None = 1.0, **kw: int) -> str | None:\n    return x | 1\n"


@pytest.mark.parametrize("old,new,equivalent", [
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("x: int | None", "x: int >> None"), True),
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("-> str | None", "-> str & None"), True),
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("*a: str", "*a: str[0]"), True),
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("k: float | None", "k: float ^ None"), True),
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("**kw: int", "**kw: -int"), True),
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("= 1.0", "= 2.0"), False),                  # a default is code
    (FUTURE + PLAIN, FUTURE + PLAIN.replace("x | 1", "x ^ 1"), False),                  # the body
    (PLAIN, PLAIN.replace("x: int | None", "x: int >> None"), False),                   # evaluated at def time
    (FUTURE + "@deco\n" + PLAIN, FUTURE + "@deco\n" + PLAIN.replace("-> str | None", "-> str & None"), False),
    (FUTURE + "class C:\n    x: int | None = None\n", FUTURE + "class C:\n    x: int >> None = None\n", False),
    (FUTURE + PLAIN, FUTURE + PLAIN, False),                                            # no change at all
])
def test_an_annotation_only_mutant_is_equivalent_by_rule_and_nothing_else_is(tool, old, new, equivalent):
    """The rule that spares the equivalent list its annotation entries: only parameter and return
    annotations of undecorated functions under PEP 563 (a decorator such as pydantic's
    validate_call, or a dataclass or pydantic field, would evaluate them; without the
    __future__ import they are evaluated when the def runs)."""
    assert tool.only_annotations(old, new) is equivalent


def test_a_recheck_judges_as_the_run_did_unless_told_otherwise(tool):
    # the fourth run's rechecks ran with the 240 s default while the file said 600 s: --recheck now
    # keeps the file's timeout, seed and whole-suite stage; --sample only ever grows the sample
    old = dict(sample=22, seed=3, full_suite=True, timeout=600.0)
    assert tool.recheck_settings(old, 0, None) == (22, 3, False, 600.0)
    assert tool.recheck_settings(old, 30, 900.0) == (30, 3, False, 900.0)
    assert tool.recheck_settings(dict(old, full_suite=False), 10, None) == (22, 3, True, 600.0)


def test_a_mutant_moved_by_lines_added_above_it_is_the_same_mutant(tool):
    """The eighteenth session: a fix that added lines above a survivor made
    --recheck call every survivor below it stale (its diff's hunk header
    moved); the change itself decides, and another change is still another."""
    a = "--- f.py\n+++ f.py\n@@ -447 +447 @@\n-    x = a != b\n+    x = a >= b\n"
    moved = a.replace("@@ -447 +447 @@", "@@ -451 +451 @@")
    other = a.replace("a >= b", "a < b")
    assert tool._same_change(a) == tool._same_change(moved) != tool._same_change(other)
