"""The ``[trajectory]`` section: the path on the surface (the circle of Fig. 2), its timing and the start."""

from __future__ import annotations

from pydantic import Field

from .fields import F, Section, num

__all__ = ["TrajectorySettings"]


class TrajectorySettings(Section):
    """Circle on the plane, traversed at constant rate."""
    center: tuple[F, F, F] = Field((0.5, -0.15, 0.55), description="centre, base frame [m]",
                                   json_schema_extra={"unit": "m"})
    radius: float = num(0.1, "m", "radius", ge=0)
    period: float = num(4.0, "s", "time per circle, at least 10 control periods", gt=0)
    cycles: float = num(4.0, "1", "number of circles (simulated time = cycles x period)", gt=0, le=1000)
    approach_gap: float = num(0.0, "m", "start this far above the surface, along the normal "
                              "(0 = on the surface at zero force, the paper's start)", ge=0, le=0.5)
    tool_spin_deg: float = num(0.0, "deg", "6-D arms: the commanded tool orientation is tool z along the "
                               "inward normal, tool x along task axis 1, turned by this angle about the normal",
                               ge=-180.0, le=180.0)
