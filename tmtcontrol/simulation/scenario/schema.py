"""The whole scenario: the :class:`Scenario` model, the checks across its sections, and validation with one-line errors.

:func:`scenario_from_dict` validates nested dicts (the TOML layout) and turns
pydantic's first error into ``dotted.key: expected ..., got ...``;
:func:`scenario_to_dict` is its inverse. The numbers a command-line flag
shares with a scenario key are checked by the same schema
(:func:`check_setting`, :func:`check_period`, :func:`check_filter_cutoff`).
"""

from __future__ import annotations

import functools
import math
from typing import Annotated, Any

from pydantic import BaseModel, Field, ValidationError, model_validator
from pydantic.fields import FieldInfo

from ...control.laws import laws, on_register
from ...control.laws.tmt import TmtParameters
from .controller import ControllerSettings, FixedDamping, ImpedanceSettings, ScheduledDamping, law_union
from .environment import (EnvironmentSettings, PiecewiseConstantStiffness, PiecewiseLinearStiffness,
                          SinusoidalStiffness, TableStiffness)
from .fields import MIN_PERIODS, ScenarioError, Section, tagged
from .robot import RobotSettings
from .sensor import SensorSettings, SimulationSettings
from .requirements import RequirementsSettings
from .trajectory import TrajectorySettings

__all__ = ["Scenario", "TAGGED_TABLES", "TAG_DEFAULTS", "SAMPLED_KEYS", "NOT_INTERVALS", "sampling_problem", "scenario_from_dict",
           "scenario_to_dict", "model_at", "check_setting", "setting_bounds", "check_period", "check_filter_cutoff",
           "takes_a_number"]


class Scenario(Section):
    """One complete simulation setup (see ``docs/scenario.md``)."""
    name: str = Field("paper", min_length=1, description="a label for outputs")
    robot: RobotSettings = Field(default_factory=RobotSettings)
    environment: EnvironmentSettings = Field(default_factory=EnvironmentSettings)
    trajectory: TrajectorySettings = Field(default_factory=TrajectorySettings)
    impedance: ImpedanceSettings = Field(default_factory=ImpedanceSettings)
    controller: ControllerSettings = Field(default_factory=ControllerSettings)
    sensor: SensorSettings = Field(default_factory=SensorSettings)
    simulation: SimulationSettings = Field(default_factory=SimulationSettings)
    requirements: RequirementsSettings = Field(default_factory=RequirementsSettings)

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

    def model_copy(self, *, update: dict | None = None, deep: bool = False) -> "Scenario":
        """A copy; with ``update`` (top-level sections or the name), the
        validated :meth:`replace` (review 58: pydantic's own copy skipped every
        check, and a scenario with f_d = -5 N ran)."""
        return self.replace(**update) if update else super().model_copy(deep=deep)

    def replace(self, **changes) -> "Scenario":
        """A validated copy with top-level sections replaced."""
        d = scenario_to_dict(self)
        d.update({k: (v.model_dump() if isinstance(v, BaseModel) else v) for k, v in changes.items()})
        return scenario_from_dict(d)


def _rebuild() -> None:
    """Accept every registered law in ``controller.law`` (called on registration)."""
    ControllerSettings.model_fields["law"] = FieldInfo.from_annotated_attribute(
        law_union(), Field(default_factory=TmtParameters, description="force-tracking law: its kind and parameters"))
    ControllerSettings.model_rebuild(force=True)
    Scenario.model_rebuild(force=True)


on_register(_rebuild)

TAGGED_TABLES = {("environment", "stiffness"): lambda: {m.model_fields["kind"].default: m for m in (
                     PiecewiseConstantStiffness, PiecewiseLinearStiffness, SinusoidalStiffness, TableStiffness)},
                 ("controller", "law"): lambda: {n: law.parameters for n, law in laws().items()},
                 ("controller", "damping_schedule"): lambda: {"off": FixedDamping, "zeta": ScheduledDamping}}
"""Tagged unions by location: kind -> model."""

TAG_DEFAULTS = {("environment", "stiffness"): "piecewise_constant", ("controller", "law"): "tmt",
                 ("controller", "damping_schedule"): "off"}
"""The kind of a tagged table that does not say."""


SAMPLED_KEYS = ("trajectory.period", "trajectory.lanes", "environment.stiffness", "sensor.filter_cutoff", "controller.rate",
                "robot.model", "environment.normal", "environment.tilt_deg", "environment.point", "trajectory.center",
                "environment.radius", "trajectory.radius", "environment.axis", "environment.heightmap",
                "environment.grid_spacing", "environment.shape", "environment.side", "trajectory.path",
                "trajectory.direction_deg", "robot.tool_radius")
"""The keys :func:`sampling_problem` relates (the only check across sections)."""


def _plane_problem(sc: Scenario) -> str | None:
    """The surface across sections: the path stays in a curved part's domain (:func:`_domain_problem`), a
    cylinder's axis lies in the tangent plane, and the circle's centre lies
    on the plane given by ``environment.point``."""
    env = sc.environment
    if env.shape != "plane":
        domain = _domain_problem(sc)
        if domain:
            return domain
    if env.axis is not None and env.normal is None:          # (an axis is a cylinder's only)
        from ..geometry import surface_frame

        n = surface_frame(env)[:, 0]
        if abs(sum(a * b for a, b in zip(env.axis, n))) > 1e-6 * math.sqrt(sum(a * a for a in env.axis)):
            return "environment.axis: must be perpendicular to the surface's normal (from tilt_deg)"
    if env.point is not None:
        from ..geometry import surface_frame   # the one definition of the task frame's normal

        n = surface_frame(env)[:, 0]
        off = sum(a * (c - p) for a, c, p in zip(n, sc.trajectory.center, env.point))
        if abs(off) > 1e-9:
            return (f"trajectory.center: must lie on the plane (environment.point, normal), "
                    f"it is {off:.6g} m off it")
    return None


def _domain_problem(sc: Scenario) -> str | None:
    """The path within the curved part's domain, along each task axis by how
    far the path really reaches (:func:`..trajectory.path_extent`: a raster
    turned by ``direction_deg`` reaches beyond ``radius``): a height map's
    grid less two spacings (beyond it the part continues on its edge's
    tangent planes: the tool would ride an extension nobody measured); the chart of a sphere or
    cylinder, regular within these angles from the path's centre (a sphere's
    latitude below pi/2, a cylinder's turn below pi; the same bound along
    both task axes: conservative along a sphere's longitude and a
    cylinder's axis)."""
    from ..trajectory import path_extent

    env, tr = sc.environment, sc.trajectory
    extent = path_extent(tr)
    turned = (" (a raster turned by trajectory.direction_deg reaches beyond its radius)"
              if max(extent) > tr.radius * (1 + 1e-9) else "")
    if any(sc.controller.part_offset):
        import numpy as np

        # review 65: a sideways offset moves the path over the true part (a map's grid), which was checked
        # unmoved: 0.1 m along a 0.3 m map rode 667 of 1,000 samples past its edge, judged converged
        moved = tuple(float(np.max(np.abs(m))) for m in _true_path(sc, _period(sc, 64 * tr.lanes + 257)))
        if max(moved) > max(extent) + 1e-9:         # the offset, not the raster's turn, reaches further
            turned += " (the true part under the commanded path: controller.part_offset moves it)"
        extent = moved
    if env.heightmap is not None:
        from .environment import read_height_grid, spacing_pair, spacing_words

        shape = read_height_grid(env.heightmap).shape
        for axis, (reach, points, d) in enumerate(zip(extent, shape, spacing_pair(env.grid_spacing))):
            half = (points - 1) / 2 * d
            if reach > half - 2 * d:
                return (f"trajectory.radius: the path leaves the height map: it reaches {reach:.6g} m from its "
                        f"centre along task axis {axis + 1}{turned}, the grid ({shape[0]} x {shape[1]} at "
                        f"{spacing_words(env.grid_spacing)}) reaches {half:g} m, "
                        + (f"a path {half - 2 * d:g} m" if half > 2 * d
                           else "no path at all") + " (two spacings kept as margin)" + _millimetres(sc))
        return None
    limit = 1.2 if env.shape == "sphere" else 2.5
    for axis, reach in enumerate(extent):
        if reach / env.radius > limit:
            return (f"trajectory.radius: the path leaves the {env.shape}'s domain: it reaches {reach:.6g} m from "
                    f"its centre along task axis {axis + 1}{turned}, {reach / env.radius:.3g} rad on radius "
                    f"{env.radius:g} m (at most {limit:g} rad from its centre)")
    return None


NOT_INTERVALS = {
    "plane": (),
    "sphere": ("trajectory.direction_deg",),
    "cylinder": ("trajectory.direction_deg",),
    "heightmap": ("trajectory.radius", "trajectory.direction_deg", "trajectory.lanes", "environment.grid_spacing"),
}
"""By shape, the numeric keys for which this module's checks of a curved part
(:func:`_domain_problem`, :func:`_tool_problem`) do not hold on an interval:
a value between two valid ones can fail (a sweep validates such a random
axis case by case, ``tmtcontrol.sweep.spec``). The path's reach from its
centre grows with ``trajectory.radius`` but not with its direction (a raster
turned 45 deg reaches furthest); a sphere's or cylinder's checks are then
monotone in its radius and the tool's; a height map's tightest concave
radius along the path changes with everything that moves the path over the
map (its size, direction, lanes, and the spacing that scales the map)."""


def _millimetres(sc: Scenario) -> str:
    """``"; "`` and the height map's millimetre note where it has one
    (:func:`.environment.steep_map_note`), for a refusal to carry: a refused
    command prints its one line, not the notes held before it (review 67)."""
    from .environment import steep_map_note

    note = steep_map_note(sc.environment.heightmap, sc.environment.grid_spacing)
    return f"; {note}" if note else ""


def _true_path(sc: Scenario, t):
    """The path's tangential coordinates (2 x k) at path times ``t`` (k, s)
    on the true part, under the path the controller commands
    (:func:`..geometry.under_the_commanded_path`: moved by a sideways
    ``controller.part_offset``; the path itself without one)."""
    import numpy as np

    from ..geometry import under_the_commanded_path
    from ..trajectory import path_reference

    pos = path_reference(np.asarray(t, dtype=float), sc.trajectory).pos
    return under_the_commanded_path(sc, np.vstack([np.zeros(pos.shape[1]), pos]))[1:]


def _period(sc: Scenario, n: int):
    """``n`` path times evenly over one period (s)."""
    import numpy as np

    return np.linspace(0.0, sc.trajectory.period, n, endpoint=False)


_CONCAVE: dict = {}
"""The tightest concave radius along a path, by (the surface's key, the path's shape)."""


def _tool_problem(sc: Scenario) -> str | None:
    """A concave part the tool's spherical tip (``robot.tool_radius``, rho)
    cannot follow. The tip touches the surface at one point, the tool point,
    only if the surface bends towards the tool less tightly than the tip in
    every tangent direction: its smallest concave radius of curvature
    (:meth:`~tmtcontrol.surface.Surface.concave_radius`, the largest
    principal curvature, not the curvature along the path: the tip bridges
    a groove the path runs along as surely as one it crosses) above rho;
    else the tip rests on the hollow's rims and the contact law at the tool
    point describes no real contact. A sphere's or cylinder's inside: its
    radius (a bore's principal curvatures are 1/radius round it and 0 along
    it); a height map: the spline's principal curvatures at the path's
    points over one period, eight per grid spacing along the path (at most
    50,000 points; a second-order, local test at the path: a feature
    narrower than the tip beside the path is not seen)."""
    import numpy as np

    env, tr, rho = sc.environment, sc.trajectory, sc.robot.tool_radius
    if env.radius is not None and env.side == "inside" and env.radius <= rho:
        return (f"environment.radius: a {env.shape} worked from inside must have a radius larger than the tool's "
                f"tip (robot.tool_radius = {rho:g} m), got {env.radius:g} m: a spherical tip touches a hollow at one "
                "point only where the hollow's radius of curvature exceeds the tip's")
    if env.heightmap is None:
        return None
    from ..geometry import surface_frame, surface_of
    from ..trajectory import path_reference
    from .environment import spacing_pair

    surface = surface_of(sc)
    # the true path under an offset depends on where the part sits (its frame and centre: review 67, a tilt
    # changed by --set reused the first tilt's answer), not only on the map's heights
    key = (surface.key, tr.path, tr.radius, tr.lanes, tr.direction_deg, tuple(sc.controller.part_offset),
           tuple(surface_frame(env).ravel().tolist()), tuple(tr.center))
    if key not in _CONCAVE:
        coarse = path_reference(np.linspace(0.0, tr.period, 64 * tr.lanes + 257), tr).pos
        length = float(np.sum(np.linalg.norm(np.diff(coarse, axis=1), axis=0)))
        n = int(min(max(math.ceil(8 * length / min(spacing_pair(env.grid_spacing))), 512), 50_000))
        t = _period(sc, n)
        s = _true_path(sc, t)           # the true part's points under the commanded path (review 65)
        radius = surface.concave_radius(s)
        i = int(np.argmin(radius))
        # the tightest point between the samples either side of the least sampled one (review 65: a groove's
        # 0.0578 m read 0.0604 m at the nearest sample, past a 0.06 m tip)
        near = np.linspace(t[i] - tr.period / n, t[i] + tr.period / n, 65)
        s_near = _true_path(sc, near)
        r_near = surface.concave_radius(s_near)
        if float(np.min(r_near)) < float(radius[i]):
            j = int(np.argmin(r_near))
            radius, s, i = r_near, s_near, j
        if len(_CONCAVE) > 64:
            _CONCAVE.clear()
        _CONCAVE[key] = (float(radius[i]), float(s[0, i]), float(s[1, i]))
    least, u, v = _CONCAVE[key]
    if least <= rho:
        u, v = (round(x, 9) + 0.0 for x in (u, v))          # no -0 or 1e-17 for a point on an axis
        return (f"environment.heightmap: must curve concave less tightly than the tool's tip (robot.tool_radius = "
                f"{rho:g} m) along the path, got a concave radius of curvature of {least:.3g} m at (u, v) = "
                f"({u:.4g}, {v:.4g}) m" + (" (the true part under the commanded path: controller.part_offset "
                                           "moves it)" if any(sc.controller.part_offset) else "")
                + ": the tip would rest on the hollow's rims, not at the tool point; smooth the map or use a "
                "smaller tool_radius" + _millimetres(sc))
    return None


def sampling_problem(sc: Scenario) -> str | None:
    """What the control period ``Ts = 1/controller.rate`` forbids, as an error
    message naming the key, or None: a path period, a stiffness segment or a
    sinusoid's period shorter than :data:`MIN_PERIODS` control periods (fewer
    samples cannot resolve them: a circle in under 10 samples, a segment whose
    last quarter holds no sample), and a force-filter cut-off at or above the
    Nyquist frequency ``rate/2`` (its discrete pole ``exp(-2 pi f_c Ts)``
    would be below ``exp(-pi) = 0.04``: no filtering at all, silently); and
    the surface's checks across sections (:func:`_plane_problem`) and a
    concave part the tool's tip cannot follow (:func:`_tool_problem`)."""
    plane = _plane_problem(sc) or _tool_problem(sc)
    if plane:
        return plane
    Ts, rate = sc.controller.Ts, sc.controller.rate
    least = MIN_PERIODS * Ts
    why = f"at least {MIN_PERIODS} control periods ({least:g} s at controller.rate = {rate:g} Hz)"
    if sc.trajectory.period < least:
        return f"trajectory.period: must be {why}, got {sc.trajectory.period!r}"
    if sc.trajectory.path == "raster" and sc.trajectory.period / sc.trajectory.lanes < least:
        return (f"trajectory.lanes: each of the {sc.trajectory.lanes} passes must take {why}: "
                f"trajectory.period / lanes = {sc.trajectory.period / sc.trajectory.lanes:g} s")
    st = sc.environment.stiffness
    if st.kind == "piecewise_constant" and st.segment != 0 and st.segment < least:
        return f"environment.stiffness.segment: must be 0 (the path period) or {why}, got {st.segment!r}"
    if st.kind == "sinusoidal" and st.period < least:
        return f"environment.stiffness.period: must be {why}, got {st.period!r}"
    cutoff = sc.sensor.filter_cutoff
    if cutoff >= rate / 2:
        return (f"sensor.filter_cutoff: must be below the Nyquist frequency controller.rate/2 = {rate / 2:g} Hz "
                f"(0 = no filter), got {cutoff!r}")
    if _pole_is_one(cutoff, 1.0 / rate):
        return _pole_message("sensor.filter_cutoff", cutoff)
    if cutoff > 0 and 1.0 / (2.0 * math.pi * cutoff) > sc.trajectory.period:
        # review 27: 1e-6 Hz ran a guarded approach that never ended, the tool driving into the part
        return (f"sensor.filter_cutoff: {cutoff!r} Hz has a time constant 1/(2 pi f_c) = "
                f"{1.0 / (2.0 * math.pi * cutoff):.3g} s, longer than a period of the path "
                f"(trajectory.period = {sc.trajectory.period:g} s): the measured force would lag the contact by "
                "more than the task; use a cut-off above 1/(2 pi period) or 0 for no filter")
    return None


def _pole_is_one(cutoff: float, Ts: float) -> bool:
    """Whether a cut-off > 0 is so low that its discrete pole exp(-2 pi f_c Ts)
    rounds to 1: the measured force would stay at 0 for ever (review 25: an
    export with 1e-15 Hz failed its own tmt_init)."""
    return cutoff > 0 and math.exp(-2.0 * math.pi * cutoff * Ts) == 1.0


def _pole_message(key: str, cutoff: float) -> str:
    return (f"{key}: {cutoff!r} Hz is so low that the filter's pole rounds to 1 (the measured force would never "
            "leave 0); use 0 for no filter")

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


def model_at(loc, data) -> type[BaseModel] | None:
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
            table = tagged(node, TAG_DEFAULTS[key])
            kind = table.get("kind") if isinstance(table, dict) else None
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
        parent = model_at(loc[:-1], data)
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


def _field_info(key: str):
    """The schema's field at dotted ``key`` (a tagged union's default kind)."""
    model: Any = Scenario
    parts = key.split(".")
    for i, part in enumerate(parts):
        info = model.model_fields[part]
        if i == len(parts) - 1:
            break
        loc = tuple(parts[max(0, i - 1):i + 1])
        model = (TAGGED_TABLES[loc]()[TAG_DEFAULTS[loc]] if loc in TAGGED_TABLES else info.annotation)
    return info


def _number_member(annotation):
    """The bounded number type of a union such as ``Spacing | tuple[...] |
    None`` (``environment.grid_spacing``: one number or a pair), else None."""
    import types
    from typing import Union, get_args, get_origin

    if get_origin(annotation) not in (Union, types.UnionType):
        return None
    return next((a for a in get_args(annotation) if get_origin(a) is Annotated and get_args(a)[0] in (int, float)),
                None)


def _field_type(key: str):
    """The type (with its constraints) of the number at dotted ``key`` of the
    schema: a tagged union's default kind; a list's element; a union's
    number (one number or a pair: the number's bounds hold for each)."""
    from typing import get_args, get_origin

    info = _field_info(key)
    typ = Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
    if get_origin(info.annotation) is tuple:
        typ = get_args(info.annotation)[0]
    elif info.annotation is not None and (number := _number_member(info.annotation)) is not None:
        typ = number
    return typ


def takes_a_number(key: str) -> bool:
    """Whether the field at dotted ``key`` takes a single number (a list-only
    key such as ``environment.stiffness.values`` does not: a sweep makes a
    number given for it a one-element list; ``environment.grid_spacing``
    takes a number or a pair). False for a key of a tagged table's other
    kind (``environment.stiffness.times``, piecewise_linear's), as for a list."""
    try:
        info = _field_info(key)
    except (KeyError, AttributeError):
        return False
    return info.annotation in (int, float) or _number_member(info.annotation) is not None


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
    if _pole_is_one(cutoff, Ts):
        raise ScenarioError(_pole_message(flag, cutoff))
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
