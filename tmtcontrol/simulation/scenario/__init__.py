"""Scenario settings: one declarative schema (pydantic v2), TOML load/dump, overrides.

A :class:`Scenario` fully describes one simulation of section V of the paper:
robot, environment (the surface and its stiffness profile), path, impedance
parameters (eqs. 2-3, 9), controller and force-tracking law (eqs. 11-12, 18
and the baselines of ``control.laws``), force sensor, and integrator. Every
field is SI (m, s, N, N/m, kg, Hz) and carries its unit, default and range in
the schema; models are frozen and forbid unknown keys. The stiffness profile,
the law and the damping schedule are tagged unions on ``kind``: each kind has
exactly its own fields.

One module per section, and one per job around them::

    fields       the error, number fields with units, the section base, tagged tables
    robot        [robot]           environment  [environment]     trajectory  [trajectory]
    controller   [impedance], [controller]       sensor       [sensor], [simulation]
    requirements [requirements]: the user's bounds, judged only where stated
    schema       the Scenario, checks across sections, one-line errors, flag checks
    builtin      the built-in scenarios (paper, ur5, panda)
    tomlio       TOML dump and load, --set overrides
    textfiles    reading the user's files within bounds
    reference    the JSON Schema, docs/scenario.md's tables, the keys that apply

Errors are :class:`ScenarioError`, one line: ``dotted.key: expected ..., got
... (in FILE)``. :func:`scenario_json_schema` gives the JSON Schema
(``tmtcontrol scenario --schema``); ``docs/scenario.md`` is generated from it.
"""

from .builtin import BUILTIN_ARMS, arm_scenario, paper_scenario
from .controller import ControllerSettings, DampingSchedule, FixedDamping, ImpedanceSettings, ScheduledDamping
from .environment import (EnvironmentSettings, PiecewiseConstantStiffness, PiecewiseLinearStiffness,
                          SinusoidalStiffness, StiffnessProfile, TableStiffness, read_stiffness_table)
from .fields import MAX_STIFFNESS, MIN_PERIODS, ScenarioError
from .reference import SettingRow, applicable_settings, scenario_json_schema, scenario_reference
from .requirements import RequirementsSettings
from .robot import RobotSettings
from .schema import (NOT_INTERVALS, SAMPLED_KEYS, TAGGED_TABLES, Scenario, check_filter_cutoff, check_period, check_setting,
                     sampling_problem, scenario_from_dict, scenario_to_dict, setting_bounds, takes_a_number)
from .sensor import SensorSettings, SimulationSettings, filter_pole
from .textfiles import MAX_INPUT_BYTES, MAX_KEY_PARTS, InputFileError, parse_toml, read_text_file, read_toml
from .tomlio import (apply_overrides, dump_scenario, load_scenario, replace_plane, resolve_files, set_key,
                     toml_document)
from .trajectory import TrajectorySettings

__all__ = [
    "ScenarioError", "RobotSettings", "PiecewiseConstantStiffness", "PiecewiseLinearStiffness",
    "SinusoidalStiffness", "TableStiffness", "StiffnessProfile", "EnvironmentSettings", "TrajectorySettings",
    "ImpedanceSettings", "FixedDamping", "ScheduledDamping", "DampingSchedule", "ControllerSettings",
    "SensorSettings", "SimulationSettings", "RequirementsSettings", "Scenario", "paper_scenario", "load_scenario", "scenario_from_dict",
    "scenario_to_dict", "dump_scenario", "toml_document", "apply_overrides", "set_key", "replace_plane", "resolve_files", "scenario_json_schema",
    "scenario_reference", "read_stiffness_table", "SettingRow", "TAGGED_TABLES", "SAMPLED_KEYS", "NOT_INTERVALS",
    "applicable_settings", "read_text_file", "read_toml", "parse_toml", "InputFileError", "MAX_INPUT_BYTES",
    "MAX_KEY_PARTS", "MAX_STIFFNESS", "MIN_PERIODS", "sampling_problem", "check_setting", "check_period",
    "check_filter_cutoff", "setting_bounds", "takes_a_number", "filter_pole", "BUILTIN_ARMS", "arm_scenario",
]
