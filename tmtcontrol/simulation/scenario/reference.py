"""The scenario described: its JSON Schema, the reference tables of docs/scenario.md and the keys that apply to a scenario's options."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from .controller import ControllerSettings, ImpedanceSettings
from .environment import EnvironmentSettings
from .robot import RobotSettings
from .schema import TAGGED_TABLES, Scenario
from .sensor import SensorSettings, SimulationSettings
from .requirements import RequirementsSettings
from .tomlio import toml_value
from .trajectory import TrajectorySettings

__all__ = ["SettingRow", "applicable_settings", "scenario_json_schema", "scenario_reference"]


@dataclass(frozen=True)
class SettingRow:
    """One applicable scenario key: dotted ``key``, its ``value`` (a Python
    value), ``unit`` (SI, "1" for dimensionless, "" for none) and ``meaning``."""
    key: str
    value: Any
    unit: str
    meaning: str


_ROTATION_KEYS = ("impedance.m_rot", "impedance.b_rot", "impedance.k_rot", "controller.orientation_tolerance",
                  "trajectory.tool_spin_deg")
"""Keys of a task with orientation (6-D: an arm with 6 or more joints)."""

_POSTURE_KEYS = ("robot.posture_kp", "robot.posture_kd")
"""Keys of a redundant arm's null-space posture task (more joints than task axes)."""


def _applies(sc: Scenario, key: str, task=None) -> bool:
    """Whether ``key`` changes anything for the options ``sc`` chose (the
    members of tagged unions already are the chosen kind's) and, given the
    arm's ``task`` (:class:`tmtcontrol.model.robot.Task`), for its task: the
    orientation's keys only on a 6-D task, the posture's only on a redundant
    arm (review 15: the PUMA's report listed both)."""
    if task is not None and key in _ROTATION_KEYS:
        return bool(task.rotational)
    if task is not None and key in _POSTURE_KEYS:
        return bool(task.posture)
    if key in ("controller.approach_speed", "controller.contact_threshold", "controller.force_ramp"):
        return sc.trajectory.approach_gap > 0
    if key == "sensor.seed":
        return sc.sensor.noise_std > 0
    if key == "environment.point":         # a curved part touches its tangent plane at trajectory.center
        return sc.environment.shape == "plane"
    if key == "environment.tilt_deg":
        return sc.environment.normal is None
    if key in ("environment.radius", "environment.side"):      # a sphere's or cylinder's (review 25: a height map's)
        return sc.environment.shape in ("sphere", "cylinder")
    if key == "environment.normal":       # unset: the plane is tilt_deg's, shown there
        return sc.environment.normal is not None
    if key == "robot.tool_radius":      # the concave parts' check and MuJoCo's own contact use it
        return (sc.environment.side == "inside" or sc.environment.heightmap is not None
                or sc.simulation.mujoco_contact == "contact")
    if key == "environment.axis":
        return sc.environment.shape == "cylinder"
    if key == "trajectory.lanes":
        return sc.trajectory.path == "raster"
    if key == "trajectory.direction_deg":
        return sc.trajectory.path != "circle"
    if key in ("environment.heightmap", "environment.grid_spacing"):
        return sc.environment.shape == "heightmap"
    if key in ("simulation.substeps", "simulation.contact_refine"):
        return sc.simulation.integrator == "fixed"
    if key == "simulation.tol":
        return sc.simulation.integrator == "cvodes"
    if key == "simulation.mujoco_contact":          # the MuJoCo plant's (--plant mujoco); shown when chosen
        return sc.simulation.mujoco_contact != "spring"
    if key == "simulation.mujoco_friction":
        return sc.simulation.mujoco_contact == "contact"
    return True


def applicable_settings(sc: Scenario, task=None) -> list[SettingRow]:
    """The scenario's keys that apply to its options, with value, unit and
    meaning (from the schema), in schema order. Unset optional values (the
    inner-loop gains) are shown as their defaults' rule. Given the arm's
    ``task`` (the model's :class:`~tmtcontrol.model.robot.Task`, which the
    schema alone does not know), the keys its task has no use for are left
    out too."""
    rows = []

    def walk(model: BaseModel, prefix: str):
        for name, info in type(model).model_fields.items():
            key, value = f"{prefix}{name}", getattr(model, name)
            if isinstance(value, BaseModel):
                walk(value, key + ".")
                continue
            if not _applies(sc, key, task):
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
            if value is None and key == "environment.side":     # review 28: "None" for the outside that ran
                value = "outside"
            rows.append(SettingRow(key, value, "" if unit == "–" else unit, desc))

    walk(sc, "")
    return rows


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
    def bounds(constraints, prefix="") -> list[str]:
        """The bounds among ``constraints`` (annotated-types objects, or FieldInfos holding them)."""
        out = []
        for m in constraints:
            for item in (getattr(m, "metadata", None) or [m]):
                for attr, op in (("gt", ">"), ("ge", "≥"), ("lt", "<"), ("le", "≤")):
                    if getattr(item, attr, None) is not None:
                        out.append(f"{prefix}{op} {getattr(item, attr):g}")
        return out

    def rng(info) -> str:
        import types
        from typing import Annotated, Union, get_args, get_origin

        parts = bounds(info.metadata) + (["non-empty"] if any(getattr(m, "min_length", None)
                                                              for m in info.metadata) else [])
        ann = info.annotation
        # an optional bounded number (requirements.first_contact_overshoot, review 51: its bounds sit in the union)
        for a in (get_args(ann) if get_origin(ann) in (Union, types.UnionType) else ()):
            if get_origin(a) is Annotated and get_args(a)[0] in (int, float):
                parts += bounds(a.__metadata__)
        # each element's bounds, of a tuple of any length or of a fixed length (impedance.m: 3 masses), also
        # when optional (impedance.kd); review 23: the fixed-length tuples' bounds were left out
        tuples = [a for a in (ann, *get_args(ann)) if get_origin(a) is tuple]
        elements = [e for e in get_args(tuples[0]) if e is not Ellipsis] if tuples else []
        if elements and all(e == elements[0] for e in elements):
            parts += bounds(get_args(elements[0])[1:], "each ")
        return ", ".join(parts) or "–"

    def fmt(v) -> str:
        if isinstance(v, tuple):
            return "[" + ", ".join(fmt(x) for x in v) + "]"
        return "–" if v is None else f"`{toml_value(v)}`" if not isinstance(v, BaseModel) else "(table)"

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
                           ("simulation", SimulationSettings), ("requirements", RequirementsSettings)):
        lines += rows(model, section)
        for (sec, field), kinds in TAGGED_TABLES.items():
            if sec == section:
                for kind, member in kinds().items():
                    lines += rows(member, f"{sec}.{field}] kind = \"{kind}\"".replace("] kind", " kind").rstrip("]"))
    return "\n".join(lines).rstrip() + "\n"
