"""Scenario dataclasses, TOML round trip and validation messages."""
import math

import pytest
from pydantic import ValidationError

from tmtcontrol import ScenarioError, apply_overrides, dump_scenario, load_scenario, paper_scenario
from tmtcontrol.simulation.scenario import ControllerSettings, scenario_from_dict, scenario_to_dict


def test_paper_scenario_values():
    sc = paper_scenario()
    assert sc.controller.f_d == 10.0
    assert sc.impedance.m == (1.0, 1.0, 1.0)
    assert sc.impedance.b == (60.0, 20.0, 20.0)
    assert sc.impedance.k == (100.0, 100.0, 100.0)
    assert sc.impedance.gains == ((60.0, 20.0, 20.0), (100.0, 100.0, 100.0))   # eq. (9)
    assert sc.environment.tilt_deg == 45.0
    assert sc.trajectory.period == 4.0 and sc.duration == 16.0
    ks = sc.environment.stiffness.values
    assert max(ks) / min(ks) >= 10 and max(ks) >= 1e4            # spans a decade, one >= 1e4
    assert sc.robot.armature and not sc.robot.friction


def test_toml_round_trip(tmp_path):
    sc = apply_overrides(paper_scenario(), ["controller.f_d=7.5", "sensor.noise_std=0.1",
                                            "environment.stiffness.values=[1e3, 3e3]"])
    path = tmp_path / "s.toml"
    path.write_text(dump_scenario(sc))
    assert load_scenario(path) == sc
    assert scenario_from_dict(scenario_to_dict(sc)) == sc


def test_frozen():
    with pytest.raises(ValidationError, match="frozen"):
        paper_scenario().controller.f_d = 3.0


@pytest.mark.parametrize("toml,match", [
    ("[controller]\nf_dd = 3\n", r"controller\.f_dd: unknown key"),
    ("[controler]\n", r"controler: unknown key"),
    ("[controller]\nf_d = \"ten\"\n", r"controller\.f_d: expected a number"),
    ("[controller]\nf_d = nan\n", r"controller\.f_d: must be finite"),
    ("[controller]\nrate = inf\n", r"controller\.rate: must be finite"),
    ("[controller]\nrate = -5\n", r"controller\.rate: must be > 0"),
    ("[impedance]\nm = [0, 1, 1]\n", r"impedance\.m\[0\]: must be > 0"),
    ("[impedance]\nb = [60, -1, 20]\n", r"impedance\.b\[1\]: must be >= 0"),
    ("[impedance]\nk = [100, 100]\n", r"impedance\.k: expected a list of 3 numbers"),
    ("[environment.stiffness]\nvalues = []\n", r"environment\.stiffness\.values: empty list"),
    ("[environment.stiffness]\nvalues = [1e3, -2]\n", r"environment\.stiffness\.values\[1\]: must be > 0"),
    ("[environment]\ndamping = -1\n", r"environment\.damping: must be >= 0"),
    ("[controller]\nlaw = \"magic\"\n", r"controller\.law: expected kind one of 'tmt', 'known'"),
    ("[simulation]\nsubsteps = 2.5\n", r"simulation\.substeps: expected an integer"),
    ("[controller\n", r"malformed TOML"),
])
def test_bad_files_name_the_key(tmp_path, toml, match):
    path = tmp_path / "bad.toml"
    path.write_text(toml)
    with pytest.raises(ScenarioError, match=match):
        load_scenario(path)


def test_missing_file():
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario("/nonexistent/scenario.toml")


def test_overrides():
    sc = apply_overrides(paper_scenario(), ["controller.law=known", "impedance.b=[80, 20, 20]"])
    assert sc.controller.law.kind == "known" and sc.impedance.b == (80.0, 20.0, 20.0)
    with pytest.raises(ScenarioError, match="controller.nope: unknown key"):
        apply_overrides(paper_scenario(), ["controller.nope=1"])
    with pytest.raises(ScenarioError, match=r"impedance\.b: expected a list, got '\[1, x\]' \(in --set\)"):
        apply_overrides(paper_scenario(), ["impedance.b=[1, x]"])
    with pytest.raises(ScenarioError, match="expected dotted.key=value"):
        apply_overrides(paper_scenario(), ["controller.f_d"])


def test_direct_construction_validates():
    with pytest.raises(ValidationError, match="f_d"):
        ControllerSettings(f_d=-1.0)
    assert math.isclose(ControllerSettings(rate=500).Ts, 2e-3)
