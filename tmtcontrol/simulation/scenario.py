"""Scenario settings: frozen dataclasses, TOML load/dump, validation.

A :class:`Scenario` fully describes one simulation of section V of the paper:
robot, environment (tilted plane and stiffness profile), circular path,
impedance parameters (eqs. 2-3, 9), controller and reference law (eqs. 11-12
or 18), force sensor, and integrator. Every field is SI (m, s, N, N/m, kg,
Hz) and is validated on construction; unknown keys raise an error naming the
key. ``docs/scenario.md`` documents every key.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import tomllib
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "ScenarioError", "RobotSettings", "StiffnessProfile", "EnvironmentSettings",
    "TrajectorySettings", "ImpedanceSettings", "ControllerSettings", "SensorSettings",
    "SimulationSettings", "Scenario", "paper_scenario", "load_scenario", "scenario_from_dict",
    "scenario_to_dict", "dump_scenario", "apply_overrides",
]


class ScenarioError(ValueError):
    """Invalid scenario input; the message names the key and the problem."""


def _num(key, value, *, lo=None, hi=None, lo_open=False, integer=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{key}: expected a number, got {value!r}")
    if integer and int(value) != value:
        raise ScenarioError(f"{key}: expected an integer, got {value!r}")
    if not math.isfinite(value):
        raise ScenarioError(f"{key}: must be finite, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise ScenarioError(f"{key}: must be {'>' if lo_open else '>='} {lo:g}, got {value!r}")
    if hi is not None and value > hi:
        raise ScenarioError(f"{key}: must be <= {hi:g}, got {value!r}")


def _vec(key, value, n, **kw):
    if not isinstance(value, (tuple, list)) or len(value) != n:
        raise ScenarioError(f"{key}: expected a list of {n} numbers, got {value!r}")
    for i, v in enumerate(value):
        _num(f"{key}[{i}]", v, **kw)


def _as_tuple(key, value):
    """A list/tuple field as a tuple; anything else (a string!) is an error."""
    if not isinstance(value, (list, tuple)):
        raise ScenarioError(f"{key}: expected a list of numbers, got {value!r}")
    return tuple(value)


def _choice(key, value, choices):
    if value not in choices:
        raise ScenarioError(f"{key}: expected one of {', '.join(map(repr, choices))}, got {value!r}")


def _bool(key, value):
    if not isinstance(value, bool):
        raise ScenarioError(f"{key}: expected true or false, got {value!r}")


@dataclass(frozen=True)
class RobotSettings:
    """Plant and the controller's model of it.

    ``armature``/``friction`` configure the simulated PUMA 560;
    ``model_mass_scale`` scales every link mass, inertia and rotor inertia of
    the controller's model (D*^, h*^ of eq. 5), so 1.1 is a 10 % overestimate;
    ``compensate_friction`` adds the controller's (smooth) friction model to
    the torque.
    """
    armature: bool = True
    friction: bool = False
    model_mass_scale: float = 1.0
    compensate_friction: bool = False

    def __post_init__(self):
        _bool("robot.armature", self.armature)
        _bool("robot.friction", self.friction)
        _num("robot.model_mass_scale", self.model_mass_scale, lo=0, lo_open=True)
        _bool("robot.compensate_friction", self.compensate_friction)


@dataclass(frozen=True)
class StiffnessProfile:
    """Environment stiffness k_e(t), N/m.

    kind:
      * ``piecewise_constant``: ``values[i]`` on ``[i, i+1) * segment``
        (``segment`` defaults to the trajectory period), the last value held;
      * ``piecewise_linear``: linear interpolation through (``times``, ``values``);
      * ``sinusoidal``: ``mean + amplitude sin(2 pi t / period)``;
      * ``table``: a CSV file of ``t, k_e`` rows (header optional), linear interpolation.
    """
    kind: str = "piecewise_constant"
    values: tuple[float, ...] = (5e3, 2e4, 2e3, 1e4)
    times: tuple[float, ...] = ()
    segment: float = 0.0
    mean: float = 1e4
    amplitude: float = 5e3
    period: float = 4.0
    file: str = ""

    def __post_init__(self):
        key = "environment.stiffness"
        _choice(f"{key}.kind", self.kind, ("piecewise_constant", "piecewise_linear", "sinusoidal", "table"))
        object.__setattr__(self, "values", _as_tuple(f"{key}.values", self.values))
        object.__setattr__(self, "times", _as_tuple(f"{key}.times", self.times))
        _num(f"{key}.segment", self.segment, lo=0)
        if self.kind in ("piecewise_constant", "piecewise_linear"):
            if len(self.values) == 0:
                raise ScenarioError(f"{key}.values: empty profile; give at least one stiffness")
            _vec(f"{key}.values", self.values, len(self.values), lo=0, lo_open=True)
        if self.kind == "piecewise_linear":
            _vec(f"{key}.times", self.times, len(self.times), lo=0)
            if len(self.times) != len(self.values):
                raise ScenarioError(f"{key}.times: needs one time per value ({len(self.values)}), "
                                    f"got {len(self.times)}")
            if any(b <= a for a, b in zip(self.times, self.times[1:])):
                raise ScenarioError(f"{key}.times: must be strictly increasing")
        if self.kind == "sinusoidal":
            _num(f"{key}.mean", self.mean, lo=0, lo_open=True)
            _num(f"{key}.amplitude", self.amplitude, lo=0)
            _num(f"{key}.period", self.period, lo=0, lo_open=True)
            if self.amplitude >= self.mean:
                raise ScenarioError(f"{key}.amplitude: must be < mean ({self.mean:g}) so that k_e stays > 0")
        if self.kind == "table" and not self.file:
            raise ScenarioError(f"{key}.file: required for kind = 'table'")


@dataclass(frozen=True)
class EnvironmentSettings:
    """The tilted plane (Fig. 2) and its unilateral spring contact.

    The plane passes through ``trajectory.center``; its outward normal is the
    base z axis rotated by ``tilt_deg`` about the base y axis (so it faces the
    robot). Contact force ``f_e = max(0, k_e(t) d + damping d')`` while the
    penetration ``d > 0``.
    """
    tilt_deg: float = 45.0
    damping: float = 0.0
    stiffness: StiffnessProfile = field(default_factory=StiffnessProfile)

    def __post_init__(self):
        _num("environment.tilt_deg", self.tilt_deg, lo=-89.0, hi=89.0)
        _num("environment.damping", self.damping, lo=0)


@dataclass(frozen=True)
class TrajectorySettings:
    """Circle on the plane: centre (base frame, m), radius (m), period (s), cycles."""
    center: tuple[float, float, float] = (0.5, -0.15, 0.55)
    radius: float = 0.1
    period: float = 4.0
    cycles: float = 4.0

    def __post_init__(self):
        object.__setattr__(self, "center", _as_tuple("trajectory.center", self.center))
        _vec("trajectory.center", self.center, 3)
        _num("trajectory.radius", self.radius, lo=0)
        _num("trajectory.period", self.period, lo=0, lo_open=True)
        _num("trajectory.cycles", self.cycles, lo=0, lo_open=True, hi=1000)


@dataclass(frozen=True)
class ImpedanceSettings:
    """Target impedance (eq. 2) in the task frame, normal axis first.

    ``m`` (kg), ``b`` (N s/m), ``k`` (N/m). The inner-loop gains of eq. (6)
    default to ``K_D = B/M``, ``K_P = K/M`` (eq. 9); set ``kd``/``kp`` to
    override.
    """
    m: tuple[float, float, float] = (1.0, 1.0, 1.0)
    b: tuple[float, float, float] = (60.0, 20.0, 20.0)
    k: tuple[float, float, float] = (100.0, 100.0, 100.0)
    kd: tuple[float, ...] = ()
    kp: tuple[float, ...] = ()

    def __post_init__(self):
        for name in ("m", "b", "k", "kd", "kp"):
            object.__setattr__(self, name, _as_tuple(f"impedance.{name}", getattr(self, name)))
        _vec("impedance.m", self.m, 3, lo=0, lo_open=True)
        _vec("impedance.b", self.b, 3, lo=0)
        _vec("impedance.k", self.k, 3, lo=0, lo_open=True)
        if self.kd:
            _vec("impedance.kd", self.kd, 3, lo=0)
        if self.kp:
            _vec("impedance.kp", self.kp, 3, lo=0, lo_open=True)

    @property
    def gains(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(K_D, K_P) of eq. (6)."""
        kd = self.kd or tuple(b / m for b, m in zip(self.b, self.m))
        kp = self.kp or tuple(k / m for k, m in zip(self.k, self.m))
        return kd, kp


@dataclass(frozen=True)
class ControllerSettings:
    """Sampled controller: rate (Hz), reference law, desired force.

    ``law``: ``"tmt"`` (eq. 18) or ``"known"`` (eqs. 11-12 with
    ``assumed_stiffness``). ``f_d`` is the desired normal force, N.
    ``force_threshold`` (N): below it the TMT law uses the f_e = 0 branch of
    eq. (18); between it and twice it the two branches are blended smoothly.
    ``min_stiffness`` (N/m) bounds the stiffness estimate from below (its
    compliance from above). ``x_e_error`` (m) is the error of the controller's
    surface location along the normal (positive: believed deeper).

    ``damping_schedule``: ``"off"`` (fixed B) or ``"zeta"``: the normal
    damping follows eq. (25) online, ``b = 2 zeta sqrt(m (k + k_hat))`` with
    the TMT stiffness estimate, clamped to [``schedule_b_min``,
    ``schedule_b_max``] N s/m, rate-limited to ``schedule_rate`` N s/m per s,
    held while the force is too small to estimate k_e; K_D = b/m follows.
    """
    rate: float = 1000.0
    law: str = "tmt"
    f_d: float = 10.0
    assumed_stiffness: float = 5e3
    force_threshold: float = 0.5
    min_stiffness: float = 100.0
    x_e_error: float = 0.0
    damping_schedule: str = "off"
    schedule_zeta: float = 1.0
    schedule_b_min: float = 1.0
    schedule_b_max: float = 1000.0
    schedule_rate: float = 1e4
    schedule_k_max: float = 1e7

    def __post_init__(self):
        _num("controller.rate", self.rate, lo=0, lo_open=True, hi=1e6)
        _choice("controller.law", self.law, ("tmt", "known"))
        _num("controller.f_d", self.f_d, lo=0, lo_open=True)
        _num("controller.assumed_stiffness", self.assumed_stiffness, lo=0, lo_open=True)
        _num("controller.force_threshold", self.force_threshold, lo=0, lo_open=True)
        _num("controller.min_stiffness", self.min_stiffness, lo=0, lo_open=True)
        _num("controller.x_e_error", self.x_e_error)
        _choice("controller.damping_schedule", self.damping_schedule, ("off", "zeta"))
        _num("controller.schedule_zeta", self.schedule_zeta, lo=0, lo_open=True)
        _num("controller.schedule_b_min", self.schedule_b_min, lo=0)
        _num("controller.schedule_b_max", self.schedule_b_max, lo=0, lo_open=True)
        if self.schedule_b_min > self.schedule_b_max:
            raise ScenarioError(f"controller.schedule_b_min: must be <= schedule_b_max "
                                f"({self.schedule_b_max:g}), got {self.schedule_b_min:g}")
        _num("controller.schedule_rate", self.schedule_rate, lo=0, lo_open=True)
        _num("controller.schedule_k_max", self.schedule_k_max, lo=0, lo_open=True)

    @property
    def Ts(self) -> float:
        """Control period, s."""
        return 1.0 / self.rate


@dataclass(frozen=True)
class SensorSettings:
    """Force sensor along the normal: Gaussian noise (N, 1 sigma), seed, and a
    first-order low-pass filter with cut-off ``filter_cutoff`` Hz (0 = off)."""
    noise_std: float = 0.0
    seed: int = 0
    filter_cutoff: float = 0.0

    def __post_init__(self):
        _num("sensor.noise_std", self.noise_std, lo=0)
        _num("sensor.seed", self.seed, lo=0, integer=True)
        _num("sensor.filter_cutoff", self.filter_cutoff, lo=0)


@dataclass(frozen=True)
class SimulationSettings:
    """Integrator: ``fixed`` (compiled RK4, ``substeps`` per control period)
    or ``cvodes`` (adaptive, accuracy reference, tolerance ``tol``)."""
    integrator: str = "fixed"
    substeps: int = 4
    tol: float = 1e-10

    def __post_init__(self):
        _choice("simulation.integrator", self.integrator, ("fixed", "cvodes"))
        _num("simulation.substeps", self.substeps, lo=1, hi=1000, integer=True)
        _num("simulation.tol", self.tol, lo=0, lo_open=True, hi=1e-2)


_SECTIONS = {
    "robot": RobotSettings, "environment": EnvironmentSettings,
    "trajectory": TrajectorySettings, "impedance": ImpedanceSettings,
    "controller": ControllerSettings, "sensor": SensorSettings,
    "simulation": SimulationSettings,
}


@dataclass(frozen=True)
class Scenario:
    """One complete simulation setup (see ``docs/scenario.md``)."""
    name: str = "paper"
    robot: RobotSettings = field(default_factory=RobotSettings)
    environment: EnvironmentSettings = field(default_factory=EnvironmentSettings)
    trajectory: TrajectorySettings = field(default_factory=TrajectorySettings)
    impedance: ImpedanceSettings = field(default_factory=ImpedanceSettings)
    controller: ControllerSettings = field(default_factory=ControllerSettings)
    sensor: SensorSettings = field(default_factory=SensorSettings)
    simulation: SimulationSettings = field(default_factory=SimulationSettings)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ScenarioError(f"name: expected a non-empty string, got {self.name!r}")
        for key, cls in _SECTIONS.items():
            if not isinstance(getattr(self, key), cls):
                raise ScenarioError(f"{key}: expected a {cls.__name__}")

    @property
    def duration(self) -> float:
        """Simulated time, s: ``cycles * period``."""
        return self.trajectory.cycles * self.trajectory.period

    def replace(self, **changes) -> "Scenario":
        return dataclasses.replace(self, **changes)


def paper_scenario() -> Scenario:
    """The paper's section V: 3-link PUMA, 45 deg plane, f_d = 10 N, M = I,
    B = diag[60, 20, 20], K = diag[100, 100, 100], 4 cycles of 4 s with the
    stiffness stepping 5e3 -> 2e4 -> 2e3 -> 1e4 N/m after each cycle."""
    return Scenario()


# -- dict / TOML ------------------------------------------------------------

def _from_mapping(cls, data: Any, prefix: str):
    if not isinstance(data, dict):
        raise ScenarioError(f"{prefix}: expected a table, got {data!r}")
    names = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in data.items():
        if key not in names:
            raise ScenarioError(f"{prefix}.{key}: unknown key (known: {', '.join(names)})")
        if key == "stiffness" and cls is EnvironmentSettings:
            value = _from_mapping(StiffnessProfile, value, f"{prefix}.stiffness")
        elif isinstance(value, list):
            value = tuple(value)
        elif isinstance(value, dict):
            raise ScenarioError(f"{prefix}.{key}: expected a value, got a table")
        kwargs[key] = value
    try:
        return cls(**kwargs)
    except TypeError as exc:  # pragma: no cover - guarded by the name check above
        raise ScenarioError(f"{prefix}: {exc}") from None


def scenario_from_dict(data: dict) -> Scenario:
    """Build and validate a :class:`Scenario` from nested dicts (TOML layout)."""
    if not isinstance(data, dict):
        raise ScenarioError("scenario: expected a table")
    kwargs = {}
    for key, value in data.items():
        if key == "name":
            kwargs["name"] = value
        elif key in _SECTIONS:
            kwargs[key] = _from_mapping(_SECTIONS[key], value, key)
        else:
            raise ScenarioError(f"{key}: unknown key (known: name, {', '.join(_SECTIONS)})")
    return Scenario(**kwargs)


def scenario_to_dict(scenario: Scenario) -> dict:
    """Nested dict of plain Python values (lists for tuples)."""
    def conv(v):
        if dataclasses.is_dataclass(v):
            return {f.name: conv(getattr(v, f.name)) for f in dataclasses.fields(v)}
        if isinstance(v, tuple):
            return [conv(x) for x in v]
        return v
    return conv(scenario)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as a TOML document that :func:`load_scenario` reads back."""
    d = scenario_to_dict(scenario)
    lines = [f"# tmtcontrol scenario (SI units; see docs/scenario.md)", f"name = {_toml_value(d.pop('name'))}"]

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

    for name, body in d.items():
        table(name, body)
    return "\n".join(lines) + "\n"


def load_scenario(path: str | pathlib.Path) -> Scenario:
    """Read and validate a scenario TOML file; the string ``"paper"`` gives
    :func:`paper_scenario`. Relative ``table`` file paths are resolved against
    the scenario file's folder."""
    if str(path) == "paper":
        return paper_scenario()
    path = pathlib.Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such scenario file") from None
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: malformed TOML ({exc})") from None
    scen = scenario_from_dict(data)
    prof = scen.environment.stiffness
    if prof.kind == "table" and not pathlib.Path(prof.file).is_absolute():
        prof = dataclasses.replace(prof, file=str(path.parent / prof.file))
        scen = scen.replace(environment=dataclasses.replace(scen.environment, stiffness=prof))
    return scen


def apply_overrides(scenario: Scenario, assignments: list[str]) -> Scenario:
    """Apply ``dotted.key=value`` strings (value in TOML syntax; bare words are
    strings), e.g. ``controller.f_d=5`` or ``environment.stiffness.values=[1e3,1e4]``."""
    d = scenario_to_dict(scenario)
    for item in assignments:
        if "=" not in item:
            raise ScenarioError(f"--set {item!r}: expected dotted.key=value")
        key, raw = (s.strip() for s in item.split("=", 1))
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw
        parts = key.split(".")
        node = d
        for i, p in enumerate(parts[:-1]):
            if not isinstance(node, dict) or p not in node or not isinstance(node[p], dict):
                raise ScenarioError(f"{'.'.join(parts[:i + 1])}: unknown key")
            node = node[p]
        if parts[-1] not in node or isinstance(node[parts[-1]], dict):
            raise ScenarioError(f"{key}: unknown key")
        node[parts[-1]] = value
    return scenario_from_dict(d)
