"""The built-in scenarios: the paper's section V (``paper``) and its experiment on the bundled 6-D arms, on planes and curved parts."""

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


BUILTIN_ARMS = ("ur5", "panda", "ur5-pipe", "panda-bowl")
"""Built-in scenarios beside ``paper``: the paper's experiment on a bundled 6-D
arm, on a plane and on a curved part."""


def arm_scenario(name: str) -> Scenario:
    """The paper's experiment (section V) moved onto a bundled arm: a 0.1 m
    circle in 4 s, f_d = 10 N, the stiffness stepping 5e3 -> 2e4 -> 2e3 ->
    1e4 N/m after each cycle, 1 kHz, the tool z axis along the inward normal.
    ``"ur5"``: on the paper's 45 deg plane, centre (0.4, 0.2, 0.2) m;
    ``"panda"``: on a 30 deg plane, centre (0.5, 0, 0.3) m, the tool turned
    180 deg about the normal (the hand's comfortable wrist). On curved parts
    (the tool turning with the surface's normal): ``"ur5-pipe"``: the
    outside of a horizontal pipe of radius 0.1 m (axis along base y) from
    above, along a helix: a line at 30 deg to the pipe's circumference
    wrapped onto it, 0.1 m each way from (0.4, 0.2, 0.2) m on its top line
    and back in the 4 s period (0.866 rad round the pipe, 0.05 m along it);
    ``"panda-bowl"``: the paper's circle wrapped onto the inside of a
    spherical bowl of radius 0.25 m whose lowest point is (0.5, 0, 0.3) m. The curved parts hold the
    torque to the middle of each period (``controller.hold = "mid_period"``):
    with the zero-order hold the turning normal leaves a force ripple above
    1e-3 N on the pipe at 1 kHz (docs/surfaces.md)."""
    arms = {   # model, start-posture seed (rad), centre (m), inward normal, tool spin (deg), the shape[, the path]
        "ur5": ("ur5", (0.0, -1.9, 1.9, -1.57, -1.57, 3.14), (0.4, 0.2, 0.2), _tilted(45.0), 0.0, {}),
        "panda": ("panda", (0.0, 0.1, 0.0, -2.0, 0.0, 2.1, 0.785), (0.5, 0.0, 0.3), _tilted(30.0), 180.0, {}),
        "ur5-pipe": ("ur5", (0.0, -1.9, 1.9, -1.57, -1.57, 3.14), (0.4, 0.2, 0.2), [0.0, 0.0, -1.0], 0.0,
                     {"shape": "cylinder", "radius": 0.1, "axis": [0.0, 1.0, 0.0]},
                     {"path": "line", "direction_deg": 30.0}),
        "panda-bowl": ("panda", (0.0, 0.1, 0.0, -2.0, 0.0, 2.1, 0.785), (0.5, 0.0, 0.3), [0.0, 0.0, -1.0], 180.0,
                       {"shape": "sphere", "radius": 0.25, "side": "inside"}),
    }
    if name not in arms:
        raise ScenarioError(f"scenario: expected 'paper' or one of {', '.join(BUILTIN_ARMS)}, got {name!r}")
    model, q0, center, normal, spin, shape, *path = arms[name]
    controller = {"hold": "mid_period"} if shape else {}
    return scenario_from_dict({"name": name, "robot": {"model": model, "q0": list(q0)},
                               "environment": {"normal": normal, **shape}, "controller": controller,
                               "trajectory": {"center": list(center), "tool_spin_deg": spin, **(path[0] if path else {})}})


def _tilted(tilt_deg: float) -> list:
    """The inward normal of the plane tilted ``tilt_deg`` about base y."""
    t = math.radians(tilt_deg)
    return [math.sin(t), 0.0, -math.cos(t)]
