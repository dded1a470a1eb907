"""``tmtcontrol design --scenario``: the specification from a scenario, the
effective normal mass from its arm's path (cross-checked with Pinocchio),
the same design as the equivalent explicit flags, and bad input."""
import json

import numpy as np
import pytest

from tmtcontrol.cli import main
from tmtcontrol.simulation.scenario import apply_overrides, load_scenario
from tmtcontrol.stability.design import DESIGN_OVERSHOOT, scenario_design_spec


def _pinocchio_normal_masses(sc):
    """1/(n^T J_v M^-1 J_v^T n) at the checked path poses, M and J from Pinocchio (not tmtcontrol's model)."""
    pytest.importorskip("pinocchio")
    from tmtcontrol.model.verify import pinocchio_model
    from tmtcontrol.simulation.geometry import surface_frame
    from tmtcontrol.simulation.simulator import path_of, robot_of

    robot = robot_of(sc)
    evaluate = pinocchio_model(robot)
    n = surface_frame(sc.environment)[:, 0]
    out = []
    for q in path_of(robot, sc).q.T:
        d = evaluate(q, np.zeros(robot.n), np.zeros(robot.n))
        Jv = d["J"][:3]
        out.append(float(1.0 / (n @ Jv @ np.linalg.solve(d["M"], Jv.T @ n))))
    return out


def test_the_ur5_spec_is_the_scenarios_with_the_paths_largest_normal_mass():
    sc = load_scenario("ur5")
    spec = scenario_design_spec(sc)
    masses = _pinocchio_normal_masses(sc)
    # both from double-precision M and J of the same URDF: agreement to round-off (1e-10 relative)
    assert spec.m_p == pytest.approx(max(masses), rel=1e-10)
    assert max(masses) > 1.05 * min(masses)                  # the mass does vary along the path: max is a choice
    assert (spec.m, spec.k, spec.Ts, spec.f_d) == (sc.impedance.m[0], sc.impedance.k[0], sc.controller.Ts,
                                                    sc.controller.f_d)
    values = sc.environment.stiffness.values
    assert (spec.k_e_min, spec.k_e_max) == (min(values), max(values))
    assert spec.max_overshoot == DESIGN_OVERSHOOT and spec.delay == sc.controller.delay_samples
    # docs/design.md quotes the range to 0.1 kg
    import pathlib
    import re

    doc = (pathlib.Path(__file__).parents[1] / "docs" / "design.md").read_text()
    lo, hi = re.search(r"UR5\s+scenario it spans about ([\d.]+)–([\d.]+) kg", doc).groups()
    assert (lo, hi) == (f"{min(masses):.1f}", f"{max(masses):.1f}")


def test_the_paper_spec_uses_the_pumas_mass_as_analyze_does():
    from tmtcontrol.stability import paper_effective_mass

    spec = scenario_design_spec(load_scenario("paper"))
    assert spec.m_p == paper_effective_mass(worst=True)      # the flag-only design's default: the same mass


def test_flags_override_the_scenario_and_a_new_ts_moves_the_filter_pole():
    sc = apply_overrides(load_scenario("paper"), ["sensor.filter_cutoff=50"])
    spec = scenario_design_spec(sc, Ts=0.002, k_e_max=3e4, m_p=5.0, f_d=None)
    assert (spec.Ts, spec.k_e_max, spec.m_p, spec.f_d) == (0.002, 3e4, 5.0, sc.controller.f_d)
    # first-order filter pole exp(-2 pi f_c Ts) at the new period
    assert spec.alpha == pytest.approx(np.exp(-2 * np.pi * 50 * 0.002), rel=1e-12)


def _explicit_flags(sc, m_p):
    values = sc.environment.stiffness.values
    return ["design", "--m", repr(sc.impedance.m[0]), "--k", repr(sc.impedance.k[0]), "--ke-min", repr(min(values)),
            "--ke-max", repr(max(values)), "--ts", repr(sc.controller.Ts), "--max-overshoot", "5",
            "--fd", repr(sc.controller.f_d), "--mp", repr(m_p), "--json"]


def test_design_scenario_ur5_passes_the_spec_of_the_explicit_flags(monkeypatch):
    """The CLI wiring, without IPOPT: both command lines hand design_impedance the same spec."""
    import dataclasses

    import tmtcontrol.stability.design as design

    specs = []

    def capture(spec, *a, **kw):
        specs.append(spec)
        raise design.DesignError("m: captured")             # stop before IPOPT (exit 2)

    monkeypatch.setattr(design, "design_impedance", capture)
    sc = load_scenario("ur5")
    assert main(["design", "--scenario", "ur5"]) == 2
    assert main(_explicit_flags(sc, max(_pinocchio_normal_masses(sc)))) == 2
    a, b = (dataclasses.asdict(s) for s in specs)
    assert a.pop("m_p") == pytest.approx(b.pop("m_p"), rel=1e-10) and a == b


@pytest.mark.heavy
def test_design_scenario_ur5_equals_the_explicit_flags(capsys):
    """Both designs solved (two IPOPT runs and their verifications, ~10 s)."""
    sc = load_scenario("ur5")
    assert main(["design", "--scenario", "ur5", "--json"]) == 0
    from_scenario = json.loads(capsys.readouterr().out)
    assert main(_explicit_flags(sc, max(_pinocchio_normal_masses(sc)))) == 0
    explicit = json.loads(capsys.readouterr().out)
    assert from_scenario["verified"] and explicit["verified"]
    # m_p agrees to ~1e-15 between the two sources; IPOPT's optimum moves by far less than its 1e-8 tolerance
    assert from_scenario["b"] == pytest.approx(explicit["b"], rel=1e-6)
    for key in ("k", "k_e_min", "k_e_max", "Ts", "max_overshoot", "m", "f_d", "delay"):
        assert from_scenario[key] == explicit[key]
    assert from_scenario["m_p"] == pytest.approx(max(_pinocchio_normal_masses(sc)), rel=1e-10)


@pytest.mark.parametrize("argv, needle", [
    (["design", "--scenario", "no_such_scenario.toml"], "no_such_scenario.toml"),
    (["design", "--scenario", "ur5", "--ke-min", "1e5"], "--ke-min: must be <= k_e_max"),
    (["design", "--scenario", "paper", "--filter-hz", "1e9"], "--filter-hz: must be below the Nyquist"),
    (["design", "--scenario", "paper", "--filter-hz", "1e-300"], "--filter-hz: 1e-300 Hz is so low"),
    (["design", "--scenario", "paper", "--mp", "-1"], "--mp: must be"),
    (["design", "--m", "1", "--k", "100"], "--ke-min: required (or use --scenario)"),
])
def test_design_bad_input_is_one_line_exit_2_nothing_written(argv, needle, tmp_path, capsys):
    assert main([*argv, "--plot", str(tmp_path / "figs")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and needle in err and "Traceback" not in err
    assert not (tmp_path / "figs").exists()


@pytest.mark.heavy   # a design and the report's design stage (6-15 s of one worker): CI's heavy step runs it
def test_a_stated_overshoot_requirement_is_the_designs_bound_and_the_reports_verdict():
    """[requirements] first_contact_overshoot: the design's bound and, only then, a report verdict on the
    scenario's own b. The paper's b = 60 N s/m: damping ratio 0.21 at 2e4 N/m (eq. 25's
    zeta = b/(2 sqrt(m (k + k_e)))), whose continuous step overshoot exp(-pi zeta/sqrt(1 - zeta^2)) = 50.6 %;
    the 1-D sampled loop's 54.8 % is within 10 % of that closed form."""
    import math

    from tmtcontrol.report.document import Report, _design
    from tmtcontrol.simulation.scenario import paper_scenario
    from tmtcontrol.stability import scenario_parameters

    zeta = 60 / (2 * math.sqrt(1 * (100 + 2e4)))
    closed = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    for bound, passed in ((5.0, False), (60.0, True)):
        sc = apply_overrides(paper_scenario(), [f"requirements.first_contact_overshoot={bound}"])
        assert scenario_design_spec(sc).max_overshoot == bound
        rep = Report(sc, "test")
        _design(rep, sc, scenario_parameters(sc), None, None)
        (v,) = rep.verdicts
        assert v.name.startswith("Scenario's damping within requirements.first_contact_overshoot")
        assert v.passed is passed and "at k_e = 20,000 N/m" in v.value and "54.8 %" in v.value
        assert abs(54.8 / closed - 1) < 0.1
    rep = Report(paper_scenario(), "test")
    _design(rep, paper_scenario(), scenario_parameters(paper_scenario()), None, None)
    assert rep.verdicts == []                                  # nobody stated a bound: information only


def test_the_reports_effective_normal_mass_is_pinocchios_along_the_path():
    """The report shows m_p = 1/(n^T J_v M^-1 J_v^T n) along the path: equal to Pinocchio's M and J at the
    same poses (1e-10 relative: both double precision from the same URDF), range quoted in its sentence."""
    from tmtcontrol.report.document import Report, _normal_mass_blocks
    from tmtcontrol.stability import scenario_parameters

    sc = load_scenario("ur5")
    rep = Report(sc, "test")
    para, fig = _normal_mass_blocks(rep, sc, scenario_parameters(sc))
    ref = np.array(_pinocchio_normal_masses(sc))
    np.testing.assert_allclose(rep.data["normal_mass"]["m_p"], ref, rtol=1e-10)
    assert f"{ref.max():.3g}" in para.text.replace("\xa0", " ") and "ur5" in para.text
    assert fig.caption.startswith("Effective normal mass m_p of the ur5") and "<svg" in fig.svg
