"""The analysis results kept in the compile cache (tmtcontrol.cache.store_result /
load_result; stability.limit keeps the deciding limit there): a second command reads
what the first computed, equal to the last bit, and only for the same inputs
(issue 42: the cache key covers what changes the result and nothing else).

The results are off in this module's tests (conftest._shared_results); each test here
turns them on with a cache folder of its own."""
import dataclasses
import json
import os

import pytest

from tmtcontrol.simulation.scenario import apply_overrides, paper_scenario
from tmtcontrol.stability import limit


@pytest.fixture
def kept(monkeypatch, tmp_path):
    """Results kept in a private cache folder; returns the results folder."""
    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("TMTCONTROL_RESULT_CACHE", "1")
    return tmp_path / "cache" / "results"


@pytest.fixture
def counted(monkeypatch):
    """``_computed_limit`` replaced by a fake that counts its calls and returns a
    limit that depends on f_d (so a wrong hit would show)."""
    calls = []

    def fake(sc, points, along_path, runner):
        calls.append(sc.controller.f_d)
        return limit.ScenarioLimit(1e5 + sc.controller.f_d, "periodic orbit", 1.1e5, 1.05e5, (1.05e5, 1.05e5 + 0.1),
                                   ((0.0, 1.05e5), (1.0, 1.07e5)), periodic=1e5 + sc.controller.f_d,
                                   first_contact=2e5)
    monkeypatch.setattr(limit, "_computed_limit", fake)
    return calls


@pytest.mark.heavy
def test_a_second_command_reads_the_deciding_limit_the_first_computed(kept, monkeypatch):
    """The paper's real limit: computed once, stored, read back equal to the last
    bit (every field, the bracket and the per-point limits included)."""
    calls = []
    real = limit._computed_limit
    monkeypatch.setattr(limit, "_computed_limit", lambda *a: calls.append(1) or real(*a))
    sc = paper_scenario()
    first = limit.deciding_limit(sc)
    kinds = sorted(json.loads(f.read_text())["kind"] for f in kept.glob("result_*.json"))
    assert len(calls) == 1 and kinds == ["deciding_limit", "small_signal_limit"]   # its 1-D guess kept too
    second = limit.deciding_limit(sc)
    assert len(calls) == 1                       # read, not computed
    assert second == first and dataclasses.asdict(second) == dataclasses.asdict(first)
    assert isinstance(second.whole_loop_bracket, tuple) and isinstance(second.whole_loop_points[0], tuple)
    assert 1.67e5 < second.limit < 1.68e5        # the periodic orbit's 167,249 N/m (test_verdict_words)


def test_a_changed_input_is_a_new_key(kept, counted, monkeypatch, tmp_path):
    """Each input that changes the limit changes the key: a scenario value, the
    content of a stiffness table behind the same file name, the search's settings,
    the package's sources and the numerical libraries' versions."""
    import casadi

    from tmtcontrol.simulation import simulator

    sc = paper_scenario()
    limit.deciding_limit(sc)
    limit.deciding_limit(sc)
    assert counted == [10.0]                                   # the same inputs: one computation
    limit.deciding_limit(apply_overrides(sc, ["controller.f_d=12"]))
    assert counted == [10.0, 12.0]
    assert limit.deciding_limit(apply_overrides(sc, ["controller.f_d=12"])).limit == 1e5 + 12.0
    limit.deciding_limit(sc, points=4)
    limit.deciding_limit(sc, along_path=False)
    assert len(counted) == 4

    table = tmp_path / "k.csv"
    table.write_text("0, 5000\n4, 20000\n")
    on_table = apply_overrides(sc, [f"environment.stiffness={{kind='table', file='{table}'}}"])
    key = limit._result_key(on_table, 8, True)
    table.write_text("0, 5000\n4, 90000\n")                    # the same name, another range
    assert limit._result_key(on_table, 8, True) != key

    key = limit._result_key(sc, 8, True)
    monkeypatch.setattr(casadi, "__version__", casadi.__version__ + ".post1")
    assert limit._result_key(sc, 8, True) != key
    monkeypatch.undo()
    monkeypatch.setattr(simulator, "_package_digest", lambda: "another source tree")
    assert limit._result_key(sc, 8, True) != key


UNREAD_CHANGES = ["name=\"another\"", "robot.dq_max=[1.0, 1.0, 1.0]", "robot.limit_margin=0.3",
                  "robot.tool_radius=0.02", "controller.force_tolerance=0.5", "controller.orientation_tolerance=0.2",
                  "sensor.seed=7", "simulation.mujoco_contact=\"contact\"",
                  "simulation.mujoco_friction=0.3", "requirements.first_contact_overshoot=20"]
"""One change of every key of ``limit.UNREAD_KEYS`` (each a value the paper scenario does not have)."""


def test_unread_changes_cover_every_unread_key():
    """The list above changes each unread key (so the tests below try them all)."""
    changed = {c.split("=")[0] for c in UNREAD_CHANGES}
    assert {k for k in limit.UNREAD_KEYS if any(c == k or c.startswith(k + ".") for c in changed)} \
        == set(limit.UNREAD_KEYS)
    sc = paper_scenario()
    for c in UNREAD_CHANGES:                                    # each is a change of the scenario
        assert apply_overrides(sc, [c]).model_dump() != sc.model_dump(), c


@pytest.mark.parametrize("change", UNREAD_CHANGES)
def test_a_key_no_limit_reads_keeps_the_key_and_one_that_does_changes_it(change):
    """Issue 42: the key covers what changes the result and nothing else. A
    value no limit reads (the verdicts' tolerances and limits, the noise, the
    MuJoCo plant's settings; that they are unread is computed in
    test_the_limits_are_the_same_with_every_unread_key_changed) gives the same
    key; the torque limits count only where the loop clips its torque."""
    sc = paper_scenario()
    assert limit._result_key(apply_overrides(sc, [change]), 8, True) == limit._result_key(sc, 8, True)


def test_the_torque_limits_are_in_the_key_only_where_the_loop_clips_its_torque():
    sc = paper_scenario()
    tau = "robot.tau_max=[50.0, 50.0, 50.0]"
    assert limit._result_key(apply_overrides(sc, [tau]), 8, True) == limit._result_key(sc, 8, True)
    clipped = apply_overrides(sc, ["robot.saturate=true"])
    assert limit._result_key(apply_overrides(clipped, [tau]), 8, True) != limit._result_key(clipped, 8, True)
    for read in ("controller.rate=500", "sensor.filter_cutoff=40", "trajectory.approach_gap=0.002",
                 "controller.contact_threshold=0.2"):
        assert limit._result_key(apply_overrides(sc, [read]), 8, True) != limit._result_key(sc, 8, True), read


def test_the_noise_is_in_the_key_only_with_a_guarded_approach():
    """Review 49: the guarded approach's detection threshold adds 6 sigma of the
    filtered noise, which moves where the approach finds the surface, so the
    surface-location error the limits are computed with (``x_e_error`` of the
    analysis parameters, computed here). Without an approach the noise is not
    read (computed in test_the_limits_are_the_same_with_every_unread_key_changed)."""
    from tmtcontrol.stability.onedim import scenario_parameters

    sc = paper_scenario()
    noisy = ["sensor.noise_std=0.5"]
    assert limit._result_key(apply_overrides(sc, noisy), 8, True) == limit._result_key(sc, 8, True)
    approach = apply_overrides(sc, ["trajectory.approach_gap=0.002"])
    assert scenario_parameters(apply_overrides(approach, noisy))["x_e_error"] != \
        scenario_parameters(approach)["x_e_error"]
    assert "noise_std" not in limit.analysed_settings(sc)["sensor"]
    assert limit.analysed_settings(apply_overrides(approach, noisy))["sensor"]["noise_std"] == 0.5
    assert limit._result_key(apply_overrides(approach, noisy), 8, True) != limit._result_key(approach, 8, True)


def test_a_kept_limit_does_not_skip_the_per_joint_checks(kept, counted):
    """Review 49: a limit read from the results skipped building the loop, where
    a robot.dq_max of the wrong length is refused: the same command exited 0
    with the results on and 2 with them off. The checks now run first."""
    from tmtcontrol.simulation.scenario import ScenarioError

    sc = paper_scenario()
    limit.deciding_limit(sc)
    for bad in ("robot.dq_max=[1.0, 1.0]", "robot.tau_max=[50.0, 50.0]", "robot.q0=[0.1, 0.2, 0.3]"):
        with pytest.raises(ScenarioError, match=f"^{bad.split('=')[0].replace('.', '[.]')}: "):
            limit.deciding_limit(apply_overrides(sc, [bad]))
    assert counted == [10.0]


@pytest.mark.heavy
def test_the_limits_are_the_same_with_every_unread_key_changed():
    """The independent check of ``limit.UNREAD_KEYS``: the deciding limit
    (periodic orbit, first contact, the frozen loop, the 1-D figure) computed
    afresh with every unread key changed at once, and the sensor noise (read
    only with a guarded approach, which the paper has not), is the paper
    scenario's, to the last bit (nothing of them enters the computation)."""
    sc = paper_scenario()
    changed = apply_overrides(sc, [*UNREAD_CHANGES, "sensor.noise_std=0.05"])
    assert limit._computed_limit(changed, 8, True, None) == limit._computed_limit(sc, 8, True, None)


@pytest.mark.heavy
def test_the_noise_moves_the_limits_of_a_scenario_with_a_guarded_approach():
    """Review 49's case, computed afresh: paper with a 2 mm guarded approach
    and x_e_error = -2 mm; 0.5 N of noise raises the detection threshold and
    moves every limit (its 1-D figure 159,499 -> 160,775 N/m): the noise must
    be in the key of such a scenario."""
    sc = apply_overrides(paper_scenario(), ["trajectory.approach_gap=0.002", "controller.x_e_error=-0.002"])
    quiet = limit._computed_limit(sc, 8, True, None)
    noisy = limit._computed_limit(apply_overrides(sc, ["sensor.noise_std=0.5"]), 8, True, None)
    assert noisy.small_signal > quiet.small_signal * (1 + 1e-3) and noisy.limit != quiet.limit


@pytest.mark.parametrize("damage", ["not json {", "another key", "fields", "\xff\xfe"])
def test_a_damaged_or_foreign_result_is_computed_again(kept, counted, damage):
    """A file that is not JSON, holds another key (a hash collision) or another
    layout of the result is no result: the limit is computed again and kept."""
    sc = paper_scenario()
    limit.deciding_limit(sc)
    (path,) = kept.glob("result_*.json")
    if damage == "fields":
        data = json.loads(path.read_text())
        del data["value"]["first_contact"]
        path.write_text(json.dumps(data))
    elif damage == "another key":          # a whole result, of other inputs (a hash collision)
        data = json.loads(path.read_text())
        data["key"] += " of another scenario"
        data["value"]["limit"] = 1.0
        path.write_text(json.dumps(data))
    else:
        path.write_bytes(damage.encode("latin-1"))
    assert limit.deciding_limit(sc).limit == 1e5 + 10.0
    assert counted == [10.0, 10.0]
    assert limit.deciding_limit(sc).limit == 1e5 + 10.0 and counted == [10.0, 10.0]   # kept again


def test_turned_off_it_computes_every_time_and_keeps_nothing(kept, counted, monkeypatch):
    monkeypatch.setenv("TMTCONTROL_RESULT_CACHE", "0")
    sc = paper_scenario()
    limit.deciding_limit(sc)
    limit.deciding_limit(sc)
    assert counted == [10.0, 10.0] and not kept.exists()


def test_an_unwritable_cache_keeps_nothing_and_the_command_goes_on(counted, monkeypatch, tmp_path):
    """The cache folder's place is a file: nothing can be kept; the limit is
    still computed and returned (no error), and computed again next time."""
    blocker = tmp_path / "a file"
    blocker.write_text("mine")
    monkeypatch.setenv("TMTCONTROL_CACHE", str(blocker))
    monkeypatch.setenv("TMTCONTROL_RESULT_CACHE", "1")
    from tmtcontrol import cache

    monkeypatch.setattr(cache, "cache_dir", lambda: blocker)
    sc = paper_scenario()
    assert limit.deciding_limit(sc).limit == 1e5 + 10.0
    assert limit.deciding_limit(sc).limit == 1e5 + 10.0 and counted == [10.0, 10.0]
    assert blocker.read_text() == "mine"


def test_results_are_pruned_least_recently_used_first_and_by_age(tmp_path, monkeypatch):
    from tmtcontrol.cache import load_result, prune_results, store_result

    monkeypatch.setenv("TMTCONTROL_CACHE", str(tmp_path))
    for i in range(4):
        assert store_result("k", f"key {i}", {"i": i})
    files = {i: next(p for p in (tmp_path / "results").glob("result_*.json") if f'"key {i}"' in p.read_text())
             for i in range(4)}
    now = 2e9
    for i, p in files.items():           # key 0 used last, key 1 longest ago
        os.utime(p, (now - [1, 400, 300, 200][i] * 86400.0,) * 2)
    (tmp_path / "results" / "notes.txt").write_text("mine")
    assert prune_results(tmp_path / "results", max_results=2, max_age_days=350, now=now) == 2
    assert [load_result("k", f"key {i}") for i in range(4)] == [{"i": 0}, None, None, {"i": 3}]
    assert (tmp_path / "results" / "notes.txt").read_text() == "mine"


def test_a_limit_another_process_stored_while_this_one_waited_is_read_not_computed(kept, counted, monkeypatch):
    """Two processes needing the same limit at once (a report's sampled-data stage
    and its sweep): the second waits at the result's lock, then reads what the
    first stored. The "first process" stores the limit while the second holds
    its place at the lock: computed once."""
    import contextlib

    from tmtcontrol import cache

    real_lock = cache.result_lock
    sc = paper_scenario()

    @contextlib.contextmanager
    def lock_after_another_computed(kind, key, wait=None):
        cache.store_result(kind, key, dataclasses.asdict(limit.ScenarioLimit(
            99999.0, "periodic orbit", 1.1e5, 1.05e5, (1.05e5, 1.05e5), ((0.0, 1.05e5),))))
        with real_lock(kind, key, wait):
            yield

    monkeypatch.setattr(cache, "result_lock", lock_after_another_computed)
    assert limit.deciding_limit(sc).limit == 99999.0 and counted == []


@pytest.mark.heavy
def test_the_design_is_solved_once_and_read_back_equal_for_the_same_spec_only(kept, monkeypatch):
    """design_impedance (IPOPT) kept under its spec: the second call reads the
    first's result equal in every field (the spec's tuples included); another
    spec value, another start or another source tree solves again; an
    infeasible spec raises every time and keeps nothing."""
    import tmtcontrol.cache as cache
    from tmtcontrol.stability import design

    calls, solved = [], []
    real = design._designed

    def counted(*a):
        """IPOPT for the first solve; later ones are counted (whether the cache asked for a
        solve is the question), not repeated: each takes 1.5-2.5 s and is not compared."""
        calls.append(a)
        if not solved:
            solved.append(real(*a))
        return solved[0]

    monkeypatch.setattr(design, "_designed", counted)
    spec = design.DesignSpec(m=1.0, k=100.0, k_e_min=2000.0, k_e_max=20000.0, Ts=1e-3, m_p=3.3)
    first = design.design_impedance(spec)
    second = design.design_impedance(spec)
    assert len(calls) == 1 and second == first
    assert dataclasses.asdict(second) == dataclasses.asdict(first)
    assert isinstance(second.spec.b_bounds, tuple) and second.spec == spec
    design.design_impedance(dataclasses.replace(spec, max_overshoot=4.0))
    design.design_impedance(spec, b0=150.0)
    assert len(calls) == 3
    monkeypatch.setattr(cache, "_DIGEST", ["another source tree"])
    design.design_impedance(spec)
    assert len(calls) == 4
    n = len(list(kept.glob("result_*.json")))
    monkeypatch.setattr(design, "_designed", real)
    with pytest.raises(design.DesignInfeasible):
        design.design_impedance(dataclasses.replace(spec, max_overshoot=0.0, k_e_min=19000.0, b_bounds=(1.0, 2.0)))
    assert len(list(kept.glob("result_*.json"))) == n


def test_the_reports_check_rows_are_kept_per_group_scenario_and_source_tree(kept, monkeypatch):
    """kept_check_group (the report's derivation checks): a group's rows are
    run once and read back equal; the arm's rows are keyed on the scenario (a
    UR5 report does not read the PUMA's), the paper's groups on the source
    tree; tmtcontrol check's run_check_group is never kept."""
    import tmtcontrol.cache as cache
    import tmtcontrol.checks as checks
    from tmtcontrol.simulation.scenario import load_scenario

    calls = []
    real = checks.run_check_group
    monkeypatch.setattr(checks, "run_check_group", lambda g, seed=2024, scenario=None:
                        calls.append((g, None if scenario is None else scenario.name)) or real(g, seed, scenario))
    sc = paper_scenario()
    first = checks.kept_check_group("model", scenario=sc)
    second = checks.kept_check_group("model", scenario=sc)
    assert len(calls) == 1 and second == first and all(r.passed for r in first)
    checks.kept_check_group("model", scenario=apply_overrides(sc, ["controller.f_d=12.0"]))
    assert len(calls) == 2                          # another scenario value: run again
    ur5 = checks.kept_check_group("arm", scenario=load_scenario("ur5"))
    assert calls[-1] == ("arm", "ur5") and ur5 != checks.kept_check_group("arm", scenario=sc)
    law = checks.kept_check_group("law: tmt")
    assert checks.kept_check_group("law: tmt") == law and calls.count(("law: tmt", None)) == 1
    monkeypatch.setattr(cache, "_DIGEST", ["another source tree"])
    checks.kept_check_group("law: tmt")
    assert calls.count(("law: tmt", None)) == 2
    stored = len(list(kept.glob("result_*.json")))
    real("law: tmt")
    assert len(list(kept.glob("result_*.json"))) == stored


def test_the_small_signal_limit_is_kept_and_read_back_to_the_last_bit(kept, monkeypatch):
    """A warm ``simulate`` reads the 1-D limit its verdict gate needs instead of
    computing it (which would import SciPy, 0.15-0.2 s): the paper's 163,402 N/m
    computed once, read back bit for bit, and a changed input (f_d: the x_e error
    and hence the loop are the same, but the key covers every value) computed anew."""
    calls = []
    real = limit._computed_one_d
    monkeypatch.setattr(limit, "_computed_one_d", lambda sc: calls.append(sc.controller.f_d) or real(sc))
    sc = paper_scenario()
    first = limit._one_d(sc)
    assert calls == [10.0] and 1.63e5 < first < 1.64e5      # the paper's 1-D figure, 163,402 N/m
    assert limit._one_d(sc) == first and calls == [10.0]    # read, equal to the last bit
    assert limit._one_d(apply_overrides(sc, ["controller.f_d=12"])) == pytest.approx(first, rel=1e-9)
    assert calls == [10.0, 12.0]
    monkeypatch.setattr(limit, "_computed_one_d", lambda sc: float("inf"))   # no limit: JSON's Infinity
    assert limit._one_d(apply_overrides(sc, ["controller.f_d=14"])) == float("inf")
    assert limit._one_d(apply_overrides(sc, ["controller.f_d=14"])) == float("inf")


def test_the_small_signal_limit_is_not_kept_when_results_are_off(kept, monkeypatch):
    monkeypatch.setenv("TMTCONTROL_RESULT_CACHE", "0")
    calls = []
    monkeypatch.setattr(limit, "_computed_one_d", lambda sc: calls.append(1) or 1.5e5)
    sc = paper_scenario()
    assert limit._one_d(sc) == limit._one_d(sc) == 1.5e5
    assert calls == [1, 1] and not kept.exists()


@pytest.mark.heavy
def test_a_law_derived_from_a_package_law_keeps_no_result_and_no_step_key(kept, monkeypatch):
    """Regression (review F1): ``TMT.replace(name="ext", ...)``, the documented way to derive
    a law, keeps TMT's ``update``; the structure key used to test only that function's
    module, so the derived law counted as the package's own and its kept results were keyed
    by its name, states and parameter names, not its ``steady_force`` (read by the 1-D limit
    through the scheduled damping), ``initial`` or ``uses_impedance_filter``. A user who
    changed the steady-force claim then read the old 1-D figure (2,575,902 N/m kept against
    163,402 N/m computed). Now such a law has no structure key, nothing is kept, and the
    figure follows its declaration; the package's own TMT is still keyed."""
    from typing import Literal

    from tmtcontrol.control.laws import TMT, get_law, register_law, unregister_law
    from tmtcontrol.control.laws.tmt import TmtParameters
    from tmtcontrol.simulation.scenario import scenario_from_dict, scenario_to_dict
    from tmtcontrol.simulation.simulator import structure_key

    class ExtParameters(TmtParameters):
        kind: Literal["ext"] = "ext"

    def scenario():
        d = scenario_to_dict(paper_scenario())
        d["controller"]["law"] = {"kind": "ext"}
        d["controller"]["damping_schedule"] = {"kind": "zeta"}
        return scenario_from_dict(d)

    derived = TMT.replace(name="ext", parameters=ExtParameters)
    register_law(derived)
    try:
        assert structure_key(paper_scenario(), get_law("tmt")) is not None      # the package's own: keyed
        assert structure_key(scenario(), derived) is None
        assert limit._result_key(scenario(), 0, False) is None
        first = limit._one_d(scenario())
        # the same name, its declaration changed: the steady force it claims
        register_law(derived.replace(steady_force=lambda params, f_d, k, k_e, delta: 0.0), replace=True)
        second = limit._one_d(scenario())
        monkeypatch.setenv("TMTCONTROL_RESULT_CACHE", "0")
        fresh = limit._one_d(scenario())
        assert second == fresh and second != pytest.approx(first, rel=1e-3)
        assert not kept.exists() or not list(kept.glob("result_*.json"))
    finally:
        unregister_law("ext")
