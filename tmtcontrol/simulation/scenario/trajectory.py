"""The ``[trajectory]`` section: the path on the surface (the circle of Fig. 2, a line or a raster), its timing and the start."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .fields import F, Section, num

__all__ = ["TrajectorySettings"]


class TrajectorySettings(Section):
    """The path on the surface, periodic: the circle of Fig. 2 at constant
    rate (default), a line back and forth, or a smooth raster over a square
    patch (:mod:`tmtcontrol.simulation.trajectory`)."""
    path: Literal["circle", "line", "raster"] = Field("circle", description=(
        "the path: circle (section V), line (back and forth) or raster (lawn-mower sweep over a square)"))
    center: tuple[F, F, F] = Field((0.5, -0.15, 0.55), description="centre, base frame [m]",
                                   json_schema_extra={"unit": "m"})
    radius: float = num(0.1, "m", "radius: the circle's, the line's half-length, the raster's half-side", ge=0)
    lanes: int = Field(6, ge=2, le=100, strict=True, description="raster: passes across the patch per period")
    direction_deg: float = num(0.0, "deg", "line and raster: direction of the passes in the tangent plane, "
                               "from task axis 1", ge=-180.0, le=180.0)
    period: float = num(4.0, "s", "time per circle (per period of the path), at least 10 control periods", gt=0)
    cycles: float = num(4.0, "1", "number of periods (simulated time = cycles x period)", gt=0, le=1000)
    approach_gap: float = num(0.0, "m", "start this far above the surface, along the normal "
                              "(0 = on the surface at zero force, the paper's start)", ge=0, le=0.5)
    tool_spin_deg: float = num(0.0, "deg", "6-D arms: the commanded tool orientation is tool z along the "
                               "inward normal, tool x along task axis 1, turned by this angle about the normal",
                               ge=-180.0, le=180.0)

    @model_validator(mode="after")
    def _path_keys(self):
        # a value other than the default on a path that does not use it (a dump writes every key, so a
        # default value is not taken as the user's)
        for key, paths in (("lanes", ("raster",)), ("direction_deg", ("line", "raster"))):
            if getattr(self, key) != type(self).model_fields[key].default and self.path not in paths:
                raise ValueError(f"{key}: not used by path = {self.path!r} (only by {' and '.join(paths)})")
        return self
