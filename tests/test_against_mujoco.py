"""The bundled arms' models against MuJoCo's model of the same URDF (issue: a plant nobody here wrote).

MuJoCo is an independent implementation (C, its own recursive algorithms):
M, the bias, fk and the tip Jacobian agree to 1e-10 relative, and a model
broken by 1 % fails the row it breaks.
"""

import numpy as np
import pytest

from tmtcontrol.cli import main
from tmtcontrol.model import load_robot
from tmtcontrol.model.against_mujoco import check_against_mujoco


@pytest.mark.parametrize("arm", ["ur5", "panda"])
def test_the_bundled_arms_agree_with_mujoco(arm):
    check = check_against_mujoco(load_robot(arm), samples=10)
    assert check.ok and check.reference.startswith("mujoco ")
    assert [i.name.split(" =")[0] for i in check.identities] == ["M", "bias", "fk", "J"]
    assert max(i.worst for i in check.identities) < 1e-14          # measured 3e-15: double precision (docs/robots.md)


def test_a_bias_off_by_one_percent_fails_only_its_row(monkeypatch):
    from tmtcontrol.model.robot import Robot

    right = Robot.bias
    monkeypatch.setattr(Robot, "bias", lambda self, q, dq: 1.01 * np.asarray(right(self, q, dq)))
    rows = {i.name: i for i in check_against_mujoco(load_robot("ur5"), samples=5).identities}
    assert not rows["bias = MuJoCo qfrc_bias"].ok
    assert rows["bias = MuJoCo qfrc_bias"].worst == pytest.approx(0.01, rel=1e-6)
    assert all(r.ok for name, r in rows.items() if not name.startswith("bias"))


def test_cli_robot_against_mujoco(capsys):
    assert main(["robot", "ur5", "--against", "mujoco", "--samples", "5"]) == 0
    out = capsys.readouterr().out
    assert "M = MuJoCo mj_fullM" in out and "mujoco " in out and "all checks pass" in out


def test_the_puma_cannot_be_loaded_into_mujoco_one_line_exit_2(capsys):
    assert main(["robot", "puma560", "--against", "mujoco"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: --against mujoco: puma560 has no URDF")


@pytest.mark.parametrize("args, flag", [
    (["simulate", "ur5", "--plant", "mujoco"], "--plant mujoco"),
    (["crosscheck", "ur5"], "crosscheck"),
    (["report", "ur5", "--plant", "mujoco", "--format", "html"], "--plant mujoco"),
    (["robot", "ur5", "--against", "mujoco"], "--against mujoco"),
], ids=["simulate", "crosscheck", "report", "robot"])
def test_without_mujoco_the_flag_says_what_to_install(monkeypatch, capsys, tmp_path, args, flag):
    """Every command that needs MuJoCo, with MuJoCo not importable: exit 2,
    one stderr line naming the flag and what to install, nothing on stdout,
    and the --out folder not created (``robot`` writes no folder)."""
    import sys

    monkeypatch.setitem(sys.modules, "mujoco", None)            # import mujoco raises ImportError
    out = tmp_path / "out"
    assert main([*args, "--out", str(out)] if args[0] != "robot" else args) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert "\n" not in err and err.startswith(f"error: {flag}: MuJoCo is not installed")
    assert "pip install 'tmtcontrol[mujoco]'" in err
    assert captured.out == "" and not out.exists()
