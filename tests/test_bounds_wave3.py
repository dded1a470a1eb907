"""Numbers the analysis cannot mean are refused in one line naming the flag (review of issue 27.5):
an impedance mass of 1e300 or 1e-300 kg, or a damping of 1e12 N s/m, left python-control's step_info
an empty response (IndexError traceback); `robot --samples 1e9` ran until killed."""
import pytest

from tmtcontrol.cli import main

BASE = ["--ke", "5000", "--ts", "0.001"]


@pytest.mark.parametrize("args, flag", [
    (["--m", "1e300", "--b", "60", "--k", "100"], "--m"),
    (["--m", "1e-300", "--b", "60", "--k", "100"], "--m"),
    (["--m", "1", "--b", "1e12", "--k", "100"], "--b"),
    (["--m", "1", "--b", "60", "--k", "1e9"], "--k"),
])
def test_analyze_refuses_an_impedance_outside_the_schema(capsys, args, flag):
    assert main(["analyze", *args, *BASE]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {flag}: must be"), err


def test_the_scenario_schema_bounds_the_impedance_the_same_way():
    from tmtcontrol import ScenarioError, apply_overrides, paper_scenario

    with pytest.raises(ScenarioError, match="impedance.b"):
        apply_overrides(paper_scenario(), ["impedance.b=[1e12, 20.0, 20.0]"])
    assert apply_overrides(paper_scenario(), ["impedance.b=[1e6, 20.0, 20.0]"]).impedance.b[0] == 1e6


def test_robot_refuses_an_unbounded_number_of_samples(capsys):
    assert main(["robot", "ur5", "--samples", "1000000000"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --samples:"), err


def test_an_unknown_robot_name_lists_the_bundled_arms(capsys):
    # `robot nope` said only "cannot read (No such file or directory)" (review of issue 29)
    assert main(["robot", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nope: not a bundled arm" in err[0]
    assert all(name in err[0] for name in ("puma560", "ur5", "panda"))
