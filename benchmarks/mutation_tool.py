"""Test strength measured by a mutation-testing tool (cosmic-ray), not a hand-written list.

benchmarks/mutation_score.py applies a list of one-line bugs written by hand
beside the tests that kill them; this script lets a well-kept tool choose the
bugs.  It applies Cosmic Ray's own mutation operators (a comparison, binary,
unary or boolean operator replaced, a number shifted by one, ``True`` for
``False``, ``not`` added, a ``break`` for a ``continue``, a loop run zero
times, an exception handler narrowed, a decorator removed, ...) to the modules
that decide safety and verdicts, one mutant at a time, and counts the mutants
the test suite kills.

Why Cosmic Ray (8.7) and not mutmut (3.x): many tests run the ``tmtcontrol``
CLI in a subprocess (``python -m tmtcontrol.cli``), so the mutated code must
be what a fresh interpreter imports.  Cosmic Ray rewrites the source file on
disk (parso keeps the rest of the file byte for byte) and runs any test
command, so a scratch clone with ``PYTHONPATH`` pointing at it reaches every
subprocess.  mutmut 3 instead copies the package into ``mutants/`` with every
function turned into a trampoline that picks its variant from an environment
variable inside the pytest process it forks; a CLI subprocess imports the
installed (editable) package, not ``mutants/``, so it would run unmutated code
and report false survivors.  mutmut 3 also leaves decorated functions (the
pydantic validators of the scenario schema) and module- and class-level code
(the schema's bounds, the module constants) unmutated, which is where much of
this package's safety lives.  Cosmic Ray mutates those too.

How a mutant is judged:

1. a scratch clone of this checkout's HEAD (``git clone``; the working tree,
   shared with others, is never modified) is made in a temporary folder and a
   subprocess with ``PYTHONPATH`` set to it is checked to import it;
2. each module's test files (``TESTS`` below, the fast and targeted ones
   first, since ``-x`` stops at the first failure) are run once unmutated; a
   test that fails unmutated is deselected for that module's mutants and
   reported (a file that does not run at all leaves the module unmeasured);
3. a mutant is applied in the clone (``cosmic_ray.mutating.use_mutation``, the
   file is restored afterwards) and its module's test files run with
   ``pytest -n 0 -x``; a failure, an error or a timeout kills it;
4. a survivor of step 3 runs the whole default suite (``pytest -x``, unless
   ``--no-full``); only a mutant that also survives that is a survivor.  A
   failure there kills the mutant only if the failing test, run again alone
   with the mutant, fails again: the whole suite runs two workers on a
   machine the benchmark loads, and a test that waits on a subprocess (the
   Ctrl-C tests) has been seen to fail under that load with the mutated line
   never run; such a mutant is a survivor, with the failure recorded.

A mutant that changes nothing but the annotations of undecorated functions in
a module with ``from __future__ import annotations`` (``int | None`` made
``int >> None``) is equivalent by rule (:func:`only_annotations`): those
annotations stay unevaluated strings.  Mutants listed in
benchmarks/equivalent_mutants.toml (argued, one line each,
that no input can tell them apart from the original) are counted as
equivalent and not run; an entry whose line no longer matches the mutant is
reported as stale and ignored.  The score of a module is
killed / (killed + survived); with ``--sample N`` a seeded random sample of N
mutants per module is run and the score is given with its 95 % Wilson
interval (an estimate of the score over all of the module's mutants).

    python benchmarks/mutation_tool.py --count                # mutants per module (fast)
    python benchmarks/mutation_tool.py --sample 12 --seed 1 --json mutation_tool.json
    python benchmarks/mutation_tool.py --modules tmtcontrol/files.py --sample 0   # every mutant of one module
    python benchmarks/mutation_tool.py --show tmtcontrol/files.py:core/NumberReplacer:3

Slow (each mutant runs test files that simulate), so it is a benchmark, not
part of CI; docs/testing.md gives the last measured table.  Requires
``pip install ".[bench]"`` (cosmic-ray 8.7.0).
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import asdict, dataclass

ROOT = pathlib.Path(__file__).resolve().parents[1]
EQUIVALENTS = ROOT / "benchmarks" / "equivalent_mutants.toml"

# module (or package folder) -> the test files that exercise it, run first for each of its mutants
TESTS: dict[str, tuple[str, ...]] = {
    "tmtcontrol/files.py": ("tests/test_files_safety.py", "tests/test_outputs.py", "tests/test_mutation_kills.py",
                            "tests/test_review_inputs.py", "tests/test_processes.py", "tests/test_cli.py"),
    "tmtcontrol/simulation/metrics.py": ("tests/test_verdicts_wave3.py", "tests/test_verdicts.py",
                                         "tests/test_mutation_kills.py", "tests/test_review_verdicts.py",
                                         "tests/test_noise_bias.py", "tests/test_edges_wave4.py",
                                         "tests/test_simulate.py", "tests/test_verdict_words.py"),
    "tmtcontrol/simulation/scenario": ("tests/test_scenario.py", "tests/test_docs.py", "tests/test_scenario_fuzz.py",
                                          "tests/test_inputs_wave3.py", "tests/test_mutation_kills.py",
                                          "tests/test_review_inputs.py", "tests/test_bounds_wave3.py",
                                          "tests/test_edges_wave4.py"),
    "tmtcontrol/control/laws": ("tests/test_laws.py", "tests/test_mutations.py", "tests/test_derivations.py",
                                "tests/test_mutation_kills.py"),
    "tmtcontrol/stability/onedim.py": ("tests/test_stability.py", "tests/test_stiffness_band.py",
                                       "tests/test_free_axes.py", "tests/test_verdicts.py",
                                       "tests/test_mutation_kills.py", "tests/test_limits.py"),
    "tmtcontrol/simulation/crosscheck.py": ("tests/test_crosscheck_verdicts.py", "tests/test_verdicts.py",
                                            "tests/test_cli.py", "tests/test_mujoco_plant.py",
                                            "tests/test_against_mujoco.py"),
    "tmtcontrol/stability/analysis.py": ("tests/test_stability.py", "tests/test_mutation_kills.py",
                                         "tests/test_review_verdicts.py", "tests/test_limits_wiring.py",
                                         "tests/test_stiffness_band.py", "tests/test_limits.py",
                                         "tests/test_stability_6d.py"),
    "tmtcontrol/stability/sampled.py": ("tests/test_mutations.py", "tests/test_stability.py", "tests/test_laws.py",
                                        "tests/test_mutation_kills.py", "tests/test_review_verdicts.py",
                                        "tests/test_stiffness_band.py", "tests/test_limits.py"),
    "tmtcontrol/stability/lawloop.py": ("tests/test_limits.py", "tests/test_laws.py", "tests/test_mutation_kills.py",
                                        "tests/test_review_verdicts.py", "tests/test_stiffness_band.py",
                                        "tests/test_stability.py"),
    "tmtcontrol/sweep/spec.py": ("tests/test_sweep.py", "tests/test_inputs_wave3.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/model/urdf.py": ("tests/test_urdf.py", "tests/test_mutation_kills.py", "tests/test_robot.py",
                                 "tests/test_arm_checks.py", "tests/test_export_6d.py", "tests/test_taskframe.py",
                                 "tests/test_edges_wave4.py"),
    "tmtcontrol/export": ("tests/test_export.py", "tests/test_mutation_kills.py", "tests/test_export_6d.py",
                           "tests/test_review_export.py", "tests/test_pose_delay.py", "tests/test_edges_wave4.py"),
    # issue 43's list of the newest modules: the limits, the one loop, the posture task, processes, arm checks
    "tmtcontrol/stability/first_contact.py": ("tests/test_limits.py", "tests/test_limits_wiring.py",
                                              "tests/test_stability_6d.py", "tests/test_verdicts.py",
                                              "tests/test_mutation_kills.py"),
    "tmtcontrol/stability/periodic.py": ("tests/test_limits.py", "tests/test_limits_wiring.py",
                                         "tests/test_stability_6d.py", "tests/test_mutation_kills.py",
                                         "tests/test_codegen.py"),
    "tmtcontrol/simulation/closedloop.py": ("tests/test_closedloop_units.py", "tests/test_one_loop.py", "tests/test_taskframe.py", "tests/test_hold.py",
                                            "tests/test_pose_delay.py", "tests/test_laws.py"),
    "tmtcontrol/simulation/posture.py": ("tests/test_posture_units.py", "tests/test_taskframe.py", "tests/test_one_loop.py",
                                         "tests/test_joint_limits.py", "tests/test_stability_6d.py"),
    "tmtcontrol/processes.py": ("tests/test_processes_units.py", "tests/test_processes.py", "tests/test_compile_signals.py",
                                "tests/test_files_safety.py"),
    "tmtcontrol/checks/arm.py": ("tests/test_arm_checks.py", "tests/test_model_checks.py"),
    # review 42 (the sixth run): modules the tool had never measured
    "tmtcontrol/surface": ("tests/test_surfaces.py", "tests/test_curved_refusals.py", "tests/test_curved_acceptance.py",
                           "tests/test_mujoco_plant.py"),
    "tmtcontrol/simulation/limits.py": ("tests/test_joint_limits.py", "tests/test_report_arm.py", "tests/test_export.py"),
    "tmtcontrol/stability/wholeloop.py": ("tests/test_wholeloop_units.py", "tests/test_tangent.py",
                                          "tests/test_verdicts.py", "tests/test_stiffness_band.py",
                                          "tests/test_stability.py", "tests/test_limits.py",
                                          "tests/test_stability_6d.py"),
    "tmtcontrol/simulation/mujoco_plant.py": ("tests/test_mujoco_plant.py", "tests/test_crosscheck_verdicts.py",
                                              "tests/test_curved_refusals.py", "tests/test_report_arm.py",
                                              "tests/test_export_6d.py"),
    # review 45: four modules the tool had never measured (each file under 60 s alone)
    "tmtcontrol/stability/limit.py": ("tests/test_limits_wiring.py", "tests/test_limits.py",
                                      "tests/test_mutation_kills.py", "tests/test_hold.py", "tests/test_edges_wave4.py",
                                      "tests/test_result_cache.py"),
    # the thirteenth session: the report's rounding down and the sweep's runner, never measured
    "tmtcontrol/fmt.py": ("tests/test_fmt.py", "tests/test_verdicts_wave3.py", "tests/test_figures.py",
                          "tests/test_presentation.py", "tests/test_design.py", "tests/test_docs.py"),
    "tmtcontrol/sweep/run.py": ("tests/test_sweep.py", "tests/test_inputs_wave3.py", "tests/test_processes.py",
                                "tests/test_limits_wiring.py"),
    "tmtcontrol/stability/continuous.py": ("tests/test_stability.py", "tests/test_mutation_kills.py",
                                           "tests/test_derivations.py", "tests/test_laws.py"),
    "tmtcontrol/simulation/rollout.py": ("tests/test_codegen.py", "tests/test_tangent.py",
                                         "tests/test_mutation_kills.py", "tests/test_files_safety.py",
                                         "tests/test_simulate.py", "tests/test_verdict_words.py"),
    "tmtcontrol/cache.py": ("tests/test_compile_signals.py", "tests/test_codegen.py", "tests/test_files_safety.py",
                            "tests/test_result_cache.py"),
    # the fifteenth session: the gain design, the arm interface and the simulator, never measured
    "tmtcontrol/stability/design.py": ("tests/test_design.py", "tests/test_design_wave3.py",
                                       "tests/test_design_scenario.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/model/robot.py": ("tests/test_robot.py", "tests/test_one_loop.py", "tests/test_urdf.py",
                                  "tests/test_mutation_kills.py", "tests/test_joint_limits.py"),
    "tmtcontrol/simulation/simulator.py": ("tests/test_simulate.py", "tests/test_one_loop.py", "tests/test_hold.py",
                                           "tests/test_joint_limits.py", "tests/test_mutation_kills.py"),
    # the sixteenth session: the URDF dynamics, the reference path and the surface's placement, never measured
    "tmtcontrol/model/featherstone.py": ("tests/test_urdf.py", "tests/test_pinocchio_loop.py",
                                         "tests/test_model_checks.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/simulation/trajectory.py": ("tests/test_simulate.py", "tests/test_surfaces.py",
                                            "tests/test_curved_refusals.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/simulation/geometry.py": ("tests/test_one_loop.py", "tests/test_surfaces.py",
                                          "tests/test_taskframe.py", "tests/test_mutation_kills.py"),
    # the seventeenth session: the paper's arm, the law comparison and the figure workers, never measured
    "tmtcontrol/model/puma560.py": ("tests/test_model_checks.py", "tests/test_robot.py", "tests/test_pinocchio_loop.py",
                                    "tests/test_simulate.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/simulation/compare.py": ("tests/test_laws.py", "tests/test_files_safety.py",
                                         "tests/test_presentation.py", "tests/test_mutation_kills.py"),
    "tmtcontrol/drawing.py": ("tests/test_drawing.py", "tests/test_outputs.py", "tests/test_files_safety.py",
                              "tests/test_animation.py"),
    # the eighteenth session: the command line and the report's document, never measured
    "tmtcontrol/cli.py": ("tests/test_cli.py", "tests/test_review_inputs.py", "tests/test_inputs_wave3.py",
                          "tests/test_edges_wave4.py", "tests/test_files_safety.py"),
    "tmtcontrol/report/document.py": ("tests/test_report_renderer.py", "tests/test_report.py",
                                      "tests/test_report_arm.py"),
    # the twenty-first session: the run's output folder and the model checks, never measured
    "tmtcontrol/simulation/output.py": ("tests/test_outputs.py", "tests/test_drawing.py", "tests/test_files_safety.py",
                                        "tests/test_curved_refusals.py"),
    "tmtcontrol/checks/model.py": ("tests/test_model_checks.py", "tests/test_arm_checks.py", "tests/test_derivations.py",
                                   "tests/test_mutation_kills.py"),
}


@dataclass(frozen=True)
class Mutant:
    module: str          # the group in TESTS it belongs to
    file: str            # path of the mutated file, relative to the checkout
    operator: str        # Cosmic Ray operator name
    occurrence: int      # the operator's n-th position in the file (Cosmic Ray's numbering)
    line: int            # 1-based line where the mutation starts

    @property
    def id(self) -> str:
        return f"{self.file}:{self.operator}:{self.occurrence}"


def module_files(module: str, root: pathlib.Path = ROOT) -> list[str]:
    """The Python files of a TESTS key (a file, or every file of a package folder)."""
    path = root / module
    files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
    return [str(f.relative_to(root)) for f in files]


def load_equivalents(path: pathlib.Path = EQUIVALENTS) -> dict[str, dict]:
    """The argued-equivalent mutants: id -> {line, reason}.  Raises ValueError on a malformed entry."""
    data = tomllib.loads(path.read_text()) if path.exists() else {}
    out = {}
    for i, entry in enumerate(data.get("mutant", [])):
        missing = {"file", "operator", "occurrence", "line", "reason"} - set(entry)
        if missing:
            raise ValueError(f"{path.name}: mutant #{i + 1} lacks {', '.join(sorted(missing))}")
        if not str(entry["reason"]).strip():
            raise ValueError(f"{path.name}: mutant #{i + 1} has an empty reason")
        key = f"{entry['file']}:{entry['operator']}:{int(entry['occurrence'])}"
        if key in out:
            raise ValueError(f"{path.name}: {key} is listed twice")
        out[key] = {"line": int(entry["line"]), "reason": str(entry["reason"])}
    return out


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k/n (nan, nan for n = 0)."""
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z / d * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, c - h), min(1.0, c + h)


def enumerate_mutants(root: pathlib.Path, modules) -> dict[str, list[Mutant]]:
    """Every mutant Cosmic Ray's operators (those that take no arguments) make in each module,
    in Cosmic Ray's own order and occurrence numbering (as ``cosmic-ray init`` makes them)."""
    import cosmic_ray.plugins
    from cosmic_ray.ast import ast_nodes, get_ast_from_path

    ops = []
    for name in sorted(cosmic_ray.plugins.operator_names()):
        cls = cosmic_ray.plugins.get_operator(name)
        if not cls.arguments():
            ops.append((name, cls()))
    out = {}
    for module in modules:
        found = []
        for file in module_files(module, root):
            tree = get_ast_from_path(root / file)
            nodes = list(ast_nodes(tree))
            for name, op in ops:
                positions = [start for node in nodes for start, _ in op.mutation_positions(node)]
                found += [Mutant(module, file, name, i, start[0]) for i, start in enumerate(positions)]
        out[module] = found
    return out


def mutated_source(root: pathlib.Path, m: Mutant) -> tuple[str, str | None]:
    import cosmic_ray.plugins
    from cosmic_ray.mutating import mutate_code

    code = (root / m.file).read_text()
    return code, mutate_code(code, cosmic_ray.plugins.get_operator(m.operator)(), m.occurrence)


def _unified(m: Mutant, old: str, new: str) -> str:
    """The mutant's change to its file as a unified diff without context."""
    return "".join(difflib.unified_diff(old.splitlines(True), new.splitlines(True), m.file, m.file, n=0))


def _same_change(diff: str) -> str:
    """A mutant's diff without its hunk headers: the same change moved by
    lines added above it (a fix elsewhere in the file) is the same mutant."""
    return "".join(line for line in diff.splitlines(True) if not line.startswith("@@"))


def diff_of(root: pathlib.Path, m: Mutant) -> str:
    random.seed(m.id)
    old, new = mutated_source(root, m)
    return "" if new is None else _unified(m, old, new)


def _ci(ci95) -> str:
    """The interval in whole percent, rounded outward (84.5 % is shown as 84, not 85: the goal is a bound)."""
    lo, hi = ci95
    return f"{math.floor(100 * lo + 1e-9)}-{math.ceil(100 * hi - 1e-9)} %"


def markdown_table(doc: dict) -> str:
    """The per-module table of a results JSON (as --json writes it), in Markdown for docs/testing.md."""
    lines = ["| module | mutants | run | killed | survived | equivalent | score | 95 % CI |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in doc["modules"]:
        if r.get("score") is None:
            lines.append(f"| `{r['module']}` | {r['mutants']} | {r['run']} | | | | not measured | |")
            continue
        lines.append(f"| `{r['module']}` | {r['mutants']} | {r['run']} | {r['killed']} | {r['survived']} | "
                     f"{r['equivalent']} | {100 * r['score']:.0f} % | {_ci(r['ci95'])} |")
    return "\n".join(lines) + "\n"


EVERY_MARK = ("-m", "")
"""The module stage and every single-test rerun select the heavy tests too (pyproject's addopts deselect
them): CI runs them, so a heavy test that fails on a mutant kills it; the whole-suite stage is the
README's command."""


def _pytest(root, args, env, timeout) -> tuple[str, float, str]:
    """Run pytest in the clone: ('pass'|'fail'|'timeout', seconds, tail of the output)."""
    t0 = time.perf_counter()
    try:
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-rfE", "-p", "no:cacheprovider", *args],
                           cwd=root, env=env, capture_output=True, text=True, timeout=timeout,
                           start_new_session=True)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, ""
    lines = (r.stdout + r.stderr).strip().splitlines()
    # the first failing test (pytest -rf's summary line) names what killed the mutant, then the counts line
    first = next((ln for ln in lines if ln.startswith(("FAILED ", "ERROR "))), "")
    tail = "\n".join(([first] if first else []) + lines[-1:])
    return ("pass" if r.returncode == 0 else "fail"), time.perf_counter() - t0, tail


def _mutated(root, m: Mutant):
    """Cosmic Ray's context that applies mutant ``m`` to its file in the clone at ``root`` and restores
    the file afterwards; yields ``(old source, new source or None)``."""
    import cosmic_ray.plugins
    from cosmic_ray.mutating import use_mutation

    random.seed(m.id)   # VariableReplacer/VariableInserter draw a number/operator: reproducible
    return use_mutation(root / m.file, cosmic_ray.plugins.get_operator(m.operator)(), m.occurrence)


def _judge(root, m: Mutant, equivalents, tests, env, timeout, full) -> dict:
    """Apply mutant ``m`` in the clone at ``root``, run its module's ``tests`` (then the whole suite if
    ``full`` and they pass) and return its record: outcome killed, survived, equivalent or incompetent."""
    rec = dict(asdict(m), id=m.id)
    eq = equivalents.get(m.id)
    if eq and eq["line"] != m.line:
        print(f"  stale equivalent entry {m.id}: listed at line {eq['line']}, now {m.line}", flush=True)
        eq = None
    if eq:
        rec.update(outcome="equivalent", reason=eq["reason"])
        return rec
    with _mutated(root, m) as (old, new):
        if new is None:
            rec.update(outcome="incompetent", stage="no mutation applied")
            return rec
        rec["diff"] = _unified(m, old, new)
        if only_annotations(old, new):
            rec.update(outcome="equivalent", reason=ANNOTATION_REASON)
            return rec
        status, dt, tail = _pytest(root, ["-n", "0", *EVERY_MARK, *tests], env, timeout)
        rec.update(module_tests=status, module_seconds=round(dt, 1))
        if status == "pass" and full:
            status, dt, tail = _pytest(root, ["-n", "2"], env, 3 * timeout)
            rec.update(full_suite=status, full_seconds=round(dt, 1))
            if status == "fail":
                # the whole suite runs two workers on a loaded machine: its kill counts only if the test that
                # failed fails again alone with the mutant (a signal test that flaked under load is no kill)
                test = _failed_test(tail)
                again = _pytest(root, ["-n", "0", *EVERY_MARK, test], env, timeout)[0] if test else "fail"
                rec["confirmed"] = again != "pass"
                if again == "pass":
                    rec["unconfirmed_kill"] = " / ".join(tail.splitlines())
                    status = "pass"
    rec["outcome"] = "survived" if status == "pass" else "killed"
    if status == "fail":
        rec["killed_by"] = " / ".join(tail.splitlines())
    return rec


ANNOTATION_REASON = ("only the annotations of undecorated functions change, in a module with `from __future__ "
                     "import annotations`: they stay unevaluated strings (nothing calls get_type_hints on them)")


def only_annotations(old: str, new: str) -> bool:
    """True if sources ``old`` and ``new`` differ only in the parameter or return annotations of
    functions without decorators, in a module that starts with ``from __future__ import
    annotations`` (PEP 563: the annotations are kept as strings, never evaluated unless something
    asks, and only a decorator such as pydantic's ``validate_call`` would). Annotations of
    decorated functions and of class or module variables (which dataclasses and pydantic read)
    count as code."""
    import ast

    def stripped(src: str) -> str | None:
        try:
            tree = ast.parse(src)
        except SyntaxError:
            return None
        future = any(isinstance(n, ast.ImportFrom) and n.module == "__future__"
                     and any(a.name == "annotations" for a in n.names) for n in tree.body)
        if not future:
            return None
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.decorator_list:
                node.returns = None
                a = node.args
                for arg in (*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg):
                    if arg is not None:
                        arg.annotation = None
        return ast.dump(tree)

    before = stripped(old)
    return before is not None and old != new and before == stripped(new)


def _failed_test(tail: str) -> str | None:
    """The node id of the first failing test in a pytest -rfE summary (None if there is none)."""
    line = next((ln for ln in tail.splitlines() if ln.startswith(("FAILED ", "ERROR "))), None)
    return line.split(" ", 1)[1].split(" - ", 1)[0].strip() if line else None


def _print_outcome(rec: dict) -> None:
    first = rec.get("diff", "").splitlines()[3:5]
    print(f"  {rec['outcome']:10s} {rec['id']} (line {rec['line']}) {' | '.join(s.strip() for s in first)}",
          flush=True)


def _module_row(row: dict, results: list[dict]) -> dict:
    """``row`` with its counts, score and interval recomputed from the module's mutant records."""
    mine = [r for r in results if r["module"] == row["module"]]
    counts = {o: sum(r["outcome"] == o for r in mine) for o in ("killed", "survived", "equivalent", "incompetent")}
    k, s = counts["killed"], counts["survived"]
    lo, hi = wilson(k, k + s)
    return dict(row, **counts, score=k / (k + s) if k + s else None, ci95=[lo, hi] if k + s else None)


def draw(population: list[Mutant], seed: int, module: str, k: int) -> list[Mutant]:
    """The first ``k`` mutants of the module's seeded random order (one generator per module, so a
    module's sample does not depend on which others are measured).  ``draw(.., k)`` is the first k
    of ``draw(.., k + j)`` for every k and j, which is what lets ``--recheck`` top a sample up past
    its equivalent mutants without changing the mutants drawn.

    The mutants are picked one index at a time (``randrange(n)`` until one not drawn yet), the
    method ``random.sample`` itself uses for a sample small against the population, so a sample of
    22 from any module of more than 277 mutants (every module here) is the one ``random.sample``
    drew for the earlier runs.  ``random.sample`` is not used: it switches to a partial shuffle,
    another order, once k is large against n (a top-up of 22 + 76 from 683 mutants did), which
    broke the prefix property."""
    rng = random.Random(f"{seed}:{module}")
    n, picked, seen = len(population), [], set()
    while len(picked) < min(k, n):
        j = rng.randrange(n)
        if j not in seen:
            seen.add(j)
            picked.append(population[j])
    return picked


def recheck_settings(old: dict, sample: int, timeout: float | None) -> tuple[int, int, bool, float]:
    """``(sample, seed, no_full, timeout)`` for ``--recheck`` of the results ``old``: its seed and
    whole-suite stage; a ``--sample`` larger than the file's tops every module up to it (more of the
    same seeded order); its timeout unless ``--timeout`` is given, so the mutants are judged again
    as the run judged them (the file records one timeout)."""
    return (max(sample, old["sample"]), old["seed"], not old["full_suite"],
            old["timeout"] if timeout is None else timeout)


def _recheck(root, commit, rows, results, deselected, muts, equivalents, env, timeout, full, sample, seed) -> None:
    """Rerun, on the clone's commit, every survivor recorded in ``results`` whose mutant is still the
    same code (same diff), and update its record and its module's row in place.  Adding tests can
    only turn a survivor into a kill, so the sample stays the random sample it was drawn as."""
    by_id = {m.id: m for ms in muts.values() for m in ms}
    for i, row in enumerate(rows):
        mod = row["module"]
        # survivors, and kills by the whole suite that were not confirmed by their test alone (runs before
        # the confirmation existed), are judged again
        survivors = [r for r in results if r["module"] == mod and (r["outcome"] == "survived" or (
            r.get("full_suite") == "fail" and not r.get("confirmed")))]
        mine = [r for r in results if r["module"] == mod]
        # a sample whose equivalent (or unappliable) mutants leave fewer than --sample judged ones is topped
        # up with the next mutants of the same seeded order, so the score rests on --sample judged mutants
        # (a survivor judged again may turn equivalent: the top-up is decided after the survivors)
        extra = []
        if 0 < sample < len(muts[mod]):
            order = draw(muts[mod], seed, mod, len(mine) + 3 * sample + 10)
            if {m.id for m in order[:row["run"]]} != {r["id"] for r in mine[:row["run"]]}:
                print(f"\n{mod}: the module changed since the run (its sample is not the same), not topped up",
                      flush=True)
            else:
                extra = [m for m in order if m.id not in {r["id"] for r in mine}]
        short = sample - sum(r["outcome"] in ("killed", "survived") for r in mine)
        may_short = short + sum(r["outcome"] == "survived" and r["id"] in equivalents for r in survivors)
        if not survivors and may_short <= 0:
            continue
        tests = [t for t in TESTS[mod] if (root / t).exists()]
        failing = _failing(root, tests, env, timeout * 2)
        if failing is None:
            print(f"\n{mod}: baseline of {' '.join(tests)} does not run, survivors not rechecked", flush=True)
            continue
        deselected[mod] = sorted(set(deselected.get(mod, [])) | set(failing))
        tests += [f"--deselect={t}" for t in failing]
        print(f"\n{mod}: rechecking {len(survivors)} survivors or unconfirmed kills on {commit}", flush=True)
        for rec in survivors:
            m = by_id.get(rec["id"])
            if m is None or _same_change(diff_of(root, m)) != _same_change(rec.get("diff", "")):
                print(f"  stale      {rec['id']}: no longer the same code, kept as {rec['outcome']}", flush=True)
                continue
            test = _failed_test(rec.get("killed_by", "").replace(" / ", "\n"))
            if rec["outcome"] == "killed" and test and _fails_alone(root, m, test, env, timeout):
                rec.update(confirmed=True, confirmed_on=commit)        # the whole suite's kill stands
                _print_outcome(rec)
                continue
            new = dict(_judge(root, m, equivalents, tests, env, timeout, full), rechecked_on=commit)
            rec.clear()
            rec.update(new)
            _print_outcome(rec)
        judged = sum(r["outcome"] in ("killed", "survived") for r in results if r["module"] == mod)
        for m in extra:
            if judged >= sample:
                break
            rec = dict(_judge(root, m, equivalents, tests, env, timeout, full), topped_up_on=commit)
            results.append(rec)
            judged += rec["outcome"] in ("killed", "survived")
            _print_outcome(rec)
            row = dict(row, run=row["run"] + 1)
        rows[i] = dict(_module_row(row, results), rechecked_on=commit)


def _fails_alone(root, m: Mutant, test: str, env, timeout) -> bool:
    """Whether ``test`` fails (or errors, or times out) run alone with mutant ``m`` applied."""
    with _mutated(root, m) as (_, new):
        return new is not None and _pytest(root, ["-n", "0", *EVERY_MARK, test], env, timeout)[0] != "pass"


def merge_results(docs: list[dict]) -> dict:
    """One results document from several runs of one sample (each measuring other modules)."""
    keys = ("sample", "seed", "full_suite", "timeout")
    for d in docs[1:]:
        for k in keys:
            if d.get(k) != docs[0].get(k):
                raise ValueError(f"the files differ in {k} ({docs[0].get(k)} and {d.get(k)})")
    modules = [r["module"] for d in docs for r in d["modules"]]
    twice = sorted({m for m in modules if modules.count(m) > 1})
    if twice:
        raise ValueError(f"{twice[0]} is measured in more than one file")
    order = list(TESTS)
    return dict({k: docs[0].get(k) for k in ("tool", *keys)},
                deselected={m: t for d in docs for m, t in d.get("deselected", {}).items()},
                modules=sorted((r for d in docs for r in d["modules"]), key=lambda r: order.index(r["module"])),
                mutants=[r for d in docs for r in d["mutants"]])


def _failing(root, tests, env, timeout) -> list[str] | None:
    """The tests of ``tests`` that fail unmutated (deselected for the module's mutants, and
    reported), or None if the files do not run at all (collection error, timeout)."""
    try:
        r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-rf", "-p", "no:cacheprovider",
                            *EVERY_MARK, *tests], cwd=root, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None
    if r.returncode not in (0, 1):
        return None
    return [line.split()[1] for line in r.stdout.splitlines() if line.startswith("FAILED ")]


def _clone(dest: pathlib.Path) -> str:
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(ROOT), str(dest)], check=True)
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=dest, capture_output=True,
                          text=True, check=True).stdout.strip()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--modules", nargs="+", default=list(TESTS), metavar="MODULE",
                    help="keys of TESTS to measure (default: all)")
    ap.add_argument("--sample", type=int, default=0, help="mutants per module, drawn at random (0: all)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the sample")
    ap.add_argument("--timeout", type=float, default=None,
                    help="seconds a mutant's module tests may take (a timeout kills it); the whole suite gets 3x "
                         "(default 240; with --recheck, the results file's)")
    ap.add_argument("--only", nargs="+", metavar="ID", help="run these mutants (FILE:OPERATOR:OCCURRENCE) only")
    ap.add_argument("--no-full", action="store_true", help="do not rerun survivors against the whole suite")
    ap.add_argument("--count", action="store_true", help="print the number of mutants per module and stop")
    ap.add_argument("--show", metavar="ID", help="print the diff of one mutant (FILE:OPERATOR:OCCURRENCE) and stop")
    ap.add_argument("--json", metavar="PATH", help="write the table and every mutant's outcome as JSON")
    ap.add_argument("--resume", action="store_true",
                    help="keep the modules already measured in the --json file and run the others")
    ap.add_argument("--recheck", action="store_true",
                    help="rerun the survivors (and unconfirmed whole-suite kills) recorded in the --json file on this "
                         "checkout's HEAD (after new tests or equivalent entries), top the sample up past equivalent "
                         "mutants, and update the outcomes and the table")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="write the modules of these results files (one sample, seed and timeout) into --json and stop")
    ap.add_argument("--markdown", metavar="JSON", help="print the Markdown table of a results JSON and stop")
    a = ap.parse_args(argv)
    if a.timeout is None and not a.recheck:
        a.timeout = 240.0
    if a.markdown:
        print(markdown_table(json.loads(pathlib.Path(a.markdown).read_text())), end="")
        return 0
    if (a.recheck or a.merge) and not a.json:
        print(f"--{'recheck' if a.recheck else 'merge'}: needs --json PATH", file=sys.stderr)
        return 2
    if a.recheck and not pathlib.Path(a.json).exists():
        print(f"--recheck: {a.json} does not exist", file=sys.stderr)
        return 2
    if a.merge:
        try:
            doc = merge_results([json.loads(pathlib.Path(f).read_text()) for f in a.merge])
        except ValueError as e:
            print(f"--merge: {e}", file=sys.stderr)
            return 2
        pathlib.Path(a.json).write_text(json.dumps(doc, indent=1, default=str) + "\n")
        print(markdown_table(doc), end="")
        return 0
    unknown = [m for m in a.modules if m not in TESTS]
    if unknown:
        print(f"--modules: {unknown[0]} is not one of {', '.join(TESTS)}", file=sys.stderr)
        return 2
    equivalents = load_equivalents()

    if a.count or a.show:
        muts = enumerate_mutants(ROOT, a.modules)
        if a.show:
            m = next((m for ms in muts.values() for m in ms if m.id == a.show), None)
            if m is None:
                print(f"--show: no mutant {a.show}", file=sys.stderr)
                return 2
            print(diff_of(ROOT, m), end="")
            return 0
        for mod, ms in muts.items():
            print(f"{mod:40s} {len(ms):5d} mutants")
        return 0

    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))   # a kill still removes the scratch clone
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="tmtcontrol-mutation-"))
    root = scratch / "src"
    try:
        commit = _clone(root)
        env = dict(os.environ, PYTHONPATH=str(root), MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1",
                   TMTCONTROL_CACHE=str(scratch / "cache"), COLUMNS="400")   # pytest's summary keeps the message
        where = subprocess.run([sys.executable, "-c", "import tmtcontrol; print(tmtcontrol.__file__)"],
                               cwd=scratch, env=env, capture_output=True, text=True).stdout.strip()
        if not where.startswith(str(root)):
            print(f"a subprocess imports tmtcontrol from {where}, not the scratch clone {root}", file=sys.stderr)
            return 1
        muts = enumerate_mutants(root, a.modules)
        started = time.perf_counter()
        rows, results, deselected = [], [], {}
        if a.resume and a.json and pathlib.Path(a.json).exists():
            old = json.loads(pathlib.Path(a.json).read_text())
            rows = [r for r in old["modules"] if r.get("score") is not None]
            kept = {r["module"] for r in rows}
            results = [r for r in old["mutants"] if r["module"] in kept]
            deselected = {m: t for m, t in old.get("deselected", {}).items() if m in kept}
            print(f"resumed from {a.json}: {', '.join(sorted(kept))}", flush=True)

        if a.recheck:
            old = json.loads(pathlib.Path(a.json).read_text())
            a.sample, a.seed, a.no_full, a.timeout = recheck_settings(old, a.sample, a.timeout)
            rows, results, deselected = old["modules"], old["mutants"], old.get("deselected", {})
            a.modules = []       # no new module is measured
            _recheck(root, commit, rows, results, deselected, enumerate_mutants(root, [r["module"] for r in rows]),
                     equivalents, env, a.timeout, not a.no_full, a.sample, a.seed)

        def save():      # after every module, so an interrupted run keeps what it measured
            if a.json:
                doc = dict(tool="cosmic-ray 8.7", sample=a.sample, seed=a.seed, full_suite=not a.no_full,
                           timeout=a.timeout, deselected=deselected,
                           modules=sorted(rows, key=lambda r: list(TESTS).index(r["module"])), mutants=results)
                pathlib.Path(a.json).write_text(json.dumps(doc, indent=1, default=str) + "\n")

        for mod in a.modules:
            if any(r["module"] == mod for r in rows):
                continue
            population = muts[mod]
            chosen = population
            if 0 < a.sample < len(population):
                chosen = sorted(draw(population, a.seed, mod, a.sample),
                                key=lambda m: (m.file, m.line, m.operator, m.occurrence))
            if a.only:
                chosen = [m for m in population if m.id in a.only]
                if not chosen:
                    continue
            t_mod = time.perf_counter()
            tests = [t for t in TESTS[mod] if (root / t).exists()]
            failing = _failing(root, tests, env, a.timeout * 2)
            if failing is None:
                print(f"\n{mod}: baseline of {' '.join(tests)} does not run, module not measured", flush=True)
                rows.append(dict(module=mod, commit=commit, mutants=len(population), run=0, baseline="fails"))
                save()
                continue
            tests += [f"--deselect={t}" for t in failing]
            names = " ".join(t for t in tests if not t.startswith("-"))
            print(f"\n{mod}: {len(population)} mutants, {len(chosen)} run; tests {names}"
                  + (f"; failing unmutated, deselected: {' '.join(failing)}" if failing else ""), flush=True)
            deselected[mod] = failing
            counts = dict(killed=0, survived=0, equivalent=0, incompetent=0)
            for m in chosen:
                rec = _judge(root, m, equivalents, tests, env, a.timeout, not a.no_full)
                counts[rec["outcome"]] += 1
                results.append(rec)
                _print_outcome(rec)
            k, s = counts["killed"], counts["survived"]
            lo, hi = wilson(k, k + s)
            rows.append(dict(module=mod, commit=commit, sample=a.sample, seed=a.seed, full_suite=not a.no_full,
                             mutants=len(population), run=len(chosen), **counts,
                             minutes=round((time.perf_counter() - t_mod) / 60, 1),
                             score=k / (k + s) if k + s else None, ci95=[lo, hi] if k + s else None))
            save()
        if a.recheck:
            save()
        elapsed = time.perf_counter() - started
    finally:
        shutil.rmtree(scratch, ignore_errors=True)

    print(f"\nCosmic Ray mutants on {commit}, sample {a.sample or 'all'} per module, seed {a.seed}, "
          f"{'module tests then whole suite' if not a.no_full else 'module tests only'}, {elapsed / 60:.1f} min\n")
    print(f"{'module':36s} {'mutants':>7s} {'run':>4s} {'killed':>6s} {'surv.':>5s} {'equiv.':>6s} "
          f"{'score':>6s}  95 % CI")
    for r in rows:
        if "score" not in r:
            print(f"{r['module']:36s} {r['mutants']:7d}  baseline fails")
            continue
        ci = "" if r["score"] is None else _ci(r["ci95"])
        sc = "-" if r["score"] is None else f"{100 * r['score']:.0f} %"
        print(f"{r['module']:36s} {r['mutants']:7d} {r['run']:4d} {r['killed']:6d} {r['survived']:5d} "
              f"{r['equivalent']:6d} {sc:>6s}  {ci}")
    survivors = [r for r in results if r["outcome"] == "survived"]
    if survivors:
        print("\nSurvivors (each a missing test, or an equivalent mutant to argue in equivalent_mutants.toml):")
        for r in survivors:
            print(f"--- {r['id']}\n{r.get('diff') or '(no diff recorded)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
