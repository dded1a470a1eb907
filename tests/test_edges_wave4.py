"""Edge cases a user meets when deciding whether a run can be trusted (wave 4):
a guarded approach whose contact threshold, raised by the sensor noise, would
only trigger beyond the desired force."""
import math

import pytest

from tmtcontrol import apply_overrides, load_scenario
from tmtcontrol.simulation.scenario import ScenarioError
from tmtcontrol.simulation.simulator import CONTACT_NOISE_SIGMAS, contact_threshold_of


def _paper(*sets):
    return apply_overrides(load_scenario("paper"), list(sets))


def test_noise_raising_the_contact_threshold_to_f_d_is_refused_naming_the_noise():
    # unfiltered (alpha = 0): threshold = 1 N + 6 sigma = 13 N >= f_d = 10 N
    sc = _paper("trajectory.approach_gap=0.005", "sensor.noise_std=2.0")
    with pytest.raises(ScenarioError, match=r"^sensor\.noise_std: .* filtered force of 13 N .* controller\.f_d = 10 N"):
        contact_threshold_of(sc, alpha=0.0)
    # the first-order filter scales the noise by sqrt((1 - a)/(1 + a)): a = 0.9 gives 1 + 12 sqrt(0.1/1.9) = 3.75 N
    assert contact_threshold_of(sc, alpha=0.9) == pytest.approx(1 + CONTACT_NOISE_SIGMAS * 2 * math.sqrt(0.1 / 1.9),
                                                                rel=1e-12)
    # just below f_d is allowed (the bound is f_d itself): sigma = (10 - 1)/6 - 1e-9
    ok = _paper("trajectory.approach_gap=0.005", f"sensor.noise_std={9 / CONTACT_NOISE_SIGMAS - 1e-9!r}")
    assert contact_threshold_of(ok, alpha=0.0) < 10.0


def test_a_threshold_at_f_d_is_refused_naming_the_threshold_and_no_gap_means_no_check():
    sc = _paper("trajectory.approach_gap=0.005", "controller.contact_threshold=10")
    with pytest.raises(ScenarioError, match=r"^controller\.contact_threshold: 10 N is not below controller\.f_d"):
        contact_threshold_of(sc, alpha=0.0)
    # without a guarded approach the threshold is never used: the same noise is accepted
    assert contact_threshold_of(_paper("sensor.noise_std=2.0"), alpha=0.0) == pytest.approx(13.0, rel=1e-12)


def test_the_cli_refuses_it_in_one_line_and_writes_nothing(tmp_path):
    from tmtcontrol.cli import main

    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["simulate", "--set", "trajectory.approach_gap=0.005", "--set", "sensor.noise_std=2",
                     "--no-plots", "--out", str(tmp_path / "o")])
    lines = err.getvalue().strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: sensor.noise_std: "), lines
    assert list(tmp_path.iterdir()) == []
