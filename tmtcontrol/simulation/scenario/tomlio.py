"""Scenarios as TOML: dump, load (a file or a built-in name) and ``--set dotted.key=value`` overrides."""

from __future__ import annotations

import math
import pathlib
import re
import tomllib
from typing import Any

from .builtin import BUILTIN_ARMS, arm_scenario, paper_scenario
from .fields import ScenarioError
from .schema import TAGGED_TABLES, Scenario, model_at, scenario_from_dict, scenario_to_dict
from .textfiles import InputFileError, parse_toml, read_toml

__all__ = ["toml_key", "toml_value", "dump_scenario", "toml_document", "load_scenario", "set_key",
           "apply_overrides"]


def toml_key(k) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else toml_value(k)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):      # an inline table (a value where the schema wants a table, or a wrong one)
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {v!r} as TOML")


def dump_scenario(scenario: Scenario) -> str:
    """The scenario as a TOML document that :func:`load_scenario` reads back;
    it holds only the fields of the chosen kinds."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"dump_scenario: expected a Scenario, got {type(scenario).__name__}")
    return toml_document(scenario_to_dict(scenario))


def toml_document(d: dict) -> str:
    """A scenario dict (TOML layout, valid or not) as a TOML document: ``name``
    and the sections (tables); other top-level values are left out."""
    d = dict(d)
    lines = ["# tmtcontrol scenario (SI units; see docs/scenario.md)", f"name = {toml_value(d.pop('name', 'scenario'))}"]

    def table(name, body):
        lines.append("")
        lines.append(f"[{name}]")
        sub = []
        for k, v in body.items():
            if isinstance(v, dict):
                sub.append((k, v))
            else:
                lines.append(f"{k} = {toml_value(v)}")
        for k, v in sub:
            table(f"{name}.{k}", v)

    for name, body in d.items():      # sections only: a scenario has no other top-level value
        if isinstance(body, dict):
            table(name, body)
    return "\n".join(lines) + "\n"


def resolve_files(data: dict, folder: pathlib.Path) -> None:
    """Join a relative stiffness ``table`` file, height map or URDF of the
    scenario dict ``data`` (TOML layout, or any part of it from the top) to
    ``folder``, in place: a file named in a file is found beside it."""
    stiff = data.get("environment", {}).get("stiffness") if isinstance(data.get("environment"), dict) else None
    if isinstance(stiff, dict) and isinstance(stiff.get("file"), str) and stiff["file"] \
            and not pathlib.Path(stiff["file"]).is_absolute():
        stiff["file"] = str(folder / stiff["file"])
    env = data.get("environment")
    if isinstance(env, dict) and isinstance(env.get("heightmap"), str) and env["heightmap"] \
            and not pathlib.Path(env["heightmap"]).is_absolute():
        env["heightmap"] = str(folder / env["heightmap"])
    robot = data.get("robot")
    if isinstance(robot, dict) and isinstance(robot.get("model"), str) and robot["model"].lower().endswith(".urdf") \
            and not pathlib.Path(robot["model"]).is_absolute():
        robot["model"] = str(folder / robot["model"])


def load_scenario(path: str | pathlib.Path) -> Scenario:
    """Read and validate a scenario TOML file; the string ``"paper"`` gives
    :func:`paper_scenario`. A relative stiffness ``table`` file, height map
    or URDF is resolved against the scenario file's folder. An empty file is refused."""
    if not isinstance(path, (str, pathlib.Path)):      # review 58: 5 failed inside pathlib
        raise TypeError(f"load_scenario: expected a file name or a built-in's ('paper', "
                        f"{', '.join(map(repr, BUILTIN_ARMS))}), got {path!r}")
    if str(path) == "paper":
        return paper_scenario()
    if str(path) in BUILTIN_ARMS:
        return arm_scenario(str(path))
    path = pathlib.Path(path)
    src = str(path)
    data = read_toml(path, "scenario", ScenarioError)
    if not data:
        raise ScenarioError(f"{src}: empty scenario; start from 'tmtcontrol scenario paper > {path.name}'")
    resolve_files(data, path.parent)
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
            parent = model_at(tuple(parts[:i]), d)
            tables = [f for f in parent.model_fields if f != "kind"] if parent is not None else []
            raise ScenarioError(f"{'.'.join(parts[:i + 1])}: unknown key"
                                + (f" (known: {', '.join(tables)})" if tables else ""))
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
    known = model_at(tuple(parts[:-1]), d)
    tagged_member = known is not None and "kind" in known.model_fields   # the schema names the kind
    if last not in node and not tagged_member and (known is None or last not in known.model_fields):
        fields = [f for f in (known.model_fields if known is not None else node) if f != "kind"]
        raise ScenarioError(f"{key}: unknown key" + (f" (known: {', '.join(fields)})" if fields else ""))
    node[last] = value


def replace_plane(d: dict, keys) -> None:
    """Before ``keys`` are set on the scenario dict ``d``: the plane is given
    by ``environment.normal`` or its shorthand ``environment.tilt_deg``, so a
    key setting one drops ``d``'s other (a dump always carries one of them),
    unless ``keys`` set both (which must then agree)."""
    keys = set(keys)
    env = d.get("environment")
    for given, other in (("environment.normal", "tilt_deg"), ("environment.tilt_deg", "normal")):
        if given in keys and f"environment.{other}" not in keys and isinstance(env, dict):
            env.pop(other, None)


def apply_overrides(scenario: Scenario, assignments: list[str]) -> Scenario:
    """Apply ``dotted.key=value`` strings (value in TOML syntax; bare words are
    strings), e.g. ``controller.f_d=5``, ``controller.law=integral`` or
    ``environment.stiffness.values=[1e3,1e4]``. The result goes through the
    same schema as a file. The plane is given by ``environment.normal`` or
    its shorthand ``environment.tilt_deg``: an override of one replaces the
    base's other (which the base's dump always carries), unless it is set too."""
    d = scenario_to_dict(scenario)
    replace_plane(d, [item.split("=", 1)[0].strip() for item in assignments if "=" in item])
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
        try:
            set_key(d, key, value)
        except ScenarioError as exc:          # say where the key came from, as the schema's messages do
            raise ScenarioError(f"{exc} (in --set)") from None
    return scenario_from_dict(d, "--set")
