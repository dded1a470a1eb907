"""Sweep files: a base scenario plus axes over dotted scenario keys, and the cases they span.

A sweep file (TOML)::

    scenario = "paper"                 # or a scenario file, relative to the sweep file
    [grid]                             # every combination of these values
    "environment.stiffness.values" = [[2000.0], [20000.0], [200000.0]]
    "controller.x_e_error" = { linspace = [-0.005, 0.005, 3] }
    [random]                           # `samples` draws, each combined with every grid point
    samples = 100
    seed = 1
    "sensor.noise_std" = { uniform = [0.0, 0.2] }

A grid value is what ``--set`` takes for that key (a list value for a list
key, e.g. one stiffness ``[2000.0]``; a number for a list key is a
one-element list); ``{ linspace = [a, b, n] }`` and ``{ geomspace = [a, b,
n] }`` generate numbers. A random axis is
``{ uniform = [a, b] }``, ``{ loguniform = [a, b] }`` or ``{ normal = [mean,
std], bounds = [lo, hi] }`` (truncated by redrawing). The draws depend only
on the seed, so identical files give identical cases. Every case goes through
the scenario schema before anything runs; an error names the axis key.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..simulation.scenario import (Scenario, ScenarioError, applicable_settings, load_scenario, paper_scenario,
                                   read_toml, scenario_from_dict, scenario_to_dict, set_key)

__all__ = ["SweepError", "Sweep", "Case", "load_sweep", "sweep_from_dict", "EXAMPLE"]

EXAMPLE = '''# tmtcontrol sweep file: a base scenario, then axes over dotted scenario keys.
# Cases = every grid combination x every random sample. SI units, as in scenarios.
scenario = "paper"            # "paper" or a scenario TOML file (relative to this file)

[grid]
# a grid value is what --set takes for that key: one stiffness profile per entry
"environment.stiffness.values" = [[2000.0], [20000.0], [200000.0]]
# or generated: { linspace = [start, stop, n] } / { geomspace = [start, stop, n] }
"controller.x_e_error" = [0.0, 0.005]

[random]
samples = 100                 # draws, each combined with every grid point
seed = 1                      # same seed, same draws
"sensor.noise_std" = { uniform = [0.0, 0.2] }
# also: { loguniform = [a, b] } and { normal = [mean, std], bounds = [lo, hi] }
'''


class SweepError(ValueError):
    """An invalid sweep file; the message names the key (exit code 2 in the CLI)."""


@dataclass(frozen=True)
class Case:
    """One case: its index and the value of every axis, by dotted key."""
    index: int
    values: dict[str, Any]


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the base scenario (as a dict), the axes and the cases."""
    base: dict
    grid: dict[str, list]
    random: dict[str, dict]
    samples: int
    seed: int
    cases: tuple[Case, ...]

    @property
    def axes(self) -> list[str]:
        return [*self.grid, *self.random]

    def scenario(self, case: Case) -> Scenario:
        return case_scenario(self.base, case.values)

    @property
    def units(self) -> dict[str, str]:
        """Each axis' SI unit from the scenario schema ("" where it has none,
        such as a law's name), as the first case's scenario applies it."""
        rows = {r.key: r.unit for r in applicable_settings(self.scenario(self.cases[0]))} if self.cases else {}
        return {axis: "" if rows.get(axis, "") == "1" else rows.get(axis, "") for axis in self.axes}

    @property
    def fingerprint(self) -> str:
        """SHA-256 of the base scenario and every case: a resumed sweep must match it."""
        blob = json.dumps({"base": self.base, "cases": [c.values for c in self.cases]}, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()


def _current(d: dict, key: str):
    node = d
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def case_scenario(base: dict, values: dict) -> Scenario:
    """The scenario of one case: ``base`` with each axis value set. A number
    given for a list-valued key (e.g. a generated stiffness) is a one-element
    list."""
    d = json.loads(json.dumps(base))
    for key, value in values.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool) and isinstance(_current(d, key), list):
            value = [value]
        set_key(d, key, value)
    return scenario_from_dict(d)


def _generated(key: str, spec: dict) -> list:
    (kind, args), = spec.items() if len(spec) == 1 else (("?", None),)
    if kind not in ("linspace", "geomspace") or not (isinstance(args, list) and len(args) == 3):
        raise SweepError(f"grid.{key}: expected a list of values, {{ linspace = [a, b, n] }} or "
                         f"{{ geomspace = [a, b, n] }}, got {spec!r}")
    a, b, n = args
    if not (isinstance(n, int) and n >= 1) or not all(isinstance(v, (int, float)) for v in (a, b)):
        raise SweepError(f"grid.{key}: {kind} needs [start, stop, n] with n an integer >= 1, got {args!r}")
    if kind == "geomspace" and not (a > 0 and b > 0):
        raise SweepError(f"grid.{key}: geomspace needs start, stop > 0, got {args!r}")
    return [float(v) for v in getattr(np, kind)(a, b, n)]


def _draw(rng: np.random.Generator, key: str, spec: dict) -> float:
    if "uniform" in spec:
        a, b = spec["uniform"]
        return float(rng.uniform(a, b))
    if "loguniform" in spec:
        a, b = spec["loguniform"]
        return float(math.exp(rng.uniform(math.log(a), math.log(b))))
    mean, std = spec["normal"]
    lo, hi = spec.get("bounds", (-math.inf, math.inf))
    for _ in range(10_000):
        v = float(rng.normal(mean, std))
        if lo <= v <= hi:
            return v
    raise SweepError(f"random.{key}: bounds [{lo}, {hi}] too far in the tail of normal({mean}, {std})")


def _check_random(key: str, spec) -> dict:
    def pair(name, v, positive=False):
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, (int, float)) and math.isfinite(x)
                                                             for x in v)):
            raise SweepError(f"random.{key}: {name} needs two finite numbers, got {v!r}")
        if positive and not (v[0] > 0 and v[1] > 0):
            raise SweepError(f"random.{key}: {name} needs numbers > 0, got {v!r}")
        return [float(x) for x in v]

    if not isinstance(spec, dict):
        raise SweepError(f"random.{key}: expected {{ uniform = [a, b] }}, {{ loguniform = [a, b] }} or "
                         f"{{ normal = [mean, std], bounds = [lo, hi] }}, got {spec!r}")
    kinds = set(spec) & {"uniform", "loguniform", "normal"}
    if len(kinds) != 1 or set(spec) - {"uniform", "loguniform", "normal", "bounds"} or \
            ("bounds" in spec and "normal" not in spec):
        raise SweepError(f"random.{key}: expected exactly one of uniform, loguniform, normal (bounds only with "
                         f"normal), got {sorted(spec)}")
    kind = kinds.pop()
    out = {kind: pair(kind, spec[kind], positive=kind == "loguniform")}
    if kind in ("uniform", "loguniform") and out[kind][0] > out[kind][1]:
        raise SweepError(f"random.{key}: {kind} needs a <= b, got {spec[kind]!r}")
    if kind == "normal":
        if out["normal"][1] < 0:
            raise SweepError(f"random.{key}: normal needs std >= 0, got {spec['normal']!r}")
        if "bounds" in spec:
            out["bounds"] = pair("bounds", spec["bounds"])
            if out["bounds"][0] > out["bounds"][1]:
                raise SweepError(f"random.{key}: bounds need lo <= hi, got {spec['bounds']!r}")
    return out


def sweep_from_dict(data: Any, folder: pathlib.Path | None = None) -> Sweep:
    """Validate a parsed sweep file (see the module docstring)."""
    if not isinstance(data, dict):
        raise SweepError(f"sweep: expected a table, got {data!r}")
    unknown = set(data) - {"scenario", "grid", "random"}
    if unknown:
        raise SweepError(f"{sorted(unknown)[0]}: unknown key (expected scenario, [grid], [random])")
    src = data.get("scenario", "paper")
    if not isinstance(src, str):
        raise SweepError(f"scenario: expected \"paper\" or a file name, got {src!r}")
    try:
        base_sc = paper_scenario() if src == "paper" else load_scenario(
            (folder / src) if folder is not None and not pathlib.Path(src).is_absolute() else src)
    except ScenarioError as exc:
        raise SweepError(f"scenario: {exc}") from None
    base = scenario_to_dict(base_sc)
    grid_in = data.get("grid", {})
    random_in = dict(data.get("random", {}))
    if not isinstance(grid_in, dict) or not isinstance(random_in, dict):
        raise SweepError("grid, random: expected tables")
    samples = random_in.pop("samples", 1 if not random_in else None)
    seed = random_in.pop("seed", 0)
    if random_in and samples is None:
        raise SweepError("random.samples: required with random axes (an integer >= 1)")
    if not (isinstance(samples, int) and not isinstance(samples, bool) and samples >= 1):
        raise SweepError(f"random.samples: expected an integer >= 1, got {samples!r}")
    if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
        raise SweepError(f"random.seed: expected an integer >= 0, got {seed!r}")
    grid = {}
    for key, values in grid_in.items():
        values = _generated(key, values) if isinstance(values, dict) else values
        if not isinstance(values, list) or not values:
            raise SweepError(f"grid.{key}: expected a non-empty list of values, got {values!r}")
        grid[key] = values
    random = {key: _check_random(key, spec) for key, spec in random_in.items()}
    overlap = set(grid) & set(random)
    if overlap:
        raise SweepError(f"{sorted(overlap)[0]}: both a grid and a random axis")
    if not grid and not random:
        raise SweepError("grid, random: a sweep needs at least one axis")
    # every grid value and every random distribution's range through the scenario schema, naming the axis
    for key, values in grid.items():
        for i, v in enumerate(values):
            try:
                case_scenario(base, {key: v})
            except ScenarioError as exc:
                raise SweepError(f"grid.{key}[{i}] = {v!r}: {exc}") from None
    rng = np.random.default_rng(seed)
    draws = [{key: _draw(rng, key, spec) for key, spec in random.items()} for _ in range(samples)]
    cases = []
    for combo in itertools.product(*grid.values()):
        for draw in draws:
            cases.append(Case(len(cases), {**dict(zip(grid, combo)), **draw}))
    for case in cases:      # combinations may conflict (e.g. a law and a schedule): name the case
        try:
            case_scenario(base, case.values)
        except ScenarioError as exc:
            raise SweepError(f"case {case.index} ({_describe(case.values)}): {exc}") from None
    return Sweep(base, grid, random, samples, seed, tuple(cases))


def _describe(values: dict) -> str:
    return ", ".join(f"{k} = {v!r}" for k, v in values.items())


def load_sweep(path: str | pathlib.Path) -> Sweep:
    """Read and validate a sweep TOML file."""
    path = pathlib.Path(path)
    return sweep_from_dict(read_toml(path, "sweep", SweepError), path.parent)
