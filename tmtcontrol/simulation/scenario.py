"""Scenario settings: one declarative schema (pydantic v2), TOML load/dump, overrides.

A :class:`Scenario` fully describes one simulation of section V of the paper:
robot, environment (tilted plane and stiffness profile), circular path,
impedance parameters (eqs. 2-3, 9), controller and force-tracking law
(eqs. 11-12, 18 and the baselines of ``control.laws``), force sensor, and
integrator. Every field is SI (m, s, N, N/m, kg, Hz) and carries its unit,
default and range in the schema; models are frozen and forbid unknown keys.
The stiffness profile, the law and the damping schedule are tagged unions on
``kind``: each kind has exactly its own fields.

Errors are :class:`ScenarioError`, one line: ``dotted.key: expected ..., got
... (in FILE)``. :func:`scenario_json_schema` gives the JSON Schema
(``tmtcontrol scenario --schema``); ``docs/scenario.md`` is generated from it.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import pathlib
import re
import tomllib
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union

from pydantic import (BaseModel, BeforeValidator, ConfigDict, Field, StrictBool, StrictInt, ValidationError,
                      model_serializer, model_validator)
from pydantic.fields import FieldInfo

from ..control.laws import laws, on_register
from ..control.laws.tmt import TmtParameters

__all__ = [
    "ScenarioError", "RobotSettings", "PiecewiseConstantStiffness", "PiecewiseLinearStiffness",
    "SinusoidalStiffness", "TableStiffness", "EnvironmentSettings", "TrajectorySettings",
    "ImpedanceSettings", "FixedDamping", "ScheduledDamping", "ControllerSettings", "SensorSettings",
    "SimulationSettings", "Scenario", "paper_scenario", "load_scenario", "scenario_from_dict",
    "scenario_to_dict", "dump_scenario", "apply_overrides", "set_key", "scenario_json_schema",
    "read_stiffness_table", "SettingRow", "TAGGED_TABLES", "applicable_settings", "read_text_file", "InputFileError",
    "MAX_INPUT_BYTES", "MAX_STIFFNESS", "MIN_PERIODS", "sampling_problem", "check_setting", "check_period",
    "check_filter_cutoff", "setting_bounds", "BUILTIN_ARMS", "arm_scenario",
]


class ScenarioError(ValueError):
    """Invalid scenario input; the message names the key and the problem."""


def num(default, unit: str, doc: str, **limits) -> Any:
    """A finite number field (an integer is accepted) with its unit."""
    return Field(default, description=f"{doc} [{unit}]", allow_inf_nan=False, strict=True,
                 json_schema_extra={"unit": unit}, **limits)


F = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Pos = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
NonNeg = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]

MAX_STIFFNESS = 1e10
"""The stiffest environment a scenario (or ``analyze``/``design``) takes, N/m:
far stiffer than any contact a force-controlled arm meets (steel on steel at
these scales is about 1e8-1e9 N/m); above it the analysis' numbers overflow."""

MIN_PERIODS = 10
"""A path period, a stiffness segment and a stiffness sinusoid's period are at
least this many control periods (fewer samples cannot resolve them)."""

Stiff = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0, le=MAX_STIFFNESS)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _tagged(value, default: str | None = None):
    """``"name"`` is shorthand for ``{kind = "name"}`` in a tagged union; a
    table without ``kind`` is of the union's default kind."""
    if isinstance(value, str):
        return {"kind": value}
    if isinstance(value, dict) and "kind" not in value and default is not None:
        return {"kind": default, **value}
    return value


def _tag_default(default: str):
    return BeforeValidator(lambda v: _tagged(v, default))


# -- robot ---------------------------------------------------------------------------

class RobotSettings(_Section):
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
    posture_kp: float = num(25.0, "1/s^2", "null-space posture stiffness of a redundant arm (more than 6 joints)",
                            ge=0)
    posture_kd: float = num(10.0, "1/s", "null-space posture damping of a redundant arm (more than 6 joints)",
                            ge=0)


# -- environment ---------------------------------------------------------------------

class PiecewiseConstantStiffness(_Section):
    """``values[i]`` on ``[i, i+1) * segment``, the last value held (Fig. 3)."""
    kind: Literal["piecewise_constant"] = "piecewise_constant"
    values: tuple[Stiff, ...] = Field((5e3, 2e4, 2e3, 1e4), min_length=1,
                                    description="stiffness of each segment [N/m]", json_schema_extra={"unit": "N/m"})
    segment: float = num(0.0, "s", "segment length, 0 (= the trajectory period) or at least 10 control "
                         "periods", ge=0)


class PiecewiseLinearStiffness(_Section):
    """Linear interpolation through (``times``, ``values``), held outside."""
    kind: Literal["piecewise_linear"] = "piecewise_linear"
    times: tuple[NonNeg, ...] = Field(..., min_length=1, description="knot times, strictly increasing [s]",
                                      json_schema_extra={"unit": "s"})
    values: tuple[Stiff, ...] = Field(..., min_length=1, description="stiffness at the knots [N/m]",
                                    json_schema_extra={"unit": "N/m"})

    @model_validator(mode="after")
    def _knots(self):
        if len(self.times) != len(self.values):
            raise ValueError(f"times: needs one time per value ({len(self.values)}), got {len(self.times)}")
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ValueError(f"times: must be strictly increasing, got {list(self.times)}")
        return self


class SinusoidalStiffness(_Section):
    """``mean + amplitude sin(2 pi t / period)``."""
    kind: Literal["sinusoidal"] = "sinusoidal"
    mean: float = num(1e4, "N/m", "mean stiffness", gt=0, le=MAX_STIFFNESS)
    amplitude: float = num(5e3, "N/m", "amplitude, < mean so that k_e stays > 0", ge=0)
    period: float = num(4.0, "s", "period, at least 10 control periods", gt=0)

    @model_validator(mode="after")
    def _positive(self):
        if self.amplitude >= self.mean:
            raise ValueError(f"amplitude: must be < mean ({self.mean:g}) so that k_e stays > 0, "
                             f"got {self.amplitude:g}")
        return self


class TableStiffness(_Section):
    """A CSV file of ``t, k_e`` rows (s, N/m), linear interpolation. A header
    row is allowed only if it holds no number; a relative path is relative
    to the scenario file."""
    kind: Literal["table"] = "table"
    file: str = Field(..., min_length=1, description="CSV file of t, k_e rows")

    @model_validator(mode="after")
    def _readable(self):
        read_stiffness_table(self.file)
        return self


StiffnessProfile = Annotated[
    Union[PiecewiseConstantStiffness, PiecewiseLinearStiffness, SinusoidalStiffness, TableStiffness],
    _tag_default("piecewise_constant"), Field(discriminator="kind")]


def read_stiffness_table(path: str | pathlib.Path) -> tuple[Any, Any]:
    """Read and validate a CSV table of ``t, k_e`` rows (s, N/m). A first row
    with no number in it is a header; any other malformed row is an error."""
    import numpy as np

    try:
        text = read_text_file(path)
    except InputFileError as exc:
        reason = str(exc)
        if reason == "no such file":
            raise ValueError(f"file: no such file {str(path)!r}") from None
        if reason == "is a folder":
            raise ValueError(f"file: {str(path)!r} is a folder, expected a CSV file") from None
        if reason.startswith("not UTF-8"):
            raise ValueError(f"file: {str(path)!r} is not UTF-8 text") from None
        raise ValueError(f"file: {str(path)!r}: {reason}") from None
    rows = [r for r in csv.reader(io.StringIO(text, newline=""))
            if r and "".join(r).strip() and not r[0].lstrip().startswith("#")]

    def number(cell):
        try:
            return float(cell)
        except ValueError:
            return None

    data = []
    for i, row in enumerate(rows):
        vals = [number(c) for c in row]
        if len(row) == 2 and None not in vals:
            data.append(vals)
        elif i == 0 and all(v is None for v in vals):
            continue  # header: no number in it
        else:
            shown = repr(row)
            if len(shown) > 200:            # one short line, whatever the row
                shown = f"{shown[:120]}... ({len(row)} fields)"
            raise ValueError(f"file: row {i + 1} of {str(path)!r} is not 't, k_e' numbers: {shown}")
    if not data:
        raise ValueError(f"file: no data rows in {str(path)!r}")
    arr = np.array(data)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"file: non-finite value in {str(path)!r}")
    if np.any(arr[:, 1] <= 0):
        raise ValueError(f"file: stiffness must be > 0 in {str(path)!r}")
    if np.any(arr[:, 1] > MAX_STIFFNESS):
        raise ValueError(f"file: stiffness must be <= {MAX_STIFFNESS:g} N/m in {str(path)!r}")
    if np.any(np.diff(arr[:, 0]) <= 0):
        raise ValueError(f"file: times must be strictly increasing in {str(path)!r}")
    return arr[:, 0], arr[:, 1]


class EnvironmentSettings(_Section):
    """The tilted plane (Fig. 2) and its unilateral spring contact,
    ``f_e = max(0, k_e(t) d + damping d')`` while the penetration d > 0. The
    plane passes through ``trajectory.center``; its outward normal is base z
    rotated by ``tilt_deg`` about base y."""
    tilt_deg: float = num(45.0, "deg", "tilt of the plane about the base y axis (the shorthand for the "
                          "inward normal (sin t, 0, -cos t); not used when normal is set)", ge=-89.0, le=89.0)
    normal: tuple[F, F, F] | None = Field(None, description=(
        "inward unit normal of the plane (pointing into the surface), base frame; 6-D arms only; default: "
        "from tilt_deg"), json_schema_extra={"unit": "1"})
    point: tuple[F, F, F] | None = Field(None, description=(
        "a point of the plane, base frame; default: trajectory.center (the circle's centre must lie on the "
        "plane)"), json_schema_extra={"unit": "m"})
    damping: float = num(0.0, "N s/m", "contact damping", ge=0)
    stiffness: StiffnessProfile = Field(default_factory=PiecewiseConstantStiffness,
                                        description="stiffness profile k_e(t), a table with its kind")

    @model_serializer(mode="wrap")
    def _without_unused_tilt(self, handler):
        # with a normal, the plane is the normal's: the shorthand is left out of every dump (TOML,
        # summary.json, a replaced copy), so it never comes back as an explicit, contradicting value
        d = handler(self)
        if isinstance(d, dict) and d.get("normal") is not None:
            d.pop("tilt_deg", None)
        return d

    @model_validator(mode="after")
    def _unit_normal(self):
        if self.normal is not None:
            norm = math.sqrt(sum(x * x for x in self.normal))
            if abs(norm - 1.0) > 1e-6:
                raise ValueError(f"normal: must be a unit vector (|n| = 1 within 1e-6), got |n| = {norm:.6g}")
            if "tilt_deg" in self.model_fields_set:   # the shorthand given too: it must be the same plane
                t = math.radians(self.tilt_deg)
                if max(abs(a - b) for a, b in zip((math.sin(t), 0.0, -math.cos(t)), self.normal)) > 1e-6:
                    raise ValueError(f"tilt_deg: {self.tilt_deg:g} deg is not the plane of normal "
                                     f"{list(self.normal)}, which sets the plane; change normal, or drop tilt_deg")
        return self


# -- path ----------------------------------------------------------------------------

class TrajectorySettings(_Section):
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


# -- impedance -----------------------------------------------------------------------

Vec3Pos = tuple[Pos, Pos, Pos]
Vec3NonNeg = tuple[NonNeg, NonNeg, NonNeg]
# the translational impedance of eq. (2), bounded to what a force-controlled arm can mean (and what the sampled
# analysis can compute: m = 1e-300 or b = 1e12 N s/m left python-control's step_info an empty response)
_Mass = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=1e-3, le=1e4)]
_Damping = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0, le=1e6)]
_Stiffness = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0, le=1e8)]


class ImpedanceSettings(_Section):
    """Target impedance (eq. 2) in the task frame, normal axis first. The
    inner-loop gains of eq. (6) default to K_D = B/M, K_P = K/M (eq. 9)."""
    m: tuple[_Mass, _Mass, _Mass] = Field((1.0, 1.0, 1.0), description="impedance mass M [kg]",
                                          json_schema_extra={"unit": "kg"})
    b: tuple[_Damping, _Damping, _Damping] = Field((60.0, 20.0, 20.0), description="impedance damping B [N s/m]",
                                                   json_schema_extra={"unit": "N s/m"})
    k: tuple[_Stiffness, _Stiffness, _Stiffness] = Field((100.0, 100.0, 100.0),
                                                         description="impedance stiffness K [N/m]",
                       json_schema_extra={"unit": "N/m"})
    kd: Vec3NonNeg | None = Field(None, description="inner-loop K_D of eq. (6); default B/M [1/s]",
                                  json_schema_extra={"unit": "1/s"})
    kp: Vec3Pos | None = Field(None, description="inner-loop K_P of eq. (6); default K/M [1/s^2]",
                               json_schema_extra={"unit": "1/s^2"})
    m_rot: Vec3Pos = Field((1.0, 1.0, 1.0), description="6-D arms: rotational impedance inertia about the task "
                           "axes [kg m^2]", json_schema_extra={"unit": "kg m^2"})
    b_rot: Vec3NonNeg = Field((40.0, 40.0, 40.0), description="6-D arms: rotational impedance damping "
                              "[N m s/rad]", json_schema_extra={"unit": "N m s/rad"})
    k_rot: Vec3Pos = Field((400.0, 400.0, 400.0), description="6-D arms: rotational impedance stiffness "
                           "[N m/rad]", json_schema_extra={"unit": "N m/rad"})

    @property
    def gains(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(K_D, K_P) of eq. (6)."""
        kd = self.kd or tuple(b / m for b, m in zip(self.b, self.m))
        kp = self.kp or tuple(k / m for k, m in zip(self.k, self.m))
        return kd, kp


# -- controller ------------------------------------------------------------------------

class FixedDamping(_Section):
    """The normal damping is impedance.b[0]."""
    kind: Literal["off"] = "off"


class ScheduledDamping(_Section):
    """Eq. (25) used online: ``b = 2 zeta sqrt(m (k + k_hat))`` with the TMT
    stiffness estimate k_hat = f_m/(x - x_e_hat), clamped and rate-limited,
    held while the force is too small to estimate k_e; K_D = b/m follows."""
    kind: Literal["zeta"] = "zeta"
    zeta: float = num(1.0, "1", "target damping ratio", gt=0)
    b_min: float = num(1.0, "N s/m", "smallest damping", ge=0)
    b_max: float = num(1000.0, "N s/m", "largest damping", gt=0)
    rate: float = num(1e4, "N s/m per s", "rate limit of the damping", gt=0)
    k_max: float = num(1e7, "N/m", "largest stiffness estimate used", gt=0, le=MAX_STIFFNESS)
    force_threshold: float = num(0.5, "N", "the estimate is used above twice this force", gt=0)
    min_stiffness: float = num(100.0, "N/m", "smallest stiffness estimate used", gt=0, le=MAX_STIFFNESS)

    @model_validator(mode="after")
    def _bounds(self):
        if self.b_min > self.b_max:
            raise ValueError(f"b_min: must be <= b_max ({self.b_max:g}), got {self.b_min:g}")
        return self


DampingSchedule = Annotated[Union[FixedDamping, ScheduledDamping], _tag_default("off"),
                            Field(discriminator="kind")]


def _law_union():
    members = tuple(law.parameters for law in laws().values())
    return Annotated[Union[members], _tag_default("tmt"), Field(discriminator="kind")]


class ControllerSettings(_Section):
    """Sampled controller: rate, desired force, surface estimate, force-tracking
    law (``controller.law``, with its parameters) and normal damping."""
    rate: float = num(1000.0, "Hz", "control rate 1/Ts (at most 10 kHz, the fastest force-control loops of "
                      "robot arms)", gt=0, le=1e4)
    f_d: float = num(10.0, "N", "desired normal force", gt=0)
    x_e_error: float = num(0.0, "m", "error of the controller's surface location along the normal "
                           "(positive: believed deeper than it is)")
    delay_samples: StrictInt = Field(0, ge=0, le=20, description="computation delay: the torque computed "
                                     "at t_k is applied from t_(k+N) [samples]")
    approach_speed: float = num(0.01, "m/s", "guarded approach from trajectory.approach_gap: the command "
                                "advances toward the surface at this speed until contact is detected; "
                                "0 = the law acts from the start", ge=0, le=1.0)
    contact_threshold: float = num(1.0, "N", "measured force that ends the guarded approach", gt=0)
    force_ramp: float = num(0.25, "s", "after a guarded approach, f_d rises linearly from 0 over this time",
                            gt=0, le=100)
    force_tolerance: float = num(0.01, "N", "tracking tolerance of the segment verdicts: a segment is "
                                 "'converged' only if the force error f_e - f_d stays within +- this "
                                 "over its last quarter, and its mean error there; with sensor noise also its noise-free "
                                 "twin, the noisy run's limits widened only by what the noise did to the force "
                                 "(docs/simulation.md)", gt=0)
    law: _law_union() = Field(default_factory=TmtParameters,
                              description="force-tracking law: its kind and parameters")
    damping_schedule: DampingSchedule = Field(default_factory=FixedDamping,
                                              description="normal damping: fixed ('off') or scheduled ('zeta')")

    @model_validator(mode="after")
    def _schedule_needs_filter(self):
        law = laws()[self.law.kind]
        if self.damping_schedule.kind != "off" and not law.uses_impedance_filter:
            raise ValueError(f"damping_schedule: law {law.name!r} does not use the impedance filter, "
                             "so its damping cannot be scheduled; use 'off'")
        return self

    @property
    def Ts(self) -> float:
        """Control period, s."""
        return 1.0 / self.rate


def filter_pole(cutoff: float, Ts: float) -> float:
    """The discrete pole ``exp(-2 pi f_c Ts)`` of a first-order low-pass at
    ``cutoff`` Hz sampled every ``Ts`` s; 0 (no filter) for a cut-off of 0."""
    return float(math.exp(-2 * math.pi * cutoff * Ts)) if cutoff > 0 else 0.0


class SensorSettings(_Section):
    """Force sensor along the normal."""
    noise_std: float = num(0.0, "N", "Gaussian noise, 1 sigma", ge=0)
    seed: StrictInt = Field(0, ge=0, description="seed of the noise generator (an integer)")
    filter_cutoff: float = num(0.0, "Hz", "first-order low-pass cut-off, below the Nyquist frequency "
                               "controller.rate/2; 0 = off", ge=0)

    def pole(self, Ts: float) -> float:
        """The force filter's discrete pole at control period ``Ts`` (0: no filter)."""
        return filter_pole(self.filter_cutoff, Ts)


class SimulationSettings(_Section):
    """Integrator: ``fixed`` (compiled RK4, ``substeps`` per control period,
    ``contact_refine`` times more in a period where the contact force
    switches on or off) or ``cvodes`` (adaptive, accuracy reference,
    tolerance ``tol``)."""
    integrator: Literal["fixed", "cvodes"] = Field("fixed", description="'fixed' (compiled RK4) or 'cvodes'")
    substeps: StrictInt = Field(1, ge=1, le=1000, description="RK4 steps per control period (fixed)")
    contact_refine: StrictInt = Field(4, ge=1, le=64, description=(
        "RK4 steps per substep in a period where the contact force switches on or off (fixed; 1: off)"))
    tol: float = num(1e-10, "1", "relative and absolute tolerance (cvodes)", gt=0, le=1e-2)


class Scenario(_Section):
    """One complete simulation setup (see ``docs/scenario.md``)."""
    name: str = Field("paper", min_length=1, description="a label for outputs")
    robot: RobotSettings = Field(default_factory=RobotSettings)
    environment: EnvironmentSettings = Field(default_factory=EnvironmentSettings)
    trajectory: TrajectorySettings = Field(default_factory=TrajectorySettings)
    impedance: ImpedanceSettings = Field(default_factory=ImpedanceSettings)
    controller: ControllerSettings = Field(default_factory=ControllerSettings)
    sensor: SensorSettings = Field(default_factory=SensorSettings)
    simulation: SimulationSettings = Field(default_factory=SimulationSettings)

    @model_validator(mode="after")
    def _sampled(self):
        """The bounds relative to the control period (see :func:`sampling_problem`)."""
        problem = sampling_problem(self)
        if problem:
            raise ValueError(problem)
        return self

    @property
    def duration(self) -> float:
        """Simulated time, s: ``cycles * period``."""
        return self.trajectory.cycles * self.trajectory.period

    def replace(self, **changes) -> "Scenario":
        """A validated copy with top-level sections replaced."""
        d = scenario_to_dict(self)
        d.update({k: (v.model_dump() if isinstance(v, BaseModel) else v) for k, v in changes.items()})
        return scenario_from_dict(d)


def _rebuild() -> None:
    """Accept every registered law in ``controller.law`` (called on registration)."""
    ControllerSettings.model_fields["law"] = FieldInfo.from_annotated_attribute(
        _law_union(), Field(default_factory=TmtParameters, description="force-tracking law: its kind and parameters"))
    ControllerSettings.model_rebuild(force=True)
    Scenario.model_rebuild(force=True)


on_register(_rebuild)

TAGGED_TABLES = {("environment", "stiffness"): lambda: {m.model_fields["kind"].default: m for m in (
                     PiecewiseConstantStiffness, PiecewiseLinearStiffness, SinusoidalStiffness, TableStiffness)},
                 ("controller", "law"): lambda: {n: law.parameters for n, law in laws().items()},
                 ("controller", "damping_schedule"): lambda: {"off": FixedDamping, "zeta": ScheduledDamping}}
"""Tagged unions by location: kind -> model."""

_TAG_DEFAULTS = {("environment", "stiffness"): "piecewise_constant", ("controller", "law"): "tmt",
                 ("controller", "damping_schedule"): "off"}
"""The kind of a tagged table that does not say."""


SAMPLED_KEYS = ("trajectory.period", "environment.stiffness", "sensor.filter_cutoff", "controller.rate",
                "robot.model", "environment.normal", "environment.point", "trajectory.center")
"""The keys :func:`sampling_problem` relates (the only check across sections)."""


def _plane_problem(sc: Scenario) -> str | None:
    """The plane across sections: the PUMA takes ``tilt_deg`` only, and the
    circle's centre lies on the plane given by ``environment.point``."""
    env = sc.environment
    if env.normal is not None and sc.robot.model.lower() == "puma560":
        return ("environment.normal: the 3-joint PUMA 560 scenario gives its plane as tilt_deg "
                "(its analyses and export use it); leave normal unset")
    if env.point is not None:
        from .geometry import surface_frame   # the one definition of the task frame's normal

        n = surface_frame(env)[:, 0]
        off = sum(a * (c - p) for a, c, p in zip(n, sc.trajectory.center, env.point))
        if abs(off) > 1e-9:
            return (f"trajectory.center: must lie on the plane (environment.point, normal), "
                    f"it is {off:.6g} m off it")
    return None


def sampling_problem(sc: Scenario) -> str | None:
    """What the control period ``Ts = 1/controller.rate`` forbids, as an error
    message naming the key, or None: a path period, a stiffness segment or a
    sinusoid's period shorter than :data:`MIN_PERIODS` control periods (fewer
    samples cannot resolve them: a circle in under 10 samples, a segment whose
    last quarter holds no sample), and a force-filter cut-off at or above the
    Nyquist frequency ``rate/2`` (its discrete pole ``exp(-2 pi f_c Ts)``
    would be below ``exp(-pi) = 0.04``: no filtering at all, silently); and
    the plane's checks across sections (:func:`_plane_problem`)."""
    plane = _plane_problem(sc)
    if plane:
        return plane
    Ts, rate = sc.controller.Ts, sc.controller.rate
    least = MIN_PERIODS * Ts
    why = f"at least {MIN_PERIODS} control periods ({least:g} s at controller.rate = {rate:g} Hz)"
    if sc.trajectory.period < least:
        return f"trajectory.period: must be {why}, got {sc.trajectory.period!r}"
    st = sc.environment.stiffness
    if st.kind == "piecewise_constant" and st.segment != 0 and st.segment < least:
        return f"environment.stiffness.segment: must be 0 (the path period) or {why}, got {st.segment!r}"
    if st.kind == "sinusoidal" and st.period < least:
        return f"environment.stiffness.period: must be {why}, got {st.period!r}"
    cutoff = sc.sensor.filter_cutoff
    if cutoff >= rate / 2:
        return (f"sensor.filter_cutoff: must be below the Nyquist frequency controller.rate/2 = {rate / 2:g} Hz "
                f"(0 = no filter), got {cutoff!r}")
    return None


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


# -- errors ----------------------------------------------------------------------------

def _dotted(loc) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _strip_tags(loc) -> tuple:
    """Drop the union tag pydantic inserts after a tagged field (``controller.law.tmt.x``)."""
    out, i = [], 0
    loc = tuple(loc)
    while i < len(loc):
        out.append(loc[i])
        if tuple(out[-2:]) in TAGGED_TABLES and i + 1 < len(loc) and isinstance(loc[i + 1], str) \
                and loc[i + 1] in TAGGED_TABLES[tuple(out[-2:])]():
            i += 1
        i += 1
    return tuple(out)


def _model_at(loc, data) -> type[BaseModel] | None:
    """The model class at ``loc`` (tag-free) for input ``data``."""
    model: Any = Scenario
    node = data
    for i, part in enumerate(loc):
        if not (isinstance(model, type) and issubclass(model, BaseModel)) or part not in model.model_fields:
            return None
        node = node.get(part) if isinstance(node, dict) else None
        key = tuple(loc[max(0, i - 1):i + 1])
        if key in TAGGED_TABLES:
            kinds = TAGGED_TABLES[key]()
            tagged = _tagged(node, _TAG_DEFAULTS[key])
            kind = tagged.get("kind") if isinstance(tagged, dict) else None
            model = kinds.get(kind)
        else:
            ann = model.model_fields[part].annotation
            model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
    return model


def _input_at(data, loc):
    node = data
    for part in loc:
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, (list, tuple)) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            return None
    return node


def _message(err: dict, data: dict, key: str | None = None) -> str:
    loc = _strip_tags(err["loc"])
    typ, ctx, got = err["type"], err.get("ctx") or {}, err.get("input")
    key = _dotted(loc) if key is None else key
    if typ == "extra_forbidden":
        parent = _model_at(loc[:-1], data)
        known = [f for f in (parent.model_fields if parent else {}) if f != "kind"]
        hint = ""
        if tuple(loc[:-1]) == ("controller",):
            owners = [n for n, law in laws().items() if loc[-1] in law.parameters.model_fields]
            if owners:
                hint = f"; it is a parameter of law {owners[0]!r}: set it in [controller.law]"
        if parent is not None and "kind" in parent.model_fields:
            kind = parent.model_fields["kind"].default
            return f"{key}: not a field of kind {kind!r} (its fields: {', '.join(known) or 'none'})"
        return f"{key}: unknown key (known: {', '.join(known)}){hint}"
    if typ in ("union_tag_invalid", "union_tag_not_found"):
        tags = ctx.get("expected_tags", "")
        found = ctx.get("tag")
        return (f"{key}: expected kind one of {tags}, got {found!r}" if found is not None
                else f"{key}: a table needs kind = one of {', '.join(map(repr, TAGGED_TABLES.get(tuple(loc[-2:]), dict)()))}")
    if typ in ("missing", "too_short", "too_long") and loc and isinstance(loc[-1], int):
        loc, got = loc[:-1], _input_at(data, loc[:-1])
        key = _dotted(loc)
        return f"{key}: expected a list of 3 numbers, got {got!r}"
    if typ in ("too_short",) and ctx.get("min_length") == 1:
        return f"{key}: empty list; give at least one value"
    if typ == "missing":
        return f"{key}: required"
    expected = {
        "float_type": "expected a number", "int_type": "expected an integer", "bool_type": "expected true or false",
        "string_type": "expected a string", "finite_number": "must be finite", "tuple_type": "expected a list",
        "model_type": "expected a table", "dict_type": "expected a table", "model_attributes_type": "expected a table",
        "int_from_float": "expected an integer",
    }.get(typ)
    if expected is None:
        if typ in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
            op = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}[typ]
            bound = next(iter(v for k, v in ctx.items() if k in ("gt", "ge", "lt", "le")))
            expected = f"must be {op} {bound:g}"
        elif typ == "literal_error":
            expected = f"expected {ctx.get('expected')}"
        elif typ == "string_too_short":
            expected = "must not be empty"
        elif typ == "value_error":
            msg = str(ctx.get("error", err["msg"]))
            field, _, rest = msg.partition(": ")
            return f"{_dotted((*loc, field))}: {rest}" if rest else f"{key}: {msg}"
        else:
            expected = err["msg"]
    return f"{key}: {expected}, got {got!r}"


def scenario_from_dict(data: Any, source: str = "") -> Scenario:
    """Build and validate a :class:`Scenario` from nested dicts (TOML layout).
    ``source`` (a file name, ``--set``) is named in errors."""
    if not isinstance(data, dict):
        raise ScenarioError(f"scenario: expected a table, got {data!r}" + (f" (in {source})" if source else ""))
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        raise ScenarioError(_message(exc.errors()[0], data) + (f" (in {source})" if source else "")) from None


def _field_type(key: str):
    """The type (with its constraints) of the number at dotted ``key`` of the
    schema: a tagged union's default kind; a list's element."""
    from typing import get_args, get_origin

    model: Any = Scenario
    parts = key.split(".")
    for i, part in enumerate(parts):
        info = model.model_fields[part]
        if i == len(parts) - 1:
            break
        loc = tuple(parts[max(0, i - 1):i + 1])
        model = (TAGGED_TABLES[loc]()[_TAG_DEFAULTS[loc]] if loc in TAGGED_TABLES else info.annotation)
    typ = Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
    if get_origin(info.annotation) is tuple:
        typ = get_args(info.annotation)[0]
    return typ


@functools.lru_cache(maxsize=None)
def _adapter(key: str):
    from pydantic import TypeAdapter

    return TypeAdapter(_field_type(key))


def check_setting(flag: str, key: str, value: Any) -> Any:
    """``value`` checked against the scenario schema's field at dotted ``key``
    (its type and range; a list key's element), for a command-line flag that
    means the same setting: the error is the schema's, naming ``flag``, e.g.
    ``--delay: must be <= 20, got 1000 (controller.delay_samples in a
    scenario)``."""
    try:
        return _adapter(key).validate_python(value)
    except ValidationError as exc:
        raise ScenarioError(_message(exc.errors()[0], {}, key=flag) + f" ({key} in a scenario)") from None


def setting_bounds(key: str) -> dict[str, float]:
    """The range of the number at dotted ``key`` of the schema: its ``gt``,
    ``ge``, ``lt``, ``le`` constraints that are set."""
    from typing import get_args

    out = {}
    for m in get_args(_field_type(key))[1:]:
        for item in (getattr(m, "metadata", None) or [m]):
            for attr in ("gt", "ge", "lt", "le"):
                if getattr(item, attr, None) is not None:
                    out[attr] = getattr(item, attr)
    return out


def check_period(flag: str, Ts: Any) -> float:
    """A control period ``Ts`` (s) from the command line, checked against the
    schema's range of ``controller.rate = 1/Ts`` (so ``--ts`` takes exactly
    the rates a scenario takes)."""
    if not (isinstance(Ts, (int, float)) and not isinstance(Ts, bool) and math.isfinite(Ts) and Ts > 0):
        raise ScenarioError(f"{flag}: must be a finite number > 0 s, got {Ts!r}")
    bounds = setting_bounds("controller.rate")
    rate = 1.0 / Ts
    for attr, op, ok in (("le", ">=", lambda b: rate <= b), ("lt", ">", lambda b: rate < b),
                         ("ge", "<=", lambda b: rate >= b), ("gt", "<", lambda b: rate > b)):
        if attr in bounds and not ok(bounds[attr]):
            sym = {"le": "<=", "lt": "<", "ge": ">=", "gt": ">"}[attr]
            raise ScenarioError(f"{flag}: must be {op} {1 / bounds[attr]:g} s (controller.rate = 1/Ts must be "
                                f"{sym} {bounds[attr]:g} Hz in a scenario), got {Ts!r}")
    return float(Ts)


def check_filter_cutoff(flag: str, cutoff: Any, Ts: float) -> float:
    """A force-filter cut-off (Hz) from the command line: the schema's range
    of ``sensor.filter_cutoff`` and, as :func:`sampling_problem` says, below
    the Nyquist frequency ``1/(2 Ts)``."""
    cutoff = check_setting(flag, "sensor.filter_cutoff", cutoff)
    if cutoff >= 0.5 / Ts:
        raise ScenarioError(f"{flag}: must be below the Nyquist frequency 1/(2 Ts) = {0.5 / Ts:g} Hz "
                            f"(0 = no filter), got {cutoff!r}")
    return cutoff


def scenario_to_dict(scenario: Scenario) -> dict:
    """Nested dict of plain Python values (lists for tuples; unset optional
    fields left out), the TOML layout."""
    def conv(v):
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items() if x is not None}
        if isinstance(v, (tuple, list)):
            return [conv(x) for x in v]
        return v
    return conv(scenario.model_dump())     # (a normal's scenario has no tilt_deg: EnvironmentSettings' dump)


@dataclass(frozen=True)
class SettingRow:
    """One applicable scenario key: dotted ``key``, its ``value`` (a Python
    value), ``unit`` (SI, "1" for dimensionless, "" for none) and ``meaning``."""
    key: str
    value: Any
    unit: str
    meaning: str


def _applies(sc: Scenario, key: str) -> bool:
    """Whether ``key`` changes anything for the options ``sc`` chose (the
    members of tagged unions already are the chosen kind's)."""
    if key in ("controller.approach_speed", "controller.contact_threshold", "controller.force_ramp"):
        return sc.trajectory.approach_gap > 0
    if key == "sensor.seed":
        return sc.sensor.noise_std > 0
    if key == "environment.tilt_deg":
        return sc.environment.normal is None
    if key in ("simulation.substeps", "simulation.contact_refine"):
        return sc.simulation.integrator == "fixed"
    if key == "simulation.tol":
        return sc.simulation.integrator == "cvodes"
    return True


def applicable_settings(sc: Scenario) -> list[SettingRow]:
    """The scenario's keys that apply to its options, with value, unit and
    meaning (from the schema), in schema order. Unset optional values (the
    inner-loop gains) are shown as their defaults' rule."""
    rows = []

    def walk(model: BaseModel, prefix: str):
        for name, info in type(model).model_fields.items():
            key, value = f"{prefix}{name}", getattr(model, name)
            if isinstance(value, BaseModel):
                walk(value, key + ".")
                continue
            if not _applies(sc, key):
                continue
            extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
            desc = info.description or ""
            bracket = re.search(r" \[([^\]]*)\]$", desc)
            trailing = re.search(r", (N/m|N s/m|N|m|s|Hz|kg|1/s|m/\(N s\))$", desc)   # the laws' style
            unit = extra.get("unit") or (bracket.group(1) if bracket else trailing.group(1) if trailing else "")
            desc = desc.replace(f" [{unit}]", "")
            if trailing and not bracket:
                desc = desc[:trailing.start()]
            if value is None and name in ("kd", "kp"):
                value = "B/M" if name == "kd" else "K/M"
            rows.append(SettingRow(key, value, "" if unit == "–" else unit, desc))

    walk(sc, "")
    return rows


def _toml_key(k) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _toml_value(k)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):      # an inline table (a value where the schema wants a table, or a wrong one)
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {v!r} as TOML")


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as a TOML document that :func:`load_scenario` reads back;
    it holds only the fields of the chosen kinds."""
    return toml_document(scenario_to_dict(scenario))


def toml_document(d: dict) -> str:
    """A scenario dict (TOML layout, valid or not) as a TOML document: ``name``
    and the sections (tables); other top-level values are left out."""
    d = dict(d)
    lines = ["# tmtcontrol scenario (SI units; see docs/scenario.md)", f"name = {_toml_value(d.pop('name', 'scenario'))}"]

    def table(name, body):
        lines.append("")
        lines.append(f"[{name}]")
        sub = []
        for k, v in body.items():
            if isinstance(v, dict):
                sub.append((k, v))
            else:
                lines.append(f"{k} = {_toml_value(v)}")
        for k, v in sub:
            table(f"{name}.{k}", v)

    for name, body in d.items():      # sections only: a scenario has no other top-level value
        if isinstance(body, dict):
            table(name, body)
    return "\n".join(lines) + "\n"


MAX_INPUT_BYTES = 16 * 2**20
"""The largest scenario, sweep or stiffness-table file read (16 MiB): anything
larger is refused before it is read."""


class InputFileError(ValueError):
    """An input file that cannot be read as text; the message is the reason,
    without the file's name (callers say which file and what it should be)."""


def read_text_file(path: str | pathlib.Path, max_bytes: int = MAX_INPUT_BYTES) -> str:
    """The text of the regular file ``path`` (UTF-8; a leading UTF-8 byte-order
    mark, as Windows Notepad and Excel's "CSV UTF-8" write, is dropped).

    The file is opened without blocking and checked before anything is read:
    a folder, a FIFO, a device (``/dev/zero``), a socket, or a file larger than
    ``max_bytes`` raise :class:`InputFileError` at once (a FIFO never blocks)."""
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise InputFileError("no such file") from None
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror})") from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputFileError("is a folder")
        if not stat.S_ISREG(st.st_mode):
            what = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode)
                    or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "special")
            raise InputFileError(f"not a regular file ({what})")
        if st.st_size > max_bytes:
            raise InputFileError(f"{st.st_size / 2**20:.1f} MiB, larger than the {max_bytes / 2**20:g} MiB limit")
        chunks, size = [], 0
        while size <= max_bytes:            # a file growing while it is read stops at the limit too
            chunk = os.read(fd, min(max(st.st_size + 1, 65536), 2**20, max_bytes + 1 - size))   # no 16 MiB buffer
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > max_bytes:
            raise InputFileError(f"larger than the {max_bytes / 2**20:g} MiB limit")
    except OSError as exc:
        raise InputFileError(f"cannot read ({exc.strerror})") from None
    finally:
        os.close(fd)
    try:
        return b"".join(chunks).decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"not UTF-8 text (byte {exc.start})") from None


def read_toml(path: pathlib.Path, what: str, error: type[Exception]) -> dict:
    """Parse the TOML file ``path``; every failure (missing, a folder, not a
    regular file, larger than :data:`MAX_INPUT_BYTES`, not UTF-8, unreadable,
    malformed) raises ``error`` naming the file and ``what`` it should have
    been. A UTF-8 byte-order mark is accepted."""
    src = str(path)
    try:
        text = read_text_file(path)
    except InputFileError as exc:
        reason = str(exc)
        if reason == "no such file":
            raise error(f"{src}: no such {what} file") from None
        if reason == "is a folder":
            raise error(f"{src}: is a folder, expected a {what} TOML file") from None
        if reason.startswith("not a regular file"):
            raise error(f"{src}: {reason}, expected a {what} TOML file") from None
        raise error(f"{src}: {reason}" + (f" of a {what} file" if "limit" in reason else "")) from None
    try:
        return parse_toml(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{src}: malformed TOML ({exc})") from None
    except InputFileError as exc:
        raise error(f"{src}: {exc}") from None


MAX_KEY_PARTS = 64
"""The most parts a dotted TOML key may have (scenario and sweep keys have at
most five): tomllib keeps every prefix of a dotted key, memory quadratic in
its length (10,000 parts took 450 MB)."""

_KEY_PART = r"""(?:[A-Za-z0-9_-]++|"[^"\n]*+"|'[^'\n]*+')"""
_LONG_KEY = re.compile(r"(?<![A-Za-z0-9_-])" + _KEY_PART + r"(?:[ \t]*+\.[ \t]*+" + _KEY_PART + r"){%d}"
                       % MAX_KEY_PARTS)


def parse_toml(text: str) -> dict:
    """``tomllib.loads(text)`` within bounds: a dotted key of more than
    :data:`MAX_KEY_PARTS` parts (found by a linear scan before parsing; a run
    inside a string or comment counts too, conservatively) and arrays or
    tables nested past the parser's recursion raise :class:`InputFileError`
    with the reason; malformed TOML raises ``tomllib.TOMLDecodeError``."""
    long_key = _LONG_KEY.search(text)
    if long_key:
        raise InputFileError(f"a key of more than {MAX_KEY_PARTS} dotted parts (line "
                             f"{text.count(chr(10), 0, long_key.start()) + 1}); no key is that deep")
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise InputFileError("arrays or tables nested too deeply") from None


def load_scenario(path: str | pathlib.Path) -> Scenario:
    """Read and validate a scenario TOML file; the string ``"paper"`` gives
    :func:`paper_scenario`. A relative stiffness ``table`` file is resolved
    against the scenario file's folder. An empty file is refused."""
    if str(path) == "paper":
        return paper_scenario()
    if str(path) in BUILTIN_ARMS:
        return arm_scenario(str(path))
    path = pathlib.Path(path)
    src = str(path)
    data = read_toml(path, "scenario", ScenarioError)
    if not data:
        raise ScenarioError(f"{src}: empty scenario; start from 'tmtcontrol scenario paper > {path.name}'")
    stiff = data.get("environment", {}).get("stiffness") if isinstance(data.get("environment"), dict) else None
    if isinstance(stiff, dict) and isinstance(stiff.get("file"), str) and stiff["file"] \
            and not pathlib.Path(stiff["file"]).is_absolute():
        stiff["file"] = str(path.parent / stiff["file"])
    robot = data.get("robot")
    if isinstance(robot, dict) and isinstance(robot.get("model"), str) and robot["model"].lower().endswith(".urdf") \
            and not pathlib.Path(robot["model"]).is_absolute():
        robot["model"] = str(path.parent / robot["model"])
    return scenario_from_dict(data, src)


def set_key(d: dict, key: str, value: Any) -> None:
    """Set dotted ``key`` of the scenario dict ``d`` (TOML layout) in place.

    Setting a tagged union (``controller.law``, ``environment.stiffness``,
    ``controller.damping_schedule``) to a kind name, or changing its
    ``kind``, starts that table afresh with the new kind's defaults, keeping
    the fields the new kind also has."""
    parts = key.split(".")
    if not all(parts):
        raise ScenarioError(f"{key}: malformed key")
    node = d
    for i, p in enumerate(parts[:-1]):
        if p not in node and tuple(parts[max(0, i - 1):i + 1]) in TAGGED_TABLES:
            node[p] = {}
        if not isinstance(node, dict) or p not in node:
            raise ScenarioError(f"{'.'.join(parts[:i + 1])}: unknown key")
        if isinstance(node[p], str) and tuple(parts[max(0, i - 1):i + 1]) in TAGGED_TABLES:
            node[p] = {"kind": node[p]}
        if not isinstance(node[p], dict):
            raise ScenarioError(f"{'.'.join(parts[:i + 1])}: is a value, not a table")
        node = node[p]
    last = parts[-1]
    union = tuple(parts[-2:]) if tuple(parts[-2:]) in TAGGED_TABLES else None
    kind_of = tuple(parts[-3:-1]) if last == "kind" and tuple(parts[-3:-1]) in TAGGED_TABLES else None
    if union is not None and isinstance(value, str):
        node[last] = {"kind": value}
        return
    if kind_of is not None and isinstance(value, str) and node.get("kind") != value:
        model = TAGGED_TABLES[kind_of]().get(value)
        keep = {k: v for k, v in node.items() if model is not None and k in model.model_fields}
        node.clear()
        node.update(keep)
        node["kind"] = value
        return
    known = _model_at(tuple(parts[:-1]), d)
    tagged_member = known is not None and "kind" in known.model_fields   # the schema names the kind
    if last not in node and not tagged_member and (known is None or last not in known.model_fields):
        raise ScenarioError(f"{key}: unknown key")
    node[last] = value


def apply_overrides(scenario: Scenario, assignments: list[str]) -> Scenario:
    """Apply ``dotted.key=value`` strings (value in TOML syntax; bare words are
    strings), e.g. ``controller.f_d=5``, ``controller.law=integral`` or
    ``environment.stiffness.values=[1e3,1e4]``. The result goes through the
    same schema as a file."""
    d = scenario_to_dict(scenario)
    for item in assignments:
        if "=" not in item:
            raise ScenarioError(f"--set {item!r}: expected dotted.key=value")
        key, raw = (s.strip() for s in item.split("=", 1))
        if not key:
            raise ScenarioError(f"--set {item!r}: expected dotted.key=value")
        try:
            value = parse_toml(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw
        except InputFileError as exc:
            raise ScenarioError(f"--set {key}: {exc}") from None
        set_key(d, key, value)
    return scenario_from_dict(d, "--set")


def scenario_json_schema() -> dict:
    """The JSON Schema of scenario files (draft 2020-12)."""
    schema = Scenario.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "tmtcontrol scenario"
    return schema


def scenario_reference() -> str:
    """The scenario reference tables of ``docs/scenario.md``, generated from
    the schema: one row per key with unit, default, valid range and meaning;
    one table per kind of each tagged union."""
    def rng(info) -> str:
        parts = []
        for m in info.metadata:
            for attr, op in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
                if getattr(m, attr, None) is not None:
                    parts.append(f"{op} {getattr(m, attr):g}")
            if getattr(m, "min_length", None):
                parts.append("non-empty")
        from typing import get_args, get_origin

        if get_origin(info.annotation) is tuple and get_args(info.annotation)[-1] is Ellipsis:   # each element's
            for m in get_args(get_args(info.annotation)[0])[1:]:
                for item in (getattr(m, "metadata", None) or [m]):
                    for attr, op in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
                        if getattr(item, attr, None) is not None:
                            parts.append(f"each {op} {getattr(item, attr):g}")
        return ", ".join(parts) or "–"

    def fmt(v) -> str:
        if isinstance(v, tuple):
            return "[" + ", ".join(fmt(x) for x in v) + "]"
        return "–" if v is None else f"`{_toml_value(v)}`" if not isinstance(v, BaseModel) else "(table)"

    def rows(model, title):
        doc = " ".join(model.__doc__.split("\n\n")[0].split()).replace("``", "`") if model.__doc__ else ""
        out = [f"**[{title}]**" + (f" — {doc}" if doc else ""), "",
               "| key | unit | default | valid range | meaning |", "|---|---|---|---|---|"]
        for name, info in model.model_fields.items():
            extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
            unit = extra.get("unit", "–")
            desc = (info.description or "").replace(f" [{unit}]", "")
            default = info.get_default(call_default_factory=True) if not info.is_required() else None
            kind = "required" if info.is_required() else fmt(default)
            if isinstance(default, BaseModel):
                kind = f"kind `{getattr(default, 'kind', '')}`" if hasattr(default, "kind") else "(table)"
            out.append(f"| `{name}` | {unit} | {kind} | {rng(info) if name != 'kind' else 'this kind'} | {desc} |")
        return out + [""]

    lines = []
    for section, model in (("robot", RobotSettings), ("environment", EnvironmentSettings),
                           ("trajectory", TrajectorySettings), ("impedance", ImpedanceSettings),
                           ("controller", ControllerSettings), ("sensor", SensorSettings),
                           ("simulation", SimulationSettings)):
        lines += rows(model, section)
        for (sec, field), kinds in TAGGED_TABLES.items():
            if sec == section:
                for kind, member in kinds().items():
                    lines += rows(member, f"{sec}.{field}] kind = \"{kind}\"".replace("] kind", " kind").rstrip("]"))
    return "\n".join(lines).rstrip() + "\n"
