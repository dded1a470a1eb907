"""The built-in scenarios: the paper's section V (``paper``) and its experiment on the bundled 6-D arms."""

from __future__ import annotations

import math

from .fields import ScenarioError
from .schema import Scenario, scenario_from_dict

__all__ = ["paper_scenario", "BUILTIN_ARMS", "arm_scenario"]


def paper_scenario() -> Scenario:
    """The paper's section V: 3-link PUMA, 45 deg plane, f_d = 10 N, M = I,
    B = diag[60, 20, 20], K = diag[100, 100, 100], 4 cycles of 4 s with the
    stiffness stepping 5e3 -> 2e4 -> 2e3 -> 1e4 N/m after each cycle."""
    return Scenario()


BUILTIN_ARMS = ("ur5", "panda")
"""Built-in scenarios beside ``paper``: the paper's experiment on a bundled 6-D arm."""


def arm_scenario(name: str) -> Scenario:
    """The paper's experiment (section V) moved onto a bundled arm: a 0.1 m
    circle in 4 s on a tilted plane in a comfortable part of the workspace,
    f_d = 10 N, the stiffness stepping 5e3 -> 2e4 -> 2e3 -> 1e4 N/m after
    each cycle, 1 kHz, the tool z axis along the inward normal. ``"ur5"``:
    the paper's 45 deg tilt, centre (0.4, 0.2, 0.2) m; ``"panda"``: 30 deg,
    centre (0.5, 0, 0.3) m, the tool turned 180 deg about the normal (the
    hand's comfortable wrist)."""
    arms = {   # model, start-posture seed (rad), centre (m), tilt (deg), tool spin (deg)
        "ur5": ("ur5", (0.0, -1.9, 1.9, -1.57, -1.57, 3.14), (0.4, 0.2, 0.2), 45.0, 0.0),
        "panda": ("panda", (0.0, 0.1, 0.0, -2.0, 0.0, 2.1, 0.785), (0.5, 0.0, 0.3), 30.0, 180.0),
    }
    if name not in arms:
        raise ScenarioError(f"scenario: expected 'paper' or one of {', '.join(BUILTIN_ARMS)}, got {name!r}")
    model, q0, center, tilt, spin = arms[name]
    t = math.radians(tilt)
    return scenario_from_dict({"name": name, "robot": {"model": model, "q0": list(q0)},
                               "environment": {"normal": [math.sin(t), 0.0, -math.cos(t)]},
                               "trajectory": {"center": list(center), "tool_spin_deg": spin}})
