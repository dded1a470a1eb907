"""Issue 28: the limits along the path and from first contact where a user reads them beyond
`analyze --scenario`: a path period that is not whole control periods (the frozen-point minimum
stands in, with a note), each sweep case's own limits, and the report (its assertions are in
tests/test_report.py, on the report built once)."""

import json

import pytest

from tmtcontrol.simulation.scenario import apply_overrides, dump_scenario, paper_scenario

# 250 Hz, 1.001 s circle: 250.25 control periods per circle, so the sampled loop is not periodic
NOT_WHOLE = ["controller.rate=250", "trajectory.period=1.001"]


def test_analyze_scenario_with_a_period_not_whole_samples_falls_back_to_the_frozen_minimum(tmp_path, capsys):
    """Was exit 2 ("not a whole number of control periods"). Now exit 0 and the JSON's
    periodic_limit is the whole-loop (frozen-point) minimum, computed independently in
    this run; the note names the key and why; the first-contact search still runs
    (bounded by that minimum)."""
    from tmtcontrol.cli import main

    path = tmp_path / "s.toml"
    path.write_text(dump_scenario(apply_overrides(paper_scenario(), NOT_WHOLE)))
    assert main(["analyze", "--scenario", str(path), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["periodic_limit"] == d["whole_loop_limit"]
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
