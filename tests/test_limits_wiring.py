"""Issue 28: the limits along the path and from first contact where a user reads them beyond
`analyze --scenario`: a path period that is not whole control periods (the frozen-point minimum
stands in, with a note), each sweep case's own limits, and the report (its assertions are in
tests/test_report.py, on the report built once)."""

import json

import pytest

from tmtcontrol.simulation.scenario import apply_overrides, dump_scenario, paper_scenario

# 250 Hz, 1.001 s circle: 250.25 control periods per circle, so the sampled loop is not periodic
NOT_WHOLE = ["controller.rate=250", "trajectory.period=1.001"]


@pytest.mark.heavy      # a whole analyze --scenario (~5 s); the README suite stays within its 3 minutes
def test_analyze_scenario_with_a_period_not_whole_samples_falls_back_to_the_frozen_minimum(tmp_path, capsys,
                                                                                            monkeypatch):
    """Was exit 2 ("not a whole number of control periods"). Now exit 0 and the JSON's
    periodic_limit is the whole-loop (frozen-point) minimum (stubbed here at 4e4 N/m, with
    the periodic analysis made to fail if it is called: what is tested is the wiring); the
    note names the key and why; the first-contact search still runs (bounded by that
    minimum; the real search)."""
    from tmtcontrol.cli import main
    from tmtcontrol.stability import periodic, wholeloop

    monkeypatch.setattr(wholeloop, "whole_loop_limit", lambda *a, **k: (4e4, [(0.0, 4e4), (0.5, 4.2e4)]))
    monkeypatch.setattr(periodic, "periodic_search", lambda *a, **k: pytest.fail("periodic analysis called"))

    path = tmp_path / "s.toml"
    path.write_text(dump_scenario(apply_overrides(paper_scenario(), NOT_WHOLE)))
    assert main(["analyze", "--scenario", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["periodic_limit"] == d["whole_loop_limit"] == 4e4
    assert "trajectory.period" in d["periodic_note"] and "not a whole number" in d["periodic_note"]
    assert 0 < d["first_contact_limit"] <= d["periodic_limit"]
    assert d["limit"] == min(d["periodic_limit"], d["first_contact_limit"])
    assert d["sampled_stable"] is (d["k_e_max"] < d["limit"])
    from tmtcontrol.stability.analysis import format_analysis

    text = format_analysis(d)       # what the command prints without --json
    assert "note                 trajectory.period = 1.001 s is not a whole number" in text


def test_periodic_note_only_when_the_period_is_not_whole_samples():
    from tmtcontrol.stability.analysis import periodic_note

    assert periodic_note(apply_overrides(paper_scenario(), ["controller.rate=300"])) is None   # 4 s = 1200 Ts
    assert periodic_note(paper_scenario()) is None
    assert "1.001 s" in periodic_note(apply_overrides(paper_scenario(), NOT_WHOLE))


@pytest.mark.heavy      # a sweep with its limits (~4 s); the README suite stays within its 3 minutes
def test_each_sweep_case_carries_its_own_limits_and_the_smaller_predicts_its_verdict():
    """Paper scenario at constant k_e, delta = 0 and -10 mm (issue 28 item 1). Known
    independently: at delta = 0 the small-signal limit is the closed-form 1-D loop's
    (stability.sampled, worst path mass) and the start settles up to it; at -10 mm the
    start locks into a contact limit cycle from about 1.2e5 N/m (the case's own
    simulation says so: its verdict is limit_cycle at 1.3e5), below the small-signal
    limit (1.438e5). So at 1.3e5 N/m the prediction must come from the first-contact
    limit and say unstable, and at 1e5 N/m both say stable and the run converges."""
    from tmtcontrol.stability.analysis import scenario_parameters
    from tmtcontrol.stability.sampled import max_stable_stiffness
    from tmtcontrol.sweep import run_sweep, sweep_from_dict

    sweep = sweep_from_dict({"grid": {"environment.stiffness.values": [[1e5], [1.3e5]],
                                      "controller.x_e_error": [0.0, -0.01]}})
    df = run_sweep(sweep).set_index(["environment.stiffness.values", "controller.x_e_error"])
    # (1.3e5, 0) is the closed form too, the same check: the four cases' simulations cost ~0.2 s
    p = scenario_parameters(paper_scenario())
    closed = min(max_stable_stiffness(p["m"], p["b"], p["k"], p["Ts"], mp, kd=p["kd"], kp=p["kp"])
                 for mp in (p["m_p_min"], p["m_p_max"]))
    for ke in (1e5, 1.3e5):
        row = df.loc[(ke, 0.0)]
        assert row["small_signal_limit"] == pytest.approx(closed, rel=1e-3)     # the bisection's tolerance
        # the start settles up to the limit along the path (above the 1-D one), which then decides
        assert row["first_contact_limit"] == row["periodic_limit"] == row["predicted_limit"] > closed
        assert row["predicted_limit_from"] == "periodic orbit"
        assert row["predicted_stable"] and row["verdict"] == "converged"
    cyc, ok = df.loc[(1.3e5, -0.01)], df.loc[(1e5, -0.01)]
    assert cyc["verdict"] == "limit_cycle"
    assert 1e5 < cyc["first_contact_limit"] < 1.3e5 < cyc["small_signal_limit"]
    assert cyc["predicted_limit"] == cyc["first_contact_limit"] and not cyc["predicted_stable"]
    assert cyc["predicted_limit_from"] == "first contact"
    assert ok["predicted_stable"] and ok["verdict"] == "converged"
    assert ok["first_contact_limit"] == cyc["first_contact_limit"]    # the same inputs: the same limit
    assert (df["limits_error"] == "").all()


def test_limits_on_by_default_unless_a_random_axis_makes_each_case_a_new_analysis():
    """The default (--limits auto): a grid, or random draws of stiffness or noise (which
    leave the small-signal analysis as it was: memoised), compute the limits; random draws
    of the x_e error (a new law-loop analysis per case, ~1 s) do not, and say so."""
    import tomllib

    from tmtcontrol.sweep import EXAMPLE, run_sweep, sweep_from_dict
    from tmtcontrol.sweep.run import limits_by_default

    assert limits_by_default(sweep_from_dict(tomllib.loads(EXAMPLE)))[0] is True
    drawn = sweep_from_dict({"grid": {"environment.stiffness.values": [[1e4]], "trajectory.cycles": [0.1]},
                             "random": {"samples": 2, "seed": 1,
                                        "controller.x_e_error": {"uniform": [-0.01, 0.0]}}})
    on, why = limits_by_default(drawn)
    assert on is False and "controller.x_e_error" in why and "--limits on" in why
    df = run_sweep(drawn)
    assert "predicted_limit" not in df and len(df) == 2


def test_on_a_plane_a_part_offset_needs_the_full_limit_exactly_as_its_normal_parts_x_e_error():
    """Review 56: a run's quoted limit came from the full analysis for any nonzero part offset and from
    the 1-D figure for the same physics written as an x_e error (a plane believed 2 mm along its
    normal is exactly x_e_error = 2 mm, tests/test_surfaces.py), or with no offset at all (a 1e-12 m
    sideways one, which only moves the path). On a plane the offset counts as the x_e error of its
    normal part; on a curved part, where its normal error varies along the path, any offset counts."""
    from tmtcontrol.simulation.geometry import surface_of
    from tmtcontrol.stability.limit import _has_surface_error

    base = paper_scenario()
    R = surface_of(base).frame()
    n, t1 = R[:, 0], R[:, 1]
    at = lambda *sets: _has_surface_error(apply_overrides(base, list(sets)))
    offset = lambda v: "controller.part_offset=" + repr([float(x) for x in v])
    for s in (0.002, -0.002, 0.0):
        assert at(offset(s * n)) == at(f"controller.x_e_error={s!r}") == (s < 0), s
    assert not at(offset(1e-12 * t1)) and not at(offset(0.05 * t1))
    assert at(offset(0.003 * n - 0.001 * t1), "controller.x_e_error=-0.004")      # -0.001 in all: nearer
    assert not at(offset(0.003 * n), "controller.x_e_error=-0.002")                # +0.001 in all: deeper
    dome = ['environment.shape="sphere"', "environment.radius=0.3"]
    assert at(*dome, offset(0.002 * n)) and at(*dome, offset(1e-6 * t1)) and not at(*dome)


@pytest.mark.parametrize("f_d, settles", [(10.0, True), (2000.0, False)])
def test_the_scenarios_own_start_at_its_smallest_stiffness_is_run(f_d, settles):
    """Review 57 (high): the paper at f_d = 2,000 N (0.4 m into its 5,000 N/m part, beyond the arm:
    200,000 random poses reach about 0.40 m below the plane there) diverged in 31 ms while analyze
    said "sampled stable yes", exit 0: the searches run the start only near their limits, where the
    tool goes a fraction of a millimetre deep. The start at the scenario's smallest stiffness is run
    now; at f_d = 10 N it settles (nothing said), at 2,000 N the tool leaves the part."""
    from tmtcontrol.stability.first_contact import LoopRunner
    from tmtcontrol.stability.limit import _own_start_unsettled

    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=1", f"controller.f_d={f_d}"])
    why = _own_start_unsettled(sc, LoopRunner(sc), 5000.0, 1.6e5)
    assert (why is None) == settles, why
    if not settles:
        assert why == ("the scenario's own start does not settle at its smallest stiffness 5,000 N/m: no contact "
                       "force in the last second of 3 s: the tool left the part (the steady depth f_d/k_e is 0.4 m "
                       "there)")
    assert _own_start_unsettled(sc, None, 5000.0, 5000.0) is None          # not below the limit: not run


@pytest.mark.heavy          # the paper's limits at f_d = 2,000 N, about 9 s
def test_analyze_calls_a_scenario_whose_start_leaves_the_part_unstable_and_exits_1(capsys):
    from tmtcontrol.cli import main

    assert main(["analyze", "--scenario", "paper", "--set", "trajectory.cycles=1", "--set",
                 "controller.f_d=2000"]) == 1
    out = capsys.readouterr().out
    assert ("limit                0 N/m (the scenario's own start does not settle at its smallest stiffness "
            "5,000 N/m: no contact force") in out and "sampled stable       NO" in out


def test_a_start_too_long_to_analyse_names_the_approach_not_the_run_length():
    """Review 57 (medium): a 5 cm guarded approach at 1 um/s (a 50,000 s start) was refused as
    "trajectory.cycles: must be <= 1000, got 12500.8", a key the user never set."""
    from tmtcontrol.simulation.scenario import ScenarioError
    from tmtcontrol.stability.first_contact import LoopRunner, _start_duration

    sc = apply_overrides(paper_scenario(), ["trajectory.cycles=1", "trajectory.approach_gap=0.05",
                                            "controller.approach_speed=1e-6"])
    assert _start_duration(sc) == pytest.approx(0.05 / 1e-6 + sc.controller.force_ramp + 3.0)
    with pytest.raises(ScenarioError, match=r"^controller\.approach_speed: the stability analysis runs the "
                                            r"scenario's start for 50003\.3 s \(trajectory\.approach_gap"):
        LoopRunner(sc).run(5000.0, _start_duration(sc))


def test_a_loop_that_never_touches_the_part_is_refused_naming_the_belief_not_an_inf_bracket():
    """Review 57 (medium): the surface believed 0.2 m nearer than it is, with the command f_d/K = 0.1 m
    beyond the believed surface, never touches: the analysis said "no stability boundary found between
    inf and inf N/m", exit 2, naming no key. The frozen loop's equilibrium (force 0, closed form: the
    command ends 0.1 m short of the part) says why, naming controller.x_e_error; at -0.05 m the command
    reaches 0.05 m into the part and nothing is raised."""
    from tmtcontrol.stability.continuous import AnalysisError
    from tmtcontrol.stability.limit import _no_contact
    from tmtcontrol.stability.wholeloop import WholeLoopModel

    short = apply_overrides(paper_scenario(), ["controller.x_e_error=-0.2"])
    with pytest.raises(AnalysisError, match=r"^controller\.x_e_error: the loop holds no contact at any stiffness "
                                            r"\(at 2,000 N/m its equilibrium is off the part, force 0 N\)"):
        _no_contact(short, WholeLoopModel(short), 2000.0)
    reaches = apply_overrides(paper_scenario(), ["controller.x_e_error=-0.05"])
    assert _no_contact(reaches, WholeLoopModel(reaches), 2000.0) is None
