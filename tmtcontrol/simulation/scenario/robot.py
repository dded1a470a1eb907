"""The ``[robot]`` section: the arm (PUMA 560, a bundled arm or a URDF), its tool frame and the controller's model of it."""

from __future__ import annotations

from pydantic import Field, StrictBool

from .fields import F, Pos, Section, num

__all__ = ["RobotSettings", "TOOL_RADIUS"]

TOOL_RADIUS = 1e-3
"""The default radius (m) of the tool's spherical tip, ``robot.tool_radius``:
the sphere of MuJoCo's ``contact`` model (:mod:`..mujoco_plant`) and the
tightest concave curvature the tool can follow (:func:`.schema.sampling_problem`)."""


class RobotSettings(Section):
    """Plant and the controller's model of it."""
    armature: StrictBool = Field(True, description="simulate the motor rotor inertias")
    friction: StrictBool = Field(False, description="simulate joint friction (smooth Coulomb + viscous)")
    model_mass_scale: float = num(1.0, "1", "scale of every mass and inertia in the controller's model "
                                  "(D*^, h*^ of eq. 5); 1.1 is a 10 % overestimate", gt=0)
    compensate_friction: StrictBool = Field(False, description="add the controller's friction model to the torque")
    model: str = Field("puma560", min_length=1, description=(
        "the arm: 'puma560' (the paper's 3 links, position-only task), a bundled arm ('ur5', 'panda') or the "
        "path of a .urdf file (a relative path is read from the scenario file's folder); an arm with 6 or more "
        "joints runs the 6-D task (position and orientation, docs/robots.md)"))
    tip: str | None = Field(None, min_length=1, description="the tool frame (link or fixed frame); default: the "
                            "arm's documented tip")
    q0: tuple[F, ...] | None = Field(None, min_length=1, description=(
        "start posture guess (one value per joint) for the start-posture solver; default: the middle of the "
        "joint limits [rad or m]"), json_schema_extra={"unit": "rad"})
    posture_kp: float = num(25.0, "1/s^2", "null-space posture stiffness of a redundant arm (more joints "
                            "than task axes: 4 or 5 joints, or more than 6)", ge=0)
    posture_kd: float = num(10.0, "1/s", "null-space posture damping of a redundant arm (more joints "
                            "than task axes: 4 or 5 joints, or more than 6)", ge=0)
    tau_max: tuple[Pos, ...] | None = Field(None, min_length=1, description=(
        "joint torque limits, one per joint (N for a prismatic joint); default: the robot's own (URDF effort; "
        "the paper's PUMA parameter set has none) [N m]"), json_schema_extra={"unit": "N m"})
    dq_max: tuple[Pos, ...] | None = Field(None, min_length=1, description=(
        "joint rate limits, one per joint (m/s for a prismatic joint); default: the robot's own (URDF "
        "velocity; the PUMA's: none) [rad/s]"), json_schema_extra={"unit": "rad/s"})
    limit_margin: float = num(0.0, "1", "fraction of each limit held in reserve: a torque or rate above "
                              "(1 - margin) x its limit, or a joint within margin x half its range of either "
                              "end, is over the limit (verdict over_limit)", ge=0, lt=1)
    tool_radius: float = num(TOOL_RADIUS, "m", (
        "radius of the tool's spherical tip, whose point furthest along the tool's z axis (into the part) is the "
        "tool point: a concave part (a bowl, a bore, a valley of a height map) must curve less tightly than the "
        "tip along the path (its smallest concave radius of curvature above this), and MuJoCo's own contact "
        "(simulation.mujoco_contact = \"contact\") touches the part with this sphere"), gt=0)
    saturate: StrictBool = Field(False, description=(
        "the drive model: clip the applied joint torque at tau_max, as a real drive does (the exported C "
        "clips at the same parameter); off, the torque is whatever the controller asks and a run beyond a "
        "limit is judged over_limit"))
